//! The first round of a diagnosis's forward selection, emulated on the design alone.
//!
//! An effect is *found* when, in the round it is offered, its candidate has the smallest
//! Bonferroni-adjusted p-value of all candidates and that p is below the family's
//! false-alarm probability (`diagnose`'s rule). Its own F test passing is not enough: a
//! jump in the middle of a run is also half explained by a drift, whose family is
//! smaller, and a diagnosis then names the drift. The chance of being found therefore
//! depends on the other candidates, and it is computed from the design alone:
//!
//! - a run of pure noise (unit σ) leaves the residuals e₀ = (I − H)z, z standard normal
//!   ([`FitGeometry::residual_of`]: O(n) and one product with the fit's cofactor), with
//!   RSS₀ = ‖e₀‖² ~ χ²(dof), and every candidate's scores s₀ = X̂ᵀe₀ (its columns X̂ at
//!   unit length; every jump of a stream from one running sum, [`Column::Suffix`]);
//! - a run with the effect x·δ adds δ·G\[:, target\] to the scores, G = X̂ᵀ(I − H)X̂, and
//!   2δ·s₀\[target\] + δ²·G\[target, target\] to the RSS: only the target's columns of G
//!   are ever formed, each from one (I − H)x;
//! - every candidate's F statistic and p-value follow from its scores and the RSS as in
//!   `diagnose`.
//!
//! The noise is drawn [`TRIALS`] times with a fixed seed (the same draws for every size
//! tried, so the chance of being found grows smoothly with the size), and the size at
//! which the effect is found in 90 % of the trials is found by bisection.
//!
//! **Near-linear in the candidates.** A trial asks whether the target's own candidates
//! beat every other. The candidates that the effect moves most (the target's groups and
//! the [`NEAR`] most correlated others) are scored exactly in every trial; for the rest,
//! grouped by family and degrees of freedom, the trial keeps its [`TOP`] strongest noise
//! scores, and the triangle inequality ‖s₀ + δ·g‖ ≤ ‖s₀‖ + δ·‖g‖ bounds what the effect
//! can make of them. Only when that bound could beat the target's candidate is the group
//! scored exactly. The answer is the one scoring every candidate in every trial gives;
//! a trial costs O(NEAR) instead of O(candidates).

mod columns;
mod winner;

pub use columns::Column;

use columns::Columns;
use nalgebra::{DMatrix, SymmetricEigen};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use winner::{Target, TrialScratch};

use super::power::noncentrality_for_power;
use crate::diagnose::candidates::Family;
use crate::diagnose::geometry::FitGeometry;

/// The draws of the scores per round.
pub const TRIALS: usize = 2000;

/// The seed of the draws (the same plan every time).
const SEED: u64 = 0x706c_616e;

/// Directions whose squared length is below this fraction of the largest column's add
/// nothing (as `diagnose`'s block scores).
const RANK_TOLERANCE: f64 = 1e-9;

/// The candidates outside a target's groups that are scored exactly in every trial: the
/// ones the effect moves most.
pub const NEAR: usize = 48;

/// The strongest noise scores a trial keeps of every class of candidates (family and
/// degrees of freedom).
pub const TOP: usize = 8;

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
    /// Its class (family and numerator degrees of freedom); `None` when it adds nothing.
    class: Option<usize>,
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

    /// ‖s‖²_P = sᵀ P s of its scores `s` (its block of a vector of the round's columns).
    fn reduction(&self, s: &[f64]) -> f64 {
        if self.len == 1 {
            s[0] * s[0] * self.pinv[(0, 0)]
        } else {
            (0..self.len)
                .map(|a| {
                    let row: f64 = (0..self.len).map(|b| self.pinv[(a, b)] * s[b]).sum();
                    s[a] * row
                })
                .sum::<f64>()
                .max(0.0)
        }
    }
}

/// Candidates that share a family and their numerator degrees of freedom: one F
/// threshold and one Bonferroni divisor, so that the larger reduction always has the
/// smaller p.
#[derive(Debug, Clone)]
struct Class {
    family: Family,
    /// Numerator degrees of freedom.
    r: usize,
    /// The F a candidate must exceed to pass its family's Bonferroni threshold (∞: none
    /// can, the residual degrees of freedom are too few).
    critical: f64,
    /// The offered candidates of the class.
    members: Vec<usize>,
}

/// One trial's draw: its noise scores, RSS₀ and the strongest scores of every class.
type Drawn = (Vec<f64>, f64, Vec<(f64, usize)>);

/// A round of the selection with its candidates and its draws.
pub struct Round<'g> {
    geometry: &'g FitGeometry,
    columns: Columns,
    offered: Vec<Offered>,
    classes: Vec<Class>,
    dof: usize,
    family_size: [usize; 3],
    /// The noise scores s₀ of every trial, one after the other (`columns.len()` each).
    noise: Vec<f64>,
    /// RSS₀ of every trial.
    rss: Vec<f64>,
    /// The [`TOP`] largest ‖s₀‖_P of every class in every trial, largest first, as
    /// (value, offered index); trial t's class k at `(t·classes + k)·TOP`.
    top: Vec<(f64, usize)>,
    /// The false-alarm probability of every family.
    alpha: f64,
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

impl<'g> Round<'g> {
    /// The memory a round of `columns` candidate columns over `readings` readings needs,
    /// bytes (its noise scores, its columns and their scratch).
    pub fn bytes_needed(columns: usize, readings: usize) -> u128 {
        let (c, n, t) = (columns as u128, readings as u128, TRIALS as u128);
        8 * (t * c + c * n + 4 * c + 4 * n) + t * 16 * (TOP as u128) * 4
    }

    /// The round of the fit whose `geometry` is given, with `dof` residual degrees of
    /// freedom, the candidates `blocks` (each: family, group, columns; a
    /// [`Column::Suffix`] of the `streams`, each a stream's readings in time order), the
    /// true number of candidates of each family (Bonferroni divisors; the jump columns
    /// offered may be a sample of the stops), and the false-alarm probability `alpha` of
    /// every family.
    pub fn new(
        geometry: &'g FitGeometry,
        dof: usize,
        streams: Vec<Vec<usize>>,
        blocks: Vec<(Family, usize, Vec<Column>)>,
        family_size: [usize; 3],
        alpha: f64,
    ) -> Round<'g> {
        let mut all: Vec<Column> = Vec::new();
        let mut offered = Vec::new();
        for (family, group, block) in blocks {
            offered.push(Offered {
                family,
                group,
                start: all.len(),
                len: block.len(),
                pinv: DMatrix::zeros(0, 0),
                rank: 0,
                class: None,
            });
            all.extend(block);
        }
        let n = geometry.readings();
        let columns = Columns::new(n, streams, all);
        // every candidate's block of G, from (I − H)x of each of its columns
        let blocks: Vec<(DMatrix<f64>, usize)> = offered
            .par_iter()
            .map(|o| {
                let residuals: Vec<Vec<f64>> = (o.start..o.start + o.len)
                    .map(|k| geometry.residual_of(&columns.unit(k)))
                    .collect();
                let mut block = DMatrix::zeros(o.len, o.len);
                for a in 0..o.len {
                    for b in a..o.len {
                        let v = 0.5
                            * (columns.dot(o.start + a, &residuals[b])
                                + columns.dot(o.start + b, &residuals[a]));
                        block[(a, b)] = v;
                        block[(b, a)] = v;
                    }
                }
                pinv(block, RANK_TOLERANCE)
            })
            .collect();
        let mut classes: Vec<Class> = Vec::new();
        for (index, (o, (p, rank))) in offered.iter_mut().zip(blocks).enumerate() {
            o.pinv = p;
            o.rank = rank;
            if rank == 0 {
                continue;
            }
            let r = if o.len == 1 { 1 } else { rank };
            let k = match classes
                .iter()
                .position(|c| c.family == o.family && c.r == r)
            {
                Some(k) => k,
                None => {
                    let m = family_size[family_index(o.family)].max(1) as f64;
                    let critical = if dof > r {
                        super::power::critical_f(alpha / m, r, (dof - r) as f64)
                    } else {
                        f64::INFINITY
                    };
                    classes.push(Class {
                        family: o.family,
                        r,
                        critical,
                        members: Vec::new(),
                    });
                    classes.len() - 1
                }
            };
            classes[k].members.push(index);
            o.class = Some(k);
        }
        // the noise of every trial: its own stream of draws, so that the trials can be
        // drawn in parallel and come out the same
        let c = columns.len();
        let drawn: Vec<Drawn> = (0..TRIALS)
            .into_par_iter()
            .map_init(Vec::new, |scratch, trial| {
                let mut rng = ChaCha8Rng::seed_from_u64(SEED);
                rng.set_stream(trial as u64);
                let z: Vec<f64> = (0..n).map(|_| rng.sample(StandardNormal)).collect();
                let e = geometry.residual_of(&z);
                let rss: f64 = e.iter().map(|v| v * v).sum();
                let mut s = vec![0.0; c];
                columns.transpose_times(&e, &mut s, scratch);
                let mut top = vec![(-1.0, usize::MAX); classes.len() * TOP];
                for (k, class) in classes.iter().enumerate() {
                    let slots = &mut top[k * TOP..(k + 1) * TOP];
                    for &index in &class.members {
                        let o = &offered[index];
                        let a = o.reduction(&s[o.start..o.start + o.len]).sqrt();
                        if a > slots[TOP - 1].0 {
                            let at = slots.iter().position(|x| a > x.0).unwrap_or(TOP - 1);
                            slots[at..].rotate_right(1);
                            slots[at] = (a, index);
                        }
                    }
                }
                (s, rss, top)
            })
            .collect();
        let mut noise = Vec::with_capacity(TRIALS * c);
        let mut rss = Vec::with_capacity(TRIALS);
        let mut top = Vec::with_capacity(TRIALS * classes.len() * TOP);
        for (s, r, t) in drawn {
            noise.extend(s);
            rss.push(r);
            top.extend(t);
        }
        Round {
            geometry,
            columns,
            offered,
            classes,
            dof,
            family_size,
            noise,
            rss,
            top,
            alpha,
        }
    }

    /// The candidates offered.
    pub fn offered(&self) -> &[Offered] {
        &self.offered
    }

    /// The correlations of the columns of one-column candidates `singles` off the model's
    /// span: element \[a\]\[b\] for `singles[a]` and `singles[b]` (`None` when either adds
    /// nothing or has several columns).
    pub fn correlations(&self, singles: &[usize]) -> Vec<Vec<Option<f64>>> {
        // G_aa of a one-column candidate that adds a direction: the inverse of its
        // pseudo-inverse (its columns are at unit length)
        let diagonal: Vec<Option<f64>> = singles
            .iter()
            .map(|&i| {
                let o = &self.offered[i];
                (o.len == 1 && o.rank > 0).then(|| 1.0 / o.pinv[(0, 0)])
            })
            .collect();
        // a row at a time from its column's (I − H)x: memory O(n) per row, not per single
        singles
            .par_iter()
            .zip(&diagonal)
            .map(|(&i, aa)| {
                let Some(aa) = *aa else {
                    return vec![None; singles.len()];
                };
                let v = self
                    .geometry
                    .residual_of(&self.columns.unit(self.offered[i].start));
                singles
                    .iter()
                    .zip(&diagonal)
                    .map(|(&j, bb)| {
                        let bb = (*bb)?;
                        let ab = self.columns.dot(self.offered[j].start, &v);
                        Some(ab / (aa * bb).sqrt())
                    })
                    .collect()
            })
            .collect()
    }

    /// Whether an effect is found in at least `power` of the trials (the fraction found
    /// ≥ `power`): the effect adds `size` times the target's columns (with their own
    /// lengths, in units of σ) to the readings, and it is found when the winner of the
    /// round belongs to the target's groups and passes α. With `random`, the
    /// coefficients are multiplied by a standard normal draw per column and trial
    /// (offsets drawn anew every cycle). The trials stop as soon as the answer is
    /// certain — enough found, or too many missed — which gives the answer all
    /// [`TRIALS`] would (the same draws in the same order) in a fraction of the time far
    /// from the threshold.
    fn found_in(&self, target: &Target, size: f64, random: bool, power: f64) -> bool {
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
        let mut rng = ChaCha8Rng::seed_from_u64(SEED ^ 0x5eed);
        let mut found = 0usize;
        let mut missed = 0usize;
        let mut w: Vec<f64> = Vec::with_capacity(target.len);
        let mut scratch = TrialScratch::default();
        for trial in 0..TRIALS {
            // the coefficients on the unit-length columns: the effect's on its own
            // columns times their lengths
            w.clear();
            w.extend((target.start..target.start + target.len).map(|k| {
                let draw = if random {
                    rng.sample::<f64, _>(StandardNormal)
                } else {
                    1.0
                };
                draw * self.columns.norm(k)
            }));
            if self.found_in_trial(target, trial, size, &w, &mut scratch) {
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

    /// The smallest size (in the unit of the target's columns, relative to σ = 1) at
    /// which an effect on `target` (its first column and number of columns) is found — a
    /// candidate of one of `groups` wins — in `power` of the trials; `None` when even
    /// 10⁴ times the first guess is not enough (another explanation always wins).
    pub fn size_for(
        &self,
        target: (usize, usize),
        random: bool,
        groups: &[usize],
        power: f64,
    ) -> Option<f64> {
        let alpha = self.alpha;
        let (t0, tlen) = target;
        let target = self.target(target, groups);
        // the target's projected squared length, in its own columns' units
        let trace: f64 = (0..tlen)
            .map(|j| target.gram_columns[j][t0 + j] * self.columns.norm(t0 + j).powi(2))
            .sum();
        let length: f64 = (0..tlen).map(|j| self.columns.norm(t0 + j).powi(2)).sum();
        if trace.is_nan() || trace <= RANK_TOLERANCE * length {
            return None;
        }
        let found_in_power = |size: f64| self.found_in(&target, size, random, power);
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
