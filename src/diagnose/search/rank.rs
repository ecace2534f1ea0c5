//! The ranking of a round's candidates: each one's F test against the current fit from
//! its score (no refit), its family's Bonferroni adjustment, and the few of the thousands
//! of jumps a round can use.

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::MAX_ATTEMPTS;
use crate::diagnose::Evidence;
use crate::diagnose::candidates::{Candidate, Family, StepScore, StepSearch};
use crate::measurement::MeasurementSet;
use crate::solve::Solution;
use crate::uncertainty::student::t_two_sided_tail;

/// The F statistic of a scored candidate against the current fit, from the reduction
/// Δ of the residual sum of squares it brings and the `rank` r of directions it adds:
/// F = (Δ/r)/(rest/(dof − r)).
pub(super) fn f_statistic(reduction: f64, rank: usize, current: &Solution, tiny: f64) -> f64 {
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
pub(super) fn evidence(
    rank: usize,
    f_statistic: f64,
    current: &Solution,
    family_size: usize,
) -> Evidence {
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

/// A round's candidates in their order: the systematic ones, the jumps (compact, one per
/// stop of every stream), the outlier; an index runs over them in that order.
pub(super) struct RoundCandidates<'c> {
    pub systematic: &'c [Candidate],
    pub steps: &'c [StepScore],
    pub outlier: Option<&'c Candidate>,
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
    pub fn candidate(
        &self,
        i: usize,
        set: &MeasurementSet,
        search: &StepSearch,
    ) -> Option<Candidate> {
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
pub(super) fn rank(
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
