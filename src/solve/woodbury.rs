//! The low-rank part of a structured cofactor, Q = B + W M Wᵀ, and the Woodbury
//! correction that forms it for cells whose readings differ from the regular design's
//! (closing readings, missing readings): W = B V, M = −(D⁻¹ + Vᵀ B V)⁻¹, where each
//! column of V is the design row of one cell (a 1 in its position, face and stream) and
//! D the cells' weight changes. The circulant engine and the coset engine both use it,
//! with [`regular_weight`], which splits a stream into its regular weight and the cells
//! that differ from it.

use nalgebra::DMatrix;

/// The regular part of stream `stream` whose readings per position are `cells`: its
/// weight, the most frequent count (ties: the larger), returned; every cell whose count
/// differs is pushed onto `corrections` as (stream, position, count − weight). A weight 0
/// leaves no regular part (the caller's fallback).
pub(crate) fn regular_weight(
    stream: usize,
    cells: &[u32],
    corrections: &mut Vec<(usize, usize, f64)>,
) -> u32 {
    let mut sorted = cells.to_vec();
    sorted.sort_unstable();
    let (mut mode, mut best, mut run) = (sorted.first().copied().unwrap_or(0), 0usize, 0usize);
    for (i, &c) in sorted.iter().enumerate() {
        run = if i > 0 && sorted[i - 1] == c {
            run + 1
        } else {
            1
        };
        if run >= best {
            best = run;
            mode = c;
        }
    }
    if mode > 0 {
        for (p, &c) in cells.iter().enumerate() {
            if c != mode {
                corrections.push((stream, p, f64::from(c) - f64::from(mode)));
            }
        }
    }
    mode
}

/// W M Wᵀ held as W and W·M, column-major: `rank` columns of length `len`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LowRank {
    len: usize,
    w: Vec<f64>,
    wm: Vec<f64>,
    rank: usize,
}

impl LowRank {
    /// W M Wᵀ; `w` column-major (r columns of length `len`), `m` r × r.
    pub(crate) fn new(len: usize, w: Vec<f64>, m: &DMatrix<f64>) -> Self {
        let rank = m.nrows();
        let mut wm = vec![0.0; w.len()];
        for c in 0..rank {
            for k in 0..rank {
                let f = m[(k, c)];
                if f == 0.0 {
                    continue;
                }
                let (src, dst) = (&w[k * len..(k + 1) * len], &mut wm[c * len..(c + 1) * len]);
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += f * s;
                }
            }
        }
        Self { len, w, wm, rank }
    }

    /// The rank r.
    pub(crate) fn rank(&self) -> usize {
        self.rank
    }

    /// Column k of W and of W·M.
    pub(crate) fn column(&self, k: usize) -> (&[f64], &[f64]) {
        let range = k * self.len..(k + 1) * self.len;
        (&self.w[range.clone()], &self.wm[range])
    }

    /// `base` + (W M Wᵀ)\[a, b\], its terms added to `base` in order.
    pub(crate) fn add_entry(&self, base: f64, a: usize, b: usize) -> f64 {
        let mut v = base;
        for c in 0..self.rank {
            v += self.wm[c * self.len + a] * self.w[c * self.len + b];
        }
        v
    }

    /// q += W M Wᵀ, for q of size len × len.
    pub(crate) fn add_to_dense(&self, q: &mut DMatrix<f64>) {
        if self.rank > 0 {
            let w = DMatrix::from_column_slice(self.len, self.rank, &self.w);
            let wm = DMatrix::from_column_slice(self.len, self.rank, &self.wm);
            q.gemm(1.0, &wm, &w.transpose(), 1.0);
        }
    }

    /// out += W M Wᵀ x.
    pub(crate) fn apply_add(&self, x: &[f64], out: &mut [f64]) {
        for k in 0..self.rank {
            let (w, wm) = self.column(k);
            let dot: f64 = w.iter().zip(x).map(|(a, b)| a * b).sum();
            if dot != 0.0 {
                for (o, v) in out.iter_mut().zip(wm) {
                    *o += dot * v;
                }
            }
        }
    }
}

/// The Woodbury correction of `cells` — per cell the three indices of its design row
/// (position, face, stream) in B's coordinates of length `len`, and its weight change d
/// — given B's entries `entry(a, b)`: W = B V (column-major) and (D⁻¹ + Vᵀ B V)⁻¹, or
/// `None` when that capacitance is singular to working precision against the size of
/// its two parts (in a design of one reading per cell every reading has leverage 1, and
/// D⁻¹ + VᵀBV of missing readings is then 0).
pub(crate) fn cell_correction(
    len: usize,
    cells: &[([usize; 3], f64)],
    entry: impl Fn(usize, usize) -> f64,
) -> Option<(Vec<f64>, DMatrix<f64>)> {
    let m = cells.len();
    let mut w = vec![0.0; len * m];
    for (c, (row, _)) in cells.iter().enumerate() {
        for (a, v) in w[c * len..(c + 1) * len].iter_mut().enumerate() {
            *v = row.iter().map(|&j| entry(a, j)).sum();
        }
    }
    let mut capacitance = DMatrix::<f64>::zeros(m, m);
    for (c, (row, d)) in cells.iter().enumerate() {
        for e in 0..m {
            capacitance[(c, e)] = row.iter().map(|&a| w[e * len + a]).sum();
        }
        capacitance[(c, c)] += 1.0 / d;
    }
    let scale = cells
        .iter()
        .enumerate()
        .map(|(c, (_, d))| (1.0 / d).abs() + (capacitance[(c, c)] - 1.0 / d).abs())
        .fold(0.0_f64, f64::max);
    let inverse = invert_checked(&capacitance, scale)?;
    Some((w, inverse))
}

/// The inverse of a small matrix by LU, or `None` when it is singular to working
/// precision: a pivot below 1e-10 of `scale` (the size of the terms it was formed from;
/// the dense path's test of its Cholesky factor is the same ratio), or a product with
/// the inverse that is not the identity to 1e-8.
pub(crate) fn invert_checked(matrix: &DMatrix<f64>, scale: f64) -> Option<DMatrix<f64>> {
    let size = matrix.nrows();
    if size == 0 {
        return Some(DMatrix::zeros(0, 0));
    }
    let lu = matrix.clone().lu();
    let u = lu.u();
    let pivots: Vec<f64> = (0..size).map(|i| u[(i, i)].abs()).collect();
    let largest = pivots.iter().fold(scale, |a, &b| a.max(b));
    let smallest = pivots.iter().fold(f64::INFINITY, |a, &b| a.min(b));
    if smallest.is_nan() || smallest <= 1e-10 * largest {
        return None;
    }
    let inverse = lu.try_inverse()?;
    if inverse.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let product = matrix * &inverse;
    let worst = (0..size)
        .flat_map(|i| (0..size).map(move |j| (i, j)))
        .map(|(i, j)| (product[(i, j)] - if i == j { 1.0 } else { 0.0 }).abs())
        .fold(0.0_f64, f64::max);
    (worst < 1e-8).then_some(inverse)
}
