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

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::Head;
use super::SelfcalSet;
use super::solve::{Closure, SelfcalOptions, SelfcalSolveError, no_correction};
use crate::solve::cofactor::{Base, Cofactor, Structured};
use crate::solve::{Engine, ParameterLayout, memory};

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
    // the per-head spectra and views (M·P complex each), the readings' residuals and
    // stream indices, and a few P-long vectors
    let needed_bytes = 16 * 3 * (m as u128) * (p as u128)
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
    let weight: Vec<f64> = (0..m)
        .map(|j| count[j * p..(j + 1) * p].iter().sum::<usize>() as f64 / p as f64)
        .collect();
    let head_mean: Vec<f64> = (0..m)
        .map(|j| sum[j * p..(j + 1) * p].iter().sum::<f64>() / (weight[j] * p as f64).max(1.0))
        .collect();

    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(p);
    let inverse = planner.plan_fft_inverse(p);
    let spectra: Vec<Vec<Complex<f64>>> = (0..m)
        .map(|j| {
            let mut y: Vec<Complex<f64>> = (0..p)
                .map(|s| {
                    let c = count[j * p + s].max(1) as f64;
                    Complex::new(sum[j * p + s] / c - head_mean[j], 0.0)
                })
                .collect();
            forward.process(&mut y);
            y
        })
        .collect();

    let phase = |k: usize, delta: f64| -> Complex<f64> {
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
    };
    let total: f64 = weight.iter().sum();
    let mut a = vec![Complex::new(0.0, 0.0); p];
    let mut phi = vec![Complex::new(0.0, 0.0); p];
    let mut raa = vec![0.0; p];
    let mut rpp = vec![0.0; p];
    let mut rap = vec![Complex::new(0.0, 0.0); p];
    let mut lost = Vec::new();
    let mut z = vec![Complex::new(0.0, 0.0); m];
    for k in 1..p {
        for (j, zj) in z.iter_mut().enumerate() {
            *zj = phase(k, offsets[j]);
        }
        let mut t = Complex::new(0.0, 0.0);
        let mut v = 0.0;
        let mut b_alpha = Complex::new(0.0, 0.0);
        let mut b_phi = Complex::new(0.0, 0.0);
        let mut det = 0.0;
        for j in 0..m {
            t += z[j] * weight[j];
            v += weight[j] * z[j].norm_sqr();
            b_alpha += spectra[j][k] * weight[j];
            b_phi += z[j].conj() * spectra[j][k] * weight[j];
            for l in j + 1..m {
                det += weight[j] * weight[l] * (z[j] - z[l]).norm_sqr();
            }
        }
        if det <= LOST_BELOW * total * v {
            lost.push(k);
            a[k] = b_alpha / total;
            raa[k] = 1.0 / total;
            continue;
        }
        a[k] = (b_alpha * v - t * b_phi) / det;
        phi[k] = (b_phi * total - t.conj() * b_alpha) / det;
        raa[k] = v / det;
        rpp[k] = total / det;
        rap[k] = -t / det;
    }

    let to_real = |spectrum: &[Complex<f64>]| -> Vec<f64> {
        let mut buffer = spectrum.to_vec();
        inverse.process(&mut buffer);
        buffer.iter().map(|c| c.re / p as f64).collect()
    };
    let alpha = to_real(&a);
    let phi_prime = to_real(&phi);
    // each head's view of the disc: φ′ at its fractional positions
    let views: Vec<Vec<f64>> = (0..m)
        .map(|j| {
            let shifted: Vec<Complex<f64>> =
                (0..p).map(|k| phi[k] * phase(k, offsets[j])).collect();
            to_real(&shifted)
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
    let base = Base::from_spectrum(
        raa,
        rpp,
        rap,
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
