//! Linking when laboratories report different encoder positions (docs/FORMAT.md §12,
//! "Linking"). A laboratory's degrees of equivalence are closed over the positions it
//! reports, so its offsets d_jk(linked) − d_jk(this) are the offset Δ_k between the two
//! references less a constant of its own: over the positions S_j it reports in both,
//!
//! ```text
//! y_jk = Δ_k + γ_j + e_jk,   Σ_k Δ_k = 0   (both references are closed),
//! ```
//!
//! one γ_j per linking laboratory. Each closed vector is opened back to independent
//! positions, its covariance at position k taken as s_j s_l Cov(d_jk, d_lk) with
//! s_j = √(N_j/(N_j − 1)) for a laboratory reporting N_j positions (the closed vector's
//! covariance is then s²·P·diag(u²)·P exactly with one u per laboratory): D_k is the sum of
//! that over both comparisons for the linking laboratories at k, W_k = D_k⁻¹. The GLS of Δ
//! and γ under the closure is solved through its normal equations, a diagonal block per
//! position and a small bordered block (γ and the closure's multiplier) by its Schur
//! complement,
//!
//! ```text
//! a_k = 1ᵀW_k1,  g_k = [W_k1 placed at the laboratories of k ; 1] / a_k,
//! M = [[Σ_k E_kᵀW_kE_k, 0], [0, 0]] − Σ_k a_k g_k g_kᵀ,
//! η = M⁻¹([Σ_k E_kᵀW_k y_k ; 0] − Σ_k g_k r_k),  r_k = 1ᵀW_k y_k,
//! Δ_k = r_k / a_k − g_kᵀη,   Cov(Δ_k, Δ_m) = δ_km / a_k + g_kᵀ M⁻¹ g_m,
//! ```
//!
//! so that nothing is N × N. The link's test is χ² = Σ_k e_kᵀW_k e_k of the residuals with
//! ν = Σ_j (N_j − 1) − (N − 1), which is the closed vectors' (N − 1)/N · Σ_k χ²_k of
//! [`super::link`] when every laboratory reports every position with one u. Laboratory i
//! of this comparison, closed over its own positions S_i, is given against the linked
//! reference as d_i + P_iΔ (P_i: less the mean over S_i), with
//! u² = u²(d_i) + Var(P_iΔ) + 2 Cov(d_i, P_iΔ), its correlation with the linking
//! laboratories' degrees of equivalence counted through the same opened covariances.

use nalgebra::{DMatrix, DVector};

use super::link::{doe, doe_covariance, standard_u};
use super::{DegreeOfEquivalence, KcError, KeyComparison, VectorTest};

/// s = √(N/(N − 1)) of a degree of equivalence closed over the N positions it reports: its
/// closed covariance opened back to independent positions (`None` for fewer than two: no
/// closed vector).
fn opening(d: &DegreeOfEquivalence) -> Option<f64> {
    let n = d.d.iter().filter(|x| x.is_finite()).count();
    (n >= 2).then(|| (n as f64 / (n as f64 - 1.0)).sqrt())
}

/// The openings of the linking laboratories' degrees of equivalence `of` in one
/// comparison, refused for one that gives fewer than two positions.
fn openings(of: &[&DegreeOfEquivalence]) -> Result<Vec<f64>, KcError> {
    of.iter()
        .map(|d| {
            opening(d).ok_or_else(|| {
                KcError::Link(format!(
                    "the linking laboratory {} gives fewer than two positions in a \
                     comparison: no closed vector to link through",
                    d.lab
                ))
            })
        })
        .collect()
}

/// Position `k` of `kc` in words: its table angle, or its index.
fn position(kc: &KeyComparison, k: usize) -> String {
    match &kc.angle_deg {
        Some(angle) => format!("{}°", angle[k]),
        None => format!("position {}", kc.index[k]),
    }
}

/// One position of the link: the linking laboratories that report it in both comparisons
/// and their offsets with the weights of the GLS.
struct AtPosition {
    /// The linking laboratories at this position (indices into the link's list).
    labs: Vec<usize>,
    /// W_k = D_k⁻¹.
    weight: DMatrix<f64>,
    /// W_k·1.
    weight_ones: DVector<f64>,
    /// a_k = 1ᵀW_k1.
    total: f64,
    /// y_k: the offsets d(linked) − d(this).
    offsets: DVector<f64>,
    /// g_k (length L + 1).
    g: DVector<f64>,
}

/// The link solved over positions: Δ with its covariance pieces, and the test.
pub(super) struct Solved {
    /// The linking laboratories' degrees of equivalence in this comparison.
    here: Vec<DegreeOfEquivalence>,
    /// Their openings s_j in this comparison.
    open_here: Vec<f64>,
    at: Vec<AtPosition>,
    /// M⁻¹.
    m_inverse: DMatrix<f64>,
    /// Δ per position.
    pub correction: Vec<f64>,
    /// u(Δ) per position.
    pub correction_u: Vec<f64>,
    /// The link's test (`None` when no degree of freedom is left).
    pub vector: Option<VectorTest>,
}

/// The linking laboratories' degrees of equivalence `labs` in `kc`.
fn degrees<'a>(
    kc: &'a KeyComparison,
    labs: &[String],
) -> Result<Vec<&'a DegreeOfEquivalence>, KcError> {
    labs.iter()
        .map(|name| {
            doe(kc, name).ok_or_else(|| {
                KcError::Link(format!(
                    "{name} has no degree of equivalence to link through"
                ))
            })
        })
        .collect()
}

/// The positions each linking laboratory reports in both comparisons, refused where a
/// position has none or the laboratories fall into groups that share no position (their
/// constants and Δ could not be told apart).
fn reporting(
    this: &KeyComparison,
    here: &[&DegreeOfEquivalence],
    there: &[&DegreeOfEquivalence],
    labs: &[String],
) -> Result<Vec<Vec<usize>>, KcError> {
    let positions = this.index.len();
    let reports = |j: usize, k: usize| here[j].d[k].is_finite() && there[j].d[k].is_finite();
    let at: Vec<Vec<usize>> = (0..positions)
        .map(|k| (0..labs.len()).filter(|&j| reports(j, k)).collect())
        .collect();
    if let Some(k) = at.iter().position(Vec::is_empty) {
        return Err(KcError::Link(format!(
            "no linking laboratory reports {} in both comparisons: the offset there cannot \
             be found",
            position(this, k)
        )));
    }
    let reports: Vec<Vec<bool>> = (0..labs.len())
        .map(|j| (0..positions).map(|k| reports(j, k)).collect())
        .collect();
    let names: Vec<&str> = labs.iter().map(String::as_str).collect();
    if let Some(groups) = super::positions::groups_apart(&reports, &names) {
        return Err(KcError::Link(format!(
            "the linking laboratories fall into groups that share no position ({groups}): \
             their offsets cannot be put on one correction"
        )));
    }
    Ok(at)
}

/// Solves the link of `this` to `linked` through `labs` over the positions each reports
/// (see the module's documentation).
pub(super) fn solve(
    this: &KeyComparison,
    linked: &KeyComparison,
    labs: &[String],
) -> Result<Solved, KcError> {
    let l = labs.len();
    let here = degrees(this, labs)?;
    let there = degrees(linked, labs)?;
    let open_here = openings(&here)?;
    let open_there = openings(&there)?;
    let reporting_at = reporting(this, &here, &there, labs)?;
    let size = l + 1;
    let mut m = DMatrix::<f64>::zeros(size, size);
    let mut rhs = DVector::<f64>::zeros(size);
    let mut at = Vec::with_capacity(reporting_at.len());
    for (k, obs) in reporting_at.into_iter().enumerate() {
        let n = obs.len();
        let cov = DMatrix::from_fn(n, n, |a, b| {
            let (j, q) = (obs[a], obs[b]);
            doe_covariance(linked, there[j], there[q], k) * open_there[j] * open_there[q]
                + doe_covariance(this, here[j], here[q], k) * open_here[j] * open_here[q]
        });
        let weight = cov.cholesky().map(|c| c.inverse()).ok_or_else(|| {
            KcError::Link(format!(
                "the covariance of the linking laboratories' offsets at {} cannot be inverted",
                position(this, k)
            ))
        })?;
        let weight_ones = DVector::from_fn(n, |a, _| (0..n).map(|b| weight[(a, b)]).sum());
        let total: f64 = weight_ones.iter().sum();
        let offsets = DVector::from_fn(n, |a, _| there[obs[a]].d[k] - here[obs[a]].d[k]);
        let mut g = DVector::zeros(size);
        for (a, &j) in obs.iter().enumerate() {
            g[j] = weight_ones[a] / total;
        }
        g[l] = 1.0 / total;
        let weighted = &weight * &offsets;
        let r_k: f64 = weighted.iter().sum();
        for (a, &j) in obs.iter().enumerate() {
            rhs[j] += weighted[a];
            for (b, &q) in obs.iter().enumerate() {
                m[(j, q)] += weight[(a, b)];
            }
        }
        m -= &g * g.transpose() * total;
        rhs -= &g * r_k;
        at.push(AtPosition {
            labs: obs,
            weight,
            weight_ones,
            total,
            offsets,
            g,
        });
    }
    let m_inverse = m.lu().try_inverse().ok_or_else(|| {
        KcError::Link("the offsets of the linking laboratories cannot be solved for".into())
    })?;
    let eta = &m_inverse * &rhs;
    let mut correction = Vec::with_capacity(at.len());
    let mut correction_u = Vec::with_capacity(at.len());
    let (mut chi2, mut observations) = (0.0, 0usize);
    for p in &at {
        let r_k = p.weight_ones.dot(&p.offsets);
        let delta = r_k / p.total - p.g.dot(&eta);
        let variance = 1.0 / p.total + p.g.dot(&(&m_inverse * &p.g));
        let residual = DVector::from_fn(p.labs.len(), |a, _| p.offsets[a] - delta - eta[p.labs[a]]);
        chi2 += residual.dot(&(&p.weight * &residual));
        observations += p.labs.len();
        correction.push(delta);
        correction_u.push(variance.max(0.0).sqrt());
    }
    let dof = observations
        .checked_sub(l + at.len() - 1)
        .filter(|&dof| dof > 0);
    Ok(Solved {
        here: here.into_iter().cloned().collect(),
        open_here,
        at,
        m_inverse,
        correction,
        correction_u,
        vector: dof.map(|dof| VectorTest::at_five_percent(chi2, dof)),
    })
}

impl Solved {
    /// `d` (a degree of equivalence of this comparison `kc`, closed over the positions it
    /// reports) against the linked reference: d + P·Δ and U at k = 2 (NaN where it does
    /// not report).
    pub(super) fn linked(
        &self,
        kc: &KeyComparison,
        d: &DegreeOfEquivalence,
    ) -> (Vec<f64>, Vec<f64>) {
        let positions = self.at.len();
        let own: Vec<usize> = (0..positions).filter(|&k| d.d[k].is_finite()).collect();
        let n_own = own.len() as f64;
        let Some(open) = opening(d) else {
            // no closed vector: nothing to give against the linked reference
            return (vec![f64::NAN; positions], vec![f64::NAN; positions]);
        };
        let size = self.m_inverse.nrows();
        // ρ_p = 1ᵀW_p c_p and κ_p = E_pᵀW_p c_p, c_p = D_p(this)[i, ·] the opened covariance
        // of d with the linking laboratories at p
        let mut rho = vec![0.0; positions];
        let mut kappa = vec![DVector::<f64>::zeros(size); positions];
        let (mut h, mut q_mean, mut g_mean) = (
            DVector::<f64>::zeros(size),
            DVector::<f64>::zeros(size),
            DVector::<f64>::zeros(size),
        );
        let (mut rho_over_a, mut inverse_a) = (0.0, 0.0);
        for &p in &own {
            let at = &self.at[p];
            let c = DVector::from_fn(at.labs.len(), |a, _| {
                let j = at.labs[a];
                doe_covariance(kc, d, &self.here[j], p) * open * self.open_here[j]
            });
            let wc = &at.weight * &c;
            for (a, &j) in at.labs.iter().enumerate() {
                kappa[p][j] = wc[a];
            }
            rho[p] = wc.iter().sum();
            h += &at.g * (rho[p] / n_own);
            q_mean += &kappa[p] / n_own;
            g_mean += &at.g / n_own;
            rho_over_a += rho[p] / at.total / (n_own * n_own);
            inverse_a += 1.0 / at.total / (n_own * n_own);
        }
        let mean_delta = own.iter().map(|&k| self.correction[k]).sum::<f64>() / n_own;
        let m_g_mean = &self.m_inverse * &g_mean;
        let mean_mean = inverse_a + g_mean.dot(&m_g_mean);
        let mut value = vec![f64::NAN; positions];
        let mut expanded = vec![f64::NAN; positions];
        for &k in &own {
            let at = &self.at[k];
            let m_g = &self.m_inverse * &at.g;
            // Var(P·Δ) at k
            let variance_k = 1.0 / at.total + at.g.dot(&m_g);
            let with_mean = 1.0 / at.total / n_own + at.g.dot(&m_g_mean);
            let variance_p = variance_k - 2.0 * with_mean + mean_mean;
            // Cov(d_k, P·Δ at k)
            let mut inner = &h - &at.g * rho[k];
            inner += &kappa[k] - &q_mean;
            let psi = &self.m_inverse * inner;
            let with_delta = (-rho[k] + rho[k] / n_own) / at.total + at.g.dot(&psi);
            let with_delta_mean = -rho[k] / (at.total * n_own) + rho_over_a + g_mean.dot(&psi);
            let covariance = with_delta - with_delta_mean;
            let u_d = standard_u(d, k);
            let variance = u_d * u_d + variance_p + 2.0 * covariance;
            value[k] = d.d[k] + self.correction[k] - mean_delta;
            expanded[k] = if variance.is_finite() {
                2.0 * variance.max(0.0).sqrt()
            } else {
                f64::NAN
            };
        }
        (value, expanded)
    }
}
