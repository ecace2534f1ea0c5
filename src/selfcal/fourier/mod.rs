//! The closure model with heads off the position grid, harmonic by harmonic.
//!
//! Head j sits at the fractional position offset δ_j = ψ_j·P/360°. With e band-limited
//! (harmonics κ with |κ| < P/2, and κ = P/2 as a cosine on the grid), the mean reading
//! of head j at step p over the cycles, ȳ_j[p], has the DFT
//!
//! ```text
//! Ȳ_j(k) = A(k) + z_j(k)·Φ(k),   z_j(k) = e^{2πi κ δ_j / P}  (κ = P/2: cos(π δ_j))
//! ```
//!
//! with A the table's error and Φ the disc's (the gauge Σα = 0, Σφ′ = 0 puts both
//! means in the heads' constants). Per harmonic, the normal equations of the readings
//! (w_j readings per position of head j) are
//!
//! ```text
//! [ W   t ] [A]   [ Σ w_j Ȳ_j       ]      W = Σ w_j,  t = Σ w_j z_j,  V = Σ w_j |z_j|²
//! [ t̄   V ] [Φ] = [ Σ w_j z̄_j Ȳ_j  ]      det = W V − |t|² = Σ_{a<b} w_a w_b |z_a − z_b|²
//! ```
//!
//! — the circulant engine's 2 × 2 system ([`crate::solve::circulant`]) with fractional
//! phases; for whole offsets the two are the same equations. The determinant is formed
//! without cancellation. A harmonic whose determinant is below 1e-12 of W·V is lost:
//! Φ(k) = 0, A(k) = Σ w_j Ȳ_j / W. The cofactor is the engine's regular part
//! ([`crate::solve::cofactor`]) built from this spectrum.

pub(crate) mod design;

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::Head;
use super::SelfcalSet;
use super::solution::{Closure, SelfcalOptions, SelfcalSolveError, no_correction};
use crate::solve::cofactor::{Base, Cofactor, Structured};
use crate::solve::{Engine, ParameterLayout, memory};
use crate::uncertainty::calibration::CellMap;

/// A harmonic is lost when det ≤ this fraction of W·V.
const LOST_BELOW: f64 = 1e-12;

/// Solves the closure model of heads at fractional offsets (module documentation).
pub(super) fn closure_off_grid(
    set: &SelfcalSet,
    heads: &[Head],
    offsets: &[f64],
    options: &SelfcalOptions,
) -> Result<Closure, SelfcalSolveError> {
    let p = set.positions;
    let m = heads.len();
    // the map's two coefficients per head and harmonic, the per-head views and sums (M·P
    // complex each), the readings' residuals and stream indices, and a few P-long vectors
    let needed_bytes = 16 * 5 * (m as u128) * (p as u128)
        + 16 * (set.readings.len() as u128)
        + 16 * 12 * (p as u128);
    if let Some((limit_bytes, _)) = memory::limit_for(needed_bytes, options.memory_limit_bytes)
        && needed_bytes > u128::from(limit_bytes)
    {
        return Err(SelfcalSolveError::TooLarge {
            positions: p,
            heads: m,
            needed_bytes,
            limit_bytes,
        });
    }
    let head_index = |head: u32| heads.binary_search_by_key(&head, |h| h.head).unwrap_or(0);

    // cell sums and counts per (head, step)
    let mut sum = vec![0.0; m * p];
    let mut count = vec![0usize; m * p];
    let reading_head: Vec<usize> = set
        .readings
        .iter()
        .map(|r| {
            let j = head_index(r.head);
            sum[j * p + r.step] += r.reading_arcsec;
            count[j * p + r.step] += 1;
            j
        })
        .collect();
    let map = OffGridMap::new(p, offsets, &count);
    let weight = &map.weight;
    let Spectra {
        head_mean,
        alpha: a,
        phi,
    } = map.spectra(&sum);
    let alpha = map.to_real(&a);
    let phi_prime = map.to_real(&phi);
    // each head's view of the disc: φ′ at its fractional positions
    let views: Vec<Vec<f64>> = (0..m)
        .map(|j| {
            let shifted: Vec<Complex<f64>> =
                (0..p).map(|k| phi[k] * phase(p, k, offsets[j])).collect();
            map.to_real(&shifted)
        })
        .collect();
    let residuals: Vec<f64> = set
        .readings
        .iter()
        .zip(&reading_head)
        .map(|(r, &j)| r.reading_arcsec - alpha[r.step] - views[j][r.step] - head_mean[j])
        .collect();

    // the reported gauge (docs/FORMAT.md §1): φ_f = φ′_f − φ′_P, U_j = U′_j + φ′_P
    let last = phi_prime[p - 1];
    let face_deviation: Vec<f64> = phi_prime.iter().map(|v| v - last).collect();
    let setup: Vec<f64> = head_mean.iter().map(|u| u + last).collect();
    let lost = map.lost.clone();
    let base = Base::from_spectrum(
        map.raa.clone(),
        map.rpp.clone(),
        map.rap.clone(),
        weight.iter().map(|w| 1.0 / (p as f64 * w)).collect(),
    );
    let layout = ParameterLayout {
        faces: p,
        setups: m,
        effects: 0,
    };
    let cofactor =
        Cofactor::structured(layout, Structured::new(base, Vec::new(), &no_correction()));
    Ok(Closure {
        face_deviation,
        setup,
        residuals,
        cofactor,
        lost,
        engine: Engine::Circulant { low_rank: 0 },
        extra_parameters: 0,
    })
}

/// e^{2πiκδ/P} of harmonic k (κ = k or k − P, the signed order) for a head at fractional
/// offset δ; for κ = P/2, cos(πδ) (the cosine on the grid).
fn phase(p: usize, k: usize, delta: f64) -> Complex<f64> {
    if 2 * k == p {
        Complex::new((std::f64::consts::PI * delta).cos(), 0.0)
    } else {
        let signed = if 2 * k < p {
            k as f64
        } else {
            k as f64 - p as f64
        };
        Complex::from_polar(1.0, std::f64::consts::TAU * signed * delta / p as f64)
    }
}

/// The solution of heads off the grid as a linear map of the readings' sums per (head,
/// step) cell (module documentation): per harmonic the 2 × 2 normal equations folded into
/// one coefficient per head for A(k) and for Φ(k), for a fixed pattern of counts. What
/// [`closure_off_grid`] solves, and what a Monte Carlo trial of such a self-calibration
/// solves (a [`CellMap`]).
pub(crate) struct OffGridMap {
    positions: usize,
    heads: usize,
    /// Readings per cell (head j, step s at j·P + s), at least 1.
    count: Vec<f64>,
    /// w_j, readings of head j per position, and its readings in all.
    weight: Vec<f64>,
    head_total: Vec<f64>,
    /// Per harmonic k and head j (at k·M + j): A(k) = Σ_j ca·Ȳ_j(k), Φ(k) = Σ_j cp·Ȳ_j(k).
    ca: Vec<Complex<f64>>,
    cp: Vec<Complex<f64>>,
    /// The cofactor's spectrum (the engine's regular part) and the lost harmonics.
    raa: Vec<f64>,
    rpp: Vec<f64>,
    rap: Vec<Complex<f64>>,
    lost: Vec<usize>,
    forward: std::sync::Arc<dyn rustfft::Fft<f64>>,
    inverse: std::sync::Arc<dyn rustfft::Fft<f64>>,
}

/// Per head the mean reading, and the spectra of the table's error A and the disc's Φ.
struct Spectra {
    head_mean: Vec<f64>,
    alpha: Vec<Complex<f64>>,
    phi: Vec<Complex<f64>>,
}

impl OffGridMap {
    /// The map of `positions` positions for heads at the fractional offsets `offsets`
    /// (positions), `count[j·P + s]` readings of head j at step s.
    pub(crate) fn new(positions: usize, offsets: &[f64], count: &[usize]) -> Self {
        let (p, m) = (positions, offsets.len());
        let head_total: Vec<f64> = (0..m)
            .map(|j| count[j * p..(j + 1) * p].iter().sum::<usize>() as f64)
            .collect();
        let weight: Vec<f64> = head_total.iter().map(|t| t / p as f64).collect();
        let total: f64 = weight.iter().sum();
        let zero = Complex::new(0.0, 0.0);
        let (mut ca, mut cp) = (vec![zero; p * m], vec![zero; p * m]);
        let (mut raa, mut rpp, mut rap) = (vec![0.0; p], vec![0.0; p], vec![zero; p]);
        let mut lost = Vec::new();
        let mut z = vec![zero; m];
        for k in 1..p {
            for (zj, &delta) in z.iter_mut().zip(offsets) {
                *zj = phase(p, k, delta);
            }
            let mut t = zero;
            let mut v = 0.0;
            let mut det = 0.0;
            for j in 0..m {
                t += z[j] * weight[j];
                v += weight[j] * z[j].norm_sqr();
                for l in j + 1..m {
                    det += weight[j] * weight[l] * (z[j] - z[l]).norm_sqr();
                }
            }
            let (ca, cp) = (&mut ca[k * m..(k + 1) * m], &mut cp[k * m..(k + 1) * m]);
            if det <= LOST_BELOW * total * v {
                lost.push(k);
                for (c, w) in ca.iter_mut().zip(&weight) {
                    *c = Complex::new(w / total, 0.0);
                }
                raa[k] = 1.0 / total;
                continue;
            }
            // A = (b_A·V − t·b_Φ)/det, Φ = (b_Φ·W − t̄·b_A)/det with b_A = Σ w_j Ȳ_j and
            // b_Φ = Σ w_j z̄_j Ȳ_j
            for j in 0..m {
                ca[j] = (Complex::new(v, 0.0) - t * z[j].conj()) * (weight[j] / det);
                cp[j] = (z[j].conj() * total - t.conj()) * (weight[j] / det);
            }
            raa[k] = v / det;
            rpp[k] = total / det;
            rap[k] = -t / det;
        }
        let mut planner = FftPlanner::<f64>::new();
        OffGridMap {
            positions: p,
            heads: m,
            count: count.iter().map(|&c| c.max(1) as f64).collect(),
            weight,
            head_total,
            ca,
            cp,
            raa,
            rpp,
            rap,
            lost,
            forward: planner.plan_fft_forward(p),
            inverse: planner.plan_fft_inverse(p),
        }
    }

    /// The heads' mean readings and the spectra of A and Φ of the sums per cell `sum`.
    fn spectra(&self, sum: &[f64]) -> Spectra {
        let (p, m) = (self.positions, self.heads);
        let head_mean: Vec<f64> = (0..m)
            .map(|j| sum[j * p..(j + 1) * p].iter().sum::<f64>() / self.head_total[j].max(1.0))
            .collect();
        let zero = Complex::new(0.0, 0.0);
        let (mut alpha, mut phi) = (vec![zero; p], vec![zero; p]);
        let mut y = vec![zero; p];
        for j in 0..m {
            for (s, y) in y.iter_mut().enumerate() {
                *y = Complex::new(sum[j * p + s] / self.count[j * p + s] - head_mean[j], 0.0);
            }
            self.forward.process(&mut y);
            for k in 1..p {
                alpha[k] += self.ca[k * m + j] * y[k];
                phi[k] += self.cp[k * m + j] * y[k];
            }
        }
        Spectra {
            head_mean,
            alpha,
            phi,
        }
    }

    /// The real sequence of a spectrum (the inverse DFT over P).
    fn to_real(&self, spectrum: &[Complex<f64>]) -> Vec<f64> {
        let mut buffer = spectrum.to_vec();
        self.inverse.process(&mut buffer);
        buffer
            .iter()
            .map(|c| c.re / self.positions as f64)
            .collect()
    }
}

/// The closure model's outputs of a trial: β, φ\[1..P−1\] and α in the reported gauge
/// (φ_f = φ′_f − φ′_P, as [`closure_off_grid`] reports them), then the heads' constants
/// U_j = Ū_j + φ′_P.
impl CellMap for OffGridMap {
    fn solve(&self, cell_sums: &[f64], out: &mut [f64]) {
        let p = self.positions;
        let spectra = self.spectra(cell_sums);
        let phi_prime = self.to_real(&spectra.phi);
        let alpha = self.to_real(&spectra.alpha);
        let last = phi_prime[p - 1];
        let (beta, rest) = out.split_at_mut(p);
        let (phi, rest) = rest.split_at_mut(p - 1);
        let (alpha_out, setups) = rest.split_at_mut(p);
        let mut previous = 0.0;
        for (f, b) in beta.iter_mut().enumerate() {
            let phi_f = phi_prime[f] - last;
            *b = phi_f - previous;
            previous = phi_f;
        }
        for (o, v) in phi.iter_mut().zip(&phi_prime) {
            *o = v - last;
        }
        alpha_out.copy_from_slice(&alpha);
        for (o, u) in setups.iter_mut().zip(&spectra.head_mean) {
            *o = u + last;
        }
    }
}
