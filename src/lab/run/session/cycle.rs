//! The check after a cycle (module `live`): the run as kept is fitted, the stop of the
//! reading furthest beyond the run's noise is measured again (at most
//! [`MAX_REMEASURED_PER_CYCLE`] stops, each cell once a session), and the reading of
//! that stop's cell that disagrees with the new one (the flagged reading or, with two
//! cycles, its twin) is replaced, or the flagged reading named suspect when none does.
//! Then the noise the run judged by, a mounting's misfit and the check itself are kept.

use super::super::live::{self, MAX_REMEASURED_PER_CYCLE, Remeasured, Suspect};
use super::super::repeat::DeviceMemory;
use super::super::store::Record;
use super::super::store::key;
use super::super::verify::stop_of;
use super::super::{RepeatNoise, RunSettings};
use super::visit::{Again, Purpose, Visit};
use super::{Action, Session, Step};
use crate::measurement::{MeasurementSet, Reading};

/// The check after one cycle, between its rounds.
#[derive(Debug, Clone)]
pub(in crate::lab::run) struct CycleChecking {
    cycle: u32,
    round: usize,
    /// The (cycle, autocollimator) pairs whose readings sit off as a whole.
    offsets: Vec<(u32, u32)>,
    remeasured: Vec<Remeasured>,
    suspect: Vec<Suspect>,
}

impl CycleChecking {
    /// The check after `cycle`, before its first round.
    pub(super) fn new(cycle: u32) -> CycleChecking {
        CycleChecking {
            cycle,
            round: 0,
            offsets: Vec::new(),
            remeasured: Vec::new(),
            suspect: Vec::new(),
        }
    }
}

/// The noise of one reading the live check judges by: the largest of the
/// autocollimators' [`RepeatNoise::sigma_used_arcsec`] (each the stated noise until its
/// repeats show less), so that no autocollimator's readings are judged by another's
/// smaller noise.
fn judged_noise(memory: &[DeviceMemory], settings: &RunSettings) -> f64 {
    let stated = settings.reading_noise_arcsec;
    if memory.is_empty() {
        return stated;
    }
    memory
        .iter()
        .map(|m| m.noise.sigma_used_arcsec(stated))
        .fold(0.0, f64::max)
        .min(stated)
        .max(f64::MIN_POSITIVE)
}

impl Session {
    /// The readings kept, as a measurement set of the run's mountings (`None` when they
    /// do not make one yet).
    fn kept_set(&self) -> Option<MeasurementSet> {
        let run = &self.kept.run;
        let set =
            MeasurementSet::from_readings(run.readings.clone(), Some(self.settings.faces), "run")
                .ok()?;
        let shifts: Vec<(u32, f64)> = run
            .mountings
            .iter()
            .map(|m| (m.mounting.setup, m.mounting.shift_deg))
            .filter(|&(setup, shift)| shift != 0.0 && run.readings.iter().any(|r| r.setup == setup))
            .collect();
        set.with_setup_shifts(shifts).ok()
    }

    /// The check's next round: a reading to measure again, or the check's end.
    pub(super) fn check_next(&mut self, mut c: CycleChecking) -> Step {
        let setup = self.mounting.setup;
        let set = self.kept_set();
        let judged = judged_noise(&self.memory, &self.settings);
        if let Some(set) = &set {
            let fit = live::fit(set, &self.settings, judged);
            if c.round == 0 {
                c.offsets = live::summary(set, fit.as_ref(), setup, c.cycle).offsets;
            }
            if let Some(fit) = fit
                && c.round < MAX_REMEASURED_PER_CYCLE
                && let Some(i) = live::worst(&fit, setup, &self.handled, &c.offsets)
            {
                let flagged = fit.readings[i].clone();
                let residual = fit.residuals[i];
                self.handled.push(live::cell(&flagged));
                let stop = stop_of(&flagged);
                let ac = flagged.ac;
                let again = Again {
                    check: c,
                    fit,
                    flagged,
                    residual,
                };
                return self.start_visit(Visit::new(
                    Purpose::Again(Box::new(again)),
                    stop,
                    vec![ac],
                ));
            }
        }
        let mut check = match &set {
            Some(set) => live::summary(
                set,
                live::fit(set, &self.settings, judged).as_ref(),
                setup,
                c.cycle,
            ),
            None => live::unchecked(setup, c.cycle),
        };
        check.remeasured = c.remeasured;
        check.suspect = c.suspect;
        let noise: Vec<RepeatNoise> = self.memory.iter().map(|m| m.noise).collect();
        let mut records = vec![Record::Noise(noise)];
        if let Some(warning) = &check.misfit {
            records.push(Record::Misfit(warning.clone()));
        }
        records.push(Record::Checked { cycle: c.cycle });
        let last = self
            .settings
            .plan()
            .into_iter()
            .rfind(|s| s.cycle == c.cycle);
        let notes = match last {
            Some(stop) => vec![Action::Progress(self.progress(stop, Some(check)))],
            None => Vec::new(),
        };
        Step::Keeping {
            records: records.into(),
            notes,
            then: Box::new(Step::NextWork),
        }
    }

    /// A flagged reading's stop measured again (`again`): the reading of the cell
    /// furthest from the new one is replaced if it disagrees beyond the tolerance of the
    /// autocollimator's measured noise for two means of `reads` readings (the tolerance
    /// of two single readings ÷ √reads), each compared with the table's offset from the stop taken
    /// out (a table that stopped within its tolerance but off the stop is no fault of the
    /// reading); when none disagrees, the cell's reading furthest from the new one is
    /// named suspect.
    pub(super) fn judge_again(&mut self, a: Again, again: Reading) -> Step {
        let Again {
            mut check,
            fit,
            flagged,
            residual,
        } = a;
        let settings = &self.settings;
        // Two means of `reads` readings each differ by √reads less than two readings do.
        let tolerance = self
            .memory
            .get(flagged.ac as usize - 1)
            .map_or(settings.agreement_arcsec(), |m| {
                m.noise.agreement_arcsec(settings.reading_noise_arcsec)
            })
            / f64::from(settings.reads_per_stop.max(2)).sqrt();
        let shift_deg = self.mounting.shift_deg;
        let at_stop =
            |r: &Reading| r.reading_arcsec - live::stop_offset_arcsec(r, settings.faces, shift_deg);
        let apart = |r: &Reading| (at_stop(r) - at_stop(&again)).abs();
        let furthest = fit
            .readings
            .iter()
            .filter(|r| live::cell(r) == live::cell(&flagged))
            .max_by(|a, b| apart(a).total_cmp(&apart(b)))
            .cloned();
        let off = furthest.clone().filter(|r| apart(r) > tolerance);
        let residual_of = |r: &Reading| {
            fit.readings
                .iter()
                .position(|f| key(f) == key(r))
                .map_or(residual, |j| fit.residuals[j])
        };
        let record = match off {
            Some(first) => {
                let residual_of_first = residual_of(&first);
                let replacement = Reading {
                    cycle: first.cycle,
                    ..again
                };
                let remeasured = Remeasured {
                    setup: first.setup,
                    cycle: first.cycle,
                    step: first.step,
                    ac: first.ac,
                    first_arcsec: first.reading_arcsec,
                    reading_arcsec: replacement.reading_arcsec,
                    residual_arcsec: residual_of_first,
                    sigma_arcsec: fit.sigma,
                    found_after_cycle: check.cycle,
                };
                self.log(
                    "remeasured",
                    format!(
                        "cycle {}, step {}, autocollimator {}: {}″ replaced by {}″ (residual {:+.4}″, σ {:.4}″)",
                        first.cycle,
                        first.step,
                        first.ac,
                        first.reading_arcsec,
                        replacement.reading_arcsec,
                        residual_of_first,
                        fit.sigma
                    ),
                );
                check.remeasured.push(remeasured.clone());
                Record::Replacement {
                    first,
                    replacement,
                    remeasured,
                }
            }
            None => {
                // The reading of the cell furthest from the stop measured again is named:
                // where the check cannot tell which of a cell's readings is off (two
                // readings after cycle 2 have residuals equal and opposite), the reading
                // measured again can.
                let named = furthest.unwrap_or(flagged);
                let suspect = Suspect {
                    setup: named.setup,
                    cycle: named.cycle,
                    step: named.step,
                    ac: named.ac,
                    reading_arcsec: named.reading_arcsec,
                    measured_again_arcsec: again.reading_arcsec,
                    residual_arcsec: residual_of(&named),
                    sigma_arcsec: fit.sigma,
                    found_after_cycle: check.cycle,
                };
                check.suspect.push(suspect.clone());
                Record::Suspect(suspect)
            }
        };
        check.round += 1;
        Step::Keeping {
            records: [record].into(),
            notes: Vec::new(),
            then: Box::new(Step::Check(Box::new(check))),
        }
    }
}
