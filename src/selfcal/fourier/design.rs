//! The closure model of heads off the position grid as a linear design: its product X·g
//! and its transpose Xᵀ·x, and a least-squares fit of any readings with effect columns
//! beside it, in near-linear time (the diagnosis of such a self-calibration,
//! [`crate::diagnose::selfcal`]).
//!
//! In g = [α (P), φ′ (P), U′ (M), effects (E)] the reading of head j at step p is
//!
//! ```text
//! y = α[p] + (S_j φ′)[p] + U′_j + Σ_e x_e · g_e,      S_j φ′ = IDFT(z_j(k) · DFT(φ′))
//! ```
//!
//! with z_j(k) the head's fractional phase (module documentation of the parent): S_j
//! reads the band-limited disc error at the head's fractional positions, and is a real
//! circulant, so Sⱼᵀ has the spectrum z̄_j(k). Every product costs M FFTs of length P
//! plus O(n·E).
//!
//! With every (head, step) cell read equally often (a self-calibration file reads every
//! step with every head in every cycle) the base model's normal equations are, harmonic
//! by harmonic, the 2 × 2 system of [`super::OffGridMap`], and their inverse B — the
//! cofactor in the gauge Σα = Σφ′ = 0, the lost harmonics of φ′ fixed at 0 — is the
//! engine's regular part built from that spectrum. Effect columns are added by the
//! bordered inverse (the circulant engine's form, [`crate::solve::circulant`]):
//!
//! ```text
//! F = X₀ᵀ X_e,  Y = B F,  S = X_eᵀ X_e − Fᵀ Y,  Q_g = B + W S⁻¹ Wᵀ,  W = [Y; −I]
//! ```
//!
//! and g = Q_g Xᵀy, followed by one step of iterative refinement (g += Q_g Xᵀ(y − X g)).

use std::sync::Arc;

use nalgebra::DMatrix;
use rustfft::num_complex::Complex;
use rustfft::{Fft, FftPlanner};

use super::{OffGridMap, phase};
use crate::measurement::{MeasurementSet, Sigma};
use crate::polygon::face_deviation_from_pitch;
use crate::solve::cofactor::{Base, Cofactor, Structured};
use crate::solve::observability::Unobservable;
use crate::solve::{
    Engine, Method, ParameterLayout, SetupError, Solution, SolveError, choose_sigma,
};
use crate::uncertainty::calibration::CellMap;

/// The band-limited closure design of heads at fractional position offsets (module
/// documentation), for the readings of one closure set.
#[derive(Clone)]
pub(crate) struct OffGridDesign {
    /// P.
    positions: usize,
    /// The heads' numbers (the closure set's autocollimators), ascending.
    heads: Vec<u32>,
    /// z_j(k) at k·M + j.
    phases: Vec<Complex<f64>>,
    /// Every reading's head index j and step p.
    reading_head: Vec<usize>,
    reading_step: Vec<usize>,
    /// The base model's cofactor B (no effect columns).
    base: Base,
    /// The spectrum's lost harmonics k (φ′ fixed at 0 there).
    lost: Vec<usize>,
    forward: Arc<dyn Fft<f64>>,
    inverse: Arc<dyn Fft<f64>>,
}

impl std::fmt::Debug for OffGridDesign {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OffGridDesign")
            .field("positions", &self.positions)
            .field("heads", &self.heads)
            .field("readings", &self.reading_head.len())
            .field("lost", &self.lost)
            .finish()
    }
}

impl OffGridDesign {
    /// The design of `set` (a closure set: the heads as its autocollimators, the disc's
    /// positions as its steps) with head `heads[j]` at the fractional offset `offsets[j]`
    /// (positions). `None` when a reading's head is not among `heads` or the cells are not
    /// read equally often by every head (then B is not the inverse of the normal
    /// equations).
    pub(crate) fn new(set: &MeasurementSet, heads: &[u32], offsets: &[f64]) -> Option<Self> {
        let p = set.faces;
        let m = heads.len();
        if p == 0 || m == 0 || offsets.len() != m {
            return None;
        }
        let mut count = vec![0usize; m * p];
        let mut reading_head = Vec::with_capacity(set.readings.len());
        let mut reading_step = Vec::with_capacity(set.readings.len());
        for r in &set.readings {
            let j = heads.binary_search(&r.ac).ok()?;
            let step = r.step % p;
            count[j * p + step] += 1;
            reading_head.push(j);
            reading_step.push(step);
        }
        for j in 0..m {
            let cells = &count[j * p..(j + 1) * p];
            if cells[0] == 0 || cells.iter().any(|&c| c != cells[0]) {
                return None;
            }
        }
        let map = OffGridMap::new(p, offsets, &count);
        let setup = map.weight.iter().map(|w| 1.0 / (p as f64 * w)).collect();
        let base = Base::from_spectrum(map.raa.clone(), map.rpp.clone(), map.rap.clone(), setup);
        let mut phases = vec![Complex::new(0.0, 0.0); p * m];
        for k in 0..p {
            for (j, &delta) in offsets.iter().enumerate() {
                phases[k * m + j] = if k == 0 {
                    Complex::new(1.0, 0.0)
                } else {
                    phase(p, k, delta)
                };
            }
        }
        let mut planner = FftPlanner::<f64>::new();
        Some(Self {
            positions: p,
            heads: heads.to_vec(),
            phases,
            reading_head,
            reading_step,
            base,
            lost: map.lost,
            forward: planner.plan_fft_forward(p),
            inverse: planner.plan_fft_inverse(p),
        })
    }

    /// P.
    pub(crate) fn positions(&self) -> usize {
        self.positions
    }

    /// M.
    pub(crate) fn heads(&self) -> usize {
        self.heads.len()
    }

    /// The number of readings.
    pub(crate) fn readings(&self) -> usize {
        self.reading_head.len()
    }

    /// Reading i's head index and step.
    pub(crate) fn cell(&self, i: usize) -> (usize, usize) {
        (self.reading_head[i], self.reading_step[i])
    }

    /// The harmonics k of φ′ fixed at 0 (the layout cannot see them).
    pub(crate) fn lost(&self) -> &[usize] {
        &self.lost
    }

    /// The length of g with `effects` effect columns.
    pub(crate) fn size(&self, effects: usize) -> usize {
        2 * self.positions + self.heads.len() + effects
    }

    /// Every head's view of a disc error: (S_j φ′)[p] for j = 0 … M−1, each of length P.
    pub(crate) fn views(&self, phi: &[f64]) -> Vec<Vec<f64>> {
        let (p, m) = (self.positions, self.heads.len());
        let mut spectrum: Vec<Complex<f64>> = phi.iter().map(|&v| Complex::new(v, 0.0)).collect();
        self.forward.process(&mut spectrum);
        (0..m)
            .map(|j| {
                let mut shifted: Vec<Complex<f64>> = (0..p)
                    .map(|k| spectrum[k] * self.phases[k * m + j])
                    .collect();
                self.inverse.process(&mut shifted);
                shifted.iter().map(|c| c.re / p as f64).collect()
            })
            .collect()
    }

    /// Σ_j Sⱼᵀ h_j for per-head vectors `h` (h[j·P + p]).
    fn transposed_views(&self, h: &[f64]) -> Vec<f64> {
        let (p, m) = (self.positions, self.heads.len());
        let mut total = vec![Complex::new(0.0, 0.0); p];
        let mut buffer = vec![Complex::new(0.0, 0.0); p];
        for j in 0..m {
            for (b, &v) in buffer.iter_mut().zip(&h[j * p..(j + 1) * p]) {
                *b = Complex::new(v, 0.0);
            }
            self.forward.process(&mut buffer);
            for k in 0..p {
                total[k] += buffer[k] * self.phases[k * m + j].conj();
            }
        }
        self.inverse.process(&mut total);
        total.iter().map(|c| c.re / p as f64).collect()
    }

    /// The design row in g of one reading of head `head` at `step` (its effect values
    /// 0), with room for `effects` effect columns.
    pub(crate) fn unit_row(&self, head: usize, step: usize, effects: usize) -> Vec<f64> {
        let p = self.positions;
        let mut g = vec![0.0; self.size(effects)];
        let mut h = vec![0.0; self.heads.len() * p];
        h[head * p + step] = 1.0;
        g[step] = 1.0;
        g[p..2 * p].copy_from_slice(&self.transposed_views(&h));
        g[2 * p + head] = 1.0;
        g
    }

    /// Xᵀx: a vector of readings `x` summed into g, with the effect `columns`.
    pub(crate) fn transpose(&self, x: &[f64], columns: &[Vec<f64>]) -> Vec<f64> {
        let (p, m) = (self.positions, self.heads.len());
        let mut g = vec![0.0; self.size(columns.len())];
        let mut h = vec![0.0; m * p];
        for (i, &xi) in x.iter().enumerate() {
            let (j, step) = (self.reading_head[i], self.reading_step[i]);
            g[step] += xi;
            h[j * p + step] += xi;
            g[2 * p + j] += xi;
        }
        let phi = self.transposed_views(&h);
        g[p..2 * p].copy_from_slice(&phi);
        for (e, column) in columns.iter().enumerate() {
            g[2 * p + m + e] = column.iter().zip(x).map(|(a, b)| a * b).sum();
        }
        g
    }

    /// X·g: the model's value at every reading for parameters `g`, with the effect
    /// `columns`.
    pub(crate) fn model(&self, g: &[f64], columns: &[Vec<f64>]) -> Vec<f64> {
        let (p, m) = (self.positions, self.heads.len());
        let views = self.views(&g[p..2 * p]);
        (0..self.reading_head.len())
            .map(|i| {
                let (j, step) = (self.reading_head[i], self.reading_step[i]);
                let mut value = g[step] + views[j][step] + g[2 * p + j];
                for (e, column) in columns.iter().enumerate() {
                    value += g[2 * p + m + e] * column[i];
                }
                value
            })
            .collect()
    }

    /// The least-squares fit of `values` (one per reading) with the effect `columns`
    /// (module documentation), reported as a closure model's [`Solution`]: φ in the
    /// reported gauge (φ_P = 0), α, the heads as setup errors (setup 1), the effects.
    /// Its degrees of freedom are the readings less 2P − 2 + M + E parameters, each lost
    /// harmonic one fewer.
    ///
    /// # Errors
    ///
    /// [`SolveError::BadRegressor`] for a column of the wrong length or with a value that
    /// is not finite, [`SolveError::Unobservable`] when the effect columns are not
    /// separable from the model and each other.
    pub(crate) fn fit(
        &self,
        values: &[f64],
        columns: &[Vec<f64>],
        stated_sigma: Option<Sigma>,
    ) -> Result<Solution, SolveError> {
        let n = self.readings();
        for (index, column) in columns.iter().enumerate() {
            if column.len() != n || column.iter().any(|v| !v.is_finite()) {
                return Err(SolveError::BadRegressor {
                    index,
                    reason: format!(
                        "{} values for {n} readings, or a value that is not finite",
                        column.len()
                    ),
                });
            }
        }
        let (p, m, e) = (self.positions, self.heads.len(), columns.len());
        let base_len = 2 * p + m;
        let len = base_len + e;
        let base = self.base.clone().with_effects(e);
        // F, Y = B F and the Schur complement S
        let mut w = vec![0.0; len * e];
        let mut schur = DMatrix::<f64>::zeros(e, e);
        let mut f = Vec::with_capacity(e);
        for (a, column) in columns.iter().enumerate() {
            let mut fa = self.transpose(column, &[]);
            fa.resize(len, 0.0);
            let mut y = vec![0.0; len];
            base.apply_add(&fa, &mut y);
            let target = &mut w[a * len..(a + 1) * len];
            target[..base_len].copy_from_slice(&y[..base_len]);
            target[base_len + a] = -1.0;
            f.push(fa);
        }
        for a in 0..e {
            for b in 0..e {
                let xx: f64 = columns[a].iter().zip(&columns[b]).map(|(x, y)| x * y).sum();
                let fy: f64 = f[a][..base_len]
                    .iter()
                    .zip(&w[b * len..b * len + base_len])
                    .map(|(x, y)| x * y)
                    .sum();
                schur[(a, b)] = xx - fy;
            }
        }
        let schur_inverse = if e > 0 {
            let scale = (0..e)
                .map(|a| columns[a].iter().map(|x| x * x).sum::<f64>())
                .fold(0.0_f64, f64::max);
            let cholesky = schur.clone().cholesky().filter(|c| {
                let l = c.l_dirty();
                let smallest = (0..e)
                    .map(|j| l[(j, j)].powi(2))
                    .fold(f64::INFINITY, f64::min);
                scale > 0.0 && smallest > 1e-10 * scale
            });
            match cholesky {
                Some(c) => c.inverse(),
                None => {
                    return Err(SolveError::Unobservable(Unobservable {
                        harmonics: Vec::new(),
                        effects: (0..e).collect(),
                        message: "the effect terms cannot be separated from the self-calibration's model and from each other".into(),
                    }));
                }
            }
        } else {
            DMatrix::zeros(0, 0)
        };
        let structured = Structured::new(base, w, &schur_inverse);
        let mut g = structured.apply(&self.transpose(values, columns));
        // one step of iterative refinement
        let model = self.model(&g, columns);
        let residuals: Vec<f64> = values.iter().zip(&model).map(|(y, f)| y - f).collect();
        for (g, d) in g
            .iter_mut()
            .zip(structured.apply(&self.transpose(&residuals, columns)))
        {
            *g += d;
        }
        let model = self.model(&g, columns);
        let residuals: Vec<f64> = values.iter().zip(&model).map(|(y, f)| y - f).collect();

        // θ in the reported gauge (docs/FORMAT.md §1): φ = φ′ − φ′_P, U = U′ + φ′_P
        let phi_last = g[2 * p - 1];
        let pitch_deviation: Vec<f64> = (0..p).map(|i| g[p + i] - g[p + (i + p - 1) % p]).collect();
        let face_deviation = face_deviation_from_pitch(&pitch_deviation);
        let rss: f64 = residuals.iter().map(|v| v * v).sum();
        let dof = (n + self.lost.len()).saturating_sub(2 * p - 2 + m + e);
        let layout = ParameterLayout {
            faces: p,
            setups: m,
            effects: e,
        };
        Ok(Solution {
            faces: p,
            method: Method::LeastSquares,
            engine: Engine::Circulant { low_rank: e },
            pitch_deviation,
            face_deviation,
            encoder_error: g[..p].to_vec(),
            setup_error: self
                .heads
                .iter()
                .enumerate()
                .map(|(j, &ac)| SetupError {
                    setup: 1,
                    ac,
                    value: g[2 * p + j] + phi_last,
                })
                .collect(),
            effect_values: g[base_len..].to_vec(),
            effect_regressors: columns.to_vec(),
            residuals,
            readings: n,
            dof,
            rss,
            sigma: choose_sigma(rss, dof, stated_sigma),
            cofactor: Cofactor::structured(layout, structured),
            layout,
            incomplete_cycles: Vec::new(),
        })
    }
}

/// A fit of the band-limited design with effect columns as a linear map of the readings
/// (every reading its own cell): g = Q_g Xᵀy with the fit's cofactor and columns, the
/// outputs as [`super::OffGridMap`] gives them. What a Monte Carlo trial of a diagnosed
/// self-calibration's final model solves.
pub(crate) struct OffGridFitMap {
    design: OffGridDesign,
    q: Structured,
    columns: Vec<Vec<f64>>,
}

impl OffGridFitMap {
    /// The map of `fit`, a fit of `design`'s readings by [`OffGridDesign::fit`]; `None`
    /// when its cofactor is not that fit's.
    pub(crate) fn new(design: OffGridDesign, fit: &Solution) -> Option<Self> {
        let q = fit.cofactor.as_structured()?.clone();
        let columns = fit.effect_regressors.clone();
        (q.size() == design.size(columns.len())
            && columns.iter().all(|c| c.len() == design.readings()))
        .then_some(Self { design, q, columns })
    }
}

/// The outputs of one trial's readings: β, φ\[1..P−1\] and α in the reported gauge, then
/// the heads' constants U_j = U′_j + φ′_P.
impl CellMap for OffGridFitMap {
    fn solve(&self, readings: &[f64], out: &mut [f64]) {
        let p = self.design.positions;
        let g = self
            .q
            .apply(&self.design.transpose(readings, &self.columns));
        let last = g[2 * p - 1];
        let (beta, rest) = out.split_at_mut(p);
        let (phi, rest) = rest.split_at_mut(p - 1);
        let (alpha, setups) = rest.split_at_mut(p);
        let mut previous = 0.0;
        for (f, b) in beta.iter_mut().enumerate() {
            let phi_f = g[p + f] - last;
            *b = phi_f - previous;
            previous = phi_f;
        }
        for (o, v) in phi.iter_mut().zip(&g[p..2 * p]) {
            *o = v - last;
        }
        alpha.copy_from_slice(&g[..p]);
        for (o, u) in setups
            .iter_mut()
            .zip(&g[2 * p..2 * p + self.design.heads.len()])
        {
            *o = u + last;
        }
    }
}
