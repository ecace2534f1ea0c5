//! The fit as a linear map of the readings: the solution operator L = Q Xᵀ (θ̂ = L y,
//! with Q the fit's cofactor matrix and X the design matrix), and the gains
//! G_j = Σ_g (Σ_{i∈g} L_ji)² of a scope through which a type-B error reaches quantity j.

use std::ops::Range;

use super::{CalibrationError, Scope};
use crate::measurement::MeasurementSet;
use crate::solve::Solution;

/// The fit as a linear map of the readings: θ̂ = Q Xᵀ y, θ = [β (N), α (N), U (K)] in
/// the model of one reading (the paper's eq. (2)) under the closure conditions Σβ = 0
/// and Σα = 0 (eqs. (1) and (3)).
#[derive(Debug, Clone)]
pub(super) struct Operator {
    pub(super) faces: usize,
    pub(super) streams: usize,
    /// Q, row-major, (2N + K)².
    q: Vec<f64>,
    /// Q with its β columns summed cumulatively: qc\[j·N + f\] = Σ_{k ≤ f} Q\[j, k\].
    qc: Vec<f64>,
    /// Per reading: position, face − 1, stream.
    position: Vec<usize>,
    face: Vec<usize>,
    stream: Vec<usize>,
}

impl Operator {
    pub(super) fn new(set: &MeasurementSet, solution: &Solution) -> Result<Self, CalibrationError> {
        let n = solution.faces;
        let layout = solution.layout;
        if layout.effects > 0 {
            return Err(CalibrationError::Effects(layout.effects));
        }
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
        let len = layout.len();
        let q: Vec<f64> = (0..len * len)
            .map(|i| solution.cofactor[(i / len, i % len)])
            .collect();
        let mut qc = vec![0.0; len * n];
        for j in 0..len {
            let mut running = 0.0;
            for f in 0..n {
                running += q[j * len + f];
                qc[j * n + f] = running;
            }
        }
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
        Ok(Operator {
            faces: n,
            streams: layout.setups,
            q,
            qc,
            position: set.readings.iter().map(|r| r.position(n)).collect(),
            face: set.readings.iter().map(|r| r.face - 1).collect(),
            stream,
        })
    }

    pub(super) fn len(&self) -> usize {
        2 * self.faces + self.streams
    }

    /// Adds w·L\[:, i\] (the response of θ̂ to reading i) to `theta`.
    pub(super) fn add_column(&self, i: usize, w: f64, theta: &mut [f64]) {
        let (n, len) = (self.faces, self.len());
        let (a, f, s) = (n + self.position[i], self.face[i], 2 * n + self.stream[i]);
        for (j, t) in theta.iter_mut().enumerate() {
            let row = &self.q[j * len..(j + 1) * len];
            *t += w * (row[a] + self.qc[j * n + f] + row[s]);
        }
    }

    /// θ̂ rows `rows` for the readings `y`: b = Xᵀy, then θ = Q b. `face_sums` (N) and
    /// `b` (2N + K) are scratch.
    pub(super) fn solve(
        &self,
        y: &[f64],
        face_sums: &mut [f64],
        b: &mut [f64],
        rows: Range<usize>,
        theta: &mut [f64],
    ) {
        let n = self.faces;
        face_sums.fill(0.0);
        b.fill(0.0);
        for (i, &v) in y.iter().enumerate() {
            face_sums[self.face[i]] += v;
            b[n + self.position[i]] += v;
            b[2 * n + self.stream[i]] += v;
        }
        // X has a 1 in β_k for every face ≥ k (φ_f = β_1 + … + β_f).
        let mut suffix = 0.0;
        for k in (0..n).rev() {
            suffix += face_sums[k];
            b[k] = suffix;
        }
        let len = self.len();
        for (t, j) in theta.iter_mut().zip(rows) {
            let row = &self.q[j * len..(j + 1) * len];
            *t = row.iter().zip(b.iter()).map(|(q, b)| q * b).sum();
        }
    }
}

/// The quantities reported, from θ = [β, α, U]: [β (N), φ (N), α (N), U (K)], with
/// φ\[N\] = 0 exactly.
pub(super) fn quantities(theta: &[f64], n: usize, out: &mut [f64]) {
    let k = theta.len() - 2 * n;
    out[..n].copy_from_slice(&theta[..n]);
    let mut running = 0.0;
    for f in 0..n {
        running += theta[f];
        out[n + f] = running;
    }
    out[2 * n - 1] = 0.0;
    out[2 * n..3 * n].copy_from_slice(&theta[n..2 * n]);
    out[3 * n..3 * n + k].copy_from_slice(&theta[2 * n..]);
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
    let mut g = vec![0.0; total];
    let mut theta = vec![0.0; op.len()];
    let mut q = vec![0.0; total];
    for members in groups(set, scope) {
        theta.fill(0.0);
        for i in members {
            op.add_column(i, 1.0, &mut theta);
        }
        quantities(&theta, n, &mut q);
        for (g, v) in g.iter_mut().zip(&q) {
            *g += v * v;
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::solve::{Method, SolveOptions, solve};
    use crate::uncertainty::calibration::test_support::set;

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
                &mut [0.0; 7],
                &mut vec![0.0; op.len()],
                0..op.len(),
                &mut theta2,
            );
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
}
