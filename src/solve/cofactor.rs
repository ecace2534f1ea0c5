//! The cofactor matrix Q of a fit (Cov(θ) = σ²·Q) as an operator: entries, the diagonal
//! and products Q·x without forming the (2N + K + E)² matrix unless a caller asks for it.
//!
//! Three representations:
//!
//! - **dense**: the matrix itself, in θ = [β (N), α (N), U (K), effects (E)]
//!   ([`ParameterLayout`]), as the dense reference solver produces it;
//! - **structured**: the closure design's own structure, in the gauge g = [α (N), φ′ (N),
//!   U′ (K), effects (E)] with Σα = 0 and Σφ′ = 0,
//!
//!   ```text
//!   Q_g = B + W M Wᵀ
//!   ```
//!
//!   where B is the cofactor of the design's *regular part* (every stream reads every
//!   position equally often): a 2 × 2 block of circulants in (α, φ′) — the same number
//!   on every diagonal, so u(α) of a regular design is one number — and a diagonal
//!   1/(N·w_s) for the setup errors; W M Wᵀ is the low-rank part (closing readings,
//!   missing or repeated readings, effect columns: r = corrections + effects columns).
//!   The reported θ is a fixed sparse map of g (β_f = φ′_f − φ′_{f−1},
//!   U_s = U′_s + φ′_N, the gauge of docs/FORMAT.md §1), so an entry of Q in θ costs
//!   O(r), its diagonal O((2N + K)·r) and a product Q·x O(N log N + (2N + K)·r).
//! - **structured on cosets**: a sub-pitch fit's Q_g = B + W M Wᵀ in the coset gauge
//!   g = [α_0, …, α_{C−1}, φ′, U′], B block-circulant with a (C + 1) × (C + 1) block
//!   per harmonic ([`super::coset`]), reported in the effect-column path's θ (the
//!   cosets' differences δ_c = α_c − α_0 as its effect terms), again through a sparse
//!   map of two terms per entry.

use std::sync::{Arc, OnceLock};

use nalgebra::DMatrix;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::ParameterLayout;
use super::coset::operator::CosetStructured;
use super::woodbury::LowRank;

/// The cofactor matrix Q of θ = [β (N), α (N), U (K), effects (E)]: Cov(θ) = σ²·Q.
///
/// It answers entries, the diagonal, the variances of the face deviations and products
/// Q·x; [`Cofactor::to_dense`] forms the whole matrix only when a caller asks for it.
///
/// ```
/// use polycal::simulate::{simulate, SimulationConfig};
/// use polycal::solve::{solve, SolveOptions};
///
/// let (set, _) = simulate(&SimulationConfig { closing: true, ..SimulationConfig::default() })?;
/// let solution = solve(&set, &SolveOptions::default())?;
/// let q = &solution.cofactor;
/// let n = solution.faces;
/// // the covariance of β_1 and β_2, and u(β_1), without forming the matrix
/// let (s, _) = solution.sigma.unwrap();
/// let u_beta_1 = s * q.entry(0, 0).sqrt();
/// assert!((u_beta_1 - solution.pitch_deviation_u().unwrap()[0]).abs() < 1e-12);
/// assert!(q.entry(0, 1) < 0.0);
/// assert_eq!(q.len(), 2 * n + 2);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Cofactor {
    layout: ParameterLayout,
    repr: Repr,
    /// A variance added to every encoder error in the closed gauge, in units of σ²:
    /// `encoder_extra`·(I − J/N) on the α block ([`Cofactor::with_encoder_variance`]).
    encoder_extra: f64,
}

#[derive(Debug, Clone, PartialEq)]
enum Repr {
    Dense(DMatrix<f64>),
    Structured(Box<Structured>),
    /// A sub-pitch fit's Q_g = B + W M Wᵀ in the coset gauge ([`super::coset`]).
    Cosets(Box<CosetStructured>),
}

/// Q_g = B + W M Wᵀ (module documentation).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Structured {
    pub(crate) base: Base,
    /// W M Wᵀ, columns of length 2N + K + E.
    low_rank: LowRank,
}

/// The cofactor B of a regular closure design in g = [α, φ′, U′, effects] (effects: 0).
///
/// `aa[j]` = B[α_p, α_{p+j}], `pp[j]` = B[φ′_p, φ′_{p+j}] (the same circulant as `aa`
/// unless harmonics are lost and set to zero), `ap[j]` = B[α_p, φ′_f] with
/// j = (p − f) mod N, `setup[s]` = B[U′_s, U′_s] = 1/(N·w_s).
///
/// A design that loses harmonics (every stream sees them in the same phase) has no
/// inverse there. When the caller asks for them to be set to zero (self-calibration,
/// [`crate::selfcal`]), harmonic k of φ′ is fixed at 0 and that of α estimated alone:
/// B's spectrum at k is (1/W, 0, 0) for (αα, αφ′, φ′φ′), W = Σ w_s — the cofactor of
/// the fit constrained to the harmonics the design sees.
#[derive(Clone)]
pub(crate) struct Base {
    faces: usize,
    aa: Vec<f64>,
    pp: Vec<f64>,
    ap: Vec<f64>,
    setup: Vec<f64>,
    effects: usize,
    /// The spectrum, for products by FFT (N ≥ [`DIRECT_BELOW`]); formed on first use.
    spectrum: OnceLock<Spectrum>,
}

/// Below this N, products with B are direct convolutions with the lags (4N² operations)
/// and the lags direct sums: cheaper than planning FFTs.
const DIRECT_BELOW: usize = 64;

/// Per harmonic k: B's (α, α) and (φ′, φ′) eigenvalues `raa`, `rpp` and its (α, φ′)
/// entry `rap` (the DFTs of the lags), and the FFT plans.
#[derive(Clone)]
struct Spectrum {
    raa: Vec<f64>,
    rpp: Vec<f64>,
    rap: Vec<Complex<f64>>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for Base {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Base")
            .field("faces", &self.faces)
            .field("setup", &self.setup)
            .field("effects", &self.effects)
            .finish_non_exhaustive()
    }
}

impl PartialEq for Base {
    fn eq(&self, other: &Self) -> bool {
        self.faces == other.faces
            && self.aa == other.aa
            && self.pp == other.pp
            && self.ap == other.ap
            && self.setup == other.setup
            && self.effects == other.effects
    }
}

/// A stream of a regular design: its face offset d (face = (p + d) mod N + 1) and its
/// readings per position w.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RegularStream {
    pub(crate) offset: usize,
    pub(crate) weight: f64,
}

impl Base {
    /// The regular design's cofactor from its spectrum. Per harmonic k ≠ 0 the normal
    /// equations in (α̂(k), φ̂′(k)) are [[W, t_k], [t̄_k, W]] with W = Σ w_s and
    /// t_k = Σ_s w_s e^{2πi k d_s / N}; their determinant W² − |t_k|² =
    /// Σ_{s,s′} 2 w_s w_s′ sin²(πk(d_s − d_s′)/N) is formed without cancellation. The
    /// caller has checked that no harmonic is lost (the determinant is positive), or
    /// lists in `lost` the harmonics to set to zero (their determinant is 0).
    pub(crate) fn new(
        faces: usize,
        streams: &[RegularStream],
        effects: usize,
        lost: &[usize],
    ) -> Self {
        let n = faces;
        // distinct offsets with their summed weights
        let mut by_offset: Vec<(usize, f64)> = Vec::new();
        for s in streams {
            match by_offset.iter_mut().find(|(d, _)| *d == s.offset % n) {
                Some((_, w)) => *w += s.weight,
                None => by_offset.push((s.offset % n, s.weight)),
            }
        }
        let total: f64 = by_offset.iter().map(|(_, w)| w).sum();
        let (cos, sin) = trig_table(n);
        let mut raa = vec![0.0; n];
        let mut rpp = vec![0.0; n];
        let mut rap = vec![Complex::new(0.0, 0.0); n];
        for k in 1..n {
            if lost.contains(&k) {
                raa[k] = 1.0 / total;
                continue;
            }
            let mut t = Complex::new(0.0, 0.0);
            let mut det = 0.0;
            for (a, &(da, wa)) in by_offset.iter().enumerate() {
                let m = (k * da) % n;
                t += Complex::new(cos[m], sin[m]) * wa;
                for &(db, wb) in &by_offset[a + 1..] {
                    // 2 sin²(πm/N) = 1 − cos(2πm/N), without cancellation near m = 0
                    let m = (k * (da + n - db)) % n;
                    let half = std::f64::consts::PI * m as f64 / n as f64;
                    det += 4.0 * wa * wb * half.sin().powi(2);
                }
            }
            raa[k] = total / det;
            rpp[k] = total / det;
            rap[k] = -t / det;
        }
        let setup = streams
            .iter()
            .map(|s| 1.0 / (n as f64 * s.weight))
            .collect();
        let (aa, pp, ap, spectrum) = if n < DIRECT_BELOW {
            let lag = |j: usize, value: &dyn Fn(usize) -> Complex<f64>| -> f64 {
                (1..n)
                    .map(|k| {
                        let m = (k * j) % n;
                        (value(k) * Complex::new(cos[m], sin[m])).re
                    })
                    .sum::<f64>()
                    / n as f64
            };
            let aa = (0..n)
                .map(|j| lag(j, &|k| Complex::new(raa[k], 0.0)))
                .collect();
            let pp = (0..n)
                .map(|j| lag(j, &|k| Complex::new(rpp[k], 0.0)))
                .collect();
            let ap = (0..n).map(|j| lag(j, &|k| rap[k])).collect();
            (aa, pp, ap, OnceLock::new())
        } else {
            let mut planner = FftPlanner::new();
            let spectrum = Spectrum {
                forward: planner.plan_fft_forward(n),
                inverse: planner.plan_fft_inverse(n),
                raa,
                rpp,
                rap,
            };
            let real_lags = |values: &[f64]| -> Vec<f64> {
                let mut buffer: Vec<Complex<f64>> =
                    values.iter().map(|&v| Complex::new(v, 0.0)).collect();
                inverse_dft(&spectrum, &mut buffer);
                buffer.iter().map(|c| c.re).collect()
            };
            let aa = real_lags(&spectrum.raa);
            let pp = real_lags(&spectrum.rpp);
            let mut buffer = spectrum.rap.clone();
            inverse_dft(&spectrum, &mut buffer);
            let ap = buffer.iter().map(|c| c.re).collect();
            (aa, pp, ap, OnceLock::from(spectrum))
        };
        Self {
            faces: n,
            aa,
            pp,
            ap,
            setup,
            effects,
            spectrum,
        }
    }

    /// A regular design's cofactor from its spectrum, per harmonic k = 0 … N−1: the
    /// (α, α), (φ′, φ′) and (α, φ′) entries of the inverse of that harmonic's normal
    /// equations (k = 0 ignored: the gauge), and the setup diagonal. Self-calibration with
    /// heads off the position grid ([`crate::selfcal`]) forms its spectrum from fractional
    /// phases; [`Base::new`] from the face offsets.
    pub(crate) fn from_spectrum(
        raa: Vec<f64>,
        rpp: Vec<f64>,
        rap: Vec<Complex<f64>>,
        setup: Vec<f64>,
    ) -> Self {
        let n = raa.len();
        let mut planner = FftPlanner::new();
        let mut spectrum = Spectrum {
            forward: planner.plan_fft_forward(n),
            inverse: planner.plan_fft_inverse(n),
            raa,
            rpp,
            rap,
        };
        spectrum.raa[0] = 0.0;
        spectrum.rpp[0] = 0.0;
        spectrum.rap[0] = Complex::new(0.0, 0.0);
        let real_lags = |values: &[f64]| -> Vec<f64> {
            let mut buffer: Vec<Complex<f64>> =
                values.iter().map(|&v| Complex::new(v, 0.0)).collect();
            inverse_dft(&spectrum, &mut buffer);
            buffer.iter().map(|c| c.re).collect()
        };
        let aa = real_lags(&spectrum.raa);
        let pp = real_lags(&spectrum.rpp);
        let mut buffer = spectrum.rap.clone();
        inverse_dft(&spectrum, &mut buffer);
        let ap = buffer.iter().map(|c| c.re).collect();
        Self {
            faces: n,
            aa,
            pp,
            ap,
            setup,
            effects: 0,
            spectrum: OnceLock::from(spectrum),
        }
    }

    /// This cofactor with room for `effects` effect columns after the setups (their
    /// block of B is 0: a bordered inverse adds them through its low-rank part).
    pub(crate) fn with_effects(mut self, effects: usize) -> Self {
        self.effects = effects;
        self
    }

    /// The paper's design (two streams on adjacent faces, offsets d and d + 1, r readings
    /// per step) in closed form: with Cφ(j) = [(N² − 1)/6 − j(N − j)] / (N·r) (the
    /// Green's function of the cycle's second difference),
    /// B[α_p, α_q] = B[φ′_p, φ′_q] = Cφ(|p − q|), B[α_p, φ′_f] = −½[Cφ(j + d) + Cφ(j + d + 1)]
    /// with j = p − f, and B[U′_s, U′_s] = 1/(N·r).
    pub(crate) fn paper(faces: usize, offset: usize, repeats: f64) -> Self {
        let n = faces;
        let nf = n as f64;
        let c = |j: usize| {
            let j = (j % n) as f64;
            ((nf * nf - 1.0) / 6.0 - j * (nf - j)) / (nf * repeats)
        };
        let aa: Vec<f64> = (0..n).map(c).collect();
        Self {
            faces: n,
            pp: aa.clone(),
            aa,
            ap: (0..n)
                .map(|j| -0.5 * (c(j + offset) + c(j + offset + 1)))
                .collect(),
            setup: vec![1.0 / (nf * repeats); 2],
            effects: 0,
            spectrum: OnceLock::new(),
        }
    }

    /// The spectrum: the DFTs of the lags (a circulant's eigenvalues are the DFT of its
    /// first column).
    fn spectrum(&self) -> &Spectrum {
        self.spectrum.get_or_init(|| {
            let n = self.faces;
            let mut planner = FftPlanner::new();
            let forward = planner.plan_fft_forward(n);
            let inverse = planner.plan_fft_inverse(n);
            let mut aa: Vec<Complex<f64>> = self.aa.iter().map(|&v| Complex::new(v, 0.0)).collect();
            forward.process(&mut aa);
            let mut ap: Vec<Complex<f64>> = self.ap.iter().map(|&v| Complex::new(v, 0.0)).collect();
            forward.process(&mut ap);
            let mut pp: Vec<Complex<f64>> = self.pp.iter().map(|&v| Complex::new(v, 0.0)).collect();
            forward.process(&mut pp);
            Spectrum {
                raa: aa.iter().map(|c| c.re).collect(),
                rpp: pp.iter().map(|c| c.re).collect(),
                rap: ap,
                forward,
                inverse,
            }
        })
    }

    fn streams(&self) -> usize {
        self.setup.len()
    }

    fn len(&self) -> usize {
        2 * self.faces + self.streams() + self.effects
    }

    /// B[a, b] in g.
    pub(crate) fn entry(&self, a: usize, b: usize) -> f64 {
        let n = self.faces;
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        // every lag below is already in 0..N (no division): b − a < N within a block,
        // and a + N − (b − N) lies in 1..2N
        if b < n {
            self.aa[b - a]
        } else if a < n && b < 2 * n {
            let lag = a + n - (b - n);
            self.ap[if lag >= n { lag - n } else { lag }]
        } else if b < 2 * n {
            self.pp[b - a]
        } else if a == b && a < 2 * n + self.streams() {
            self.setup[a - 2 * n]
        } else {
            0.0
        }
    }

    /// out += B x in g (O(N log N); direct below [`DIRECT_BELOW`]).
    pub(crate) fn apply_add(&self, x: &[f64], out: &mut [f64]) {
        let n = self.faces;
        let (xa, xp) = (&x[..n], &x[n..2 * n]);
        if n < DIRECT_BELOW {
            // lags laid out twice, so that row p is a contiguous window: aa[(q − p) mod N]
            // and ap[(p − q) mod N] = reversed[(q − p) mod N]
            let twice = |f: &dyn Fn(usize) -> f64| (0..2 * n).map(|j| f(j % n)).collect::<Vec<_>>();
            let aa = twice(&|j| self.aa[j]);
            let pp = twice(&|j| self.pp[j]);
            let ap = twice(&|j| self.ap[j]);
            let reversed = twice(&|j| self.ap[(n - j) % n]);
            for p in 0..n {
                let window = n - p..2 * n - p;
                let (aa, pp, ap, reversed) = (
                    &aa[window.clone()],
                    &pp[window.clone()],
                    &ap[window.clone()],
                    &reversed[window],
                );
                let mut alpha = 0.0;
                let mut phi = 0.0;
                for q in 0..n {
                    alpha += aa[q] * xa[q] + reversed[q] * xp[q];
                    phi += ap[q] * xa[q] + pp[q] * xp[q];
                }
                out[p] += alpha;
                out[n + p] += phi;
            }
        } else {
            let spectrum = self.spectrum();
            let mut fa: Vec<Complex<f64>> = xa.iter().map(|&v| Complex::new(v, 0.0)).collect();
            let mut fp: Vec<Complex<f64>> = xp.iter().map(|&v| Complex::new(v, 0.0)).collect();
            spectrum.forward.process(&mut fa);
            spectrum.forward.process(&mut fp);
            for k in 0..n {
                let (a, p) = (fa[k], fp[k]);
                fa[k] = a * spectrum.raa[k] + p * spectrum.rap[k];
                fp[k] = a * spectrum.rap[k].conj() + p * spectrum.rpp[k];
            }
            inverse_dft(spectrum, &mut fa);
            inverse_dft(spectrum, &mut fp);
            for (o, v) in out[..n].iter_mut().zip(&fa) {
                *o += v.re;
            }
            for (o, v) in out[n..2 * n].iter_mut().zip(&fp) {
                *o += v.re;
            }
        }
        for (s, &d) in self.setup.iter().enumerate() {
            out[2 * n + s] += d * x[2 * n + s];
        }
    }
}

/// x ← (1/N) Σ_k x_k e^{2πi k j / N}.
fn inverse_dft(spectrum: &Spectrum, x: &mut [Complex<f64>]) {
    spectrum.inverse.process(x);
    let scale = 1.0 / x.len() as f64;
    for v in x.iter_mut() {
        *v *= scale;
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

impl Structured {
    /// Q_g = B + W M Wᵀ; `w` column-major (r columns of length 2N + K + E), `m` r × r.
    pub(crate) fn new(base: Base, w: Vec<f64>, m: &DMatrix<f64>) -> Self {
        let low_rank = LowRank::new(base.len(), w, m);
        Self { base, low_rank }
    }

    fn len(&self) -> usize {
        self.base.len()
    }

    /// Q_g[a, b].
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

    /// The rank r of the low-rank part.
    pub(crate) fn rank(&self) -> usize {
        self.low_rank.rank()
    }

    /// The length 2N + K + E of g.
    pub(crate) fn size(&self) -> usize {
        self.len()
    }

    /// N.
    pub(crate) fn faces(&self) -> usize {
        self.base.faces
    }

    /// Column k of W and of W·M (each of length 2N + K + E).
    pub(crate) fn low_rank_column(&self, k: usize) -> (&[f64], &[f64]) {
        self.low_rank.column(k)
    }
}

/// θ = T g: the reported gauge (docs/FORMAT.md §1) from the structured gauge
/// (β_f = φ′_f − φ′_{f−1}, α = α, U_s = U′_s + φ′_N, effects unchanged).
pub(crate) fn theta_from_g(layout: &ParameterLayout, g: &[f64], theta: &mut [f64]) {
    for (i, t) in theta.iter_mut().enumerate() {
        *t = theta_row(layout, i).iter().map(|&(a, c)| c * g[a]).sum();
    }
}

/// The reported θ as a sparse map of g: θ_i = Σ coefficient · g_index.
fn theta_row(layout: &ParameterLayout, i: usize) -> [(usize, f64); 2] {
    let n = layout.faces;
    let none = (0, 0.0);
    if i < n {
        // β_f = φ′_f − φ′_{f−1}
        [(n + i, 1.0), (n + (i + n - 1) % n, -1.0)]
    } else if i < 2 * n {
        [(i - n, 1.0), none]
    } else if i < 2 * n + layout.setups {
        // U_s = U′_s + φ′_N
        [(i, 1.0), (2 * n - 1, 1.0)]
    } else {
        [(i, 1.0), none]
    }
}

impl Cofactor {
    /// A dense cofactor matrix in θ (layout order).
    pub(crate) fn dense(layout: ParameterLayout, matrix: DMatrix<f64>) -> Self {
        Self {
            layout,
            repr: Repr::Dense(matrix),
            encoder_extra: 0.0,
        }
    }

    /// A structured cofactor (module documentation).
    pub(crate) fn structured(layout: ParameterLayout, structured: Structured) -> Self {
        Self {
            layout,
            repr: Repr::Structured(Box::new(structured)),
            encoder_extra: 0.0,
        }
    }

    /// A sub-pitch fit's cofactor from the coset engine ([`super::coset`]).
    pub(crate) fn cosets(layout: ParameterLayout, structured: CosetStructured) -> Self {
        Self {
            layout,
            repr: Repr::Cosets(Box::new(structured)),
            encoder_extra: 0.0,
        }
    }

    /// The layout of θ.
    pub fn layout(&self) -> ParameterLayout {
        self.layout
    }

    /// Length of θ, 2N + K + E.
    pub fn len(&self) -> usize {
        self.layout.len()
    }

    /// Whether θ is empty (never, for a solved polygon).
    pub fn is_empty(&self) -> bool {
        self.layout.is_empty()
    }

    /// Whether the matrix is held densely (the dense reference solver's output).
    pub fn is_dense(&self) -> bool {
        matches!(self.repr, Repr::Dense(_))
    }

    /// The rank of the low-rank part of a structured cofactor (0 for a regular design
    /// without effect terms; `None` when the matrix is dense).
    pub fn low_rank(&self) -> Option<usize> {
        match &self.repr {
            Repr::Dense(_) => None,
            Repr::Structured(s) => Some(s.rank()),
            Repr::Cosets(s) => Some(s.rank()),
        }
    }

    /// Q\[i, j\] in θ ([`ParameterLayout`] indices).
    ///
    /// # Panics
    ///
    /// When i or j is not below [`Cofactor::len`].
    pub fn entry(&self, i: usize, j: usize) -> f64 {
        self.repr_entry(i, j) + self.encoder_extra_entry(i, j)
    }

    /// This cofactor with the variance `extra` (in units of σ², ≥ 0) added to every
    /// encoder error in the closed gauge Σα = 0: `extra`·(I − J/N) on the α block, the
    /// other blocks as they are. A variance the fit's residuals cannot show — the scatter
    /// the autocollimators share at a stop, which no position resolves
    /// ([`crate::diagnose::stop_scatter`]) — enters u(α), the covariance and every product
    /// through it.
    pub fn with_encoder_variance(mut self, extra: f64) -> Self {
        self.encoder_extra += extra.max(0.0);
        self
    }

    /// The variance added to every encoder error, in units of σ²
    /// ([`Cofactor::with_encoder_variance`]; 0 for a fit alone).
    pub fn encoder_variance(&self) -> f64 {
        self.encoder_extra
    }

    fn encoder_extra_entry(&self, i: usize, j: usize) -> f64 {
        if self.encoder_extra == 0.0 {
            return 0.0;
        }
        let n = self.layout.faces;
        let start = self.layout.encoder(0);
        let block = start..start + n;
        if !block.contains(&i) || !block.contains(&j) {
            return 0.0;
        }
        let delta = if i == j { 1.0 } else { 0.0 };
        self.encoder_extra * (delta - 1.0 / n as f64)
    }

    fn repr_entry(&self, i: usize, j: usize) -> f64 {
        match &self.repr {
            Repr::Dense(m) => m[(i, j)],
            Repr::Structured(s) => {
                let mut v = 0.0;
                for (a, ca) in theta_row(&self.layout, i) {
                    if ca == 0.0 {
                        continue;
                    }
                    for (b, cb) in theta_row(&self.layout, j) {
                        if cb != 0.0 {
                            v += ca * cb * s.entry(a, b);
                        }
                    }
                }
                v
            }
            Repr::Cosets(s) => s.theta_entry(&self.layout, i, j),
        }
    }

    /// The diagonal of Q in θ.
    pub fn diagonal(&self) -> Vec<f64> {
        (0..self.len()).map(|i| self.entry(i, i)).collect()
    }

    /// The cofactors of the face deviations φ\[1..=N\] of the reported gauge (φ\[N\] = 0):
    /// Q_φ\[f\] = Σ_{i,j ≤ f} Q\[β_i, β_j\].
    pub fn face_deviation_diagonal(&self) -> Vec<f64> {
        let n = self.layout.faces;
        match &self.repr {
            Repr::Dense(m) => {
                // φ[f] = φ[f−1] + β[f]: var φ[f] = var φ[f−1] + 2 Σ_{j<f} Q[j, f] + Q[f, f]
                let mut out = Vec::with_capacity(n);
                let mut var = 0.0;
                for f in 0..n {
                    let border: f64 = (0..f).map(|j| m[(j, f)]).sum();
                    var += 2.0 * border + m[(f, f)];
                    out.push(var);
                }
                if let Some(last) = out.last_mut() {
                    *last = 0.0;
                }
                out
            }
            Repr::Structured(s) => {
                // φ_f = φ′_f − φ′_N
                let last = 2 * n - 1;
                let q_last = s.entry(last, last);
                (0..n)
                    .map(|f| {
                        if f == n - 1 {
                            0.0
                        } else {
                            s.entry(n + f, n + f) + q_last - 2.0 * s.entry(n + f, last)
                        }
                    })
                    .collect()
            }
            Repr::Cosets(s) => {
                // φ_f = φ′_f − φ′_N
                let last = s.phi(n - 1);
                let q_last = s.entry(last, last);
                (0..n)
                    .map(|f| {
                        if f == n - 1 {
                            0.0
                        } else {
                            let a = s.phi(f);
                            s.entry(a, a) + q_last - 2.0 * s.entry(a, last)
                        }
                    })
                    .collect()
            }
        }
    }

    /// Variances (in units of σ²) of the face deviations in the gauge Σφ = 0, φ_f − φ̄: the
    /// disc's graduation error of a self-calibration ([`crate::selfcal`]). Structured,
    /// that is the φ′ block's diagonal; dense, var φ_f − 2 cov(φ_f, φ̄) + var φ̄ with one
    /// product Q·x.
    pub fn centered_face_deviation_diagonal(&self) -> Vec<f64> {
        let n = self.layout.faces;
        if let Repr::Structured(s) = &self.repr {
            return (0..n).map(|f| s.entry(n + f, n + f)).collect();
        }
        if let Repr::Cosets(s) = &self.repr {
            return (0..n).map(|f| s.entry(s.phi(f), s.phi(f))).collect();
        }
        // φ = T β (T the cumulative sum): cov(φ, φ̄) = T Q_ββ Tᵀ 1/N, with (Tᵀ 1)_i = N − i
        let mut x = vec![0.0; self.len()];
        for (i, v) in x[..n].iter_mut().enumerate() {
            *v = (n - i) as f64 / n as f64;
        }
        let y = self.apply(&x);
        let mut cov = Vec::with_capacity(n);
        let mut running = 0.0;
        for v in &y[..n] {
            running += v;
            cov.push(running);
        }
        let var_mean = cov.iter().sum::<f64>() / n as f64;
        self.face_deviation_diagonal()
            .into_iter()
            .zip(&cov)
            .map(|(var, c)| var - 2.0 * c + var_mean)
            .collect()
    }

    /// Q·x for a vector x in θ (O(N log N + (2N + K)·r) when structured, O((2N + K)²)
    /// when dense).
    ///
    /// # Panics
    ///
    /// When x does not have [`Cofactor::len`] values.
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        assert_eq!(x.len(), self.len(), "a vector of θ's length");
        let mut out = self.repr_apply(x);
        if self.encoder_extra != 0.0 {
            let n = self.layout.faces;
            let start = self.layout.encoder(0);
            let mean = x[start..start + n].iter().sum::<f64>() / n as f64;
            for p in start..start + n {
                out[p] += self.encoder_extra * (x[p] - mean);
            }
        }
        out
    }

    fn repr_apply(&self, x: &[f64]) -> Vec<f64> {
        match &self.repr {
            Repr::Dense(m) => (0..self.len())
                .map(|i| m.row(i).iter().zip(x).map(|(a, b)| a * b).sum())
                .collect(),
            Repr::Structured(s) => {
                // Tᵀ x, Q_g, T
                let mut g = vec![0.0; self.len()];
                for (i, &v) in x.iter().enumerate() {
                    for (a, c) in theta_row(&self.layout, i) {
                        g[a] += c * v;
                    }
                }
                let qg = s.apply(&g);
                (0..self.len())
                    .map(|i| {
                        theta_row(&self.layout, i)
                            .iter()
                            .map(|&(a, c)| c * qg[a])
                            .sum()
                    })
                    .collect()
            }
            Repr::Cosets(s) => s.theta_apply(&self.layout, x),
        }
    }

    /// Bytes the dense matrix takes ((2N + K + E)² values).
    pub fn dense_bytes(&self) -> u128 {
        (self.len() as u128).pow(2) * 8
    }

    /// The whole matrix in θ. It takes [`Cofactor::dense_bytes`] of memory and
    /// O((2N + K + E)²·r) work when structured: for callers that need every entry.
    pub fn to_dense(&self) -> DMatrix<f64> {
        let mut q = self.repr_dense();
        if self.encoder_extra != 0.0 {
            let n = self.layout.faces;
            let start = self.layout.encoder(0);
            for i in start..start + n {
                for j in start..start + n {
                    q[(i, j)] += self.encoder_extra_entry(i, j);
                }
            }
        }
        q
    }

    fn repr_dense(&self) -> DMatrix<f64> {
        match &self.repr {
            Repr::Dense(m) => m.clone(),
            Repr::Structured(s) => {
                let len = self.len();
                // Q_g = B + W (W M)ᵀ, then Q = T Q_g Tᵀ by rows and by columns
                let mut qg = DMatrix::from_fn(len, len, |a, b| s.base.entry(a, b));
                s.low_rank.add_to_dense(&mut qg);
                let map: Vec<[(usize, f64); 2]> =
                    (0..len).map(|i| theta_row(&self.layout, i)).collect();
                let mut rows = DMatrix::<f64>::zeros(len, len);
                for j in 0..len {
                    let source = qg.column(j);
                    for (target, terms) in rows.column_mut(j).iter_mut().zip(&map) {
                        *target = terms.iter().map(|&(a, c)| c * source[a]).sum();
                    }
                }
                let mut q = DMatrix::<f64>::zeros(len, len);
                for j in 0..len {
                    for (b, c) in theta_row(&self.layout, j) {
                        if c != 0.0 {
                            let source = rows.column(b).clone_owned();
                            q.column_mut(j).axpy(c, &source, 1.0);
                        }
                    }
                }
                q
            }
            Repr::Cosets(s) => s.theta_dense(&self.layout),
        }
    }

    /// The structured form of a closure fit on one coset, when there is one.
    pub(crate) fn as_structured(&self) -> Option<&Structured> {
        match &self.repr {
            Repr::Structured(s) => Some(s),
            Repr::Dense(_) | Repr::Cosets(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper design's closed-form lags equal the FFT route's, for several N, offsets
    /// and repeats: the Green's function identity Σ_{k≠0} cos(2πkj/N)/(1 − cos(2πk/N)) =
    /// (N² − 1)/6 − j(N − j) checked numerically.
    #[test]
    fn paper_lags_equal_the_spectrum() {
        for (n, d, r) in [
            (3, 0, 1.0),
            (7, 2, 3.0),
            (24, 0, 1.0),
            (24, 5, 6.0),
            (100, 99, 2.0),
        ] {
            let fft = Base::new(
                n,
                &[
                    RegularStream {
                        offset: d,
                        weight: r,
                    },
                    RegularStream {
                        offset: d + 1,
                        weight: r,
                    },
                ],
                0,
                &[],
            );
            let paper = Base::paper(n, d, r);
            for j in 0..n {
                assert!((fft.aa[j] - paper.aa[j]).abs() < 1e-11, "aa {n} {j}");
                assert!((fft.ap[j] - paper.ap[j]).abs() < 1e-11, "ap {n} {j}");
            }
            // Σα = 0: each row of the circulant sums to 0
            assert!(paper.aa.iter().sum::<f64>().abs() < 1e-9);
        }
    }
}
