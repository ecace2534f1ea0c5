//! The closed vector: the GLS reference of several laboratories' closed vectors (Σ = 0)
//! and its χ², the one test of a comparison's consistency (docs/FORMAT.md §12).
//!
//! A laboratory's closed result given without a covariance has V = c·P·D·P, c = N/(N − 1),
//! D = diag(u²), P = I − J/N: diagonal plus rank one on the closed subspace, whose
//! pseudo-inverse is V⁺ = W − w wᵀ/s with W = diag(w), w_k = 1/(c·u_k²), s = Σ_k w_k.
//! Then (x − r)ᵀ V⁺ (x − r) = min_a Σ_k w_k (x_k − r_k − a)², so the GLS of n such
//! laboratories is the weighted two-way additive fit
//!
//! ```text
//! x_ik = r_k + a_i + e_ik,   weights w_ik,   Σ_k r_k = 0
//! χ² = Σ_ik w_ik (x_ik − r_k − a_i)²,   ν = (N − 1)(n − 1)
//! ```
//!
//! r eliminated (r_k = Σ_i w_ik (x_ik − a_i) / W_k, W_k = Σ_i w_ik) leaves the n × n
//! system M a = h, M = diag(s) − G, G_ij = Σ_k w_ik w_jk / W_k, whose null space is the
//! constants (the gauge a + t, r − t): fixing a_1 = 0 makes it positive definite. The
//! reference's covariance is (Σ V_i⁺)⁺ = P·A′⁻¹·P with A′ = diag(W) − Σ_{i≥2} w_i w_iᵀ/s_i
//! (the gauge a_1 = 0), and by Woodbury A′⁻¹ = W⁻¹ + W⁻¹U′ M′⁻¹ U′ᵀW⁻¹ (U′ the columns
//! w_i, i ≥ 2; M′ the system without lab 1): O(N·n² + n³) time, O(N·n) memory, no N × N
//! matrix. A laboratory's own covariance (dense, from `solve --covariance`) takes the
//! dense GLS x_ref = (Σ V_i⁺)⁺ Σ V_i⁺ x_i instead, the same numbers.
//!
//! Every calculation is scaled by the comparison's largest standard uncertainty, so that
//! χ² is as accurate for u = 10⁻⁸″ as for u = 0.1″ (χ² is invariant under the scale).

use nalgebra::{DMatrix, DVector};

/// One laboratory's covariance on the closed subspace, in the comparison's scaled units.
#[derive(Debug, Clone)]
pub(crate) enum ClosedCovariance {
    /// Taken as closed from the row's standard uncertainties: V = c·P·diag(u²)·P.
    Stated(Vec<f64>),
    /// Not a closed vector: each position on its own, V = diag(u²), u = +∞ where the
    /// result does not report the position (angle blocks, [`super::blocks`]).
    Independent(Vec<f64>),
    /// Its own covariance V (N × N) with its pseudo-inverse V⁺, scaled.
    Own {
        /// V.
        v: DMatrix<f64>,
        /// V⁺ on the closed subspace.
        v_plus: DMatrix<f64>,
    },
}

impl ClosedCovariance {
    /// The diagonal of V: c·(u_k²(1 − 2/N) + Σ u²/N²) for a stated one.
    pub(crate) fn diagonal(&self) -> Vec<f64> {
        match self {
            ClosedCovariance::Stated(u) => {
                // closed over the positions the result reports (u finite); NaN elsewhere
                let faces = u.iter().filter(|u| u.is_finite()).count() as f64;
                let c = faces / (faces - 1.0);
                let mean_square = u
                    .iter()
                    .filter(|u| u.is_finite())
                    .map(|u| u * u)
                    .sum::<f64>()
                    / (faces * faces);
                u.iter()
                    .map(|u| {
                        if u.is_finite() {
                            c * (u * u * (1.0 - 2.0 / faces) + mean_square)
                        } else {
                            f64::NAN
                        }
                    })
                    .collect()
            }
            ClosedCovariance::Independent(u) => u.iter().map(|u| u * u).collect(),
            ClosedCovariance::Own { v, .. } => v.diagonal().iter().copied().collect(),
        }
    }

    /// V⁺ as a dense matrix (the dense path).
    pub(crate) fn dense_plus(&self) -> DMatrix<f64> {
        match self {
            ClosedCovariance::Stated(u) => {
                let (w, s) = weights(u);
                DMatrix::from_fn(u.len(), u.len(), |i, j| {
                    let diagonal = if i == j { w[i] } else { 0.0 };
                    diagonal - w[i] * w[j] / s
                })
            }
            ClosedCovariance::Independent(u) => DMatrix::from_fn(u.len(), u.len(), |i, j| {
                if i == j { 1.0 / (u[i] * u[i]) } else { 0.0 }
            }),
            ClosedCovariance::Own { v_plus, .. } => v_plus.clone(),
        }
    }
}

/// w_k = 1/(c·u_k²) and s = Σ w_k, c = N/(N − 1) with N the positions the result reports
/// (u finite; w_k = 0 where u_k = +∞, a position it does not report).
fn weights(u: &[f64]) -> (Vec<f64>, f64) {
    let faces = u.iter().filter(|u| u.is_finite()).count() as f64;
    let c = faces / (faces - 1.0);
    let w: Vec<f64> = u
        .iter()
        .map(|u| {
            if u.is_finite() {
                1.0 / (c * u * u)
            } else {
                0.0
            }
        })
        .collect();
    let s = w.iter().sum();
    (w, s)
}

/// The GLS fit of closed vectors.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ClosedFit {
    /// The closed reference r (Σ r = 0).
    pub reference: Vec<f64>,
    /// The diagonal of its covariance (Σ V_i⁺)⁺.
    pub reference_variance: Vec<f64>,
    /// χ² = Σ_i (x_i − r)ᵀ V_i⁺ (x_i − r).
    pub chi2: f64,
    /// (N − 1)(n − 1) (Σ_i N_i − n − (K − 1) when results report different positions).
    pub dof: usize,
    /// What [`projected_variance`] needs, when the results report different positions.
    pub pieces: Option<Box<Pieces>>,
}

/// The GLS fit of the closed vectors `x` (each already closed) with covariances `v`; `None`
/// for fewer than 2 vectors or 2 positions, or a system that cannot be solved (a
/// covariance singular on the closed subspace).
pub(crate) fn fit(x: &[&[f64]], v: &[&ClosedCovariance]) -> Option<ClosedFit> {
    fit_keeping(x, v, false)
}

/// [`fit`], keeping what [`projected_variance`] needs when `keep` (a comparison whose
/// results report different positions: a result outside the fit may report other
/// positions than those inside).
pub(crate) fn fit_keeping(x: &[&[f64]], v: &[&ClosedCovariance], keep: bool) -> Option<ClosedFit> {
    let independent: Option<Vec<&[f64]>> = v
        .iter()
        .map(|c| match c {
            ClosedCovariance::Independent(u) => Some(u.as_slice()),
            _ => None,
        })
        .collect();
    if let Some(u) = independent {
        return super::blocks::fit(x, &u);
    }
    let faces = x.first()?.len();
    if x.len() < 2 || faces < 2 || v.len() != x.len() {
        return None;
    }
    let all_stated: Option<Vec<&[f64]>> = v
        .iter()
        .map(|c| match c {
            ClosedCovariance::Stated(u) => Some(u.as_slice()),
            ClosedCovariance::Own { .. } | ClosedCovariance::Independent(_) => None,
        })
        .collect();
    let fit = match all_stated {
        Some(u) => additive_keeping(x, &u, keep)?,
        None => dense(x, v)?,
    };
    // a position no result in the set reports has neither (NaN): [`additive`]
    let finite = fit.chi2.is_finite()
        && fit
            .reference
            .iter()
            .zip(&fit.reference_variance)
            .all(|(r, v)| (r.is_finite() && v.is_finite()) || (r.is_nan() && v.is_nan()));
    finite.then_some(fit)
}

/// The two-way additive fit (module documentation): every laboratory's covariance stated.
/// A result that does not report a position has u = +∞ there (no weight): the fit is then
/// of what is there, ν = Σ_i N_i − n − (K − 1) with N_i the positions result i reports and
/// K those some result reports; a position no result reports has a reference of NaN, and
/// the fit keeps what [`projected_variance`] needs. The pieces of [`projected_variance`]
/// are kept when `keep` too.
fn additive_keeping(x: &[&[f64]], u: &[&[f64]], keep: bool) -> Option<ClosedFit> {
    let (labs, faces) = (x.len(), x[0].len());
    let reported: Vec<usize> = (0..faces)
        .filter(|&k| u.iter().any(|u| u[k].is_finite()))
        .collect();
    let complete = u.iter().all(|u| u.iter().all(|u| u.is_finite()));
    if !complete && reported.len() < faces {
        return compacted(x, u, &reported);
    }
    // results whose positions fall into groups sharing none: no one reference (the
    // system is singular, whatever rounding makes of it)
    if reported.len() < 2 || (!complete && super::positions::groups(u).len() > 1) {
        return None;
    }
    let mut w = Vec::with_capacity(labs);
    let mut s = Vec::with_capacity(labs);
    for u in u {
        let (wi, si) = weights(u);
        w.push(wi);
        s.push(si);
    }
    let total: Vec<f64> = (0..faces)
        .map(|k| (0..labs).map(|i| w[i][k]).sum())
        .collect();
    // m_k, the per-face weighted mean; b_i = Σ_k w_ik x_ik; h_i = b_i − Σ_k w_ik m_k.
    let mean: Vec<f64> = (0..faces)
        .map(|k| (0..labs).map(|i| w[i][k] * x[i][k]).sum::<f64>() / total[k])
        .collect();
    let h: Vec<f64> = (0..labs)
        .map(|i| (0..faces).map(|k| w[i][k] * (x[i][k] - mean[k])).sum())
        .collect();
    // M′ (labs 2 … n): s_i δ_ij − G_ij.
    let rest = labs - 1;
    let mut m = DMatrix::zeros(rest, rest);
    for p in 0..rest {
        for q in p..rest {
            let g: f64 = (0..faces)
                .map(|k| w[p + 1][k] * w[q + 1][k] / total[k])
                .sum();
            let entry = if p == q { s[p + 1] - g } else { -g };
            m[(p, q)] = entry;
            m[(q, p)] = entry;
        }
    }
    let cholesky = m.cholesky()?;
    let a_rest = cholesky.solve(&DVector::from_iterator(rest, h[1..].iter().copied()));
    let a: Vec<f64> = std::iter::once(0.0).chain(a_rest.iter().copied()).collect();
    let raw: Vec<f64> = (0..faces)
        .map(|k| mean[k] - (0..labs).map(|i| w[i][k] * a[i]).sum::<f64>() / total[k])
        .collect();
    let shift = raw.iter().sum::<f64>() / faces as f64;
    let reference: Vec<f64> = raw.iter().map(|r| r - shift).collect();
    let mut chi2 = 0.0;
    for i in 0..labs {
        for k in 0..faces {
            if w[i][k] > 0.0 {
                chi2 += w[i][k] * (x[i][k] - raw[k] - a[i]).powi(2);
            }
        }
    }
    let m_inverse = cholesky.inverse();
    let reference_variance = closed_reference_variance(&w, &total, &m_inverse);
    if complete && !keep {
        return Some(ClosedFit {
            reference,
            reference_variance,
            chi2,
            dof: (faces - 1) * (labs - 1),
            pieces: None,
        });
    }
    let observations = w.iter().flatten().filter(|w| **w > 0.0).count();
    let dof = observations.checked_sub(labs + faces - 1)?;
    Some(ClosedFit {
        reference,
        reference_variance,
        chi2,
        dof,
        pieces: Some(Box::new(Pieces {
            w,
            total,
            m_inverse,
            positions: (0..faces).collect(),
            faces,
        })),
    })
}

/// The variance of the closed reference at each position, the diagonal of P·A′⁻¹·P with
/// A′⁻¹ = W⁻¹ + Z M′⁻¹ Zᵀ, Z_kp = w_{p+1,k}/W_k (module documentation), from the weights
/// `w`, their totals W_k and M′⁻¹, without forming a K × K matrix.
fn closed_reference_variance(w: &[Vec<f64>], total: &[f64], m_inverse: &DMatrix<f64>) -> Vec<f64> {
    let (faces, rest) = (total.len(), m_inverse.nrows());
    let z = |k: usize, p: usize| w[p + 1][k] / total[k];
    let mut diagonal = vec![0.0; faces];
    let mut row_sum = vec![0.0; faces]; // (A′⁻¹ 1)_k
    let mut zt_one = vec![0.0; rest]; // Zᵀ 1
    for k in 0..faces {
        for (p, sum) in zt_one.iter_mut().enumerate() {
            *sum += z(k, p);
        }
    }
    let m_zt_one = m_inverse * DVector::from_column_slice(&zt_one);
    for k in 0..faces {
        let zk: Vec<f64> = (0..rest).map(|p| z(k, p)).collect();
        let mut quadratic = 0.0;
        for p in 0..rest {
            let mut inner = 0.0;
            for q in 0..rest {
                inner += m_inverse[(p, q)] * zk[q];
            }
            quadratic += zk[p] * inner;
        }
        diagonal[k] = 1.0 / total[k] + quadratic;
        row_sum[k] = 1.0 / total[k] + (0..rest).map(|p| zk[p] * m_zt_one[p]).sum::<f64>();
    }
    let n = faces as f64;
    let grand = row_sum.iter().sum::<f64>();
    (0..faces)
        .map(|k| (diagonal[k] - 2.0 * row_sum[k] / n + grand / (n * n)).max(0.0))
        .collect()
}

/// The fit of the positions some result reports (`reported`, at least 2), those no result
/// reports put back with a reference of NaN.
fn compacted(x: &[&[f64]], u: &[&[f64]], reported: &[usize]) -> Option<ClosedFit> {
    let faces = x.first()?.len();
    if reported.len() < 2 {
        return None;
    }
    let pick = |row: &[f64]| -> Vec<f64> { reported.iter().map(|&k| row[k]).collect() };
    let xs: Vec<Vec<f64>> = x.iter().map(|x| pick(x)).collect();
    let us: Vec<Vec<f64>> = u.iter().map(|u| pick(u)).collect();
    let xr: Vec<&[f64]> = xs.iter().map(Vec::as_slice).collect();
    let ur: Vec<&[f64]> = us.iter().map(Vec::as_slice).collect();
    let inner = additive_keeping(&xr, &ur, true)?;
    let mut fit = ClosedFit {
        reference: vec![f64::NAN; faces],
        reference_variance: vec![f64::NAN; faces],
        chi2: inner.chi2,
        dof: inner.dof,
        pieces: None,
    };
    for (j, &k) in reported.iter().enumerate() {
        fit.reference[k] = inner.reference[j];
        fit.reference_variance[k] = inner.reference_variance[j];
    }
    fit.pieces = inner.pieces.map(|mut p| {
        p.positions = reported.to_vec();
        p.faces = faces;
        p
    });
    Some(fit)
}

/// What a fit of results that report different positions keeps for [`projected_variance`]:
/// the weights, their sums per position and M′⁻¹ (module documentation), over the positions
/// some result reports (`positions`, of the comparison's `faces`).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Pieces {
    /// w_ik per result of the fit and reported position.
    w: Vec<Vec<f64>>,
    /// W_k = Σ_i w_ik.
    total: Vec<f64>,
    /// M′⁻¹.
    m_inverse: DMatrix<f64>,
    /// The comparison's positions the fit is of (some result reports them), ascending.
    positions: Vec<usize>,
    /// The comparison's number of positions.
    faces: usize,
}

/// diag(P_S·C_SS·P_S) for a result that reports the positions `reported` (of the
/// comparison's), C the covariance of the fit's reference, P_S the projector closing a
/// vector over S: the variance the reference takes out of (or adds to) that result's closed
/// degree of equivalence, d_i = P_S(x_i − x_ref,S). With Cov(x_i, x_ref) = P_S·C for a result
/// in the reference, Var(d_i) = V_i − P_S·C_SS·P_S (+ out of it). Per position of the
/// comparison, NaN where the result does not report it. `None` without pieces (every result
/// reports every position: then it is C_kk, the reference's own variance).
///
/// By Woodbury, B = A′⁻¹ = W⁻¹ + Z·M′⁻¹·Zᵀ, C = P·B·P (P closing over the K positions
/// fitted), so the row sums of C over S and its sum over S × S come from g_S = M′⁻¹·Zᵀ·1_S in
/// O(K·n) time, no K × K matrix.
pub(crate) fn projected_variance(fit: &ClosedFit, reported: &[bool]) -> Option<Vec<f64>> {
    let p = fit.pieces.as_ref()?;
    let k_count = p.positions.len();
    let rest = p.w.len().saturating_sub(1);
    let z = |j: usize, q: usize| p.w[q + 1][j] / p.total[j];
    // over the fitted positions j (compact), whether the result reports each
    let in_s: Vec<bool> = p
        .positions
        .iter()
        .map(|&k| reported.get(k).copied().unwrap_or(false))
        .collect();
    let n_s = in_s.iter().filter(|b| **b).count() as f64;
    let n_k = k_count as f64;
    let g = |mask: &dyn Fn(usize) -> bool| -> Vec<f64> {
        let mut zt = vec![0.0; rest];
        for (j, _) in p.positions.iter().enumerate().filter(|(j, _)| mask(*j)) {
            for (q, sum) in zt.iter_mut().enumerate() {
                *sum += z(j, q);
            }
        }
        (&p.m_inverse * DVector::from_column_slice(&zt))
            .iter()
            .copied()
            .collect()
    };
    let g_s = g(&|j| in_s[j]);
    let g_all = g(&|_| true);
    let zg = |j: usize, g: &[f64]| (0..rest).map(|q| z(j, q) * g[q]).sum::<f64>();
    // (B·1_S)_j and (B·1)_j
    let b_s: Vec<f64> = (0..k_count)
        .map(|j| f64::from(u8::from(in_s[j])) / p.total[j] + zg(j, &g_s))
        .collect();
    let b_all: Vec<f64> = (0..k_count)
        .map(|j| 1.0 / p.total[j] + zg(j, &g_all))
        .collect();
    let t_s: f64 = b_s.iter().sum();
    let grand: f64 = b_all.iter().sum();
    // (C·1_S)_j
    let c_s: Vec<f64> = (0..k_count)
        .map(|j| b_s[j] - n_s * b_all[j] / n_k - t_s / n_k + n_s * grand / (n_k * n_k))
        .collect();
    let total_s: f64 = (0..k_count).filter(|&j| in_s[j]).map(|j| c_s[j]).sum();
    let mut out = vec![f64::NAN; p.faces];
    for (j, &k) in p.positions.iter().enumerate() {
        if in_s[j] {
            let c_kk = fit.reference_variance[k];
            out[k] = (c_kk - 2.0 * c_s[j] / n_s + total_s / (n_s * n_s)).max(0.0);
        }
    }
    Some(out)
}

/// The dense GLS: x_ref = (Σ V_i⁺)⁺ Σ V_i⁺ x_i, its covariance (Σ V_i⁺)⁺.
fn dense(x: &[&[f64]], v: &[&ClosedCovariance]) -> Option<ClosedFit> {
    let faces = x[0].len();
    let mut sum_inverse = DMatrix::zeros(faces, faces);
    let mut sum_weighted = DVector::zeros(faces);
    let mut weights = Vec::with_capacity(x.len());
    for (x, v) in x.iter().zip(v) {
        let v_plus = v.dense_plus();
        sum_weighted += &v_plus * DVector::from_column_slice(x);
        sum_inverse += &v_plus;
        weights.push(v_plus);
    }
    let covariance = closed_pseudo_inverse(&sum_inverse)?;
    let reference = &covariance * sum_weighted;
    let mut chi2 = 0.0;
    for (xi, v_plus) in x.iter().zip(&weights) {
        let d = DVector::from_column_slice(xi) - &reference;
        chi2 += d.dot(&(v_plus * &d));
    }
    Some(ClosedFit {
        reference: reference.iter().copied().collect(),
        reference_variance: covariance.diagonal().iter().map(|v| v.max(0.0)).collect(),
        chi2,
        dof: (faces - 1) * (x.len() - 1),
        pieces: None,
    })
}

/// The χ² of a vector of differences d whose covariance is P·diag(v)·P, P = I − J/N (each
/// of two results closed, and their sum, as `compare` takes them): dᵀ(P·D·P)⁺d, its
/// constant part left out (P·D·P has the constants as its null space). As for one
/// laboratory above, (P·D·P)⁺ = W − w·wᵀ/s (Sherman–Morrison), so the χ² is the weighted sum
/// of squares about the weighted mean, Σ w_i·(d_i − d̄_w)², w_i = 1/v_i,
/// d̄_w = Σ w_i·d_i / Σ w_i: O(N), no matrix formed. Returns (χ², d̄_w). Every `v_i` must be
/// positive with a finite 1/v_i (the caller checks and scales).
pub(crate) fn difference_chi2(d: &[f64], variance: &[f64]) -> (f64, f64) {
    let weight_sum: f64 = variance.iter().map(|v| 1.0 / v).sum();
    let mean = d.iter().zip(variance).map(|(d, v)| d / v).sum::<f64>() / weight_sum;
    let chi2 = d
        .iter()
        .zip(variance)
        .map(|(d, v)| (d - mean).powi(2) / v)
        .sum();
    (chi2, mean)
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
/// vectors: A⁺ = (A + β·J/N)⁻¹ − J/(β·N), β the mean of A's diagonal (the constant
/// direction given an eigenvalue of A's own scale, inverted, and taken out again). `None`
/// when A + β·J/N is not positive definite.
pub(crate) fn closed_pseudo_inverse(a: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    closed_pseudo_inverse_blocks(a, 1)
}

/// [`closed_pseudo_inverse`] of a symmetric matrix of `blocks` × `blocks` blocks of
/// N × N whose null space is exactly the vectors constant within one block and zero in
/// the others (the normal matrix of several closed vectors fitted together, such as a
/// standard's value and drift in `polycal history`): each such direction is given an
/// eigenvalue β_b, the mean of its block's diagonal, the sum inverted, and the
/// directions taken out again, A⁺ = (A + Σ_b β_b·E_b)⁻¹ − Σ_b E_b/β_b with E_b = J/N on
/// block b. `None` when the sum is not positive definite or `a` is not square in blocks.
pub(crate) fn closed_pseudo_inverse_blocks(
    a: &DMatrix<f64>,
    blocks: usize,
) -> Option<DMatrix<f64>> {
    let size = a.nrows();
    if blocks == 0 || !size.is_multiple_of(blocks) || a.ncols() != size {
        return None;
    }
    let faces = size / blocks;
    let n = faces as f64;
    let mut added = a.clone();
    let mut taken_out = DMatrix::zeros(size, size);
    for b in 0..blocks {
        let range = b * faces..(b + 1) * faces;
        let beta = range.clone().map(|i| a[(i, i)]).sum::<f64>() / n;
        if !(beta > 0.0 && beta.is_finite()) {
            return None;
        }
        for i in range.clone() {
            for j in range.clone() {
                added[(i, j)] += beta / n;
                taken_out[(i, j)] = 1.0 / (beta * n);
            }
        }
    }
    let inverse = added.cholesky()?.inverse();
    Some(inverse - taken_out)
}

/// `x` closed: its mean taken out.
pub(crate) fn closed(x: &[f64]) -> Vec<f64> {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    x.iter().map(|x| x - mean).collect()
}

#[cfg(test)]
mod tests {
    /// Results that share no position fall into groups, and are not fitted together.
    #[test]
    fn kc_results_sharing_no_position_are_not_fitted() {
        let inf = f64::INFINITY;
        let u: [&[f64]; 4] = [
            &[0.1, 0.1, inf, inf],
            &[0.1, 0.1, inf, inf],
            &[inf, inf, 0.1, 0.1],
            &[inf, 0.1, 0.1, 0.1],
        ];
        assert_eq!(super::super::positions::groups(&u), vec![vec![0, 1, 2, 3]]);
        let apart: [&[f64]; 4] = [u[0], u[1], u[2], &[inf, inf, 0.1, 0.1]];
        assert_eq!(
            super::super::positions::groups(&apart),
            vec![vec![0, 1], vec![2, 3]]
        );
        let x: [&[f64]; 4] = [&[0.0; 4], &[0.0; 4], &[0.0; 4], &[0.0; 4]];
        assert!(super::additive_keeping(&x, &apart, false).is_none());
        assert!(super::additive_keeping(&x, &u, false).is_some());
    }

    /// The O(N) χ² of a closed difference is the dense one through the pseudo-inverse of
    /// the sum of two closed covariances.
    #[test]
    fn kc_difference_chi2_is_the_dense_one() {
        let u_a = [0.1, 0.2, 0.15, 0.3, 0.12, 0.05];
        let u_b = [0.3, 0.1, 0.1, 0.2, 0.02, 0.5];
        let v = crate::kc::closed_covariance(&u_a) + crate::kc::closed_covariance(&u_b);
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
        let (chi2, _) = difference_chi2(d.as_slice(), &variance);
        assert!((chi2 - dense).abs() < 1e-10 * dense, "{chi2} vs {dense}");
    }

    use super::*;

    /// The additive fit is the dense GLS: reference, its covariance's diagonal and χ².
    #[test]
    fn kc_closed_additive_fit_is_the_dense_gls() {
        let u: Vec<Vec<f64>> = (0..4)
            .map(|i| {
                (0..7)
                    .map(|k| 0.05 + 0.02 * i as f64 + 0.013 * k as f64)
                    .collect()
            })
            .collect();
        let x: Vec<Vec<f64>> = (0..4)
            .map(|i| {
                closed(
                    &(0..7)
                        .map(|k| ((i * 7 + k) as f64).sin() * 0.1)
                        .collect::<Vec<_>>(),
                )
            })
            .collect();
        let covariances: Vec<ClosedCovariance> = u
            .iter()
            .map(|u| ClosedCovariance::Stated(u.clone()))
            .collect();
        let xs: Vec<&[f64]> = x.iter().map(Vec::as_slice).collect();
        let vs: Vec<&ClosedCovariance> = covariances.iter().collect();
        let fast =
            additive_keeping(&xs, &u.iter().map(Vec::as_slice).collect::<Vec<_>>(), false).unwrap();
        let slow = dense(&xs, &vs).unwrap();
        assert!(
            (fast.chi2 - slow.chi2).abs() < 1e-9 * slow.chi2,
            "{fast:?} {slow:?}"
        );
        for k in 0..7 {
            assert!((fast.reference[k] - slow.reference[k]).abs() < 1e-12);
            let (a, b) = (fast.reference_variance[k], slow.reference_variance[k]);
            assert!((a - b).abs() < 1e-9 * b, "{a} {b}");
        }
        assert!(fast.reference.iter().sum::<f64>().abs() < 1e-14);
    }

    #[test]
    fn kc_pseudo_inverse_is_the_moore_penrose_one() {
        let u = [0.1, 0.2, 0.15, 0.3, 0.12];
        let v = ClosedCovariance::Stated(u.to_vec());
        let faces = u.len() as f64;
        let p = closing_projector(5);
        let d = DMatrix::from_diagonal(&DVector::from_iterator(5, u.iter().map(|u| u * u)));
        let dense_v = (&p * d * &p) * (faces / (faces - 1.0));
        let v_plus = v.dense_plus();
        assert!((&dense_v * &v_plus - &p).amax() < 1e-10);
        assert!((&dense_v * &v_plus * &dense_v - &dense_v).amax() < 1e-12);
        let from_trick = closed_pseudo_inverse(&dense_v).unwrap();
        assert!((from_trick - &v_plus).amax() < 1e-8 * v_plus.amax());
        let diagonal = v.diagonal();
        for k in 0..5 {
            assert!((diagonal[k] - dense_v[(k, k)]).abs() < 1e-15);
        }
        // Equal u: the diagonal is u².
        let v = ClosedCovariance::Stated(vec![0.2; 6]);
        assert!(v.diagonal().iter().all(|d| (d - 0.04).abs() < 1e-15));
    }
}
