//! A cycle against the others (docs/FORMAT.md §5, `cycles`): every cycle of every
//! mounting with at least [`MIN_CYCLES`] cycles is tested against the rest of its
//! mounting, as one decision per run at [`CYCLE_ALPHA`] (Bonferroni over the cycles
//! tested). The statistic is the exact Chow F of the cycle × stop interaction
//! ([`test`]): it needs no model fit and sees nothing that is the same at a stop in every
//! cycle, so a zero set anew every cycle, a direction offset or a linear drift of a
//! clockwise run do not trigger it.
//!
//! A cycle that disagrees is tried against the usual logging errors ([`CycleCause`]):
//! the one whose undoing makes the cycle agree with the rest at the same level, when it
//! is the only one, is named and undone (`repaired`); two or more that do so are named
//! and the cycle is set aside (the verdict is then not adequate). When none does, the
//! cycle is kept for the search (a jump inside it, a drift of a counter-clockwise cycle
//! or one bad reading also break the additivity), and tested again on the final model's
//! residuals (a handful of outliers of the cycle counted as found, more put back: a
//! cycle that disagrees as a whole is not removed reading by reading); still
//! disagreeing, and grossly ([`GROSS_F`]), it is set aside as `unexplained`, the search
//! run again without it, and the verdict is not adequate (a milder disagreement no cause
//! explains is left to the search's own checks and not listed). `before` stays the fit of the readings as logged.
//!
//! Self-calibration runs are not tested (their diagnosis goes through
//! [`super::selfcal`]). Whole mountings are tested against each other after the cycles
//! ([`mountings`]).

mod causes;
pub mod mountings;
mod table;
mod test;

use std::collections::{BTreeMap, BTreeSet};

pub use causes::CycleCause;
use table::{Entry, Table};
use test::{Chow, chow, chow_of, sum};

use super::base::Base;
use super::residuals::Check;
use super::{DiagnoseOptions, Diagnosis};
use crate::effects::Effect;
use crate::measurement::MeasurementSet;
use crate::solve::SolveError;

/// False-alarm probability of the cycle test for a whole run: each of the m cycles tested
/// is judged at `CYCLE_ALPHA / m` (Bonferroni). Measured on clean runs in
/// docs/verdicts.md.
pub const CYCLE_ALPHA: f64 = 0.01;

/// The fewest cycles a mounting needs for its cycles to be tested (with two, the one that
/// disagrees cannot be told from the other).
pub const MIN_CYCLES: usize = 3;

/// The fewest degrees of freedom the other cycles must leave for a test.
pub(super) const MIN_REST_DOF: usize = 10;

/// The smallest F at which a cycle no logging error explains is set aside: its
/// disagreement with the others is then gross (the variance of its interaction at least
/// four times theirs), the cycle disagrees as a whole. A milder disagreement no cause
/// explains is left to the search and its checks (a slow wander or a temperature the
/// search cannot express also breaks the additivity a little, in every cycle).
pub const GROSS_F: f64 = 4.0;

/// The most outliers the search may find in a cycle that first disagreed for the cycle
/// to count as agreeing without them; with more, they are put back for the retest.
const MAX_OUTLIERS_KEPT: usize = 2;

/// What was done with a cycle that disagrees.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum CycleAction {
    /// Evaluated with its cause undone.
    Repaired,
    /// Left out of the fit.
    SetAside,
}

impl CycleAction {
    /// As spelled in the JSON: `repaired`, `set-aside`.
    pub fn as_str(self) -> &'static str {
        match self {
            CycleAction::Repaired => "repaired",
            CycleAction::SetAside => "set-aside",
        }
    }
}

/// A reading that left the fit with its cycle's repair or set-aside.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct SetAsideReading {
    /// Mounting.
    pub setup: u32,
    /// Cycle.
    pub cycle: u32,
    /// The stop the file logs it at.
    pub step: usize,
    /// Autocollimator.
    pub ac: u32,
    /// Line of the file (0 when not from a file).
    pub line: u64,
    /// The reading, arcsec.
    pub reading_arcsec: f64,
    /// Why it left the fit.
    pub reason: String,
}

/// A cycle that disagrees with the rest of its mounting.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CycleFinding {
    /// Mounting.
    pub setup: u32,
    /// Cycle.
    pub cycle: u32,
    /// Chow F of the cycle as logged against the others ([`test`]).
    pub f_statistic: f64,
    /// Its numerator degrees of freedom.
    pub dof_numerator: usize,
    /// Its denominator degrees of freedom.
    pub dof_denominator: usize,
    /// Its p-value.
    pub p_value: f64,
    /// The level each cycle is judged at: [`CYCLE_ALPHA`] over the cycles tested.
    pub level: f64,
    /// Whether the cycle as logged agrees with the others (false for every entry).
    pub consistent: bool,
    /// The logging error that explains it, or [`CycleCause::Unexplained`].
    pub cause: CycleCause,
    /// Causes that explain it equally well (then `cause` is unexplained and the cycle set
    /// aside).
    pub alternatives: Vec<CycleCause>,
    /// The F and p of the cycle with its cause undone (repaired cycles).
    pub repaired: Option<(f64, f64)>,
    /// What was done.
    pub action: CycleAction,
    /// The readings that left the fit with it, with the reason.
    pub set_aside: Vec<SetAsideReading>,
    /// Largest change of a pitch deviation between the base fits of the readings as
    /// logged and as repaired (all cycles' findings together), arcsec.
    pub pitch_change_max: f64,
    /// Likewise of an encoder error, arcsec.
    pub encoder_change_max: f64,
}

/// One reading of a cycle as the test sees it: autocollimator, stop, value.
type CycleReading = (u32, usize, f64);

/// The tables of `setup`'s autocollimators (rows cycles, columns stops) of `values` (one
/// per reading of `set`), readings whose index is in `skip` left out; each with its
/// autocollimator.
fn tables(
    set: &MeasurementSet,
    values: &[f64],
    setup: u32,
    skip: &BTreeSet<usize>,
) -> Vec<(u32, Table)> {
    let mut by_ac: BTreeMap<u32, Vec<Entry>> = BTreeMap::new();
    for (i, (r, v)) in set.readings.iter().zip(values).enumerate() {
        if r.setup == setup && !skip.contains(&i) {
            by_ac.entry(r.ac).or_default().push((r.cycle, r.step, *v));
        }
    }
    by_ac
        .into_iter()
        .map(|(ac, entries)| (ac, Table::of(entries)))
        .collect()
}

/// The tables of `tables` alone.
fn tables_only(tables: Vec<(u32, Table)>) -> Vec<Table> {
    tables.into_iter().map(|(_, t)| t).collect()
}

/// The fits of `tables` with row `cycle` replaced by `replacement` (ac, step, value).
fn fits_replaced(
    tables: &[(u32, Table)],
    cycle: u32,
    replacement: &[CycleReading],
) -> (f64, usize) {
    sum(tables.iter().map(|(ac, table)| {
        let row: Vec<(usize, f64)> = replacement
            .iter()
            .filter(|e| e.0 == *ac)
            .map(|&(_, step, v)| (step, v))
            .collect();
        table.fit_replaced(cycle, &row)
    }))
}

/// The cycle's readings (ac, step, value) with `cause` undone, in the tables of its own
/// mounting, and the number of readings the repair sets aside; `None` when it cannot be
/// undone.
fn undone(cycle: &causes::Cycle<'_>, cause: CycleCause) -> Option<(Vec<CycleReading>, usize)> {
    let undone = cycle.undo(cause)?;
    let entries: Vec<CycleReading> = match cause {
        CycleCause::FacesShifted { by } => {
            // the values are of the face `by` on: compared with the autocollimator of
            // this mounting that reads that face at the same stop, where there is one
            let n = cycle.faces() as i64;
            cycle
                .readings()
                .filter_map(|r| {
                    let target = (cycle.offset_of(r.setup, r.ac)? as i64 + by).rem_euclid(n);
                    let ac = cycle.ac_with_offset(target as usize)?;
                    Some((ac, r.step, r.reading_arcsec))
                })
                .collect()
        }
        _ => undone
            .readings
            .iter()
            .map(|(_, r)| (r.ac, r.step, r.reading_arcsec))
            .collect(),
    };
    Some((entries, undone.aside.len()))
}

fn values(set: &MeasurementSet) -> Vec<f64> {
    set.readings.iter().map(|r| r.reading_arcsec).collect()
}

/// The (setup, cycle) pairs tested: every cycle of a mounting with [`MIN_CYCLES`] or more.
fn tested(set: &MeasurementSet) -> Vec<(u32, u32)> {
    let pairs: BTreeSet<(u32, u32)> = set.readings.iter().map(|r| (r.setup, r.cycle)).collect();
    pairs
        .iter()
        .copied()
        .filter(|&(s, _)| pairs.iter().filter(|(t, _)| *t == s).count() >= MIN_CYCLES)
        .collect()
}

/// The cycles of `set` that disagree with the others at the run's level, as logged and
/// before any repair: (setup, cycle, F, p), the decision whose false-alarm rate is
/// [`CYCLE_ALPHA`] per run (docs/verdicts.md).
pub fn disagreeing_cycles(set: &MeasurementSet) -> Vec<(u32, u32, f64, f64)> {
    let pairs = tested(set);
    let level = CYCLE_ALPHA / pairs.len().max(1) as f64;
    tests(set, &pairs)
        .0
        .into_iter()
        .filter(|t| t.chow.p_value < level)
        .map(|t| (t.setup, t.cycle, t.chow.f_statistic, t.chow.p_value))
        .collect()
}

/// Each mounting's tables, by mounting: each autocollimator's, with the autocollimator.
type Mountings = BTreeMap<u32, Vec<(u32, Table)>>;

/// One cycle's test as logged, with the fits of its mounting's tables (shared by the
/// tests of the cycle's repairs).
struct CycleTest {
    setup: u32,
    cycle: u32,
    chow: Chow,
    /// The fits of the mounting's tables without the cycle.
    rest: (f64, usize),
}

/// The test of every cycle of `pairs` in `set`, with each mounting's tables (built and
/// fitted once for all its cycles).
fn tests(set: &MeasurementSet, pairs: &[(u32, u32)]) -> (Vec<CycleTest>, Mountings) {
    let v = values(set);
    let none = BTreeSet::new();
    let setups: BTreeSet<u32> = pairs.iter().map(|p| p.0).collect();
    let mut found = Vec::new();
    let mut by_setup = BTreeMap::new();
    for setup in setups {
        let tables = tables(set, &v, setup, &none);
        let all = sum(tables.iter().map(|(_, t)| t.fit()));
        for &(_, cycle) in pairs.iter().filter(|p| p.0 == setup) {
            let rest = sum(tables.iter().map(|(_, t)| t.fit_without(cycle)));
            if let Some(chow) = chow_of(all, rest, MIN_REST_DOF) {
                found.push(CycleTest {
                    setup,
                    cycle,
                    chow,
                    rest,
                });
            }
        }
        by_setup.insert(setup, tables);
    }
    (found, by_setup)
}

pub(super) fn aside_readings(
    set: &MeasurementSet,
    indices: &[usize],
    reason: &str,
) -> Vec<SetAsideReading> {
    indices
        .iter()
        .map(|&i| {
            let r = &set.readings[i];
            SetAsideReading {
                setup: r.setup,
                cycle: r.cycle,
                step: r.step,
                ac: r.ac,
                line: r.line,
                reading_arcsec: r.reading_arcsec,
                reason: reason.to_string(),
            }
        })
        .collect()
}

fn finding(setup: u32, cycle: u32, logged: Chow, level: f64) -> CycleFinding {
    CycleFinding {
        setup,
        cycle,
        f_statistic: logged.f_statistic,
        dof_numerator: logged.dof_numerator,
        dof_denominator: logged.dof_denominator,
        p_value: logged.p_value,
        level,
        consistent: false,
        cause: CycleCause::Unexplained,
        alternatives: Vec::new(),
        repaired: None,
        action: CycleAction::SetAside,
        set_aside: Vec::new(),
        pitch_change_max: 0.0,
        encoder_change_max: 0.0,
    }
}

/// The readings after the cycles' test and repairs, what was found, and the cycles left
/// for the search.
struct Examined {
    set: MeasurementSet,
    findings: Vec<CycleFinding>,
    pending: Vec<(u32, u32, Chow)>,
    level: f64,
}

/// Tests every cycle; repairs or sets aside those a logging error explains.
fn examine(set: &MeasurementSet) -> Examined {
    let pairs = tested(set);
    let level = CYCLE_ALPHA / pairs.len().max(1) as f64;
    let mut current = set.clone();
    let mut handled = BTreeSet::new();
    let mut findings = Vec::new();
    let mut pending = Vec::new();
    // the tests as logged, computed anew only when a cycle is repaired or set aside
    let (mut logged_tests, mut mountings) = tests(&current, &pairs);
    loop {
        let worst = logged_tests
            .iter()
            .filter(|t| !handled.contains(&(t.setup, t.cycle)) && t.chow.p_value < level)
            .max_by(|a, b| a.chow.f_statistic.total_cmp(&b.chow.f_statistic));
        let Some(&CycleTest {
            setup,
            cycle,
            chow: logged,
            rest,
        }) = worst
        else {
            break;
        };
        handled.insert((setup, cycle));
        let Some(mounting) = mountings.get(&setup) else {
            continue;
        };
        // the causes whose undoing makes the cycle agree, with the number of the cycle's
        // readings the test could compare (faces shifted onto a face no autocollimator
        // of the mounting reads at that stop cannot be compared)
        let prepared = causes::Cycle::of(&current, setup, cycle);
        let consistent: Vec<(usize, CycleCause, Chow)> = prepared
            .iter()
            .flat_map(|c| c.candidates().into_iter().map(move |cause| (c, cause)))
            .filter_map(|(prepared, cause)| {
                let (entries, aside) = undone(prepared, cause)?;
                let t = chow_of(fits_replaced(mounting, cycle, &entries), rest, MIN_REST_DOF)?;
                (t.p_value >= level).then_some((entries.len() + aside, cause, t))
            })
            .collect();
        // a cause that leaves some of the cycle's readings unchecked does not explain it
        // as well as one that checks them all
        let most = consistent.iter().map(|e| e.0).max().unwrap_or(0);
        let explaining: Vec<(CycleCause, Chow)> = consistent
            .into_iter()
            .filter(|e| e.0 == most)
            .map(|(_, cause, t)| (cause, t))
            .collect();
        let mut found = finding(setup, cycle, logged, level);
        match explaining.len() {
            0 => pending.push((setup, cycle, logged)),
            n if n > 1 && logged.f_statistic < GROSS_F => pending.push((setup, cycle, logged)),
            1 => {
                let Some((cause, t)) = explaining.into_iter().next() else {
                    continue;
                };
                let Some((repaired, aside)) = causes::repair(&current, setup, cycle, cause) else {
                    continue;
                };
                found.cause = cause;
                found.repaired = Some((t.f_statistic, t.p_value));
                found.action = CycleAction::Repaired;
                found.set_aside = aside_readings(
                    &current,
                    &aside,
                    &format!(
                        "{}: the value left without a stop of cycle {cycle} when the readings are moved to the stops they belong to",
                        cause.as_str()
                    ),
                );
                current = repaired;
                (logged_tests, mountings) = tests(&current, &pairs);
                findings.push(found);
            }
            _ => {
                found.alternatives = explaining.iter().map(|e| e.0).collect();
                let (rest, aside) = causes::without_cycle(&current, setup, cycle);
                let names: Vec<&str> = found.alternatives.iter().map(|c| c.as_str()).collect();
                found.set_aside = aside_readings(
                    &current,
                    &aside,
                    &format!(
                        "cycle {cycle} set aside: {} explain it equally well",
                        names.join(" and ")
                    ),
                );
                current = rest;
                (logged_tests, mountings) = tests(&current, &pairs);
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

/// The pending cycles that still disagree on the final model's residuals of `diagnosis`
/// (of `set`).
fn still_disagreeing(
    set: &MeasurementSet,
    diagnosis: &Diagnosis,
    pending: &[(u32, u32, Chow)],
    level: f64,
) -> Vec<(u32, u32, Chow)> {
    let residuals = &diagnosis.after.residuals;
    if residuals.len() != set.readings.len() {
        return Vec::new();
    }
    pending
        .iter()
        .copied()
        .filter(|&(setup, cycle, _)| {
            let outliers: Vec<(usize, f64)> = diagnosis
                .effects
                .iter()
                .filter_map(|f| match f.effect {
                    Effect::Outlier {
                        cycle: c,
                        step,
                        ac,
                        setup: s,
                        value,
                    } if c == cycle && s.is_none_or(|s| s == setup) => set
                        .readings
                        .iter()
                        .position(|r| {
                            r.setup == setup && r.cycle == cycle && r.step == step && r.ac == ac
                        })
                        .map(|i| (i, value)),
                    _ => None,
                })
                .collect();
            let mut skip = BTreeSet::new();
            let mut values = residuals.clone();
            if outliers.len() <= MAX_OUTLIERS_KEPT {
                skip.extend(outliers.iter().map(|o| o.0));
            } else {
                for &(i, value) in &outliers {
                    values[i] += value;
                }
            }
            chow(
                &tables_only(tables(set, &values, setup, &skip)),
                cycle,
                MIN_REST_DOF,
            )
            .is_some_and(|t| t.p_value < level && t.f_statistic >= GROSS_F)
        })
        .collect()
}

/// [`super::diagnose`] of `logged` (on its clock) with the cycles tested first
/// (module documentation); `plain` is the diagnosis of a set of readings without it.
pub(crate) fn diagnose_checked(
    logged: &MeasurementSet,
    options: &DiagnoseOptions,
    plain: impl Fn(&MeasurementSet) -> Result<Diagnosis, SolveError>,
) -> Result<Diagnosis, SolveError> {
    let Examined {
        set: cycles_repaired,
        mut findings,
        pending,
        level,
    } = examine(logged);
    // then every mounting against the others, on the cycles as repaired
    let mut mounted = mountings::examine(cycles_repaired);
    let mut diagnosis = plain(&mounted.set)?;
    let changed =
        set_aside_pending_cycles(&mut mounted.set, &diagnosis, &pending, level, &mut findings);
    if changed {
        diagnosis = plain(&mounted.set)?;
    }
    // the mountings left to the search, one set aside at a time (each pending mounting
    // at most once)
    while mounted.set_aside_worst(&diagnosis) {
        diagnosis = plain(&mounted.set)?;
    }
    let used = mounted.set;
    if findings.is_empty() && mounted.findings.is_empty() {
        return Ok(diagnosis);
    }
    // `before` is the fit of every reading as logged
    let base = Base::of(logged);
    let before = base.fit(&[], options.sigma)?;
    let repaired_base = Base::of(&used).fit(&[], options.sigma)?;
    let change = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    let pitch_change_max = change(&before.pitch_deviation, &repaired_base.pitch_deviation);
    let encoder_change_max = change(&before.encoder_error, &repaired_base.encoder_error);
    for found in &mut findings {
        found.pitch_change_max = pitch_change_max;
        found.encoder_change_max = encoder_change_max;
        diagnosis.notes.push(note(found));
        if found.action == CycleAction::SetAside {
            set_aside_check(
                &mut diagnosis,
                format!(
                    "cycle {} of setup {} agrees with the others (set aside: {})",
                    found.cycle,
                    found.setup,
                    why_set_aside(&found.alternatives)
                ),
                (
                    found.f_statistic,
                    found.dof_numerator,
                    found.dof_denominator,
                ),
                found.level,
            );
        }
    }
    for found in &mounted.findings {
        diagnosis.notes.push(mountings::note(found));
        if found.action == CycleAction::SetAside {
            set_aside_check(
                &mut diagnosis,
                format!(
                    "setup {} agrees with the other mountings (set aside: {})",
                    found.setup,
                    why_set_aside(&found.alternatives)
                ),
                (
                    found.f_statistic,
                    found.dof_numerator,
                    found.dof_denominator,
                ),
                found.level,
            );
        }
    }
    diagnosis.before_sub_pitch = base.sub_pitch_solution(&before);
    diagnosis.before = before;
    diagnosis.cycles = findings;
    diagnosis.mountings = mounted.findings;
    Ok(diagnosis)
}

/// The finding in words.
fn note(found: &CycleFinding) -> String {
    let head = format!(
        "Cycle {} (setup {}) disagrees with the other cycles (F = {:.1} on {} and {} degrees of freedom, p = {:.1e}, level {:.1e} per cycle)",
        found.cycle,
        found.setup,
        found.f_statistic,
        found.dof_numerator,
        found.dof_denominator,
        found.p_value,
        found.level
    );
    let changed = format!(
        "against the readings as logged, β changes by up to {:.4}″ and α by up to {:.4}″",
        found.pitch_change_max, found.encoder_change_max
    );
    let aside = left_the_fit(found.set_aside.len());
    match found.action {
        CycleAction::Repaired => format!(
            "{head}: {} explains it exactly (undone, the cycle agrees: F = {:.2}); the cycle is evaluated with it undone, and {changed}.{aside}",
            found.cause.describe(),
            found.repaired.map_or(f64::NAN, |r| r.0),
        ),
        CycleAction::SetAside if !found.alternatives.is_empty() => {
            let names: Vec<String> = found.alternatives.iter().map(|c| c.describe()).collect();
            format!(
                "{head}: {} explain it equally well, so neither is a finding; the cycle is set aside and the calibration is not certified as adequate; {changed}.{aside}",
                names.join(" and ")
            )
        }
        CycleAction::SetAside => format!(
            "{head}: no usual logging error (autocollimators exchanged, one stop late or early, faces shifted, reversed) explains it, nor any effect found; the cycle is set aside and the calibration is not certified as adequate; {changed}. Check that cycle's log.{aside}"
        ),
    }
}

/// " N readings left the fit with it." (nothing for none), the end of a finding's note.
pub(super) fn left_the_fit(readings: usize) -> String {
    match readings {
        0 => String::new(),
        1 => " 1 reading left the fit with it.".to_string(),
        n => format!(" {n} readings left the fit with it."),
    }
}

/// The pending cycles (left to the search) that still disagree grossly on the final
/// residuals of `diagnosis` (of `used`), set aside from `used` and listed in `findings`;
/// whether any was. Which ones is decided on `diagnosis` before any leaves.
fn set_aside_pending_cycles(
    used: &mut MeasurementSet,
    diagnosis: &Diagnosis,
    pending: &[(u32, u32, Chow)],
    level: f64,
    findings: &mut Vec<CycleFinding>,
) -> bool {
    if pending.is_empty() {
        return false;
    }
    let still = still_disagreeing(used, diagnosis, pending, level);
    for &(setup, cycle, logged_test) in &still {
        let (rest, aside) = causes::without_cycle(used, setup, cycle);
        let mut found = finding(setup, cycle, logged_test, level);
        found.set_aside = aside_readings(
            used,
            &aside,
            &format!(
                "cycle {cycle} set aside: it disagrees with the others, no usual logging error explains it, and no effect the search found does"
            ),
        );
        findings.push(found);
        *used = rest;
    }
    !still.is_empty()
}

/// Why a cycle or a mounting was set aside, in the words of its check.
fn why_set_aside(alternatives: &[CycleCause]) -> &'static str {
    if alternatives.is_empty() {
        "no cause explains it"
    } else {
        "several causes explain it equally well"
    }
}

/// The failed check of a cycle or a mounting set aside: its F (with its degrees of
/// freedom) against the F its level allows; the diagnosis is then not adequate.
fn set_aside_check(
    diagnosis: &mut Diagnosis,
    name: String,
    (f_statistic, dof_numerator, dof_denominator): (f64, usize, usize),
    level: f64,
) {
    use statrs::distribution::{ContinuousCDF, FisherSnedecor};
    let limit = FisherSnedecor::new(dof_numerator as f64, dof_denominator as f64)
        .map_or(GROSS_F, |d| d.inverse_cdf(1.0 - level));
    diagnosis.adequacy.checks.push(Check {
        name,
        statistic: f_statistic,
        limit: if limit.is_finite() { limit } else { GROSS_F },
        passed: false,
        stream: None,
    });
    diagnosis.adequacy.adequate = false;
}
