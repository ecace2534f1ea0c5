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

use rayon::prelude::*;

use super::geometry::{BlockScore, ColumnScore, FitGeometry, SuffixCache};

/// The fewest readings of a stream on either side of a jump (fewer are outliers).
pub const MIN_STEP_READINGS: usize = 3;

/// The highest order of a smooth drift: linear, quadratic, then Legendre shapes of orders
/// 3 … `MAX_DRIFT_ORDER` over the run's time span, the order picked by F tests.
pub const MAX_DRIFT_ORDER: usize = 4;

/// The fewest cycles of a stream for which a zero set anew every cycle (`rezero`) is
/// tried.
pub const MIN_REZERO_CYCLES: u32 = 3;

/// One column of the model: an effect's value, or a part of a multi-column effect.
#[derive(Debug, Clone, PartialEq)]
pub enum Term {
    /// The `value` of an effect (docs/FORMAT.md §6).
    Effect(Effect),
    /// The `quadratic` of the drift of autocollimator `ac`, arcsec/h² (per stop² on the
    /// stop clock).
    Quadratic {
        /// Autocollimator number.
        ac: u32,
    },
    /// The shape of order `order` (≥ 3) of the drift of autocollimator `ac`: the Legendre
    /// polynomial P_order(τ), τ the reading's time mapped onto −1 … 1 over the run's
    /// span; its value is in arcsec.
    DriftShape {
        /// Autocollimator number.
        ac: u32,
        /// Polynomial order, 3 … [`MAX_DRIFT_ORDER`].
        order: usize,
    },
    /// The change of rate of autocollimator `ac`'s drift from the clock time `at_seconds`
    /// on: the hinge max(0, t − t_k) in hours, so that with the linear drift the drift is
    /// continuous and piecewise linear with its kink at t_k; its value is in arcsec/h
    /// (per stop on the stop clock).
    DriftKink {
        /// Autocollimator number.
        ac: u32,
        /// Where the rate changes, seconds of the clock.
        at_seconds: f64,
    },
    /// The offset of autocollimator `ac`'s zero in cycle `cycle` (of mounting `setup`,
    /// when given) against its first cycle: one column of a `rezero`.
    RezeroCycle {
        /// Autocollimator number.
        ac: u32,
        /// Mounting, or `None` for every mounting.
        setup: Option<u32>,
        /// Cycle (≥ 2).
        cycle: u32,
    },
}

/// The Legendre polynomial P_k(τ).
fn legendre(k: usize, tau: f64) -> f64 {
    let (mut previous, mut current) = (1.0, tau);
    if k == 0 {
        return 1.0;
    }
    for n in 1..k {
        let next = ((2 * n + 1) as f64 * tau * current - n as f64 * previous) / (n + 1) as f64;
        previous = current;
        current = next;
    }
    current
}

/// The span of the readings' times, seconds (first, last); (0, 0) without times.
pub fn time_span(set: &MeasurementSet) -> (f64, f64) {
    let times = set.readings.iter().filter_map(|r| r.time_seconds);
    let (lo, hi) = times.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
        (lo.min(t), hi.max(t))
    });
    if lo.is_finite() { (lo, hi) } else { (0.0, 0.0) }
}

impl Term {
    /// The term's column: one value per reading.
    pub fn column(&self, set: &MeasurementSet, context: &EffectContext) -> Vec<f64> {
        Term::columns(std::slice::from_ref(self), set, context)
            .pop()
            .unwrap_or_default()
    }

    /// The columns of `terms`, in their order: one pass over the readings in chunks that
    /// stay in cache, every term's values of a chunk filled from it (a reading is read
    /// once, not once per term).
    pub fn columns(terms: &[Term], set: &MeasurementSet, context: &EffectContext) -> Vec<Vec<f64>> {
        const CHUNK: usize = 2048;
        let n = set.readings.len();
        // the run's span is read by a drift's shapes alone
        let span = if terms.iter().any(|t| matches!(t, Term::DriftShape { .. })) {
            time_span(set)
        } else {
            (0.0, 0.0)
        };
        let mut out = vec![vec![0.0; n]; terms.len()];
        for start in (0..n).step_by(CHUNK) {
            let end = (start + CHUNK).min(n);
            let readings = &set.readings[start..end];
            for (term, column) in terms.iter().zip(out.iter_mut()) {
                term.fill(readings, &mut column[start..end], context, span);
            }
        }
        // a weighted diagnosis's columns are whitened, as its fits' readings are
        if let Some(weights) = &context.weights
            && weights.len() == n
        {
            for column in &mut out {
                for (x, w) in column.iter_mut().zip(weights.iter()) {
                    *x *= w;
                }
            }
        }
        out
    }

    /// The term's values of `readings` into `out` (one each); `span` is the run's
    /// [`time_span`].
    fn fill(
        &self,
        readings: &[Reading],
        out: &mut [f64],
        context: &EffectContext,
        span: (f64, f64),
    ) {
        let values = out.iter_mut().zip(readings);
        match self {
            Term::Effect(effect) => {
                for (o, r) in values {
                    *o = effect.regressor(r, context);
                }
            }
            Term::Quadratic { ac } => {
                let drift = Effect::Drift {
                    ac: *ac,
                    value: 0.0,
                    quadratic: None,
                };
                for (o, r) in values {
                    *o = drift.quadratic_regressor(r);
                }
            }
            Term::DriftShape { ac, order } => {
                let (lo, hi) = span;
                let half = 0.5 * (hi - lo);
                for (o, r) in values {
                    *o = match r.time_seconds {
                        Some(t) if r.ac == *ac && half > 0.0 => {
                            legendre(*order, (t - lo) / half - 1.0)
                        }
                        _ => 0.0,
                    };
                }
            }
            Term::DriftKink { ac, at_seconds } => {
                for (o, r) in values {
                    *o = match r.time_seconds {
                        Some(t) if r.ac == *ac => ((t - at_seconds) / 3600.0).max(0.0),
                        _ => 0.0,
                    };
                }
            }
            Term::RezeroCycle { ac, setup, cycle } => {
                for (o, r) in values {
                    let hit =
                        r.ac == *ac && setup.is_none_or(|s| r.setup == s) && r.cycle == *cycle;
                    *o = if hit { 1.0 } else { 0.0 };
                }
            }
        }
    }

    /// Whether two terms are the same column (values ignored).
    pub fn same(&self, other: &Term) -> bool {
        match (self, other) {
            (Term::Effect(a), Term::Effect(b)) => {
                a.clone().with_value(0.0) == b.clone().with_value(0.0)
            }
            (a, b) => a == b,
        }
    }

    /// The kind of the term as in docs/FORMAT.md §6 (`drift` for a drift's curvature and
    /// shape, `rezero` for a cycle's offset).
    pub fn kind(&self) -> &'static str {
        match self {
            Term::Effect(e) => e.kind(),
            Term::Quadratic { .. } | Term::DriftShape { .. } | Term::DriftKink { .. } => "drift",
            Term::RezeroCycle { .. } => "rezero",
        }
    }

    /// The drift order this term is of autocollimator `ac`'s drift (1 the linear drift,
    /// 2 its curvature, 3… its shapes); `None` for other terms.
    pub fn drift_order(&self, of_ac: u32) -> Option<usize> {
        match *self {
            Term::Effect(Effect::Drift { ac, .. }) if ac == of_ac => Some(1),
            Term::Quadratic { ac } if ac == of_ac => Some(2),
            Term::DriftShape { ac, order } if ac == of_ac => Some(order),
            _ => None,
        }
    }

    /// Whether this term is part of autocollimator `ac`'s drift: an order of it
    /// ([`Term::drift_order`]) or its kink.
    pub fn is_drift_of(&self, of_ac: u32) -> bool {
        self.drift_order(of_ac).is_some()
            || matches!(*self, Term::DriftKink { ac, .. } if ac == of_ac)
    }

    /// The drift term of order `order` of autocollimator `ac`.
    pub fn drift_of_order(ac: u32, order: usize) -> Term {
        match order {
            1 => Term::Effect(Effect::Drift {
                ac,
                value: 0.0,
                quadratic: None,
            }),
            2 => Term::Quadratic { ac },
            _ => Term::DriftShape { ac, order },
        }
    }
}

/// The family a candidate is corrected within.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Family {
    /// Drift of any order, temperature, cross-talk, direction, a zero set anew every
    /// cycle.
    Systematic,
    /// A jump of a zero at any stop.
    OffsetStep,
    /// One bad reading.
    Outlier,
}

/// A candidate with its score against the current fit: one term, or a block of terms
/// added together (a drift's further orders, a zero per cycle) and tested by one F test
/// with as many numerator degrees of freedom as directions it adds.
#[derive(Debug, Clone)]
pub struct Candidate {
    /// The term that names the candidate (the first of its block).
    pub term: Term,
    /// The other terms of its block (empty for a single column).
    pub block: Vec<Term>,
    /// Its family.
    pub family: Family,
    /// The reduction of the residual sum of squares it would bring.
    pub reduction: f64,
    /// The number of directions it adds (numerator degrees of freedom of its F test).
    pub rank: usize,
    /// The value of its first term if it were added.
    pub value: f64,
    /// For an outlier: the reading and its studentized residual.
    pub outlier: Option<(usize, f64)>,
}

impl Candidate {
    /// A single-column candidate from its column score.
    pub fn single(term: Term, family: Family, score: &ColumnScore) -> Self {
        Candidate {
            term,
            block: Vec::new(),
            family,
            reduction: score.reduction(),
            rank: usize::from(score.is_new()),
            value: if score.is_new() {
                score.projection / score.new_length_squared
            } else {
                0.0
            },
            outlier: None,
        }
    }

    /// A block candidate from its block score.
    pub fn block(mut terms: Vec<Term>, family: Family, score: &BlockScore) -> Option<Self> {
        if terms.is_empty() {
            return None;
        }
        let term = terms.remove(0);
        Some(Candidate {
            term,
            block: terms,
            family,
            reduction: score.reduction,
            rank: score.rank,
            value: score.values.first().copied().unwrap_or(0.0),
            outlier: None,
        })
    }

    /// Every term of the candidate, the naming one first.
    pub fn terms(&self) -> Vec<Term> {
        let mut all = vec![self.term.clone()];
        all.extend(self.block.iter().cloned());
        all
    }

    /// The term's value if it were added (for a block: its first term's).
    pub fn value(&self) -> f64 {
        self.value
    }

    /// Whether the candidate adds a direction to the model.
    pub fn is_new(&self) -> bool {
        self.rank > 0
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

/// The systematic candidates not yet in the model (`present`), each a block of terms
/// added together: for every autocollimator its drift's next orders (when every reading
/// has a clock: `time`, or the stop order), temperature, cross-talk (unless `stated`),
/// direction, and a zero set anew every cycle (per stream of [`step_streams`], with at
/// least [`MIN_REZERO_CYCLES`] cycles). ([`SystematicLayout`] keeps what this reads of
/// the set for the rounds of a search.)
pub fn systematic_blocks(set: &MeasurementSet, present: &[Term], stated: &[u32]) -> Vec<Vec<Term>> {
    SystematicLayout::of(set, stated).blocks(present)
}

/// What [`systematic_blocks`] reads of a set, read once: a search asks for the blocks of
/// every round.
#[derive(Debug, Clone)]
pub struct SystematicLayout {
    /// The autocollimators with their readings, when every reading has a clock.
    timed: Option<Vec<(u32, usize)>>,
    /// The autocollimators, when every reading has a temperature.
    temperature: Vec<u32>,
    /// The autocollimators whose cross-talk is a candidate.
    cross_talk: Vec<u32>,
    /// The autocollimators, when both directions were measured (with several, each one's
    /// direction offset too).
    direction: Option<Vec<u32>>,
    /// The zero-per-cycle blocks of the streams that have enough cycles.
    rezero: Vec<Vec<Term>>,
}

impl SystematicLayout {
    /// The layout of `set`, with the cross-talk of the autocollimators `stated` known.
    pub fn of(set: &MeasurementSet, stated: &[u32]) -> Self {
        let acs = autocollimators(set);
        let timed = set
            .readings
            .iter()
            .all(|r| r.time_seconds.is_some())
            .then(|| {
                acs.iter()
                    .map(|&ac| (ac, set.readings.iter().filter(|r| r.ac == ac).count()))
                    .collect()
            });
        let temperature = if set.readings.iter().all(|r| r.temperature_celsius.is_some()) {
            acs.clone()
        } else {
            Vec::new()
        };
        let cross_talk = acs
            .iter()
            .copied()
            .filter(|ac| {
                !stated.contains(ac)
                    && set
                        .readings
                        .iter()
                        .filter(|r| r.ac == *ac)
                        .all(|r| r.reading_y_arcsec.is_some())
            })
            .collect();
        let direction = both_directions(set).then(|| acs.clone());
        let rezero = step_streams(set)
            .into_iter()
            .map(|(ac, setup)| rezero_block(set, ac, setup))
            .filter(|block| block.len() + 1 >= MIN_REZERO_CYCLES as usize)
            .collect();
        SystematicLayout {
            timed,
            temperature,
            cross_talk,
            direction,
            rezero,
        }
    }

    /// The blocks not yet in the model (`present`), as [`systematic_blocks`].
    pub fn blocks(&self, present: &[Term]) -> Vec<Vec<Term>> {
        let mut blocks: Vec<Vec<Term>> = Vec::new();
        for &(ac, readings) in self.timed.iter().flatten() {
            let have = present
                .iter()
                .filter_map(|t| t.drift_order(ac))
                .max()
                .unwrap_or(0);
            for order in have + 1..=MAX_DRIFT_ORDER {
                if readings < 4 * order {
                    break;
                }
                blocks.push(
                    (have + 1..=order)
                        .map(|k| Term::drift_of_order(ac, k))
                        .collect(),
                );
            }
        }
        let single = |t: Term| vec![t];
        blocks.extend(
            self.temperature
                .iter()
                .map(|&ac| single(Term::Effect(Effect::Temperature { ac, value: 0.0 }))),
        );
        blocks.extend(
            self.cross_talk
                .iter()
                .map(|&ac| single(Term::Effect(Effect::CrossTalk { ac, value: 0.0 }))),
        );
        if let Some(acs) = &self.direction {
            blocks.push(single(Term::Effect(Effect::Direction {
                ac: None,
                value: 0.0,
            })));
            if acs.len() > 1 {
                blocks.extend(acs.iter().map(|&ac| {
                    single(Term::Effect(Effect::Direction {
                        ac: Some(ac),
                        value: 0.0,
                    }))
                }));
            }
        }
        blocks.extend(self.rezero.iter().cloned());
        blocks.retain(|b| !b.iter().any(|t| present.iter().any(|p| p.same(t))));
        blocks
    }
}

/// The columns of a zero set anew every cycle in stream (`ac`, `setup`): one offset per
/// cycle after the stream's first (the first is the setup error's).
pub fn rezero_block(set: &MeasurementSet, ac: u32, setup: Option<u32>) -> Vec<Term> {
    let mut cycles: Vec<u32> = set
        .readings
        .iter()
        .filter(|r| r.ac == ac && setup.is_none_or(|s| r.setup == s))
        .map(|r| r.cycle)
        .collect();
    cycles.sort_unstable();
    cycles.dedup();
    cycles
        .into_iter()
        .skip(1)
        .map(|cycle| Term::RezeroCycle { ac, setup, cycle })
        .collect()
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
    let mut search = StepSearch::new();
    let mut scores = Vec::new();
    offset_step_scores_with(set, geometry, residuals, present, &mut search, &mut scores);
    scores
        .iter()
        .filter_map(|score| search.candidate(set, score))
        .collect()
}

/// A stream a jump can belong to: (autocollimator, mounting when the file has several).
type StepStream = (u32, Option<u32>);

/// What a change-point search keeps from one round of a diagnosis to the next (of one
/// set): every stream's readings in time order. (The streams' suffix quadratics are kept
/// by the geometry: a diagnosis's geometries share its base fit's, which adding a term to
/// the model does not change.)
#[derive(Debug, Clone, Default)]
pub struct StepSearch {
    /// The streams of [`step_streams`] with their readings in time order.
    streams: Option<Vec<(StepStream, Vec<usize>)>>,
}

/// A jump candidate of a round, as compact as a round's thousands of them need: its
/// stream, the reading it starts at and its score. [`StepSearch::candidate`] gives its
/// [`Candidate`] (one column, one direction: `rank` 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepScore {
    /// The stream: its index in the search's streams ([`StepSearch::stream`]).
    pub stream: usize,
    /// The reading the jump starts at: its place in the stream's time order.
    pub position: usize,
    /// The reduction of the residual sum of squares it would bring.
    pub reduction: f64,
    /// The jump's value if it were added, arcsec.
    pub value: f64,
}

impl StepSearch {
    /// Nothing kept yet.
    pub fn new() -> Self {
        Self::default()
    }

    /// The stream of `score`: (autocollimator, mounting when the file has several);
    /// `None` for a score this search did not give.
    pub fn stream(&self, score: &StepScore) -> Option<StepStream> {
        self.streams
            .as_ref()?
            .get(score.stream)
            .map(|(stream, _)| *stream)
    }

    /// The candidate `score` names (of this search's set `set`, whose
    /// [`offset_step_scores_with`] gave it); `None` for a score it did not give.
    pub fn candidate(&self, set: &MeasurementSet, score: &StepScore) -> Option<Candidate> {
        let ((ac, setup), order) = self.streams.as_ref()?.get(score.stream)?;
        let (cycle, step) = step_at(set, order, score.position)?;
        Some(Candidate {
            term: Term::Effect(Effect::OffsetStep {
                ac: *ac,
                cycle,
                step,
                setup: *setup,
                value: 0.0,
            }),
            block: Vec::new(),
            family: Family::OffsetStep,
            reduction: score.reduction,
            rank: 1,
            value: score.value,
            outlier: None,
        })
    }
}

/// The (cycle, stop) of a jump at reading `order[position]` of a stream: a jump at a
/// cycle's (or a mounting's) first reading is a jump "from that cycle on" (stop `None`).
fn step_at(set: &MeasurementSet, order: &[usize], position: usize) -> Option<(u32, Option<usize>)> {
    let r = &set.readings[*order.get(position)?];
    let previous = &set.readings[*order.get(position.checked_sub(1)?)?];
    let from_cycle_start = previous.cycle != r.cycle || previous.setup != r.setup;
    Some((r.cycle, (!from_cycle_start).then_some(r.step)))
}

/// Every jump candidate of every stream, scored by one suffix scan per stream, with what
/// does not change between rounds kept in `search` (for one set), the scores pushed onto
/// `out` in the streams' order and each stream's time order; a jump the model holds
/// (`present`) or whose column adds no direction is left out.
pub fn offset_step_scores_with(
    set: &MeasurementSet,
    geometry: &FitGeometry,
    residuals: &[f64],
    present: &[Term],
    search: &mut StepSearch,
    out: &mut Vec<StepScore>,
) {
    let streams = search.streams.get_or_insert_with(|| {
        step_streams(set)
            .into_iter()
            .map(|(ac, setup)| ((ac, setup), stream_in_time_order(set, ac, setup)))
            .collect()
    });
    // every stream's suffix scan, side by side
    let scored: Vec<Option<Vec<ColumnScore>>> = streams
        .par_iter()
        .map(|(_, order)| {
            (order.len() >= 2 * MIN_STEP_READINGS)
                .then(|| geometry.suffix_scores_with(order, residuals, &mut SuffixCache::new()))
        })
        .collect();
    for (stream, (((ac, setup), order), scores)) in streams.iter().zip(scored).enumerate() {
        let Some(scores) = scores else {
            continue;
        };
        // only a jump of this stream can be the same term as a candidate of it
        let present: Vec<(u32, Option<usize>)> = present
            .iter()
            .filter_map(|t| match t {
                Term::Effect(Effect::OffsetStep {
                    ac: a,
                    setup: s,
                    cycle,
                    step,
                    ..
                }) if a == ac && s == setup => Some((*cycle, *step)),
                _ => None,
            })
            .collect();
        for (position, score) in scores
            .iter()
            .enumerate()
            .take(order.len() - MIN_STEP_READINGS + 1)
            .skip(MIN_STEP_READINGS)
        {
            if !score.is_new()
                || (!present.is_empty()
                    && step_at(set, order, position).is_some_and(|at| present.contains(&at)))
            {
                continue;
            }
            out.push(StepScore {
                stream,
                position,
                reduction: score.reduction(),
                value: score.projection / score.new_length_squared,
            });
        }
    }
}
