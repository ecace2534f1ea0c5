//! Identifiability: an explanation the data cannot tell from another is not a finding.
//!
//! For every effect found, the alternatives are the terms of its family that stand in
//! its place — the same kind on another autocollimator, in another mounting or stream
//! (for a jump, at the same stop), and pairs of them — and the terms of another kind that
//! can (a direction offset and a jump of the same zero at a cycle's start). Each alternative model (the final
//! model with the finding replaced by the alternative) is fitted. It explains the data as
//! well when the increase of the residual sum of squares it brings is not significant:
//! F = ΔRSS/(r·s²) with r the finding's columns and s² the final model's residual mean
//! square, p > [`AMBIGUITY_ALPHA`] — which is the case when the two columns, projected
//! onto the residual space of the rest of the model, are nearly collinear (cross-talk is
//! the known instance: closure data determine only the differences of the
//! autocollimators' cross-talk coefficients). Nothing here lists special cases: any term
//! added later gets its alternatives from its kind's siblings.
//!
//! The calibration each alternative implies is compared with the final model's: when it
//! moves some β or α by more than that quantity's expanded uncertainty (k = 2 on the
//! final model's standard uncertainty), the finding is ambiguous and the diagnosis cannot
//! certify.

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::base::Base;
use super::candidates::{Term, autocollimators, rezero_block, step_streams};
use super::findings::{block_effect, difference, max_abs};
use crate::effects::{Effect, EffectContext};
use crate::measurement::{MeasurementSet, Sigma};
use crate::solve::Solution;

/// The significance below which an alternative is told apart from a finding: an
/// alternative whose increase of the residual sum of squares has p above it explains the
/// data as well.
pub const AMBIGUITY_ALPHA: f64 = 0.05;

/// The coverage factor of the expanded uncertainty an alternative's calibration is
/// compared with.
pub const AMBIGUITY_COVERAGE_FACTOR: f64 = 2.0;

/// Another explanation of what a finding explains, fitted in its place.
#[derive(Debug, Clone, PartialEq)]
pub struct Alternative {
    /// Its effects with their fitted values (one, or a pair taken together).
    pub effects: Vec<Effect>,
    /// F = ΔRSS/(r·s²) of the alternative against the final model.
    pub f_statistic: f64,
    /// The p-value of that F (r and the final model's dof degrees of freedom).
    pub p_value: f64,
    /// The largest change of a pitch deviation between the two models, arcsec.
    pub pitch_change_max: f64,
    /// The largest change of an encoder error between the two models, arcsec.
    pub encoder_change_max: f64,
    /// The largest change of a β or α as a multiple of its expanded uncertainty
    /// (k = [`AMBIGUITY_COVERAGE_FACTOR`]); above 1 the finding is ambiguous.
    pub change_over_expanded_u: f64,
    /// Whether it fits exactly as well as the finding (the increase of the residual sum
    /// of squares within the readings' rounding): the same explanation in other words
    /// when it changes no β or α either, e.g. a direction offset of an autocollimator and a
    /// jump of its zero at the start of the one counter-clockwise cycle.
    pub equivalent: bool,
}

impl Alternative {
    /// Whether the alternative moves some β or α by more than its expanded uncertainty.
    pub fn changes_calibration(&self) -> bool {
        self.change_over_expanded_u > 1.0
    }
}

/// The siblings of a finding's block: the same kind on another autocollimator, stream or
/// mounting, each a block of terms. An outlier's twins are found apart in a polygon run;
/// in a self-calibration (`same_stop`) its siblings are the other heads' readings at the
/// same stop (which the table's error there may make equivalent).
fn siblings(
    set: &MeasurementSet,
    block: &[Term],
    stated: &[u32],
    same_stop: bool,
) -> Vec<Vec<Term>> {
    let Some(first) = block.first() else {
        return Vec::new();
    };
    let acs = autocollimators(set);
    let with_y = |ac: u32| {
        !stated.contains(&ac)
            && set
                .readings
                .iter()
                .filter(|r| r.ac == ac)
                .all(|r| r.reading_y_arcsec.is_some())
    };
    match first {
        Term::Effect(Effect::CrossTalk { ac, .. }) => acs
            .iter()
            .filter(|&&a| a != *ac && with_y(a))
            .map(|&a| vec![Term::Effect(Effect::CrossTalk { ac: a, value: 0.0 })])
            .collect(),
        Term::Effect(Effect::Temperature { ac, .. }) => acs
            .iter()
            .filter(|&&a| a != *ac)
            .map(|&a| vec![Term::Effect(Effect::Temperature { ac: a, value: 0.0 })])
            .collect(),
        Term::Effect(Effect::Drift { ac, .. })
        | Term::Quadratic { ac }
        | Term::DriftShape { ac, .. }
        | Term::DriftKink { ac, .. } => {
            let orders: Vec<usize> = block.iter().filter_map(|t| t.drift_order(*ac)).collect();
            let kinks: Vec<f64> = block
                .iter()
                .filter_map(|t| match *t {
                    Term::DriftKink { at_seconds, .. } => Some(at_seconds),
                    _ => None,
                })
                .collect();
            acs.iter()
                .filter(|&&a| a != *ac)
                .map(|&a| {
                    let mut terms: Vec<Term> =
                        orders.iter().map(|&k| Term::drift_of_order(a, k)).collect();
                    terms.extend(
                        kinks
                            .iter()
                            .map(|&at_seconds| Term::DriftKink { ac: a, at_seconds }),
                    );
                    terms
                })
                .collect()
        }
        Term::Effect(Effect::Direction { ac, .. }) => {
            let mut out: Vec<Vec<Term>> = Vec::new();
            let direction =
                |a: Option<u32>| vec![Term::Effect(Effect::Direction { ac: a, value: 0.0 })];
            if ac.is_some() {
                out.push(direction(None));
            }
            out.extend(
                acs.iter()
                    .filter(|&&a| Some(a) != *ac)
                    .map(|&a| direction(Some(a))),
            );
            out
        }
        Term::Effect(Effect::OffsetStep {
            ac,
            cycle,
            step,
            setup,
            ..
        }) => step_streams(set)
            .into_iter()
            .filter(|&(a, s)| (a, s) != (*ac, *setup))
            .map(|(a, s)| {
                vec![Term::Effect(Effect::OffsetStep {
                    ac: a,
                    cycle: *cycle,
                    step: *step,
                    setup: s,
                    value: 0.0,
                })]
            })
            .collect(),
        Term::RezeroCycle { ac, setup, .. } => step_streams(set)
            .into_iter()
            .filter(|&(a, s)| (a, s) != (*ac, *setup))
            .map(|(a, s)| rezero_block(set, a, s))
            .filter(|b| !b.is_empty())
            .collect(),
        Term::Effect(Effect::Outlier {
            cycle,
            step,
            ac,
            setup,
            ..
        }) if same_stop => set
            .readings
            .iter()
            .filter(|r| r.cycle == *cycle && r.step == *step && r.ac != *ac)
            .map(|r| {
                vec![Term::Effect(Effect::Outlier {
                    cycle: *cycle,
                    step: *step,
                    ac: r.ac,
                    setup: *setup,
                    value: 0.0,
                })]
            })
            .collect(),
        Term::Effect(Effect::Outlier { .. } | Effect::Rezero { .. }) => Vec::new(),
    }
}

/// Terms of another kind that can stand in a finding's place, tried one by one (never in
/// pairs): for a direction offset of one autocollimator, a jump of its zero at the start
/// of each cycle after the first (with one clockwise and one counter-clockwise cycle, the
/// same column); for such a jump, the direction offset of its autocollimator, when the run
/// has both directions.
fn other_kinds(set: &MeasurementSet, block: &[Term]) -> Vec<Vec<Term>> {
    use crate::measurement::Direction as Rotation;
    let has = |d: Rotation| set.readings.iter().any(|r| r.direction == d);
    match block {
        [Term::Effect(Effect::Direction { ac: Some(ac), .. })] => {
            let mut cycles: Vec<u32> = set
                .readings
                .iter()
                .map(|r| r.cycle)
                .filter(|&c| c >= 2)
                .collect();
            cycles.sort_unstable();
            cycles.dedup();
            step_streams(set)
                .into_iter()
                .filter(|&(a, _)| a == *ac)
                .flat_map(|(a, setup)| {
                    cycles.iter().map(move |&cycle| {
                        vec![Term::Effect(Effect::OffsetStep {
                            ac: a,
                            cycle,
                            step: None,
                            setup,
                            value: 0.0,
                        })]
                    })
                })
                .collect()
        }
        [Term::Effect(Effect::OffsetStep { ac, step: None, .. })]
            if has(Rotation::Cw) && has(Rotation::Ccw) =>
        {
            vec![vec![Term::Effect(Effect::Direction {
                ac: Some(*ac),
                value: 0.0,
            })]]
        }
        _ => Vec::new(),
    }
}

/// An alternative whose p-value by the geometry's residual sum of squares is at most
/// this fraction of [`AMBIGUITY_ALPHA`] is rejected without a refit.
const SCREEN_MARGIN: f64 = 1e-3;

/// What [`alternatives`] needs of the final model.
#[derive(Debug, Clone, Copy)]
pub struct FinalModel<'a> {
    /// The readings, as the file has them.
    pub set: &'a MeasurementSet,
    /// The base model they are fitted with.
    pub base: &'a Base<'a>,
    /// The effects' context.
    pub context: &'a EffectContext,
    /// Its terms.
    pub terms: &'a [Term],
    /// Its fit.
    pub fit: &'a Solution,
    /// The stated σ, if any.
    pub sigma: Option<Sigma>,
    /// Autocollimators whose cross-talk is stated.
    pub stated_cross_talk: &'a [u32],
    /// The readings' rounding level of the residual sum of squares.
    pub tiny: f64,
}

/// The alternatives that explain the data as well as the finding `block` (terms of the
/// final model), best first.
pub fn alternatives(model: FinalModel<'_>, block: &[Term]) -> Vec<Alternative> {
    let FinalModel {
        set,
        base,
        context,
        terms,
        fit,
        sigma,
        stated_cross_talk,
        tiny,
    } = model;
    let rest: Vec<Term> = terms
        .iter()
        .filter(|t| !block.contains(t))
        .cloned()
        .collect();
    let candidates: Vec<Vec<Term>> =
        siblings(set, block, stated_cross_talk, base.is_self_calibration())
            .into_iter()
            .filter(|s| !s.iter().any(|t| rest.contains(t)))
            .collect();
    let mut sets: Vec<Vec<Term>> = candidates.clone();
    // one bad reading is one reading: its alternatives are single readings
    let single = matches!(block.first(), Some(Term::Effect(Effect::Outlier { .. })));
    for i in 0..candidates.len() * usize::from(!single) {
        for j in i + 1..candidates.len() {
            let mut pair = candidates[i].clone();
            pair.extend(candidates[j].iter().cloned());
            sets.push(pair);
        }
    }
    sets.extend(
        other_kinds(set, block)
            .into_iter()
            .filter(|s| !s.iter().any(|t| rest.contains(t) || block.contains(t))),
    );
    let [u_pitch, u_encoder] = base.calibrated_u(fit);
    let [fit_pitch, fit_encoder] = base.calibrated(fit);
    let rest_columns = Term::columns(&rest, set, context);
    let r = block.len().max(1) as f64;
    let mean_square = if fit.dof > 0 {
        fit.rss / fit.dof as f64
    } else {
        0.0
    };
    let mut out: Vec<Alternative> = Vec::new();
    let f_test = |increase: f64| -> (f64, f64) {
        if increase <= tiny {
            (0.0, 1.0)
        } else if mean_square <= tiny / (fit.dof.max(1) as f64) {
            (f64::INFINITY, 0.0)
        } else {
            let f = increase / (r * mean_square);
            let p = FisherSnedecor::new(r, fit.dof.max(1) as f64).map_or(0.0, |d| d.sf(f));
            (f, p)
        }
    };
    // the geometry of the model without the finding, for a screen of the alternatives
    let rest_geometry = base.geometry_without_fit(&rest_columns);
    for alternative in sets {
        let alternative_columns = Term::columns(&alternative, set, context);
        // an alternative that fits far worse (p a thousandth of the level or less, from
        // the geometry's residual sum of squares) is not refitted: its refit would be
        // rejected too, the round-off of either sum being nowhere near the margin
        if let Some(rest_geometry) = &rest_geometry {
            let geometry = base.add_terms(rest_geometry, &alternative_columns);
            let rss = base.rss_without_fit(&geometry);
            if f_test(rss - fit.rss).1 <= AMBIGUITY_ALPHA * SCREEN_MARGIN {
                continue;
            }
        }
        let mut columns = rest_columns.clone();
        columns.extend(alternative_columns);
        let Ok(other) = base.fit(&columns, sigma) else {
            continue;
        };
        let increase = other.rss - fit.rss;
        let (f_statistic, p_value) = f_test(increase);
        if p_value <= AMBIGUITY_ALPHA {
            continue;
        }
        let [other_pitch, other_encoder] = base.calibrated(&other);
        let pitch_change = difference(&other_pitch, &fit_pitch);
        let encoder_change = difference(&other_encoder, &fit_encoder);
        let ratio = |change: &[f64], u: &Option<Vec<f64>>| match u {
            Some(u) => change
                .iter()
                .zip(u)
                .map(|(c, u)| {
                    let expanded = AMBIGUITY_COVERAGE_FACTOR * u;
                    if expanded > 0.0 {
                        c.abs() / expanded
                    } else if c.abs() > 0.0 {
                        f64::INFINITY
                    } else {
                        0.0
                    }
                })
                .fold(0.0, f64::max),
            None => 0.0,
        };
        let change_over_expanded_u =
            ratio(&pitch_change, &u_pitch).max(ratio(&encoder_change, &u_encoder));
        let values = base.term_values(&other).get(rest.len()..).unwrap_or(&[]);
        let mut effects = Vec::new();
        let mut start = 0;
        for sibling in split_siblings(&alternative) {
            let end = start + sibling.len();
            if let Some(e) = block_effect(&sibling, &values[start..end.min(values.len())]) {
                effects.push(e);
            }
            start = end;
        }
        out.push(Alternative {
            effects,
            f_statistic,
            p_value,
            pitch_change_max: max_abs(&pitch_change),
            encoder_change_max: max_abs(&encoder_change),
            change_over_expanded_u,
            equivalent: increase <= tiny,
        });
    }
    out.sort_by(|a, b| a.f_statistic.total_cmp(&b.f_statistic));
    out
}

/// The sibling blocks a set of alternative terms is made of (consecutive terms of one
/// kind and stream belong together).
fn split_siblings(terms: &[Term]) -> Vec<Vec<Term>> {
    let key = |t: &Term| -> (u32, Option<u32>, &'static str) {
        match *t {
            Term::Effect(Effect::Drift { ac, .. })
            | Term::Quadratic { ac }
            | Term::DriftShape { ac, .. }
            | Term::DriftKink { ac, .. } => (ac, None, "drift"),
            Term::RezeroCycle { ac, setup, .. } => (ac, setup, "rezero"),
            _ => (u32::MAX, None, "single"),
        }
    };
    let mut out: Vec<Vec<Term>> = Vec::new();
    for t in terms {
        match out.last_mut() {
            Some(last) if key(&last[0]) == key(t) && key(t).2 != "single" => last.push(t.clone()),
            _ => out.push(vec![t.clone()]),
        }
    }
    out
}

/// What would move a common cross-talk: the pitch deviations and encoder errors that the
/// `reading_y` values give when evaluated as readings through the base model (β_Y, α_Y).
/// A cross-talk c common to all autocollimators moves β by c·β_Y and α by c·α_Y and
/// leaves the residual part of `reading_y` only. `None` when a reading has no
/// `reading_y`, or `reading_y` spans at most `min_span_arcsec`.
pub fn common_cross_talk_reach(
    set: &MeasurementSet,
    base: &Base<'_>,
    min_span_arcsec: f64,
) -> Option<(f64, f64, f64)> {
    let ys: Vec<f64> = set
        .readings
        .iter()
        .map(|r| r.reading_y_arcsec)
        .collect::<Option<Vec<f64>>>()?;
    let span = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - ys.iter().copied().fold(f64::INFINITY, f64::min);
    if span.is_nan() || span <= min_span_arcsec {
        return None;
    }
    let fit = base.fit_values(&ys).ok()?;
    Some((
        span,
        max_abs(&fit.pitch_deviation),
        max_abs(&fit.encoder_error),
    ))
}
