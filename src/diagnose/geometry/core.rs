//! The core of a fit's geometry: the hat matrix H of the fit itself, from its cofactor
//! (dense in ψ, structured in g, or the off-grid design's) and the sparse design row of
//! every reading, plus a self-calibration's stop nuisance P_D. What depends only on the
//! fit — every reading's leverage, every stream's suffix quadratics — is formed once and
//! kept: a diagnosis extends one core with its terms' columns round after round
//! ([`super::FitGeometry::with_columns`]).

use std::sync::{Arc, Mutex, OnceLock};

use nalgebra::DMatrix;
use rayon::prelude::*;

use super::off_grid::OffGridGeometry;
use super::rows::Rows;
use super::structured::{StructuredGeometry, SuffixCache};
use super::{ColumnScore, StopNuisance, dot};
use crate::measurement::MeasurementSet;
use crate::selfcal::OffGridDesign;
use crate::solve::Solution;

/// The hat-matrix geometry of one fit (module documentation).
#[derive(Debug)]
pub(super) struct Core {
    /// The cofactor.
    form: Form,
    /// The design row of every reading: (index in ψ or g, coefficient).
    rows: Rows,
    /// A self-calibration's table error at every stop, taken out of the fit
    /// ([`StopNuisance`]): its P_D is added to the hat matrix.
    nuisance: Option<StopNuisance>,
    /// A weighted fit's whitening factors (its rows are whitened; a stream's suffix
    /// column is wᵢ on the suffix).
    weights: Option<Arc<[f64]>>,
    /// Every reading's leverage, once formed.
    leverage: OnceLock<Vec<f64>>,
    /// The suffix quadratics of the streams met so far: (order of the readings, them).
    suffix: Mutex<Vec<(Vec<usize>, Arc<SuffixQuads>)>>,
    /// The columns added to the fit's model so far with their (I − H)·x: (a fingerprint
    /// of the column, it, its part outside the span).
    #[allow(clippy::type_complexity)]
    outside: Mutex<Vec<(u64, Vec<f64>, Vec<f64>)>>,
}

/// The most added columns a core keeps with their part outside its span (a diagnosis
/// meets a few terms and their alternatives; the oldest is let go, a miss only costs the
/// product again). Each holds two vectors of the readings: 16 of them add at most 32
/// readings' worth of memory (67 MB at 262 144 readings), beside the diagnosis's own.
const KEPT_COLUMNS: usize = 16;

/// The quadratics of every suffix of one stream's readings under a core (element k for
/// the suffix from the stream's k-th reading on).
#[derive(Debug)]
pub(super) struct SuffixQuads {
    /// The engine's gᵀ Q g.
    pub engine: Vec<f64>,
    /// The stop nuisance's xᵀ P_D x, with one.
    pub nuisance: Option<Vec<f64>>,
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

impl Core {
    /// A core of the cofactor `form` and the design `rows`, without a stop nuisance.
    fn of(form: Form, rows: Rows) -> Self {
        Core {
            form,
            rows,
            nuisance: None,
            weights: None,
            leverage: OnceLock::new(),
            suffix: Mutex::new(Vec::new()),
            outside: Mutex::new(Vec::new()),
        }
    }

    /// A copy of this core with nothing formed yet (its kept leverages and suffix
    /// quadratics are not copied).
    pub(super) fn detached(&self) -> Self {
        Core {
            nuisance: self.nuisance.clone(),
            weights: self.weights.clone(),
            ..Self::of(self.form.clone(), self.rows.clone())
        }
    }

    /// The core of a fit of M·y with the stop nuisance `nuisance` taken out: the hat
    /// matrix of the full model is the fit's plus P_D.
    pub(super) fn with_nuisance(mut self, nuisance: Option<StopNuisance>) -> Self {
        self.nuisance = nuisance;
        self.leverage = OnceLock::new();
        self.suffix = Mutex::new(Vec::new());
        self.outside = Mutex::new(Vec::new());
        self
    }

    /// The geometry of `solution`, a fit of `set` with the effect `columns` (one value per
    /// reading each, in the order of the solution's effect terms): structured when the
    /// fit's cofactor is, dense otherwise.
    pub(super) fn new(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        match solution.cofactor.as_structured() {
            Some(q) => {
                let (geometry, rows) = StructuredGeometry::new(solution, set, columns, q);
                Self::of(Form::Structured(Box::new(geometry)), rows)
            }
            None => Self::dense(solution, set, columns),
        }
    }

    /// The geometry of `solution`, a fit of a self-calibration whose heads sit between
    /// the positions (`design`'s readings, with the effect `columns`); `None` when the
    /// fit is not that design's.
    pub(super) fn off_grid(
        solution: &Solution,
        design: Arc<OffGridDesign>,
        columns: &[Vec<f64>],
    ) -> Option<Self> {
        let n = design.readings();
        let geometry = OffGridGeometry::new(solution, design, columns)?;
        let mut rows = Rows::with_capacity(n, 0);
        for _ in 0..n {
            rows.end_row();
        }
        Some(Self::of(Form::OffGrid(Box::new(geometry)), rows))
    }

    /// The dense geometry of `solution` whatever its cofactor (the reference the
    /// structured form is tested against; O((2N + K + E)²) memory).
    pub(super) fn dense(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        Self::dense_weighted(solution, set, columns, None)
    }

    /// [`Core::dense`] of a weighted fit: reading i's row of α, φ and U times
    /// `weights[i]` (the whitened design), the effect `columns` as given (whitened).
    pub(super) fn dense_weighted(
        solution: &Solution,
        set: &MeasurementSet,
        columns: &[Vec<f64>],
        weights: Option<Arc<[f64]>>,
    ) -> Self {
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
        let mut rows = Rows::with_capacity(set.readings.len(), 3 + columns.len());
        for (i, r) in set.readings.iter().enumerate() {
            let w = weights.as_ref().map_or(1.0, |w| w[i]);
            rows.push(r.face - 1, w);
            rows.push(layout.encoder(r.step % n), w);
            if let Some(s) = streams.iter().position(|&k| k == (r.setup, r.ac)) {
                rows.push(layout.setup(s), w);
            }
            for (j, x) in columns.iter().enumerate() {
                if x[i] != 0.0 {
                    rows.push(layout.effect(j), x[i]);
                }
            }
            rows.end_row();
        }
        Core {
            weights,
            ..Self::of(Form::Dense(q), rows)
        }
    }

    /// The number of readings the geometry's fit has.
    pub(super) fn readings(&self) -> usize {
        self.rows.len()
    }

    /// Whether the geometry is the structured form (or the off-grid form, which is
    /// structured too).
    pub(super) fn is_structured(&self) -> bool {
        matches!(self.form, Form::Structured(_) | Form::OffGrid(_))
    }

    /// cᵢᵀ Q cⱼ: the fit's part of the hat matrix, without a stop nuisance's P_D.
    pub(super) fn engine_hat(&self, i: usize, j: usize) -> f64 {
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
    pub(super) fn size(&self) -> usize {
        match &self.form {
            Form::Dense(q) => q.nrows(),
            Form::Structured(s) => s.size(),
            Form::OffGrid(o) => o.size(),
        }
    }

    /// gᵀ Q g for a vector g in ψ or g.
    pub(super) fn quadratic(&self, g: &[f64]) -> f64 {
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
                dot(g, &qg)
            }
            // the off-grid form has no rows: its callers go through `engine_fitted`
            Form::OffGrid(_) => 0.0,
        }
    }

    /// Q g for a vector g in ψ or g.
    pub(super) fn product(&self, g: &[f64]) -> Vec<f64> {
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
    pub(super) fn engine_fitted(&self, x: &[f64]) -> Vec<f64> {
        if let Form::OffGrid(o) = &self.form {
            return o.fitted(x);
        }
        let qg = self.product(&self.summed_rows(x));
        (0..self.rows.len())
            .map(|i| self.rows[i].iter().map(|&(a, v)| v * qg[a]).sum())
            .collect()
    }

    /// xᵀHx without a stop nuisance's part.
    pub(super) fn engine_quadratic(&self, x: &[f64]) -> f64 {
        if let Form::OffGrid(o) = &self.form {
            return dot(x, &o.fitted(x));
        }
        self.quadratic(&self.summed_rows(x))
    }

    /// g = Σᵢ xᵢ cᵢ, the design rows summed with the column's values.
    pub(super) fn summed_rows(&self, x: &[f64]) -> Vec<f64> {
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
    pub(super) fn hat(&self, i: usize, j: usize) -> f64 {
        self.engine_hat(i, j) + self.nuisance.as_ref().map_or(0.0, |n| n.hat(i, j))
    }

    /// (I − H)·z: the part of a vector of readings `z` (one value per reading) the model
    /// does not span — the residuals a fit of `z` would leave, in O(n) plus one product
    /// with the cofactor. With z standard normal, (I − H)·z are the residuals of a run of
    /// pure noise of unit σ (H is a projection).
    pub(super) fn residual_of(&self, z: &[f64]) -> Vec<f64> {
        let fitted = self.engine_fitted(z);
        let nuisance = self.nuisance.as_ref().map(|n| n.hat_times(z));
        z.iter()
            .zip(&fitted)
            .enumerate()
            .map(|(i, (&zi, fitted))| zi - fitted - nuisance.as_ref().map_or(0.0, |h| h[i]))
            .collect()
    }

    /// (I − H)·x of a column added to the fit's model ([`Core::residual_of`]), kept for
    /// the next call with the same column (to the bit): a diagnosis adds its terms to
    /// one core round after round.
    pub(super) fn outside_of(&self, x: &[f64]) -> Vec<f64> {
        let fingerprint = x
            .iter()
            .fold(x.len() as u64, |h, v| h.rotate_left(5) ^ v.to_bits());
        let same = |(f, column, _): &(u64, Vec<f64>, Vec<f64>)| {
            *f == fingerprint
                && column.len() == x.len()
                && column
                    .iter()
                    .zip(x)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
        };
        if let Ok(kept) = self.outside.lock()
            && let Some((_, _, outside)) = kept.iter().find(|entry| same(entry))
        {
            return outside.clone();
        }
        let outside = self.residual_of(x);
        if let Ok(mut kept) = self.outside.lock() {
            if kept.len() == KEPT_COLUMNS {
                kept.remove(0);
            }
            kept.push((fingerprint, x.to_vec(), outside.clone()));
        }
        outside
    }

    /// Scores a column x (one value per reading) against the residuals of the fit.
    pub(super) fn score(&self, x: &[f64], residuals: &[f64]) -> ColumnScore {
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

    /// The leverage h_ii of every reading, formed at the first call (in chunks that
    /// idle threads take: a round forms it beside its other candidates).
    pub(super) fn leverage(&self) -> &[f64] {
        self.leverage.get_or_init(|| {
            (0..self.rows.len())
                .into_par_iter()
                .with_min_len(1024)
                .map(|i| self.hat(i, i))
                .collect()
        })
    }

    /// The engine's gᵀ Q g and the stop nuisance's xᵀ P_D x of every suffix
    /// `order[k..]` of a time-ordered stream (element k): formed at the first call for
    /// `order` (with the structured form's convolution from `cache`), kept for the next.
    pub(super) fn suffix_quads(
        &self,
        order: &[usize],
        cache: &mut SuffixCache,
    ) -> Arc<SuffixQuads> {
        if let Ok(kept) = self.suffix.lock()
            && let Some((_, quads)) = kept.iter().find(|(o, _)| o.as_slice() == order)
        {
            return Arc::clone(quads);
        }
        let engine = match &self.form {
            Form::Dense(q) => dense_suffix_quads(q, &self.rows, order, self.weights.as_deref()),
            Form::Structured(s) => s.suffix_quads(&self.rows, order, cache),
            Form::OffGrid(o) => o.suffix_quads(order),
        };
        let nuisance = self.nuisance.as_ref().map(|n| {
            let mut running = n.suffix();
            let mut quads = vec![0.0; order.len()];
            for (k, &i) in order.iter().enumerate().rev() {
                quads[k] = running.add(i);
            }
            quads
        });
        let quads = Arc::new(SuffixQuads { engine, nuisance });
        if let Ok(mut kept) = self.suffix.lock() {
            kept.push((order.to_vec(), Arc::clone(&quads)));
        }
        quads
    }
}

impl Core {
    /// The Gram matrix X̃ᵀX̃ = XᵀX − XᵀHX of a block of columns (one value per reading
    /// each) projected off the model's span: what the block adds to the model, whatever
    /// the readings (a design's power to see the block, and how far two columns can be
    /// told apart, follow from it alone).
    pub(super) fn projected_gram<C: AsRef<[f64]>>(&self, columns: &[C]) -> nalgebra::DMatrix<f64> {
        let m = columns.len();
        let columns: Vec<&[f64]> = columns.iter().map(AsRef::as_ref).collect();
        // xᵀ H y as gₓᵀ Q g_y through the sparse rows, or xᵀ (H y) off the grid
        let (g, qg): (Vec<Vec<f64>>, Vec<Vec<f64>>) = match &self.form {
            Form::OffGrid(o) => (
                columns.iter().map(|x| x.to_vec()).collect(),
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
                let xx = dot(columns[a], columns[b]);
                let mut xhx = dot(&g[a], &qg[b]);
                if let Some(n) = &self.nuisance {
                    xhx += n.quadratic(columns[a], columns[b]);
                }
                gram[(a, b)] = xx - xhx;
                gram[(b, a)] = xx - xhx;
            }
        }
        gram
    }
}

/// The dense form's gᵀ Q g of every suffix `order[k..]` (element k): w = Q g kept for the
/// running suffix sum g of the design rows, O(P) per reading.
/// With `weights` (a weighted fit's whitened rows), the suffix's whitened column is wᵢ
/// on the suffix: each row enters times its wᵢ.
fn dense_suffix_quads(
    q: &DMatrix<f64>,
    rows: &Rows,
    order: &[usize],
    weights: Option<&[f64]>,
) -> Vec<f64> {
    let size = q.nrows();
    let mut w = vec![0.0; size];
    let mut quad = 0.0;
    let mut quads = vec![0.0; order.len()];
    let mut scaled: Vec<(usize, f64)> = Vec::new();
    for (k, &i) in order.iter().enumerate().rev() {
        let row: &[(usize, f64)] = match weights {
            Some(weights) => {
                scaled.clear();
                scaled.extend(rows[i].iter().map(|&(a, v)| (a, weights[i] * v)));
                &scaled
            }
            None => &rows[i],
        };
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
