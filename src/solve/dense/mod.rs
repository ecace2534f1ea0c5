//! The dense reference: general constrained least squares for any measurement design,
//! by a dense factorisation. [`super::least_squares_with_regressors`] uses it for designs
//! the circulant engine does not serve, and the tests hold the circulant engine to it.
//!
//! Unknowns: α\[0..N) (Σα = 0), φ[1..N−1\] (φ\[N\] = 0, so Σβ = 0), one setup error U per
//! (setup, ac) stream, and optional effect terms (extra regressor columns). Each reading
//! touches one α, one φ and one U, so the normal matrix has a diagonal α block. The
//! solver fixes the gauge with U\[first stream\] = 0, eliminates the α block (a Schur
//! complement of size N − 1 + K − 1 + E, built from sparse per-position rows), solves it
//! by Cholesky, and maps the estimates and their covariance to the Σα = 0 gauge. The
//! cost is dominated by one dense factorisation and inversion of about N × N, never
//! the (2N + K)² system.
//!
//! The inverse is solved against the Cholesky factor one block of identity columns at a
//! time (`blocked`): each column as nalgebra's `Cholesky::inverse` solves
//! it, to the bit, with the factor read once per block instead of twice per column,
//! and a progress observer told after every block (`Work`: the factorisation, the
//! inverse's blocks and the cofactor's other steps weighted by their cost, so that the
//! total is known from the start).

use super::observability::Unobservable;
use super::{
    Cofactor, Engine, Method, ParameterLayout, SetupError, Solution, SolveError, choose_sigma,
};
use crate::measurement::{MeasurementSet, Sigma};
use crate::polygon::face_deviation_from_pitch;
use crate::progress::Progress;
use blocked::{cholesky_by_blocks, inverse_by_blocks};
use nalgebra::{Cholesky, DMatrix, DVector};

mod blocked;
mod singular;

/// Bytes the dense path needs for a design of N faces, K streams and E effect terms: the
/// reduced normal matrix, its inverse and the cofactor of g and of θ (about seven
/// matrices of (2N + K + E)² values).
pub fn dense_bytes_needed(faces: usize, streams: usize, effects: usize) -> u128 {
    let len = (2 * faces + streams + effects) as u128;
    7 * len * len * 8
}

/// The problem after elimination of the α block.
pub(crate) struct Reduced {
    pub faces: usize,
    pub streams: usize,
    pub effects: usize,
    /// Readings per encoder position.
    pub count: Vec<f64>,
    /// Σ reading per encoder position.
    pub sum_alpha: Vec<f64>,
    /// Sparse rows b_p of the α–rest block of the normal matrix, merged and sorted.
    pub rows: Vec<Vec<(usize, f64)>>,
    /// Schur complement S = C − Bᵀ D⁻¹ B.
    pub schur: DMatrix<f64>,
    /// Right-hand side s = b_rest − Bᵀ D⁻¹ b_α.
    pub rhs: DVector<f64>,
}

impl Reduced {
    /// Size of the rest vector r = [φ\[1..N−1\], U\[2..K\], effects].
    fn rest_len(&self) -> usize {
        self.faces - 1 + self.streams - 1 + self.effects
    }

    /// Maps a gauge-fixed vector g = [α (N); r] to θ = [β (N); α (N, Σα = 0); U (K); e (E)].
    pub(crate) fn to_theta(&self, g: &[f64], theta: &mut [f64]) {
        let n = self.faces;
        let k = self.streams;
        let (alpha, rest) = g.split_at(n);
        let phi = &rest[..n - 1];
        let mean_alpha = alpha.iter().sum::<f64>() / n as f64;
        // β[1] = φ[1], β[f] = φ[f] − φ[f−1], β[N] = −φ[N−1]
        theta[0] = phi[0];
        for f in 1..n - 1 {
            theta[f] = phi[f] - phi[f - 1];
        }
        theta[n - 1] = -phi[n - 2];
        for (t, a) in theta[n..2 * n].iter_mut().zip(alpha) {
            *t = a - mean_alpha;
        }
        theta[2 * n] = mean_alpha;
        for s in 1..k {
            theta[2 * n + s] = rest[n - 1 + s - 1] + mean_alpha;
        }
        let e0 = n - 1 + k - 1;
        theta[2 * n + k..].copy_from_slice(&rest[e0..]);
    }

    /// α = D⁻¹ (b_α − B r) for a rest vector r (or its null-space analogue with b_α = 0).
    pub(crate) fn alpha_from_rest(&self, rest: &[f64], with_rhs: bool) -> Vec<f64> {
        (0..self.faces)
            .map(|p| {
                let br: f64 = self.rows[p].iter().map(|&(j, v)| v * rest[j]).sum();
                let b = if with_rhs { self.sum_alpha[p] } else { 0.0 };
                (b - br) / self.count[p]
            })
            .collect()
    }
}

/// Fits the model with extra effect terms (reading += Σ_e value_e · `regressors[e][i]`)
/// by the dense reference path: the α block eliminated, the Schur complement factorised
/// by Cholesky, the full cofactor matrix formed.
///
/// Each regressor has one value per reading of `set`, in order. Returns the estimates,
/// their cofactor matrix in the Σα = 0 gauge, residuals and degrees of freedom. A design
/// (or an effect term) that the data cannot determine is refused with
/// [`SolveError::Unobservable`]. It does not check memory: callers that may meet large
/// designs use [`super::least_squares_with_regressors`], which does.
pub fn dense_least_squares(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    stated_sigma: Option<Sigma>,
) -> Result<Solution, SolveError> {
    dense_least_squares_observed(set, regressors, stated_sigma, None)
}

/// [`dense_least_squares`] telling `progress` how much of its work is done (module
/// documentation: [`Work`]); the answer is the same number for number.
pub(crate) fn dense_least_squares_observed(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    stated_sigma: Option<Sigma>,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    dense_fit(set, regressors, None, stated_sigma, progress)
}

/// [`dense_least_squares`] by weighted least squares: reading i weighs `weights[i]`² (a
/// whitening factor, e.g. σ_ref/σᵢ), the regressors are given already whitened (each
/// value times its reading's `weights[i]`). The residuals, the residual sum of squares
/// and σ are the whitened ones (wᵢ·(yᵢ − model)); the cofactor is (XᵀW²X)⁻¹.
///
/// # Errors
///
/// As [`dense_least_squares`]. A reading whose weight is not finite and positive is left
/// out of the normal equations (a position left without readings is refused as
/// unobservable); `weights` of another length than the readings are ignored (an
/// unweighted fit).
pub fn dense_weighted_least_squares(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    weights: &[f64],
    stated_sigma: Option<Sigma>,
) -> Result<Solution, SolveError> {
    let weights = (weights.len() == set.readings.len()).then_some(weights);
    dense_fit(set, regressors, weights, stated_sigma, None)
}

/// The dense fit, weighted when `weights` are given ([`dense_weighted_least_squares`]).
fn dense_fit(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
    weights: Option<&[f64]>,
    stated_sigma: Option<Sigma>,
    progress: Option<&dyn Progress>,
) -> Result<Solution, SolveError> {
    check_regressors(set, regressors)?;
    let streams = set.streams();
    let (n, k, e) = (set.faces, streams.len(), regressors.len());
    let cells = set.readings.len() * (3 + e);
    let mut work = Work::new(progress, n - 1 + k - 1 + e, 2 * n + k + e, cells);
    let reduced = reduce_weighted(set, &streams, regressors, weights)?;
    work.reduced();
    let m = reduced.rest_len();
    let cholesky = factorise(&reduced.schur, |j0, j1| work.factorised(j0, j1))
        .ok_or_else(|| singular::explain_singular(&reduced, set))?;
    let rest = cholesky.solve(&reduced.rhs);
    let alpha = reduced.alpha_from_rest(rest.as_slice(), true);

    let mut g = alpha.clone();
    g.extend_from_slice(rest.as_slice());
    let layout = ParameterLayout {
        faces: n,
        setups: k,
        effects: e,
    };
    let mut theta = vec![0.0; layout.len()];
    reduced.to_theta(&g, &mut theta);

    let stream_index = |setup: u32, ac: u32| {
        streams
            .binary_search(&(setup, ac))
            .unwrap_or_else(|_| unreachable!("every stream was listed"))
    };
    let mut face_deviation = vec![0.0; n];
    face_deviation[..n - 1].copy_from_slice(&rest.as_slice()[..n - 1]);
    let residuals: Vec<f64> = set
        .readings
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let s = stream_index(r.setup, r.ac);
            let w = weights.map_or(1.0, |w| w[i]);
            let mut model =
                w * (theta[n + r.step % n] + face_deviation[r.face - 1] + theta[2 * n + s]);
            for (j, regressor) in regressors.iter().enumerate() {
                model += theta[2 * n + k + j] * regressor[i];
            }
            w * r.reading_arcsec - model
        })
        .collect();
    let rss: f64 = residuals.iter().map(|r| r * r).sum();
    let parameters = 2 * n - 2 + k + e;
    let dof = set.readings.len().saturating_sub(parameters);

    let cofactor = Cofactor::dense(layout, cofactor(&reduced, &cholesky, m, &mut work));
    work.finished();

    let pitch_deviation = theta[..n].to_vec();
    let face_deviation = face_deviation_from_pitch(&pitch_deviation);
    Ok(Solution {
        faces: n,
        method: Method::LeastSquares,
        engine: Engine::Dense,
        pitch_deviation,
        face_deviation,
        encoder_error: theta[n..2 * n].to_vec(),
        setup_error: streams
            .iter()
            .enumerate()
            .map(|(s, &(setup, ac))| SetupError {
                setup,
                ac,
                value: theta[2 * n + s],
            })
            .collect(),
        effect_values: theta[2 * n + k..].to_vec(),
        effect_regressors: regressors.to_vec(),
        residuals,
        readings: set.readings.len(),
        dof,
        rss,
        sigma: choose_sigma(rss, dof, stated_sigma),
        cofactor,
        layout,
        incomplete_cycles: Vec::new(),
    })
}

/// Builds the normal equations with the α block eliminated; with `weights`, of the
/// whitened problem: reading i's row of α, φ and U and its reading times `weights[i]`, the
/// regressors as given (whitened by the caller).
fn reduce_weighted(
    set: &MeasurementSet,
    streams: &[(u32, u32)],
    regressors: &[Vec<f64>],
    weights: Option<&[f64]>,
) -> Result<Reduced, SolveError> {
    let n = set.faces;
    let k = streams.len();
    let e = regressors.len();
    let m = n - 1 + k - 1 + e;
    let mut count = vec![0.0; n];
    let mut sum_alpha = vec![0.0; n];
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); n];
    let mut normal = DMatrix::<f64>::zeros(m, m);
    let mut rhs = DVector::<f64>::zeros(m);
    let mut x: Vec<(usize, f64)> = Vec::with_capacity(2 + e);
    for (i, r) in set.readings.iter().enumerate() {
        x.clear();
        let p = r.step % n;
        let w = weights.map_or(1.0, |w| w[i]);
        if !(w.is_finite() && w > 0.0) {
            continue;
        }
        if r.face < n {
            x.push((r.face - 1, w));
        }
        let s = streams
            .binary_search(&(r.setup, r.ac))
            .unwrap_or_else(|_| unreachable!("every stream was listed"));
        if s > 0 {
            x.push((n - 1 + s - 1, w));
        }
        for (j, regressor) in regressors.iter().enumerate() {
            let v = regressor[i];
            if v != 0.0 {
                x.push((n - 1 + k - 1 + j, v));
            }
        }
        let y = w * r.reading_arcsec;
        count[p] += w * w;
        sum_alpha[p] += w * y;
        for &(a, va) in &x {
            rhs[a] += va * y;
            for &(b, vb) in &x {
                normal[(a, b)] += va * vb;
            }
        }
        rows[p].extend(x.iter().map(|&(j, v)| (j, w * v)));
    }
    for row in &mut rows {
        row.sort_by_key(|&(j, _)| j);
        let mut merged: Vec<(usize, f64)> = Vec::with_capacity(row.len());
        for &(j, v) in row.iter() {
            match merged.last_mut() {
                Some((last, acc)) if *last == j => *acc += v,
                _ => merged.push((j, v)),
            }
        }
        *row = merged;
    }
    if let Some(p) = count.iter().position(|&c| c == 0.0) {
        return Err(Unobservable::position_unread(p, n).into());
    }
    for p in 0..n {
        let inv = 1.0 / count[p];
        for &(a, va) in &rows[p] {
            rhs[a] -= inv * va * sum_alpha[p];
            for &(b, vb) in &rows[p] {
                normal[(a, b)] -= inv * va * vb;
            }
        }
    }
    Ok(Reduced {
        faces: n,
        streams: k,
        effects: e,
        count,
        sum_alpha,
        rows,
        schur: normal,
        rhs,
    })
}

/// Cholesky factor of S, or `None` when S is singular to working precision;
/// `after_block(j0, j1)` is called when columns j0 … j1 − 1 of the factor are done.
fn factorise(
    schur: &DMatrix<f64>,
    after_block: impl FnMut(usize, usize),
) -> Option<Cholesky<f64, nalgebra::Dyn>> {
    let scale = (0..schur.nrows())
        .map(|i| schur[(i, i)])
        .fold(0.0_f64, f64::max);
    if scale <= 0.0 {
        return None;
    }
    let cholesky = cholesky_by_blocks(schur.clone(), after_block)?;
    let l = cholesky.l_dirty();
    let smallest = (0..l.nrows())
        .map(|i| l[(i, i)] * l[(i, i)])
        .fold(f64::INFINITY, f64::min);
    (smallest > 1e-10 * scale).then_some(cholesky)
}

/// The cofactor matrix Q of θ in the Σα = 0 gauge, from Q of g = [α; r]:
/// Q_rr = S⁻¹, Q_αr = −D⁻¹ B S⁻¹, Q_αα = D⁻¹ + D⁻¹ B S⁻¹ Bᵀ D⁻¹, then Q_θ = T Q_g Tᵀ
/// with the structured map T of [`Reduced::to_theta`] (O(N²) work).
fn cofactor(
    reduced: &Reduced,
    cholesky: &Cholesky<f64, nalgebra::Dyn>,
    m: usize,
    work: &mut Work<'_>,
) -> DMatrix<f64> {
    let n = reduced.faces;
    let s_inv = inverse_by_blocks(cholesky, |c0, c1| work.inverted(c0, c1));
    // Q_αr transposed: column p = −(1/n_p) Σ_j b_p[j] S⁻¹[:, j]
    let mut q_ar_t = DMatrix::<f64>::zeros(m, n);
    for p in 0..n {
        let inv = 1.0 / reduced.count[p];
        for &(j, v) in &reduced.rows[p] {
            let column = s_inv.column(j);
            let target = q_ar_t.column_mut(p);
            for (t, c) in target.into_iter().zip(column.iter()) {
                *t -= inv * v * c;
            }
        }
    }
    let size = n + m;
    let mut q_g = DMatrix::<f64>::zeros(size, size);
    for q in 0..n {
        let inv = 1.0 / reduced.count[q];
        for p in 0..n {
            let mut value = if p == q { inv } else { 0.0 };
            for &(j, v) in &reduced.rows[q] {
                value -= q_ar_t[(j, p)] * v * inv;
            }
            q_g[(p, q)] = value;
        }
    }
    for p in 0..n {
        for j in 0..m {
            let v = q_ar_t[(j, p)];
            q_g[(n + j, p)] = v;
            q_g[(p, n + j)] = v;
        }
    }
    q_g.view_mut((n, n), (m, m)).copy_from(&s_inv);
    drop(s_inv);
    work.mapped();

    let len = 2 * n + reduced.streams + reduced.effects;
    // T Q_g: apply T to every column of Q_g.
    let mut tq = DMatrix::<f64>::zeros(len, size);
    for c in 0..size {
        let column = q_g.column(c);
        reduced.to_theta(column.as_slice(), tq.column_mut(c).as_mut_slice());
    }
    // Q_θ = T (T Q_g)ᵀ: column i of Q_θ is T applied to row i of T Q_g.
    let tq_t = tq.transpose();
    let mut q_theta = DMatrix::<f64>::zeros(len, len);
    for i in 0..len {
        let column = tq_t.column(i);
        reduced.to_theta(column.as_slice(), q_theta.column_mut(i).as_mut_slice());
    }
    work.mapped();
    q_theta
}

/// The dense path's work as a progress observer sees it: a count with its total known
/// from the start, each step weighted by its cost (about one unit per column of the
/// inverse: the factorisation about m³/6 multiply–adds, a block of the inverse its forward
/// and back substitutions, each mapping of the cofactor one pass over its
/// (2N + K + E)² entries), so that the time left can be estimated from the rate.
pub(crate) struct Work<'a> {
    progress: Option<&'a dyn Progress>,
    /// Size of the reduced system.
    m: f64,
    /// Size of the cofactor of θ.
    len: f64,
    /// Readings times the columns of each (the reduction's work).
    cells: f64,
    /// Work done, in multiply–adds.
    done: f64,
    /// All the work, in multiply–adds.
    total: f64,
}

// The weights, in multiply–adds of the inverse's substitutions, measured on a sub-pitch
// set of 720 faces (m = 2887: the reduction 1.2 s, the factorisation 1.1 s, the inverse
// 4.4 s, the two mappings 0.6 s) and of 360.
/// Time of a multiply–add of the factorisation relative to one of the inverse's.
const FACTORISATION_WEIGHT: f64 = 1.0;
/// Time of one entry of a cofactor mapping (its (2N + K + E)² entries formed, read and
/// mapped) relative to a multiply–add of the inverse.
const MAPPING_WEIGHT: f64 = 64.0;
/// Time of one column of one reading in the reduction (the normal equations built,
/// the effect columns read reading by reading) relative to a multiply–add of the
/// inverse.
const REDUCTION_WEIGHT: f64 = 40.0;

impl<'a> Work<'a> {
    /// The work of a reduction of `cells` (readings times their columns) to a system of
    /// size `m`, and of a cofactor of size `len`, reported to `progress` (0 done) at once.
    fn new(progress: Option<&'a dyn Progress>, m: usize, len: usize, cells: usize) -> Self {
        let (m, len) = (m as f64, len as f64);
        let mut work = Work {
            progress,
            m,
            len,
            cells: cells as f64,
            done: 0.0,
            total: 0.0,
        };
        // factorisation, the inverse's substitutions (forward from each column on, back
        // in full), two mappings
        let forward = m * (m + 1.0) * (2.0 * m + 1.0) / 12.0;
        work.total = work.reduction()
            + work.factorisation()
            + forward
            + m * m * m / 2.0
            + 2.0 * work.mapping();
        work.report();
        work
    }

    fn reduction(&self) -> f64 {
        REDUCTION_WEIGHT * self.cells
    }

    /// The normal equations are built and reduced.
    fn reduced(&mut self) {
        self.done += self.reduction();
        self.report();
    }

    /// Multiply–adds of the factorisation: column j takes j·(m − j).
    fn factorisation(&self) -> f64 {
        let m = self.m;
        FACTORISATION_WEIGHT * (m * m * (m - 1.0) / 2.0 - (m - 1.0) * m * (2.0 * m - 1.0) / 6.0)
    }

    fn mapping(&self) -> f64 {
        MAPPING_WEIGHT * self.len * self.len
    }

    /// The unit of the count: one column of the inverse, about m² multiply–adds.
    fn unit(&self) -> f64 {
        (self.m * self.m).max(1.0)
    }

    fn report(&self) {
        if let Some(progress) = self.progress {
            let total = (self.total / self.unit()).ceil().max(1.0) as u64;
            let done = if self.done >= self.total {
                total
            } else {
                ((self.done / self.unit()) as u64).min(total)
            };
            progress.update(done, Some(total));
        }
    }

    /// Columns j0 … j1 − 1 of the factor are done.
    fn factorised(&mut self, j0: usize, j1: usize) {
        let m = self.m;
        let columns: f64 = (j0..j1).map(|j| j as f64 * (m - j as f64)).sum();
        self.done += FACTORISATION_WEIGHT * columns;
        self.report();
    }

    /// Columns c0 … c1 − 1 of the inverse are done.
    fn inverted(&mut self, c0: usize, c1: usize) {
        let rows = |c: usize| self.m - c as f64;
        // forward: Σ (m − c)²/2 over the block, back: m²/2 each
        let forward: f64 = (c0..c1).map(|c| rows(c) * rows(c) / 2.0).sum();
        self.done += forward + (c1 - c0) as f64 * self.m * self.m / 2.0;
        self.report();
    }

    /// One mapping of the cofactor is done.
    fn mapped(&mut self) {
        self.done += self.mapping();
        self.report();
    }

    /// All is done: the count at its total (whatever the rounding of the steps).
    fn finished(&mut self) {
        self.done = self.total;
        self.report();
    }
}

/// Every regressor has one finite value per reading.
pub(crate) fn check_regressors(
    set: &MeasurementSet,
    regressors: &[Vec<f64>],
) -> Result<(), SolveError> {
    for (index, regressor) in regressors.iter().enumerate() {
        if regressor.len() != set.readings.len() {
            return Err(SolveError::BadRegressor {
                index,
                reason: format!(
                    "{} values for {} readings",
                    regressor.len(),
                    set.readings.len()
                ),
            });
        }
        if regressor.iter().any(|v| !v.is_finite()) {
            return Err(SolveError::BadRegressor {
                index,
                reason: "a value is not finite".into(),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::blocked::BLOCK;
    use super::blocked::tests::spd;
    use super::*;

    #[test]
    fn the_work_rises_to_its_total() {
        use std::sync::Mutex;
        let seen = Mutex::new(Vec::new());
        let observer = |done: u64, total: Option<u64>| {
            seen.lock().expect("not poisoned").push((done, total));
        };
        let m = 3 * BLOCK + 5;
        let mut work = Work::new(Some(&observer), m, 2 * m, 100 * m);
        work.reduced();
        let cholesky = cholesky_by_blocks(spd(m, 7), |j0, j1| work.factorised(j0, j1))
            .expect("positive definite");
        let _ = inverse_by_blocks(&cholesky, |c0, c1| work.inverted(c0, c1));
        work.mapped();
        work.mapped();
        work.finished();
        let seen = seen.into_inner().expect("not poisoned");
        let total = seen[0].1.expect("a total");
        assert!(seen.iter().all(|&(_, t)| t == Some(total)));
        assert!(seen.windows(2).all(|w| w[0].0 <= w[1].0));
        assert_eq!(seen[0].0, 0);
        // before the last call, the steps' sum is at the total but for rounding
        assert!(seen[seen.len() - 2].0 + 1 >= total, "{seen:?}");
        assert_eq!(seen.last().map(|s| s.0), Some(total));
        // one report per block of the inverse, besides the others
        assert_eq!(seen.len(), 2 + 2 * m.div_ceil(BLOCK) + 2 + 1);
    }
}
