//! The final model's verdict beyond the checks of its residuals
//! ([`residuals::adequacy`](super::residuals::adequacy)): the checks a found term brings (a
//! drift's stability, a zero left out as a wander, each finding's identifiability), a
//! search a limit ended, the scatter the stops share, and the notes that say each in
//! words. Each function is one step of [`diagnose`](super::diagnose), in the order it runs.

use super::notes;
use super::residuals::{Adequacy, Check};
use super::search::SearchStop;
use super::stop_scatter::StopScatter;
use super::{Clock, FoundEffect, LackOfFit, SuspectReading};
use crate::diagnose::base::Base;
use crate::effects::Effect;
use crate::measurement::MeasurementSet;
use crate::solve::Solution;

/// The outliers the data cannot attribute to one reading, as readings of `set` with their
/// residuals in `fit`, and a note for each group.
pub(super) fn unattributed(
    set: &MeasurementSet,
    fit: &Solution,
    sets: &[Vec<(usize, f64)>],
    notes: &mut Vec<String>,
) -> Vec<Vec<SuspectReading>> {
    let unattributed: Vec<Vec<SuspectReading>> = sets
        .iter()
        .map(|group| {
            group
                .iter()
                .map(|&(i, t)| {
                    let r = &set.readings[i];
                    SuspectReading {
                        setup: r.setup,
                        cycle: r.cycle,
                        step: r.step,
                        ac: r.ac,
                        residual_arcsec: fit.residuals[i],
                        studentized_residual: t,
                    }
                })
                .collect()
        })
        .collect();
    for group in &unattributed {
        let names: Vec<String> = group
            .iter()
            .map(|s| {
                format!(
                    "setup {} cycle {} step {} autocollimator {} (residual {:+.4}″)",
                    s.setup, s.cycle, s.step, s.ac, s.residual_arcsec
                )
            })
            .collect();
        notes.push(format!(
            "One of these readings is bad, but the data cannot tell which: {}. Their residuals are equally large because the design determines their cell only by these readings. Both are kept in the fit, so the result carries about half of the bad reading's error there; repeat that stop (a third reading tells which one is bad).",
            names.join(" and ")
        ));
    }
    unattributed
}

/// The drifts' stability between the run's halves, checks of the verdict.
pub(super) fn stability(checks: Vec<Check>, adequacy: &mut Adequacy) {
    for check in checks {
        adequacy.adequate &= check.passed;
        adequacy.checks.push(check);
    }
}

/// A zero whose drifts and jumps were left out as a wander is not certified, whether or
/// not the residuals without them still show it.
pub(super) fn wandering(acs: &[u32], adequacy: &mut Adequacy) {
    for &ac in acs {
        adequacy.checks.push(Check {
            name: format!(
                "zero of ac {ac} followed by the terms found (not a wander they only approximate: its drift and jumps are left out)"
            ),
            statistic: 1.0,
            limit: 0.0,
            passed: false,
            stream: None,
        });
    }
    adequacy.adequate = false;
}

/// A finding with an alternative that fits as well and moves β or α by more than their
/// expanded uncertainty is not certified; a note says what cannot be told apart.
pub(super) fn identifiability(
    effects: &[FoundEffect],
    clock: Clock,
    adequacy: &mut Adequacy,
    notes: &mut Vec<String>,
) {
    for found in effects {
        if found.alternatives.is_empty() {
            continue;
        }
        let worst = found
            .alternatives
            .iter()
            .map(|a| a.change_over_expanded_u)
            .fold(0.0, f64::max);
        let passed = worst <= 1.0;
        adequacy.checks.push(Check {
            name: format!(
                "identifiability of the {} (largest change of β or α by an explanation that fits as well, in expanded uncertainties)",
                found.effect.label()
            ),
            statistic: worst,
            limit: 1.0,
            passed,
            stream: None,
        });
        adequacy.adequate &= passed;
        notes.push(notes::ambiguity(found, clock));
    }
}

/// The note on the cross-talk the caller stated (`stated`, autocollimators) and what the
/// data add to it; `None` when none was stated.
pub(super) fn stated_cross_talk_note(stated: &[u32], effects: &[FoundEffect]) -> Option<String> {
    if stated.is_empty() {
        return None;
    }
    let names: Vec<String> = stated.iter().map(u32::to_string).collect();
    let found: Vec<String> = effects
        .iter()
        .filter_map(|f| match f.effect {
            Effect::CrossTalk { ac, value } if !f.ambiguous() => {
                Some(format!("autocollimator {ac}'s ({value:+.5}″/″)"))
            }
            _ => None,
        })
        .collect();
    Some(format!(
        "The cross-talk of autocollimator{} {} is stated from its calibration and corrected for{}",
        if names.len() == 1 { "" } else { "s" },
        names.join(", "),
        if found.is_empty() {
            ": no further cross-talk is significant.".to_string()
        } else {
            format!(
                "; against it, {} follows from the data, and the ambiguity of a cross-talk the closure cannot place is resolved.",
                found.join(" and ")
            )
        }
    ))
}

/// A search a limit ended is not certified: its check fails, and a note says why.
pub(super) fn search_stopped(stop: SearchStop, adequacy: &mut Adequacy, notes: &mut Vec<String>) {
    adequacy.checks.push(Check {
        name: format!(
            "search ended because nothing more was significant (not a limit: {})",
            stop.as_str()
        ),
        statistic: 1.0,
        limit: 0.0,
        passed: false,
        stream: None,
    });
    adequacy.adequate = false;
    notes.push(notes::search_stopped(stop));
}

/// The lack of fit's band-limit order (heads between the positions) and its notes: too
/// small to be true, its carriers when it fails, a finding of its own beside `effects`
/// effects found, the band limit.
pub(super) fn lack_of_fit_notes(
    lack_of_fit: &mut Option<LackOfFit>,
    base: &Base<'_>,
    effects: usize,
    notes: &mut Vec<String>,
) {
    let Some(lof) = lack_of_fit else {
        return;
    };
    if base.is_off_grid() {
        lof.band_limit_order = Some(base.positions().faces / 2);
    }
    if lof.too_good() {
        notes.push(notes::lack_of_fit_too_good(lof));
    }
    if !lof.passed() {
        notes.extend(lof.carriers.iter().cloned());
        // the effects found are findings of their own, and so is what they leave
        if effects > 0 {
            notes.push(notes::lack_of_fit_left(lof, effects));
        }
        if base.is_off_grid() {
            notes.push(notes::band_limit(base.positions().faces));
        }
    }
}

/// The scatter the autocollimators share at a stop beyond the final model `fit`
/// ([`super::stop_scatter`]): when significant, every u(α) of `fit` carries it and a note
/// names the band limit; evaluated, it is a check of the verdict (structure the model
/// lacks, which no position can attribute, is not certified).
pub(super) fn stop_scatter(
    set: &MeasurementSet,
    fit: &mut Solution,
    adequacy: &mut Adequacy,
    notes: &mut Vec<String>,
) -> Option<StopScatter> {
    let scatter = super::stop_scatter::stop_scatter(set, fit)?;
    if scatter.significant
        && let Some((sigma, _)) = fit.sigma
        && sigma > 0.0
    {
        fit.cofactor = fit
            .cofactor
            .clone()
            .with_encoder_variance((scatter.sigma_arcsec / sigma).powi(2));
        notes.push(notes::stop_scatter(&scatter, set.faces));
    }
    adequacy.checks.push(Check {
        name: "no scatter shared by the autocollimators at a stop (the table's angle: an encoder error beyond the band limit N/2; F of a parameter per stop, 0.1 %)".into(),
        statistic: scatter.f_statistic,
        limit: scatter.f_limit,
        passed: !scatter.significant,
        stream: None,
    });
    adequacy.adequate &= !scatter.significant;
    Some(scatter)
}
