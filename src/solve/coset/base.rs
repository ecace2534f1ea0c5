//! The cofactor B of a sub-pitch design's regular part, harmonic by harmonic.
//!
//! In g = [α_0 (N), …, α_{C−1} (N), φ′ (N), U′ (K)] with Σα_c = 0 for every coset c and
//! Σφ′ = 0, a stream s of coset c_s with face offset d_s and w_s readings per position
//! contributes w_s·|α_{c_s}\[p\] + φ′\[(p + d_s) mod N\] + U′_s|² per position p. For the
//! Fourier mode k ≠ 0 (α_c = a_c·ω^{kp}, φ′ = f·ω^{kp}, ω = e^{2πi/N}) the setup
//! errors drop out and the normal equations are the (C + 1) × (C + 1) Hermitian block
//!
//! ```text
//!        ⎡ W_0           t_0(k)     ⎤
//! M_k  = ⎢      ⋱         ⋮         ⎥ ,   W_c = Σ_{s ∈ c} w_s,   W = Σ_c W_c,
//!        ⎢         W_{C−1} t_{C−1}(k)⎥    t_c(k) = Σ_{s ∈ c} w_s e^{2πi k d_s / N},
//!        ⎣ t̄_0(k) … t̄_{C−1}(k)  W   ⎦
//! ```
//!
//! Its inverse R_k = M_k⁻¹, by the Schur complement of the diagonal, is
//!
//! ```text
//! s_k = W − Σ_c |t_c|²/W_c = Σ_c (1/W_c) Σ_{s<s′ ∈ c} 4 w_s w_s′ sin²(πk(d_s − d_s′)/N),
//! R_k[φ′, φ′] = 1/s_k,   R_k[c, φ′] = −t_c/(W_c s_k),
//! R_k[c, c′] = δ_{cc′}/W_c + t_c t̄_{c′}/(W_c W_{c′} s_k),
//! ```
//!
//! every term formed without cancellation (s_k from the sines, as for one coset). A
//! harmonic with s_k = 0 is lost: every coset sees it in one phase (the caller refuses
//! such a design before it gets here). At k = 0 the gauge fixes the constants of every
//! α_c and of φ′, and U′_s is its stream's mean: B[U′_s, U′_s] = 1/(N·w_s).
//!
//! B is then block-circulant: B\[x_p, y_q\] = b_xy\[(p − q) mod N\] for the blocks
//! x, y ∈ {α_0, …, α_{C−1}, φ′}, with the lags b_xy\[j\] = (1/N) Σ_{k≠0} R_k\[x, y\]·ω^{kj},
//! and a product B·v is C + 1 forward FFTs, the (C + 1)² products per harmonic, and
//! C + 1 inverse FFTs.

use std::sync::Arc;

use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

/// A stream of a sub-pitch design's regular part: its coset, face offset d (face =
/// (p + d) mod N + 1 at position p of its coset) and readings per position w.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct CosetStream {
    pub(crate) coset: usize,
    pub(crate) offset: usize,
    pub(crate) weight: f64,
}

/// B of the module documentation: its lags, its spectrum R_k and the setup diagonal.
#[derive(Clone)]
pub(crate) struct CosetBase {
    faces: usize,
    cosets: usize,
    /// `lags[(x·(C + 1) + y)·N + j]` = B\[x_p, y_q\] with j = (p − q) mod N; block C is φ′.
    lags: Vec<f64>,
    /// `spectrum[k·(C + 1)² + x·(C + 1) + y]` = R_k\[x, y\] (0 at k = 0).
    spectrum: Vec<Complex<f64>>,
    /// B\[U′_s, U′_s\] = 1/(N·w_s).
    setup: Vec<f64>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for CosetBase {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("CosetBase")
            .field("faces", &self.faces)
            .field("cosets", &self.cosets)
            .field("setup", &self.setup)
            .finish_non_exhaustive()
    }
}

impl PartialEq for CosetBase {
    fn eq(&self, other: &Self) -> bool {
        self.faces == other.faces
            && self.cosets == other.cosets
            && self.lags == other.lags
            && self.setup == other.setup
    }
}

impl CosetBase {
    /// B of `cosets` cosets of `faces` positions read by `streams`; `None` when a
    /// harmonic is lost (s_k not positive) or a coset has no weight.
    pub(crate) fn new(faces: usize, cosets: usize, streams: &[CosetStream]) -> Option<Self> {
        let n = faces;
        let blocks = cosets + 1;
        // per coset: distinct offsets with their summed weights
        let mut by_offset: Vec<Vec<(usize, f64)>> = vec![Vec::new(); cosets];
        for s in streams {
            let group = by_offset.get_mut(s.coset)?;
            match group.iter_mut().find(|(d, _)| *d == s.offset % n) {
                Some((_, w)) => *w += s.weight,
                None => group.push((s.offset % n, s.weight)),
            }
        }
        let coset_weight: Vec<f64> = by_offset
            .iter()
            .map(|g| g.iter().map(|(_, w)| w).sum())
            .collect();
        if coset_weight.iter().any(|&w| w <= 0.0) {
            return None;
        }
        let (cos, sin) = trig_table(n);
        let mut spectrum = vec![Complex::new(0.0, 0.0); n * blocks * blocks];
        let mut t = vec![Complex::new(0.0, 0.0); cosets];
        for k in 1..n {
            let mut schur = 0.0;
            for (c, group) in by_offset.iter().enumerate() {
                let mut tc = Complex::new(0.0, 0.0);
                let mut det = 0.0;
                for (a, &(da, wa)) in group.iter().enumerate() {
                    let m = (k * da) % n;
                    tc += Complex::new(cos[m], sin[m]) * wa;
                    for &(db, wb) in &group[a + 1..] {
                        let m = (k * (da + n - db)) % n;
                        let half = std::f64::consts::PI * m as f64 / n as f64;
                        det += 4.0 * wa * wb * half.sin().powi(2);
                    }
                }
                t[c] = tc;
                schur += det / coset_weight[c];
            }
            if schur.is_nan() || schur <= 0.0 {
                return None;
            }
            let r = &mut spectrum[k * blocks * blocks..(k + 1) * blocks * blocks];
            r[cosets * blocks + cosets] = Complex::new(1.0 / schur, 0.0);
            for c in 0..cosets {
                let wc = coset_weight[c];
                let cross = -t[c] / (wc * schur);
                r[c * blocks + cosets] = cross;
                r[cosets * blocks + c] = cross.conj();
                for c2 in 0..cosets {
                    let mut v = t[c] * t[c2].conj() / (wc * coset_weight[c2] * schur);
                    if c == c2 {
                        v += 1.0 / wc;
                    }
                    r[c * blocks + c2] = v;
                }
            }
        }
        let mut planner = FftPlanner::new();
        let forward = planner.plan_fft_forward(n);
        let inverse = planner.plan_fft_inverse(n);
        let mut lags = vec![0.0; blocks * blocks * n];
        let mut buffer = vec![Complex::new(0.0, 0.0); n];
        for xy in 0..blocks * blocks {
            for (k, b) in buffer.iter_mut().enumerate() {
                *b = spectrum[k * blocks * blocks + xy];
            }
            inverse.process(&mut buffer);
            for (lag, b) in lags[xy * n..(xy + 1) * n].iter_mut().zip(&buffer) {
                *lag = b.re / n as f64;
            }
        }
        let setup = streams
            .iter()
            .map(|s| 1.0 / (n as f64 * s.weight))
            .collect();
        Some(Self {
            faces: n,
            cosets,
            lags,
            spectrum,
            setup,
            forward,
            inverse,
        })
    }

    /// Bytes [`CosetBase::new`] keeps and uses while it builds: the lags and the spectrum
    /// ((C + 1)²·N values, real and complex), the trigonometric table and one buffer.
    pub(crate) fn bytes_needed(faces: usize, cosets: usize, streams: usize) -> u128 {
        let (n, blocks) = (faces as u128, cosets as u128 + 1);
        8 * blocks * blocks * n + 16 * blocks * blocks * n + 16 * n + 16 * n + 8 * streams as u128
    }

    /// N.
    pub(crate) fn faces(&self) -> usize {
        self.faces
    }

    /// C.
    pub(crate) fn cosets(&self) -> usize {
        self.cosets
    }

    /// The length (C + 1)·N + K of g.
    pub(crate) fn len(&self) -> usize {
        (self.cosets + 1) * self.faces + self.setup.len()
    }

    /// B\[a, b\] in g.
    pub(crate) fn entry(&self, a: usize, b: usize) -> f64 {
        let n = self.faces;
        let blocks = self.cosets + 1;
        let circulant = blocks * n;
        if a < circulant && b < circulant {
            let (x, p, y, q) = (a / n, a % n, b / n, b % n);
            self.lags[(x * blocks + y) * n + (p + n - q) % n]
        } else if a == b && a >= circulant {
            self.setup.get(a - circulant).copied().unwrap_or(0.0)
        } else {
            0.0
        }
    }

    /// out += B x in g (O((C + 1)·N log N + (C + 1)²·N)).
    pub(crate) fn apply_add(&self, x: &[f64], out: &mut [f64]) {
        let n = self.faces;
        let blocks = self.cosets + 1;
        let mut hats: Vec<Vec<Complex<f64>>> = (0..blocks)
            .map(|b| {
                let mut v: Vec<Complex<f64>> = x[b * n..(b + 1) * n]
                    .iter()
                    .map(|&v| Complex::new(v, 0.0))
                    .collect();
                self.forward.process(&mut v);
                v
            })
            .collect();
        let mut column = vec![Complex::new(0.0, 0.0); blocks];
        for k in 0..n {
            let r = &self.spectrum[k * blocks * blocks..(k + 1) * blocks * blocks];
            for (y, c) in column.iter_mut().enumerate() {
                *c = hats[y][k];
            }
            for (xb, hat) in hats.iter_mut().enumerate() {
                hat[k] = (0..blocks).map(|y| r[xb * blocks + y] * column[y]).sum();
            }
        }
        for (b, hat) in hats.iter_mut().enumerate() {
            self.inverse.process(hat);
            for (o, v) in out[b * n..(b + 1) * n].iter_mut().zip(hat.iter()) {
                *o += v.re / n as f64;
            }
        }
        let circulant = blocks * n;
        for (s, &d) in self.setup.iter().enumerate() {
            out[circulant + s] += d * x[circulant + s];
        }
    }
}

/// cos and sin of 2πm/N for m in 0..N.
fn trig_table(n: usize) -> (Vec<f64>, Vec<f64>) {
    (0..n)
        .map(|m| {
            let angle = 2.0 * std::f64::consts::PI * m as f64 / n as f64;
            (angle.cos(), angle.sin())
        })
        .unzip()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One coset is the circulant engine's regular part: the same lags as
    /// [`crate::solve::cofactor`]'s `Base`, and B·v equals the sum over its entries.
    #[test]
    fn one_coset_is_the_circulant_base_and_products_match_entries() {
        let streams = [
            CosetStream {
                coset: 0,
                offset: 0,
                weight: 2.0,
            },
            CosetStream {
                coset: 0,
                offset: 3,
                weight: 1.0,
            },
        ];
        let n = 10;
        let coset = CosetBase::new(n, 1, &streams).unwrap();
        let base = crate::solve::cofactor::Base::new(
            n,
            &[
                crate::solve::cofactor::RegularStream {
                    offset: 0,
                    weight: 2.0,
                },
                crate::solve::cofactor::RegularStream {
                    offset: 3,
                    weight: 1.0,
                },
            ],
            0,
            &[],
        );
        let len = 2 * n + 2;
        for a in 0..len {
            for b in 0..len {
                assert!(
                    (coset.entry(a, b) - base.entry(a, b)).abs() < 1e-12,
                    "{a} {b}"
                );
            }
        }
        // three cosets: B·v from the FFT equals Σ_b B[a, b] v_b, and B is symmetric
        let streams = [
            (0, 0, 1.0),
            (0, 1, 1.0),
            (1, 4, 2.0),
            (2, 2, 1.0),
            (2, 5, 3.0),
        ]
        .map(|(coset, offset, weight)| CosetStream {
            coset,
            offset,
            weight,
        });
        let n = 7;
        let b = CosetBase::new(n, 3, &streams).unwrap();
        let len = b.len();
        let x: Vec<f64> = (0..len)
            .map(|i| ((i * 37 % 11) as f64 - 5.0) / 3.0)
            .collect();
        let mut out = vec![0.0; len];
        b.apply_add(&x, &mut out);
        for (a, product) in out.iter().enumerate() {
            let direct: f64 = (0..len).map(|j| b.entry(a, j) * x[j]).sum();
            assert!((product - direct).abs() < 1e-12, "{a}");
            for j in 0..len {
                assert!((b.entry(a, j) - b.entry(j, a)).abs() < 1e-12);
            }
        }
    }

    /// A coset read by one autocollimator only, with no other coset to fix the polygon,
    /// loses every harmonic.
    #[test]
    fn a_lone_autocollimator_loses_every_harmonic() {
        let streams = [CosetStream {
            coset: 0,
            offset: 1,
            weight: 1.0,
        }];
        assert!(CosetBase::new(6, 1, &streams).is_none());
    }
}
