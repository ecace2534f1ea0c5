//! The structured form of a fit's geometry: the hat matrix from the engine's cofactor
//! Q_g = B + W M Wᵀ ([`crate::solve::cofactor`]) without forming it.
//!
//! In the engine's gauge g = [α (N), φ′ (N), U′ (K), effects (E)] a reading's design row
//! is α_p + φ′_f + U′_s plus its effect values (φ_f + U_s of the reported gauge is
//! φ′_f + U′_s). Then
//!
//! - H_ij = cᵢᵀ B cⱼ + (WM)ᵀcᵢ · Wᵀcⱼ: B's entries are O(1) (circulant lags and the setup
//!   diagonal), the low-rank part O(r);
//! - a column's score needs one product Q·g (O(N log N + (2N + K)·r));
//! - the suffixes of one stream (a change-point search): two readings of one stream at
//!   positions p and q (faces p + d and q + d) have cᵀBc′ = K(p − q) + B[U′_s, U′_s],
//!   K one circulant kernel of the stream, so Σ_{later i} K(p_t − p_i) for every reading t
//!   is a suffix convolution: blocks of readings, the histogram of the positions after
//!   each block convolved with K by FFT, the pairs within a block directly — O((m/b)·N
//!   log N + m·b) for m readings and blocks of b — and the low-rank part's running sum
//!   of Wᵀcᵢ, O(r) per reading.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::rows::Rows;
use crate::measurement::MeasurementSet;
use crate::solve::Solution;
use crate::solve::cofactor::Structured;

/// The structured cofactor of a fit and what a reading's row needs.
#[derive(Debug, Clone)]
pub(super) struct StructuredGeometry {
    /// Q_g.
    q: Structured,
    /// N.
    faces: usize,
    /// Every reading's position p.
    position: Vec<usize>,
    /// Every reading's face index f (0-based).
    face: Vec<usize>,
    /// Every reading's stream index s.
    stream: Vec<usize>,
    /// The rank r of the low-rank part.
    rank: usize,
    /// W by rows: entry (a, k) at a·r + k, so that a design row's r values lie together.
    w_rows: Vec<f64>,
    /// W·M by rows, likewise.
    wm_rows: Vec<f64>,
}

/// Streams with at most this many readings sum their pairs directly.
const DIRECT_PAIRS: usize = 2048;

impl StructuredGeometry {
    /// The geometry of `solution` (a fit of `set` with the effect `columns`) from its
    /// structured cofactor `q`, and every reading's design row in g.
    pub(super) fn new(
        solution: &Solution,
        set: &MeasurementSet,
        columns: &[Vec<f64>],
        q: &Structured,
    ) -> (Self, Rows) {
        let n = q.faces();
        let k = solution.setup_error.len();
        let streams: Vec<(u32, u32)> = solution
            .setup_error
            .iter()
            .map(|s| (s.setup, s.ac))
            .collect();
        let mut position = Vec::with_capacity(set.readings.len());
        let mut face = Vec::with_capacity(set.readings.len());
        let mut stream = Vec::with_capacity(set.readings.len());
        let mut rows = Rows::with_capacity(set.readings.len(), 3 + columns.len());
        for (i, r) in set.readings.iter().enumerate() {
            let (p, f) = (r.step % n, (r.face - 1) % n);
            let s = streams
                .iter()
                .position(|&key| key == (r.setup, r.ac))
                .unwrap_or(0);
            position.push(p);
            face.push(f);
            stream.push(s);
            rows.push(p, 1.0);
            rows.push(n + f, 1.0);
            rows.push(2 * n + s, 1.0);
            for (j, x) in columns.iter().enumerate() {
                if x[i] != 0.0 {
                    rows.push(2 * n + k + j, x[i]);
                }
            }
            rows.end_row();
        }
        let (rank, size) = (q.rank(), q.size());
        let mut w_rows = vec![0.0; size * rank];
        let mut wm_rows = vec![0.0; size * rank];
        for k in 0..rank {
            let (w, wm) = q.low_rank_column(k);
            for (a, (&x, &y)) in w.iter().zip(wm).enumerate() {
                w_rows[a * rank + k] = x;
                wm_rows[a * rank + k] = y;
            }
        }
        (
            Self {
                q: q.clone(),
                faces: n,
                position,
                face,
                stream,
                rank,
                w_rows,
                wm_rows,
            },
            rows,
        )
    }

    /// Wᵀc and (WM)ᵀc of a design row c into `a` and `b` (each of length r), so that
    /// cᵀ W M Wᵀ d = (WM)ᵀc · Wᵀd: each value summed over c's entries in order, from the
    /// rows of W (a design row's r values lie together).
    fn low_rank_into(&self, c: &[(usize, f64)], a: &mut [f64], b: &mut [f64]) {
        let r = self.rank;
        for k in 0..r {
            let (mut x, mut y) = (0.0, 0.0);
            for &(i, v) in c {
                x += v * self.w_rows[i * r + k];
                y += v * self.wm_rows[i * r + k];
            }
            a[k] = x;
            b[k] = y;
        }
    }

    /// cᵀ W M Wᵀ d for two design rows, without allocating: Σ_k ((WM)ᵀc)_k (Wᵀd)_k.
    fn low_rank_product(&self, c: &[(usize, f64)], d: &[(usize, f64)]) -> f64 {
        let r = self.rank;
        (0..r)
            .map(|k| {
                let x: f64 = c.iter().map(|&(i, v)| v * self.wm_rows[i * r + k]).sum();
                let y: f64 = d.iter().map(|&(i, v)| v * self.w_rows[i * r + k]).sum();
                x * y
            })
            .sum()
    }

    /// The length of g.
    pub(super) fn size(&self) -> usize {
        self.q.size()
    }

    /// Q_g x.
    pub(super) fn apply(&self, x: &[f64]) -> Vec<f64> {
        self.q.apply(x)
    }

    /// cᵢᵀ Q_g cⱼ for two design rows.
    pub(super) fn hat(&self, ci: &[(usize, f64)], cj: &[(usize, f64)]) -> f64 {
        let mut h = 0.0;
        for &(a, va) in ci {
            for &(b, vb) in cj {
                h += va * vb * self.q.base.entry(a, b);
            }
        }
        h + self.low_rank_product(ci, cj)
    }

    /// gᵀ Q_g g of every suffix `order[k..]` of one stream's readings (element k); the
    /// stream's suffix convolution is taken from `cache` when it holds it for the same
    /// kernel and order, and kept there otherwise.
    pub(super) fn suffix_quads(
        &self,
        rows: &Rows,
        order: &[usize],
        cache: &mut SuffixCache,
    ) -> Vec<f64> {
        let m = order.len();
        let Some(&first) = order.first() else {
            return Vec::new();
        };
        let n = self.faces;
        let offset = (self.face[first] + n - self.position[first]) % n;
        let stream = self.stream[first];
        let one_stream = order.iter().all(|&i| {
            self.stream[i] == stream && (self.face[i] + n - self.position[i]) % n == offset
        });
        if !one_stream {
            return self.suffix_quads_by_products(rows, order);
        }
        // K(δ) = c_δᵀ B c_0 for rows of the stream (α_x + φ′_{x+d}); plus B[U′_s, U′_s]
        let base = &self.q.base;
        let kernel: Vec<f64> = (0..n)
            .map(|delta| {
                let (a, b) = (delta, n + (delta + offset) % n);
                let (c, d) = (0, n + offset);
                base.entry(a, c) + base.entry(a, d) + base.entry(b, c) + base.entry(b, d)
            })
            .collect();
        let setup = base.entry(2 * n + stream, 2 * n + stream);
        let later = cache.convolution(&kernel, order, || {
            suffix_convolution(&kernel, order.iter().map(|&i| self.position[i]), m)
        });
        // the rows beyond α, φ′ and U′ (effect values) and the low-rank part: through
        // W, with the running sum of Wᵀcᵢ
        let rank = self.rank;
        let mut v = vec![0.0; rank];
        let (mut a, mut b) = (vec![0.0; rank], vec![0.0; rank]);
        let mut quads = vec![0.0; m];
        let mut quad = 0.0;
        for (k, &i) in order.iter().enumerate().rev() {
            let row = &rows[i];
            self.low_rank_into(row, &mut a, &mut b);
            let after = (m - 1 - k) as f64;
            // effect values of this row against the stream's α, φ′, U′ part: B is zero
            // there, so only the low-rank part couples them
            let cross =
                later[k] + setup * after + b.iter().zip(&v).map(|(x, y)| x * y).sum::<f64>();
            let own = kernel[0] + setup + b.iter().zip(&a).map(|(x, y)| x * y).sum::<f64>();
            quad += 2.0 * cross + own;
            for (t, x) in v.iter_mut().zip(&a) {
                *t += x;
            }
            quads[k] = quad;
        }
        quads
    }

    /// The suffix quadratics by one product per reading (readings of several streams or
    /// offsets: not expected of a change-point search).
    fn suffix_quads_by_products(&self, rows: &Rows, order: &[usize]) -> Vec<f64> {
        let size = self.size();
        let mut w = vec![0.0; size];
        let mut quad = 0.0;
        let mut quads = vec![0.0; order.len()];
        for (k, &i) in order.iter().enumerate().rev() {
            let row = &rows[i];
            let c_w: f64 = row.iter().map(|&(a, v)| v * w[a]).sum();
            quad += 2.0 * c_w + self.hat(row, row);
            let mut c = vec![0.0; size];
            for &(a, v) in row {
                c[a] += v;
            }
            for (t, q) in w.iter_mut().zip(self.apply(&c)) {
                *t += q;
            }
            quads[k] = quad;
        }
        quads
    }
}

/// The suffix convolutions of the streams of a change-point search
/// ([`super::FitGeometry::suffix_scores_with`]), kept from one round of a diagnosis to the
/// next: a stream's convolution depends only on its readings' positions and on its
/// circulant kernel, which comes from the regular part B of the cofactor — and adding
/// effect columns to the model changes only the low-rank part. An entry is used only for
/// the same order of readings and a kernel equal to the bit, so a cached convolution is
/// the one that would be computed.
#[derive(Debug, Clone, Default)]
pub struct SuffixCache {
    /// (order of the readings, kernel, Σ_{i > k} K(p_k − p_i) for every k).
    entries: Vec<(Vec<usize>, Vec<f64>, Vec<f64>)>,
}

impl SuffixCache {
    /// An empty cache.
    pub fn new() -> Self {
        Self::default()
    }

    /// The convolution of `order` with `kernel`: cached, or `compute`d and kept.
    fn convolution(
        &mut self,
        kernel: &[f64],
        order: &[usize],
        compute: impl FnOnce() -> Vec<f64>,
    ) -> &[f64] {
        let same = |(o, k, _): &(Vec<usize>, Vec<f64>, Vec<f64>)| {
            o.as_slice() == order
                && k.len() == kernel.len()
                && k.iter()
                    .zip(kernel)
                    .all(|(a, b)| a.to_bits() == b.to_bits())
        };
        let index = match self.entries.iter().position(same) {
            Some(index) => index,
            None => {
                let later = compute();
                self.entries.push((order.to_vec(), kernel.to_vec(), later));
                self.entries.len() - 1
            }
        };
        &self.entries[index].2
    }
}

/// For readings at `positions` (m of them, in order): element k is
/// Σ_{i > k} K((p_k − p_i) mod N), the kernel summed over the later readings.
///
/// A run of a table's cycles visits the positions in order (p, p ± 1, …): when the
/// readings fall into few such runs ([`Run`]), every later run adds a sum of the kernel
/// over consecutive lags, one difference of its prefix sums — O(runs) per reading
/// ([`by_runs`]). Otherwise the later readings are counted by position in blocks, each
/// block's count convolved with K by FFT, the pairs within a block summed directly —
/// O((m/b)·N log N + m·b) — or, for short streams, every pair directly.
pub(super) fn suffix_convolution(
    kernel: &[f64],
    positions: impl Iterator<Item = usize>,
    m: usize,
) -> Vec<f64> {
    let n = kernel.len();
    let p: Vec<usize> = positions.collect();
    let mut out = vec![0.0; m];
    // the kernel laid out twice: K((p_a − p_b) mod N) = twice[p_a + N − p_b], no division
    let twice: Vec<f64> = kernel.iter().chain(kernel).copied().collect();
    let pair = |a: usize, b: usize| twice[p[a] + n - p[b]];
    let block = ((n as f64 * (n as f64).log2()).sqrt() as usize).clamp(256, 4096);
    let runs = Run::split(&p, n);
    if runs.len() <= block && 4 * runs.len() <= m {
        return by_runs(kernel, &p, &runs);
    }
    if m <= DIRECT_PAIRS || n < 64 {
        for (k, o) in out.iter_mut().enumerate() {
            *o = (k + 1..m).map(|i| pair(k, i)).sum();
        }
        return out;
    }
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let mut spectrum: Vec<Complex<f64>> = kernel.iter().map(|&v| Complex::new(v, 0.0)).collect();
    forward.process(&mut spectrum);
    // the positions after the current block, counted
    let mut histogram = vec![0.0; n];
    let mut any_after = false;
    let mut hi = m;
    while hi > 0 {
        let lo = hi.saturating_sub(block);
        // conv[x] = Σ_y K((x − y) mod N) h[y]
        let conv: Vec<f64> = if any_after {
            let mut h: Vec<Complex<f64>> =
                histogram.iter().map(|&v| Complex::new(v, 0.0)).collect();
            forward.process(&mut h);
            for (a, b) in h.iter_mut().zip(&spectrum) {
                *a *= b;
            }
            inverse.process(&mut h);
            h.iter().map(|c| c.re / n as f64).collect()
        } else {
            vec![0.0; n]
        };
        for k in lo..hi {
            out[k] = conv[p[k]] + (k + 1..hi).map(|i| pair(k, i)).sum::<f64>();
        }
        for &q in &p[lo..hi] {
            histogram[q] += 1.0;
        }
        any_after = true;
        hi = lo;
    }
    out
}

/// A stretch of a stream's readings whose positions step by the same amount, −1, 0 or +1
/// (mod N): a table turning one way reads its positions so, cycle after cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Run {
    /// The index of the run's first reading.
    start: usize,
    /// Its readings.
    length: usize,
    /// The step from one reading's position to the next: −1, 0 or 1.
    step: i64,
}

impl Run {
    /// The maximal runs of the positions `p` on N positions, in order.
    fn split(p: &[usize], n: usize) -> Vec<Run> {
        let step_of = |a: usize, b: usize| -> Option<i64> {
            if b == a {
                Some(0)
            } else if b == (a + 1) % n {
                Some(1)
            } else if (b + 1) % n == a {
                Some(-1)
            } else {
                None
            }
        };
        let mut runs: Vec<Run> = Vec::new();
        for i in 0..p.len() {
            if let Some(run) = runs.last_mut()
                && run.start + run.length == i
            {
                let step = step_of(p[i - 1], p[i]);
                if run.length == 1
                    && let Some(step) = step
                {
                    run.step = step;
                    run.length += 1;
                    continue;
                }
                if step == Some(run.step) {
                    run.length += 1;
                    continue;
                }
            }
            runs.push(Run {
                start: i,
                length: 1,
                step: 0,
            });
        }
        runs
    }
}

/// [`suffix_convolution`] by runs: for the later readings of reading k's own run and of
/// every later run, Σ_j K((p_k − q₀ − s·j) mod N) over the run's readings, a sum of K over
/// consecutive lags (or L·K(d) for a run that stays at one position).
fn by_runs(kernel: &[f64], p: &[usize], runs: &[Run]) -> Vec<f64> {
    let n = kernel.len();
    let ni = n as i64;
    // prefix[x] = Σ_{t < x} K(t), x = 0 … N
    let mut prefix = vec![0.0; n + 1];
    for (t, &v) in kernel.iter().enumerate() {
        prefix[t + 1] = prefix[t] + v;
    }
    let total = prefix[n];
    // Σ_{t = 0 … length − 1} K((first + t) mod N)
    let ascending = |first: i64, length: usize| -> f64 {
        let first = first.rem_euclid(ni) as usize;
        let (whole, rest) = (length / n, length % n);
        let part = if first + rest <= n {
            prefix[first + rest] - prefix[first]
        } else {
            (total - prefix[first]) + prefix[first + rest - n]
        };
        whole as f64 * total + part
    };
    // Σ over `length` readings from position `q0` stepping by `step`, against position pk
    let over = |pk: usize, q0: usize, step: i64, length: usize| -> f64 {
        if length == 0 {
            return 0.0;
        }
        let d = pk as i64 - q0 as i64;
        match step {
            0 => length as f64 * kernel[d.rem_euclid(ni) as usize],
            // lags d, d − 1, …, d − L + 1
            1 => ascending(d - (length as i64 - 1), length),
            // lags d, d + 1, …, d + L − 1
            _ => ascending(d, length),
        }
    };
    let mut out = vec![0.0; p.len()];
    for (r, run) in runs.iter().enumerate() {
        for k in run.start..run.start + run.length {
            let rest = run.start + run.length - k - 1;
            let mut sum = if rest > 0 {
                over(p[k], p[k + 1], run.step, rest)
            } else {
                0.0
            };
            for later in &runs[r + 1..] {
                sum += over(p[k], p[later.start], later.step, later.length);
            }
            out[k] = sum;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    //! The suffix convolution against its definition, summed pair by pair.

    use super::{Run, suffix_convolution};

    /// Σ_{i > k} K((p_k − p_i) mod N), pair by pair.
    fn direct(kernel: &[f64], p: &[usize]) -> Vec<f64> {
        let n = kernel.len();
        (0..p.len())
            .map(|k| {
                (k + 1..p.len())
                    .map(|i| kernel[(p[k] + n - p[i]) % n])
                    .sum()
            })
            .collect()
    }

    fn check(kernel: &[f64], p: &[usize], what: &str) {
        let fast = suffix_convolution(kernel, p.iter().copied(), p.len());
        let truth = direct(kernel, p);
        let scale: f64 =
            kernel.iter().map(|v| v.abs()).sum::<f64>() * p.len() as f64 / kernel.len() as f64;
        for (k, (a, b)) in fast.iter().zip(&truth).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12 * scale.max(1.0),
                "{what}: reading {k}: {a} against {b}"
            );
        }
    }

    /// A kernel with no symmetry, of length n.
    fn kernel(n: usize) -> Vec<f64> {
        (0..n)
            .map(|t| ((t * 7919 % 101) as f64 - 50.0) * 0.01 + if t == 0 { 3.0 } else { 0.0 })
            .collect()
    }

    #[test]
    fn runs_of_cycles_give_the_pairwise_sums() {
        for n in [5, 24, 97, 360] {
            let k = kernel(n);
            // cw cycles with a closing reading, ccw cycles, both, and a repeated stop
            let cw: Vec<usize> = (0..4).flat_map(|_| (0..=n).map(move |s| s % n)).collect();
            let ccw: Vec<usize> = (0..3)
                .flat_map(|_| (0..=n).rev().map(move |s| s % n))
                .collect();
            let both: Vec<usize> = cw.iter().chain(&ccw).copied().collect();
            let mut repeated = cw.clone();
            repeated.insert(n / 2, repeated[n / 2]);
            repeated.insert(n / 2, repeated[n / 2]);
            for (p, what) in [
                (&cw, "cw"),
                (&ccw, "ccw"),
                (&both, "both"),
                (&repeated, "repeated"),
            ] {
                let runs = Run::split(p, n);
                assert!(runs.len() <= 2 * 7 + 2, "{what}: {} runs", runs.len());
                check(&k, p, &format!("{n} positions, {what}"));
            }
        }
    }

    #[test]
    fn scattered_orders_take_the_other_ways_and_agree() {
        // a pseudo-random order (runs of one or two readings): blocks and FFTs, or pairs
        for (n, m) in [(97, 500), (128, 6000)] {
            let k = kernel(n);
            let p: Vec<usize> = (0..m).map(|i| (i * 7919 + i * i * 31) % n).collect();
            assert!(Run::split(&p, n).len() * 4 > m);
            check(&k, &p, &format!("{n} positions, scattered"));
        }
    }

    #[test]
    fn a_run_longer_than_the_circle_wraps_whole_turns() {
        // one run of 2.5 turns on 7 positions, then a short one
        let n = 7;
        let k = kernel(n);
        let mut p: Vec<usize> = (0..18).map(|i| i % n).collect();
        p.extend([3, 2, 1]);
        assert_eq!(Run::split(&p, n).len(), 2);
        check(&k, &p, "wrapping");
    }
}
