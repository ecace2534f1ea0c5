//! The largest consistent subset (docs/FORMAT.md §12, "Decisions at their stated rate"):
//! when the closed vector of every laboratory fails its test at 5 %, the largest subset of
//! laboratories whose closed vector passes, found by trying every subset of each size from
//! n − 1 down while that is cheap, ties broken by the smaller χ²; the laboratories the user
//! keeps are in every subset tried.

use serde::{Deserialize, Serialize};

use super::closed::ClosedFit;
use super::reference::chi2_quantile_95;

/// How many subsets an exhaustive search may fit before it gives way to a greedy one.
pub(crate) const EXHAUSTIVE_SUBSETS: u64 = 1 << 16;

/// How the subsets were searched.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[non_exhaustive]
pub enum SearchMethod {
    /// Every subset of each size tried, from n − 1 down to the first that passes.
    Exhaustive,
    /// Too many subsets: from the size where they became too many, the laboratory whose
    /// removal lowers χ² most left out one at a time (backward elimination).
    Greedy,
}

/// One size of subset tried: how many, the best (smallest χ²) and its test.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct SearchStep {
    /// The number of laboratories in each subset of this step.
    pub size: usize,
    /// How many subsets of this size were fitted.
    pub subsets: u64,
    /// The subset with the smallest χ² (the laboratories' names, in the order given).
    pub best: Vec<String>,
    /// Its closed vector's χ².
    pub chi2: f64,
    /// ν = (N − 1)(size − 1).
    pub dof: usize,
    /// χ²_0.95(ν) (`null` in a JSON read as +∞, as the tests' quantiles are).
    #[serde(deserialize_with = "super::nullable::quantile")]
    pub chi2_critical: f64,
    /// Whether it passes (χ² ≤ χ²_0.95(ν)): the first step that passes ends the search.
    pub consistent: bool,
}

/// The search for the largest consistent subset, as the JSON reports it (`search`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct SubsetSearch {
    /// Exhaustive, or greedy from some size on.
    pub method: SearchMethod,
    /// The subsets fitted in all.
    pub subsets_tested: u64,
    /// Each size tried, largest first; the last passes unless no subset did.
    pub steps: Vec<SearchStep>,
}

/// The outcome: the laboratories kept (indices into the laboratories) and the search.
pub(crate) struct Found {
    /// The subset chosen, ascending; every laboratory when none passes.
    pub inside: Vec<usize>,
    /// Whether a subset passed.
    pub passed: bool,
    /// The search as reported.
    pub search: SubsetSearch,
}

/// C(n, k), saturating.
fn binomial(n: usize, k: usize) -> u64 {
    if k > n {
        return 0;
    }
    let k = k.min(n - k);
    let mut c: u64 = 1;
    for i in 0..k {
        c = c.saturating_mul((n - i) as u64) / (i as u64 + 1);
    }
    c
}

/// Whether fit `f` is more consistent than `b`: the smaller χ² at the same ν (as every
/// subset of one size of closed vectors has); at different ν (laboratories that report
/// different angle blocks or encoder positions), the larger p-value P(χ²_ν > χ²), so that
/// leaving out a laboratory that reports more is not favoured for its larger χ² alone,
/// then the smaller χ².
fn more_consistent(f: &ClosedFit, b: &ClosedFit) -> bool {
    if f.dof == b.dof {
        return f.chi2 < b.chi2;
    }
    let (p_f, p_b) = (p_value(f), p_value(b));
    if p_f != p_b {
        return p_f > p_b;
    }
    f.chi2 < b.chi2
}

/// P(χ²_ν > χ²) of a fit (1 with ν = 0).
fn p_value(f: &ClosedFit) -> f64 {
    use statrs::distribution::{ChiSquared, ContinuousCDF};
    if f.dof == 0 {
        return 1.0;
    }
    ChiSquared::new(f.dof as f64).map_or(0.0, |law| law.sf(f.chi2))
}

/// Every k-subset of `free`, in lexicographic order of positions.
fn for_each_subset(free: &[usize], k: usize, mut visit: impl FnMut(&[usize])) {
    let n = free.len();
    if k > n {
        return;
    }
    let mut pick: Vec<usize> = (0..k).collect();
    loop {
        let chosen: Vec<usize> = pick.iter().map(|&p| free[p]).collect();
        visit(&chosen);
        let Some(i) = (0..k).rev().find(|&i| pick[i] < n - k + i) else {
            return;
        };
        pick[i] += 1;
        for j in i + 1..k {
            pick[j] = pick[j - 1] + 1;
        }
    }
}

/// The largest subset of `labs` laboratories (every one in `kept` included) whose closed
/// vector `fit` passes at 5 %, searched from n − 1 down; `names` name them in the steps.
/// `fit` returns `None` for a subset that cannot be fitted (it is passed over); a subset
/// with no degree of freedom (laboratories that share too few positions) is no test and is
/// passed over too, never taken as passing.
pub(crate) fn largest_consistent(
    names: &[String],
    kept: &[usize],
    fit: &dyn Fn(&[usize]) -> Option<ClosedFit>,
) -> Found {
    let fit = |subset: &[usize]| fit(subset).filter(|f| f.dof > 0);
    let labs = names.len();
    let free: Vec<usize> = (0..labs).filter(|r| !kept.contains(r)).collect();
    let mut steps = Vec::new();
    let mut tested: u64 = 0;
    let mut method = SearchMethod::Exhaustive;
    let min_size = kept.len().max(2);
    // The greedy path's current set, used once the exhaustive one stops.
    let mut current: Vec<usize> = (0..labs).collect();
    let step_of = |size: usize, subsets: u64, best: &(Vec<usize>, ClosedFit)| {
        let critical = chi2_quantile_95(best.1.dof);
        SearchStep {
            size,
            subsets,
            best: best.0.iter().map(|&r| names[r].clone()).collect(),
            chi2: best.1.chi2,
            dof: best.1.dof,
            chi2_critical: critical,
            consistent: best.1.chi2 <= critical,
        }
    };
    for size in (min_size..labs).rev() {
        let take = size - kept.len();
        let count = binomial(free.len(), take);
        let mut best: Option<(Vec<usize>, ClosedFit)> = None;
        let mut best_passing: Option<(Vec<usize>, ClosedFit)> = None;
        let mut subsets = 0;
        if method == SearchMethod::Exhaustive && tested.saturating_add(count) <= EXHAUSTIVE_SUBSETS
        {
            for_each_subset(&free, take, |chosen| {
                let mut subset: Vec<usize> = kept.iter().chain(chosen).copied().collect();
                subset.sort_unstable();
                subsets += 1;
                let Some(f) = fit(&subset) else { return };
                let passes = f.chi2 <= chi2_quantile_95(f.dof);
                if best.as_ref().is_none_or(|(_, b)| more_consistent(&f, b)) {
                    best = Some((subset.clone(), f.clone()));
                }
                if passes
                    && best_passing
                        .as_ref()
                        .is_none_or(|(_, b)| more_consistent(&f, b))
                {
                    best_passing = Some((subset, f));
                }
            });
            // at one ν the best passes when any does; at several (laboratories reporting
            // different positions) the step states the passing subset chosen
        } else {
            method = SearchMethod::Greedy;
            // leave out the laboratory (not kept) whose removal lowers χ² most
            for &r in current.iter().filter(|r| !kept.contains(r)) {
                let subset: Vec<usize> = current.iter().copied().filter(|&q| q != r).collect();
                subsets += 1;
                let Some(f) = fit(&subset) else { continue };
                if best.as_ref().is_none_or(|(_, b)| more_consistent(&f, b)) {
                    best = Some((subset, f));
                }
            }
            if let Some((subset, f)) = &best
                && f.chi2 <= chi2_quantile_95(f.dof)
            {
                best_passing = Some((subset.clone(), f.clone()));
            }
        }
        tested += subsets;
        let Some(best) = best else { break };
        current = best.0.clone();
        // the step states the subset the search chose: the passing one when one passes
        steps.push(step_of(
            size,
            subsets,
            best_passing.as_ref().unwrap_or(&best),
        ));
        if let Some((subset, _)) = best_passing {
            return Found {
                inside: subset,
                passed: true,
                search: SubsetSearch {
                    method,
                    subsets_tested: tested,
                    steps,
                },
            };
        }
    }
    Found {
        inside: (0..labs).collect(),
        passed: false,
        search: SubsetSearch {
            method,
            subsets_tested: tested,
            steps,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kc_every_subset_is_visited_once() {
        let free = [0, 2, 3, 5, 7];
        for k in 0..=5 {
            let mut seen = Vec::new();
            for_each_subset(&free, k, |s| seen.push(s.to_vec()));
            assert_eq!(seen.len() as u64, binomial(5, k), "k = {k}");
            let mut unique = seen.clone();
            unique.sort();
            unique.dedup();
            assert_eq!(unique.len(), seen.len());
            assert!(seen.iter().all(|s| s.windows(2).all(|w| w[0] < w[1])));
        }
        assert_eq!(binomial(10, 3), 120);
        assert_eq!(binomial(20, 10), 184_756);
    }
}
