//! The fit as a linear map of the readings: the solution operator L = Q Xᵀ (θ̂ = L y,
//! with Q the fit's cofactor matrix and X the design matrix, effect columns included),
//! and the gains G_j = Σ_g (Σ_{i∈g} L_ji)² of a scope through which a type-B error
//! reaches quantity j.

use std::ops::Range;

use super::{CalibrationError, Scope};
use crate::measurement::MeasurementSet;
use crate::solve::cofactor::theta_from_g;
use crate::solve::{Cofactor, ParameterLayout, Solution};

/// The fit as a linear map of the readings: θ̂ = Q Xᵀ y, θ = [β (N), α (N), U (K),
/// effects (E)] in the model of one reading (the paper's eq. (2), plus the effect terms
/// of the solution's [`Solution::effect_regressors`]) under the closure conditions
/// Σβ = 0 and Σα = 0 (eqs. (1) and (3)).
#[derive(Debug, Clone)]
pub(super) struct Operator {
    pub(super) faces: usize,
    pub(super) streams: usize,
    pub(super) effects: usize,
    map: Map,
    /// Per reading: position, face − 1, stream.
    position: Vec<usize>,
    face: Vec<usize>,
    stream: Vec<usize>,
    /// Per reading, its cell (the readings of one stream at one position share position,
    /// face and stream): an index into `cells`, (position, face − 1, stream) each.
    cell: Vec<usize>,
    cells: Vec<(usize, usize, usize)>,
    /// Per reading, its E effect regressors: x\[i·E + e\].
    x: Vec<f64>,
}

/// Q held densely (small designs, or a dense solution), or the solution's structured
/// cofactor, applied in its own gauge g = [α, φ′, U′, effects] without forming Q.
#[derive(Debug, Clone)]
enum Map {
    Dense {
        /// Q, row-major, (2N + K + E)².
        q: Vec<f64>,
        /// Q with its β columns summed cumulatively: qc\[j·N + f\] = Σ_{k ≤ f} Q\[j, k\].
        qc: Vec<f64>,
        /// Q by columns: qt\[k·len + j\] = Q\[j, k\].
        qt: Vec<f64>,
    },
    Structured(Cofactor),
}

/// Up to this length of θ, Q is copied densely: a row product is then cheaper than an FFT.
const DENSE_UP_TO: usize = 256;

impl Operator {
    pub(super) fn new(set: &MeasurementSet, solution: &Solution) -> Result<Self, CalibrationError> {
        if set.has_shifts() {
            // the design below reads the encoder at step mod N, and the stops by step
            return Err(CalibrationError::ShiftedMountings);
        }
        let n = solution.faces;
        let layout = solution.layout;
        if set.faces != n
            || set.readings.len() != solution.readings
            || solution.residuals.len() != set.readings.len()
        {
            return Err(CalibrationError::Mismatch(format!(
                "{} faces and {} readings, the solution {} faces and {} readings",
                set.faces,
                set.readings.len(),
                n,
                solution.readings
            )));
        }
        let e = layout.effects;
        if solution.effect_regressors.len() != e
            || solution.effect_values.len() != e
            || solution
                .effect_regressors
                .iter()
                .any(|x| x.len() != set.readings.len())
        {
            return Err(CalibrationError::Mismatch(format!(
                "{} effect terms, {} effect values and {} regressors of lengths {:?} for {} readings",
                e,
                solution.effect_values.len(),
                solution.effect_regressors.len(),
                solution
                    .effect_regressors
                    .iter()
                    .map(Vec::len)
                    .collect::<Vec<_>>(),
                set.readings.len()
            )));
        }
        let len = layout.len();
        if solution.cofactor.len() != len {
            return Err(CalibrationError::Mismatch(format!(
                "a cofactor matrix of {0}×{0} for {len} parameters",
                solution.cofactor.len(),
            )));
        }
        let map = if solution.cofactor.is_dense() || len <= DENSE_UP_TO {
            let dense = solution.cofactor.to_dense();
            let q: Vec<f64> = (0..len * len).map(|i| dense[(i / len, i % len)]).collect();
            let mut qc = vec![0.0; len * n];
            for j in 0..len {
                let mut running = 0.0;
                for f in 0..n {
                    running += q[j * len + f];
                    qc[j * n + f] = running;
                }
            }
            let qt = (0..len * len)
                .map(|i| q[(i % len) * len + i / len])
                .collect();
            Map::Dense { q, qc, qt }
        } else {
            Map::Structured(solution.cofactor.clone())
        };
        let mut stream = Vec::with_capacity(set.readings.len());
        for r in &set.readings {
            let s = solution
                .setup_error
                .iter()
                .position(|s| (s.setup, s.ac) == (r.setup, r.ac))
                .ok_or_else(|| {
                    CalibrationError::Mismatch(format!(
                        "no setup error for setup {} autocollimator {}",
                        r.setup, r.ac
                    ))
                })?;
            stream.push(s);
        }
        let x = (0..set.readings.len())
            .flat_map(|i| solution.effect_regressors.iter().map(move |x| x[i]))
            .collect();
        let position: Vec<usize> = set.readings.iter().map(|r| r.position(n)).collect();
        let face: Vec<usize> = set.readings.iter().map(|r| r.face - 1).collect();
        let mut index = std::collections::HashMap::new();
        let mut cells = Vec::new();
        let cell = (0..set.readings.len())
            .map(|i| {
                let key = (position[i], face[i], stream[i]);
                *index.entry(key).or_insert_with(|| {
                    cells.push(key);
                    cells.len() - 1
                })
            })
            .collect();
        Ok(Operator {
            faces: n,
            streams: layout.setups,
            effects: e,
            map,
            position,
            face,
            stream,
            cell,
            cells,
            x,
        })
    }

    /// The length of the scratch `sums` of [`Operator::solve`]: N face sums and one sum
    /// per cell.
    pub(super) fn sums_len(&self) -> usize {
        self.faces + self.cells.len()
    }

    pub(super) fn len(&self) -> usize {
        2 * self.faces + self.streams + self.effects
    }

    fn layout(&self) -> ParameterLayout {
        ParameterLayout {
            faces: self.faces,
            setups: self.streams,
            effects: self.effects,
        }
    }

    /// The effect regressors of reading i.
    fn regressors(&self, i: usize) -> &[f64] {
        &self.x[i * self.effects..(i + 1) * self.effects]
    }

    /// Adds w·x_i, the design row of reading i in the structured gauge g, to `g`.
    fn add_row_g(&self, i: usize, w: f64, g: &mut [f64]) {
        let n = self.faces;
        g[self.position[i]] += w;
        g[n + self.face[i]] += w;
        g[2 * n + self.stream[i]] += w;
        let first_effect = 2 * n + self.streams;
        for (g, x) in g[first_effect..].iter_mut().zip(self.regressors(i)) {
            *g += w * x;
        }
    }

    /// Adds w·L\[:, i\] (the response of θ̂ to reading i) to `theta`.
    pub(super) fn add_column(&self, i: usize, w: f64, theta: &mut [f64]) {
        let (n, len) = (self.faces, self.len());
        match &self.map {
            Map::Dense { q, qc, .. } => {
                let (a, f, s) = (n + self.position[i], self.face[i], 2 * n + self.stream[i]);
                let first_effect = 2 * n + self.streams;
                let x = self.regressors(i);
                for (j, t) in theta.iter_mut().enumerate() {
                    let row = &q[j * len..(j + 1) * len];
                    let effects: f64 = row[first_effect..].iter().zip(x).map(|(q, x)| q * x).sum();
                    *t += w * (row[a] + qc[j * n + f] + row[s] + effects);
                }
            }
            Map::Structured(cofactor) => {
                let mut g = vec![0.0; len];
                self.add_row_g(i, w, &mut g);
                self.add_structured(cofactor, &g, theta);
            }
        }
    }

    /// theta += T Q_g v for a vector v in g.
    fn add_structured(&self, cofactor: &Cofactor, v: &[f64], theta: &mut [f64]) {
        let Some(structured) = cofactor.as_structured() else {
            unreachable!("a structured map holds a structured cofactor")
        };
        let qg = structured.apply(v);
        let mut t = vec![0.0; theta.len()];
        theta_from_g(&self.layout(), &qg, &mut t);
        for (theta, t) in theta.iter_mut().zip(&t) {
            *theta += t;
        }
    }

    /// θ̂ rows `rows` for the readings `y`: b = Xᵀy, then θ = Q b. `sums`
    /// ([`Operator::sums_len`]) and `b` (2N + K + E) are scratch.
    pub(super) fn solve(
        &self,
        y: &[f64],
        sums: &mut [f64],
        b: &mut [f64],
        rows: Range<usize>,
        theta: &mut [f64],
    ) {
        let (face_sums, cell_sums) = sums.split_at_mut(self.faces);
        // The readings' sums per cell: one addition per reading.
        cell_sums.fill(0.0);
        for (&c, &v) in self.cell.iter().zip(y) {
            cell_sums[c] += v;
        }
        b.fill(0.0);
        if self.effects > 0 {
            let first_effect = 2 * self.faces + self.streams;
            for (i, &v) in y.iter().enumerate() {
                for (b, x) in b[first_effect..].iter_mut().zip(self.regressors(i)) {
                    *b += x * v;
                }
            }
        }
        self.solve_from_cells(cell_sums, face_sums, b, rows, theta);
    }

    /// [`Operator::solve`] of readings given by their sums per cell (`cell_sums`, one
    /// per [`Operator::cell_of`] index), for a model without effect terms (whose Xᵀy
    /// needs every reading). `sums` and `b` are scratch as there.
    pub(super) fn solve_cells(
        &self,
        cell_sums: &[f64],
        sums: &mut [f64],
        b: &mut [f64],
        rows: Range<usize>,
        theta: &mut [f64],
    ) {
        debug_assert_eq!(self.effects, 0, "effect terms need every reading");
        b.fill(0.0);
        self.solve_from_cells(cell_sums, &mut sums[..self.faces], b, rows, theta);
    }

    /// The readings' cell (an index into the cell sums of [`Operator::solve_cells`]),
    /// reading by reading, and the number of cells.
    pub(super) fn cell_of(&self) -> (&[usize], usize) {
        (&self.cell, self.cells.len())
    }

    /// b = Xᵀy (effect terms already in `b`, the rest zero) from the cell sums (three
    /// additions per cell), then θ = Q b.
    fn solve_from_cells(
        &self,
        cell_sums: &[f64],
        face_sums: &mut [f64],
        b: &mut [f64],
        rows: Range<usize>,
        theta: &mut [f64],
    ) {
        let n = self.faces;
        match &self.map {
            Map::Dense { qt, .. } => {
                // θ through Q's columns: the cell sums per face, position and stream, X's
                // β columns (a 1 in β_k for every face ≥ k: φ_f = β_1 + … + β_f) as
                // suffix sums, then θ_j = Σ_k Q_jk b_k, k in order.
                face_sums.fill(0.0);
                let (alpha, setup) = b[n..2 * n + self.streams].split_at_mut(n);
                for (&(a, f, s), &v) in self.cells.iter().zip(cell_sums) {
                    face_sums[f] += v;
                    alpha[a] += v;
                    setup[s] += v;
                }
                let mut suffix = 0.0;
                for k in (0..n).rev() {
                    suffix += face_sums[k];
                    b[k] = suffix;
                }
                columns_times(qt, self.len(), b, rows, theta);
            }
            Map::Structured(cofactor) => {
                // In the gauge g = [α, φ′, U′, effects]: sums per position, face and
                // stream.
                let (alpha, rest) = b.split_at_mut(n);
                let (phi, setup) = rest.split_at_mut(n);
                for (&(a, f, s), &v) in self.cells.iter().zip(cell_sums) {
                    alpha[a] += v;
                    phi[f] += v;
                    setup[s] += v;
                }
                let mut all = vec![0.0; self.len()];
                self.add_structured(cofactor, b, &mut all);
                for (t, j) in theta.iter_mut().zip(rows) {
                    *t = all[j];
                }
            }
        }
    }

    /// The gains of independent errors on every reading, Σ_i L_ji² = Q_jj (L Lᵀ = Q for
    /// a least-squares fit), in [`quantities`] order, from the structured cofactor
    /// without a pass over the readings; `None` for a dense map.
    fn each_reading_gains(&self) -> Option<Vec<f64>> {
        let Map::Structured(cofactor) = &self.map else {
            return None;
        };
        let n = self.faces;
        let diagonal = cofactor.diagonal();
        let mut g = Vec::with_capacity(3 * n + self.streams);
        g.extend_from_slice(&diagonal[..n]);
        g.extend(cofactor.face_deviation_diagonal());
        g.extend_from_slice(&diagonal[n..2 * n + self.streams]);
        Some(g)
    }
}

/// `theta[i] = Σ_k M[rows.start + i, k]·b[k]` for M of size len × len held by columns
/// (`columns[k·len + j]` = M\[j, k\]): every sum in the order of k, sixteen rows at a
/// time side by side (independent sums the vector units add together, where a dot
/// product per row waits for every addition), the same value whatever the vector units.
fn columns_times(columns: &[f64], len: usize, b: &[f64], rows: Range<usize>, theta: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    if crate::uncertainty::monte_carlo::has_avx2() {
        // SAFETY: the processor has AVX2 (just checked).
        unsafe { columns_times_avx2(columns, len, b, rows, theta) };
        return;
    }
    columns_times_portable(columns, len, b, rows, theta);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn columns_times_avx2(
    columns: &[f64],
    len: usize,
    b: &[f64],
    rows: Range<usize>,
    theta: &mut [f64],
) {
    columns_times_portable(columns, len, b, rows, theta);
}

#[inline(always)]
fn columns_times_portable(
    columns: &[f64],
    len: usize,
    b: &[f64],
    rows: Range<usize>,
    theta: &mut [f64],
) {
    const BLOCK: usize = 16;
    let theta = &mut theta[..rows.len()];
    let b = &b[..len];
    let mut first = rows.start;
    for chunk in theta.chunks_mut(BLOCK) {
        let mut acc = [0.0; BLOCK];
        if chunk.len() == BLOCK {
            for (k, &bk) in b.iter().enumerate() {
                let column = &columns[k * len + first..k * len + first + BLOCK];
                for (a, m) in acc.iter_mut().zip(column) {
                    *a += m * bk;
                }
            }
        } else {
            for (k, &bk) in b.iter().enumerate() {
                let column = &columns[k * len + first..k * len + first + chunk.len()];
                for (a, m) in acc.iter_mut().zip(column) {
                    *a += m * bk;
                }
            }
        }
        chunk.copy_from_slice(&acc[..chunk.len()]);
        first += chunk.len();
    }
}

/// The quantities reported, from θ = [β, α, U, effects]: [β (N), φ (N), α (N), U (K)]
/// (`out` holds 3N + K values), with φ\[N\] = 0 exactly.
pub(super) fn quantities(theta: &[f64], n: usize, out: &mut [f64]) {
    let k = out.len() - 3 * n;
    out[..n].copy_from_slice(&theta[..n]);
    let mut running = 0.0;
    for f in 0..n {
        running += theta[f];
        out[n + f] = running;
    }
    out[2 * n - 1] = 0.0;
    out[2 * n..3 * n].copy_from_slice(&theta[n..2 * n]);
    out[3 * n..3 * n + k].copy_from_slice(&theta[2 * n..2 * n + k]);
}

/// Dense group number of every reading for a scope (not for [`Scope::Result`]).
pub(super) fn groups(set: &MeasurementSet, scope: Scope) -> Vec<Vec<usize>> {
    let n = set.faces;
    let mut keys: Vec<(u64, u64, u64)> = set
        .readings
        .iter()
        .enumerate()
        .map(|(i, r)| match scope {
            Scope::EachReading | Scope::Result => (i as u64, 0, 0),
            Scope::EachAutocollimator => (u64::from(r.ac), 0, 0),
            Scope::EachPosition => (r.position(n) as u64, 0, 0),
            Scope::EachStop => (u64::from(r.setup), u64::from(r.cycle), r.step as u64),
        })
        .collect();
    let mut distinct = keys.clone();
    distinct.sort_unstable();
    distinct.dedup();
    let mut members = vec![Vec::new(); distinct.len()];
    for (i, key) in keys.drain(..).enumerate() {
        let g = distinct
            .binary_search(&key)
            .unwrap_or_else(|_| unreachable!("every key was listed"));
        members[g].push(i);
    }
    members
}

/// G_j = Σ_g (Σ_{i∈g} L_ji)² for every reported quantity j ([`quantities`] order).
pub(super) fn gains(op: &Operator, set: &MeasurementSet, scope: Scope) -> Vec<f64> {
    let n = op.faces;
    let total = 3 * n + op.streams;
    if scope == Scope::Result {
        let mut g = vec![1.0; total];
        g[2 * n - 1] = 0.0;
        return g;
    }
    if scope == Scope::EachReading
        && let Some(g) = op.each_reading_gains()
    {
        return g;
    }
    let mut g = vec![0.0; total];
    let mut theta = vec![0.0; op.len()];
    let mut q = vec![0.0; total];
    let mut row = vec![0.0; op.len()];
    for members in groups(set, scope) {
        theta.fill(0.0);
        match &op.map {
            Map::Dense { .. } => {
                for i in members {
                    op.add_column(i, 1.0, &mut theta);
                }
            }
            Map::Structured(cofactor) => {
                row.fill(0.0);
                for i in members {
                    op.add_row_g(i, 1.0, &mut row);
                }
                op.add_structured(cofactor, &row, &mut theta);
            }
        }
        quantities(&theta, n, &mut q);
        for (g, v) in g.iter_mut().zip(&q) {
            *g += v * v;
        }
    }
    g
}

/// s = L·w for a weighted sum of the readings: the change of every reported quantity
/// ([`quantities`] order) per unit of an error that moves reading i by wᵢ.
pub(super) fn sensitivities(op: &Operator, weights: &[f64]) -> Vec<f64> {
    let n = op.faces;
    let mut theta = vec![0.0; op.len()];
    match &op.map {
        Map::Dense { .. } => {
            for (i, &w) in weights.iter().enumerate() {
                if w != 0.0 {
                    op.add_column(i, w, &mut theta);
                }
            }
        }
        Map::Structured(cofactor) => {
            let mut row = vec![0.0; op.len()];
            for (i, &w) in weights.iter().enumerate() {
                if w != 0.0 {
                    op.add_row_g(i, w, &mut row);
                }
            }
            op.add_structured(cofactor, &row, &mut theta);
        }
    }
    let mut q = vec![0.0; 3 * n + op.streams];
    quantities(&theta, n, &mut q);
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{Method, SolveOptions, solve};
    use crate::uncertainty::calibration::test_support::set;

    /// Q b by columns is the row-by-row product, in any rows, and the vector units give
    /// the same bits as the portable code.
    #[test]
    fn columns_times_is_the_product() {
        let len = 50;
        let m: Vec<f64> = (0..len * len)
            .map(|i| ((i * 7919) % 1013) as f64 / 1013.0 - 0.5)
            .collect();
        let b: Vec<f64> = (0..len).map(|k| (k as f64 * 0.37).sin()).collect();
        for rows in [0..len, 0..48, 3..40, 17..18] {
            let mut theta = vec![0.0; rows.len()];
            columns_times(&m, len, &b, rows.clone(), &mut theta);
            let mut portable = vec![0.0; rows.len()];
            columns_times_portable(&m, len, &b, rows.clone(), &mut portable);
            assert_eq!(theta, portable);
            for (t, j) in theta.iter().zip(rows) {
                let row: f64 = (0..len).map(|k| m[k * len + j] * b[k]).sum();
                assert!((t - row).abs() < 1e-13, "{t} {row}");
            }
        }
    }

    /// L = Q Xᵀ reproduces the solver: θ̂ = L y, for least squares and the closed form.
    #[test]
    fn operator_is_the_solver() {
        for (closing, method) in [(true, Method::LeastSquares), (false, Method::ClosedForm)] {
            let s = set(7, 3, closing, 4);
            let solution = solve(
                &s,
                &SolveOptions {
                    method,
                    ..Default::default()
                },
            )
            .unwrap();
            let op = Operator::new(&s, &solution).unwrap();
            let y: Vec<f64> = s.readings.iter().map(|r| r.reading_arcsec).collect();
            let mut theta = vec![0.0; op.len()];
            for (i, &v) in y.iter().enumerate() {
                op.add_column(i, v, &mut theta);
            }
            let mut theta2 = vec![0.0; op.len()];
            op.solve(
                &y,
                &mut vec![0.0; op.sums_len()],
                &mut vec![0.0; op.len()],
                0..op.len(),
                &mut theta2,
            );
            // The same from the readings' sums per cell (three cycles: three readings
            // in every cell).
            let (cell, cells) = op.cell_of();
            assert_eq!(cells, 14);
            let mut cell_sums = vec![0.0; cells];
            for (&c, &v) in cell.iter().zip(&y) {
                cell_sums[c] += v;
            }
            let mut theta3 = vec![0.0; op.len()];
            op.solve_cells(
                &cell_sums,
                &mut vec![0.0; op.sums_len()],
                &mut vec![0.0; op.len()],
                0..op.len(),
                &mut theta3,
            );
            assert_eq!(theta3, theta2);
            for k in 0..7 {
                assert!((theta[k] - solution.pitch_deviation[k]).abs() < 1e-12);
                assert!((theta2[k] - solution.pitch_deviation[k]).abs() < 1e-12);
                assert!((theta[7 + k] - solution.encoder_error[k]).abs() < 1e-12);
                assert!((theta2[7 + k] - solution.encoder_error[k]).abs() < 1e-12);
            }
            // Σ_i L_ji² = Q_jj (L Lᵀ = Q)
            let g = gains(&op, &s, Scope::EachReading);
            let sigma = solution.sigma.unwrap().0;
            let u = solution.pitch_deviation_u().unwrap();
            let uf = solution.face_deviation_u().unwrap();
            let ua = solution.encoder_error_u().unwrap();
            for k in 0..7 {
                assert!((sigma * g[k].sqrt() - u[k]).abs() < 1e-12);
                assert!((sigma * g[7 + k].sqrt() - uf[k]).abs() < 1e-12);
                assert!((sigma * g[14 + k].sqrt() - ua[k]).abs() < 1e-12);
            }
        }
    }

    /// With effect columns (a drift-like ramp on autocollimator 2 and one reading left
    /// out as an outlier), L = Q Xᵀ still reproduces the solver, effect values included,
    /// and σ²·Σ_i L_ji² is the fit's own variance; the outlier's reading moves nothing
    /// but its own effect term.
    #[test]
    fn operator_is_the_solver_with_effects() {
        use crate::solve::least_squares_with_regressors;
        let s = set(7, 3, true, 5);
        let ramp: Vec<f64> = s
            .readings
            .iter()
            .enumerate()
            .map(|(i, r)| if r.ac == 2 { i as f64 / 10.0 } else { 0.0 })
            .collect();
        let mut outlier = vec![0.0; s.readings.len()];
        outlier[17] = 1.0;
        let solution = least_squares_with_regressors(&s, &[ramp, outlier], None).unwrap();
        assert_eq!(solution.layout.effects, 2);
        let op = Operator::new(&s, &solution).unwrap();
        let y: Vec<f64> = s.readings.iter().map(|r| r.reading_arcsec).collect();
        let mut theta = vec![0.0; op.len()];
        for (i, &v) in y.iter().enumerate() {
            op.add_column(i, v, &mut theta);
        }
        let mut theta2 = vec![0.0; op.len()];
        op.solve(
            &y,
            &mut vec![0.0; op.sums_len()],
            &mut vec![0.0; op.len()],
            0..op.len(),
            &mut theta2,
        );
        let expected: Vec<f64> = solution
            .pitch_deviation
            .iter()
            .chain(&solution.encoder_error)
            .chain(solution.setup_error.iter().map(|s| &s.value))
            .chain(&solution.effect_values)
            .copied()
            .collect();
        assert_eq!(expected.len(), op.len());
        for (j, e) in expected.iter().enumerate() {
            assert!((theta[j] - e).abs() < 1e-10, "{j}: {} vs {e}", theta[j]);
            assert!((theta2[j] - e).abs() < 1e-10, "{j}: {} vs {e}", theta2[j]);
        }
        let mut column = vec![0.0; op.len()];
        op.add_column(17, 1.0, &mut column);
        for (j, c) in column.iter().enumerate() {
            let own = if j == op.len() - 1 { 1.0 } else { 0.0 };
            assert!((c - own).abs() < 1e-10, "{j}: {c}");
        }
        let g = gains(&op, &s, Scope::EachReading);
        let sigma = solution.sigma.unwrap().0;
        let u = solution.pitch_deviation_u().unwrap();
        let ua = solution.encoder_error_u().unwrap();
        let us = solution.setup_error_u().unwrap();
        for k in 0..7 {
            assert!((sigma * g[k].sqrt() - u[k]).abs() < 1e-12);
            assert!((sigma * g[14 + k].sqrt() - ua[k]).abs() < 1e-12);
        }
        for (k, us) in us.iter().enumerate() {
            assert!((sigma * g[21 + k].sqrt() - us).abs() < 1e-12);
        }
    }

    /// A solution whose effect columns are missing is refused, not propagated as if it
    /// had none.
    #[test]
    fn missing_effect_columns_are_refused() {
        use crate::solve::least_squares_with_regressors;
        let s = set(7, 3, true, 6);
        let ramp: Vec<f64> = (0..s.readings.len()).map(|i| i as f64).collect();
        let mut solution = least_squares_with_regressors(&s, &[ramp], None).unwrap();
        solution.effect_regressors.clear();
        assert!(matches!(
            Operator::new(&s, &solution),
            Err(CalibrationError::Mismatch(_))
        ));
    }

    /// Above 256 parameters the operator applies the structured cofactor in its own
    /// gauge instead of copying Q: for every scope its gains, its solve and its columns
    /// equal those of the dense map built from the dense reference fit of the same data,
    /// effect columns included.
    #[test]
    fn structured_map_equals_the_dense_map() {
        use crate::solve::{dense_least_squares, least_squares_with_regressors};
        let s = set(150, 3, true, 9);
        let ramp: Vec<f64> = s
            .readings
            .iter()
            .enumerate()
            .map(|(i, r)| if r.ac == 2 { i as f64 / 100.0 } else { 0.0 })
            .collect();
        let columns = [ramp];
        let fast = least_squares_with_regressors(&s, &columns, None).unwrap();
        let dense = dense_least_squares(&s, &columns, None).unwrap();
        assert!(!fast.cofactor.is_dense());
        let (op_fast, op_dense) = (
            Operator::new(&s, &fast).unwrap(),
            Operator::new(&s, &dense).unwrap(),
        );
        assert!(matches!(op_fast.map, Map::Structured(_)));
        assert!(matches!(op_dense.map, Map::Dense { .. }));
        for scope in [
            Scope::EachReading,
            Scope::EachAutocollimator,
            Scope::EachPosition,
            Scope::EachStop,
        ] {
            let (a, b) = (gains(&op_fast, &s, scope), gains(&op_dense, &s, scope));
            for (j, (a, b)) in a.iter().zip(&b).enumerate() {
                assert!(
                    (a - b).abs() < 1e-9 * b.abs().max(1.0),
                    "{scope:?} {j}: {a} vs {b}"
                );
            }
        }
        let y: Vec<f64> = s.readings.iter().map(|r| r.reading_arcsec).collect();
        let len = op_fast.len();
        let (mut t1, mut t2) = (vec![0.0; len], vec![0.0; len]);
        op_fast.solve(
            &y,
            &mut vec![0.0; op_fast.sums_len().max(op_dense.sums_len())],
            &mut vec![0.0; len],
            0..len,
            &mut t1,
        );
        op_dense.solve(
            &y,
            &mut vec![0.0; op_fast.sums_len().max(op_dense.sums_len())],
            &mut vec![0.0; len],
            0..len,
            &mut t2,
        );
        for j in 0..len {
            assert!((t1[j] - t2[j]).abs() < 1e-9, "{j}");
        }
        assert!((t1[150] - fast.encoder_error[0]).abs() < 1e-10);
        let (mut c1, mut c2) = (vec![0.0; len], vec![0.0; len]);
        op_fast.add_column(77, 2.0, &mut c1);
        op_dense.add_column(77, 2.0, &mut c2);
        for j in 0..len {
            assert!((c1[j] - c2[j]).abs() < 1e-10, "{j}");
        }
    }
}
