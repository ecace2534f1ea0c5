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
    ) -> (Self, Vec<Vec<(usize, f64)>>) {
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
        let rows = set
            .readings
            .iter()
            .enumerate()
            .map(|(i, r)| {
                let (p, f) = (r.step % n, (r.face - 1) % n);
                let s = streams
                    .iter()
                    .position(|&key| key == (r.setup, r.ac))
                    .unwrap_or(0);
                position.push(p);
                face.push(f);
                stream.push(s);
                let mut row = Vec::with_capacity(3 + columns.len());
                row.push((p, 1.0));
                row.push((n + f, 1.0));
                row.push((2 * n + s, 1.0));
                for (j, x) in columns.iter().enumerate() {
                    if x[i] != 0.0 {
                        row.push((2 * n + k + j, x[i]));
                    }
                }
                row
            })
            .collect();
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
        rows: &[Vec<(usize, f64)>],
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
    fn suffix_quads_by_products(&self, rows: &[Vec<(usize, f64)>], order: &[usize]) -> Vec<f64> {
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
    if m <= DIRECT_PAIRS || n < 64 {
        for (k, o) in out.iter_mut().enumerate() {
            *o = (k + 1..m).map(|i| pair(k, i)).sum();
        }
        return out;
    }
    let block = ((n as f64 * (n as f64).log2()).sqrt() as usize).clamp(256, 4096);
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
