//! The reference value of one quantity from several laboratories: the weighted mean (Cox
//! 2002, procedure A) and the DerSimonian–Laird random-effects mean, and the χ² about the
//! weighted mean (Cochran's Q), reported per quantity as information; the covariance a
//! closed result is taken to have (the closed vector itself is `closed`).

use nalgebra::{DMatrix, DVector};

use super::ReferenceMethod;
use super::closed::closing_projector;
use statrs::distribution::{ChiSquared, ContinuousCDF};

/// A χ² for people: `decimals` decimals below 10⁶, three significant digits in exponent
/// form at and above (`1.23e12`), so that a comparison far off reads at a glance, not as
/// a thirteen-digit number (the table, the report and the DCC write χ² so; the JSON keeps
/// every digit); a value that is not finite as Rust prints it.
///
/// ```
/// use polycal::kc::chi2_text;
/// assert_eq!(chi2_text(85.677_069, 2), "85.68");
/// assert_eq!(chi2_text(85.677_069, 3), "85.677");
/// assert_eq!(chi2_text(999_999.994, 2), "999999.99");
/// assert_eq!(chi2_text(1.234_567e12, 2), "1.23e12");
/// assert_eq!(chi2_text(1.0e6, 3), "1.00e6");
/// assert_eq!(chi2_text(f64::INFINITY, 2), "inf");
/// ```
pub fn chi2_text(chi2: f64, decimals: usize) -> String {
    if chi2.is_finite() && chi2.abs() >= 1e6 {
        format!("{chi2:.2e}")
    } else {
        format!("{chi2:.decimals$}")
    }
}

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
/// χ² = Σ (x_i − x̄_w)²/u_i², the weights taken relative to the largest u so that no
/// square of a tiny u underflows.
pub(crate) fn weighted_mean(x: &[f64], u: &[f64]) -> (f64, f64, f64) {
    let scale = u.iter().copied().fold(0.0, f64::max);
    let w: Vec<f64> = u.iter().map(|u| (scale / u).powi(2)).collect();
    let s1: f64 = w.iter().sum();
    let sx: f64 = x.iter().zip(&w).map(|(x, w)| x * w).sum();
    let mean = sx / s1;
    let chi2 = x.iter().zip(u).map(|(x, u)| ((x - mean) / u).powi(2)).sum();
    (mean, scale / s1.sqrt(), chi2)
}

/// The estimate of one quantity by `method`: the weighted mean; the DerSimonian–Laird
/// mean, τ² = max(0, (Q − (n − 1)) / (S1 − S2/S1)), S1 = Σ w_i, S2 = Σ w_i², w_i = 1/u_i²;
/// or the Mandel–Paule mean, τ² ≥ 0 with Σ (x_i − x_ref)²/(u_i² + τ²) = n − 1 (τ = 0 when
/// Q ≤ n − 1). For both x_ref = Σ x_i/(u_i² + τ²) / Σ 1/(u_i² + τ²),
/// u_ref² = 1 / Σ 1/(u_i² + τ²).
pub(crate) fn estimate(x: &[f64], u: &[f64], method: ReferenceMethod) -> Estimate {
    let (mean, mean_u, chi2) = weighted_mean(x, u);
    let dof = x.len().saturating_sub(1);
    if !method.is_random_effects() {
        return Estimate {
            reference: mean,
            reference_u: mean_u,
            chi2,
            dof,
            tau: 0.0,
        };
    }
    let tau2 = if method == ReferenceMethod::MandelPaule {
        mandel_paule_tau2(x, u, chi2, dof)
    } else {
        let s1: f64 = u.iter().map(|u| u.powi(-2)).sum();
        let s2: f64 = u.iter().map(|u| u.powi(-4)).sum();
        ((chi2 - dof as f64) / (s1 - s2 / s1)).max(0.0)
    };
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

/// The Mandel–Paule τ²: the root of F(τ²) = Σ (x_i − x̄(τ²))²/(u_i² + τ²) − (n − 1), which
/// falls as τ² grows; 0 when F(0) = Q − (n − 1) ≤ 0. The root lies below the plain sample
/// variance s² (F(s²) ≤ Σ (x_i − x̄)²/s² − (n − 1) = 0), found there by bisection to the
/// last bits.
fn mandel_paule_tau2(x: &[f64], u: &[f64], chi2: f64, dof: usize) -> f64 {
    let n = x.len() as f64;
    if dof == 0 || chi2 <= dof as f64 {
        return 0.0;
    }
    let f = |tau2: f64| {
        let widened: Vec<f64> = u.iter().map(|u| (u * u + tau2).sqrt()).collect();
        weighted_mean(x, &widened).2 - dof as f64
    };
    let plain = x.iter().sum::<f64>() / n;
    let mut high = x.iter().map(|x| (x - plain).powi(2)).sum::<f64>() / (n - 1.0);
    let mut low = 0.0;
    // F(high) ≤ 0 by the bound above; rounding aside, make sure of it.
    while f(high) > 0.0 && high.is_finite() {
        high *= 2.0;
    }
    for _ in 0..200 {
        let middle = 0.5 * (low + high);
        if middle <= low || middle >= high {
            break;
        }
        if f(middle) > 0.0 {
            low = middle;
        } else {
            high = middle;
        }
    }
    0.5 * (low + high)
}

/// The covariance a laboratory's closed result is taken to have when it gives none:
/// V = N/(N − 1)·P·diag(u²)·P, P = I − J/N, as a dense N × N matrix (the comparison itself
/// never forms it: it is diagonal plus rank one, see the closed vector's module).
///
/// ```
/// let v = polycal::kc::closed_covariance(&[0.2; 6]);
/// assert!((v[(0, 0)] - 0.04).abs() < 1e-15); // equal u: the diagonal is u²
/// assert!(v.row(2).iter().sum::<f64>().abs() < 1e-15); // closed
/// ```
pub fn closed_covariance(u: &[f64]) -> DMatrix<f64> {
    let faces = u.len();
    let p = closing_projector(faces);
    let d = DMatrix::from_diagonal(&DVector::from_iterator(faces, u.iter().map(|u| u * u)));
    (&p * d * &p) * (faces as f64 / (faces as f64 - 1.0))
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
    fn kc_dersimonian_laird_is_the_weighted_mean_without_excess() {
        let x = [1.0, 1.01, 0.99];
        let u = [0.1, 0.1, 0.1];
        let e = estimate(&x, &u, ReferenceMethod::DersimonianLaird);
        assert_eq!(e.tau, 0.0);
        assert!((e.reference - 1.0).abs() < 1e-15);
        let e = estimate(&[0.0, 1.0, 2.0], &u, ReferenceMethod::DersimonianLaird);
        // Q = 200, S1 = 300, S2 = 30000: τ² = 198/200.
        assert!((e.tau * e.tau - 0.99).abs() < 1e-12);
    }

    #[test]
    fn kc_mandel_paule_by_hand() {
        // Equal u: the mean stays 1, Σ (x − 1)²/(0.01 + τ²) = 2/(0.01 + τ²) = n − 1 = 2.
        let e = estimate(&[0.0, 1.0, 2.0], &[0.1; 3], ReferenceMethod::MandelPaule);
        assert!((e.tau * e.tau - 0.99).abs() < 1e-12);
        assert!((e.reference - 1.0).abs() < 1e-12);
        // Two laboratories: Σ w_i (x_i − x̄)² = (x₁ − x₂)²/(v₁ + v₂) = 1 with v = u² + τ², so
        // τ² = ((x₁ − x₂)² − u₁² − u₂²)/2 = (4 − 0.05)/2 = 1.975.
        let e = estimate(&[0.0, 2.0], &[0.1, 0.2], ReferenceMethod::MandelPaule);
        assert!((e.tau * e.tau - 1.975).abs() < 1e-12);
        // Consistent: τ = 0 and the weighted mean.
        let e = estimate(&[1.0, 1.01, 0.99], &[0.1; 3], ReferenceMethod::MandelPaule);
        assert_eq!(e.tau, 0.0);
    }
}
