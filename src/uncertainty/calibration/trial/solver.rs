//! What solves a trial's targets: the paper's closed form on `Const<N>`, the calibration's
//! least-squares operator (readings or their sums per cell), or a [`CellMap`].

use nalgebra::{DVector, DefaultAllocator, Dim, SVector, allocator::Allocator};

use super::{McModel, McScratch};
use crate::solve::{ClosedFormSolution, closed_form};
use crate::uncertainty::calibration::operator::Operator;

/// Solves one trial's targets into the outputs; false on failure.
type ClosedFormFn = fn(&[f64], usize, &mut [f64]) -> bool;

fn write_closed_form<D: Dim>(s: &ClosedFormSolution<D>, offset: usize, out: &mut [f64])
where
    DefaultAllocator: Allocator<D>,
{
    let n = s.encoder_error.len();
    let (beta, rest) = out.split_at_mut(n);
    let (phi, alpha) = rest.split_at_mut(n - 1);
    beta.copy_from_slice(s.polygon.pitch_deviation_arcsec().as_slice());
    phi.copy_from_slice(&s.polygon.face_deviation_arcsec().as_slice()[..n - 1]);
    // α of position p is the solution's α[(p + offset) mod N]: a rotation, without a
    // division per position.
    let offset = offset % n;
    let encoder = s.encoder_error.as_slice();
    alpha[..n - offset].copy_from_slice(&encoder[offset..]);
    alpha[n - offset..n].copy_from_slice(&encoder[..offset]);
}

fn closed_form_const<const N: usize>(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let m1 = SVector::<f64, N>::from_column_slice(&t[..N]);
    let m2 = SVector::<f64, N>::from_column_slice(&t[N..2 * N]);
    // By reference: the solution is not moved out of the result (a copy of 3N values).
    match &closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(s, offset, out);
            true
        }
        Err(_) => false,
    }
}

fn closed_form_dyn(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let n = t.len() / 2;
    let m1 = DVector::from_column_slice(&t[..n]);
    let m2 = DVector::from_column_slice(&t[n..]);
    match closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(&s, offset, out);
            true
        }
        Err(_) => false,
    }
}

macro_rules! closed_form_for {
    ($n:expr; $($c:literal),*) => {
        match $n {
            $($c => closed_form_const::<$c> as ClosedFormFn,)*
            _ => closed_form_dyn as ClosedFormFn,
        }
    };
}

/// The closed form for N faces: `Const<N>` (stack only) for the usual N, else `Dyn`.
pub(super) fn closed_form_fn(n: usize) -> ClosedFormFn {
    closed_form_for!(n; 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14, 15, 16, 18, 20, 24, 30, 36, 40, 45, 48, 60, 72)
}

pub(super) enum TrialSolver {
    ClosedForm {
        offset: usize,
        solve: ClosedFormFn,
    },
    /// The operator, and whether the targets are the readings' sums per cell (else the
    /// readings).
    LeastSquares {
        op: Box<Operator>,
        cells: bool,
    },
    /// A linear map of the sums per cell.
    Cells(Box<dyn CellMap>),
}

/// A linear map of a trial's targets — the readings' sums per cell — to the outputs
/// ([`McModel::outputs`] order: β, φ\[1..N−1\], α, the setup errors), for a design the
/// calibration's operator does not solve (a self-calibration's heads between the
/// positions).
pub(crate) trait CellMap: Send + Sync {
    /// Writes the outputs of the sums per cell `cell_sums` into `out`.
    fn solve(&self, cell_sums: &[f64], out: &mut [f64]);
}

impl McModel {
    /// Solves the targets drawn by [`McModel::sample`] into `out` ([`McModel::outputs`]
    /// values: β, φ\[1..N−1\], α, and the setup errors when asked for), without the
    /// `result` offsets. False if the solver
    /// failed.
    pub fn solve(&self, scratch: &mut McScratch, out: &mut [f64]) -> bool {
        let n = self.faces;
        match &self.solver {
            TrialSolver::ClosedForm { offset, solve } => solve(&scratch.targets, *offset, out),
            TrialSolver::Cells(map) => {
                map.solve(&scratch.targets, out);
                true
            }
            TrialSolver::LeastSquares { op, cells } => {
                let solve = if *cells {
                    Operator::solve_cells
                } else {
                    Operator::solve
                };
                solve(
                    op,
                    &scratch.targets,
                    &mut scratch.face_sums,
                    &mut scratch.b,
                    0..2 * n + self.setup_outputs,
                    &mut scratch.theta,
                );
                let theta = &scratch.theta;
                out[..n].copy_from_slice(&theta[..n]);
                let mut running = 0.0;
                for f in 0..n - 1 {
                    running += theta[f];
                    out[n + f] = running;
                }
                out[2 * n - 1..3 * n - 1].copy_from_slice(&theta[n..2 * n]);
                let k = self.setup_outputs;
                out[3 * n - 1..3 * n - 1 + k].copy_from_slice(&theta[2 * n..2 * n + k]);
                true
            }
        }
    }
}
