//! The circulant engine: least squares for closure designs in near-linear time.
//!
//! In a design where every stream (autocollimator × mounting) reads every encoder
//! position equally often — w_s readings per position for stream s — the normal
//! equations of the model (docs/FORMAT.md §1, the paper's eq. (2)) decouple by Fourier
//! harmonic: after the setup errors are eliminated, harmonic k ≠ 0 of (α, φ) solves a
//! 2 × 2 system ([`super::cofactor`]). That is the design's *regular part*, with cofactor B
//! in the gauge Σα = 0, Σφ′ = 0.
//!
//! What breaks the symmetry is a low-rank correction:
//!
//! - a (stream, position) cell read n_sp ≠ w_s times (closing readings, missing or
//!   repeated readings) adds (n_sp − w_s)·x xᵀ to the normal matrix, x the cell's design
//!   row: Woodbury, with the capacitance D⁻¹ + VᵀBV of one row and column per cell;
//! - the effect columns border the system: their Schur complement ZᵀZ − Fᵀ Q_A F.
//!
//! The cofactor is then Q_g = B + W M Wᵀ with W = [B V, Q_A F] and
//! M = diag(−(D⁻¹ + VᵀBV)⁻¹, S_e⁻¹), the estimates g = Q_g Xᵀy, and the penalty that fixes
//! the gauge cancels exactly (the design rows are orthogonal to the gauge directions).
//! The work is O(N log N) for the regular part plus O((2N + K)·r + r³) for r corrections
//! and effect terms, against O(N³) for the dense reference ([`super::dense`]), which the
//! tests hold this engine to.

use nalgebra::DMatrix;

use super::cofactor::{Base, RegularStream, Structured};
use super::observability::{describe, lost_harmonics};
use super::{
    Cofactor, Engine, Method, ParameterLayout, SetupError, Solution, SolveError, woodbury,
};
use crate::measurement::{MeasurementSet, Sigma};
use crate::polygon::face_deviation_from_pitch;

/// A design the circulant engine serves: its regular part and the cells that differ.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CirculantPlan {
    /// Readings per position of each stream in the regular part (≥ 1).
    weights: Vec<f64>,
    /// Face offset of each stream.
    offsets: Vec<usize>,
    /// (stream, position, n_sp − w_s) for every cell read a different number of times.
    corrections: Vec<(usize, usize, f64)>,
    effects: usize,
    /// Harmonics the offsets lose, set to zero in φ′ (self-calibration only; empty
    /// otherwise).
    pub(crate) lost: Vec<usize>,
}

impl CirculantPlan {
    /// The rank r of the low-rank part: corrections plus effect terms.
    pub(crate) fn rank(&self) -> usize {
        self.corrections.len() + self.effects
    }

    /// Bytes the engine needs: W and W·M ((2N + K + E)·r each), F, B·F and Q_A·F
    /// ((2N + K)·E each), the capacitance and its inverse (r² each), the regular part
    /// (a few N) and, per reading, its design row, stream and residual (the copy of the
    /// effect columns the solution keeps: E per reading).
    pub(crate) fn bytes_needed(&self, faces: usize, readings: usize) -> u128 {
        let streams = self.weights.len() as u128;
        let e = self.effects as u128;
        let len = 2 * faces as u128 + streams + e;
        let r = self.rank() as u128;
        let per_reading = 5 + e;
        8 * (2 * len * r
            + 3 * len * e
            + 3 * r * r
            + 12 * faces as u128
            + 4 * len
            + per_reading * readings as u128)
    }

    /// Work of the engine relative to the dense path, for the choice between them.
    pub(crate) fn is_cheaper_than_dense(&self, faces: usize) -> bool {
        let len = 2 * faces + self.weights.len() + self.effects;
        self.rank() <= (len / 4).max(16)
    }
}

/// How the circulant engine sees a design: its plan, or why it does not serve it.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Plan {
    /// The engine serves it.
    Circulant(CirculantPlan),
    /// A stream reads most positions zero times: no regular part.
    NoRegularPart,
    /// The face offsets lose these harmonics; with effect terms the dense path says
    /// which effect terms are lost with them.
    Lost(Vec<usize>),
}

/// Counts of every (stream, position) cell; plans the engine, or refuses a design that
/// leaves a position unread or loses harmonics (by the rule of the face offsets). With
/// `zero_lost`, harmonics lost by that rule are planned to be set to zero instead
/// (self-calibration: a head layout always loses some).
pub(crate) fn plan(
    set: &MeasurementSet,
    streams: &[(u32, u32)],
    effects: usize,
    zero_lost: bool,
) -> Result<Plan, SolveError> {
    let n = set.faces;
    let k = streams.len();
    let mut count = vec![0u32; k * n];
    for r in &set.readings {
        let s = stream_index(streams, r.setup, r.ac);
        count[s * n + r.position(n)] += 1;
    }
    if let Some(p) = (0..n).find(|&p| (0..k).all(|s| count[s * n + p] == 0)) {
        return Err(super::Unobservable::position_unread(p, n).into());
    }
    let offsets: Vec<usize> = set.face_offsets().into_iter().map(|(_, d)| d).collect();
    let mut weights = Vec::with_capacity(k);
    let mut corrections = Vec::new();
    for s in 0..k {
        let mode = woodbury::regular_weight(s, &count[s * n..(s + 1) * n], &mut corrections);
        if mode == 0 {
            return Ok(Plan::NoRegularPart);
        }
        weights.push(f64::from(mode));
    }
    let lost = lost_harmonics(n, &offsets);
    if !lost.is_empty() {
        // the rule names everything lost when nothing is missing and no effect term can
        // add to it; otherwise the dense path's null space does. Set to zero, the rule's
        // harmonics stay lost whatever effect terms are added (a term the data cannot
        // separate makes the solve singular, and the dense path names it).
        let complete = corrections.iter().all(|&(_, _, delta)| delta > 0.0);
        let by_rule = effects == 0 && complete;
        if complete && zero_lost {
            return Ok(Plan::Circulant(CirculantPlan {
                weights,
                offsets,
                corrections,
                effects,
                lost,
            }));
        }
        if by_rule {
            return Err(describe(lost, Vec::new(), set).into());
        }
        return Ok(Plan::Lost(lost));
    }
    Ok(Plan::Circulant(CirculantPlan {
        weights,
        offsets,
        corrections,
        effects,
        lost: Vec::new(),
    }))
}

/// A design the engine serves, with what it forms from the design alone — its streams,
/// plan, regular cofactor B and every reading's stream — kept for fits of it that
/// differ only in their effect columns (the diagnosis refits the base model with each
/// round's terms: [`crate::diagnose`]).
#[derive(Clone)]
pub(crate) struct Prepared {
    streams: Vec<(u32, u32)>,
    /// The plan without effect terms ([`CirculantPlan::with_effects`] adds them).
    plan: CirculantPlan,
    base: Base,
    reading_stream: Vec<usize>,
}

impl std::fmt::Debug for Prepared {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Prepared")
            .field("streams", &self.streams)
            .field("plan", &self.plan)
            .finish_non_exhaustive()
    }
}

impl Prepared {
    /// `set`'s design prepared, when the engine serves it with every harmonic seen (the
    /// plan is then the same whatever the effect terms); `None` otherwise (the caller
    /// fits by [`super::least_squares`]'s decision) and for a design that is refused.
    pub(crate) fn of(set: &MeasurementSet) -> Option<Self> {
        let streams = set.streams();
        let Ok(Plan::Circulant(plan)) = plan(set, &streams, 0, false) else {
            return None;
        };
        if !plan.lost.is_empty() {
            return None;
        }
        let base = regular_base(set.faces, &plan);
        let reading_stream = set
            .readings
            .iter()
            .map(|r| stream_index(&streams, r.setup, r.ac))
            .collect();
        Some(Self {
            streams,
            plan,
            base,
            reading_stream,
        })
    }

    /// The streams, in [`MeasurementSet::streams`] order.
    pub(crate) fn streams(&self) -> &[(u32, u32)] {
        &self.streams
    }

    /// The plan with `effects` effect terms.
    pub(crate) fn plan(&self, effects: usize) -> CirculantPlan {
        CirculantPlan {
            effects,
            ..self.plan.clone()
        }
    }

    /// [`solve`] of `set` (the set prepared) with the effect columns `regressors`.
    pub(crate) fn solve(
        &self,
        set: &MeasurementSet,
        regressors: &[Vec<f64>],
        stated_sigma: Option<Sigma>,
    ) -> Result<Option<Solution>, SolveError> {
        let plan = self.plan(regressors.len());
        let base = self.base.clone().with_effects(regressors.len());
        solve_on(
            set,
            &self.streams,
            &plan,
            base,
            &self.reading_stream,
            regressors,
            stated_sigma,
        )
    }
}

/// The regular part's cofactor B of a planned design (no effect terms).
fn regular_base(faces: usize, plan: &CirculantPlan) -> Base {
    Base::new(
        faces,
        &plan
            .offsets
            .iter()
            .zip(&plan.weights)
            .map(|(&offset, &weight)| RegularStream { offset, weight })
            .collect::<Vec<_>>(),
        0,
        &plan.lost,
    )
}

fn stream_index(streams: &[(u32, u32)], setup: u32, ac: u32) -> usize {
    streams
        .binary_search(&(setup, ac))
        .unwrap_or_else(|_| unreachable!("every stream was listed"))
}

/// Solves the planned design. `Ok(None)` when the corrections or the effect terms make
/// the system singular (missing readings, an effect the data cannot separate): the
/// caller then asks the dense path, which names what is lost.
pub(crate) fn solve(
    set: &MeasurementSet,
    streams: &[(u32, u32)],
    plan: &CirculantPlan,
    regressors: &[Vec<f64>],
    stated_sigma: Option<Sigma>,
) -> Result<Option<Solution>, SolveError> {
    let base = regular_base(set.faces, plan).with_effects(regressors.len());
    let reading_stream: Vec<usize> = set
        .readings
        .iter()
        .map(|r| stream_index(streams, r.setup, r.ac))
        .collect();
    solve_on(
        set,
        streams,
        plan,
        base,
        &reading_stream,
        regressors,
        stated_sigma,
    )
}

/// [`solve`] with the regular part's cofactor `base` (room for the effect terms) and
/// every reading's stream (an index into `streams`) formed.
fn solve_on(
    set: &MeasurementSet,
    streams: &[(u32, u32)],
    plan: &CirculantPlan,
    base: Base,
    reading_stream: &[usize],
    regressors: &[Vec<f64>],
    stated_sigma: Option<Sigma>,
) -> Result<Option<Solution>, SolveError> {
    let n = set.faces;
    let k = streams.len();
    let e = regressors.len();
    let design = Normal::of(set, k, reading_stream, regressors);
    let (base_len, len) = (design.base_len, design.len);

    // Woodbury: W1 = B V, C1 = D⁻¹ + Vᵀ B V
    let m = plan.corrections.len();
    let cells: Vec<([usize; 3], f64)> = plan
        .corrections
        .iter()
        .map(|&(s, p, d)| ([p, n + (p + plan.offsets[s]) % n, 2 * n + s], d))
        .collect();
    let Some((w1, capacitance_inverse)) =
        woodbury::cell_correction(base_len, &cells, |a, b| base.entry(a, b))
    else {
        return Ok(None);
    };
    let corrected = CellCorrected {
        base: &base,
        w1: &w1,
        capacitance_inverse: &capacitance_inverse,
        cells: m,
        base_len,
        len,
    };
    let Some((y_cols, schur_inverse)) = design.effects_schur(&corrected) else {
        return Ok(None);
    };

    // W = [[B V, Y], [0, −I]], M = diag(−C1⁻¹, S_e⁻¹)
    let r = m + e;
    let mut w = vec![0.0; len * r];
    for c in 0..m {
        w[c * len..c * len + base_len].copy_from_slice(&w1[c * base_len..(c + 1) * base_len]);
    }
    for j in 0..e {
        let column = &mut w[(m + j) * len..(m + j + 1) * len];
        column[..base_len].copy_from_slice(&y_cols[j * base_len..(j + 1) * base_len]);
        column[base_len + j] = -1.0;
    }
    let mut middle = DMatrix::<f64>::zeros(r, r);
    middle
        .view_mut((0, 0), (m, m))
        .copy_from(&(-&capacitance_inverse));
    middle.view_mut((m, m), (e, e)).copy_from(&schur_inverse);
    let structured = Structured::new(base, w, &middle);
    let mut g = structured.apply(&design.b);
    let residuals = design.refine(&structured, &mut g);

    // θ in the reported gauge (docs/FORMAT.md §1): φ = φ′ − φ′_N, U = U′ + φ′_N
    let phi_last = g[2 * n - 1];
    let pitch_deviation: Vec<f64> = (0..n).map(|i| g[n + i] - g[n + (i + n - 1) % n]).collect();
    let face_deviation = face_deviation_from_pitch(&pitch_deviation);
    let encoder_error = g[..n].to_vec();
    let effect_values = g[base_len..].to_vec();
    for (u, mean) in g[2 * n..base_len].iter_mut().zip(&design.stream_mean) {
        *u += mean;
    }
    let setup_values: Vec<f64> = (0..k).map(|s| g[2 * n + s] + phi_last).collect();
    let rss: f64 = residuals.iter().map(|v| v * v).sum();
    // each harmonic set to zero is one real dimension fewer of φ′
    let dof = (set.readings.len() + plan.lost.len()).saturating_sub(2 * n - 2 + k + e);
    let layout = ParameterLayout {
        faces: n,
        setups: k,
        effects: e,
    };
    Ok(Some(Solution {
        faces: n,
        method: Method::LeastSquares,
        engine: Engine::Circulant { low_rank: r },
        pitch_deviation,
        face_deviation,
        encoder_error,
        setup_error: streams
            .iter()
            .zip(setup_values)
            .map(|(&(setup, ac), value)| SetupError { setup, ac, value })
            .collect(),
        effect_values,
        effect_regressors: regressors.to_vec(),
        residuals,
        readings: set.readings.len(),
        dof,
        rss,
        sigma: super::choose_sigma(rss, dof, stated_sigma),
        cofactor: Cofactor::structured(layout, structured),
        layout,
        incomplete_cycles: Vec::new(),
    }))
}

/// The normal equations of one solve in g = [α, φ′, U′, effects]: Xᵀy, F = XᵀZ and ZᵀZ,
/// with what forms them (the readings less their stream's mean, each reading's
/// coordinates).
struct Normal<'a> {
    set: &'a MeasurementSet,
    reading_stream: &'a [usize],
    regressors: &'a [Vec<f64>],
    /// Each stream's mean reading, arcsec, taken out of its readings.
    stream_mean: Vec<f64>,
    /// Per reading, its coordinates of α, φ′ and U′ in g.
    rows: Vec<[usize; 3]>,
    /// Xᵀy.
    b: Vec<f64>,
    /// F = XᵀZ, column by column (each `base_len` long).
    f: Vec<f64>,
    /// ZᵀZ.
    ztz: DMatrix<f64>,
    /// The length of [α, φ′, U′]: 2N + K.
    base_len: usize,
    /// The length of g.
    len: usize,
}

impl<'a> Normal<'a> {
    /// The normal equations of `set` with `streams` streams. Each stream's mean is taken
    /// out of its readings first (the U′ column absorbs it exactly), so that the sums the
    /// FFT sees carry the variations, not the zeros.
    fn of(
        set: &'a MeasurementSet,
        streams: usize,
        reading_stream: &'a [usize],
        regressors: &'a [Vec<f64>],
    ) -> Normal<'a> {
        let n = set.faces;
        let k = streams;
        let e = regressors.len();
        let base_len = 2 * n + k;
        let len = base_len + e;
        let mut stream_sum = vec![0.0; k];
        let mut stream_count = vec![0usize; k];
        for (r, &s) in set.readings.iter().zip(reading_stream) {
            stream_sum[s] += r.reading_arcsec;
            stream_count[s] += 1;
        }
        let stream_mean: Vec<f64> = stream_sum
            .iter()
            .zip(&stream_count)
            .map(|(sum, &count)| sum / count.max(1) as f64)
            .collect();

        // Xᵀy, F = XᵀZ and ZᵀZ in g = [α, φ′, U′, effects]
        let mut b = vec![0.0; len];
        let mut f = vec![0.0; base_len * e];
        let mut ztz = DMatrix::<f64>::zeros(e, e);
        let mut rows = Vec::with_capacity(set.readings.len());
        for (i, r) in set.readings.iter().enumerate() {
            let s = reading_stream[i];
            let row = [r.position(n), n + r.face - 1, 2 * n + s];
            rows.push(row);
            let y = r.reading_arcsec - stream_mean[s];
            for &a in &row {
                b[a] += y;
            }
            for (j, z) in regressors.iter().enumerate() {
                let zij = z[i];
                if zij == 0.0 {
                    continue;
                }
                b[base_len + j] += zij * y;
                for &a in &row {
                    f[j * base_len + a] += zij;
                }
                for (l, zl) in regressors.iter().enumerate().take(j + 1) {
                    let v = zij * zl[i];
                    ztz[(j, l)] += v;
                    if l != j {
                        ztz[(l, j)] += v;
                    }
                }
            }
        }
        Normal {
            set,
            reading_stream,
            regressors,
            stream_mean,
            rows,
            b,
            f,
            ztz,
            base_len,
            len,
        }
    }

    /// The effects: Y = Q_A F and the inverse of their Schur complement
    /// S_e = ZᵀZ − Fᵀ Y. `None` when S_e is singular (an effect the data cannot
    /// separate).
    fn effects_schur(&self, corrected: &CellCorrected) -> Option<(Vec<f64>, DMatrix<f64>)> {
        let (base_len, e) = (self.base_len, self.regressors.len());
        let (f, ztz) = (&self.f, &self.ztz);
        let mut y_cols = vec![0.0; base_len * e];
        for j in 0..e {
            let column = corrected.q_a(&f[j * base_len..(j + 1) * base_len]);
            y_cols[j * base_len..(j + 1) * base_len].copy_from_slice(&column);
        }
        let mut schur = ztz.clone();
        for j in 0..e {
            for l in 0..e {
                let dot: f64 = f[j * base_len..(j + 1) * base_len]
                    .iter()
                    .zip(&y_cols[l * base_len..(l + 1) * base_len])
                    .map(|(a, b)| a * b)
                    .sum();
                schur[(j, l)] -= dot;
            }
        }
        let schur_inverse = if e > 0 {
            let scale = (0..e).map(|j| ztz[(j, j)]).fold(0.0_f64, f64::max);
            let cholesky = schur.clone().cholesky()?;
            let l = cholesky.l_dirty();
            let smallest = (0..e)
                .map(|j| l[(j, j)].powi(2))
                .fold(f64::INFINITY, f64::min);
            if scale <= 0.0 || smallest <= 1e-10 * scale {
                return None;
            }
            cholesky.inverse()
        } else {
            DMatrix::zeros(0, 0)
        };
        Some((y_cols, schur_inverse))
    }

    /// The residuals, arcsec, of the estimates `g` (in the stream-mean-free readings).
    fn model_residual(&self, g: &[f64], out: &mut Vec<f64>) {
        let base_len = self.base_len;
        out.clear();
        out.extend(self.set.readings.iter().zip(&self.rows).enumerate().map(
            |(i, (reading, row))| {
                let mut model: f64 = row.iter().map(|&a| g[a]).sum();
                for (j, z) in self.regressors.iter().enumerate() {
                    model += g[base_len + j] * z[i];
                }
                (reading.reading_arcsec - self.stream_mean[self.reading_stream[i]]) - model
            },
        ));
    }

    /// One step of iterative refinement of the estimates `g`: the gradient Xᵀe of the
    /// residuals e, formed from the readings without cancellation, mapped through Q_g
    /// (`structured`) again. At large N the harmonics near a zero of the design's
    /// transfer function are amplified (by N²/2π² at N = 65 536: 10⁸), and with them the
    /// rounding of the first product; the step takes that back to the level of the
    /// closed form. Returns the residuals of the refined estimates, arcsec.
    fn refine(&self, structured: &Structured, g: &mut [f64]) -> Vec<f64> {
        let base_len = self.base_len;
        let mut residuals = Vec::with_capacity(self.set.readings.len());
        self.model_residual(g, &mut residuals);
        let mut gradient = vec![0.0; self.len];
        for (i, (e, row)) in residuals.iter().zip(&self.rows).enumerate() {
            for &a in row {
                gradient[a] += e;
            }
            for (j, z) in self.regressors.iter().enumerate() {
                gradient[base_len + j] += z[i] * e;
            }
        }
        for (g, d) in g.iter_mut().zip(structured.apply(&gradient)) {
            *g += d;
        }
        self.model_residual(g, &mut residuals);
        residuals
    }
}

/// The regular part's cofactor B corrected for the cells read other than the regular
/// part has them (Woodbury: W1 = B V, C1⁻¹).
struct CellCorrected<'a> {
    base: &'a Base,
    w1: &'a [f64],
    capacitance_inverse: &'a DMatrix<f64>,
    /// The number of cells corrected (m).
    cells: usize,
    base_len: usize,
    len: usize,
}

impl CellCorrected<'_> {
    /// Q_A v = B v − W1 C1⁻¹ W1ᵀ v for v in the base coordinates.
    fn q_a(&self, v: &[f64]) -> Vec<f64> {
        let (base_len, len) = (self.base_len, self.len);
        let (w1, capacitance_inverse) = (self.w1, self.capacitance_inverse);
        let m = self.cells;
        let mut out = vec![0.0; len];
        let mut padded = v.to_vec();
        padded.resize(len, 0.0);
        self.base.apply_add(&padded, &mut out);
        out.truncate(base_len);
        if m > 0 {
            let proj: Vec<f64> = (0..m)
                .map(|c| {
                    w1[c * base_len..(c + 1) * base_len]
                        .iter()
                        .zip(v)
                        .map(|(a, b)| a * b)
                        .sum()
                })
                .collect();
            for c in 0..m {
                let coefficient: f64 = (0..m).map(|d| capacitance_inverse[(c, d)] * proj[d]).sum();
                for (o, w) in out.iter_mut().zip(&w1[c * base_len..(c + 1) * base_len]) {
                    *o -= coefficient * w;
                }
            }
        }
        out
    }
}
