//! Every U of a key comparison by Monte Carlo (docs/FORMAT.md §12, "Other estimates"): a
//! parametric bootstrap, as the consensus builders do. Each of M draws simulates every
//! result from the fitted model — the reference, for the random-effects methods a closed
//! laboratory effect with a dark uncertainty τ* of each quantity, and the result's own
//! closed noise with its u (the pilot's u_stab in it) — and evaluates the reference again
//! from the draw. For the random-effects methods τ* is itself drawn, as τ's estimate from a
//! first simulated comparison with the fitted τ (two stages), and τ is estimated again from
//! the draw: so τ's own uncertainty is in every U. The degree of equivalence of a draw is y_i − x_ref⁽ᵐ⁾; U is the 95.45 %
//! quantile of its magnitude (k = 2 for a normal law), and u_ref the standard deviation of
//! x_ref⁽ᵐ⁾. Each pair's U is the 95.45 % quantile of the drawn |y_i − y_j| when those draws
//! fit beside the others ([`MAX_NUMBERS`]). The generator is seeded: the same inputs give
//! the same U.

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use nalgebra::DMatrix;

use super::closed::{self, ClosedCovariance};
use super::reference;
use super::{KcError, KeyComparison, ReferenceMethod};

/// The generator's seed: a run is reproducible.
pub(crate) const SEED: u64 = 20_551;

/// The most numbers the draws may keep (M × results × positions): 200 MB.
pub(crate) const MAX_NUMBERS: u64 = 25_000_000;

/// The fewest draws: a 95.45 % quantile needs a few hundred at least.
pub(crate) const MIN_DRAWS: usize = 1_000;

/// What the draws start from, in the comparison's scaled units.
pub(crate) struct Model<'a> {
    /// The reference per quantity.
    pub reference: &'a [f64],
    /// Every result's u per quantity (the pilot's u_stab in it), laboratories then repeats.
    pub u: &'a [Vec<f64>],
    /// τ per quantity (0 for the weighted mean).
    pub tau: &'a [f64],
    /// The laboratories in the reference.
    pub inside: &'a [usize],
    /// The method, whose estimate is made again in every draw.
    pub method: ReferenceMethod,
    /// Whether the results are closed vectors (else angle blocks, each on its own).
    pub closed: bool,
    /// Whether each result reports each quantity (`None`: all of them).
    pub measured: Option<&'a [Vec<bool>]>,
    /// How many of the results are laboratories (the pilot's repeats after them): the
    /// pairs are theirs.
    pub labs: usize,
}

impl Model<'_> {
    /// Whether result `r` reports quantity `k`.
    fn reports(&self, r: usize, k: usize) -> bool {
        self.measured
            .is_none_or(|m| m.get(r).and_then(|m| m.get(k)).copied().unwrap_or(false))
    }

    /// Whether the results are closed vectors that report different positions (each closed
    /// over its own).
    fn uneven(&self) -> bool {
        self.closed && self.measured.is_some()
    }

    /// Result `r`'s own noise: closed over the positions it reports, with its u there (0
    /// elsewhere, never used).
    fn own_noise(&self, rng: &mut ChaCha8Rng, r: usize) -> Vec<f64> {
        if !self.uneven() {
            return self.noise(rng, &self.u[r]);
        }
        let positions: Vec<usize> = (0..self.u[r].len())
            .filter(|&k| self.reports(r, k))
            .collect();
        let u: Vec<f64> = positions.iter().map(|&k| self.u[r][k]).collect();
        let drawn = closed_noise(rng, &u);
        let mut noise = vec![0.0; self.u[r].len()];
        for (&k, e) in positions.iter().zip(drawn) {
            noise[k] = e;
        }
        noise
    }

    /// Normal noise with standard deviations `u`: closed for closed vectors.
    fn noise(&self, rng: &mut ChaCha8Rng, u: &[f64]) -> Vec<f64> {
        if self.closed {
            return closed_noise(rng, u);
        }
        u.iter()
            .map(|u| {
                let z: f64 = StandardNormal.sample(rng);
                u * z
            })
            .collect()
    }
}

/// The Monte Carlo U of every result's degree of equivalence (per result, per quantity)
/// and u_ref per quantity, in scaled units; `None` when a draw cannot be fitted.
pub(crate) struct Draws {
    /// U(d_i) per result and quantity.
    pub expanded_u: Vec<Vec<f64>>,
    /// u_ref per quantity.
    pub reference_u: Vec<f64>,
    /// U(d_ab) per pair of laboratories (in the order of [`super::Pairs`]) and quantity,
    /// when the draws kept them.
    pub pairs_u: Option<Vec<Vec<f64>>>,
}

/// Closed normal noise with marginal standard deviations `u` (covariance
/// N/(N − 1)·P·diag(u²)·P, as a closed result is taken to have).
fn closed_noise(rng: &mut ChaCha8Rng, u: &[f64]) -> Vec<f64> {
    let n = u.len() as f64;
    let raw: Vec<f64> = u
        .iter()
        .map(|u| {
            let z: f64 = StandardNormal.sample(rng);
            u * z
        })
        .collect();
    let mean = raw.iter().sum::<f64>() / n;
    let factor = (n / (n - 1.0)).sqrt();
    raw.iter().map(|e| factor * (e - mean)).collect()
}

/// τ per quantity estimated from the draw `y` as the comparison estimated it (0 for the
/// weighted mean).
fn tau_of(model: &Model, y: &[Vec<f64>]) -> Vec<f64> {
    let positions = model.reference.len();
    if !model.method.is_random_effects() {
        return vec![0.0; positions];
    }
    // closed over different positions: on one level first, as the comparison's estimates
    let levelled = model
        .uneven()
        .then(|| super::positions::levelled(y, |r, k| model.reports(r, k), model.reference));
    let y = levelled.as_deref().unwrap_or(y);
    (0..positions)
        .map(|k| {
            let inside: Vec<usize> = model
                .inside
                .iter()
                .copied()
                .filter(|&r| model.reports(r, k))
                .collect();
            if inside.is_empty() {
                return 0.0;
            }
            let x: Vec<f64> = inside.iter().map(|&r| y[r][k]).collect();
            let u: Vec<f64> = inside.iter().map(|&r| model.u[r][k]).collect();
            reference::estimate(&x, &u, model.method).tau
        })
        .collect()
}

/// Every result drawn from the model with the dark uncertainty `tau`.
fn draw(rng: &mut ChaCha8Rng, model: &Model, tau: &[f64]) -> Vec<Vec<f64>> {
    (0..model.u.len())
        .map(|r| {
            let effect = model.noise(rng, tau);
            let noise = model.own_noise(rng, r);
            (0..model.reference.len())
                .map(|k| model.reference[k] + effect[k] + noise[k])
                .collect()
        })
        .collect()
}

/// The reference of one draw `y`, estimated as the comparison was.
fn reference_of(model: &Model, y: &[Vec<f64>]) -> Option<Vec<f64>> {
    let tau = tau_of(model, y);
    let covariances: Vec<ClosedCovariance> = model
        .inside
        .iter()
        .map(|&r| {
            let u = model.u[r].iter().zip(&tau).enumerate().map(|(k, (u, t))| {
                if model.reports(r, k) {
                    u.hypot(*t)
                } else {
                    f64::INFINITY // no weight where the result does not report k
                }
            });
            if model.closed {
                ClosedCovariance::Stated(u.collect())
            } else {
                ClosedCovariance::Independent(u.collect())
            }
        })
        .collect();
    let x: Vec<&[f64]> = model.inside.iter().map(|&r| y[r].as_slice()).collect();
    let v: Vec<&ClosedCovariance> = covariances.iter().collect();
    closed::fit(&x, &v).map(|fit| fit.reference)
}

impl Model<'_> {
    /// The drawn difference of laboratories `a` and `b`, y_a − y_b, at the positions both
    /// report, closed over them when the results report different positions (as the
    /// pairs' d is).
    fn pair_difference(&self, a: usize, b: usize, y: &[Vec<f64>]) -> Vec<(usize, f64)> {
        let mut d: Vec<(usize, f64)> = (0..self.reference.len())
            .filter(|&k| self.reports(a, k) && self.reports(b, k))
            .map(|k| (k, y[a][k] - y[b][k]))
            .collect();
        if self.uneven() && !d.is_empty() {
            let mean = d.iter().map(|(_, d)| d).sum::<f64>() / d.len() as f64;
            d.iter_mut().for_each(|(_, d)| *d -= mean);
        }
        d
    }

    /// Result `r`'s drawn degree of equivalence `y − reference` at the positions it reports
    /// (and the reference has), closed over them when the results report different
    /// positions (as [`super::scaled`] closes it).
    fn degree_of_equivalence(&self, r: usize, y: &[f64], reference: &[f64]) -> Vec<(usize, f64)> {
        let mut d: Vec<(usize, f64)> = (0..reference.len())
            .filter(|&k| self.reports(r, k) && reference[k].is_finite())
            .map(|k| (k, y[k] - reference[k]))
            .collect();
        if self.uneven() && !d.is_empty() {
            let mean = d.iter().map(|(_, d)| d).sum::<f64>() / d.len() as f64;
            d.iter_mut().for_each(|(_, d)| *d -= mean);
        }
        d
    }
}

/// The 95.45 % quantile of `magnitudes` (reordered); NaN for none (a block the result
/// does not report).
fn quantile_9545(magnitudes: &mut [f64]) -> f64 {
    if magnitudes.is_empty() {
        return f64::NAN;
    }
    let at = ((magnitudes.len() as f64 * 0.9545).ceil() as usize).clamp(1, magnitudes.len()) - 1;
    let (_, value, _) = magnitudes.select_nth_unstable_by(at, f64::total_cmp);
    *value
}

/// `draws` draws from `model`; see the module's documentation.
pub(crate) fn run(model: &Model, draws: usize, with_pairs: bool) -> Option<Draws> {
    let results = model.u.len();
    let positions = model.reference.len();
    let mut rng = ChaCha8Rng::seed_from_u64(SEED);
    let mut magnitudes = vec![vec![Vec::with_capacity(draws); positions]; results];
    let pairs: Vec<(usize, usize)> = if with_pairs {
        (0..model.labs)
            .flat_map(|a| (a + 1..model.labs).map(move |b| (a, b)))
            .collect()
    } else {
        Vec::new()
    };
    let mut pair_magnitudes = vec![vec![Vec::with_capacity(draws); positions]; pairs.len()];
    let (mut sum, mut sum_squares) = (vec![0.0; positions], vec![0.0; positions]);
    for _ in 0..draws {
        let y = if model.method.is_random_effects() {
            // τ* as its estimate varies: from a first comparison drawn with the fitted τ
            let first = draw(&mut rng, model, model.tau);
            draw(&mut rng, model, &tau_of(model, &first))
        } else {
            draw(&mut rng, model, model.tau)
        };
        let reference = reference_of(model, &y)?;
        for k in 0..positions {
            sum[k] += reference[k];
            sum_squares[k] += reference[k] * reference[k];
        }
        for (r, drawn) in magnitudes.iter_mut().enumerate() {
            for (k, d) in model.degree_of_equivalence(r, &y[r], &reference) {
                drawn[k].push(d.abs());
            }
        }
        for (&(a, b), drawn) in pairs.iter().zip(pair_magnitudes.iter_mut()) {
            for (k, d) in model.pair_difference(a, b, &y) {
                drawn[k].push(d.abs());
            }
        }
    }
    let m = draws as f64;
    let reference_u = (0..positions)
        .map(|k| {
            let mean = sum[k] / m;
            if !mean.is_finite() {
                return f64::NAN; // a block nobody in the reference reports
            }
            ((sum_squares[k] / m - mean * mean).max(0.0) * m / (m - 1.0)).sqrt()
        })
        .collect();
    let expanded_u = magnitudes
        .iter_mut()
        .map(|per_result| per_result.iter_mut().map(|d| quantile_9545(d)).collect())
        .collect();
    let pairs_u = with_pairs.then(|| {
        pair_magnitudes
            .iter_mut()
            .map(|per_pair| per_pair.iter_mut().map(|d| quantile_9545(d)).collect())
            .collect()
    });
    Some(Draws {
        expanded_u,
        reference_u,
        pairs_u,
    })
}

/// Every U of the degrees of equivalence (the pilot's repeats' too) and u_ref by `draws`
/// Monte Carlo draws from `model` ([`run`]), in place, with a note; refused with
/// a laboratory's own covariance, too few draws, or more than the machine should hold.
pub(crate) fn apply(
    comparison: &mut KeyComparison,
    model: &Model,
    draws: usize,
    covariances: &[Option<DMatrix<f64>>],
    scale: f64,
) -> Result<(), KcError> {
    let refuse = |reason: String| Err(KcError::MonteCarlo(reason));
    if covariances.iter().any(Option::is_some) {
        return refuse(
            "the draws take every result as closed with its stated u; a laboratory's own \
             covariance is not drawn from"
                .to_string(),
        );
    }
    if draws < MIN_DRAWS {
        return refuse(format!(
            "{draws} draws: at least {} for a 95.45 % quantile",
            MIN_DRAWS
        ));
    }
    let numbers = (draws as u64)
        .saturating_mul(model.u.len() as u64)
        .saturating_mul(model.reference.len() as u64);
    if numbers > MAX_NUMBERS {
        return refuse(format!(
            "{draws} draws × {} results × {} positions = {numbers} numbers to keep, more than \
             {} (200 MB): fewer draws",
            model.u.len(),
            model.reference.len(),
            MAX_NUMBERS
        ));
    }
    // the pairs' U too when their draws fit in the same room
    let pairs = (model.labs * model.labs.saturating_sub(1) / 2) as u64;
    let with_pairs = numbers.saturating_add(
        (draws as u64)
            .saturating_mul(pairs)
            .saturating_mul(model.reference.len() as u64),
    ) <= MAX_NUMBERS;
    let found = run(model, draws, with_pairs)
        .ok_or_else(|| KcError::MonteCarlo("a drawn comparison cannot be fitted".to_string()))?;
    if let Some(pairs_u) = &found.pairs_u {
        let listed: Vec<super::PairDifference> = comparison
            .pairs
            .iter()
            .zip(pairs_u)
            .map(|(mut pair, u)| {
                pair.expanded_u = u.iter().map(|u| u * scale).collect();
                pair
            })
            .collect();
        comparison.pairs = super::Pairs::from(listed);
    }
    let degrees = comparison.degrees_of_equivalence.iter_mut().chain(
        comparison
            .pilot
            .iter_mut()
            .flat_map(|p| p.degrees_of_equivalence.iter_mut()),
    );
    for (doe, expanded_u) in degrees.zip(&found.expanded_u) {
        doe.expanded_u = expanded_u.iter().map(|u| u * scale).collect();
    }
    comparison.reference_u = found.reference_u.iter().map(|u| u * scale).collect();
    comparison.notes.push(format!(
        "every U(d_i) and u_ref by Monte Carlo: {draws} draws from the fitted model (the \
         reference{}, each result's {}noise with its u), the reference evaluated again \
         in every draw{}; U is the 95.45 % quantile of |d_i| (k = 2 for a normal law), u_ref \
         the standard deviation of the drawn references; seed {} (the same inputs give the same \
         U); {}",
        match (model.method.is_random_effects(), model.closed) {
            (true, true) => ", a closed laboratory effect with the dark uncertainty τ",
            (true, false) => ", a laboratory effect with the dark uncertainty τ",
            (false, _) => "",
        },
        if model.closed { "closed " } else { "" },
        if model.method.is_random_effects() {
            " with τ estimated again, so that τ's own uncertainty is in U"
        } else {
            ""
        },
        SEED,
        if found.pairs_u.is_some() {
            "the pairs' U too: the 95.45 % quantile of the drawn |d_ij|".to_string()
        } else {
            format!(
                "the pairs' U stay 2·√(u_i² + u_j² + …): their draws would keep more than {} \
                 numbers",
                MAX_NUMBERS
            )
        }
    ));
    Ok(())
}
