//! From the terms of the final model to the effects a diagnosis reports: a block of
//! terms (a drift with its orders, a zero per cycle) becomes one docs/FORMAT.md §6 effect
//! with its value and uncertainty, a drift's later orders merge into it, and terms tried
//! and not added are recorded with their reason.

use super::base::Base;
use super::candidates::{Candidate, Term};
use super::{Evidence, FoundEffect, Rejection, TriedEffect};
use crate::effects::Effect;
use crate::solve::Solution;
use crate::uncertainty::student::t_two_sided_tail;

/// The effect a block of terms stands for, with the values of its columns (in the order
/// of `terms`): a drift's orders give one drift (its linear `value`, `quadratic`), a
/// zero per cycle one `rezero` with its first offset 0, a single term its effect.
pub fn block_effect(terms: &[Term], values: &[f64]) -> Option<Effect> {
    let first = terms.first()?;
    let value_of = |want: &Term| {
        terms
            .iter()
            .position(|t| t == want)
            .and_then(|i| values.get(i))
            .copied()
    };
    match first {
        Term::Effect(Effect::Drift { ac, .. })
        | Term::Quadratic { ac }
        | Term::DriftShape { ac, .. }
        | Term::DriftKink { ac, .. } => {
            let ac = *ac;
            Some(Effect::Drift {
                ac,
                value: value_of(&Term::drift_of_order(ac, 1)).unwrap_or(0.0),
                quadratic: value_of(&Term::Quadratic { ac }),
            })
        }
        Term::RezeroCycle { ac, setup, .. } => {
            let mut offsets = vec![0.0];
            offsets.extend(values.iter().take(terms.len()));
            Some(Effect::rezero(*ac, *setup, offsets))
        }
        Term::Effect(e) => Some(e.clone().with_value(values.first().copied().unwrap_or(0.0))),
    }
}

/// The effect a candidate stands for, with the value it would have (a drift's further
/// orders are reported on their drift).
pub fn candidate_effect(candidate: &Candidate) -> Effect {
    match &candidate.term {
        Term::Effect(e) => e.clone().with_value(candidate.value()),
        Term::Quadratic { ac } => Effect::Drift {
            ac: *ac,
            value: 0.0,
            quadratic: Some(candidate.value()),
        },
        Term::DriftShape { ac, .. } | Term::DriftKink { ac, .. } => Effect::Drift {
            ac: *ac,
            value: 0.0,
            quadratic: None,
        },
        Term::RezeroCycle { ac, setup, .. } => Effect::rezero(*ac, *setup, Vec::new()),
    }
}

/// A finding while the search runs: its terms (a block) and the statistics of the round
/// it was added in.
#[derive(Debug, Clone)]
pub struct Finding {
    /// The terms it added.
    pub terms: Vec<Term>,
    /// Its entry, values and uncertainties still of the round it was added in.
    pub entry: FoundEffect,
    /// The change it made to every β.
    pub pitch_change: Vec<f64>,
    /// The change it made to every α.
    pub encoder_change: Vec<f64>,
}

impl Finding {
    /// The finding as a term tried and not kept, for `rejection`, with the evidence it
    /// had when it was added.
    pub fn withdrawn(&self, rejection: Rejection) -> TriedEffect {
        TriedEffect {
            effect: self.entry.effect.clone(),
            quadratic: false,
            evidence: Evidence {
                f_statistic: self.entry.f_statistic,
                p_value: self.entry.p_value,
                p_adjusted: self.entry.p_adjusted,
            },
            rejection,
        }
    }
}

/// The drift order of a term block of one autocollimator (its highest), if a drift.
fn drift_of(terms: &[Term]) -> Option<(u32, usize)> {
    terms.iter().find_map(|t| match *t {
        Term::Effect(Effect::Drift { ac, .. })
        | Term::Quadratic { ac }
        | Term::DriftShape { ac, .. }
        | Term::DriftKink { ac, .. } => Some((
            ac,
            terms
                .iter()
                .filter_map(|t| t.drift_order(ac))
                .max()
                .unwrap_or(1),
        )),
        _ => None,
    })
}

/// The found effects with their values and uncertainties in the final model (`current`,
/// a fit of `base` with `terms`): a drift's later orders merged into its drift, and whether each
/// changes the calibration by more than its uncertainty; each with the terms of the
/// final model it stands for (a drift: all of its orders).
pub fn final_effects(
    current: &Solution,
    base: &Base<'_>,
    terms: &[Term],
    findings: Vec<Finding>,
) -> Vec<(FoundEffect, Vec<Term>)> {
    let offset = base.offset();
    let u = base.term_u(current);
    let [u_pitch, u_encoder] = base.calibrated_u(current);
    let exceeds = |change: &[f64], u: &Option<Vec<f64>>| match u {
        Some(u) => change.iter().zip(u).any(|(c, u)| c.abs() > *u),
        None => change.iter().any(|c| *c != 0.0),
    };
    let index = |t: &Term| terms.iter().position(|p| p == t);
    let value_of = |t: &Term| index(t).map_or(0.0, |j| current.effect_values[offset + j]);
    let u_of = |t: &Term| index(t).and_then(|j| u.as_ref().map(|u| u[j]));
    let mut effects: Vec<(FoundEffect, Vec<Term>)> = Vec::new();
    for finding in findings {
        let Finding {
            terms: block,
            mut entry,
            pitch_change,
            encoder_change,
        } = finding;
        let changes = exceeds(&pitch_change, &u_pitch) || exceeds(&encoder_change, &u_encoder);
        if let Some((ac, _)) = drift_of(&block) {
            let all: Vec<Term> = terms
                .iter()
                .filter(|t| t.is_drift_of(ac))
                .cloned()
                .collect();
            let order = all
                .iter()
                .filter_map(|t| t.drift_order(ac))
                .max()
                .unwrap_or(1);
            let quadratic = Term::Quadratic { ac };
            let effect = Effect::Drift {
                ac,
                value: value_of(&Term::drift_of_order(ac, 1)),
                quadratic: index(&quadratic).map(|_| value_of(&quadratic)),
            };
            let shape: Vec<f64> = (3..=order)
                .map(|k| value_of(&Term::DriftShape { ac, order: k }))
                .collect();
            let shape_u: Option<Vec<f64>> = (3..=order)
                .map(|k| u_of(&Term::DriftShape { ac, order: k }))
                .collect();
            let quadratic_u = u_of(&quadratic);
            // a kink the final model holds, its change of rate from the fit
            let kink_term = all.iter().find_map(|t| match *t {
                Term::DriftKink { at_seconds, .. } => Some((t.clone(), at_seconds)),
                _ => None,
            });
            let kink = |found: Option<super::DriftKink>| {
                let (term, at_seconds) = kink_term.clone()?;
                let found = found?;
                Some(super::DriftKink {
                    at_seconds,
                    rate_change: value_of(&term),
                    rate_change_u: u_of(&term),
                    ..found
                })
            };
            let quadratic_evidence = match (index(&quadratic), quadratic_u) {
                (Some(_), Some(uq)) if uq > 0.0 => {
                    let t = value_of(&quadratic) / uq;
                    Some(Evidence {
                        f_statistic: t * t,
                        p_value: t_two_sided_tail(t.abs(), Some(current.dof as f64)),
                        p_adjusted: t_two_sided_tail(t.abs(), Some(current.dof as f64)),
                    })
                }
                _ => None,
            };
            if let Some((drift, _)) = effects
                .iter_mut()
                .find(|(f, _)| matches!(f.effect, Effect::Drift { ac: a, .. } if a == ac))
            {
                drift.changes_calibration |= changes;
                drift.pitch_change_max = drift.pitch_change_max.max(entry.pitch_change_max);
                drift.encoder_change_max = drift.encoder_change_max.max(entry.encoder_change_max);
                drift.effect = effect;
                drift.quadratic_u = quadratic_u;
                drift.quadratic_evidence = quadratic_evidence;
                drift.drift_order = Some(order);
                drift.shape = shape;
                drift.shape_u = shape_u;
                drift.kink = kink(drift.kink.or(entry.kink));
                continue;
            }
            entry.effect = effect;
            entry.u = u_of(&Term::drift_of_order(ac, 1));
            entry.quadratic_u = quadratic_u;
            entry.quadratic_evidence = quadratic_evidence;
            entry.drift_order = Some(order);
            entry.shape = shape;
            entry.shape_u = shape_u;
            entry.kink = kink(entry.kink);
            entry.changes_calibration = changes;
            effects.push((entry, all));
            continue;
        }
        let values: Vec<f64> = block.iter().map(value_of).collect();
        let Some(mut effect) = block_effect(&block, &values) else {
            continue;
        };
        if let Effect::Rezero {
            offsets, offsets_u, ..
        } = &mut effect
        {
            let mut us = vec![0.0];
            us.extend(block.iter().map(|t| u_of(t).unwrap_or(f64::NAN)));
            let largest = offsets
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                .map_or(0, |(i, _)| i);
            entry.u = us.get(largest).copied().filter(|u| u.is_finite());
            *offsets_u = us.iter().all(|u| u.is_finite()).then_some(us);
        } else {
            entry.u = block.first().and_then(u_of);
        }
        entry.effect = effect;
        entry.changes_calibration = changes;
        effects.push((entry, block));
    }
    effects
}

/// Adds, for every kind of term (and autocollimator, mounting) of the last round, its best
/// candidate as "not significant".
pub fn record_not_significant(
    tried: &mut Vec<TriedEffect>,
    scored: &[(Candidate, Evidence)],
    family_alpha: f64,
) {
    let mut seen: Vec<String> = Vec::new();
    for (candidate, ev) in scored {
        if ev.p_adjusted < family_alpha {
            continue;
        }
        let group = match &candidate.term {
            Term::Effect(Effect::OffsetStep { ac, setup, .. }) => {
                format!("offset-step {ac} {setup:?}")
            }
            Term::Effect(Effect::Outlier { .. }) => "outlier".into(),
            Term::Effect(Effect::Drift { ac, .. })
            | Term::Quadratic { ac }
            | Term::DriftShape { ac, .. }
            | Term::DriftKink { ac, .. } => {
                format!("drift {ac}")
            }
            Term::RezeroCycle { ac, setup, .. } => format!("rezero {ac} {setup:?}"),
            other => format!("{other:?}"),
        };
        if seen.contains(&group) {
            continue;
        }
        seen.push(group);
        tried.push(TriedEffect {
            effect: candidate_effect(candidate),
            quadratic: matches!(candidate.term, Term::Quadratic { .. }),
            evidence: *ev,
            rejection: Rejection::NotSignificant,
        });
    }
}

/// The difference a − b, element by element.
pub fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

/// The largest |v|.
pub fn max_abs(v: &[f64]) -> f64 {
    v.iter().map(|x| x.abs()).fold(0.0, f64::max)
}
