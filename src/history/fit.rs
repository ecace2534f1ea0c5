//! The two models of a standard's history fitted to its calibrations' vectors by
//! generalized least squares: the constant x_i = a + e_i and the linear
//! x_i = a + b·τ_i + e_i, τ_i the calibration's date in years from a reference date, e_i
//! with the calibration's covariance V_i (closed: V_i = N/(N − 1)·P·diag(u_i²)·P; not
//! closed: diag(u_i²)).
//!
//! With M_i = V_i⁺ the normal equations of the linear model are
//!
//! ```text
//! [Σ M_i      Σ τ_i M_i ] [a]   [Σ M_i x_i    ]
//! [Σ τ_i M_i  Σ τ_i² M_i] [b] = [Σ τ_i M_i x_i]
//! ```
//!
//! whose matrix H has, for closed vectors, the constants of each block as its null space
//! (a and b are closed): (a, b) = H⁺·g and Cov(a, b) = H⁺ (the pseudo-inverse of
//! `kc::closed`). With one u per calibration on every face (M_i = P/(c·u_i²)) this is the
//! per-face weighted least squares of value on date with weights 1/u_i², so the per-face
//! slopes and their u are those of the textbook straight line. The residual
//! χ² = Σ_i r_iᵀ M_i r_i. Everything is computed in units of the largest u (χ² does not
//! change with the scale).

use nalgebra::{DMatrix, DVector};

use crate::kc::closed::{ClosedCovariance, closed_pseudo_inverse_blocks};

/// The calibrations' vectors lined up, in the fit's scaled units.
pub(crate) struct Series<'a> {
    /// Values per calibration and position.
    pub x: &'a [Vec<f64>],
    /// Standard uncertainties per calibration and position.
    pub u: &'a [Vec<f64>],
    /// Date of each calibration, years from the reference date.
    pub years: &'a [f64],
    /// Whether every vector is closed (Σ = 0; pitch deviations, encoder errors).
    pub closed: bool,
}

/// A model fitted: its estimates, their covariance and the residual χ².
#[derive(Debug, Clone)]
pub(crate) struct Fitted {
    /// a (the value at the reference date), per position.
    pub value: Vec<f64>,
    /// b (the drift per year), per position; empty for the constant model.
    pub drift: Vec<f64>,
    /// Cov(a, b) (2N × 2N) or Cov(a) (N × N).
    pub covariance: DMatrix<f64>,
    /// Σ_i r_iᵀ M_i r_i.
    pub chi2: f64,
    /// Its degrees of freedom: (N − 1)(n − p) closed, N(n − p) not, p the parameters per
    /// position (1 or 2).
    pub dof: usize,
}

impl Fitted {
    /// Var(a_k), Cov(a_k, b_k), Var(b_k) (the last two 0 for the constant model).
    pub(crate) fn variance_terms(&self, k: usize) -> (f64, f64, f64) {
        let n = self.value.len();
        if self.drift.is_empty() {
            (self.covariance[(k, k)], 0.0, 0.0)
        } else {
            (
                self.covariance[(k, k)],
                self.covariance[(k, n + k)],
                self.covariance[(n + k, n + k)],
            )
        }
    }

    /// The drift vector's χ² bᵀ Cov(b)⁺ b (the test of b = 0), `None` for the constant
    /// model or a covariance that cannot be inverted.
    pub(crate) fn drift_chi2(&self, closed: bool) -> Option<f64> {
        if self.drift.is_empty() {
            return None;
        }
        let n = self.value.len();
        let cov_b = self.covariance.view((n, n), (n, n)).into_owned();
        let inverse = if closed {
            closed_pseudo_inverse_blocks(&cov_b, 1)?
        } else {
            cov_b.cholesky()?.inverse()
        };
        let b = DVector::from_column_slice(&self.drift);
        let chi2 = b.dot(&(inverse * &b));
        chi2.is_finite().then_some(chi2.max(0.0))
    }
}

/// M_i = V_i⁺ of calibration i.
fn weight(u: &[f64], closed: bool) -> DMatrix<f64> {
    if closed {
        ClosedCovariance::Stated(u.to_vec()).dense_plus()
    } else {
        DMatrix::from_diagonal(&DVector::from_iterator(
            u.len(),
            u.iter().map(|u| 1.0 / (u * u)),
        ))
    }
}

/// The model with `parameters` per position (1 constant, 2 linear) fitted; `None` when
/// its normal matrix cannot be inverted (all dates equal for the linear model).
pub(crate) fn fit(series: &Series, parameters: usize) -> Option<Fitted> {
    let n = series.x.first()?.len();
    let size = n * parameters;
    let mut h = DMatrix::zeros(size, size);
    let mut g = DVector::zeros(size);
    let weights: Vec<DMatrix<f64>> = series.u.iter().map(|u| weight(u, series.closed)).collect();
    for ((x, m), &t) in series.x.iter().zip(&weights).zip(series.years) {
        let mx = m * DVector::from_column_slice(x);
        let powers = [1.0, t, t * t];
        for p in 0..parameters {
            g.rows_mut(p * n, n).axpy(powers[p], &mx, 1.0);
            for q in 0..parameters {
                let mut block = h.view_mut((p * n, q * n), (n, n));
                block += m * powers[p + q];
            }
        }
    }
    let covariance = if series.closed {
        closed_pseudo_inverse_blocks(&h, parameters)?
    } else {
        h.cholesky()?.inverse()
    };
    let theta = &covariance * g;
    let value: Vec<f64> = theta.rows(0, n).iter().copied().collect();
    let drift: Vec<f64> = if parameters > 1 {
        theta.rows(n, n).iter().copied().collect()
    } else {
        Vec::new()
    };
    let mut chi2 = 0.0;
    for ((x, m), &t) in series.x.iter().zip(&weights).zip(series.years) {
        let r = DVector::from_iterator(
            n,
            (0..n).map(|k| x[k] - value[k] - drift.get(k).map_or(0.0, |b| b * t)),
        );
        chi2 += r.dot(&(m * &r));
    }
    let per_calibration = if series.closed { n - 1 } else { n };
    let dof = per_calibration * series.x.len().saturating_sub(parameters);
    let finite = chi2.is_finite()
        && theta.iter().all(|v| v.is_finite())
        && covariance.iter().all(|v| v.is_finite());
    finite.then_some(Fitted {
        value,
        drift,
        covariance,
        chi2: chi2.max(0.0),
        dof,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One u per calibration on every face: the closed GLS is the per-face weighted
    /// straight line (slope Σw(t − t̄)x / Σw(t − t̄)², its variance u²-free form below).
    #[test]
    fn history_closed_fit_is_the_per_face_weighted_line() {
        let years = [0.0, 1.0, 2.5, 4.0];
        let s = [0.1, 0.2, 0.15, 0.1];
        let faces = 5;
        let x: Vec<Vec<f64>> = (0..4)
            .map(|i| {
                crate::kc::closed::closed(
                    &(0..faces)
                        .map(|k| ((i * 7 + k * 3) as f64).sin() * 0.3 + 0.05 * k as f64 * years[i])
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        let u: Vec<Vec<f64>> = s.iter().map(|s| vec![*s; faces]).collect();
        let series = Series {
            x: &x,
            u: &u,
            years: &years,
            closed: true,
        };
        let linear = fit(&series, 2).expect("fits");
        let w: Vec<f64> = s.iter().map(|s| 1.0 / (s * s)).collect();
        let sw: f64 = w.iter().sum();
        let t_bar = w.iter().zip(&years).map(|(w, t)| w * t).sum::<f64>() / sw;
        let stt: f64 = w
            .iter()
            .zip(&years)
            .map(|(w, t)| w * (t - t_bar).powi(2))
            .sum();
        for (k, drift) in linear.drift.iter().enumerate() {
            let slope = (0..4)
                .map(|i| w[i] * (years[i] - t_bar) * x[i][k])
                .sum::<f64>()
                / stt;
            assert!((drift - slope).abs() < 1e-12, "{k}");
            let (_, _, var_b) = linear.variance_terms(k);
            // closed: the diagonal of c·P·D·P with equal u is u², so Var(b_k) = 1/S_tt
            assert!((var_b - 1.0 / stt).abs() < 1e-10, "{var_b} {}", 1.0 / stt);
        }
        assert!(linear.drift.iter().sum::<f64>().abs() < 1e-12);
        assert_eq!(linear.dof, 4 * 2);
    }
}
