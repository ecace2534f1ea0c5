//! Checked while it runs: after every cycle the run evaluates what it has measured
//! (docs/FORMAT.md §7.3, *Checked while it runs*). The evaluation is `solve`'s on the
//! measurement file as it is on disk; what it finds is reported while the polygon is
//! still on the table:
//!
//! - the cycle's closure (each autocollimator's reading at the closing step N minus its
//!   reading at step 0 of the same cycle), and the residual RMS of the cycle's readings
//!   against that of the cycles before;
//! - the reading whose residual lies furthest beyond the run's noise (more than
//!   [`OUTLIER_SIGMAS`] times σ, σ estimated robustly from the residuals, 1.4826·MAD, and
//!   never taken below the stated noise of a stored reading), which the measuring loop
//!   measures again;
//! - an autocollimator whose readings of the cycle sit off the fit as a whole (their
//!   mean residual beyond [`OFFSET_SIGMAS`] standard errors): a drift or a jump of its
//!   zero, as a warning.

use serde::{Deserialize, Serialize};

use super::RunSettings;
use crate::measurement::{Direction, MeasurementSet, Reading};
use crate::solve::{SolveOptions, solve};

/// How many σ a reading's residual must lie beyond for the reading to be measured again.
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// How many standard errors an autocollimator's mean residual over a cycle must lie
/// beyond for a warning.
pub const OFFSET_SIGMAS: f64 = 5.0;
/// Fewest residual degrees of freedom for a check: fewer cannot estimate the noise.
pub const MIN_DOF: usize = 4;
/// Most stops measured again after one cycle.
pub const MAX_REMEASURED_PER_CYCLE: usize = 3;

/// A reading measured again at the end of a cycle, whose first value was not kept in
/// the measurement file (it is in `remeasured.csv` and here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Remeasured {
    /// The reading's cycle, step and autocollimator.
    pub cycle: u32,
    /// Its step.
    pub step: usize,
    /// Its autocollimator.
    pub ac: u32,
    /// The first value, arcsec (left out of the evaluation).
    pub first_arcsec: f64,
    /// The value measured again and stored, arcsec.
    pub reading_arcsec: f64,
    /// The first value's residual in the check that found it, arcsec.
    pub residual_arcsec: f64,
    /// The run's noise σ in that check, arcsec.
    pub sigma_arcsec: f64,
    /// The cycle after which the check ran.
    pub found_after_cycle: u32,
}

/// A reading whose residual lay far beyond the run's noise but that was confirmed when
/// its stop was measured again: kept, and named, since no reading of its stop was off.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Suspect {
    /// The reading's cycle.
    pub cycle: u32,
    /// Its step.
    pub step: usize,
    /// Its autocollimator.
    pub ac: u32,
    /// Its value, arcsec.
    pub reading_arcsec: f64,
    /// The value measured again, arcsec.
    pub measured_again_arcsec: f64,
    /// Its residual, arcsec.
    pub residual_arcsec: f64,
    /// The run's noise σ, arcsec.
    pub sigma_arcsec: f64,
    /// The cycle after which the check ran.
    pub found_after_cycle: u32,
}

/// What the check after a cycle found.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CycleCheck {
    /// The cycle just measured.
    pub cycle: u32,
    /// Per autocollimator, its reading at the closing step minus that at step 0 in this
    /// cycle, arcsec (empty without the closing step).
    pub closure_arcsec: Vec<(u32, f64)>,
    /// RMS of this cycle's residuals, arcsec (`None` while the fit cannot tell).
    pub residual_rms_arcsec: Option<f64>,
    /// RMS of the residuals of the cycles before, arcsec.
    pub previous_residual_rms_arcsec: Option<f64>,
    /// The run's noise σ as the check took it, arcsec.
    pub sigma_arcsec: Option<f64>,
    /// Readings measured again after this cycle.
    pub remeasured: Vec<Remeasured>,
    /// Readings confirmed though far off the fit.
    pub suspect: Vec<Suspect>,
    /// What the residuals show that the run should know now (a drift or a jump).
    pub warnings: Vec<String>,
    /// The (cycle, autocollimator) pairs the warnings are about.
    pub offsets: Vec<(u32, u32)>,
}

/// The run's fit at a check.
#[derive(Debug, Clone)]
pub(super) struct Fit {
    pub(super) readings: Vec<Reading>,
    pub(super) residuals: Vec<f64>,
    /// σ as the check takes it: the robust estimate, not below the stated noise of a
    /// stored reading.
    pub(super) sigma: f64,
}

/// A reading's cell: (step, autocollimator, direction).
pub(super) type Cell = (usize, u32, Direction);

/// The cell of `reading`.
pub(super) fn cell(reading: &Reading) -> Cell {
    (reading.step, reading.ac, reading.direction)
}

/// Fits the readings so far; `None` while there are too few to estimate the noise (or
/// the design cannot be solved yet).
pub(super) fn fit(set: &MeasurementSet, settings: &RunSettings) -> Option<Fit> {
    let solution = solve(set, &SolveOptions::new()).ok()?;
    if solution.dof < MIN_DOF || solution.residuals.len() != set.readings.len() {
        return None;
    }
    let mut magnitudes: Vec<f64> = solution.residuals.iter().map(|r| r.abs()).collect();
    magnitudes.sort_by(f64::total_cmp);
    let n = magnitudes.len();
    let median = if n % 2 == 1 {
        magnitudes[n / 2]
    } else {
        (magnitudes[n / 2 - 1] + magnitudes[n / 2]) / 2.0
    };
    // Residuals shrink by dof/n on average; the MAD of normal residuals is 0.6745 σ.
    let robust = 1.4826 * median * (n as f64 / solution.dof as f64).sqrt();
    let stated = settings.reading_noise_arcsec / f64::from(settings.reads_per_stop).sqrt();
    Some(Fit {
        readings: set.readings.clone(),
        residuals: solution.residuals,
        sigma: robust.max(stated),
    })
}

/// The reading (its index) whose residual lies furthest beyond [`OUTLIER_SIGMAS`]·σ,
/// outside the cells in `handled` and the (cycle, autocollimator) pairs in `explained`
/// (whose readings sit off as a whole: a drift or a jump, not one reading).
pub(super) fn worst(fit: &Fit, handled: &[Cell], explained: &[(u32, u32)]) -> Option<usize> {
    let limit = OUTLIER_SIGMAS * fit.sigma;
    fit.residuals
        .iter()
        .enumerate()
        .filter(|&(i, r)| {
            let reading = &fit.readings[i];
            r.abs() > limit
                && !handled.contains(&cell(reading))
                && !explained.contains(&(reading.cycle, reading.ac))
        })
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(i, _)| i)
}

/// The summary of a cycle whose file could not be read back: nothing but its number.
pub(super) fn unchecked(cycle: u32) -> CycleCheck {
    CycleCheck {
        cycle,
        closure_arcsec: Vec::new(),
        residual_rms_arcsec: None,
        previous_residual_rms_arcsec: None,
        sigma_arcsec: None,
        remeasured: Vec::new(),
        suspect: Vec::new(),
        warnings: Vec::new(),
        offsets: Vec::new(),
    }
}

/// The summary of `cycle`: closure, residual RMS against the cycles before, the noise,
/// and the warnings (the lists of readings measured again are the loop's to fill).
pub(super) fn summary(set: &MeasurementSet, fit: Option<&Fit>, cycle: u32) -> CycleCheck {
    let mut closure_arcsec = Vec::new();
    let faces = set.faces;
    let mut acs: Vec<u32> = set.readings.iter().map(|r| r.ac).collect();
    acs.sort_unstable();
    acs.dedup();
    for &ac in &acs {
        let at = |step: usize| {
            set.readings
                .iter()
                .find(|r| r.cycle == cycle && r.ac == ac && r.step == step)
                .map(|r| r.reading_arcsec)
        };
        if let (Some(last), Some(first)) = (at(faces), at(0)) {
            closure_arcsec.push((ac, last - first));
        }
    }
    let mut check = CycleCheck {
        closure_arcsec,
        ..unchecked(cycle)
    };
    let Some(fit) = fit else {
        return check;
    };
    let rms = |keep: &dyn Fn(&Reading) -> bool| {
        let (sum, n) = fit
            .readings
            .iter()
            .zip(&fit.residuals)
            .filter(|(r, _)| keep(r))
            .fold((0.0, 0usize), |(s, n), (_, e)| (s + e * e, n + 1));
        (n > 0).then(|| (sum / n as f64).sqrt())
    };
    check.residual_rms_arcsec = rms(&|r| r.cycle == cycle);
    check.previous_residual_rms_arcsec = rms(&|r| r.cycle < cycle);
    check.sigma_arcsec = Some(fit.sigma);
    if cycle >= 2 {
        for &ac in &acs {
            let (sum, n) = fit
                .readings
                .iter()
                .zip(&fit.residuals)
                .filter(|(r, _)| r.cycle == cycle && r.ac == ac)
                .fold((0.0, 0usize), |(s, n), (_, e)| (s + e, n + 1));
            if n == 0 {
                continue;
            }
            let mean = sum / n as f64;
            let z = mean / (fit.sigma / (n as f64).sqrt());
            if z.abs() > OFFSET_SIGMAS {
                check.offsets.push((cycle, ac));
                check.warnings.push(format!(
                    "autocollimator {ac}: its readings of cycle {cycle} sit {mean:+.4}″ off the \
                     fit of the run so far on average ({z:+.1} standard errors; σ {:.4}″): a \
                     drift or a jump of its zero? `polycal diagnose` names it once the run is done",
                    fit.sigma
                ));
            }
        }
    }
    check
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{SimulationConfig, simulate};

    fn run_set(outlier: Option<(u32, usize, u32, f64)>) -> MeasurementSet {
        let config = SimulationConfig {
            faces: 12,
            cycles: 3,
            closing: true,
            noise_arcsec: 0.05,
            seed: 3,
            ..SimulationConfig::default()
        };
        let (mut set, _) = simulate(&config).unwrap();
        if let Some((cycle, step, ac, value)) = outlier {
            for r in &mut set.readings {
                if (r.cycle, r.step, r.ac) == (cycle, step, ac) {
                    r.reading_arcsec += value;
                }
            }
        }
        set
    }

    fn settings() -> RunSettings {
        RunSettings::new(12, 3)
            .with_closing(true)
            .with_reading_noise_arcsec(0.05)
    }

    #[test]
    fn a_reading_two_arcseconds_off_is_the_one_found() {
        let set = run_set(Some((2, 5, 1, 2.0)));
        let fit = fit(&set, &settings()).unwrap();
        let i = worst(&fit, &[], &[]).unwrap();
        let r = &fit.readings[i];
        assert_eq!((r.cycle, r.step, r.ac), (2, 5, 1));
        // Handled, nothing else stands out.
        assert_eq!(worst(&fit, &[cell(r)], &[]), None);
    }

    #[test]
    fn a_clean_run_has_nothing_to_measure_again_and_no_warning() {
        let set = run_set(None);
        let fit = fit(&set, &settings()).unwrap();
        assert_eq!(worst(&fit, &[], &[]), None);
        let check = summary(&set, Some(&fit), 3);
        assert!(check.warnings.is_empty(), "{:?}", check.warnings);
        // The closure of a clean cycle is the noise of two readings (and the stated σ
        // of a stored reading bounds σ from below).
        assert_eq!(check.closure_arcsec.len(), 2);
        for (_, c) in &check.closure_arcsec {
            assert!(c.abs() < 6.0 * 0.05 * 2f64.sqrt(), "{c}");
        }
        let sigma = check.sigma_arcsec.unwrap();
        assert!((0.035..0.07).contains(&sigma), "{sigma}");
    }

    #[test]
    fn a_zero_jump_from_a_cycle_on_is_a_warning() {
        let mut set = run_set(None);
        for r in &mut set.readings {
            if r.cycle == 3 && r.ac == 2 {
                r.reading_arcsec += 0.5;
            }
        }
        let fit = fit(&set, &settings()).unwrap();
        let check = summary(&set, Some(&fit), 3);
        assert_eq!(check.warnings.len(), 1, "{:?}", check.warnings);
        assert!(check.warnings[0].starts_with("autocollimator 2:"));
        assert_eq!(check.offsets, [(3, 2)]);
        // Its readings are not chased one by one.
        assert_eq!(worst(&fit, &[], &check.offsets), None);
    }
}
