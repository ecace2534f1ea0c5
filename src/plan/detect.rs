//! What a diagnosis of a run of a design can see, before it is measured.
//!
//! `diagnose` scores each candidate term by the part of its column the model does not
//! span ([`crate::diagnose::geometry`]) and adds the candidate with the smallest
//! Bonferroni-adjusted p-value of its round when that p is below its family's false-alarm
//! probability. Both depend on the design alone. For each effect term this module gives:
//!
//! - whether the design can tell it from the base model at all (`identifiable`: its
//!   column adds a direction, as `diagnose` decides it);
//! - the smallest size found in 90 % of runs, from [`super::selection`]'s emulation of
//!   the round in which `diagnose` offers it (the first; a drift's curvature in the
//!   second, with the linear drift in the model): a jump is sized at up to
//!   [`JUMP_STOPS_SIZED`] spread stops of its stream and reported at the best;
//! - the pairs of the same kind the design cannot tell apart: with a at its 90 % size,
//!   b leaves the F test of a against b the noncentrality λ·(1 − ρ²), ρ the correlation
//!   of their projected columns, below the 5 % critical value of χ²₁ (the level of
//!   `diagnose`'s identifiability check).

use rayon::prelude::*;
use serde::Serialize;

use super::power::{critical_f, noncentrality_for_power};
use super::selection::{Column, Round};
use super::{DETECTION_POWER, PlanError};
use crate::diagnose::DiagnoseOptions;
use crate::diagnose::base::Base;
use crate::diagnose::candidates::{
    self, Family, MIN_STEP_READINGS, Term, step_streams, stream_in_time_order, systematic_blocks,
};
use crate::diagnose::geometry::FitGeometry;
use crate::effects::{Effect, EffectContext};
use crate::measurement::MeasurementSet;
use crate::progress::Progress;
use crate::solve::Solution;

/// The false-alarm probability of the ambiguity test (as `diagnose`'s).
const AMBIGUITY_ALPHA: f64 = 0.05;

/// A cross-talk term whose column lies within 10 % of the model's span is not tried by
/// `diagnose` (as there).
const CROSS_TALK_MIN_NEW_FRACTION: f64 = 0.1;

/// What a design lets a diagnosis see of one effect term.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Detectable {
    /// The kind (docs/FORMAT.md §6): `drift` (of order 1, or its curvature: `order` 2), `offset-step`, `rezero`,
    /// `direction`, `cross-talk`, `temperature`.
    pub kind: &'static str,
    /// The autocollimator (`null` for a direction offset of all).
    pub ac: Option<u32>,
    /// The mounting, for a stream's terms when the design has several.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub setup: Option<u32>,
    /// For a drift: 1 for the linear drift, 2 for its curvature (`quadratic`), as
    /// `diagnose` reports a drift's `order`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub order: Option<usize>,
    /// Whether the design can tell the term from the base model at all.
    pub identifiable: bool,
    /// The size found with 90 % probability, in [`Detectable::unit`]; `null` when not
    /// identifiable.
    pub size: Option<f64>,
    /// The unit of `size`, as `simulate` takes the effect: `arcsec/h` (a drift),
    /// `arcsec/h^2` (its curvature), `arcsec` (a jump, a direction offset, the standard
    /// deviation of a zero set anew every cycle), `arcsec/arcsec` (cross-talk),
    /// `arcsec/degC` (temperature).
    pub unit: &'static str,
    /// Numerator degrees of freedom of its F test.
    pub df: usize,
    /// The candidates of its family in the first round (the Bonferroni divisor).
    pub family_size: usize,
    /// The fraction of its column outside the base model's span, √(‖x̃‖²/‖x‖²).
    pub new_fraction: f64,
    /// A jump: the cycle of the stop where it is seen best (the `size`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cycle: Option<u32>,
    /// A jump: the step of that stop (absent for a jump at a cycle's first reading,
    /// "from that cycle on").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub step: Option<usize>,
    /// A jump: the median of the 90 % sizes over every stop it may happen at.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub median_size: Option<f64>,
}

/// One explanation of a pair the design cannot tell apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Explanation {
    /// Its kind.
    pub kind: &'static str,
    /// Its autocollimator (`null`: all).
    pub ac: Option<u32>,
    /// Its mounting, where it applies.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub setup: Option<u32>,
}

/// Two explanations the data of a run of the design cannot tell apart.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ambiguity {
    /// The first.
    pub first: Explanation,
    /// The second.
    pub second: Explanation,
    /// The correlation of their columns projected off the model's span.
    pub correlation: f64,
}

/// A term the plan looks at, with how it is named.
struct Looked {
    kind: &'static str,
    ac: Option<u32>,
    setup: Option<u32>,
    unit: &'static str,
}

fn looked(term: &Term) -> Option<Looked> {
    let (kind, ac, setup, unit) = match term {
        Term::Effect(Effect::Drift { ac, .. }) => ("drift", Some(*ac), None, "arcsec/h"),
        Term::Effect(Effect::Direction { ac, .. }) => ("direction", *ac, None, "arcsec"),
        Term::Effect(Effect::CrossTalk { ac, .. }) => {
            ("cross-talk", Some(*ac), None, "arcsec/arcsec")
        }
        Term::Effect(Effect::Temperature { ac, .. }) => {
            ("temperature", Some(*ac), None, "arcsec/degC")
        }
        Term::Quadratic { ac } => ("drift", Some(*ac), None, "arcsec/h^2"),
        Term::RezeroCycle { ac, setup, .. } => ("rezero", Some(*ac), *setup, "arcsec"),
        _ => return None,
    };
    Some(Looked {
        kind,
        ac,
        setup,
        unit,
    })
}

/// Bytes of the diagnosis geometry of `solution` with `extra` effect columns.
fn geometry_bytes(solution: &Solution, extra: usize) -> u128 {
    let p = (solution.layout.len() + extra) as u128;
    3 * p * p * 8
}

/// The most jump columns of one stream a round offers (a sample of its stops, evenly
/// spread; neighbouring stops' columns are nearly the same).
pub const JUMP_COLUMNS_PER_STREAM: usize = 60;

/// The stops of one stream whose jump size is computed (evenly spread, and the best).
pub const JUMP_STOPS_SIZED: usize = 9;

/// What a systematic block names, for grouping: the drift of an autocollimator (any
/// order), else the block's first term.
fn group_key(block: &[Term]) -> String {
    match block.first() {
        Some(Term::Effect(Effect::Drift { ac, .. })) => format!("drift {ac}"),
        Some(Term::Quadratic { ac })
        | Some(Term::DriftShape { ac, .. })
        | Some(Term::DriftKink { ac, .. }) => {
            format!("drift-curvature {ac}")
        }
        Some(Term::RezeroCycle { ac, setup, .. }) => format!("rezero {ac} {setup:?}"),
        Some(Term::Effect(e)) => format!("{:?}", e.clone().with_value(0.0)),
        None => String::new(),
    }
}

/// A systematic block of a round: its terms, its columns, whether it is a candidate, and
/// the fraction of its columns off the model's span.
type TestedBlock = (Vec<Term>, Vec<Vec<f64>>, bool, f64);

/// The systematic blocks of a round, tested as `diagnose` tests them: (block, its
/// columns, whether it is a candidate).
fn systematic(
    set: &MeasurementSet,
    context: &EffectContext,
    geometry: &FitGeometry,
    present: &[Term],
    options: &DiagnoseOptions,
) -> Vec<TestedBlock> {
    let zero = vec![0.0; set.readings.len()];
    systematic_blocks(set, present, &options.stated_cross_talk)
        .into_iter()
        .map(|block| {
            let columns: Vec<Vec<f64>> = block.iter().map(|t| t.column(set, context)).collect();
            let (testable, fraction) = if let [term] = block.as_slice() {
                let score = geometry.score(&columns[0], &zero);
                let is_cross_talk = matches!(term, Term::Effect(Effect::CrossTalk { .. }));
                (
                    score.is_new()
                        && !(is_cross_talk && score.new_fraction() < CROSS_TALK_MIN_NEW_FRACTION),
                    score.new_fraction(),
                )
            } else {
                let gram = geometry.projected_gram(&columns);
                let total: f64 = columns.iter().flatten().map(|x| x * x).sum();
                let rank = geometry.score_block(&columns, &zero).rank;
                (
                    rank > 0,
                    if total > 0.0 {
                        (gram.trace().max(0.0) / total).sqrt()
                    } else {
                        0.0
                    },
                )
            };
            (block, columns, testable, fraction)
        })
        .collect()
}

/// One stream's jump columns: every stop a jump may start at (as `diagnose` scans).
struct Stream {
    ac: u32,
    setup: Option<u32>,
    order: Vec<usize>,
    /// (k in `order`, new fraction) of the stops whose column adds a direction.
    stops: Vec<(usize, f64)>,
}

impl Stream {
    fn column(&self, k: usize, readings: usize) -> Vec<f64> {
        let mut column = vec![0.0; readings];
        for &i in &self.order[k..] {
            column[i] = 1.0;
        }
        column
    }
}

/// Evenly spread picks of at most `most` of `items`.
fn spread<T: Copy>(items: &[T], most: usize) -> Vec<T> {
    if items.len() <= most {
        return items.to_vec();
    }
    (0..most)
        .map(|j| items[(j * (items.len() - 1)) / (most - 1).max(1)])
        .collect()
}

/// What a diagnosis of a run of `set`'s design can see: one [`Detectable`] per effect
/// term (module documentation), and the pairs it cannot tell apart. `solution` is the
/// base fit of the set.
///
/// # Errors
///
/// [`PlanError::TooLarge`] when the geometry would not fit in memory.
pub fn detectable(
    set: &MeasurementSet,
    solution: &Solution,
    sigma: f64,
    options: &DiagnoseOptions,
    memory_limit_bytes: Option<u64>,
    progress: Option<&(dyn Progress + Send)>,
) -> Result<(Vec<Detectable>, Vec<Ambiguity>), PlanError> {
    super::check_memory(
        geometry_bytes(solution, 1),
        "the geometry of a diagnosis of the design",
        memory_limit_bytes,
    )?;
    // the clock drift terms run on, as `diagnose` has it: `time`, or the stop order
    let (clocked, clock) = crate::diagnose::clock::clocked(set);
    let set: &MeasurementSet = &clocked;
    // the fit `diagnose` starts from: in encoder positions, with the sub-pitch cosets'
    // differences in the model (the same cofactor as `solution`'s)
    let base = Base::of(set);
    let geometry = base.geometry(solution, &[]);
    let streams = jump_streams(set, &geometry);
    let design = Design {
        set,
        context: EffectContext::of(&set.readings),
        jump_family: streams.iter().map(|s| s.stops.len()).sum(),
        streams,
        base,
        options,
        sigma,
    };
    let n = set.readings.len();
    let dof = solution.dof;
    let alpha = options.family_alpha;

    // round 1: the systematic blocks and a sample of every stream's jumps
    let blocks = systematic(set, &design.context, &geometry, &[], options);
    let systematic_family = blocks.iter().filter(|b| b.2).count();
    let first = FirstOffer::of(&blocks, &design.streams);
    let round_columns: usize = first.offered.iter().map(|o| o.2.len()).sum();
    super::check_memory(
        Round::bytes_needed(round_columns, n),
        "the simulated rounds of a diagnosis of the design",
        memory_limit_bytes,
    )?;
    let round = Round::new(
        &geometry,
        dof,
        design.orders(),
        first.offered,
        [systematic_family, design.jump_family, n],
        alpha,
    );

    let chi_critical = critical_f(AMBIGUITY_ALPHA, 1, f64::INFINITY);
    let (mut ambiguous, class) = systematic_ambiguities(
        &round,
        &blocks,
        &first.systematic_index,
        lambda_alone(alpha, dof, systematic_family),
        chi_critical,
    );
    let sizes = FirstRoundSizes::of(
        &round,
        &blocks,
        &first.systematic_index,
        &first.sized,
        &class,
        sigma,
        progress,
    );
    let mut out = systematic_entries(
        &round,
        &blocks,
        &first.systematic_index,
        sizes.systematic_arcsec,
        systematic_family,
    );
    let jumps = jump_entries(&design, sizes.jumps_arcsec);

    // round 2 of a drift: its curvature, once the linear drift is in the model
    for ac in candidates::autocollimators(set) {
        let drift = Term::drift_of_order(ac, 1);
        if !blocks
            .iter()
            .any(|b| b.2 && b.0.len() == 1 && b.0[0].same(&drift))
        {
            continue;
        }
        out.extend(curvature_entry(&design, ac, drift));
    }

    // a jump against the same stop's jump of another stream
    if let Some(lambda) = lambda_alone(alpha, dof, design.jump_family) {
        ambiguous.extend(jump_ambiguities(
            set,
            &geometry,
            &jumps,
            lambda,
            chi_critical,
        ));
    }
    out.extend(jumps.into_iter().map(|(d, _)| d));
    if clock == crate::diagnose::Clock::StopOrder {
        per_stop_units(&mut out);
    }
    Ok((out, ambiguous))
}

/// The design a diagnosis looks at, on its clock, with what every round of the emulation
/// shares: the base fit, the jump streams and the jump family's size.
struct Design<'s> {
    set: &'s MeasurementSet,
    context: EffectContext,
    base: Base<'s>,
    options: &'s DiagnoseOptions,
    /// The noise standard deviation the emulated sizes are scaled by, in arcsec.
    sigma: f64,
    streams: Vec<Stream>,
    /// The stops a jump may start at, over every stream (the jump family's Bonferroni
    /// divisor).
    jump_family: usize,
}

impl Design<'_> {
    /// Each stream's readings in time order, as a [`Round`] takes them.
    fn orders(&self) -> Vec<Vec<usize>> {
        self.streams.iter().map(|s| s.order.clone()).collect()
    }
}

/// The streams a jump can belong to, and every stop it may start at (those whose column
/// adds a direction to the base model's span).
fn jump_streams(set: &MeasurementSet, geometry: &FitGeometry) -> Vec<Stream> {
    let zero = vec![0.0; set.readings.len()];
    let mut streams = Vec::new();
    for (ac, setup) in step_streams(set) {
        let order = stream_in_time_order(set, ac, setup);
        if order.len() < 2 * MIN_STEP_READINGS {
            continue;
        }
        let scores = geometry.suffix_scores(&order, &zero);
        let stops = (MIN_STEP_READINGS..=order.len() - MIN_STEP_READINGS)
            .filter(|&k| scores[k].is_new())
            .map(|k| (k, scores[k].new_fraction()))
            .collect();
        streams.push(Stream {
            ac,
            setup,
            order,
            stops,
        });
    }
    streams
}

/// A candidate a round offers: its family, its group and its columns.
type OfferedColumns = (Family, usize, Vec<Column>);

/// What the first round offers: the systematic candidates and a sample of every
/// stream's jumps.
struct FirstOffer {
    offered: Vec<OfferedColumns>,
    /// Per systematic block, its index into `offered` (`usize::MAX`: not a candidate).
    systematic_index: Vec<usize>,
    /// Per stream, the stops sized: (k in its time order, index into `offered`).
    sized: Vec<Vec<(usize, usize)>>,
}

impl FirstOffer {
    /// The first round's candidates of `blocks` and `streams`, grouped by the effect
    /// they would name.
    fn of(blocks: &[TestedBlock], streams: &[Stream]) -> FirstOffer {
        let mut groups: Vec<String> = Vec::new();
        let mut group_of = |key: String| match groups.iter().position(|g| *g == key) {
            Some(g) => g,
            None => {
                groups.push(key);
                groups.len() - 1
            }
        };
        let mut offered: Vec<OfferedColumns> = Vec::new();
        // (index into offered, block) of the systematic candidates
        let mut systematic_index = Vec::new();
        for (block, columns, testable, _) in blocks {
            if *testable {
                systematic_index.push(offered.len());
                offered.push((
                    Family::Systematic,
                    group_of(group_key(block)),
                    columns.iter().cloned().map(Column::Values).collect(),
                ));
            } else {
                systematic_index.push(usize::MAX);
            }
        }
        // the stops sized per stream, and the offered index of each
        let mut sized: Vec<Vec<(usize, usize)>> = Vec::new();
        for (stream_index, stream) in streams.iter().enumerate() {
            let group = group_of(format!("jump {} {:?}", stream.ac, stream.setup));
            let ks: Vec<usize> = stream.stops.iter().map(|s| s.0).collect();
            let mut picks = spread(&ks, JUMP_COLUMNS_PER_STREAM);
            let chosen = spread(&ks, JUMP_STOPS_SIZED);
            for k in &chosen {
                if !picks.contains(k) {
                    picks.push(*k);
                }
            }
            let mut here = Vec::new();
            for k in picks {
                if chosen.contains(&k) {
                    here.push((k, offered.len()));
                }
                offered.push((
                    Family::OffsetStep,
                    group,
                    vec![Column::Suffix {
                        stream: stream_index,
                        from: k,
                    }],
                ));
            }
            sized.push(here);
        }
        FirstOffer {
            offered,
            systematic_index,
            sized,
        }
    }
}

/// The noncentrality a one-column term's own F test needs to be found in 90 % of runs,
/// its level Bonferroni-divided by `family_size` (`None`: no size reaches it).
fn lambda_alone(alpha: f64, dof: usize, family_size: usize) -> Option<f64> {
    noncentrality_for_power(
        alpha / family_size.max(1) as f64,
        DETECTION_POWER,
        1,
        dof.saturating_sub(1) as f64,
    )
}

/// Pairs of one-column systematic terms of the same kind that the data of a run cannot
/// tell apart: at the size its own F test finds in 90 % of runs (noncentrality
/// `lambda`), the other leaves it the noncentrality λ·(1 − ρ²), below the 5 % critical
/// value of χ²₁ (`chi_critical`). Either one found counts as the effect found (the pair
/// is reported), as `diagnose` reports it with its alternative: returned with the pairs,
/// per offered candidate, the groups that count as finding it.
fn systematic_ambiguities(
    round: &Round,
    blocks: &[TestedBlock],
    systematic_index: &[usize],
    lambda: Option<f64>,
    chi_critical: f64,
) -> (Vec<Ambiguity>, Vec<Vec<usize>>) {
    let mut ambiguous = Vec::new();
    let mut class: Vec<Vec<usize>> = (0..round.offered().len())
        .map(|i| vec![round.offered()[i].group])
        .collect();
    let singles: Vec<(usize, Looked)> = blocks
        .iter()
        .zip(systematic_index)
        .filter(|(b, index)| b.2 && b.0.len() == 1 && **index != usize::MAX)
        .filter_map(|(b, &index)| looked(&b.0[0]).map(|l| (index, l)))
        .collect();
    let Some(lambda) = lambda else {
        return (ambiguous, class);
    };
    let indices: Vec<usize> = singles.iter().map(|(index, _)| *index).collect();
    let correlations = round.correlations(&indices);
    for (i, (a, la)) in singles.iter().enumerate() {
        for (j, (b, lb)) in singles.iter().enumerate().skip(i + 1) {
            if la.kind != lb.kind {
                continue;
            }
            let Some(rho) = correlations[i][j] else {
                continue;
            };
            if lambda * (1.0 - (rho * rho).min(1.0)) < chi_critical {
                ambiguous.push(Ambiguity {
                    first: Explanation {
                        kind: la.kind,
                        ac: la.ac,
                        setup: la.setup,
                    },
                    second: Explanation {
                        kind: lb.kind,
                        ac: lb.ac,
                        setup: lb.setup,
                    },
                    correlation: rho,
                });
                let (ga, gb) = (round.offered()[*a].group, round.offered()[*b].group);
                class[*a].push(gb);
                class[*b].push(ga);
            }
        }
    }
    (ambiguous, class)
}

/// The 90 % sizes of the first round, in the unit of each term (σ-scaled).
struct FirstRoundSizes {
    /// Per systematic block, its size (`None`: not sized).
    systematic_arcsec: Vec<Option<f64>>,
    /// Per stream, (k in its time order, size in arcsec) of the stops sized.
    jumps_arcsec: Vec<Vec<(usize, f64)>>,
}

impl FirstRoundSizes {
    /// The sizes, term by term in parallel (each a bisection over the same draws), each
    /// counted for the progress observer once known.
    fn of(
        round: &Round,
        blocks: &[TestedBlock],
        systematic_index: &[usize],
        sized: &[Vec<(usize, usize)>],
        class: &[Vec<usize>],
        sigma: f64,
        progress: Option<&(dyn Progress + Send)>,
    ) -> FirstRoundSizes {
        let column_start = |index: usize| -> (usize, usize) {
            let o = &round.offered()[index];
            (o.start(), o.len())
        };
        let total_sizes = (blocks.len() + sized.iter().map(Vec::len).sum::<usize>()) as u64;
        let sizes_known = std::sync::atomic::AtomicU64::new(0);
        let one_more = || {
            if let Some(progress) = progress {
                let done = sizes_known.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
                progress.update(done, Some(total_sizes));
            }
        };
        let systematic_arcsec: Vec<Option<f64>> = blocks
            .par_iter()
            .zip(systematic_index)
            .map(|((block, _, testable, _), &index)| {
                let size = (|| {
                    let l = block.first().and_then(looked)?;
                    if !*testable || (l.kind == "drift" && block.len() > 1) {
                        return None;
                    }
                    round
                        .size_for(
                            column_start(index),
                            l.kind == "rezero",
                            &class[index],
                            DETECTION_POWER,
                        )
                        .map(|s| s * sigma)
                })();
                one_more();
                size
            })
            .collect();
        let jumps_arcsec: Vec<Vec<(usize, f64)>> = sized
            .par_iter()
            .map(|here| {
                here.par_iter()
                    .filter_map(|&(k, index)| {
                        let size = round
                            .size_for(column_start(index), false, &class[index], DETECTION_POWER)
                            .map(|s| (k, s * sigma));
                        one_more();
                        size
                    })
                    .collect()
            })
            .collect();
        FirstRoundSizes {
            systematic_arcsec,
            jumps_arcsec,
        }
    }
}

/// One entry per systematic effect: a drift by its linear term, a zero per cycle by its
/// block.
fn systematic_entries(
    round: &Round,
    blocks: &[TestedBlock],
    systematic_index: &[usize],
    sizes: Vec<Option<f64>>,
    systematic_family: usize,
) -> Vec<Detectable> {
    let mut out = Vec::new();
    for (((block, columns, testable, fraction), &index), size) in
        blocks.iter().zip(systematic_index).zip(sizes)
    {
        let Some(l) = block.first().and_then(looked) else {
            continue;
        };
        if l.kind == "drift" && block.len() > 1 {
            continue;
        }
        out.push(Detectable {
            kind: l.kind,
            ac: l.ac,
            setup: l.setup,
            order: (l.kind == "drift").then_some(1),
            identifiable: *testable,
            size,
            unit: l.unit,
            df: if *testable {
                round.offered()[index].rank()
            } else {
                columns.len()
            },
            family_size: systematic_family,
            new_fraction: *fraction,
            cycle: None,
            step: None,
            median_size: None,
        });
    }
    out
}

/// A jump per stream: sized at spread stops of the stream, the best reported (with the
/// median of them), each with the column of its best stop.
fn jump_entries(
    design: &Design,
    jump_sizes: Vec<Vec<(usize, f64)>>,
) -> Vec<(Detectable, Vec<f64>)> {
    let set = design.set;
    let n = set.readings.len();
    let mut jumps: Vec<(Detectable, Vec<f64>)> = Vec::new();
    for (stream, mut sizes) in design.streams.iter().zip(jump_sizes) {
        sizes.sort_by(|a, b| a.1.total_cmp(&b.1));
        let best = sizes.first().copied();
        let median = (!sizes.is_empty()).then(|| {
            let m = sizes.len();
            if m % 2 == 1 {
                sizes[m / 2].1
            } else {
                0.5 * (sizes[m / 2 - 1].1 + sizes[m / 2].1)
            }
        });
        let (cycle, step, column, fraction) = match best {
            Some((k, _)) => {
                let r = &set.readings[stream.order[k]];
                let previous = &set.readings[stream.order[k - 1]];
                let from_cycle_start = previous.cycle != r.cycle || previous.setup != r.setup;
                let fraction = stream.stops.iter().find(|s| s.0 == k).map_or(0.0, |s| s.1);
                (
                    Some(r.cycle),
                    if from_cycle_start { None } else { Some(r.step) },
                    stream.column(k, n),
                    fraction,
                )
            }
            None => (None, None, Vec::new(), 0.0),
        };
        jumps.push((
            Detectable {
                kind: "offset-step",
                ac: Some(stream.ac),
                setup: stream.setup,
                order: None,
                identifiable: !stream.stops.is_empty(),
                size: best.map(|b| b.1),
                unit: "arcsec",
                df: 1,
                family_size: design.jump_family,
                new_fraction: fraction,
                cycle,
                step,
                median_size: median,
            },
            column,
        ));
    }
    jumps
}

/// Round 2 of autocollimator `ac`'s drift: its curvature, offered once the linear
/// `drift` is in the model (`None` when the fit with the drift fails).
fn curvature_entry(design: &Design, ac: u32, drift: Term) -> Option<Detectable> {
    let set = design.set;
    let n = set.readings.len();
    let column = drift.column(set, &design.context);
    let with_drift = design.base.fit(std::slice::from_ref(&column), None).ok()?;
    let g = design
        .base
        .geometry(&with_drift, std::slice::from_ref(&column));
    let present = [drift];
    let blocks2 = systematic(set, &design.context, &g, &present, design.options);
    let family2 = blocks2.iter().filter(|b| b.2).count();
    let mut offered2 = Vec::new();
    let mut target = None;
    let mut fraction = 0.0;
    let mut groups2: Vec<String> = Vec::new();
    for (block, columns, testable, f) in &blocks2 {
        let key = group_key(block);
        let group = match groups2.iter().position(|g| *g == key) {
            Some(g) => g,
            None => {
                groups2.push(key);
                groups2.len() - 1
            }
        };
        if matches!(block.as_slice(), [Term::Quadratic { ac: a }] if *a == ac) {
            fraction = *f;
            if *testable {
                target = Some(offered2.len());
            }
        }
        if *testable {
            offered2.push((
                Family::Systematic,
                group,
                columns.iter().cloned().map(Column::Values).collect(),
            ));
        }
    }
    for (stream_index, stream) in design.streams.iter().enumerate() {
        let group = groups2.len() + 1;
        let ks: Vec<usize> = stream.stops.iter().map(|s| s.0).collect();
        for k in spread(&ks, JUMP_COLUMNS_PER_STREAM) {
            offered2.push((
                Family::OffsetStep,
                group,
                vec![Column::Suffix {
                    stream: stream_index,
                    from: k,
                }],
            ));
        }
    }
    let round2 = Round::new(
        &g,
        with_drift.dof,
        design.orders(),
        offered2,
        [family2, design.jump_family, n],
        design.options.family_alpha,
    );
    let size = target.and_then(|index| {
        let o = &round2.offered()[index];
        round2
            .size_for((o.start(), o.len()), false, &[o.group], DETECTION_POWER)
            .map(|s| s * design.sigma)
    });
    Some(Detectable {
        kind: "drift",
        ac: Some(ac),
        setup: None,
        order: Some(2),
        identifiable: target.is_some(),
        size,
        unit: "arcsec/h^2",
        df: 1,
        family_size: family2,
        new_fraction: fraction,
        cycle: None,
        step: None,
        median_size: None,
    })
}

/// Pairs of jumps the data of a run cannot tell apart: a jump against the same stop's
/// jump of another stream, by the test of [`systematic_ambiguities`].
fn jump_ambiguities(
    set: &MeasurementSet,
    geometry: &FitGeometry,
    jumps: &[(Detectable, Vec<f64>)],
    lambda: f64,
    chi_critical: f64,
) -> Vec<Ambiguity> {
    let mut ambiguous = Vec::new();
    for (i, a) in jumps.iter().enumerate() {
        for b in &jumps[i + 1..] {
            let Some(other) = same_stop_column(set, b.0.ac, b.0.setup, a.0.cycle, a.0.step) else {
                continue;
            };
            if a.1.is_empty() {
                continue;
            }
            let gram = geometry.projected_gram(&[a.1.clone(), other]);
            let (aa, bb, ab) = (gram[(0, 0)], gram[(1, 1)], gram[(0, 1)]);
            if aa <= 0.0 || bb <= 0.0 {
                continue;
            }
            let rho = ab / (aa * bb).sqrt();
            if lambda * (1.0 - (rho * rho).min(1.0)) < chi_critical {
                let name = |d: &Detectable| Explanation {
                    kind: d.kind,
                    ac: d.ac,
                    setup: d.setup,
                };
                ambiguous.push(Ambiguity {
                    first: name(&a.0),
                    second: name(&b.0),
                    correlation: rho,
                });
            }
        }
    }
    ambiguous
}

/// A design on the stop-order clock: drifts per stop (and per stop²) rather than per
/// hour.
fn per_stop_units(out: &mut [Detectable]) {
    for d in out {
        d.unit = match d.unit {
            "arcsec/h" => "arcsec/stop",
            "arcsec/h^2" => "arcsec/stop^2",
            other => other,
        };
    }
}

/// The jump column of stream (`ac`, `setup`) at the stop (`cycle`, `step`) in time order.
fn same_stop_column(
    set: &MeasurementSet,
    ac: Option<u32>,
    setup: Option<u32>,
    cycle: Option<u32>,
    step: Option<usize>,
) -> Option<Vec<f64>> {
    let (ac, cycle) = (ac?, cycle?);
    let effect = Effect::OffsetStep {
        ac,
        cycle,
        step,
        setup,
        value: 0.0,
    };
    let context = EffectContext::of(&set.readings);
    let column: Vec<f64> = set
        .readings
        .iter()
        .map(|r| effect.regressor(r, &context))
        .collect();
    column.iter().any(|&x| x != 0.0).then_some(column)
}
