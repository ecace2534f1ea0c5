//! The forward selection of a diagnosis: round by round, every candidate term is scored
//! against the current fit without refitting, the most significant (by its family's
//! Bonferroni-adjusted F test) is refitted and kept unless the lack of fit then fails and
//! is no smaller, judged against one pure error ([`refused_for_lack_of_fit`]); outliers
//! with an indistinguishable twin are named, not dropped; a jump beyond
//! [`MAX_JUMPS_PER_STREAM`] of one zero is not added.

use std::collections::HashSet;

use nalgebra::DMatrix;
use rayon::prelude::*;

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::base::{Base, Ticker};
use super::candidates::{self, Candidate, Family, StepScore, StepSearch, Term};
use super::findings::{Finding, candidate_effect, difference, max_abs, record_not_significant};
use super::geometry::{BlockScore, ColumnScore, FitGeometry, dot};
use super::lack_of_fit::LackOfFit;
use super::{
    DiagnoseOptions, Evidence, FoundEffect, MAX_JUMPS_PER_STREAM, Rejection, TriedEffect, notes,
    residuals,
};
use crate::effects::{Effect, EffectContext};
use crate::measurement::MeasurementSet;
use crate::solve::Solution;
use crate::uncertainty::student::t_two_sided_tail;

/// What the search ends with.
pub(super) struct Outcome {
    /// The terms of the model.
    pub terms: Vec<Term>,
    /// The findings behind them.
    pub findings: Vec<Finding>,
    /// The terms tried and not added.
    pub tried: Vec<TriedEffect>,
    /// Outliers with their indistinguishable twins: (reading, studentized residual).
    pub unattributed_sets: Vec<Vec<(usize, f64)>>,
    /// Streams whose zero would need one jump too many in the last round.
    pub jumps_exceeded: Vec<(u32, Option<u32>)>,
    /// The fit of the model.
    pub fit: Solution,
    /// Its lack-of-fit test.
    pub lack_of_fit: Option<LackOfFit>,
}

impl Outcome {
    /// The base model, searched no further (no redundancy, or noise-free data).
    pub fn base(before: &Solution) -> Self {
        Outcome {
            terms: Vec::new(),
            findings: Vec::new(),
            tried: Vec::new(),
            unattributed_sets: Vec::new(),
            jumps_exceeded: Vec::new(),
            fit: before.clone(),
            lack_of_fit: None,
        }
    }
}

/// The most candidates a round refits (tries) before it gives up.
const MAX_ATTEMPTS: usize = 4;

/// Terms whose columns one task forms ([`Columns::form`]): enough that a task reads the
/// readings for several columns at once, few enough that a round's columns (tens of
/// terms) keep both threads busy.
const FORMED_TOGETHER: usize = 4;

/// The F statistic of a scored candidate against the current fit, from the reduction
/// Δ of the residual sum of squares it brings and the `rank` r of directions it adds:
/// F = (Δ/r)/(rest/(dof − r)).
fn f_statistic(reduction: f64, rank: usize, current: &Solution, tiny: f64) -> f64 {
    let r = rank.max(1);
    let dof = current.dof.saturating_sub(r);
    let rest = (current.rss - reduction).max(0.0);
    if dof == 0 {
        0.0
    } else if rest > tiny {
        (reduction / r as f64) / (rest / dof as f64)
    } else if reduction > tiny {
        f64::INFINITY
    } else {
        0.0
    }
}

/// The F test of a scored candidate adding `rank` directions against the current fit,
/// its statistic `f_statistic` ([`f_statistic`]): the p-value (for r = 1 through
/// Student's t, as before blocks) and its Bonferroni adjustment over `family_size`.
fn evidence(rank: usize, f_statistic: f64, current: &Solution, family_size: usize) -> Evidence {
    let r = rank.max(1);
    let dof = current.dof.saturating_sub(r);
    let p_value = if dof == 0 || f_statistic <= 0.0 {
        1.0
    } else if r == 1 {
        t_two_sided_tail(f_statistic.sqrt(), Some(dof as f64))
    } else if f_statistic.is_infinite() {
        0.0
    } else {
        FisherSnedecor::new(r as f64, dof as f64).map_or(1.0, |d| d.sf(f_statistic))
    };
    Evidence {
        f_statistic,
        p_value,
        p_adjusted: (p_value * family_size.max(1) as f64).min(1.0),
    }
}

/// Whether a candidate the round's F test chose is refused because the lack of fit
/// against pure error still fails with it and is no smaller (`new`: the lack-of-fit test
/// of the fit with it; `old_against_new_pure_error`: the current fit's lack-of-fit test
/// recomputed with the candidate's within-cell columns in the full model).
///
/// # The rule: both fits judged against one pure error
///
/// Let the current model M₀ hold the terms T, the candidate add the columns X_c (rank
/// r), and M₁ = M₀ + X_c. The lack-of-fit test of a model M compares it with its full
/// model F(M): one free mean per cell (and the stops' table errors of a
/// self-calibration) plus the within-cell part W of every effect column of M (its
/// deviations from its cells' means), so that M is nested in F(M). A term that varies
/// within cells (a drift, a jump, a zero per cycle, a temperature, a reading) has a
/// within-cell part W_c, so F(M₁) = F(M₀) + W_c: the two fits' F statistics
///
/// ```text
/// F(M) = [(RSS_M − RSS_F) / (dof_M − ν_F)] / [RSS_F / ν_F]
/// ```
///
/// have different denominators. When the candidate is real, RSS_{F(M₀)} holds its
/// within-cell signal (a head drifting 0.6″/h inflates the pure error of the old fit
/// many times over): the old fit's F is small because its yardstick is inflated, and
/// once the term is fitted the yardstick shrinks to σ², so that a lack of fit the term
/// was hiding (say an encoder's orders above a band limit) shows with a larger F. The
/// comparison `F₁ ≥ F₀` then throws away a real term for a finding that is not its own
/// (issue 46) — the same reason that exempts single readings, in a new form.
///
/// Both M₀ and M₁ are nested in F₁ = F(M₁) (M₀'s columns are cell means, stop effects
/// and terms of T, whose within-cell parts F₁ holds). Judged against that one full
/// model, with s² = RSS_{F₁}/ν₁, ν_L = dof₀ − ν₁ and dof₁ = dof₀ − r,
///
/// ```text
/// F₀* = [(RSS₀ − RSS_{F₁}) / ν_L] / s²,   F₁ = [(RSS₁ − RSS_{F₁}) / (ν_L − r)] / s²,
/// F₁ < F₀*  ⇔  (RSS₀ − RSS₁) / r  >  (RSS₀ − RSS_{F₁}) / ν_L :
/// ```
///
/// the term is kept when its mean square exceeds the mean square of all the current
/// model lacks against F₁ — it explains more per degree of freedom than the average
/// direction the current model falls short in, which is what "reduces the lack of fit"
/// means on one scale. F₀* is the current fit's lack-of-fit test with the candidate's
/// columns in the full model (`old_against_new_pure_error`).
///
/// # Why no false finding comes through it
///
/// The rule differs from the comparison with F₀ only by moving the candidate's
/// within-cell sum of squares w from the pure error into the lack of fit. When the
/// candidate is not real, w is noise, about r_w·σ² for r_w within-cell directions; as a
/// lack of fit that fails has a mean square above σ², moving w pulls the lack-of-fit
/// mean square towards σ² and leaves s² about as it was, so F₀* is at most about F₀: a
/// term that only mops up the between-cell structure of a lack of fit is refused about
/// as often as before, or more. Only a term whose within-cell part is signal — evidence
/// no between-cell structure can give — raises F₀*. When that signal is another term's
/// of the same zero (a drift taken for a jump), the term is kept as any significant
/// term is, and the rules of doubt decide (a drift's orders the final model does not
/// need dropped, a zero that needs several kinds of terms left out as a wander). A candidate
/// without within-cell part (a direction offset) has F₀* = F₀: the rule is then the
/// old one. The search's F tests and their Bonferroni families are not touched, so the
/// false-alarm rates stay as stated (`tests/diagnose_monte_carlo.rs`,
/// `tests/diagnose_selfcal_within_cells.rs`). F₀* is formed only when `new` fails (one
/// more projection onto the within-cell columns, no refit).
fn refused_for_lack_of_fit(
    new: &LackOfFit,
    old_against_new_pure_error: impl FnOnce() -> Option<LackOfFit>,
) -> bool {
    !new.passed()
        && old_against_new_pure_error().is_none_or(|old| new.f_statistic >= old.f_statistic)
}

/// A round's candidates in their order: the systematic ones, the jumps (compact, one per
/// stop of every stream), the outlier; an index runs over them in that order.
struct RoundCandidates<'c> {
    systematic: &'c [Candidate],
    steps: &'c [StepScore],
    outlier: Option<&'c Candidate>,
}

impl RoundCandidates<'_> {
    /// How many there are.
    fn len(&self) -> usize {
        self.systematic.len() + self.steps.len() + usize::from(self.outlier.is_some())
    }

    /// The jump at index `i`, if it is one.
    fn step(&self, i: usize) -> Option<&StepScore> {
        i.checked_sub(self.systematic.len())
            .and_then(|j| self.steps.get(j))
    }

    /// The candidate at index `i` that is not a jump.
    fn other(&self, i: usize) -> Option<&Candidate> {
        if i < self.systematic.len() {
            self.systematic.get(i)
        } else if i == self.systematic.len() + self.steps.len() {
            self.outlier
        } else {
            None
        }
    }

    /// (Δ, directions, family) of the candidate at index `i`.
    fn score(&self, i: usize) -> (f64, usize, Family) {
        match (self.step(i), self.other(i)) {
            (Some(s), _) => (s.reduction, 1, Family::OffsetStep),
            (None, Some(c)) => (c.reduction, c.rank, c.family),
            (None, None) => (0.0, 0, Family::Systematic),
        }
    }

    /// The candidate at index `i`, formed (a jump's term made from its stream and stop).
    fn candidate(&self, i: usize, set: &MeasurementSet, search: &StepSearch) -> Option<Candidate> {
        match (self.step(i), self.other(i)) {
            (Some(s), _) => search.candidate(set, s),
            (None, other) => other.cloned(),
        }
    }
}

/// The candidates of a round whose F tests the round can use, with them, in the
/// candidates' order: every one of the systematic and outlier families (a few), and of
/// the jumps (one per stop of every stream: thousands) only those the round's loop can
/// reach or records — the four strongest significant jumps of streams that may take
/// another (the loop tries at most four candidates), the strongest significant jump of
/// each stream that may not (its one refusal), and the strongest jump of each stream
/// that is not significant (the round's record when nothing is added). A jump's p-value
/// falls as its F statistic grows (one numerator degree of freedom, the same
/// denominator and family for all), so the jumps are ordered by F and the p-values are
/// computed for those and for the few a bisection for the significant ones needs.
fn rank(
    candidates: &RoundCandidates<'_>,
    current: &Solution,
    tiny: f64,
    family_alpha: f64,
    family_size: impl Fn(Family) -> usize,
    stream: impl Fn(&StepScore) -> Option<(u32, Option<u32>)>,
    full: impl Fn(u32, Option<u32>) -> bool,
) -> Vec<(usize, Evidence)> {
    // as the round's loop decides: a candidate is tried unless p·m ≥ α
    let significant = |e: &Evidence| e.p_adjusted < family_alpha || e.p_adjusted.is_nan();
    let mut out: Vec<(usize, Evidence)> = (0..candidates.len())
        .filter(|&i| candidates.step(i).is_none())
        .map(|i| {
            let (reduction, rank, family) = candidates.score(i);
            let f = f_statistic(reduction, rank, current, tiny);
            (i, evidence(rank, f, current, family_size(family)))
        })
        .collect();
    let steps = candidates.steps;
    let first = candidates.systematic.len();
    let step_family = family_size(Family::OffsetStep);
    let f: Vec<f64> = steps
        .iter()
        .map(|s| f_statistic(s.reduction, 1, current, tiny))
        .collect();
    let evidence_of = |j: usize| evidence(1, f[j], current, step_family);
    // strongest first; ties in candidate order
    let stronger = |a: &usize, b: &usize| f[*b].total_cmp(&f[*a]).then(a.cmp(b));
    // A jump whose F is at most LOW is not significant when one at LOW is not (the
    // p-value falls as F grows): only those above it are ordered; of the others, each
    // stream's strongest is kept in one pass.
    const LOW: f64 = 4.0;
    let low_is_not_significant = !significant(&evidence(1, LOW, current, step_family));
    let streams = steps.iter().map(|s| s.stream + 1).max().unwrap_or(0);
    let mut strongest_low: Vec<Option<usize>> = vec![None; streams];
    let mut open_part: Vec<usize> = Vec::new();
    for (j, (score, &fj)) in steps.iter().zip(&f).enumerate() {
        if low_is_not_significant && fj <= LOW {
            let best = &mut strongest_low[score.stream];
            if best.is_none_or(|b| stronger(&j, &b).is_lt()) {
                *best = Some(j);
            }
        } else {
            open_part.push(j);
        }
    }
    // the number of significant jumps: the first `count` in the order of `stronger`,
    // by bisection over partitions (each step halves the part still open)
    let (mut lo, mut hi) = (0, open_part.len());
    while lo < hi {
        let part = &mut open_part[lo..hi];
        let mid = part.len() / 2;
        part.select_nth_unstable_by(mid, stronger);
        if significant(&evidence_of(part[mid])) {
            lo += mid + 1;
        } else {
            hi = lo + mid;
        }
    }
    let (tried, others) = open_part.split_at(lo);
    // the strongest of each stream among `items` that `keep` keeps, by stream index
    let strongest_of_streams = |items: &[usize], keep: &dyn Fn(&StepScore) -> bool| {
        let mut best: Vec<Option<usize>> = vec![None; streams];
        for &j in items {
            if !keep(&steps[j]) {
                continue;
            }
            let b = &mut best[steps[j].stream];
            if b.is_none_or(|b| stronger(&j, &b).is_lt()) {
                *b = Some(j);
            }
        }
        best
    };
    // a score of no stream of the search names no candidate (the round drops it)
    let full_stream = |score: &StepScore| stream(score).is_some_and(|(ac, setup)| full(ac, setup));
    let mut keep: Vec<usize> = strongest_of_streams(tried, &full_stream)
        .into_iter()
        .flatten()
        .collect();
    let mut open: Vec<usize> = tried
        .iter()
        .copied()
        .filter(|&j| !full_stream(&steps[j]))
        .collect();
    if open.len() > MAX_ATTEMPTS {
        open.select_nth_unstable_by(MAX_ATTEMPTS, stronger);
        open.truncate(MAX_ATTEMPTS);
    }
    keep.extend(open);
    let above = strongest_of_streams(others, &|_| true);
    for (a, b) in above.into_iter().zip(strongest_low) {
        let best = match (a, b) {
            (Some(a), Some(b)) => Some(if stronger(&a, &b).is_lt() { a } else { b }),
            (a, b) => a.or(b),
        };
        keep.extend(best);
    }
    out.extend(keep.into_iter().map(|j| (first + j, evidence_of(j))));
    out.sort_unstable_by_key(|&(i, _)| i);
    out
}

/// Runs the forward selection from the base model `before`; notes for people go to
/// `notes`.
pub(super) fn run(
    set: &MeasurementSet,
    base: &Base<'_>,
    context: &EffectContext,
    options: &DiagnoseOptions,
    before: &Solution,
    tiny: f64,
    notes: &mut Vec<String>,
) -> Outcome {
    let sigma = options.sigma;
    let mut known = Columns {
        set,
        context,
        known: Vec::new(),
    };
    let mut step_search = candidates::StepSearch::new();
    let layout = candidates::SystematicLayout::of(set, &options.stated_cross_talk);
    // the candidates of a round: the jumps (thousands) in one vector for every round,
    // the others (a few) in another
    let mut candidates: Vec<Candidate> = Vec::new();
    let mut steps: Vec<StepScore> = Vec::new();
    let mut terms: Vec<Term> = Vec::new();
    let mut findings: Vec<Finding> = Vec::new();
    let mut tried: Vec<TriedEffect> = Vec::new();
    let mut suspects: HashSet<usize> = HashSet::new();
    let mut unattributed_sets: Vec<Vec<(usize, f64)>> = Vec::new();
    let mut cross_talk_noted = false;
    let mut jumps_exceeded: Vec<(u32, Option<u32>)> = Vec::new();
    let mut current = before.clone();
    // the base fit's lack-of-fit test, formed beside the first round's candidates (its
    // cells are the longest part of it; nothing before the round's loop reads it)
    let mut lof_current: Option<LackOfFit> = None;
    let mut lof_pending = true;
    // the Gram matrices of the systematic blocks off the base fit's span (geometry's
    // `core_projected_gram`): (the longest block of nested ones, its matrix)
    let mut core_grams: Vec<(Vec<Term>, nalgebra::DMatrix<f64>)> = Vec::new();
    let mut core_of_grams: Option<FitGeometry> = None;
    while findings.len() < options.max_effects && current.dof >= 2 {
        let columns = known.of(&terms);
        let geometry = base.geometry(&current, &columns);
        // the Gram matrices kept are of the core they were formed with (a new one with
        // the dense reference geometry, formed from every round's fit)
        if core_of_grams
            .as_ref()
            .is_none_or(|core| !core.same_core(&geometry))
        {
            core_grams.clear();
            core_of_grams = Some(geometry.clone());
        }
        candidates.clear();
        let blocks = layout.blocks(&terms);
        // the systematic blocks (their columns formed first), the jumps of every stream
        // and the leverages side by side
        let residuals = &current.residuals;
        steps.clear();
        let step_candidates = &mut steps;
        let known_columns = &mut known;
        let ((leverage, systematic), ()) = rayon::join(
            || {
                rayon::join(
                    || geometry.leverage(),
                    || {
                        known_columns.form(blocks.iter().flatten());
                        let known = &*known_columns;
                        let systematic = Systematic {
                            geometry: &geometry,
                            known,
                            residuals,
                            terms: &terms,
                            ticker: base.ticker(),
                        };
                        systematic.candidates(&blocks, &mut core_grams)
                    },
                )
            },
            || {
                if lof_pending {
                    lof_current = base.lack_of_fit(set, &current, &[], options.lack_of_fit_alpha);
                    lof_pending = false;
                }
                candidates::offset_step_scores_with(
                    set,
                    &geometry,
                    residuals,
                    &terms,
                    &mut step_search,
                    step_candidates,
                );
            },
        );
        let (systematic, cross_talk_untestable) = systematic;
        for ac in cross_talk_untestable {
            if !cross_talk_noted && let Some(note) = notes::cross_talk_untestable(set, ac) {
                notes.push(note);
                cross_talk_noted = true;
            }
        }
        candidates.extend(systematic);
        let studentized = residuals::studentized(&current, &leverage);
        let eligible = studentized.iter().filter(|t| t.is_some()).count();
        if let Some((i, t)) = studentized
            .iter()
            .enumerate()
            .filter(|(i, _)| !suspects.contains(i))
            .filter_map(|(i, t)| t.map(|t| (i, t)))
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        {
            let r = &set.readings[i];
            let several_setups = set.readings.iter().any(|q| q.setup != r.setup);
            // the reading's own column: eᵢ against the residuals, 1 − hᵢᵢ outside the span
            let score = ColumnScore {
                projection: current.residuals[i],
                new_length_squared: 1.0 - leverage[i],
                length_squared: 1.0,
            };
            let mut candidate = Candidate::single(
                Term::Effect(Effect::Outlier {
                    cycle: r.cycle,
                    step: r.step,
                    ac: r.ac,
                    setup: several_setups.then_some(r.setup),
                    value: 0.0,
                }),
                Family::Outlier,
                &score,
            );
            candidate.outlier = Some((i, t));
            candidates.push(candidate);
        }
        // in the order systematic, jumps, outlier
        let (systematic, outlier) = match candidates.last() {
            Some(c) if c.family == Family::Outlier => candidates.split_at(candidates.len() - 1),
            _ => candidates.split_at(candidates.len()),
        };
        let round = RoundCandidates {
            systematic,
            steps: &steps,
            outlier: outlier.first(),
        };
        let systematic_count = systematic
            .iter()
            .filter(|c| c.family == Family::Systematic)
            .count();
        let step_count = steps.len();
        let family_size = |family: Family| match family {
            Family::Outlier => eligible,
            Family::Systematic => systematic_count,
            Family::OffsetStep => step_count,
        };
        let jumps_of = |ac: u32, setup: Option<u32>, terms: &[Term]| {
            terms
                .iter()
                .filter(|t| {
                    matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, .. }) if *a == ac && *s == setup)
                })
                .count()
        };
        let full =
            |ac: u32, setup: Option<u32>| jumps_of(ac, setup, &terms) >= MAX_JUMPS_PER_STREAM;
        let scored = rank(
            &round,
            &current,
            tiny,
            options.family_alpha,
            family_size,
            |score| step_search.stream(score),
            full,
        );
        let mut scored: Vec<(Candidate, Evidence)> = scored
            .into_iter()
            .filter_map(|(i, e)| Some((round.candidate(i, set, &step_search)?, e)))
            .collect();
        scored.sort_by(|a, b| {
            a.1.p_adjusted
                .total_cmp(&b.1.p_adjusted)
                .then(b.1.f_statistic.total_cmp(&a.1.f_statistic))
        });
        // A further jump of a zero that already jumped as often as a diagnosis accepts is
        // not tried: the stream is marked, and a smooth drift or a zero per cycle of it
        // may still take the structure.
        jumps_exceeded.clear();
        let mut attempts = 0;
        let mut accepted = false;
        for (candidate, ev) in &scored {
            if attempts >= MAX_ATTEMPTS || ev.p_adjusted >= options.family_alpha {
                break;
            }
            let rejected = |rejection| TriedEffect {
                effect: candidate_effect(candidate),
                quadratic: matches!(candidate.term, Term::Quadratic { .. }),
                evidence: *ev,
                rejection,
            };
            if let Term::Effect(Effect::OffsetStep { ac, setup, .. }) = candidate.term
                && jumps_of(ac, setup, &terms) >= MAX_JUMPS_PER_STREAM
            {
                if !jumps_exceeded.contains(&(ac, setup)) {
                    jumps_exceeded.push((ac, setup));
                    tried.push(rejected(Rejection::TooManyJumps));
                }
                continue;
            }
            attempts += 1;
            if let Some((i, t)) = candidate.outlier {
                let twins = twins(&geometry, &studentized, i, t);
                if !twins.is_empty() && !exchangeable(base, &columns, i, &twins, sigma) {
                    let mut group = vec![(i, t)];
                    group.extend(twins);
                    for &(j, _) in &group {
                        suspects.insert(j);
                    }
                    unattributed_sets.push(group);
                    tried.push(rejected(Rejection::Unattributable));
                    continue;
                }
            }
            let added = candidate.terms();
            // a zero per cycle holds every jump of its stream at a cycle's start
            let absorbed: Vec<Term> = match candidate.term {
                Term::RezeroCycle { ac, setup, .. } => terms
                    .iter()
                    .filter(|t| {
                        matches!(t, Term::Effect(Effect::OffsetStep { ac: a, setup: s, step: None, .. }) if *a == ac && *s == setup)
                    })
                    .cloned()
                    .collect(),
                _ => Vec::new(),
            };
            let mut new_terms: Vec<Term> = terms
                .iter()
                .filter(|t| !absorbed.contains(t))
                .cloned()
                .collect();
            new_terms.extend(added.iter().cloned());
            let new_columns = known.of(&new_terms);
            let Ok(fit) = base.fit(&new_columns, sigma) else {
                tried.push(rejected(Rejection::NotDetermined));
                continue;
            };
            let lof_new = base.lack_of_fit(set, &fit, &new_columns, options.lack_of_fit_alpha);
            // A term that acts on many cells must reduce a lack of fit the data shows,
            // judged against the pure error it leaves ([`refused_for_lack_of_fit`]); a
            // single reading is decided by its own statistic (its externally studentized
            // residual, Bonferroni over the readings): a gross error must never stay in
            // the fit for a lack of fit it has no part in.
            if candidate.outlier.is_none()
                && let Some(new) = &lof_new
                && refused_for_lack_of_fit(new, || {
                    let mut full = columns.clone();
                    full.extend(known.of(&added));
                    base.lack_of_fit(set, &current, &full, options.lack_of_fit_alpha)
                })
            {
                tried.push(rejected(Rejection::DoesNotReduceLackOfFit));
                continue;
            }
            for gone in &absorbed {
                if let Some(k) = findings.iter().position(|f| f.terms.contains(gone)) {
                    tried.push(findings.remove(k).withdrawn(Rejection::Absorbed));
                }
            }
            let ([pitch_new, encoder_new], [pitch_old, encoder_old]) =
                (base.calibrated(&fit), base.calibrated(&current));
            let pitch_change = difference(&pitch_new, &pitch_old);
            let encoder_change = difference(&encoder_new, &encoder_old);
            let entry = FoundEffect {
                effect: candidate_effect(candidate),
                u: None,
                quadratic_u: None,
                quadratic_evidence: None,
                f_statistic: ev.f_statistic,
                p_value: ev.p_value,
                p_adjusted: ev.p_adjusted,
                residual_rms_before: current.residual_rms().unwrap_or(0.0),
                residual_rms_after: fit.residual_rms().unwrap_or(0.0),
                pitch_change_max: max_abs(&pitch_change),
                encoder_change_max: max_abs(&encoder_change),
                changes_calibration: true,
                studentized_residual: candidate.outlier.map(|(_, t)| t),
                dof_numerator: candidate.rank.max(1),
                drift_order: None,
                shape: Vec::new(),
                shape_u: None,
                alternatives: Vec::new(),
            };
            findings.push(Finding {
                terms: added,
                entry,
                pitch_change,
                encoder_change,
            });
            terms = new_terms;
            current = fit;
            lof_current = lof_new;
            accepted = true;
            break;
        }
        base.ticker().round_done();
        if !accepted {
            // The last round's verdict on every kind of term not in the model.
            record_not_significant(&mut tried, &scored, options.family_alpha);
            break;
        }
    }
    Outcome {
        terms,
        findings,
        tried,
        unattributed_sets,
        jumps_exceeded,
        fit: current,
        // no round ran: the fit is the base fit
        lack_of_fit: if lof_pending {
            base.lack_of_fit(set, before, &[], options.lack_of_fit_alpha)
        } else {
            lof_current
        },
    }
}

/// A term's column against a round's fit: xᵀe, xᵀx and its coordinates on the basis of
/// the columns added to the base fit (Uᵀx).
struct TermStats {
    projection: f64,
    length_squared: f64,
    coordinates: Vec<f64>,
}

/// What the systematic blocks of a round are scored with.
struct Systematic<'r> {
    geometry: &'r FitGeometry,
    /// Every block's columns, formed.
    known: &'r Columns<'r>,
    residuals: &'r [f64],
    /// The terms of the model.
    terms: &'r [Term],
    ticker: &'r Ticker,
}

impl Systematic<'_> {
    /// The candidates of the systematic `blocks`, in their order, and the autocollimators
    /// whose cross-talk is untestable against the base model, in the blocks' order (none
    /// when another autocollimator's cross-talk is in the model: it is that term's
    /// alternative then).
    /// A drift's orders are nested blocks: each one's Gram matrix is the leading part of
    /// the longest block it begins; its part off the base fit's span is the same in every
    /// round (formed once, side by side, into `core_grams`), the terms found take theirs
    /// off.
    fn candidates(
        &self,
        blocks: &[Vec<Term>],
        core_grams: &mut Vec<(Vec<Term>, DMatrix<f64>)>,
    ) -> (Vec<Candidate>, Vec<u32>) {
        let longest_of = |block: &Vec<Term>| -> Vec<Term> {
            blocks
                .iter()
                .filter(|o| o.len() >= block.len() && o.starts_with(block))
                .max_by_key(|o| o.len())
                .unwrap_or(block)
                .clone()
        };
        let mut missing: Vec<Vec<Term>> = Vec::new();
        for block in blocks {
            let longest = longest_of(block);
            if !core_grams.iter().any(|(terms, _)| *terms == longest) && !missing.contains(&longest)
            {
                missing.push(longest);
            }
        }
        let grams: Vec<DMatrix<f64>> = missing
            .par_iter()
            .map(|block| {
                self.geometry
                    .core_projected_gram(&self.known.columns(block))
            })
            .collect();
        core_grams.extend(missing.into_iter().zip(grams));
        // every term's xᵀe, xᵀx and Uᵀx once (a term is in several nested blocks)
        let mut stats: Vec<(&Term, TermStats)> = Vec::new();
        for term in blocks.iter().flatten() {
            if stats.iter().any(|(t, _)| *t == term) {
                continue;
            }
            let Some((x, length_squared)) = self.known.with_length(term) else {
                continue;
            };
            stats.push((
                term,
                TermStats {
                    projection: dot(x, self.residuals),
                    length_squared,
                    coordinates: self.geometry.added_coordinates(x),
                },
            ));
        }
        let stats_of = |term: &Term| stats.iter().find(|(t, _)| *t == term).map(|(_, s)| s);
        let mut out = Vec::new();
        let mut untestable = Vec::new();
        for block in blocks {
            self.ticker.tick();
            let longest = longest_of(block);
            let Some((_, core_gram)) = core_grams.iter().find(|(terms, _)| *terms == longest)
            else {
                continue;
            };
            let Some(block_stats) = block.iter().map(stats_of).collect::<Option<Vec<_>>>() else {
                continue;
            };
            let m = block.len();
            let coordinates: Vec<&[f64]> = block_stats
                .iter()
                .map(|s| s.coordinates.as_slice())
                .collect();
            let gram = FitGeometry::projected_gram_from_coordinates(
                core_gram.view((0, 0), (m, m)).into_owned(),
                &coordinates,
            );
            if let [term] = block.as_slice() {
                let score = ColumnScore {
                    projection: block_stats[0].projection,
                    new_length_squared: gram[(0, 0)],
                    length_squared: block_stats[0].length_squared,
                };
                if let Term::Effect(Effect::CrossTalk { ac, .. }) = term
                    && score.new_fraction() < 0.1
                {
                    let other_in_model = self
                        .terms
                        .iter()
                        .any(|t| matches!(t, Term::Effect(Effect::CrossTalk { .. })));
                    if !other_in_model {
                        untestable.push(*ac);
                    }
                    continue;
                }
                if score.is_new() {
                    out.push(Candidate::single(term.clone(), Family::Systematic, &score));
                }
            } else {
                let projection =
                    nalgebra::DVector::from_iterator(m, block_stats.iter().map(|s| s.projection));
                let scale = block_stats
                    .iter()
                    .map(|s| s.length_squared)
                    .fold(0.0, f64::max);
                let score = BlockScore::of(projection, scale, gram);
                if score.rank > 0
                    && let Some(c) = Candidate::block(block.clone(), Family::Systematic, &score)
                {
                    out.push(c);
                }
            }
        }
        (out, untestable)
    }
}

/// The columns of the terms met so far in a search: a term's column is the same in every
/// round, so it is formed once.
struct Columns<'s> {
    set: &'s MeasurementSet,
    context: &'s EffectContext,
    /// (term, its column, xᵀx).
    known: Vec<(Term, Vec<f64>, f64)>,
}

impl Columns<'_> {
    /// The column of `term`.
    fn column(&mut self, term: &Term) -> &[f64] {
        let index = match self.known.iter().position(|(t, ..)| t == term) {
            Some(index) => index,
            None => {
                let column = term.column(self.set, self.context);
                let length_squared = dot(&column, &column);
                self.known.push((term.clone(), column, length_squared));
                self.known.len() - 1
            }
        };
        &self.known[index].1
    }

    /// Forms the columns of `terms` not formed yet, in one pass over the readings
    /// ([`Term::columns`]).
    fn form<'t>(&mut self, terms: impl Iterator<Item = &'t Term>) {
        let mut missing: Vec<Term> = Vec::new();
        for term in terms {
            if !self.known.iter().any(|(t, ..)| t == term) && !missing.contains(term) {
                missing.push(term.clone());
            }
        }
        // a few terms to a task, side by side (each task reads the readings once for its
        // terms: [`Term::columns`])
        let columns: Vec<(Vec<f64>, f64)> = missing
            .par_chunks(FORMED_TOGETHER)
            .flat_map_iter(|terms| Term::columns(terms, self.set, self.context))
            .map(|column| {
                let length_squared = dot(&column, &column);
                (column, length_squared)
            })
            .collect();
        self.known.extend(
            missing
                .into_iter()
                .zip(columns)
                .map(|(term, (column, length_squared))| (term, column, length_squared)),
        );
    }

    /// The columns of `terms`, formed before ([`Columns::column`]), in their order
    /// (none for a term not formed).
    fn columns(&self, terms: &[Term]) -> Vec<&[f64]> {
        terms
            .iter()
            .filter_map(|t| {
                self.known
                    .iter()
                    .find(|(k, ..)| k == t)
                    .map(|(_, c, _)| c.as_slice())
            })
            .collect()
    }

    /// The column of `term` and its xᵀx, formed before.
    fn with_length(&self, term: &Term) -> Option<(&[f64], f64)> {
        self.known
            .iter()
            .find(|(k, ..)| k == term)
            .map(|(_, c, l)| (c.as_slice(), *l))
    }

    /// The columns of `terms`, in their order.
    fn of(&mut self, terms: &[Term]) -> Vec<Vec<f64>> {
        terms.iter().map(|t| self.column(t).to_vec()).collect()
    }
}

/// Readings whose outlier column is nearly the same as reading `i`'s (|correlation of
/// their residual directions| ≥ 0.9) and that explain nearly as much (t² within 4 of
/// reading i's): the data cannot say which of them is bad.
/// Whether leaving out reading `i` or any of its `twins` instead gives the same
/// calibration ([`Base::calibrated`], to 1e-9 of its size): in a self-calibration with two
/// heads, the two readings of a stop differ only by the table's error there, so the bad
/// one cannot be named but the calibration does not depend on which it is.
fn exchangeable(
    base: &Base<'_>,
    columns: &[Vec<f64>],
    i: usize,
    twins: &[(usize, f64)],
    sigma: Option<crate::measurement::Sigma>,
) -> bool {
    let n = base.positions().readings.len();
    let calibration = |reading: usize| {
        let mut all = columns.to_vec();
        let mut column = vec![0.0; n];
        column[reading] = 1.0;
        all.push(column);
        base.fit(&all, sigma).ok().map(|fit| base.calibrated(&fit))
    };
    let Some([a0, a1]) = calibration(i) else {
        return false;
    };
    let scale = a0.iter().chain(&a1).fold(1.0_f64, |m, v| m.max(v.abs()));
    twins.iter().all(|&(j, _)| {
        calibration(j).is_some_and(|[b0, b1]| {
            a0.iter()
                .chain(&a1)
                .zip(b0.iter().chain(&b1))
                .all(|(x, y)| (x - y).abs() <= 1e-9 * scale)
        })
    })
}

fn twins(
    geometry: &FitGeometry,
    studentized: &[Option<f64>],
    i: usize,
    t_i: f64,
) -> Vec<(usize, f64)> {
    let h_ii = geometry.hat(i, i);
    (0..studentized.len())
        .filter(|&j| j != i)
        .filter_map(|j| {
            let t_j = studentized[j]?;
            if t_j * t_j < t_i * t_i - 4.0 {
                return None;
            }
            let h_jj = geometry.hat(j, j);
            let room = (1.0 - h_ii) * (1.0 - h_jj);
            if room <= 0.0 {
                return None;
            }
            let correlation = -geometry.hat(i, j) / room.sqrt();
            (correlation.abs() >= 0.9).then_some((j, t_j))
        })
        .collect()
}
