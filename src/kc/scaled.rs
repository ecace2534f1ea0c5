//! Every result of a key comparison as a closed vector in the comparison's scaled units,
//! with its covariance (the laboratory's own, or taken from its u; the pilot's u_stab and
//! τ in it where they apply), its fits and its degree of equivalence against the closed
//! reference (the formulas are in the module's documentation, [`super`]).

use nalgebra::DMatrix;

use super::closed::{self, ClosedCovariance, ClosedFit, closed, closed_pseudo_inverse};
use super::input::Aligned;
use super::reference::closed_covariance;
use super::{DegreeOfEquivalence, KcError, LabResult};

/// Every result as a closed vector, in units of the largest u (so that χ² is as accurate
/// for any scale), with the laboratories' own covariances.
pub(crate) struct Scaled<'a> {
    pub(crate) labs: &'a [LabResult],
    pub(crate) covariances: &'a [Option<DMatrix<f64>>],
    /// The unit of `values` and `u`: the largest standard uncertainty given, in the
    /// quantity's unit (arcsec).
    pub(crate) scale: f64,
    /// Per result, its closed values, in units of `scale`.
    pub(crate) values: Vec<Vec<f64>>,
    /// Per result, its standard uncertainties, in units of `scale`.
    pub(crate) u: Vec<Vec<f64>>,
    /// The quantities compared (faces or encoder positions).
    pub(crate) positions: usize,
    /// The pilot's stability u_stab per quantity, in units of `scale` (0 unless the
    /// repeats' test failed): in every result's covariance.
    pub(crate) stability: Vec<f64>,
    /// Whether the positions make a closed vector; else scalars each on its own (angle
    /// blocks).
    pub(crate) closed: bool,
    /// Whether each result reports each position (`None`: all of them).
    pub(crate) measured: Option<Vec<Vec<bool>>>,
}

impl<'a> Scaled<'a> {
    /// Every result as a closed vector: pitch deviations closed already (their mean, 0 to
    /// rounding, taken out); encoder errors, defined up to a constant, less their mean.
    /// Everything in units of the largest u.
    pub(crate) fn of(
        labs: &'a [LabResult],
        aligned: &Aligned,
        covariances: &'a [Option<DMatrix<f64>>],
    ) -> Scaled<'a> {
        // the largest u given (not the placeholders where a result does not report a
        // position)
        let given = |r: usize, k: usize| {
            aligned
                .measured
                .as_ref()
                .is_none_or(|m| m.get(r).and_then(|m| m.get(k)).copied().unwrap_or(false))
        };
        let scale = aligned
            .u
            .iter()
            .enumerate()
            .flat_map(|(r, u)| {
                u.iter()
                    .enumerate()
                    .filter(move |(k, _)| given(r, *k))
                    .map(|(_, u)| *u)
            })
            .chain(
                covariances
                    .iter()
                    .flatten()
                    .map(|v| v.diagonal().amax().sqrt()),
            )
            .fold(0.0, f64::max);
        let values: Vec<Vec<f64>> = aligned
            .values
            .iter()
            .enumerate()
            .map(|(r, x)| {
                let x = match (aligned.closed, &aligned.measured) {
                    (false, _) => x.clone(),
                    (true, None) => closed(x),
                    // closed over the positions the result reports
                    (true, Some(_)) => {
                        let reported: Vec<usize> = (0..x.len()).filter(|&k| given(r, k)).collect();
                        let mean = reported.iter().map(|&k| x[k]).sum::<f64>()
                            / reported.len().max(1) as f64;
                        (0..x.len())
                            .map(|k| if given(r, k) { x[k] - mean } else { 0.0 })
                            .collect()
                    }
                };
                x.iter().map(|x| x / scale).collect()
            })
            .collect();
        let u: Vec<Vec<f64>> = aligned
            .u
            .iter()
            .map(|u| u.iter().map(|u| u / scale).collect())
            .collect();
        Scaled {
            labs,
            covariances,
            scale,
            values,
            u,
            positions: aligned.index.len(),
            stability: vec![0.0; aligned.index.len()],
            closed: aligned.closed,
            measured: aligned.measured.clone(),
        }
    }

    /// Whether result `r` reports position `k`.
    pub(crate) fn is_measured(&self, r: usize, k: usize) -> bool {
        self.measured
            .as_ref()
            .is_none_or(|m| m.get(r).and_then(|m| m.get(k)).copied().unwrap_or(false))
    }

    /// Result `r`'s values, NaN where it does not report a position (what the pairs are
    /// formed from).
    pub(crate) fn reported_values(&self, r: usize) -> Vec<f64> {
        self.values[r]
            .iter()
            .enumerate()
            .map(|(k, x)| if self.is_measured(r, k) { *x } else { f64::NAN })
            .collect()
    }

    /// Every result's standard uncertainties with the pilot's stability u_stab in them,
    /// √(u² + u_stab²), in units of the scale: what the per-quantity estimates use.
    pub(crate) fn judged_u(&self) -> Vec<Vec<f64>> {
        self.u
            .iter()
            .map(|u| {
                u.iter()
                    .zip(&self.stability)
                    .map(|(u, s)| u.hypot(*s))
                    .collect()
            })
            .collect()
    }

    /// The closed covariance of result `r`: its own (scaled) or taken from its stated u,
    /// widened by the pilot's stability u_stab and by the dark uncertainty `tau` (in units
    /// of the scale) where given.
    pub(crate) fn covariance(
        &self,
        r: usize,
        tau: Option<&[f64]>,
    ) -> Result<ClosedCovariance, KcError> {
        let extra: Vec<f64> = match tau {
            None => self.stability.clone(),
            Some(tau) => self
                .stability
                .iter()
                .zip(tau)
                .map(|(s, t)| s.hypot(*t))
                .collect(),
        };
        let widened = extra.iter().any(|e| *e > 0.0);
        if !self.closed || self.measured.is_some() {
            // each position on its own (angle blocks), or closed over the positions the
            // result reports: +∞ (no weight) where it does not report one
            let u: Vec<f64> = self.u[r]
                .iter()
                .zip(&extra)
                .enumerate()
                .map(|(k, (u, e))| {
                    if self.is_measured(r, k) {
                        u.hypot(*e)
                    } else {
                        f64::INFINITY
                    }
                })
                .collect();
            return Ok(if self.closed {
                ClosedCovariance::Stated(u)
            } else {
                ClosedCovariance::Independent(u)
            });
        }
        match self.covariances.get(r).and_then(Option::as_ref) {
            None => Ok(ClosedCovariance::Stated(
                self.u[r]
                    .iter()
                    .zip(&extra)
                    .map(|(u, e)| u.hypot(*e))
                    .collect(),
            )),
            Some(v) => {
                let mut v = v / (self.scale * self.scale);
                if widened {
                    v += closed_covariance(&extra);
                }
                let v_plus = closed_pseudo_inverse(&v).ok_or_else(|| KcError::Covariance {
                    file: self.labs[r].source.clone(),
                    lab: self.labs[r].name.clone(),
                    reason: "it cannot be inverted on the closed subspace".to_string(),
                })?;
                Ok(ClosedCovariance::Own { v, v_plus })
            }
        }
    }

    /// The closed fit of the results `set`, with the covariances `v` (per result).
    pub(crate) fn fit(&self, set: &[usize], v: &[ClosedCovariance]) -> Option<ClosedFit> {
        let x: Vec<&[f64]> = set.iter().map(|&r| self.values[r].as_slice()).collect();
        let c: Vec<&ClosedCovariance> = set.iter().map(|&r| &v[r]).collect();
        closed::fit_keeping(&x, &c, self.closed && self.measured.is_some())
    }

    /// Result `r`'s (laboratory `lab`'s) degree of equivalence against the closed
    /// `reference`: d and U(d) (k = 2) per quantity, in arcsec. Its variance (the pilot's
    /// stability and τ in it) is less the reference's when it is inside the reference, more
    /// when outside.
    pub(crate) fn degree_of_equivalence(
        &self,
        r: usize,
        inside_reference: bool,
        lab: String,
        reference: &Reference,
    ) -> DegreeOfEquivalence {
        let fit = reference.fit;
        let scale = self.scale;
        let diagonal = reference.widened[r].diagonal();
        let sign = if inside_reference { -1.0 } else { 1.0 };
        // NaN where the result does not report the position (or nobody in the reference
        // does): no degree of equivalence there (null in the JSON)
        let mut d: Vec<f64> = self
            .reported_values(r)
            .iter()
            .zip(&fit.reference)
            .map(|(x, x_ref)| (x - x_ref) * scale)
            .collect();
        let mut diagonal = diagonal;
        let mut reference_variance = std::borrow::Cow::Borrowed(&fit.reference_variance);
        if let Some(own) = self.closed_over_own(r, &d, fit, &reference.widened[r]) {
            d = own.d;
            diagonal = own.variance;
            reference_variance = std::borrow::Cow::Owned(own.reference_variance);
        }
        let expanded_u = diagonal
            .iter()
            .zip(reference_variance.iter())
            .enumerate()
            .map(|(k, (v, v_ref))| {
                if self.is_measured(r, k) && v.is_finite() && v_ref.is_finite() {
                    2.0 * ((v + sign * v_ref).max(0.0) * scale * scale).sqrt()
                } else {
                    f64::NAN
                }
            })
            .collect();
        DegreeOfEquivalence {
            lab,
            d,
            expanded_u,
            in_reference: inside_reference,
            d_linked: None,
            expanded_u_linked: None,
            dof_effective: None,
            k: None,
        }
    }
}

impl Scaled<'_> {
    /// A closed result that does not report every position the reference has (or reports
    /// one the reference does not): its degree of equivalence closed over the positions S
    /// both have, d = P_S(x − x_ref,S); its own variance there, diag(P_S·V_S·P_S) =
    /// c·(u_k²(1 − 2/M) + Σ_S u²/M²) with its c = N/(N − 1) (V closed over its N
    /// positions, M = |S|); and the variance the reference takes out of it (adds to it),
    /// diag(P_S·C_SS·P_S) ([`closed::projected_variance`]). `None` for a result that reports
    /// exactly the reference's positions (d, V and C_kk as they are) and for angle blocks.
    fn closed_over_own(
        &self,
        r: usize,
        d: &[f64],
        fit: &ClosedFit,
        widened: &ClosedCovariance,
    ) -> Option<OwnPositions> {
        if !self.closed || self.measured.is_none() {
            return None;
        }
        let ClosedCovariance::Stated(u) = widened else {
            return None;
        };
        let both: Vec<bool> = d.iter().map(|d| d.is_finite()).collect();
        let fitted = fit.reference.iter().filter(|x| x.is_finite()).count();
        let reported = (0..d.len()).filter(|&k| self.is_measured(r, k)).count();
        let m = both.iter().filter(|b| **b).count();
        if m == fitted && m == reported {
            return None;
        }
        if m < 2 {
            // closed over one position d is 0 by construction: not given
            let none = vec![f64::NAN; d.len()];
            return Some(OwnPositions {
                d: none.clone(),
                variance: none.clone(),
                reference_variance: none,
            });
        }
        let mean = (0..d.len()).filter(|&k| both[k]).map(|k| d[k]).sum::<f64>() / m as f64;
        let n = reported as f64;
        let c = n / (n - 1.0);
        let mf = m as f64;
        let total: f64 = (0..d.len()).filter(|&k| both[k]).map(|k| u[k] * u[k]).sum();
        let variance = (0..d.len())
            .map(|k| {
                if both[k] {
                    c * (u[k] * u[k] * (1.0 - 2.0 / mf) + total / (mf * mf))
                } else {
                    f64::NAN
                }
            })
            .collect();
        Some(OwnPositions {
            d: d.iter().map(|d| d - mean).collect(),
            variance,
            reference_variance: closed::projected_variance(fit, &both)?,
        })
    }
}

/// A degree of equivalence over the positions a result and the reference both have
/// ([`Scaled::closed_over_own`]), arcsec and the scale's units².
struct OwnPositions {
    /// d closed over those positions (NaN elsewhere).
    d: Vec<f64>,
    /// The result's own variance of it there.
    variance: Vec<f64>,
    /// The reference's variance taken out (in it) or added (out of it) there.
    reference_variance: Vec<f64>,
}

/// The closed reference the degrees of equivalence are taken against: its fit and every
/// result's covariance (with the pilot's stability, and τ for DerSimonian–Laird).
pub(crate) struct Reference<'a> {
    /// The closed fit of the laboratories in the reference.
    pub fit: &'a ClosedFit,
    /// Every result's covariance as the reference used it.
    pub widened: &'a [ClosedCovariance],
}
