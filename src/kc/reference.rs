//! The reference value of one quantity from several laboratories: the weighted mean (Cox
//! 2002, procedure A) and the DerSimonian–Laird random-effects mean; the χ² test of their
//! consistency; and the reference of the whole closed vector of pitch deviations by
//! generalised least squares.

use nalgebra::{DMatrix, DVector};
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// The 95 % quantile of χ² with `dof` degrees of freedom, χ²_{0.95}(ν) (`+∞` for ν = 0).
///
/// ```
/// let q = polycal::kc::chi2_quantile_95(1);
/// assert!((q - 3.841_458_820_694_124).abs() < 1e-9);
/// ```
pub fn chi2_quantile_95(dof: usize) -> f64 {
    if dof == 0 {
        return f64::INFINITY;
    }
    // ν ≥ 1 is a valid parameter: the constructor cannot fail.
    ChiSquared::new(dof as f64).map_or(f64::NAN, |law| law.inverse_cdf(0.95))
}

/// One quantity's estimate from the laboratories in the reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Estimate {
    /// The reference value x_ref.
    pub reference: f64,
    /// Its standard uncertainty u_ref (without a pilot's stability term).
    pub reference_u: f64,
    /// χ² = Σ (x_i − x̄_w)²/u_i² about the weighted mean (Cochran's Q).
    pub chi2: f64,
    /// n − 1.
    pub dof: usize,
    /// The dark uncertainty τ (0 for the weighted mean).
    pub tau: f64,
}

/// The weighted mean x̄_w = Σ x_i/u_i² / Σ 1/u_i², u(x̄_w) = (Σ 1/u_i²)^(−1/2) and
/// χ² = Σ (x_i − x̄_w)²/u_i².
pub(crate) fn weighted_mean(x: &[f64], u: &[f64]) -> (f64, f64, f64) {
    let s1: f64 = u.iter().map(|u| 1.0 / (u * u)).sum();
    let sx: f64 = x.iter().zip(u).map(|(x, u)| x / (u * u)).sum();
    let mean = sx / s1;
    let chi2 = x.iter().zip(u).map(|(x, u)| ((x - mean) / u).powi(2)).sum();
    (mean, s1.powf(-0.5), chi2)
}

/// The estimate of one quantity: the weighted mean, or with `random_effects` the
/// DerSimonian–Laird mean: τ² = max(0, (Q − (n − 1)) / (S1 − S2/S1)), S1 = Σ w_i,
/// S2 = Σ w_i², w_i = 1/u_i²; x_ref = Σ x_i/(u_i² + τ²) / Σ 1/(u_i² + τ²),
/// u_ref² = 1 / Σ 1/(u_i² + τ²).
pub(crate) fn estimate(x: &[f64], u: &[f64], random_effects: bool) -> Estimate {
    let (mean, mean_u, chi2) = weighted_mean(x, u);
    let dof = x.len().saturating_sub(1);
    if !random_effects {
        return Estimate {
            reference: mean,
            reference_u: mean_u,
            chi2,
            dof,
            tau: 0.0,
        };
    }
    let s1: f64 = u.iter().map(|u| u.powi(-2)).sum();
    let s2: f64 = u.iter().map(|u| u.powi(-4)).sum();
    let tau2 = ((chi2 - dof as f64) / (s1 - s2 / s1)).max(0.0);
    let widened: Vec<f64> = u.iter().map(|u| (u * u + tau2).sqrt()).collect();
    let (reference, reference_u, _) = weighted_mean(x, &widened);
    Estimate {
        reference,
        reference_u,
        chi2,
        dof,
        tau: tau2.sqrt(),
    }
}

/// The projector onto closed vectors, P = I − J/N.
pub(crate) fn closing_projector(faces: usize) -> DMatrix<f64> {
    let n = faces as f64;
    DMatrix::from_fn(
        faces,
        faces,
        |i, j| {
            if i == j { 1.0 - 1.0 / n } else { -1.0 / n }
        },
    )
}

/// The pseudo-inverse of a symmetric matrix whose null space is exactly the constant
/// vectors: A⁺ = (A + J/N)⁻¹ − J/N (the constant direction given eigenvalue 1, inverted,
/// and taken out again). `None` when A + J/N is not positive definite.
pub(crate) fn closed_pseudo_inverse(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    let faces = a.nrows();
    let j_over_n = DMatrix::from_element(faces, faces, 1.0 / faces as f64);
    let inverse = (a + &j_over_n).cholesky()?.inverse();
    Some(inverse - j_over_n)
}

/// The covariance a laboratory's closed result is taken to have when it gives none:
/// V = N/(N − 1)·P·diag(u²)·P, P = I − J/N.
pub fn closed_covariance(u: &[f64]) -> DMatrix<f64> {
    let faces = u.len();
    let p = closing_projector(faces);
    let d = DMatrix::from_diagonal(&DVector::from_iterator(faces, u.iter().map(|u| u * u)));
    (&p * d * &p) * (faces as f64 / (faces as f64 - 1.0))
}

/// The χ² of a vector of differences d whose covariance is P·diag(v)·P, P = I − J/N (each
/// of two results closed, [`closed_covariance`], and their sum): dᵀ(P·D·P)⁺d, its constant
/// part left out (P·D·P has the constants as its null space). By Sherman–Morrison,
/// (P·D·P)⁺ = D⁻¹ − D⁻¹·1·1ᵀ·D⁻¹ / (1ᵀ·D⁻¹·1), so the χ² is the weighted sum of squares about
/// the weighted mean, Σ w_i·(d_i − d̄_w)², w_i = 1/v_i, d̄_w = Σ w_i·d_i / Σ w_i: O(N),
/// no matrix formed. Returns (χ², d̄_w). Every `v_i` must be positive with a finite 1/v_i
/// (the caller checks and scales).
pub(crate) fn closed_difference_chi2(d: &[f64], variance: &[f64]) -> (f64, f64) {
    let weight_sum: f64 = variance.iter().map(|v| 1.0 / v).sum();
    let mean = d.iter().zip(variance).map(|(d, v)| d / v).sum::<f64>() / weight_sum;
    let chi2 = d
        .iter()
        .zip(variance)
        .map(|(d, v)| (d - mean).powi(2) / v)
        .sum();
    (chi2, mean)
}

/// The test of the whole closed vector.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct VectorFit {
    /// The GLS reference vector.
    pub reference: Vec<f64>,
    /// χ² = Σ_i (x_i − x_ref)ᵀ V_i⁺ (x_i − x_ref).
    pub chi2: f64,
    /// (N − 1)(n − 1).
    pub dof: usize,
}

/// The GLS reference of closed vectors x_i (each projected onto Σ = 0 first) with their
/// covariances `v` (a laboratory's own, or [`closed_covariance`] of its u):
/// x_ref = (Σ V_i⁺)⁺ Σ V_i⁺ x_i, and its χ². `None` for fewer than 2 faces or a
/// covariance that cannot be inverted on the closed subspace.
pub(crate) fn closed_vector(x: &[&[f64]], v: &[DMatrix<f64>]) -> Option<VectorFit> {
    let faces = x.first()?.len();
    if faces < 2 {
        return None;
    }
    let p = closing_projector(faces);
    let mut sum_inverse = DMatrix::zeros(faces, faces);
    let mut sum_weighted = DVector::zeros(faces);
    let mut closed = Vec::new();
    let mut weights = Vec::new();
    for (x, v) in x.iter().zip(v) {
        let v_plus = closed_pseudo_inverse(v)?;
        let xi = &p * DVector::from_column_slice(x);
        sum_weighted += &v_plus * &xi;
        sum_inverse += &v_plus;
        closed.push(xi);
        weights.push(v_plus);
    }
    let reference = closed_pseudo_inverse(&sum_inverse)? * sum_weighted;
    let mut chi2 = 0.0;
    for (xi, v_plus) in closed.iter().zip(&weights) {
        let d: DVector<f64> = xi - &reference;
        let vd: DVector<f64> = v_plus * &d;
        chi2 += d.iter().zip(vd.iter()).map(|(a, b)| a * b).sum::<f64>();
    }
    Some(VectorFit {
        reference: reference.iter().copied().collect(),
        chi2,
        dof: (faces - 1) * (x.len() - 1),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// χ²_{0.95}(ν) against the tables (Abramowitz & Stegun, table 26.8; NIST/SEMATECH
    /// e-Handbook 1.3.6.7.4).
    #[test]
    fn kc_chi2_quantiles_match_the_tables() {
        for (dof, table) in [
            (1, 3.841),
            (2, 5.991),
            (5, 11.070),
            (7, 14.067),
            (11, 19.675),
            (30, 43.773),
            (55, 73.311),
            (100, 124.342),
        ] {
            let q = chi2_quantile_95(dof);
            assert!((q - table).abs() < 1.5e-3, "ν = {dof}: {q} vs {table}");
        }
        assert_eq!(chi2_quantile_95(0), f64::INFINITY);
    }

    #[test]
    fn kc_pseudo_inverse_is_the_moore_penrose_one() {
        let u = [0.1, 0.2, 0.15, 0.3, 0.12];
        let v = closed_covariance(&u);
        let v_plus = closed_pseudo_inverse(&v).expect("invertible on the closed subspace");
        let p = closing_projector(5);
        assert!((&v * &v_plus - &p).amax() < 1e-10);
        assert!((&v * &v_plus * &v - &v).amax() < 1e-12);
        // Equal u: the diagonal is u².
        let v = closed_covariance(&[0.2; 6]);
        assert!((0..6).all(|i| (v[(i, i)] - 0.04).abs() < 1e-15));
    }

    /// The O(N) χ² of a closed difference is the dense one through the pseudo-inverse of
    /// the sum of two closed covariances.
    #[test]
    fn kc_closed_difference_chi2_is_the_dense_one() {
        let u_a = [0.1, 0.2, 0.15, 0.3, 0.12, 0.05];
        let u_b = [0.3, 0.1, 0.1, 0.2, 0.02, 0.5];
        let v = closed_covariance(&u_a) + closed_covariance(&u_b);
        let v_plus = closed_pseudo_inverse(&v).expect("invertible on the closed subspace");
        // Not closed: the constant part is left out by both.
        let d = DVector::from_column_slice(&[0.3, -0.2, 0.05, 0.4, -0.1, 0.7]);
        let dense = (d.transpose() * &v_plus * &d)[(0, 0)];
        let c = 6.0 / 5.0;
        let variance: Vec<f64> = u_a
            .iter()
            .zip(&u_b)
            .map(|(a, b)| c * (a * a + b * b))
            .collect();
        let (chi2, _) = closed_difference_chi2(d.as_slice(), &variance);
        assert!((chi2 - dense).abs() < 1e-10 * dense, "{chi2} vs {dense}");
    }

    #[test]
    fn kc_dersimonian_laird_is_the_weighted_mean_without_excess() {
        let x = [1.0, 1.01, 0.99];
        let u = [0.1, 0.1, 0.1];
        let e = estimate(&x, &u, true);
        assert_eq!(e.tau, 0.0);
        assert!((e.reference - 1.0).abs() < 1e-15);
        let e = estimate(&[0.0, 1.0, 2.0], &u, true);
        // Q = 200, S1 = 300, S2 = 30000: τ² = 198/200.
        assert!((e.tau * e.tau - 0.99).abs() < 1e-12);
    }
}
