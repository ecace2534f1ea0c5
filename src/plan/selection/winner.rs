//! A trial of a round: does the effect's candidate win? The candidates the effect moves
//! most are scored exactly; every other is bounded by the triangle inequality from its
//! class's strongest noise scores, and scored only when the bound could win (the module
//! documentation of [`super`]).

use rayon::prelude::*;
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::{NEAR, Round, TOP, TRIALS, family_index};
use crate::uncertainty::student::t_two_sided_tail;

/// What a target (the columns an effect acts on, and the groups that count as finding
/// it) needs in every trial, formed once per target.
pub(super) struct Target {
    pub(super) start: usize,
    pub(super) len: usize,
    /// G[:, start + j] of every column j of the target.
    pub(super) gram_columns: Vec<Vec<f64>>,
    /// Whether each offered candidate counts as finding the effect.
    in_group: Vec<bool>,
    /// The one-column candidates among `near`, packed for the trials: (column, the
    /// pseudo-inverse of its G entry, class, whether it is of the target's groups), and
    /// G[column, start + j] of each, `len` values per candidate.
    near_singles: Vec<(usize, f64, usize, bool)>,
    near_single_gram: Vec<f64>,
    /// The noise scores of the one-column candidates among `near`, trial after trial
    /// (gathered once, so that a trial reads them from one place).
    near_single_noise: Vec<f64>,
    /// The candidates of several columns among `near`.
    near_blocks: Vec<usize>,
    /// Whether each offered candidate is among `near`.
    is_near: Vec<bool>,
    /// The other candidates of every class.
    far: Vec<Vec<usize>>,
    /// The far candidates of every class in tiers, the ones the effect moves most first
    /// (tiers of 32, 64, 128, … candidates): a tier is scored only when its own bound
    /// could win.
    tiers: Vec<Vec<Vec<usize>>>,
    /// max over a tier's candidates of ‖G[o, start + j]‖_P, for every column j, of every
    /// class's tiers.
    far_bound: Vec<Vec<Vec<f64>>>,
}

/// The buffers of a trial, allocated once per bisection step rather than per trial.
#[derive(Default)]
pub(super) struct TrialScratch {
    /// The largest reduction of the target's groups and of the others, per class.
    largest_in: Vec<f64>,
    largest_out: Vec<f64>,
    /// The scores of a candidate of several columns.
    scores: Vec<f64>,
}

impl Round<'_> {
    /// The F statistic of a candidate of class `k` whose reduction of the residual sum of
    /// squares `rss` is `reduction`; `None` when it does not pass its family's threshold
    /// (it cannot be found: p·m ≥ α).
    fn f_passing(&self, k: usize, reduction: f64, rss: f64) -> Option<f64> {
        let class = &self.classes[k];
        let r = class.r;
        let dof = self.dof.saturating_sub(r);
        if dof == 0 {
            return None;
        }
        let rest = (rss - reduction).max(0.0);
        let f = if rest > 0.0 {
            (reduction / r as f64) / (rest / dof as f64)
        } else {
            f64::INFINITY
        };
        (!f.is_nan() && f > class.critical).then_some(f)
    }

    /// The Bonferroni-adjusted p-value of F statistic `f` of a candidate of class `k`.
    fn p_adjusted(&self, k: usize, f: f64) -> f64 {
        let class = &self.classes[k];
        let r = class.r;
        let dof = self.dof.saturating_sub(r) as f64;
        let p = if f <= 0.0 {
            1.0
        } else if r == 1 {
            t_two_sided_tail(f.sqrt(), Some(dof))
        } else if f.is_infinite() {
            0.0
        } else {
            FisherSnedecor::new(r as f64, dof).map_or(1.0, |d| d.sf(f))
        };
        let m = self.family_size[family_index(class.family)].max(1) as f64;
        (p * m).min(1.0)
    }

    /// Whether verdict `a` (class, F) beats `b`, as `diagnose` picks a round's winner: a
    /// smaller adjusted p, or the same p and a larger F. Within a class the larger F has
    /// the smaller p, and no p is computed.
    fn beats(&self, a: (usize, f64), b: (usize, f64)) -> bool {
        if a.0 == b.0 {
            return a.1 > b.1;
        }
        let (pa, pb) = (self.p_adjusted(a.0, a.1), self.p_adjusted(b.0, b.1));
        pa < pb || (pa == pb && a.1 > b.1)
    }

    /// The target on columns `start .. start + len` found by a winner of `groups`.
    pub(super) fn target(&self, (start, len): (usize, usize), groups: &[usize]) -> Target {
        let c = self.columns.len();
        let gram_columns: Vec<Vec<f64>> = (start..start + len)
            .into_par_iter()
            .map(|k| {
                let v = self.geometry.residual_of(&self.columns.unit(k));
                let mut g = vec![0.0; c];
                self.columns.transpose_times(&v, &mut g, &mut Vec::new());
                g
            })
            .collect();
        let in_group: Vec<bool> = self
            .offered
            .iter()
            .map(|o| groups.contains(&o.group))
            .collect();
        // ‖G[o, column j]‖_P of every candidate and column
        let moved: Vec<Vec<f64>> = self
            .offered
            .iter()
            .map(|o| {
                gram_columns
                    .iter()
                    .map(|g| o.reduction(&g[o.start..o.start + o.len]).sqrt())
                    .collect()
            })
            .collect();
        let weight: Vec<f64> = (start..start + len).map(|k| self.columns.norm(k)).collect();
        let strength = |o: usize| -> f64 { moved[o].iter().zip(&weight).map(|(b, w)| b * w).sum() };
        let mut others: Vec<usize> = (0..self.offered.len())
            .filter(|&o| !in_group[o] && self.offered[o].class.is_some())
            .collect();
        others.sort_by(|&a, &b| strength(b).total_cmp(&strength(a)));
        others.truncate(NEAR);
        let mut near: Vec<usize> = (0..self.offered.len())
            .filter(|&o| in_group[o] && self.offered[o].class.is_some())
            .collect();
        near.extend(others);
        let mut is_near = vec![false; self.offered.len()];
        for &o in &near {
            is_near[o] = true;
        }
        let far: Vec<Vec<usize>> = self
            .classes
            .iter()
            .map(|class| {
                class
                    .members
                    .iter()
                    .copied()
                    .filter(|&o| !is_near[o])
                    .collect()
            })
            .collect();
        let tiers: Vec<Vec<Vec<usize>>> = far
            .iter()
            .map(|members| {
                let mut sorted = members.clone();
                sorted.sort_by(|&a, &b| strength(b).total_cmp(&strength(a)));
                let mut tiers = Vec::new();
                let mut size = 32;
                while !sorted.is_empty() {
                    let rest = sorted.split_off(size.min(sorted.len()));
                    tiers.push(sorted);
                    sorted = rest;
                    size *= 2;
                }
                tiers
            })
            .collect();
        let far_bound = tiers
            .iter()
            .map(|class_tiers| {
                class_tiers
                    .iter()
                    .map(|members| {
                        (0..len)
                            .map(|j| members.iter().map(|&o| moved[o][j]).fold(0.0, f64::max))
                            .collect()
                    })
                    .collect()
            })
            .collect();
        let mut near_singles = Vec::new();
        let mut near_single_gram = Vec::new();
        let mut near_blocks = Vec::new();
        for &o in &near {
            let offered = &self.offered[o];
            match offered.class {
                Some(class) if offered.len == 1 => {
                    near_singles.push((offered.start, offered.pinv[(0, 0)], class, in_group[o]));
                    near_single_gram.extend(gram_columns.iter().map(|g| g[offered.start]));
                }
                Some(_) => near_blocks.push(o),
                None => {}
            }
        }
        let c = self.columns.len();
        let mut near_single_noise = Vec::with_capacity(TRIALS * near_singles.len());
        for trial in 0..TRIALS {
            let row = &self.noise[trial * c..(trial + 1) * c];
            near_single_noise.extend(near_singles.iter().map(|&(column, ..)| row[column]));
        }
        Target {
            start,
            len,
            near_single_noise,
            near_singles,
            near_single_gram,
            near_blocks,
            gram_columns,
            in_group,
            is_near,
            far,
            far_bound,
            tiers,
        }
    }

    /// The residual sum of squares of `trial` with the effect `size`·Σ wⱼ·(column j):
    /// RSS₀ + 2·size·wᵀs₀ + size²·wᵀG w over the target's columns.
    fn rss_with(&self, target: &Target, trial: usize, size: f64, w: &[f64]) -> f64 {
        let c = self.columns.len();
        let noise = &self.noise[trial * c..(trial + 1) * c];
        let t0 = target.start;
        let mut cross = 0.0;
        let mut quad = 0.0;
        for a in 0..target.len {
            cross += w[a] * noise[t0 + a];
            for b in 0..target.len {
                quad += w[a] * w[b] * target.gram_columns[b][t0 + a];
            }
        }
        self.rss[trial] + 2.0 * size * cross + size * size * quad
    }

    /// Whether the effect is found in `trial` (module documentation): the best candidate
    /// of the target's groups passes α and no other candidate beats it.
    pub(super) fn found_in_trial(
        &self,
        target: &Target,
        trial: usize,
        size: f64,
        w: &[f64],
        scratch: &mut TrialScratch,
    ) -> bool {
        let TrialScratch {
            largest_in,
            largest_out,
            scores,
        } = scratch;
        let c = self.columns.len();
        let noise = &self.noise[trial * c..(trial + 1) * c];
        let tlen = target.len;
        let rss = self.rss_with(target, trial, size, w);
        let shift = |k: usize| -> f64 {
            w.iter()
                .zip(&target.gram_columns)
                .map(|(wj, g)| wj * g[k])
                .sum::<f64>()
        };
        let mut reduction = |o: usize| -> f64 {
            let offered = &self.offered[o];
            if offered.len == 1 {
                let s = noise[offered.start] + size * shift(offered.start);
                s * s * offered.pinv[(0, 0)]
            } else {
                scores.clear();
                scores.extend(
                    (offered.start..offered.start + offered.len)
                        .map(|k| noise[k] + size * shift(k)),
                );
                offered.reduction(scores)
            }
        };
        // within a class the larger reduction has the smaller p: the largest of the
        // target's groups and of the others in every class, then one verdict per class
        let classes = self.classes.len();
        largest_in.clear();
        largest_in.resize(classes, -1.0);
        largest_out.clear();
        largest_out.resize(classes, -1.0);
        let gram = target.near_single_gram.chunks_exact(tlen.max(1));
        let singles = target.near_singles.len();
        let near_noise = &target.near_single_noise[trial * singles..(trial + 1) * singles];
        for ((&(_, pinv, k, in_group), g), s0) in
            target.near_singles.iter().zip(gram).zip(near_noise)
        {
            let moved: f64 = w.iter().zip(g).map(|(wj, gj)| wj * gj).sum();
            let s = s0 + size * moved;
            let r = s * s * pinv;
            let slot = if in_group {
                &mut largest_in[k]
            } else {
                &mut largest_out[k]
            };
            *slot = slot.max(r);
        }
        for &o in &target.near_blocks {
            let Some(k) = self.offered[o].class else {
                continue;
            };
            let r = reduction(o);
            let slot = if target.in_group[o] {
                &mut largest_in[k]
            } else {
                &mut largest_out[k]
            };
            *slot = slot.max(r);
        }
        let Some(winner) = largest_in
            .iter()
            .enumerate()
            .filter(|(_, r)| **r >= 0.0)
            .filter_map(|(k, &r)| self.f_passing(k, r, rss).map(|f| (k, f)))
            .reduce(|best, v| if self.beats(v, best) { v } else { best })
        else {
            return false;
        };
        // above its threshold (to 1e-12) the winner's adjusted p is below α; only near
        // the threshold is it computed
        let winner_p = std::cell::OnceCell::new();
        let p_of_winner = || *winner_p.get_or_init(|| self.p_adjusted(winner.0, winner.1));
        if winner.1 <= self.classes[winner.0].critical * (1.0 + 1e-9) && p_of_winner() >= self.alpha
        {
            return false;
        }
        // whether a candidate of class k with F statistic f beats the winner (`beats`,
        // with the winner's p computed once)
        let beats_winner = |k: usize, f: f64| -> bool {
            if k == winner.0 {
                return f > winner.1;
            }
            let (p, p_winner) = (self.p_adjusted(k, f), p_of_winner());
            p < p_winner || (p == p_winner && f > winner.1)
        };
        for (k, &r) in largest_out.iter().enumerate() {
            if r >= 0.0
                && let Some(f) = self.f_passing(k, r, rss)
                && beats_winner(k, f)
            {
                return false;
            }
        }
        // the far candidates of every class: bounded, scored only when the bound could win
        for (k, far) in target.far.iter().enumerate() {
            if far.is_empty() {
                continue;
            }
            let kept = &self.top[(trial * classes + k) * TOP..(trial * classes + k + 1) * TOP];
            let strongest = match kept
                .iter()
                .find(|(_, o)| *o != usize::MAX && !target.is_near[*o])
            {
                Some(&(a, _)) => a,
                None if self.classes[k].members.len() > TOP => far
                    .iter()
                    .map(|&o| {
                        let offered = &self.offered[o];
                        offered
                            .reduction(&noise[offered.start..offered.start + offered.len])
                            .sqrt()
                    })
                    .fold(0.0, f64::max),
                None => 0.0,
            };
            for (tier, bounds) in target.tiers[k].iter().zip(&target.far_bound[k]) {
                let moved: f64 = w.iter().zip(bounds).map(|(wj, b)| wj.abs() * b).sum();
                let bound = strongest + size * moved;
                let could_beat = self
                    .f_passing(k, bound * bound, rss)
                    .is_some_and(|f| beats_winner(k, f));
                if could_beat {
                    let largest = tier.iter().map(|&o| reduction(o)).fold(0.0, f64::max);
                    if self
                        .f_passing(k, largest, rss)
                        .is_some_and(|f| beats_winner(k, f))
                    {
                        return false;
                    }
                }
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::super::Column;
    use super::*;
    use crate::diagnose::base::Base;
    use crate::diagnose::candidates::Family;
    use crate::plan::Design;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_distr::StandardNormal;

    impl Round<'_> {
        /// `found_in_trial` by brute force: every candidate scored in the trial, the
        /// winner by `beats` (the reference the bounded search is held to).
        fn found_in_trial_exhaustive(
            &self,
            target: &Target,
            trial: usize,
            size: f64,
            w: &[f64],
        ) -> bool {
            let c = self.columns.len();
            let noise = &self.noise[trial * c..(trial + 1) * c];
            let tlen = target.len;
            let rss = self.rss_with(target, trial, size, w);
            let mut best: Option<((usize, f64), bool)> = None;
            for (o, offered) in self.offered.iter().enumerate() {
                let Some(k) = offered.class else { continue };
                let s: Vec<f64> = (offered.start..offered.start + offered.len)
                    .map(|col| {
                        noise[col]
                            + size
                                * (0..tlen)
                                    .map(|j| w[j] * target.gram_columns[j][col])
                                    .sum::<f64>()
                    })
                    .collect();
                let Some(f) = self.f_passing(k, offered.reduction(&s), rss) else {
                    continue;
                };
                if best.is_none_or(|(b, _)| self.beats((k, f), b)) {
                    best = Some(((k, f), target.in_group[o]));
                }
            }
            best.is_some_and(|((k, f), in_group)| in_group && self.p_adjusted(k, f) < self.alpha)
        }
    }

    #[test]
    fn the_bounded_winner_search_answers_as_scoring_every_candidate() {
        // three autocollimators, 12 faces, 4 cycles: jumps of every stream at every stop,
        // a drift of each autocollimator and a zero per cycle of the first (a block)
        let design = Design::default()
            .with_spec("faces=12;ac-faces=1,2,5;cycles=4")
            .expect("a valid design");
        let set = design.measurement_set().expect("the design's readings");
        let base = Base::of(&set);
        let solution = base.fit(&[], None).expect("the base fit");
        let geometry = base.geometry(&solution, &[]);
        let n = set.readings.len();
        let mut streams: Vec<Vec<usize>> = Vec::new();
        for ac in 1..=3u32 {
            let mut order: Vec<usize> = (0..n).filter(|&i| set.readings[i].ac == ac).collect();
            order.sort_by_key(|&i| (set.readings[i].cycle, set.readings[i].step));
            streams.push(order);
        }
        let mut blocks: Vec<(Family, usize, Vec<Column>)> = Vec::new();
        for (s, order) in streams.iter().enumerate() {
            for from in 3..order.len() - 3 {
                blocks.push((
                    Family::OffsetStep,
                    s,
                    vec![Column::Suffix { stream: s, from }],
                ));
            }
        }
        for ac in 1..=3u32 {
            let drift: Vec<f64> = set
                .readings
                .iter()
                .enumerate()
                .map(|(i, r)| if r.ac == ac { i as f64 } else { 0.0 })
                .collect();
            blocks.push((
                Family::Systematic,
                3 + ac as usize,
                vec![Column::Values(drift)],
            ));
        }
        let zero_per_cycle: Vec<Column> = (1..=4u32)
            .map(|cycle| {
                Column::Values(
                    set.readings
                        .iter()
                        .map(|r| f64::from(u8::from(r.ac == 1 && r.cycle == cycle)))
                        .collect(),
                )
            })
            .collect();
        blocks.push((Family::Systematic, 10, zero_per_cycle));
        let offered = blocks.len();
        let round = Round::new(
            &geometry,
            solution.dof,
            streams,
            blocks,
            [4, offered - 4, n],
            0.05,
        );
        let jump = round.offered()[20].clone();
        let drift = round.offered()[offered - 3].clone();
        let zero = round.offered()[offered - 1].clone();
        let mut compared = 0;
        let mut found = [0usize; 2];
        for (o, random) in [(&jump, false), (&drift, false), (&zero, true)] {
            let target = round.target((o.start, o.len), &[o.group]);
            let size = round
                .size_for((o.start, o.len), random, &[o.group], 0.9)
                .expect("a size");
            let mut rng = ChaCha8Rng::seed_from_u64(7);
            let mut scratch = TrialScratch::default();
            for scale in [0.3, 0.7, 1.0, 1.5, 4.0] {
                for trial in 0..TRIALS {
                    let w: Vec<f64> = (o.start..o.start + o.len)
                        .map(|k| {
                            let draw = if random {
                                rng.sample::<f64, _>(StandardNormal)
                            } else {
                                1.0
                            };
                            draw * round.columns.norm(k)
                        })
                        .collect();
                    let bounded =
                        round.found_in_trial(&target, trial, size * scale, &w, &mut scratch);
                    let exhaustive =
                        round.found_in_trial_exhaustive(&target, trial, size * scale, &w);
                    assert_eq!(bounded, exhaustive, "trial {trial} at {scale} of the size");
                    found[usize::from(bounded)] += 1;
                    compared += 1;
                }
            }
        }
        assert_eq!(compared, 3 * 5 * TRIALS);
        // both answers occur often: the comparison is not of a trivial verdict
        assert!(found[0] > 3000 && found[1] > 3000, "{found:?}");
    }
}
