//! Angle blocks (docs/FORMAT.md §12): a laboratory's blocks as result rows, the per-block
//! weighted mean written out from the textbook (each block a scalar of its own, among the
//! laboratories that report it), and a generator of block comparisons with a known truth.

use polycal::kc::LabResult;
use polycal::results::{Quantity, ResultRow};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

/// A laboratory's angle blocks: `blocks[b]` is block b + 1's (value, u), arcsec, or `None`
/// where the laboratory does not report it; written with U = 2u, k = 2.
pub fn block_lab(name: &str, blocks: &[Option<(f64, f64)>]) -> LabResult {
    let rows = blocks
        .iter()
        .enumerate()
        .filter_map(|(b, block)| {
            let (x, u) = (*block)?;
            Some(
                ResultRow::new(Quantity::AngleBlock, b as u32 + 1, x)
                    .with_expanded_u(2.0 * u)
                    .with_k(2.0),
            )
        })
        .collect();
    LabResult::from_rows(name, rows)
}

/// The textbook per-block fit of the laboratories `inside`: per block b, over those of
/// them that report it, x_ref,b = Σ x/u² / Σ 1/u², u_ref,b = (Σ 1/u²)^(−1/2) (NaN where
/// none reports it), and the joint χ² = Σ_b Σ_i (x − x_ref,b)²/u², ν = Σ_b (n_b − 1).
#[derive(Debug, Clone)]
pub struct BlockFit {
    pub reference: Vec<f64>,
    pub reference_u: Vec<f64>,
    pub chi2: f64,
    pub dof: usize,
    /// χ² of each block on its own, about its weighted mean.
    pub chi2_per_block: Vec<f64>,
}

/// [`BlockFit`] of `x[i][b]` (`None`: not reported) with standard uncertainties `u[i][b]`
/// (each a variance u² + extra, the caller's τ² or u_stab², already in it).
pub fn block_fit(x: &[Vec<Option<f64>>], u: &[Vec<f64>], inside: &[usize]) -> BlockFit {
    let blocks = x[0].len();
    let mut fit = BlockFit {
        reference: Vec::new(),
        reference_u: Vec::new(),
        chi2: 0.0,
        dof: 0,
        chi2_per_block: Vec::new(),
    };
    for b in 0..blocks {
        let mut sum_w = 0.0;
        let mut sum_wx = 0.0;
        let mut n = 0;
        for &i in inside {
            if let Some(xi) = x[i][b] {
                let w = 1.0 / (u[i][b] * u[i][b]);
                sum_w += w;
                sum_wx += w * xi;
                n += 1;
            }
        }
        if n == 0 {
            fit.reference.push(f64::NAN);
            fit.reference_u.push(f64::NAN);
            fit.chi2_per_block.push(0.0);
            continue;
        }
        let mean = sum_wx / sum_w;
        let mut chi2 = 0.0;
        for &i in inside {
            if let Some(xi) = x[i][b] {
                chi2 += (xi - mean) * (xi - mean) / (u[i][b] * u[i][b]);
            }
        }
        fit.reference.push(mean);
        fit.reference_u.push(1.0 / sum_w.sqrt());
        fit.chi2 += chi2;
        fit.chi2_per_block.push(chi2);
        fit.dof += n - 1;
    }
    fit
}

/// A comparison of angle blocks: `x[i][b]` (`None` where laboratory i does not report
/// block b) and `u[i][b]`, arcsec.
#[derive(Debug, Clone)]
pub struct Blocks {
    pub x: Vec<Vec<Option<f64>>>,
    pub u: Vec<Vec<f64>>,
}

impl Blocks {
    /// The laboratories as results named L0, L1, …
    pub fn results(&self) -> Vec<LabResult> {
        self.x
            .iter()
            .zip(&self.u)
            .enumerate()
            .map(|(i, (x, u))| {
                let blocks: Vec<Option<(f64, f64)>> =
                    x.iter().zip(u).map(|(x, u)| x.map(|x| (x, *u))).collect();
                block_lab(&format!("L{i}"), &blocks)
            })
            .collect()
    }
}

/// The blocks' true deviations from nominal, arcsec.
pub fn block_truth(blocks: usize) -> Vec<f64> {
    (0..blocks)
        .map(|b| 2.0 * (b as f64 * 1.7 + 0.4).sin())
        .collect()
}

/// One comparison of `blocks` angle blocks by `labs` laboratories: each u drawn uniformly
/// in 0.05–0.2″ (per laboratory and block), each result the truth plus N(0, u²); each
/// laboratory misses each block with probability `missing`, the pattern drawn again until
/// every block has at least two laboratories and every laboratory at least one block.
/// `bias` = (laboratory, block, amount in its u) adds that to the result, the laboratory
/// then reporting that block.
pub fn block_comparison(
    rng: &mut ChaCha8Rng,
    blocks: usize,
    labs: usize,
    missing: f64,
    bias: Option<(usize, usize, f64)>,
) -> Blocks {
    let truth = block_truth(blocks);
    let reported = loop {
        let pattern: Vec<Vec<bool>> = (0..labs)
            .map(|i| {
                (0..blocks)
                    .map(|b| {
                        bias.is_some_and(|(l, k, _)| l == i && k == b)
                            || rng.random::<f64>() >= missing
                    })
                    .collect()
            })
            .collect();
        let blocks_kept = (0..blocks).all(|b| pattern.iter().filter(|p| p[b]).count() >= 2);
        let labs_kept = pattern.iter().all(|p| p.iter().any(|&r| r));
        if blocks_kept && labs_kept {
            break pattern;
        }
    };
    let mut x = Vec::with_capacity(labs);
    let mut u = Vec::with_capacity(labs);
    for i in 0..labs {
        let (mut xi, mut ui) = (Vec::new(), Vec::new());
        for b in 0..blocks {
            let u_ib = rng.random_range(0.05..0.2);
            let z: f64 = StandardNormal.sample(rng);
            let shift = match bias {
                Some((l, k, amount)) if l == i && k == b => amount * u_ib,
                _ => 0.0,
            };
            xi.push(reported[i][b].then_some(truth[b] + u_ib * z + shift));
            ui.push(u_ib);
        }
        x.push(xi);
        u.push(ui);
    }
    Blocks { x, u }
}

/// The decision of docs/FORMAT.md §12 on angle blocks by brute force: the laboratories in
/// the reference — all when the joint χ² of every one passes; else, from n − 1 down, the
/// subset of the first size with one that passes, the most consistent passing one (the
/// smaller χ² at one ν, the larger p-value where ν differs between subsets of a size, as
/// when laboratories miss blocks; a subset with ν = 0 is no test); all when none
/// passes, or when that subset leaves out more than half.
pub fn block_largest_subset(x: &[Vec<Option<f64>>], u: &[Vec<f64>]) -> Vec<usize> {
    let labs = x.len();
    let passes = |fit: &BlockFit| fit.chi2 <= super::critical(fit.dof);
    let all: Vec<usize> = (0..labs).collect();
    if passes(&block_fit(x, u, &all)) {
        return all;
    }
    for size in (2..labs).rev() {
        // the most consistent passing subset: the smaller χ² at one ν, the larger p-value
        // P(χ²_ν > χ²) at different ν (the library's rule, docs/FORMAT.md §12)
        let mut best: Option<(BlockFit, Vec<usize>)> = None;
        for mask in 0u32..(1 << labs) {
            if mask.count_ones() as usize != size {
                continue;
            }
            let set: Vec<usize> = (0..labs).filter(|&r| mask & (1 << r) != 0).collect();
            let fit = block_fit(x, u, &set);
            let better = |b: &BlockFit| {
                if fit.dof == b.dof {
                    fit.chi2 < b.chi2
                } else {
                    let (p, q) = (
                        super::encoder::p_value(fit.chi2, fit.dof),
                        super::encoder::p_value(b.chi2, b.dof),
                    );
                    p > q || (p == q && fit.chi2 < b.chi2)
                }
            };
            // (no degree of freedom: no test, passed over)
            if fit.dof > 0 && passes(&fit) && best.as_ref().is_none_or(|(b, _)| better(b)) {
                best = Some((fit, set));
            }
        }
        if let Some((_, set)) = best {
            return if 2 * (labs - set.len()) > labs {
                all
            } else {
                set
            };
        }
    }
    all
}
