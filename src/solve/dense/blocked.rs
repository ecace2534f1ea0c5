//! The Cholesky factor and inverse of the dense path, a block of columns at a time: the
//! same numbers as nalgebra's `Cholesky::new` and `Cholesky::inverse`, to the bit, with
//! the columns before a block read once per block, and a call after every block (the
//! dense solve's progress).

use nalgebra::{Cholesky, DMatrix};

/// Columns of the factor, or of the inverse, computed together: what they read of the
/// columns before them is read once per block.
pub(super) const BLOCK: usize = 32;

/// nalgebra's `Cholesky::new` of a symmetric matrix (its lower triangle read), column
/// block by column block, `after_block(j0, j1)` called when columns j0 … j1 − 1 are
/// done; `None` where a pivot is not positive, as nalgebra refuses.
///
/// nalgebra's factorisation is left-looking: column j is updated by every column k < j
/// in turn (col_j\[j..\] += −L\[j, k\]·col_k\[j..\], its `axpy`), then divided by the square
/// root of its pivot. Here a block of columns takes the updates of each earlier column
/// k together, in the same order of k for each column, so every entry sees the same
/// operations in the same order: the factor is the same to the bit, with the earlier
/// columns read once per block instead of once per column.
pub(super) fn cholesky_by_blocks(
    mut matrix: DMatrix<f64>,
    mut after_block: impl FnMut(usize, usize),
) -> Option<Cholesky<f64, nalgebra::Dyn>> {
    let n = matrix.nrows();
    let data = matrix.as_mut_slice();
    let mut j0 = 0;
    while j0 < n {
        let j1 = (j0 + BLOCK).min(n);
        let (left, right) = data.split_at_mut(j0 * n);
        // the updates by the finished columns k < j0
        for col_k in left.chunks_exact(n) {
            for (offset, col_j) in right.chunks_exact_mut(n).take(j1 - j0).enumerate() {
                let j = j0 + offset;
                let a = -col_k[j];
                for (y, &x) in col_j[j..].iter_mut().zip(&col_k[j..]) {
                    *y += a * x;
                }
            }
        }
        // within the block: the updates by its own earlier columns, then the pivot
        for j in j0..j1 {
            let (left, right) = data.split_at_mut(j * n);
            let col_j = &mut right[..n];
            for col_k in left[j0 * n..].chunks_exact(n) {
                let a = -col_k[j];
                for (y, &x) in col_j[j..].iter_mut().zip(&col_k[j..]) {
                    *y += a * x;
                }
            }
            let diag = col_j[j];
            if diag == 0.0 || diag.is_nan() || diag < 0.0 {
                return None;
            }
            let denom = diag.sqrt();
            col_j[j] = denom;
            for value in &mut col_j[j + 1..] {
                *value /= denom;
            }
        }
        after_block(j0, j1);
        j0 = j1;
    }
    Some(Cholesky::pack_dirty(matrix))
}

/// S⁻¹ from the Cholesky factor L of S (S = L Lᵀ), solved against blocks of
/// [`BLOCK`] identity columns, `after_block(c0, c1)` called when columns
/// c0 … c1 − 1 are done.
///
/// Every column is solved with nalgebra's arithmetic for `Cholesky::inverse` (the
/// forward substitution's `axpy`, the back substitution's eight-way unrolled `dot`), in
/// the same order, so the inverse is the same to the bit; only the forward
/// substitution's leading rows, which stay exactly zero for an identity column, are
/// skipped.
pub(super) fn inverse_by_blocks(
    cholesky: &Cholesky<f64, nalgebra::Dyn>,
    mut after_block: impl FnMut(usize, usize),
) -> DMatrix<f64> {
    let l = cholesky.l_dirty();
    let m = l.nrows();
    let factor = l.as_slice();
    let mut inverse = DMatrix::<f64>::zeros(m, m);
    if m == 0 {
        return inverse;
    }
    let mut c0 = 0;
    for block in inverse.as_mut_slice().chunks_mut(BLOCK * m) {
        let c1 = c0 + block.len() / m;
        for (j, column) in block.chunks_exact_mut(m).enumerate() {
            column[c0 + j] = 1.0;
        }
        // L y = e_c: rows above c are zero and stay zero
        for i in c0..m {
            let diag = factor[i * m + i];
            let below = &factor[i * m + i + 1..(i + 1) * m];
            for (j, column) in block.chunks_exact_mut(m).enumerate() {
                if i < c0 + j {
                    continue;
                }
                let coeff = column[i] / diag;
                column[i] = coeff;
                let a = -coeff;
                for (y, &x) in column[i + 1..].iter_mut().zip(below) {
                    *y += a * x;
                }
            }
        }
        // Lᵀ x = y
        for i in (0..m).rev() {
            let diag = factor[i * m + i];
            let below = &factor[i * m + i + 1..(i + 1) * m];
            for column in block.chunks_exact_mut(m) {
                let dot = unrolled_dot(below, &column[i + 1..]);
                column[i] = (column[i] - dot) / diag;
            }
        }
        after_block(c0, c1);
        c0 = c1;
    }
    inverse
}

/// Σ aᵢbᵢ summed as nalgebra's `dot` sums a dynamic column: eight running sums, paired
/// (0 + 4, 1 + 5, 2 + 6, 3 + 7) into the result, then the tail one by one.
fn unrolled_dot(a: &[f64], b: &[f64]) -> f64 {
    let len = a.len().min(b.len());
    let (a, b) = (&a[..len], &b[..len]);
    let mut acc = [0.0_f64; 8];
    let (eights_a, eights_b) = (a.chunks_exact(8), b.chunks_exact(8));
    let (tail_a, tail_b) = (eights_a.remainder(), eights_b.remainder());
    for (x, y) in eights_a.zip(eights_b) {
        // indexed, so that the eight sums vectorize
        #[allow(clippy::needless_range_loop)]
        for r in 0..8 {
            acc[r] += x[r] * y[r];
        }
    }
    let mut result = 0.0;
    result += acc[0] + acc[4];
    result += acc[1] + acc[5];
    result += acc[2] + acc[6];
    result += acc[3] + acc[7];
    for (x, y) in tail_a.iter().zip(tail_b) {
        result += x * y;
    }
    result
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use nalgebra::DVector;
    use rand::{Rng, SeedableRng};

    /// A symmetric positive definite m × m matrix: AᵀA + m·I of a random A.
    pub(in crate::solve::dense) fn spd(m: usize, seed: u64) -> DMatrix<f64> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let a = DMatrix::from_fn(m, m, |_, _| rng.random_range(-1.0..1.0));
        a.transpose() * &a + DMatrix::identity(m, m) * m as f64
    }

    #[test]
    fn the_inverse_by_blocks_is_nalgebras_to_the_bit() {
        // within a block, at a block's edge, across several blocks and a short last one
        for (m, seed) in [(1, 1), (7, 2), (BLOCK, 3), (BLOCK + 1, 4), (101, 5)] {
            let cholesky = Cholesky::new(spd(m, seed)).expect("positive definite");
            let mut blocks = Vec::new();
            let ours = inverse_by_blocks(&cholesky, |c0, c1| blocks.push((c0, c1)));
            let theirs = cholesky.inverse();
            assert!(
                ours.iter()
                    .zip(theirs.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "m = {m}"
            );
            // the blocks cover every column once, in order
            assert_eq!(blocks.first().map(|b| b.0), Some(0));
            assert_eq!(blocks.last().map(|b| b.1), Some(m));
            assert!(blocks.windows(2).all(|w| w[0].1 == w[1].0));
        }
    }

    #[test]
    fn the_factorisation_by_blocks_is_nalgebras_to_the_bit() {
        for (m, seed) in [(1, 1), (7, 2), (BLOCK, 3), (BLOCK + 1, 4), (101, 5)] {
            let matrix = spd(m, seed);
            let mut blocks = Vec::new();
            let ours = cholesky_by_blocks(matrix.clone(), |j0, j1| blocks.push((j0, j1)))
                .expect("positive definite");
            let theirs = Cholesky::new(matrix).expect("positive definite");
            let (ours, theirs) = (ours.l_dirty(), theirs.l_dirty());
            assert!(
                ours.iter()
                    .zip(theirs.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "m = {m}"
            );
            assert_eq!(blocks.last().map(|b| b.1), Some(m));
            assert!(blocks.windows(2).all(|w| w[0].1 == w[1].0));
        }
        // not positive definite: refused, as nalgebra refuses
        let mut indefinite = spd(40, 6);
        indefinite[(35, 35)] = -1e6;
        assert!(Cholesky::new(indefinite.clone()).is_none());
        assert!(cholesky_by_blocks(indefinite, |_, _| {}).is_none());
    }

    #[test]
    fn the_unrolled_dot_sums_as_nalgebra_does() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        for len in [0, 1, 7, 8, 9, 16, 23, 200] {
            let a = DVector::from_fn(len, |_, _| rng.random_range(-1e3..1e3));
            let b = DVector::from_fn(len, |_, _| rng.random_range(-1e-3..1e-3));
            assert_eq!(
                unrolled_dot(a.as_slice(), b.as_slice()).to_bits(),
                a.dot(&b).to_bits(),
                "length {len}"
            );
        }
    }
}
