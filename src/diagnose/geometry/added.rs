//! Columns added to a fit's model without refitting its geometry.
//!
//! The hat matrix of a model extended by columns X is the old one plus the projection on
//! the part of X the old model does not span:
//!
//! ```text
//! H′ = H + U Uᵀ,   U an orthonormal basis of (I − H)·X
//! ```
//!
//! (H′ projects on span(old, X) = span(old) ⊕ span((I − H)X), an orthogonal sum). So a
//! diagnosis forms the geometry of its base fit once and, round after round, only the few
//! vectors U of its terms (one product with the cofactor per column, then Gram–Schmidt):
//! a leverage gains Σₖ uₖ[i]², a column's xᵀH′x gains Σₖ (uₖᵀx)², a suffix's gains the
//! squares of the running sums of the uₖ — O(n) per term instead of a new geometry.

use super::dot;

/// An orthonormal basis U of the added columns' part outside a core's span, one vector
/// per reading each.
#[derive(Debug, Clone, Default)]
pub(super) struct Added {
    /// The basis vectors uₖ.
    directions: Vec<Vec<f64>>,
}

/// A column adds a direction when the part of it outside the model keeps more than this
/// fraction of its squared length (as [`super::ColumnScore::is_new`]).
const NEW_DIRECTION: f64 = 1e-9;

impl Added {
    /// Whether no column is added.
    pub(super) fn is_empty(&self) -> bool {
        self.directions.is_empty()
    }

    /// The basis with one more column `x`, given `outside`, its part outside the core's
    /// span ((I − H)x): orthogonalised against the basis (twice, for the round-off) and
    /// kept when it adds a direction.
    pub(super) fn push(&mut self, x: &[f64], mut outside: Vec<f64>) {
        let length_squared = dot(x, x);
        for _ in 0..2 {
            for u in &self.directions {
                let c = dot(u, &outside);
                for (o, v) in outside.iter_mut().zip(u) {
                    *o -= c * v;
                }
            }
        }
        let norm_squared = dot(&outside, &outside);
        if length_squared > 0.0 && norm_squared > NEW_DIRECTION * length_squared {
            let scale = 1.0 / norm_squared.sqrt();
            outside.iter_mut().for_each(|v| *v *= scale);
            self.directions.push(outside);
        }
    }

    /// (U Uᵀ)\[i, j\].
    pub(super) fn hat(&self, i: usize, j: usize) -> f64 {
        self.directions.iter().map(|u| u[i] * u[j]).sum()
    }

    /// Adds (U Uᵀ)\[i, i\] to every leverage.
    pub(super) fn add_leverage(&self, leverage: &mut [f64]) {
        for u in &self.directions {
            for (h, v) in leverage.iter_mut().zip(u) {
                *h += v * v;
            }
        }
    }

    /// Uᵀx.
    pub(super) fn coordinates(&self, x: &[f64]) -> Vec<f64> {
        self.directions.iter().map(|u| dot(u, x)).collect()
    }

    /// xᵀ U Uᵀ x.
    pub(super) fn quadratic(&self, x: &[f64]) -> f64 {
        self.coordinates(x).iter().map(|c| c * c).sum()
    }

    /// Takes U Uᵀ z out of `residual` ((I − H)z becomes (I − H′)z).
    pub(super) fn take_out(&self, z: &[f64], residual: &mut [f64]) {
        for u in &self.directions {
            let c = dot(u, z);
            for (r, v) in residual.iter_mut().zip(u) {
                *r -= c * v;
            }
        }
    }

    /// (Uᵀxₐ)·(Uᵀx_b) for every pair of `columns`: what the added columns take from their
    /// projected Gram matrix.
    pub(super) fn gram<C: AsRef<[f64]>>(&self, columns: &[C]) -> nalgebra::DMatrix<f64> {
        let m = columns.len();
        let coordinates: Vec<Vec<f64>> = columns
            .iter()
            .map(|x| self.coordinates(x.as_ref()))
            .collect();
        nalgebra::DMatrix::from_fn(m, m, |a, b| dot(&coordinates[a], &coordinates[b]))
    }

    /// 1ᵀ U Uᵀ 1 over every suffix `order[k..]` (element k): the squares of the running
    /// sums of every uₖ over the stream.
    /// With `weights`, the suffix's whitened column (wᵢ on it): the running sums of wᵢuₖ[i].
    pub(super) fn suffix_quads(&self, order: &[usize], weights: Option<&[f64]>) -> Vec<f64> {
        let mut quads = vec![0.0; order.len()];
        for u in &self.directions {
            let mut running = 0.0;
            for (k, &i) in order.iter().enumerate().rev() {
                running += weights.map_or(1.0, |w| w[i]) * u[i];
                quads[k] += running * running;
            }
        }
        quads
    }
}
