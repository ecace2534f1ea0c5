//! Checked while it runs: after every cycle the run evaluates what it has measured
//! (docs/FORMAT.md §7.3, *Checked while it runs*). The evaluation is `solve`'s on the
//! measurement file as it is on disk; what it finds is reported while the polygon is
//! still on the table:
//!
//! - the cycle's closure (each autocollimator's reading at the closing step N minus its
//!   reading at step 0 of the same cycle), and the residual RMS of the cycle's readings
//!   against that of the cycles before;
//! - the reading whose studentized residual lies furthest beyond the run's noise (its
//!   residual over √(1 − h), h its leverage in the fit, more than [`OUTLIER_SIGMAS`]
//!   times σ; σ estimated robustly from the studentized residuals, 1.4826·MAD, and never
//!   taken below the noise of a stored reading the run judges by), which the measuring
//!   loop measures again. The fit draws each reading towards itself by its leverage and
//!   leaves a residual of (1 − h) times its error: judged by its residual alone, a
//!   reading 8σ off in a three-cycle run (h ≈ 0.3–0.5) would be measured again in a
//!   fifth of the runs; studentized, its statistic is √(1 − h) times its error and, for
//!   an honest reading, has the noise's own σ whatever h. A reading of leverage 1 (the
//!   only one of its kind so far) has nothing to be judged by and is never flagged;
//! - an autocollimator whose readings of the cycle sit off the fit as a whole (their
//!   mean residual beyond [`OFFSET_SIGMAS`] standard errors): a drift or a jump of its
//!   zero, as a warning;
//! - in a mounting after the first, readings that do not fit those of the mountings
//!   before (an F test of the fit with them against the fit without, p below
//!   [`MOUNTING_MISFIT_P`]): a polygon not mounted as the run was told, as a warning.

use serde::{Deserialize, Serialize};

use super::RunSettings;
use crate::diagnose::base::Base;
use crate::measurement::{Direction, MeasurementSet, Reading};
use crate::solve::sub_pitch::solve_shifted;
use crate::solve::{SolveOptions, solve};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

/// How many σ a reading's studentized residual (its residual over √(1 − h), h its
/// leverage) must lie beyond for the reading to be measured again.
pub const OUTLIER_SIGMAS: f64 = 6.0;
/// The least 1 − h (h a reading's leverage) with which a reading is judged: a reading
/// of leverage within this of 1 determines its own fitted value, its residual is 0
/// whatever it read, and the fit has nothing to judge it by.
pub(super) const MIN_ROOM: f64 = 1e-6;
/// How many standard errors an autocollimator's mean residual over a cycle must lie
/// beyond for a warning.
pub const OFFSET_SIGMAS: f64 = 5.0;
/// Fewest residual degrees of freedom for a check: fewer cannot estimate the noise.
pub const MIN_DOF: usize = 4;
/// Most stops measured again after one cycle.
pub const MAX_REMEASURED_PER_CYCLE: usize = 3;
/// The p-value below which the readings of a mounting are said not to fit those of the
/// mountings before it.
pub const MOUNTING_MISFIT_P: f64 = 1e-3;

fn first_setup() -> u32 {
    1
}

/// A reading measured again at the end of a cycle, whose first value was not kept in
/// the measurement file (it is in `remeasured.csv` and here).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Remeasured {
    /// The reading's mounting (absent from older manifests: 1).
    #[serde(default = "first_setup")]
    pub setup: u32,
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
    /// The reading's mounting (absent from older manifests: 1).
    #[serde(default = "first_setup")]
    pub setup: u32,
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

/// What the check after a cycle found (as JSON: its fields by name, pairs as arrays).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct CycleCheck {
    /// The mounting of the cycle.
    pub setup: u32,
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
    /// The (cycle, autocollimator) pairs of the mounting the warnings are about.
    pub offsets: Vec<(u32, u32)>,
    /// The warning that the mounting's readings do not fit those of the mountings before
    /// it (also among `warnings`), if they do not.
    pub misfit: Option<String>,
}

/// The run's fit at a check.
#[derive(Debug, Clone)]
pub(super) struct Fit {
    pub(super) readings: Vec<Reading>,
    /// Each reading's residual, arcsec.
    pub(super) residuals: Vec<f64>,
    /// Each reading's leverage h in the fit (the diagonal of its hat matrix; 0 for every
    /// reading when the geometry could not be formed, which judges the residuals as
    /// they are).
    pub(super) leverage: Vec<f64>,
    /// σ as the check takes it: the robust estimate, not below the noise of a stored
    /// reading the run judges by.
    pub(super) sigma: f64,
}

impl Fit {
    /// Reading `i`'s studentized residual, its residual over √(1 − h), arcsec: what is
    /// judged against [`OUTLIER_SIGMAS`]·σ. `None` for a reading the fit has nothing to
    /// judge by (1 − h below [`MIN_ROOM`]).
    pub(super) fn studentized(&self, i: usize) -> Option<f64> {
        let r = *self.residuals.get(i)?;
        let room = 1.0 - self.leverage.get(i).copied().unwrap_or(0.0);
        (room >= MIN_ROOM).then(|| r / room.sqrt())
    }

    /// Whether reading `i`'s studentized residual lies beyond [`OUTLIER_SIGMAS`]·σ.
    pub(super) fn beyond(&self, i: usize) -> bool {
        self.studentized(i)
            .is_some_and(|t| t.abs() > OUTLIER_SIGMAS * self.sigma)
    }
}

/// A reading's cell: (setup, step, autocollimator, direction).
pub type Cell = (u32, usize, u32, Direction);

/// The cell of `reading`.
pub(super) fn cell(reading: &Reading) -> Cell {
    (reading.setup, reading.step, reading.ac, reading.direction)
}

/// The table's offset from the commanded stop that `reading` includes, arcsec: its
/// `encoder` (the position the table reported, within the position tolerance of the
/// stop) minus the stop's angle (`shift_deg` + step·360°/N), times 3600. The
/// autocollimator sees the polygon where the table stands, so its reading carries the
/// offset. 0 without an encoder, and for an encoder more than a degree off (not this
/// stop).
pub(super) fn stop_offset_arcsec(reading: &Reading, faces: usize, shift_deg: f64) -> f64 {
    let Some(encoder) = reading.encoder_degrees else {
        return 0.0;
    };
    let commanded = shift_deg + reading.step as f64 * 360.0 / faces.max(1) as f64;
    let off = (encoder - commanded + 180.0).rem_euclid(360.0) - 180.0;
    if off.is_finite() && off.abs() <= 1.0 {
        off * 3600.0
    } else {
        0.0
    }
}

/// `set` with every reading's table offset ([`stop_offset_arcsec`]) taken out: what the
/// autocollimators would have read with the table exactly at its stops.
fn at_commanded_stops(set: &MeasurementSet) -> MeasurementSet {
    let mut set = set.clone();
    let faces = set.faces;
    let shifts = set.setup_shift_deg.clone();
    for r in &mut set.readings {
        let shift = shifts.get(&r.setup).copied().unwrap_or(0.0);
        r.reading_arcsec -= stop_offset_arcsec(r, faces, shift);
    }
    set
}

/// `solve`'s fit of `set`, the table's offsets from the commanded stops taken out of the
/// readings ([`at_commanded_stops`]): a table that stopped within its tolerance but off
/// the stop moved the readings by what its encoder reports, not by a fault. Mountings
/// between the stops in their encoder positions, as `solve` takes them.
fn solved(set: &MeasurementSet) -> Option<crate::solve::Solution> {
    let set = &at_commanded_stops(set);
    if set.has_shifts() {
        Some(solve_shifted(set, &SolveOptions::new()).ok()?.solution)
    } else {
        solve(set, &SolveOptions::new()).ok()
    }
}

/// Whether the readings of mounting `setup` so far fit those of the mountings before it:
/// F = ((RSS − RSS₀)/(ν − ν₀)) / (RSS₀/ν₀), the fit of every reading against the fit of
/// the earlier mountings alone (RSS₀ with ν₀ degrees of freedom), both without the
/// readings `fit` finds beyond [`OUTLIER_SIGMAS`]·σ ([`Fit::beyond`]; one reading off is not a mounting
/// off). The warning when p < [`MOUNTING_MISFIT_P`]; `None` when it fits, for the first
/// mounting, or when a fit cannot tell.
pub(super) fn mounting_misfit(set: &MeasurementSet, fit: &Fit, setup: u32) -> Option<String> {
    if setup < 2 || fit.residuals.len() != set.readings.len() {
        return None;
    }
    let mut set = set.clone();
    let mut kept = (0..fit.residuals.len()).map(|i| !fit.beyond(i));
    set.readings.retain(|_| kept.next().unwrap_or(true));
    let set = &set;
    let mut before = set.clone();
    before.readings.retain(|r| r.setup < setup);
    before.setup_shift_deg.retain(|&s, _| s < setup);
    let earlier = solved(&before)?;
    let all = solved(set)?;
    if earlier.dof < MIN_DOF || all.dof <= earlier.dof || earlier.rss.is_nan() || earlier.rss <= 0.0
    {
        return None;
    }
    let (nu0, nu) = (earlier.dof as f64, (all.dof - earlier.dof) as f64);
    let f = ((all.rss - earlier.rss).max(0.0) / nu) / (earlier.rss / nu0);
    let p = FisherSnedecor::new(nu, nu0).ok()?.sf(f);
    if p.is_nan() || p >= MOUNTING_MISFIT_P {
        return None;
    }
    let rms = |rss: f64, n: usize| (rss / n.max(1) as f64).sqrt();
    Some(format!(
        "the readings of mounting {setup} do not fit those of the mountings before it: \
         residual RMS {:.4}″ with them, {:.4}″ without (F = {f:.1} on {nu} and {nu0} degrees \
         of freedom, p = {p:.1e}): is the polygon mounted as the run was told (the faces \
         named when it asked)? If not, stop the run (Ctrl-C): these readings carry the wrong faces",
        rms(all.rss, set.readings.len()),
        rms(earlier.rss, before.readings.len()),
    ))
}

/// The leverage h of every reading of `set` in the fit [`solved`] makes of it: the
/// diagonal of the hat matrix of the same model as `diagnose` forms it (`solve`'s closure
/// model in encoder positions, a sub-pitch mounting's coset columns with it). The
/// leverages depend on the design alone, not on the values read. `None` when the fit
/// fails.
fn leverage(set: &MeasurementSet) -> Option<Vec<f64>> {
    let base = Base::of(set);
    let fit = base.fit(&[], None).ok()?;
    Some(base.geometry(&fit, &[]).leverage())
}

/// The constant that makes the mean square of normal values within ±3σ an estimate of
/// σ²: E\[Z² | |Z| ≤ 3\] = 1 − 2·3·φ(3)/(2Φ(3) − 1).
const WITHIN_3_SIGMA: f64 = 0.973_336_924_662_541_5;

/// σ estimated robustly from studentized residuals `t` (each of σ itself when honest,
/// whatever its leverage): a first σ₀ = 1.4826·median |t| (the MAD of normal values is
/// 0.6745 σ), which a few readings far off do not move; then the mean square of the
/// values within 3σ₀, over [`WITHIN_3_SIGMA`] — as robust, with about two thirds of the
/// MAD's sampling error (the MAD uses 37 % of the information of normal values, the
/// mean square within 3σ about 90 %). 0 without values.
fn robust_sigma(t: &[f64]) -> f64 {
    let mut magnitudes: Vec<f64> = t.iter().map(|t| t.abs()).collect();
    magnitudes.sort_by(f64::total_cmp);
    let m = magnitudes.len();
    let median = match m {
        0 => return 0.0,
        _ if m % 2 == 1 => magnitudes[m / 2],
        _ => (magnitudes[m / 2 - 1] + magnitudes[m / 2]) / 2.0,
    };
    let first = 1.4826 * median;
    let (sum, kept) = magnitudes
        .iter()
        .take_while(|t| **t <= 3.0 * first)
        .fold((0.0, 0usize), |(s, k), t| (s + t * t, k + 1));
    if kept == 0 {
        return first;
    }
    (sum / kept as f64 / WITHIN_3_SIGMA).sqrt()
}

/// Fits the readings so far; `None` while there are too few to estimate the noise (or
/// the design cannot be solved yet). Each reading is judged by its studentized residual
/// ([`Fit::studentized`]); σ is estimated robustly from them ([`robust_sigma`]) and not
/// taken below `reading_noise_arcsec` (the noise of one reading the run judges by: the
/// stated one, or the smaller one its repeats measured,
/// [`super::RepeatNoise::sigma_used_arcsec`]) over √`reads`.
pub(super) fn fit(
    set: &MeasurementSet,
    settings: &RunSettings,
    reading_noise_arcsec: f64,
) -> Option<Fit> {
    let solution = solved(set)?;
    let n = solution.residuals.len();
    if solution.dof < MIN_DOF || n != set.readings.len() {
        return None;
    }
    let leverage = leverage(set)
        .filter(|h| h.len() == n && h.iter().all(|h| h.is_finite()))
        .unwrap_or_else(|| vec![0.0; n]);
    let mut fit = Fit {
        readings: set.readings.clone(),
        residuals: solution.residuals,
        leverage,
        sigma: 0.0,
    };
    let studentized: Vec<f64> = (0..n).filter_map(|i| fit.studentized(i)).collect();
    let robust = robust_sigma(&studentized);
    let floor = reading_noise_arcsec.min(settings.reading_noise_arcsec)
        / f64::from(settings.reads_per_stop).sqrt();
    fit.sigma = robust.max(floor);
    Some(fit)
}

/// The reading (its index) of mounting `setup` — the polygon is mounted so now — whose
/// studentized residual ([`Fit::studentized`]) lies furthest beyond [`OUTLIER_SIGMAS`]·σ,
/// outside the cells in `handled` and the (cycle, autocollimator) pairs in `explained`
/// (whose readings sit off as a whole: a drift or a jump, not one reading).
pub(super) fn worst(
    fit: &Fit,
    setup: u32,
    handled: &[Cell],
    explained: &[(u32, u32)],
) -> Option<usize> {
    let magnitude = |i: usize| fit.studentized(i).map_or(0.0, f64::abs);
    (0..fit.readings.len())
        .filter(|&i| {
            let reading = &fit.readings[i];
            fit.beyond(i)
                && reading.setup == setup
                && !handled.contains(&cell(reading))
                && !explained.contains(&(reading.cycle, reading.ac))
        })
        .max_by(|&a, &b| magnitude(a).total_cmp(&magnitude(b)))
}

/// A reading the check after a cycle measures again: the first decision of the check
/// ([`to_measure_again`]).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ToMeasureAgain {
    /// The reading's index in the measurement set checked.
    pub index: usize,
    /// Its residual in the run's fit, arcsec.
    pub residual_arcsec: f64,
    /// Its leverage h in the run's fit (0 … 1).
    pub leverage: f64,
    /// Its studentized residual, the residual over √(1 − h), arcsec: beyond
    /// [`OUTLIER_SIGMAS`]·σ.
    pub studentized_arcsec: f64,
    /// The run's noise σ as the check took it, arcsec.
    pub sigma_arcsec: f64,
}

/// The check's decision after cycle `cycle` of mounting `setup`, with the file on disk
/// holding `set` (docs/FORMAT.md §7.3, *Checked while it runs*): the reading the run
/// measures again first, or `None`. It is the measuring loop's own first decision —
/// `solve`'s fit of every reading so far, each reading's studentized residual r/√(1 − h)
/// (h its leverage; a reading of leverage 1 is not judged), σ robust (1.4826 times their
/// median magnitude) and not below the stated noise of a stored reading
/// (`reading_noise`/√`reads`), and the reading of the mounting on the table whose
/// studentized residual lies furthest beyond [`OUTLIER_SIGMAS`]·σ, outside the cells in `handled` (measured again already in this session) and the
/// readings of an autocollimator whose cycle sits off the fit as a whole (a warning,
/// not one reading). `None` too while the fit has fewer than [`MIN_DOF`] residual
/// degrees of freedom. The run asks again after every stop it measures again, up to
/// [`MAX_REMEASURED_PER_CYCLE`] stops a cycle.
pub fn to_measure_again(
    set: &MeasurementSet,
    settings: &RunSettings,
    setup: u32,
    cycle: u32,
    handled: &[Cell],
) -> Option<ToMeasureAgain> {
    to_measure_again_judged(
        set,
        settings,
        settings.reading_noise_arcsec,
        (setup, cycle),
        handled,
    )
}

/// [`to_measure_again`] with σ's floor from `reading_noise_arcsec`, the noise of one
/// reading the run judges by (the loop's: the largest of the autocollimators'
/// [`super::RepeatNoise::sigma_used_arcsec`], never above the stated noise), over
/// √`reads`; `(setup, cycle)` as there.
pub fn to_measure_again_judged(
    set: &MeasurementSet,
    settings: &RunSettings,
    reading_noise_arcsec: f64,
    (setup, cycle): (u32, u32),
    handled: &[Cell],
) -> Option<ToMeasureAgain> {
    let fit = fit(set, settings, reading_noise_arcsec)?;
    let offsets = summary(set, Some(&fit), setup, cycle).offsets;
    let index = worst(&fit, setup, handled, &offsets)?;
    Some(ToMeasureAgain {
        index,
        residual_arcsec: fit.residuals[index],
        leverage: fit.leverage[index],
        studentized_arcsec: fit.studentized(index)?,
        sigma_arcsec: fit.sigma,
    })
}

/// The summary of a cycle whose file could not be read back: nothing but its number.
pub(super) fn unchecked(setup: u32, cycle: u32) -> CycleCheck {
    CycleCheck {
        setup,
        cycle,
        closure_arcsec: Vec::new(),
        residual_rms_arcsec: None,
        previous_residual_rms_arcsec: None,
        sigma_arcsec: None,
        remeasured: Vec::new(),
        suspect: Vec::new(),
        warnings: Vec::new(),
        offsets: Vec::new(),
        misfit: None,
    }
}

/// The summary of `cycle` of mounting `setup`: closure, residual RMS against the cycles
/// before (those of the earlier mountings included), the noise, and the warnings (the
/// lists of readings measured again are the loop's to fill).
pub(super) fn summary(
    set: &MeasurementSet,
    fit: Option<&Fit>,
    setup: u32,
    cycle: u32,
) -> CycleCheck {
    let this = |r: &Reading| r.setup == setup && r.cycle == cycle;
    let mut closure_arcsec = Vec::new();
    let faces = set.faces;
    let mut acs: Vec<u32> = set.readings.iter().map(|r| r.ac).collect();
    acs.sort_unstable();
    acs.dedup();
    for &ac in &acs {
        let at = |step: usize| {
            set.readings
                .iter()
                .find(|r| this(r) && r.ac == ac && r.step == step)
                .map(|r| r.reading_arcsec)
        };
        if let (Some(last), Some(first)) = (at(faces), at(0)) {
            closure_arcsec.push((ac, last - first));
        }
    }
    let mut check = CycleCheck {
        closure_arcsec,
        ..unchecked(setup, cycle)
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
    check.residual_rms_arcsec = rms(&this);
    check.previous_residual_rms_arcsec =
        rms(&|r| r.setup < setup || (r.setup == setup && r.cycle < cycle));
    check.sigma_arcsec = Some(fit.sigma);
    if let Some(warning) = mounting_misfit(set, fit, setup) {
        check.warnings.push(warning.clone());
        check.misfit = Some(warning);
    }
    if cycle >= 2 {
        for &ac in &acs {
            let (sum, n) = fit
                .readings
                .iter()
                .zip(&fit.residuals)
                .filter(|(r, _)| this(r) && r.ac == ac)
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
        let fit = fit(&set, &settings(), 0.05).unwrap();
        let i = worst(&fit, 1, &[], &[]).unwrap();
        let r = &fit.readings[i];
        assert_eq!((r.cycle, r.step, r.ac), (2, 5, 1));
        // Handled, nothing else stands out.
        assert_eq!(worst(&fit, 1, &[cell(r)], &[]), None);
        // Not in the mounting on the table now.
        assert_eq!(worst(&fit, 2, &[], &[]), None);
    }

    #[test]
    fn a_clean_run_has_nothing_to_measure_again_and_no_warning() {
        let set = run_set(None);
        let fit = fit(&set, &settings(), 0.05).unwrap();
        assert_eq!(worst(&fit, 1, &[], &[]), None);
        let check = summary(&set, Some(&fit), 1, 3);
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
        let fit = fit(&set, &settings(), 0.05).unwrap();
        let check = summary(&set, Some(&fit), 1, 3);
        assert_eq!(check.warnings.len(), 1, "{:?}", check.warnings);
        assert!(check.warnings[0].starts_with("autocollimator 2:"));
        assert_eq!(check.offsets, [(3, 2)]);
        // Its readings are not chased one by one.
        assert_eq!(worst(&fit, 1, &[], &check.offsets), None);
    }

    #[test]
    fn a_second_mounting_between_the_stops_is_checked_too() {
        let config = SimulationConfig {
            faces: 8,
            cycles: 2,
            closing: true,
            noise_arcsec: 0.05,
            setups: 2,
            table_shift_deg: vec![0.0, 22.5],
            seed: 5,
            ..SimulationConfig::default()
        };
        let (mut set, _) = simulate(&config).unwrap();
        for r in &mut set.readings {
            if (r.setup, r.cycle, r.step, r.ac) == (2, 2, 3, 2) {
                r.reading_arcsec += 2.0;
            }
        }
        let settings = RunSettings::new(8, 2)
            .with_closing(true)
            .with_reading_noise_arcsec(0.05);
        let fit = fit(&set, &settings, 0.05).expect("a fit of two mountings");
        let i = worst(&fit, 2, &[], &[]).unwrap();
        let r = &fit.readings[i];
        assert_eq!((r.setup, r.cycle, r.step, r.ac), (2, 2, 3, 2));
        // The first mounting is off the table: nothing of it is measured again.
        assert_eq!(worst(&fit, 1, &[], &[]), None);
        let check = summary(&set, Some(&fit), 2, 2);
        assert_eq!((check.setup, check.closure_arcsec.len()), (2, 2));
        assert!(check.residual_rms_arcsec.is_some());
        // One reading off does not make the mounting a misfit…
        assert_eq!(mounting_misfit(&set, &fit, 2), None, "{:?}", check.warnings);
        // … the polygon mounted one face off from what the run was told does.
        for r in &mut set.readings {
            if r.setup == 2 {
                r.face = r.face % 8 + 1;
            }
        }
        let fit = super::fit(&set, &settings, 0.05).unwrap();
        let warning = mounting_misfit(&set, &fit, 2).expect("a misfit");
        assert!(
            warning.starts_with(
                "the readings of mounting 2 do not fit those of the mountings before it"
            ),
            "{warning}"
        );
    }

    /// The leverages are those of the fit the check judges by: the diagonal of its hat
    /// matrix sums to its parameters (readings minus residual degrees of freedom), and
    /// `diagnose`'s fit of the same model leaves the same residuals. In the 3-cycle design
    /// a reading's leverage is 1/2 after cycle 2 and 1/3 after cycle 3 (1/4 and 1/6 at the
    /// first and closing steps, which share their position).
    #[test]
    fn the_leverages_are_those_of_the_fit_judged() {
        let set = run_set(None);
        for (cycle, inner) in [(2u32, 0.5), (3, 1.0 / 3.0)] {
            let mut on_disk = set.clone();
            on_disk.readings.retain(|r| r.cycle <= cycle);
            let solution = solved(&on_disk).unwrap();
            let h = leverage(&on_disk).unwrap();
            let parameters = (on_disk.readings.len() - solution.dof) as f64;
            assert!((h.iter().sum::<f64>() - parameters).abs() < 1e-9);
            let base = Base::of(&on_disk);
            let again = base.fit(&[], None).unwrap();
            for (a, b) in again.residuals.iter().zip(&solution.residuals) {
                assert!((a - b).abs() < 1e-12, "{a} {b}");
            }
            for (r, h) in on_disk.readings.iter().zip(&h) {
                let want = if r.step % 12 == 0 { inner / 2.0 } else { inner };
                assert!(
                    (h - want).abs() < 1e-9,
                    "cycle {cycle}, step {}: {h}",
                    r.step
                );
            }
        }
    }

    /// An honest reading's studentized residual has the noise's own σ whatever its
    /// leverage, which makes the limit 6σ a rate of 2Φ(−6) per reading and check: over
    /// 4 000 clean 3-cycle runs (312 000 readings at the check after cycle 3) the fractions
    /// beyond 2.5σ and 3σ are the normal's, 2Φ(−2.5) = 0.0124 and 2Φ(−3) = 0.0027, within
    /// 4 binomial standard deviations. The raw residuals, of σ·√(1 − h), fall beyond them
    /// in about 0.003 and 0.0004: far outside these bounds.
    #[test]
    fn honest_studentized_residuals_have_the_noises_sigma() {
        let sigma = 0.05;
        let (mut judged, mut beyond_2_5, mut beyond_3) = (0usize, 0usize, 0usize);
        let mut ms = 0.0;
        for seed in 1..=4000 {
            let config = SimulationConfig {
                faces: 12,
                cycles: 3,
                closing: true,
                noise_arcsec: sigma,
                seed,
                ..SimulationConfig::default()
            };
            let (set, _) = simulate(&config).unwrap();
            let fit = fit(&set, &settings(), 0.05).unwrap();
            for t in (0..set.readings.len()).filter_map(|i| fit.studentized(i)) {
                judged += 1;
                ms += t * t;
                beyond_2_5 += usize::from(t.abs() > 2.5 * sigma);
                beyond_3 += usize::from(t.abs() > 3.0 * sigma);
            }
        }
        assert_eq!(judged, 4000 * 78);
        println!(
            "studentized residuals beyond 2.5σ: {beyond_2_5}, beyond 3σ: {beyond_3} of {judged}, mean square {}",
            ms / judged as f64 / sigma / sigma
        );
        let n = judged as f64;
        for (count, p) in [(beyond_2_5, 0.012_419), (beyond_3, 0.002_700)] {
            let sd = (n * p * (1.0 - p)).sqrt();
            assert!(
                (count as f64 - n * p).abs() <= 4.0 * sd,
                "{count} of {judged} beyond, nominal {:.1}",
                n * p
            );
        }
    }

    /// A reading that determines its own fitted value (leverage 1: the only reading of
    /// its autocollimator) has a residual of 0 whatever it read: it is not judged, and
    /// the others are judged as before.
    #[test]
    fn a_reading_of_leverage_one_is_never_flagged() {
        let mut set = run_set(None);
        set.readings.retain(|r| r.cycle <= 2);
        let mut alone = set.readings[5].clone();
        alone.ac = 3;
        alone.reading_arcsec += 100.0;
        set.readings.push(alone);
        let fit = fit(&set, &settings(), 0.05).expect("a fit");
        let last = set.readings.len() - 1;
        assert!(fit.leverage[last] > 1.0 - 1e-9, "{}", fit.leverage[last]);
        assert_eq!(fit.studentized(last), None);
        assert!(!fit.beyond(last));
        assert_eq!(worst(&fit, 1, &[], &[]), None);
        let judged = (0..set.readings.len())
            .filter(|&i| fit.studentized(i).is_some())
            .count();
        assert_eq!(judged, set.readings.len() - 1);
    }

    /// A reading 8σ off, judged by the check after cycle 3 of the 3-cycle design (the
    /// other readings without noise, σ the stated one): its residual is shrunk to
    /// (1 − h)·8σ = 5.3σ and would pass, its studentized residual √(1 − h)·8σ = 6.5σ does
    /// not.
    #[test]
    fn a_reading_eight_sigma_off_is_judged_by_its_studentized_residual() {
        let config = SimulationConfig {
            faces: 12,
            cycles: 3,
            closing: true,
            noise_arcsec: 0.0,
            seed: 3,
            ..SimulationConfig::default()
        };
        let (mut set, _) = simulate(&config).unwrap();
        // The stored reading's σ: the stated 0.05″ of one reading over √2 readings.
        let sigma = 0.05 / 2f64.sqrt();
        for r in &mut set.readings {
            if (r.cycle, r.step, r.ac) == (2, 5, 1) {
                r.reading_arcsec += 8.0 * sigma;
            }
        }
        let fit = fit(&set, &settings(), 0.05).unwrap();
        assert!((fit.sigma - sigma).abs() < 1e-15, "{}", fit.sigma);
        let i = worst(&fit, 1, &[], &[]).expect("found");
        let r = &fit.readings[i];
        assert_eq!((r.cycle, r.step, r.ac), (2, 5, 1));
        assert!(fit.residuals[i].abs() < OUTLIER_SIGMAS * fit.sigma);
        let flag = to_measure_again(&set, &settings(), 1, 3, &[]).unwrap();
        assert_eq!(flag.index, i);
        assert!((flag.leverage - 1.0 / 3.0).abs() < 1e-9);
        assert!(
            (flag.studentized_arcsec - flag.residual_arcsec / (2.0f64 / 3.0).sqrt()).abs() < 1e-12
        );
    }
}
