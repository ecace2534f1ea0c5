//! The geometry of a fit: the hat matrix H = X Q Xᵀ of a least-squares solution, used to
//! score a candidate column without refitting.
//!
//! Adding a column x to a model with residuals e reduces the residual sum of squares by
//!
//! ```text
//! Δ = (xᵀe)² / (xᵀx − xᵀHx)
//! ```
//!
//! (the squared projection of the residuals on the part of x the model does not already
//! span). With the cofactor matrix Q of the fit, xᵀHx = gᵀQg where g = Σᵢ xᵢ cᵢ sums the
//! design rows cᵢ of the readings x touches. Each design row is sparse (one α, one φ, one
//! setup error, the effect columns).
//!
//! Two forms, one answer:
//!
//! - **structured** (whenever the fit's cofactor is, [`crate::solve::cofactor`]): Q in the
//!   engine's gauge g as B + W M Wᵀ, never formed; an entry of H costs O(r), a column's
//!   score one product Q·g (O(N log N)), and every suffix of a time-ordered stream — the
//!   columns of a change-point search — comes from the stream's circulant kernel by
//!   blocked FFT convolution plus the low-rank part in O(r) per reading
//!   (`structured.rs`). Memory O(n + N·r).
//! - **dense** (the dense reference solver's fits, and [`FitGeometry::dense`] for tests):
//!   Q formed in ψ, a column scored in O(n + P²), every suffix in O(P) per reading.
//! - **off the grid** (a self-calibration whose heads sit between the positions,
//!   `FitGeometry::off_grid`): the rows are dense in φ′ and never formed; products go
//!   through the band-limited design and the fit's structured cofactor, the entries of H
//!   through one kernel per pair of heads (`off_grid.rs`).

mod off_grid;
mod structured;

use std::sync::Arc;

use nalgebra::DMatrix;

use super::nuisance::StopNuisance;
use crate::measurement::MeasurementSet;
use crate::selfcal::OffGridDesign;
use crate::solve::Solution;
use off_grid::OffGridGeometry;
use structured::StructuredGeometry;
pub use structured::SuffixCache;

/// The hat-matrix geometry of one fit: its cofactor (dense in ψ, or structured in g) and
/// the sparse design row of every reading.
#[derive(Debug, Clone)]
pub struct FitGeometry {
    /// The cofactor.
    form: Form,
    /// The design row of every reading: (index in ψ or g, coefficient).
    rows: Vec<Vec<(usize, f64)>>,
    /// A self-calibration's table error at every stop, taken out of the fit
    /// ([`StopNuisance`]): its P_D is added to the hat matrix.
    nuisance: Option<StopNuisance>,
}

/// The cofactor a geometry holds.
#[derive(Debug, Clone)]
enum Form {
    /// Q in ψ = [φ (N), α (N), U (K), effects (E)].
    Dense(DMatrix<f64>),
    /// Q_g = B + W M Wᵀ in g = [α (N), φ′ (N), U′ (K), effects (E)].
    Structured(Box<StructuredGeometry>),
    /// The band-limited closure design of heads between the positions (no rows).
    OffGrid(Box<OffGridGeometry>),
}

/// What adding one column to the model would do.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ColumnScore {
    /// xᵀe: the column against the current residuals.
    pub projection: f64,
    /// xᵀx − xᵀHx: the column's squared length outside the model's span.
    pub new_length_squared: f64,
    /// xᵀx.
    pub length_squared: f64,
}

impl ColumnScore {
    /// Whether the column adds a direction to the model (its part outside the span is at
    /// least `1e-9` of its length).
    pub fn is_new(&self) -> bool {
        self.length_squared > 0.0 && self.new_length_squared > 1e-9 * self.length_squared
    }

    /// The reduction of the residual sum of squares, Δ = (xᵀe)² / (xᵀx − xᵀHx); 0 when the
    /// column adds no direction.
    pub fn reduction(&self) -> f64 {
        if self.is_new() {
            self.projection * self.projection / self.new_length_squared
        } else {
            0.0
        }
    }

    /// The fraction of the column that lies outside the model's span, √((xᵀx − xᵀHx)/xᵀx).
    pub fn new_fraction(&self) -> f64 {
        if self.length_squared > 0.0 {
            (self.new_length_squared.max(0.0) / self.length_squared).sqrt()
        } else {
            0.0
        }
    }
}

impl FitGeometry {
    /// The geometry of `solution`, a fit of `set` with the effect `columns` (one value per
    /// reading each, in the order of the solution's effect terms): structured when the
    /// fit's cofactor is, dense otherwise.
    pub fn new(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        match solution.cofactor.as_structured() {
            Some(q) => {
                let (geometry, rows) = StructuredGeometry::new(solution, set, columns, q);
                Self {
                    form: Form::Structured(Box::new(geometry)),
                    rows,
                    nuisance: None,
                }
            }
            None => Self::dense(solution, set, columns),
        }
    }

    /// The geometry of `solution`, a fit of a self-calibration whose heads sit between
    /// the positions (`design`'s readings, with the effect `columns`); `None` when the
    /// fit is not that design's.
    pub(crate) fn off_grid(
        solution: &Solution,
        design: Arc<OffGridDesign>,
        columns: &[Vec<f64>],
    ) -> Option<Self> {
        let n = design.readings();
        let geometry = OffGridGeometry::new(solution, design, columns)?;
        Some(Self {
            form: Form::OffGrid(Box::new(geometry)),
            rows: vec![Vec::new(); n],
            nuisance: None,
        })
    }

    /// The dense geometry of `solution` whatever its cofactor (the reference the
    /// structured form is tested against; O((2N + K + E)²) memory).
    pub fn dense(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        let n = solution.faces;
        let layout = solution.layout;
        let size = layout.len();
        // Q in ψ: replace the β rows and columns by their prefix sums (φ = Σβ).
        let mut q = solution.cofactor.to_dense();
        for c in 0..size {
            let mut running = 0.0;
            for f in 0..n {
                running += q[(f, c)];
                q[(f, c)] = running;
            }
        }
        for r in 0..size {
            let mut running = 0.0;
            for f in 0..n {
                running += q[(r, f)];
                q[(r, f)] = running;
            }
        }
        let streams: Vec<(u32, u32)> = solution
            .setup_error
            .iter()
            .map(|s| (s.setup, s.ac))
            .collect();
        let rows = set
            .readings
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let mut row = Vec::with_capacity(3 + columns.len());
                row.push((r.face - 1, 1.0));
                row.push((layout.encoder(r.step % n), 1.0));
                if let Some(s) = streams.iter().position(|&k| k == (r.setup, r.ac)) {
                    row.push((layout.setup(s), 1.0));
                }
                for (j, x) in columns.iter().enumerate() {
                    if x[i] != 0.0 {
                        row.push((layout.effect(j), x[i]));
                    }
                }
                row
            })
            .collect();
        Self {
            form: Form::Dense(q),
            rows,
            nuisance: None,
        }
    }

    /// The number of readings the geometry's fit has.
    pub fn readings(&self) -> usize {
        self.rows.len()
    }

    /// Whether the geometry is the structured form (or the off-grid form, which is
    /// structured too).
    pub fn is_structured(&self) -> bool {
        matches!(self.form, Form::Structured(_) | Form::OffGrid(_))
    }

    /// The geometry of a fit of M·y with the stop nuisance `nuisance` taken out: the hat
    /// matrix of the full model is the fit's plus P_D.
    pub fn with_nuisance(mut self, nuisance: Option<StopNuisance>) -> Self {
        self.nuisance = nuisance;
        self
    }

    /// cᵢᵀ Q cⱼ: the fit's part of the hat matrix, without a stop nuisance's P_D.
    fn engine_hat(&self, i: usize, j: usize) -> f64 {
        match &self.form {
            Form::Dense(q) => {
                let mut h = 0.0;
                for &(a, va) in &self.rows[i] {
                    for &(b, vb) in &self.rows[j] {
                        h += va * vb * q[(a, b)];
                    }
                }
                h
            }
            Form::Structured(s) => s.hat(&self.rows[i], &self.rows[j]),
            Form::OffGrid(o) => o.hat(i, j),
        }
    }

    /// The length of the cofactor's vectors (ψ or g).
    fn size(&self) -> usize {
        match &self.form {
            Form::Dense(q) => q.nrows(),
            Form::Structured(s) => s.size(),
            Form::OffGrid(o) => o.size(),
        }
    }

    /// gᵀ Q g for a vector g in ψ or g.
    fn quadratic(&self, g: &[f64]) -> f64 {
        match &self.form {
            Form::Dense(q) => {
                let size = q.nrows();
                let touched: Vec<usize> = (0..size).filter(|&a| g[a] != 0.0).collect();
                let mut quad = 0.0;
                for &a in &touched {
                    let mut row = 0.0;
                    for &b in &touched {
                        row += q[(a, b)] * g[b];
                    }
                    quad += g[a] * row;
                }
                quad
            }
            Form::Structured(s) => {
                let qg = s.apply(g);
                g.iter().zip(&qg).map(|(a, b)| a * b).sum()
            }
            // the off-grid form has no rows: its callers go through `engine_fitted`
            Form::OffGrid(_) => 0.0,
        }
    }

    /// Q g for a vector g in ψ or g.
    fn product(&self, g: &[f64]) -> Vec<f64> {
        match &self.form {
            Form::Dense(q) => {
                let size = q.nrows();
                let mut out = vec![0.0; size];
                for (b, &gb) in g.iter().enumerate() {
                    if gb != 0.0 {
                        let column = &q.as_slice()[b * size..(b + 1) * size];
                        for (o, q) in out.iter_mut().zip(column) {
                            *o += q * gb;
                        }
                    }
                }
                out
            }
            Form::Structured(s) => s.apply(g),
            Form::OffGrid(_) => vec![0.0; g.len()],
        }
    }

    /// H·x without a stop nuisance's part: the fitted values of a fit of `x`.
    fn engine_fitted(&self, x: &[f64]) -> Vec<f64> {
        if let Form::OffGrid(o) = &self.form {
            return o.fitted(x);
        }
        let qg = self.product(&self.summed_rows(x));
        self.rows
            .iter()
            .map(|row| row.iter().map(|&(a, v)| v * qg[a]).sum())
            .collect()
    }

    /// xᵀHx without a stop nuisance's part.
    fn engine_quadratic(&self, x: &[f64]) -> f64 {
        if let Form::OffGrid(o) = &self.form {
            return x.iter().zip(o.fitted(x)).map(|(a, b)| a * b).sum();
        }
        self.quadratic(&self.summed_rows(x))
    }

    /// g = Σᵢ xᵢ cᵢ, the design rows summed with the column's values.
    fn summed_rows(&self, x: &[f64]) -> Vec<f64> {
        let mut g = vec![0.0; self.size()];
        for (i, &xi) in x.iter().enumerate() {
            if xi != 0.0 {
                for &(a, v) in &self.rows[i] {
                    g[a] += xi * v;
                }
            }
        }
        g
    }

    /// H_ij = cᵢᵀ Q cⱼ (plus P_D\[i, j\] with a stop nuisance): the covariance of the
    /// fitted values of readings i and j in units of σ² (the leverage when i = j).
    pub fn hat(&self, i: usize, j: usize) -> f64 {
        self.engine_hat(i, j) + self.nuisance.as_ref().map_or(0.0, |n| n.hat(i, j))
    }

    /// (I − H)·z: the part of a vector of readings `z` (one value per reading) the model
    /// does not span — the residuals a fit of `z` would leave, in O(n) plus one product
    /// with the cofactor. With z standard normal, (I − H)·z are the residuals of a run of
    /// pure noise of unit σ (H is a projection).
    pub fn residual_of(&self, z: &[f64]) -> Vec<f64> {
        let fitted = self.engine_fitted(z);
        let nuisance = self.nuisance.as_ref().map(|n| n.hat_times(z));
        z.iter()
            .zip(&fitted)
            .enumerate()
            .map(|(i, (&zi, fitted))| zi - fitted - nuisance.as_ref().map_or(0.0, |h| h[i]))
            .collect()
    }

    /// The leverage h_ii of every reading.
    pub fn leverage(&self) -> Vec<f64> {
        (0..self.rows.len()).map(|i| self.hat(i, i)).collect()
    }

    /// Scores a column x (one value per reading) against the residuals of the fit.
    pub fn score(&self, x: &[f64], residuals: &[f64]) -> ColumnScore {
        let (mut projection, mut length_squared) = (0.0, 0.0);
        for (i, &xi) in x.iter().enumerate() {
            if xi != 0.0 {
                projection += xi * residuals[i];
                length_squared += xi * xi;
            }
        }
        let mut quad = self.engine_quadratic(x);
        if let Some(n) = &self.nuisance {
            quad += n.quadratic(x, x);
        }
        ColumnScore {
            projection,
            new_length_squared: length_squared - quad,
            length_squared,
        }
    }

    /// The scores of the step columns of a time-ordered stream: for every k, the column
    /// that is 1 on the readings `order[k..]` and 0 elsewhere (a jump of the stream's zero
    /// from its k-th reading on). Element k of the result belongs to that column.
    pub fn suffix_scores(&self, order: &[usize], residuals: &[f64]) -> Vec<ColumnScore> {
        self.suffix_scores_with(order, residuals, &mut SuffixCache::new())
    }

    /// [`FitGeometry::suffix_scores`] with the structured form's suffix convolutions kept
    /// in `cache` from one fit to the next ([`SuffixCache`]): a diagnosis's rounds share
    /// them.
    pub fn suffix_scores_with(
        &self,
        order: &[usize],
        residuals: &[f64],
        cache: &mut SuffixCache,
    ) -> Vec<ColumnScore> {
        // the engine's gᵀ Q g of every suffix, then the stop nuisance's part
        let quads = match &self.form {
            Form::Dense(q) => dense_suffix_quads(q, &self.rows, order),
            Form::Structured(s) => s.suffix_quads(&self.rows, order, cache),
            Form::OffGrid(o) => o.suffix_quads(order),
        };
        let mut nuisance = self.nuisance.as_ref().map(StopNuisance::suffix);
        let mut scores = vec![
            ColumnScore {
                projection: 0.0,
                new_length_squared: 0.0,
                length_squared: 0.0,
            };
            order.len()
        ];
        let mut projection = 0.0;
        for (k, &i) in order.iter().enumerate().rev() {
            let nuisance_quad = nuisance.as_mut().map_or(0.0, |n| n.add(i));
            projection += residuals[i];
            let length_squared = (order.len() - k) as f64;
            scores[k] = ColumnScore {
                projection,
                new_length_squared: length_squared - quads[k] - nuisance_quad,
                length_squared,
            };
        }
        scores
    }
}

/// The dense form's gᵀ Q g of every suffix `order[k..]` (element k): w = Q g kept for the
/// running suffix sum g of the design rows, O(P) per reading.
fn dense_suffix_quads(q: &DMatrix<f64>, rows: &[Vec<(usize, f64)>], order: &[usize]) -> Vec<f64> {
    let size = q.nrows();
    let mut w = vec![0.0; size];
    let mut quad = 0.0;
    let mut quads = vec![0.0; order.len()];
    for (k, &i) in order.iter().enumerate().rev() {
        let row = &rows[i];
        // quad += 2 cᵀ w + cᵀ Q c, then w += Q c
        let c_w: f64 = row.iter().map(|&(a, v)| v * w[a]).sum();
        let mut c_q_c = 0.0;
        for &(a, va) in row {
            for &(b, vb) in row {
                c_q_c += va * vb * q[(a, b)];
            }
        }
        quad += 2.0 * c_w + c_q_c;
        let q = q.as_slice();
        for &(a, v) in row {
            // Q is symmetric and stored by columns: column a is contiguous.
            for (t, q) in w.iter_mut().zip(&q[a * size..(a + 1) * size]) {
                *t += v * q;
            }
        }
        quads[k] = quad;
    }
    quads
}

/// What adding a block of columns to the model together would do.
#[derive(Debug, Clone, PartialEq)]
pub struct BlockScore {
    /// The reduction of the residual sum of squares, eᵀX̃(X̃ᵀX̃)⁺X̃ᵀe with X̃ the block's
    /// part outside the model's span (X̃ᵀe = Xᵀe, since e is orthogonal to that span).
    pub reduction: f64,
    /// The number of directions the block adds (its rank outside the span).
    pub rank: usize,
    /// The values the block's columns would have if added: (X̃ᵀX̃)⁺Xᵀe.
    pub values: Vec<f64>,
}

impl FitGeometry {
    /// Scores a block of columns (one value per reading each) against the residuals of
    /// the fit: the reduction of the residual sum of squares if they were added together,
    /// and how many directions they add. A direction whose squared length outside the
    /// span is below `1e-9` of the block's largest squared length adds nothing.
    pub fn score_block(&self, columns: &[Vec<f64>], residuals: &[f64]) -> BlockScore {
        self.score_block_with_gram(columns, self.projected_gram(columns), residuals)
    }

    /// [`FitGeometry::score_block`] with the block's [`FitGeometry::projected_gram`]
    /// given (a block that begins another block has the leading part of its Gram matrix).
    pub fn score_block_with_gram(
        &self,
        columns: &[Vec<f64>],
        gram: nalgebra::DMatrix<f64>,
        residuals: &[f64],
    ) -> BlockScore {
        let m = columns.len();
        let mut projection = nalgebra::DVector::<f64>::zeros(m);
        for a in 0..m {
            projection[a] = columns[a].iter().zip(residuals).map(|(x, e)| x * e).sum();
        }
        let scale = (0..m)
            .map(|a| columns[a].iter().map(|x| x * x).sum::<f64>())
            .fold(0.0, f64::max);
        let eigen = nalgebra::SymmetricEigen::new(gram);
        let mut values = nalgebra::DVector::<f64>::zeros(m);
        let (mut reduction, mut rank) = (0.0, 0);
        for k in 0..m {
            let lambda = eigen.eigenvalues[k];
            if scale > 0.0 && lambda > 1e-9 * scale {
                let v = eigen.eigenvectors.column(k).into_owned();
                let c = v.dot(&projection);
                reduction += c * c / lambda;
                values += v * (c / lambda);
                rank += 1;
            }
        }
        BlockScore {
            reduction,
            rank,
            values: values.iter().copied().collect(),
        }
    }
}

impl FitGeometry {
    /// The Gram matrix X̃ᵀX̃ = XᵀX − XᵀHX of a block of columns (one value per reading
    /// each) projected off the model's span: what the block adds to the model, whatever
    /// the readings (a design's power to see the block, and how far two columns can be
    /// told apart, follow from it alone).
    pub fn projected_gram(&self, columns: &[Vec<f64>]) -> nalgebra::DMatrix<f64> {
        let m = columns.len();
        // xᵀ H y as gₓᵀ Q g_y through the sparse rows, or xᵀ (H y) off the grid
        let (g, qg): (Vec<Vec<f64>>, Vec<Vec<f64>>) = match &self.form {
            Form::OffGrid(o) => (
                columns.to_vec(),
                columns.iter().map(|x| o.fitted(x)).collect(),
            ),
            _ => {
                let g: Vec<Vec<f64>> = columns.iter().map(|x| self.summed_rows(x)).collect();
                let qg = g.iter().map(|g| self.product(g)).collect();
                (g, qg)
            }
        };
        let mut gram = nalgebra::DMatrix::<f64>::zeros(m, m);
        for a in 0..m {
            for b in a..m {
                let xx: f64 = columns[a].iter().zip(&columns[b]).map(|(x, y)| x * y).sum();
                let mut xhx: f64 = g[a].iter().zip(&qg[b]).map(|(x, y)| x * y).sum();
                if let Some(n) = &self.nuisance {
                    xhx += n.quadratic(&columns[a], &columns[b]);
                }
                gram[(a, b)] = xx - xhx;
                gram[(b, a)] = xx - xhx;
            }
        }
        gram
    }
}
