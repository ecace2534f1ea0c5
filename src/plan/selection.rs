//! The first round of a diagnosis's forward selection, emulated on the design alone.
//!
//! An effect is *found* when, in the round it is offered, its candidate has the smallest
//! Bonferroni-adjusted p-value of all candidates and that p is below the family's
//! false-alarm probability (`diagnose`'s rule). Its own F test passing is not enough: a
//! jump in the middle of a run is also half explained by a drift, whose family is
//! smaller, and a diagnosis then names the drift. The chance of being found therefore
//! depends on the other candidates, and it is computed from the design alone:
//!
//! - the candidates' columns X (the systematic blocks, and jump columns of the streams)
//!   projected off the model's span give the Gram matrix G = X̃ᵀX̃;
//! - the residuals e of a run with the effect x·δ have the scores s = X̃ᵀe ~ N(δ·X̃ᵀx̃, σ²G),
//!   and, since x is among the columns, RSS = sᵀG⁺s + σ²χ²(dof − rank G);
//! - every candidate's F statistic and p-value follow from s and RSS as in `diagnose`.
//!
//! The scores are drawn [`TRIALS`] times with a fixed seed (the same draws for every size
//! tried, so the chance of being found grows smoothly with the size), and the size at
//! which the effect is found in 90 % of the trials is found by bisection.

use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};
use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::power::noncentrality_for_power;
use crate::diagnose::candidates::Family;
use crate::diagnose::geometry::FitGeometry;
use crate::uncertainty::student::t_two_sided_tail;

/// The draws of the scores per round.
pub const TRIALS: usize = 2000;

/// The seed of the draws (the same plan every time).
const SEED: u64 = 0x706c_616e;

/// Directions whose squared length is below this fraction of the largest column's add
/// nothing (as `diagnose`'s block scores).
const RANK_TOLERANCE: f64 = 1e-9;

/// One candidate of the round: columns `start .. start + len` of the round's matrix.
#[derive(Debug, Clone)]
pub struct Offered {
    /// Its family.
    pub family: Family,
    /// The group it belongs to: the effect it would name (several candidates may name
    /// one effect, such as a drift's orders or the stops of one stream's jump).
    pub group: usize,
    start: usize,
    len: usize,
    /// The pseudo-inverse of its block of G (1 × 1 for one column) and its rank.
    pinv: DMatrix<f64>,
    rank: usize,
}

impl Offered {
    /// Its first column in the round's matrix.
    pub fn start(&self) -> usize {
        self.start
    }

    /// Its number of columns.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Whether it has no column.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The directions it adds to the model.
    pub fn rank(&self) -> usize {
        self.rank
    }
}

/// A round of the selection with its candidates and its draws.
pub struct Round {
    gram: DMatrix<f64>,
    offered: Vec<Offered>,
    dof: usize,
    family_size: [usize; 3],
    /// σ·(noise scores) per trial, without σ (unit σ): one vector of the round's columns.
    noise: Vec<DVector<f64>>,
    /// sᵀG⁺s of the noise scores per trial (unit σ).
    noise_in_span: Vec<f64>,
    /// χ² of the residual directions no candidate spans, per trial (unit σ).
    outside: Vec<f64>,
    /// The length ‖x‖ of every column: the round works with the columns scaled to unit
    /// length (F tests do not depend on a column's scale, and the rank tolerance is then
    /// the same for a drift in hours and one on the stop clock).
    norms: Vec<f64>,
    /// The false-alarm probability of every family.
    alpha: f64,
    /// The F a candidate of (family, numerator degrees of freedom) must exceed to pass
    /// its family's Bonferroni threshold: below it, its adjusted p is at least α.
    critical: Vec<((usize, usize), f64)>,
}

fn family_index(f: Family) -> usize {
    match f {
        Family::Systematic => 0,
        Family::OffsetStep => 1,
        Family::Outlier => 2,
    }
}

/// Pseudo-inverse and rank of a symmetric block, directions below `tolerance` left out.
fn pinv(block: DMatrix<f64>, tolerance: f64) -> (DMatrix<f64>, usize) {
    let m = block.nrows();
    let eigen = SymmetricEigen::new(block);
    let mut out = DMatrix::zeros(m, m);
    let mut rank = 0;
    for k in 0..m {
        let lambda = eigen.eigenvalues[k];
        if lambda > tolerance {
            let v = eigen.eigenvectors.column(k).into_owned();
            out += &v * v.transpose() / lambda;
            rank += 1;
        }
    }
    (out, rank)
}

impl Round {
    /// The round of the fit whose `geometry` is given, with `dof` residual degrees of
    /// freedom, the candidates `blocks` (each: family, group, columns), the true number of
    /// candidates of each family (Bonferroni divisors; the jump columns offered may be a
    /// sample of the stops), and the false-alarm probability `alpha` of every family.
    pub fn new(
        geometry: &FitGeometry,
        dof: usize,
        blocks: Vec<(Family, usize, Vec<Vec<f64>>)>,
        family_size: [usize; 3],
        alpha: f64,
    ) -> Round {
        let mut columns: Vec<Vec<f64>> = Vec::new();
        let mut offered = Vec::new();
        for (family, group, block) in blocks {
            offered.push(Offered {
                family,
                group,
                start: columns.len(),
                len: block.len(),
                pinv: DMatrix::zeros(0, 0),
                rank: 0,
            });
            columns.extend(block);
        }
        let norms: Vec<f64> = columns
            .iter()
            .map(|x| x.iter().map(|v| v * v).sum::<f64>().sqrt())
            .collect();
        for (x, norm) in columns.iter_mut().zip(&norms) {
            if *norm > 0.0 {
                x.iter_mut().for_each(|v| *v /= norm);
            }
        }
        let gram = geometry.projected_gram(&columns);
        let tolerance = RANK_TOLERANCE;
        for o in &mut offered {
            let block = gram.view((o.start, o.start), (o.len, o.len)).into_owned();
            let (p, r) = pinv(block, tolerance);
            o.pinv = p;
            o.rank = r;
        }
        // the noise scores: s = L z with L Lᵀ = G (eigen-decomposition, G may be singular)
        let c = gram.nrows();
        let eigen = SymmetricEigen::new(gram.clone());
        let mut factor = DMatrix::zeros(c, c);
        let mut rank = 0;
        for k in 0..c {
            let lambda = eigen.eigenvalues[k];
            if lambda > tolerance {
                let v = eigen.eigenvectors.column(k);
                factor.column_mut(k).copy_from(&(v * lambda.sqrt()));
                rank += 1;
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(SEED);
        let outside_dof = dof.saturating_sub(rank);
        let chi = (outside_dof > 0)
            .then(|| ChiSquared::new(outside_dof as f64).ok())
            .flatten();
        let mut noise = Vec::with_capacity(TRIALS);
        let mut noise_in_span = Vec::with_capacity(TRIALS);
        let mut outside = Vec::with_capacity(TRIALS);
        for _ in 0..TRIALS {
            let z = DVector::from_fn(c, |k, _| {
                let draw: f64 = rng.sample(StandardNormal);
                if eigen.eigenvalues[k] > tolerance {
                    draw
                } else {
                    0.0
                }
            });
            noise_in_span.push(z.norm_squared());
            noise.push(&factor * z);
            outside.push(chi.as_ref().map_or(0.0, |d| d.sample(&mut rng)));
        }
        let mut critical: Vec<((usize, usize), f64)> = Vec::new();
        for key in offered
            .iter()
            .filter(|o| o.rank > 0)
            .map(|o| (family_index(o.family), if o.len == 1 { 1 } else { o.rank }))
        {
            if critical.iter().all(|(k, _)| *k != key) && dof > key.1 {
                let m = family_size[key.0].max(1) as f64;
                let f = super::power::critical_f(alpha / m, key.1, (dof - key.1) as f64);
                critical.push((key, f));
            }
        }
        Round {
            gram,
            offered,
            dof,
            family_size,
            noise,
            noise_in_span,
            outside,
            norms,
            alpha,
            critical,
        }
    }

    /// The candidates offered.
    pub fn offered(&self) -> &[Offered] {
        &self.offered
    }

    /// The correlation of two one-column candidates' columns off the model's span
    /// (`None` when either adds nothing).
    pub fn correlation(&self, a: usize, b: usize) -> Option<f64> {
        let (a, b) = (&self.offered[a], &self.offered[b]);
        if a.len != 1 || b.len != 1 || a.rank == 0 || b.rank == 0 {
            return None;
        }
        let (aa, bb) = (self.gram[(a.start, a.start)], self.gram[(b.start, b.start)]);
        Some(self.gram[(a.start, b.start)] / (aa * bb).sqrt())
    }

    /// Whether an effect is found in at least `power` of the trials (the fraction found
    /// ≥ `power`): the effect adds `signal` (the columns `target` of the round's matrix
    /// with these coefficients, in units of σ) to the readings, and it is found when the
    /// winner of the round belongs to `groups` and passes `alpha`. With `random`, the
    /// coefficients are multiplied by a standard normal draw per column and trial
    /// (offsets drawn anew every cycle). The trials stop as soon as the answer is
    /// certain — enough found, or too many missed — which gives the answer all
    /// [`TRIALS`] would (the same draws in the same order) in a fraction of the time far
    /// from the threshold.
    fn found_in(
        &self,
        target: (usize, usize),
        size: f64,
        random: bool,
        groups: &[usize],
        power: f64,
    ) -> bool {
        // the fewest found with found / TRIALS ≥ power, as the fraction compares
        let needed = (0..=TRIALS)
            .find(|&k| k as f64 / TRIALS as f64 >= power)
            .unwrap_or(TRIALS + 1);
        if needed == 0 {
            return true;
        }
        if needed > TRIALS {
            return false;
        }
        let allowed_misses = TRIALS - needed;
        let (t0, tlen) = target;
        let c = self.gram.nrows();
        let mut rng = ChaCha8Rng::seed_from_u64(SEED ^ 0x5eed);
        let mut found = 0usize;
        let mut missed = 0usize;
        let mut scores = DVector::<f64>::zeros(c);
        for trial in 0..TRIALS {
            // s = noise + G[:, target]·w·size; sᵀG⁺s = ‖z‖² + 2 size wᵀ noise_t + size² wᵀG_tt w
            // the coefficients on the unit-length columns: the effect's on its own columns
            // times their lengths
            let w: Vec<f64> = (0..tlen)
                .map(|j| {
                    let draw = if random {
                        rng.sample::<f64, _>(StandardNormal)
                    } else {
                        1.0
                    };
                    draw * self.norms[t0 + j]
                })
                .collect();
            scores.copy_from(&self.noise[trial]);
            for (j, wj) in w.iter().enumerate() {
                scores.axpy(size * wj, &self.gram.column(t0 + j), 1.0);
            }
            let mut cross = 0.0;
            let mut quad = 0.0;
            for (a, wa) in w.iter().enumerate() {
                cross += wa * self.noise[trial][t0 + a];
                for (b, wb) in w.iter().enumerate() {
                    quad += wa * wb * self.gram[(t0 + a, t0 + b)];
                }
            }
            let rss = self.noise_in_span[trial]
                + 2.0 * size * cross
                + size * size * quad
                + self.outside[trial];
            if let Some((g, p_adjusted)) = self.winner(&scores, rss)
                && groups.contains(&g)
                && p_adjusted < self.alpha
            {
                found += 1;
                if found >= needed {
                    return true;
                }
            } else {
                missed += 1;
                if missed > allowed_misses {
                    return false;
                }
            }
        }
        found >= needed
    }

    /// The group and adjusted p-value of the round's winner for scores `s` and `rss`,
    /// among the candidates that pass their family's threshold (`None`: none passes, and
    /// nothing is found).
    fn winner(&self, s: &DVector<f64>, rss: f64) -> Option<(usize, f64)> {
        // singles of one family share ν: the largest reduction has the smallest p
        let mut best_single: [Option<(f64, usize)>; 3] = [None, None, None];
        let mut best: Option<(f64, f64, usize)> = None; // (p_adj, F, group)
        let mut consider = |reduction: f64, r: usize, family: Family, group: usize| {
            let dof = self.dof.saturating_sub(r);
            if dof == 0 {
                return;
            }
            let rest = (rss - reduction).max(0.0);
            let f = if rest > 0.0 {
                (reduction / r as f64) / (rest / dof as f64)
            } else {
                f64::INFINITY
            };
            // below its family's threshold a candidate cannot be found (p·m ≥ α): only
            // the candidates that pass compete for the round
            let threshold = self
                .critical
                .iter()
                .find(|(k, _)| *k == (family_index(family), r))
                .map_or(f64::INFINITY, |(_, f)| *f);
            if f <= threshold {
                return;
            }
            let p = if f <= 0.0 {
                1.0
            } else if r == 1 {
                t_two_sided_tail(f.sqrt(), Some(dof as f64))
            } else if f.is_infinite() {
                0.0
            } else {
                FisherSnedecor::new(r as f64, dof as f64).map_or(1.0, |d| d.sf(f))
            };
            let p_adjusted = (p * self.family_size[family_index(family)].max(1) as f64).min(1.0);
            let better = match best {
                None => true,
                Some((bp, bf, _)) => p_adjusted < bp || (p_adjusted == bp && f > bf),
            };
            if better {
                best = Some((p_adjusted, f, group));
            }
        };
        for o in &self.offered {
            if o.rank == 0 {
                continue;
            }
            if o.len == 1 {
                let reduction = s[o.start] * s[o.start] * o.pinv[(0, 0)];
                let slot = &mut best_single[family_index(o.family)];
                if slot.is_none_or(|(r, _)| reduction > r) {
                    *slot = Some((reduction, o.group));
                }
            } else {
                // sᵀ P s over the block, without a copy of it (this runs for every
                // candidate of every trial)
                let reduction: f64 = (0..o.len)
                    .map(|a| {
                        let row: f64 = (0..o.len).map(|b| o.pinv[(a, b)] * s[o.start + b]).sum();
                        s[o.start + a] * row
                    })
                    .sum();
                consider(reduction, o.rank, o.family, o.group);
            }
        }
        for (k, slot) in best_single.iter().enumerate() {
            if let Some((reduction, group)) = *slot {
                let family = [Family::Systematic, Family::OffsetStep, Family::Outlier][k];
                consider(reduction, 1, family, group);
            }
        }
        best.map(|(p, _, g)| (g, p))
    }

    /// The smallest size (in the unit of the target's columns, relative to σ = 1) at
    /// which an effect on `target` is found — a candidate of one of `groups` wins — in
    /// `power` of the trials; `None` when even 10⁴ times the first guess is not enough
    /// (another explanation always wins).
    pub fn size_for(
        &self,
        target: (usize, usize),
        random: bool,
        groups: &[usize],
        power: f64,
    ) -> Option<f64> {
        let alpha = self.alpha;
        let (t0, tlen) = target;
        // the target's projected squared length, in its own columns' units
        let trace: f64 = (0..tlen)
            .map(|j| self.gram[(t0 + j, t0 + j)] * self.norms[t0 + j].powi(2))
            .sum();
        let length: f64 = (0..tlen).map(|j| self.norms[t0 + j].powi(2)).sum();
        if trace.is_nan() || trace <= RANK_TOLERANCE * length {
            return None;
        }
        let found_in_power = |size: f64| self.found_in(target, size, random, groups, power);
        // start from the size its own F test finds in `power` of the runs: competing
        // candidates only lower the chance, so the answer is rarely below it
        let rank = tlen.min(self.dof.saturating_sub(1)).max(1);
        let family = self
            .offered
            .iter()
            .find(|o| o.start == t0)
            .map_or(Family::Systematic, |o| o.family);
        let m = self.family_size[family_index(family)].max(1) as f64;
        let alone =
            noncentrality_for_power(alpha / m, power, rank, self.dof.saturating_sub(rank) as f64)
                .map_or(1.0 / trace.sqrt(), |lambda| (lambda / trace).sqrt());
        let (mut lo, mut hi);
        if !found_in_power(alone) {
            lo = alone;
            hi = alone * 1.25;
            let mut steps = 0;
            while !found_in_power(hi) {
                lo = hi;
                hi *= 2.0;
                steps += 1;
                if steps > 14 {
                    return None;
                }
            }
        } else {
            hi = alone;
            lo = alone * 0.8;
            let mut steps = 0;
            while found_in_power(lo) {
                hi = lo;
                lo *= 0.5;
                steps += 1;
                if steps > 30 {
                    return Some(hi);
                }
            }
        }
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if !found_in_power(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
            if hi - lo <= 2e-3 * hi {
                break;
            }
        }
        Some(hi)
    }
}
