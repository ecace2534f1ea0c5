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
//!
//! A geometry is a *core* — the fit's own hat matrix, in one of these forms, with what
//! depends on it alone (leverages, suffix quadratics) formed once (`core.rs`) — and the
//! columns added to that fit's model since (`added.rs`): H′ = H + U Uᵀ. A diagnosis forms
//! the core of its base fit once and adds its terms round after round
//! ([`FitGeometry::with_columns`]).

mod added;
mod core;
mod off_grid;
mod rows;
mod structured;

use std::sync::Arc;

use super::nuisance::StopNuisance;
use crate::measurement::MeasurementSet;
use crate::selfcal::OffGridDesign;
use crate::solve::Solution;
use added::Added;
use core::Core;
pub use structured::SuffixCache;

/// aᵀb (over the shorter of the two), by four running sums in a fixed order: the same
/// bits on every machine, and about four times the speed of one running sum, whose
/// additions wait on each other. The one dot product of the geometry's reading-length
/// vectors.
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let (a_quads, b_quads) = (a.chunks_exact(4), b.chunks_exact(4));
    let rest: f64 = a_quads
        .remainder()
        .iter()
        .zip(b_quads.remainder())
        .map(|(x, y)| x * y)
        .sum();
    let mut sums = [0.0_f64; 4];
    for (x, y) in a_quads.zip(b_quads) {
        for lane in 0..4 {
            sums[lane] += x[lane] * y[lane];
        }
    }
    (sums[0] + sums[1]) + (sums[2] + sums[3]) + rest
}

/// The hat-matrix geometry of one fit: the core of a fit (its cofactor, dense in ψ or
/// structured in g, and the sparse design row of every reading) and the columns added to
/// its model since ([`FitGeometry::with_columns`]). Clones share the core.
#[derive(Debug, Clone)]
pub struct FitGeometry {
    /// The fit's own geometry.
    core: Arc<Core>,
    /// The columns added to its model.
    added: Added,
    /// A weighted fit's whitening factors, one per reading (its rows, columns and
    /// residuals are the whitened ones; a jump's suffix column is wᵢ on the suffix).
    weights: Option<Arc<[f64]>>,
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
    /// A geometry of `core` alone.
    fn of(core: Core) -> Self {
        Self {
            core: Arc::new(core),
            added: Added::default(),
            weights: None,
        }
    }

    /// The geometry of `solution`, a weighted fit of `set` (reading i weighing
    /// `weights[i]`², [`crate::solve::dense::dense_weighted_least_squares`]) with the
    /// whitened effect `columns`: dense, in whitened quantities. Every vector given to it
    /// (a column, the residuals) is a whitened one; a jump's suffix column is wᵢ on the
    /// suffix ([`FitGeometry::suffix_scores`]).
    pub fn weighted(
        solution: &Solution,
        set: &MeasurementSet,
        columns: &[Vec<f64>],
        weights: Arc<[f64]>,
    ) -> Self {
        let mut geometry = Self::of(Core::dense_weighted(
            solution,
            set,
            columns,
            Some(Arc::clone(&weights)),
        ));
        geometry.weights = Some(weights);
        geometry
    }

    /// The geometry of `solution`, a fit of `set` with the effect `columns` (one value per
    /// reading each, in the order of the solution's effect terms): structured when the
    /// fit's cofactor is, dense otherwise.
    pub fn new(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        Self::of(Core::new(solution, set, columns))
    }

    /// The geometry of `solution`, a fit of a self-calibration whose heads sit between
    /// the positions (`design`'s readings, with the effect `columns`); `None` when the
    /// fit is not that design's.
    pub(crate) fn off_grid(
        solution: &Solution,
        design: Arc<OffGridDesign>,
        columns: &[Vec<f64>],
    ) -> Option<Self> {
        Core::off_grid(solution, design, columns).map(Self::of)
    }

    /// The dense geometry of `solution` whatever its cofactor (the reference the
    /// structured form is tested against; O((2N + K + E)²) memory).
    pub fn dense(solution: &Solution, set: &MeasurementSet, columns: &[Vec<f64>]) -> Self {
        Self::of(Core::dense(solution, set, columns))
    }

    /// The number of readings the geometry's fit has.
    pub fn readings(&self) -> usize {
        self.core.readings()
    }

    /// Whether the geometry is the structured form (or the off-grid form, which is
    /// structured too).
    pub fn is_structured(&self) -> bool {
        self.core.is_structured()
    }

    /// The geometry of a fit of M·y with the stop nuisance `nuisance` taken out: the hat
    /// matrix of the full model is the fit's plus P_D. Columns added before are dropped
    /// (add them after).
    pub fn with_nuisance(self, nuisance: Option<StopNuisance>) -> Self {
        let weights = self.weights;
        let core = match Arc::try_unwrap(self.core) {
            Ok(core) => core,
            Err(shared) => shared.detached(),
        };
        Self {
            weights,
            ..Self::of(core.with_nuisance(nuisance))
        }
    }

    /// The geometry of this fit's model with the effect `columns` (one value per reading
    /// each) added: H + U Uᵀ with U an orthonormal basis of (I − H)·columns (`added.rs`),
    /// what a refit with them would give, to the round-off, for one product with the
    /// cofactor per column. A column whose part outside the model is below 1e-9 of its
    /// squared length adds nothing. The core is shared, not copied.
    pub fn with_columns(&self, columns: &[Vec<f64>]) -> Self {
        let mut added = self.added.clone();
        for x in columns {
            added.push(x, self.core.outside_of(x));
        }
        Self {
            core: Arc::clone(&self.core),
            added,
            weights: self.weights.clone(),
        }
    }

    /// H_ij = cᵢᵀ Q cⱼ (plus P_D\[i, j\] with a stop nuisance, plus the added columns'
    /// part): the covariance of the fitted values of readings i and j in units of σ²
    /// (the leverage when i = j).
    pub fn hat(&self, i: usize, j: usize) -> f64 {
        let h = self.core.hat(i, j);
        if self.added.is_empty() {
            h
        } else {
            h + self.added.hat(i, j)
        }
    }

    /// (I − H)·z: the part of a vector of readings `z` (one value per reading) the model
    /// does not span — the residuals a fit of `z` would leave, in O(n) plus one product
    /// with the cofactor. With z standard normal, (I − H)·z are the residuals of a run of
    /// pure noise of unit σ (H is a projection).
    pub fn residual_of(&self, z: &[f64]) -> Vec<f64> {
        let mut residual = self.core.residual_of(z);
        self.added.take_out(z, &mut residual);
        residual
    }

    /// [`FitGeometry::residual_of`] of a vector the core keeps its part of for the next
    /// call (the readings a diagnosis screens alternatives with, the same every time).
    pub fn residual_of_kept(&self, z: &[f64]) -> Vec<f64> {
        let mut residual = self.core.outside_of(z);
        self.added.take_out(z, &mut residual);
        residual
    }

    /// The leverage h_ii of every reading.
    pub fn leverage(&self) -> Vec<f64> {
        let mut leverage = self.core.leverage().to_vec();
        self.added.add_leverage(&mut leverage);
        leverage
    }

    /// Scores a column x (one value per reading) against the residuals of the fit.
    pub fn score(&self, x: &[f64], residuals: &[f64]) -> ColumnScore {
        let mut score = self.core.score(x, residuals);
        if !self.added.is_empty() {
            score.new_length_squared -= self.added.quadratic(x);
        }
        score
    }

    /// The scores of the step columns of a time-ordered stream: for every k, the column
    /// that is 1 on the readings `order[k..]` and 0 elsewhere (a jump of the stream's zero
    /// from its k-th reading on). Element k of the result belongs to that column.
    pub fn suffix_scores(&self, order: &[usize], residuals: &[f64]) -> Vec<ColumnScore> {
        self.suffix_scores_with(order, residuals, &mut SuffixCache::new())
    }

    /// [`FitGeometry::suffix_scores`] with the structured form's suffix convolutions kept
    /// in `cache` from one fit to the next ([`SuffixCache`]): a diagnosis's rounds share
    /// them (and its geometries, sharing one core, the core's suffix quadratics).
    pub fn suffix_scores_with(
        &self,
        order: &[usize],
        residuals: &[f64],
        cache: &mut SuffixCache,
    ) -> Vec<ColumnScore> {
        let weights = self.weights.as_deref();
        let weight = |i: usize| weights.map_or(1.0, |w| w[i]);
        let core = self.core.suffix_quads(order, cache);
        let added = (!self.added.is_empty()).then(|| self.added.suffix_quads(order, weights));
        let mut scores = vec![
            ColumnScore {
                projection: 0.0,
                new_length_squared: 0.0,
                length_squared: 0.0,
            };
            order.len()
        ];
        let (mut projection, mut length_squared) = (0.0, 0.0);
        for (k, &i) in order.iter().enumerate().rev() {
            projection += weight(i) * residuals[i];
            length_squared += weight(i) * weight(i);
            let nuisance_quad = core.nuisance.as_ref().map_or(0.0, |q| q[k]);
            let mut new_length_squared = length_squared - core.engine[k] - nuisance_quad;
            if let Some(added) = &added {
                new_length_squared -= added[k];
            }
            scores[k] = ColumnScore {
                projection,
                new_length_squared,
                length_squared,
            };
        }
        scores
    }

    /// The Gram matrix X̃ᵀX̃ = XᵀX − XᵀHX of a block of columns (one value per reading
    /// each) projected off the model's span: what the block adds to the model, whatever
    /// the readings (a design's power to see the block, and how far two columns can be
    /// told apart, follow from it alone).
    pub fn projected_gram<C: AsRef<[f64]>>(&self, columns: &[C]) -> nalgebra::DMatrix<f64> {
        self.projected_gram_from(self.core.projected_gram(columns), columns)
    }

    /// Whether this geometry and `other` extend the same core (one fit's geometry, shared
    /// by the geometries [`FitGeometry::with_columns`] makes of it): what a
    /// [`FitGeometry::core_projected_gram`] of one holds for the other.
    pub fn same_core(&self, other: &FitGeometry) -> bool {
        Arc::ptr_eq(&self.core, &other.core)
    }

    /// The Gram matrix of `columns` projected off the span of the fit this geometry
    /// extends (its core, without the columns added since): the same for every geometry
    /// of one diagnosis, so a search forms it once per block and gives it to
    /// [`FitGeometry::projected_gram_from`].
    pub fn core_projected_gram<C: AsRef<[f64]>>(&self, columns: &[C]) -> nalgebra::DMatrix<f64> {
        self.core.projected_gram(columns)
    }

    /// [`FitGeometry::projected_gram`] from the block's [`FitGeometry::core_projected_gram`]
    /// `core_gram`: the added columns' part taken off, O(n) per column and added column.
    pub fn projected_gram_from<C: AsRef<[f64]>>(
        &self,
        core_gram: nalgebra::DMatrix<f64>,
        columns: &[C],
    ) -> nalgebra::DMatrix<f64> {
        if self.added.is_empty() {
            core_gram
        } else {
            core_gram - self.added.gram(columns)
        }
    }
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
    pub fn score_block<C: AsRef<[f64]>>(&self, columns: &[C], residuals: &[f64]) -> BlockScore {
        self.score_block_with_gram(columns, self.projected_gram(columns), residuals)
    }

    /// [`FitGeometry::score_block`] with the block's [`FitGeometry::projected_gram`]
    /// given (a block that begins another block has the leading part of its Gram matrix).
    pub fn score_block_with_gram<C: AsRef<[f64]>>(
        &self,
        columns: &[C],
        gram: nalgebra::DMatrix<f64>,
        residuals: &[f64],
    ) -> BlockScore {
        let m = columns.len();
        let mut projection = nalgebra::DVector::<f64>::zeros(m);
        for a in 0..m {
            projection[a] = columns[a]
                .as_ref()
                .iter()
                .zip(residuals)
                .map(|(x, e)| x * e)
                .sum();
        }
        let scale = (0..m)
            .map(|a| columns[a].as_ref().iter().map(|x| x * x).sum::<f64>())
            .fold(0.0, f64::max);
        BlockScore::of(projection, scale, gram)
    }

    /// Uᵀx: column `x` against the orthonormal basis of the columns added to the fit
    /// ([`FitGeometry::with_columns`]; empty when none is). With them a block's
    /// [`FitGeometry::projected_gram_from`] is its core Gram matrix less the products of
    /// its columns' coordinates ([`FitGeometry::projected_gram_from_coordinates`]).
    pub fn added_coordinates(&self, x: &[f64]) -> Vec<f64> {
        self.added.coordinates(x)
    }

    /// [`FitGeometry::projected_gram_from`] from the block's columns'
    /// [`FitGeometry::added_coordinates`]: O(m² · added) instead of a pass over the
    /// readings per column.
    pub fn projected_gram_from_coordinates(
        core_gram: nalgebra::DMatrix<f64>,
        coordinates: &[&[f64]],
    ) -> nalgebra::DMatrix<f64> {
        let m = coordinates.len();
        let dot = |a: &[f64], b: &[f64]| -> f64 { a.iter().zip(b).map(|(x, y)| x * y).sum() };
        if coordinates.iter().all(|c| c.is_empty()) {
            return core_gram;
        }
        core_gram - nalgebra::DMatrix::from_fn(m, m, |a, b| dot(coordinates[a], coordinates[b]))
    }
}

impl BlockScore {
    /// The score of a block from its columns against the residuals (Xᵀe, `projection`),
    /// their largest squared length `scale` and their projected Gram matrix `gram`.
    pub fn of(
        projection: nalgebra::DVector<f64>,
        scale: f64,
        gram: nalgebra::DMatrix<f64>,
    ) -> BlockScore {
        let m = projection.len();
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
