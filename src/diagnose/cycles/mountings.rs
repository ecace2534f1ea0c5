//! A whole mounting against the others (docs/FORMAT.md §5, `mountings`): in a run of at
//! least [`MIN_MOUNTINGS`] mountings, each is tested against the rest as one decision per
//! run at [`MOUNTING_ALPHA`] (Bonferroni over the mountings). A logging error that
//! touches every cycle of a mounting alike (its autocollimators' columns exchanged, its
//! faces labelled one round, every reading one stop late) leaves the mounting at one
//! with itself, so the test of a cycle against its own mounting ([`super`]) cannot see
//! it; only the other mountings can.
//!
//! The statistic is the Chow F of the base model (`solve`'s closure model): the fit of
//! every reading against the mounting and the others each fitted on its own,
//!
//! F = [(RSS_all − RSS_m − RSS_rest) / (dof_all − dof_m − dof_rest)] / [(RSS_m + RSS_rest) / (dof_m + dof_rest)],
//!
//! exactly F-distributed when the base model holds with one σ. A mounting that disagrees
//! is tried against the usual logging errors applied to every one of its cycles; the one
//! whose undoing makes it agree, when it is the only one, is named and undone; none: the
//! mounting is left to the search (a drift or a jump of that mounting also sets it apart
//! from a model without them) and tested again on the final model's residuals; still
//! disagreeing grossly ([`super::GROSS_F`]), it is set aside and the verdict is not
//! adequate. Runs with shifted mountings are not tested (their encoder positions differ
//! from one mounting to the next by design).

use std::collections::BTreeSet;

use super::causes::{self, CycleCause};
use super::test::f_test;
use super::{CycleAction, GROSS_F, MIN_REST_DOF, SetAsideReading, aside_readings, left_the_fit};
use crate::diagnose::Diagnosis;
use crate::diagnose::base::Base;
use crate::measurement::MeasurementSet;

/// False-alarm probability of the mounting test for a whole run: each of the m mountings
/// is judged at `MOUNTING_ALPHA / m` (Bonferroni). Measured on clean runs in
/// docs/verdicts.md.
pub const MOUNTING_ALPHA: f64 = 0.01;

/// The fewest mountings a run needs for its mountings to be tested (with two, the one
/// that disagrees cannot be told from the other).
pub const MIN_MOUNTINGS: usize = 3;

/// A mounting that disagrees with the others.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct MountingFinding {
    /// The mounting.
    pub setup: u32,
    /// Chow F of the mounting as logged against the others (module documentation).
    pub f_statistic: f64,
    /// Its numerator degrees of freedom.
    pub dof_numerator: usize,
    /// Its denominator degrees of freedom.
    pub dof_denominator: usize,
    /// Its p-value.
    pub p_value: f64,
    /// The level each mounting is judged at: [`MOUNTING_ALPHA`] over the mountings.
    pub level: f64,
    /// The logging error that explains it, or [`CycleCause::Unexplained`].
    pub cause: CycleCause,
    /// Causes that explain it equally well (then `cause` is unexplained and the mounting
    /// set aside).
    pub alternatives: Vec<CycleCause>,
    /// The F and p of the mounting with its cause undone (repaired mountings).
    pub repaired: Option<(f64, f64)>,
    /// What was done.
    pub action: CycleAction,
    /// The readings that left the fit with it, with the reason.
    pub set_aside: Vec<SetAsideReading>,
}

/// One mounting's test: F, its degrees of freedom and p.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Chow {
    f_statistic: f64,
    dof_numerator: usize,
    dof_denominator: usize,
    p_value: f64,
}

/// The readings of `set` that `keep` keeps, each with its value from `values`.
fn part(set: &MeasurementSet, values: &[f64], keep: impl Fn(u32) -> bool) -> MeasurementSet {
    let readings = set
        .readings
        .iter()
        .zip(values)
        .filter(|(r, _)| keep(r.setup))
        .map(|(r, v)| {
            let mut r = r.clone();
            r.reading_arcsec = *v;
            r
        })
        .collect();
    MeasurementSet {
        faces: set.faces,
        readings,
        source: set.source.clone(),
        setup_shift_deg: set.setup_shift_deg.clone(),
    }
}

/// The base model's fit of `set`: RSS and degrees of freedom.
fn base_fit(set: &MeasurementSet) -> Option<(f64, usize)> {
    let fit = Base::of(set).fit(&[], None).ok()?;
    (fit.rss.is_finite() && fit.dof > 0).then_some((fit.rss, fit.dof))
}

/// The test of mounting `setup` of `set` (with `values` in place of the readings) against
/// the others, from the fit of all of them, `all`. On a final model's residuals, `added`
/// is the number of parameters the search added to the base model: they are in `all`'s
/// degrees of freedom and are taken from the denominator's (0 before the search).
fn chow(
    set: &MeasurementSet,
    values: &[f64],
    setup: u32,
    all: (f64, usize),
    added: usize,
) -> Option<Chow> {
    let (rss_m, dof_m) = base_fit(&part(set, values, |s| s == setup))?;
    let (rss_rest, dof_rest) = base_fit(&part(set, values, |s| s != setup))?;
    let dof_numerator = (all.1 + added).checked_sub(dof_m + dof_rest)?;
    let dof_denominator = (dof_m + dof_rest).checked_sub(added)?;
    if dof_numerator == 0 || dof_denominator < MIN_REST_DOF {
        return None;
    }
    let rss_apart = rss_m + rss_rest;
    let (f_statistic, p_value) = f_test(
        (all.0 - rss_apart).max(0.0),
        dof_numerator,
        rss_apart,
        dof_denominator,
    );
    Some(Chow {
        f_statistic,
        dof_numerator,
        dof_denominator,
        p_value,
    })
}

/// The mountings of `set` that are tested: all, when there are [`MIN_MOUNTINGS`] or more
/// and none is shifted.
fn tested(set: &MeasurementSet) -> Vec<u32> {
    let setups: BTreeSet<u32> = set.readings.iter().map(|r| r.setup).collect();
    if setups.len() < MIN_MOUNTINGS || !set.setup_shift_deg.is_empty() {
        return Vec::new();
    }
    setups.into_iter().collect()
}

/// The test of every mounting of `set` as logged.
fn tests(set: &MeasurementSet, mountings: &[u32]) -> Vec<(u32, Chow)> {
    let values: Vec<f64> = set.readings.iter().map(|r| r.reading_arcsec).collect();
    let Some(all) = base_fit(set) else {
        return Vec::new();
    };
    mountings
        .iter()
        .filter_map(|&m| Some((m, chow(set, &values, m, all, 0)?)))
        .collect()
}

/// The mountings of `set` that disagree with the others at the run's level, as logged and
/// before any repair: (setup, F, p), the decision whose false-alarm rate is
/// [`MOUNTING_ALPHA`] per run (docs/verdicts.md).
pub fn disagreeing_mountings(set: &MeasurementSet) -> Vec<(u32, f64, f64)> {
    let mountings = tested(set);
    let level = MOUNTING_ALPHA / mountings.len().max(1) as f64;
    tests(set, &mountings)
        .into_iter()
        .filter(|(_, t)| t.p_value < level)
        .map(|(m, t)| (m, t.f_statistic, t.p_value))
        .collect()
}

/// The causes tried on a whole mounting: the usual logging errors of its cycles, applied
/// to every cycle alike.
fn candidates(set: &MeasurementSet, setup: u32) -> Vec<CycleCause> {
    let mut acs: Vec<u32> = set
        .readings
        .iter()
        .filter(|r| r.setup == setup)
        .map(|r| r.ac)
        .collect();
    acs.sort_unstable();
    acs.dedup();
    causes::of_autocollimators(&acs)
}

/// `set` with `cause` undone in every cycle of mounting `setup`, and the readings the
/// repair leaves without a stop; `None` when some cycle cannot be undone.
fn repair(
    set: &MeasurementSet,
    setup: u32,
    cause: CycleCause,
) -> Option<(MeasurementSet, Vec<SetAsideReading>)> {
    if let CycleCause::FacesShifted { by } = cause {
        // the mounting's face labels one round: every reading of it relabelled alike
        let n = set.faces as i64;
        let mut repaired = set.clone();
        for r in repaired.readings.iter_mut().filter(|r| r.setup == setup) {
            r.face = ((r.face as i64 - 1 + by).rem_euclid(n) + 1) as usize;
        }
        return Some((repaired, Vec::new()));
    }
    let cycles: BTreeSet<u32> = set
        .readings
        .iter()
        .filter(|r| r.setup == setup)
        .map(|r| r.cycle)
        .collect();
    let mut current = set.clone();
    let mut aside = Vec::new();
    for cycle in cycles {
        let (next, left) = causes::repair(&current, setup, cycle, cause)?;
        aside.extend(aside_readings(
            &current,
            &left,
            &format!(
                "{} in every cycle of setup {setup}: the value left without a stop of cycle {cycle} when the readings are moved to the stops they belong to",
                cause.as_str()
            ),
        ));
        current = next;
    }
    Some((current, aside))
}

fn finding(setup: u32, logged: Chow, level: f64) -> MountingFinding {
    MountingFinding {
        setup,
        f_statistic: logged.f_statistic,
        dof_numerator: logged.dof_numerator,
        dof_denominator: logged.dof_denominator,
        p_value: logged.p_value,
        level,
        cause: CycleCause::Unexplained,
        alternatives: Vec::new(),
        repaired: None,
        action: CycleAction::SetAside,
        set_aside: Vec::new(),
    }
}

/// `set` without mounting `setup`, and its readings as set aside with `reason`.
fn without(
    set: &MeasurementSet,
    setup: u32,
    reason: &str,
) -> (MeasurementSet, Vec<SetAsideReading>) {
    let indices: Vec<usize> = (0..set.readings.len())
        .filter(|&i| set.readings[i].setup == setup)
        .collect();
    let values: Vec<f64> = set.readings.iter().map(|r| r.reading_arcsec).collect();
    (
        part(set, &values, |s| s != setup),
        aside_readings(set, &indices, reason),
    )
}

/// The readings after the mountings' test and repairs, what was found, and the mountings
/// left for the search (with their test as logged).
pub(super) struct Examined {
    pub set: MeasurementSet,
    pub findings: Vec<MountingFinding>,
    pending: Vec<(u32, Chow)>,
    level: f64,
}

/// Tests every mounting; repairs or sets aside the one a logging error explains (one at
/// a time, the most disagreeing first, the others tested again after each).
pub(super) fn examine(set: MeasurementSet) -> Examined {
    let mountings = tested(&set);
    let level = MOUNTING_ALPHA / mountings.len().max(1) as f64;
    let mut current = set;
    let mut handled = BTreeSet::new();
    let mut findings = Vec::new();
    let mut pending = Vec::new();
    let mut logged = tests(&current, &mountings);
    loop {
        let worst = logged
            .iter()
            .filter(|(m, t)| !handled.contains(m) && t.p_value < level)
            .max_by(|a, b| a.1.f_statistic.total_cmp(&b.1.f_statistic))
            .copied();
        let Some((setup, test)) = worst else {
            break;
        };
        handled.insert(setup);
        let explaining: Vec<(CycleCause, Chow, MeasurementSet, Vec<SetAsideReading>)> =
            candidates(&current, setup)
                .into_iter()
                .filter_map(|cause| {
                    let (repaired, aside) = repair(&current, setup, cause)?;
                    let values: Vec<f64> =
                        repaired.readings.iter().map(|r| r.reading_arcsec).collect();
                    let all = base_fit(&repaired)?;
                    let t = chow(&repaired, &values, setup, all, 0)?;
                    (t.p_value >= level).then_some((cause, t, repaired, aside))
                })
                .collect();
        let mut found = finding(setup, test, level);
        match explaining.len() {
            0 => pending.push((setup, test)),
            n if n > 1 && test.f_statistic < GROSS_F => pending.push((setup, test)),
            1 => {
                let Some((cause, t, repaired, aside)) = explaining.into_iter().next() else {
                    continue;
                };
                found.cause = cause;
                found.repaired = Some((t.f_statistic, t.p_value));
                found.action = CycleAction::Repaired;
                found.set_aside = aside;
                current = repaired;
                logged = tests(&current, &mountings);
                findings.push(found);
            }
            _ => {
                found.alternatives = explaining.iter().map(|e| e.0).collect();
                let names: Vec<&str> = found.alternatives.iter().map(|c| c.as_str()).collect();
                let (rest, aside) = without(
                    &current,
                    setup,
                    &format!(
                        "setup {setup} set aside: {} explain it equally well",
                        names.join(" and ")
                    ),
                );
                found.set_aside = aside;
                current = rest;
                logged = tests(&current, &mountings);
                findings.push(found);
            }
        }
    }
    Examined {
        set: current,
        findings,
        pending,
        level,
    }
}

impl Examined {
    /// Of the pending mountings, the one that disagrees most on the final model's
    /// residuals of `diagnosis` (of `self.set`), when it still disagrees grossly: set aside
    /// from `self.set` and listed; whether one was. One at a time: a mounting that
    /// disagrees pulls the fit of the others, which are tested again on the diagnosis
    /// without it.
    pub(super) fn set_aside_worst(&mut self, diagnosis: &Diagnosis) -> bool {
        let residuals = &diagnosis.after.residuals;
        // (a weighted diagnosis's RSS is of whitened residuals: not compared here)
        let weighted = diagnosis.noise.as_ref().is_some_and(|n| n.weighted);
        if self.pending.is_empty() || residuals.len() != self.set.readings.len() || weighted {
            return false;
        }
        // (with fewer mountings left, which one disagrees is not decided)
        let mut setups: Vec<u32> = self.set.readings.iter().map(|r| r.setup).collect();
        setups.sort_unstable();
        setups.dedup();
        if setups.len() < MIN_MOUNTINGS {
            return false;
        }
        // the parameters the search added (an outlier's among them: its residual is 0)
        let Some(added) = diagnosis.before.dof.checked_sub(diagnosis.after.dof) else {
            return false;
        };
        let all = (diagnosis.after.rss, diagnosis.after.dof);
        let worst = self
            .pending
            .iter()
            .enumerate()
            .filter_map(|(k, &(setup, _))| {
                let t = chow(&self.set, residuals, setup, all, added)?;
                (t.p_value < self.level && t.f_statistic >= GROSS_F).then_some((k, t.f_statistic))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((k, _)) = worst else {
            return false;
        };
        let (setup, logged) = self.pending.remove(k);
        let (rest, aside) = without(
            &self.set,
            setup,
            &format!(
                "setup {setup} set aside: it disagrees with the other mountings, no usual logging error explains it, and no effect the search found does"
            ),
        );
        let mut found = finding(setup, logged, self.level);
        found.set_aside = aside;
        self.findings.push(found);
        self.set = rest;
        true
    }
}

/// The finding in words.
pub(super) fn note(found: &MountingFinding) -> String {
    let head = format!(
        "Setup {} disagrees with the other mountings (F = {:.1} on {} and {} degrees of freedom, p = {:.1e}, level {:.1e} per mounting)",
        found.setup,
        found.f_statistic,
        found.dof_numerator,
        found.dof_denominator,
        found.p_value,
        found.level
    );
    let aside = left_the_fit(found.set_aside.len());
    match found.action {
        CycleAction::Repaired => format!(
            "{head}: {} in every one of its cycles explains it exactly (undone, the mounting agrees: F = {:.2}); it is evaluated with it undone.{aside}",
            found.cause.describe(),
            found.repaired.map_or(f64::NAN, |r| r.0),
        ),
        CycleAction::SetAside if !found.alternatives.is_empty() => {
            let names: Vec<String> = found.alternatives.iter().map(|c| c.describe()).collect();
            format!(
                "{head}: {} explain it equally well, so neither is a finding; the mounting is set aside and the calibration is not certified as adequate.{aside}",
                names.join(" and ")
            )
        }
        CycleAction::SetAside => format!(
            "{head}: no usual logging error of the whole mounting explains it, nor any effect found; the mounting is set aside and the calibration is not certified as adequate. Check that mounting's log.{aside}"
        ),
    }
}
