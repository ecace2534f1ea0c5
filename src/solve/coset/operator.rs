//! The cofactor of a sub-pitch fit as an operator: Q_g = B + W M Wᵀ in the coset gauge
//! g = [α_0, …, α_{C−1}, φ′, U′], and the fixed sparse map to the reported θ.
//!
//! The reported θ is the effect-column path's ([`crate::solve::sub_pitch`]): θ = [β (N),
//! α_0 (N), U (K), δ_c\[q\] (c = 1 … C−1, q = 0 … N−2)] with
//!
//! ```text
//! β_f = φ′_f − φ′_{f−1},   α_0[p] = α_0[p],   U_s = U′_s + φ′_{N−1},
//! δ_c[q] = α_c[q] − α_0[q],
//! ```
//!
//! two terms of g each, so an entry of Q in θ costs O(r) and a product O(N log N + L·r)
//! for L = (C + 1)·N + K and the rank r of the low-rank part.

use nalgebra::DMatrix;

use super::base::CosetBase;
use crate::solve::ParameterLayout;
use crate::solve::woodbury::LowRank;

/// Q_g = B + W M Wᵀ of a sub-pitch fit (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CosetStructured {
    base: CosetBase,
    /// W M Wᵀ, columns of length L.
    low_rank: LowRank,
}

impl CosetStructured {
    /// Q_g = B + W M Wᵀ; `w` column-major (r columns of length L), `m` r × r.
    pub(crate) fn new(base: CosetBase, w: Vec<f64>, m: &DMatrix<f64>) -> Self {
        let low_rank = LowRank::new(base.len(), w, m);
        Self { base, low_rank }
    }

    /// The rank r of the low-rank part.
    pub(crate) fn rank(&self) -> usize {
        self.low_rank.rank()
    }

    /// The length L of g.
    pub(crate) fn len(&self) -> usize {
        self.base.len()
    }

    /// The index of φ′_f in g.
    pub(crate) fn phi(&self, face: usize) -> usize {
        self.base.cosets() * self.base.faces() + face
    }

    /// Q_g\[a, b\].
    pub(crate) fn entry(&self, a: usize, b: usize) -> f64 {
        self.low_rank.add_entry(self.base.entry(a, b), a, b)
    }

    /// Q_g x.
    pub(crate) fn apply(&self, x: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.base.apply_add(x, &mut out);
        self.low_rank.apply_add(x, &mut out);
        out
    }

    /// θ_i as a sparse combination of g: θ_i = Σ coefficient · g_index (module
    /// documentation); a coefficient 0 is no term.
    pub(crate) fn theta_row(&self, layout: &ParameterLayout, i: usize) -> [(usize, f64); 2] {
        let n = layout.faces;
        let none = (0, 0.0);
        let phi = self.phi(0);
        if i < n {
            [(phi + i, 1.0), (phi + (i + n - 1) % n, -1.0)]
        } else if i < 2 * n {
            [(i - n, 1.0), none]
        } else if i < 2 * n + layout.setups {
            // U′_s follows φ′ in g
            [(phi + n + (i - 2 * n), 1.0), (phi + n - 1, 1.0)]
        } else {
            let e = i - 2 * n - layout.setups;
            let (coset, q) = (e / (n - 1) + 1, e % (n - 1));
            [(coset * n + q, 1.0), (q, -1.0)]
        }
    }

    /// Q\[i, j\] in θ.
    pub(crate) fn theta_entry(&self, layout: &ParameterLayout, i: usize, j: usize) -> f64 {
        let mut v = 0.0;
        for (a, ca) in self.theta_row(layout, i) {
            if ca == 0.0 {
                continue;
            }
            for (b, cb) in self.theta_row(layout, j) {
                if cb != 0.0 {
                    v += ca * cb * self.entry(a, b);
                }
            }
        }
        v
    }

    /// Q·x for x in θ: Tᵀx, Q_g, T.
    pub(crate) fn theta_apply(&self, layout: &ParameterLayout, x: &[f64]) -> Vec<f64> {
        let mut g = vec![0.0; self.len()];
        for (i, &v) in x.iter().enumerate() {
            for (a, c) in self.theta_row(layout, i) {
                g[a] += c * v;
            }
        }
        let qg = self.apply(&g);
        (0..x.len())
            .map(|i| {
                self.theta_row(layout, i)
                    .iter()
                    .map(|&(a, c)| c * qg[a])
                    .sum()
            })
            .collect()
    }

    /// The whole matrix in θ (layout order): one product per column.
    pub(crate) fn theta_dense(&self, layout: &ParameterLayout) -> DMatrix<f64> {
        let len = layout.len();
        let mut q = DMatrix::<f64>::zeros(len, len);
        let mut unit = vec![0.0; len];
        for j in 0..len {
            unit[j] = 1.0;
            let column = self.theta_apply(layout, &unit);
            unit[j] = 0.0;
            q.column_mut(j).copy_from_slice(&column);
        }
        q
    }
}
