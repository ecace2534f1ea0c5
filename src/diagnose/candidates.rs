//! The terms a diagnosis can add, and the candidates of one round of forward selection,
//! each scored against the current fit without refitting ([`super::geometry`]).
//!
//! Three families, each with its own Bonferroni correction:
//! - *systematic*: `drift` per autocollimator (when every reading has a `time`), its
//!   `quadratic` once the linear drift is in the model, `temperature` per autocollimator
//!   (when every reading has a `temperature`), `cross-talk` per autocollimator (when its
//!   readings have `reading_y` and the design can tell it apart from the polygon and the
//!   encoder), `direction` for all autocollimators and each one (when both directions
//!   were measured);
//! - *offset-step*: a jump of one autocollimator's zero (in one mounting when the file has
//!   several) at every stop of the run in time order — a change-point search; the jump
//!   must leave at least [`MIN_STEP_READINGS`] readings of the stream before it and after
//!   it, since a jump over fewer is an outlier (a jump after the first reading is the
//!   first reading off, as the setup error absorbs the rest);
//! - *outlier*: the reading with the largest studentized residual, among all readings.

use crate::effects::{Effect, EffectContext};
use crate::measurement::{Direction, MeasurementSet, Reading};

use super::geometry::{ColumnScore, FitGeometry};

/// The fewest readings of a stream on either side of a jump (fewer are outliers).
pub const MIN_STEP_READINGS: usize = 3;

/// One column of the model: an effect's value, or the quadratic part of a drift.
#[derive(Debug, Clone, PartialEq)]
pub enum Term {
    /// The `value` of an effect (docs/FORMAT.md §6).
    Effect(Effect),
    /// The `quadratic` of the drift of autocollimator `ac`, arcsec/h².
    Quadratic {
        /// Autocollimator number.
        ac: u32,
    },
}

impl Term {
    /// The term's column: one value per reading.
    pub fn column(&self, set: &MeasurementSet, context: &EffectContext) -> Vec<f64> {
        match self {
            Term::Effect(effect) => set
                .readings
                .iter()
                .map(|r| effect.regressor(r, context))
                .collect(),
            Term::Quadratic { ac } => {
                let drift = Effect::Drift {
                    ac: *ac,
                    value: 0.0,
                    quadratic: None,
                };
                set.readings
                    .iter()
                    .map(|r| drift.quadratic_regressor(r))
                    .collect()
            }
        }
    }

    /// Whether two terms are the same column (values ignored).
    pub fn same(&self, other: &Term) -> bool {
        match (self, other) {
            (Term::Effect(a), Term::Effect(b)) => {
                a.clone().with_value(0.0) == b.clone().with_value(0.0)
            }
            (Term::Quadratic { ac: a }, Term::Quadratic { ac: b }) => a == b,
            _ => false,
        }
    }

    /// The kind of the term as in docs/FORMAT.md §6 (`drift` for a quadratic).
    pub fn kind(&self) -> &'static str {
        match self {
            Term::Effect(e) => e.kind(),
            Term::Quadratic { .. } => "drift",
        }
    }
}

/// The family a candidate is corrected within.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Drift, its curvature, temperature, cross-talk, direction.
    Systematic,
    /// A jump of a zero at any stop.
    OffsetStep,
    /// One bad reading.
    Outlier,
}

/// A candidate term with its score against the current fit.
#[derive(Debug, Clone)]
pub struct Candidate {
    /// The term.
    pub term: Term,
    /// Its family.
    pub family: Family,
    /// Its score.
    pub score: ColumnScore,
    /// For an outlier: the reading and its studentized residual.
    pub outlier: Option<(usize, f64)>,
}

impl Candidate {
    /// The term's value if it were added: xᵀe / (xᵀx − xᵀHx).
    pub fn value(&self) -> f64 {
        if self.score.is_new() {
            self.score.projection / self.score.new_length_squared
        } else {
            0.0
        }
    }
}

/// The autocollimators of the set, ascending.
pub fn autocollimators(set: &MeasurementSet) -> Vec<u32> {
    let mut acs: Vec<u32> = set.readings.iter().map(|r| r.ac).collect();
    acs.sort_unstable();
    acs.dedup();
    acs
}

/// Whether both directions were measured.
pub fn both_directions(set: &MeasurementSet) -> bool {
    let has = |d: Direction| set.readings.iter().any(|r| r.direction == d);
    has(Direction::Cw) && has(Direction::Ccw)
}

/// The systematic candidates not yet in the model (`present`).
pub fn systematic_terms(set: &MeasurementSet, present: &[Term]) -> Vec<Term> {
    let acs = autocollimators(set);
    let mut terms = Vec::new();
    if set.readings.iter().all(|r| r.time_seconds.is_some()) {
        for &ac in &acs {
            let drift = Term::Effect(Effect::Drift {
                ac,
                value: 0.0,
                quadratic: None,
            });
            if present.iter().any(|p| p.same(&drift)) {
                terms.push(Term::Quadratic { ac });
            } else {
                terms.push(drift);
            }
        }
    }
    if set.readings.iter().all(|r| r.temperature_celsius.is_some()) {
        terms.extend(
            acs.iter()
                .map(|&ac| Term::Effect(Effect::Temperature { ac, value: 0.0 })),
        );
    }
    for &ac in &acs {
        if set
            .readings
            .iter()
            .filter(|r| r.ac == ac)
            .all(|r| r.reading_y_arcsec.is_some())
        {
            terms.push(Term::Effect(Effect::CrossTalk { ac, value: 0.0 }));
        }
    }
    if both_directions(set) {
        terms.push(Term::Effect(Effect::Direction {
            ac: None,
            value: 0.0,
        }));
        if acs.len() > 1 {
            terms.extend(acs.iter().map(|&ac| {
                Term::Effect(Effect::Direction {
                    ac: Some(ac),
                    value: 0.0,
                })
            }));
        }
    }
    terms.retain(|t| !present.iter().any(|p| p.same(t)));
    terms
}

/// Position of a reading within its cycle in time order: clockwise cycles run steps
/// 0 … N, counter-clockwise ones N … 0.
fn order_in_cycle(r: &Reading) -> i64 {
    match r.direction {
        Direction::Cw => r.step as i64,
        Direction::Ccw => -(r.step as i64),
    }
}

/// The readings of autocollimator `ac` (in mounting `setup`, if given) in time order.
pub fn stream_in_time_order(set: &MeasurementSet, ac: u32, setup: Option<u32>) -> Vec<usize> {
    let mut order: Vec<usize> = (0..set.readings.len())
        .filter(|&i| {
            let r = &set.readings[i];
            r.ac == ac && setup.is_none_or(|s| r.setup == s)
        })
        .collect();
    order.sort_by_key(|&i| {
        let r = &set.readings[i];
        (r.setup, r.cycle, order_in_cycle(r), i)
    });
    order
}

/// The streams a jump can belong to: each autocollimator, in each mounting when the file
/// has several (a jump in one mounting is not smeared across the others).
pub fn step_streams(set: &MeasurementSet) -> Vec<(u32, Option<u32>)> {
    let several_setups = set
        .readings
        .iter()
        .any(|r| r.setup != set.readings[0].setup);
    let mut streams: Vec<(u32, Option<u32>)> = if several_setups {
        set.streams()
            .into_iter()
            .map(|(setup, ac)| (ac, Some(setup)))
            .collect()
    } else {
        autocollimators(set)
            .into_iter()
            .map(|ac| (ac, None))
            .collect()
    };
    streams.sort_unstable();
    streams
}

/// Every jump candidate of every stream, scored by one suffix scan per stream.
pub fn offset_step_candidates(
    set: &MeasurementSet,
    geometry: &FitGeometry,
    residuals: &[f64],
    present: &[Term],
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for (ac, setup) in step_streams(set) {
        let order = stream_in_time_order(set, ac, setup);
        if order.len() < 2 * MIN_STEP_READINGS {
            continue;
        }
        let scores = geometry.suffix_scores(&order, residuals);
        for k in MIN_STEP_READINGS..=order.len() - MIN_STEP_READINGS {
            let r = &set.readings[order[k]];
            let previous = &set.readings[order[k - 1]];
            // A jump at a cycle's first reading is a jump "from that cycle on".
            let step = (previous.cycle != r.cycle || previous.setup != r.setup).then_some(());
            let effect = Effect::OffsetStep {
                ac,
                cycle: r.cycle,
                step: match step {
                    Some(()) => None,
                    None => Some(r.step),
                },
                setup,
                value: 0.0,
            };
            let term = Term::Effect(effect);
            if present.iter().any(|p| p.same(&term)) || !scores[k].is_new() {
                continue;
            }
            out.push(Candidate {
                term,
                family: Family::OffsetStep,
                score: scores[k],
                outlier: None,
            });
        }
    }
    out
}
