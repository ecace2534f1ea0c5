//! Why the dense engine's reduced normal matrix is singular: its null space mapped to β,
//! α and the effect terms, and the Fourier harmonics it holds named as
//! [`super::super::observability`] names those a design's offsets lose.

use super::Reduced;
use crate::measurement::MeasurementSet;
use crate::solve::observability::{Unobservable, describe};
use nalgebra::SymmetricEigen;

/// Explains a singular reduced normal matrix: finds its null space, maps it to β, α
/// and the effect terms, and names the Fourier harmonics it contains.
pub(super) fn explain_singular(reduced: &Reduced, set: &MeasurementSet) -> Unobservable {
    let n = reduced.faces;
    let k = reduced.streams;
    let eigen = SymmetricEigen::new(reduced.schur.clone());
    let largest = eigen
        .eigenvalues
        .iter()
        .fold(0.0_f64, |a, &b| a.max(b.abs()));
    let threshold = 1e-9 * largest.max(1.0);
    let mut energy = vec![0.0; n];
    let mut effect_energy = vec![0.0; reduced.effects];
    let mut total = 0.0;
    let mut theta = vec![0.0; 2 * n + k + reduced.effects];
    for (i, &lambda) in eigen.eigenvalues.iter().enumerate() {
        if lambda.abs() > threshold {
            continue;
        }
        let rest: Vec<f64> = eigen.eigenvectors.column(i).iter().copied().collect();
        let mut g = reduced.alpha_from_rest(&rest, false);
        g.extend_from_slice(&rest);
        reduced.to_theta(&g, &mut theta);
        let (beta, tail) = theta.split_at(n);
        let alpha = &tail[..n];
        for (bin, e) in energy.iter_mut().enumerate().skip(1) {
            *e += dft_power(beta, bin) + dft_power(alpha, bin);
        }
        for (j, e) in effect_energy.iter_mut().enumerate() {
            *e += theta[2 * n + k + j].powi(2);
        }
        total += beta.iter().chain(alpha).map(|v| v * v).sum::<f64>()
            + theta[2 * n + k..].iter().map(|v| v * v).sum::<f64>();
    }
    let total = total.max(f64::MIN_POSITIVE);
    let harmonics: Vec<usize> = (1..n)
        .filter(|&bin| energy[bin] * n as f64 > 1e-6 * total)
        .collect();
    let effects: Vec<usize> = (0..reduced.effects)
        .filter(|&j| effect_energy[j] > 1e-6 * total)
        .collect();
    describe(harmonics, effects, set)
}

/// The power of harmonic `bin` of `x` (its DFT's squared modulus over its length).
fn dft_power(x: &[f64], bin: usize) -> f64 {
    let n = x.len();
    let (mut re, mut im) = (0.0, 0.0);
    for (f, v) in x.iter().enumerate() {
        let angle = -2.0 * std::f64::consts::PI * ((bin * f) % n) as f64 / n as f64;
        re += v * angle.cos();
        im += v * angle.sin();
    }
    (re * re + im * im) / n as f64
}
