//! The Monte Carlo trial model of a calibration (JCGM 101 §7.2 through the solver): draw
//! the readings as the fitted model plus the reading noise plus the scoped type-B errors,
//! solve them, add the `result` components ([`McModel`], the engine's
//! [`Trial`](crate::uncertainty::monte_carlo::Trial)).

use nalgebra::{DVector, DefaultAllocator, Dim, SVector, allocator::Allocator};
use rand::Rng;
use rand_distr::{ChiSquared, Distribution as _};

use super::draws::{Plan, Spread, Trapezoids, draw_into, pair_rectangles};
use super::operator::{Operator, groups};
use super::{CalibrationError, InstrumentBudget, KnownCorrection, Scope};
use crate::measurement::MeasurementSet;
use crate::solve::{ClosedFormSolution, PaperDesign, SigmaSource, Solution, closed_form};
use crate::uncertainty::distribution::{Distribution, Sampler, standard_normals, uniforms};
use crate::uncertainty::monte_carlo::{Trial, TrialFailure};

/// Which solver the Monte Carlo trials use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum McSolver {
    /// The paper's closed form (eqs. (6)–(10)) when the design is the paper's and the
    /// model has no effect terms, else least squares.
    #[default]
    Auto,
    /// The least-squares solution operator θ = Q Xᵀ y, whatever the design.
    LeastSquares,
}

/// Solves one trial's targets into the outputs; false on failure.
type ClosedFormFn = fn(&[f64], usize, &mut [f64]) -> bool;

fn write_closed_form<D: Dim>(s: &ClosedFormSolution<D>, offset: usize, out: &mut [f64])
where
    DefaultAllocator: Allocator<D>,
{
    let n = s.encoder_error.len();
    let (beta, rest) = out.split_at_mut(n);
    let (phi, alpha) = rest.split_at_mut(n - 1);
    beta.copy_from_slice(s.polygon.pitch_deviation_arcsec().as_slice());
    phi.copy_from_slice(&s.polygon.face_deviation_arcsec().as_slice()[..n - 1]);
    // α of position p is the solution's α[(p + offset) mod N]: a rotation, without a
    // division per position.
    let offset = offset % n;
    let encoder = s.encoder_error.as_slice();
    alpha[..n - offset].copy_from_slice(&encoder[offset..]);
    alpha[n - offset..n].copy_from_slice(&encoder[..offset]);
}

fn closed_form_const<const N: usize>(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let m1 = SVector::<f64, N>::from_column_slice(&t[..N]);
    let m2 = SVector::<f64, N>::from_column_slice(&t[N..2 * N]);
    // By reference: the solution is not moved out of the result (a copy of 3N values).
    match &closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(s, offset, out);
            true
        }
        Err(_) => false,
    }
}

fn closed_form_dyn(t: &[f64], offset: usize, out: &mut [f64]) -> bool {
    let n = t.len() / 2;
    let m1 = DVector::from_column_slice(&t[..n]);
    let m2 = DVector::from_column_slice(&t[n..]);
    match closed_form(&m1, &m2) {
        Ok(s) => {
            write_closed_form(&s, offset, out);
            true
        }
        Err(_) => false,
    }
}

macro_rules! closed_form_for {
    ($n:expr; $($c:literal),*) => {
        match $n {
            $($c => closed_form_const::<$c> as ClosedFormFn,)*
            _ => closed_form_dyn as ClosedFormFn,
        }
    };
}

/// The closed form for N faces: `Const<N>` (stack only) for the usual N, else `Dyn`.
fn closed_form_fn(n: usize) -> ClosedFormFn {
    closed_form_for!(n; 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 14, 15, 16, 18, 20, 24, 30, 36, 40, 45, 48, 60, 72)
}

enum TrialSolver {
    ClosedForm {
        offset: usize,
        solve: ClosedFormFn,
    },
    /// The operator, and whether the targets are the readings' sums per cell (else the
    /// readings).
    LeastSquares {
        op: Box<Operator>,
        cells: bool,
    },
    /// A linear map of the sums per cell.
    Cells(Box<dyn CellMap>),
}

/// A linear map of a trial's targets — the readings' sums per cell — to the outputs
/// ([`McModel::outputs`] order: β, φ\[1..N−1\], α, the setup errors), for a design the
/// calibration's operator does not solve (a self-calibration's heads between the
/// positions).
pub(crate) trait CellMap: Send + Sync {
    /// Writes the outputs of the sums per cell `cell_sums` into `out`.
    fn solve(&self, cell_sums: &[f64], out: &mut [f64]);
}

/// A design solved by a [`CellMap`] ([`McModel::with_cell_map`]): the fit's residuals,
/// σ and residual degrees of freedom, each reading's cell, and the outputs' layout.
pub(crate) struct CellRoute<'a> {
    pub(crate) residuals: &'a [f64],
    pub(crate) sigma: Option<(f64, SigmaSource)>,
    pub(crate) dof: usize,
    /// Per reading, its cell (an index into the sums `map` solves), and the number of
    /// cells.
    pub(crate) cell: Vec<usize>,
    pub(crate) cells: usize,
    pub(crate) faces: usize,
    pub(crate) setups: usize,
    pub(crate) map: Box<dyn CellMap>,
}

enum Noise {
    /// Stated σ: normal, folded into `McModel::normal_sd`.
    Normal,
    ScaledT {
        sigma: f64,
        dof: f64,
        chi: ChiSquared<f64>,
    },
}

/// What a trial model starts from: the fit's residuals (the fitted model is the readings
/// less them), its σ and residual degrees of freedom, where each reading lands (target,
/// weight), and the outputs' layout and centre.
struct Start<'a> {
    residuals: &'a [f64],
    sigma: (f64, SigmaSource),
    dof: usize,
    targets: usize,
    map: Vec<(usize, f64)>,
    faces: usize,
    setup_outputs: usize,
    centre: Vec<f64>,
}

/// One Monte Carlo trial of a calibration: draws the readings (as targets of the solver:
/// per-step means for the closed form; for least squares the readings' sums per cell,
/// or the readings themselves when the model has effect terms) and solves them. The
/// normal parts of a target's readings (noise, normal errors of each reading) are drawn
/// as one normal with their summed variance, the same distribution as their sum.
/// Built by [`McModel::new`]; [`super::monte_carlo`] runs it on the engine.
pub struct McModel {
    pub(super) faces: usize,
    solver: TrialSolver,
    base: Vec<f64>,
    noise: Noise,
    /// Per target: Σw² of the noise, the variance of the normal components whose draws
    /// each land on one target (drawn together with the noise), and the total standard
    /// deviation when the noise is normal.
    noise_var: Vec<f64>,
    fixed_var: Vec<f64>,
    /// (Σw², the normal components' variance) when every target has the same.
    uniform_var: Option<(f64, f64)>,
    normal_sd: Vec<f64>,
    /// Pairs of rectangular errors of each reading, drawn as one trapezoid each, in the
    /// order of the targets they land on: those of target t are
    /// `trapezoid_starts[t]..trapezoid_starts[t + 1]`.
    trapezoids: Trapezoids,
    trapezoid_starts: Vec<usize>,
    /// Whether every target has exactly one trapezoid (each reading's errors of the
    /// paper's design): trapezoid t lands on target t.
    one_trapezoid_each: bool,
    plans: Vec<Plan>,
    result_draws: Vec<(Sampler, f64)>,
    /// The setup errors among the outputs (after α): their number K, or 0.
    setup_outputs: usize,
    centre: Vec<f64>,
}

impl McModel {
    /// The trial model of a solved measurement set and a budget.
    ///
    /// # Errors
    ///
    /// As [`super::evaluate`].
    pub fn new(
        set: &MeasurementSet,
        solution: &Solution,
        budget: &InstrumentBudget,
        solver: McSolver,
    ) -> Result<Self, CalibrationError> {
        Self::with_corrections(set, solution, budget, &[], solver)
    }

    /// The trial model with the uncertainties of known corrections applied to the
    /// readings: each trial draws the error e of every [`KnownCorrection`] once, normal
    /// with its u, and moves reading i by e·`column[i]`.
    ///
    /// # Errors
    ///
    /// As [`super::evaluate_with_corrections`].
    pub fn with_corrections(
        set: &MeasurementSet,
        solution: &Solution,
        budget: &InstrumentBudget,
        corrections: &[KnownCorrection],
        solver: McSolver,
    ) -> Result<Self, CalibrationError> {
        Self::build(set, solution, budget, corrections, solver, false)
    }

    /// The trial model, solved by least squares, whose outputs end with the K setup
    /// errors (after β, φ\[1..N−1\], α): a self-calibration's heads are the closure
    /// model's setups, and an error every reading of one head shares moves only them.
    ///
    /// # Errors
    ///
    /// As [`McModel::new`].
    pub(crate) fn with_setup_outputs(
        set: &MeasurementSet,
        solution: &Solution,
        budget: &InstrumentBudget,
    ) -> Result<Self, CalibrationError> {
        Self::build(set, solution, budget, &[], McSolver::LeastSquares, true)
    }

    /// The trial model of readings `set` whose sums per cell `route.map` solves, with the
    /// setup errors among the outputs as [`McModel::with_setup_outputs`]; its
    /// [`McModel::estimates`] are the map's solution of the fitted model.
    ///
    /// # Errors
    ///
    /// As [`McModel::new`].
    pub(crate) fn with_cell_map(
        set: &MeasurementSet,
        route: CellRoute<'_>,
        budget: &InstrumentBudget,
    ) -> Result<Self, CalibrationError> {
        budget.check()?;
        let sigma = route.sigma.ok_or(CalibrationError::NoSigma)?;
        let readings = set.readings.len();
        if route.residuals.len() != readings
            || route.cell.len() != readings
            || route.cell.iter().any(|&c| c >= route.cells)
        {
            return Err(CalibrationError::Mismatch(format!(
                "{readings} readings, {} residuals and {} cells of {}",
                route.residuals.len(),
                route.cell.len(),
                route.cells
            )));
        }
        let outputs = 3 * route.faces - 1 + route.setups;
        let start = Start {
            residuals: route.residuals,
            sigma,
            dof: route.dof,
            targets: route.cells,
            map: route.cell.iter().map(|&c| (c, 1.0)).collect(),
            faces: route.faces,
            setup_outputs: route.setups,
            centre: vec![0.0; outputs],
        };
        let mut model = Self::assemble(set, start, budget, &[], TrialSolver::Cells(route.map))?;
        let mut scratch = model.scratch();
        scratch.targets.copy_from_slice(&model.base);
        let mut centre = vec![0.0; outputs];
        model.solve(&mut scratch, &mut centre);
        model.centre = centre;
        Ok(model)
    }

    fn build(
        set: &MeasurementSet,
        solution: &Solution,
        budget: &InstrumentBudget,
        corrections: &[KnownCorrection],
        solver: McSolver,
        setups: bool,
    ) -> Result<Self, CalibrationError> {
        budget.check()?;
        for c in corrections {
            c.check(set.readings.len())?;
        }
        let op = Operator::new(set, solution)?;
        let (sigma, source) = solution.sigma.ok_or(CalibrationError::NoSigma)?;
        let n = op.faces;
        // The closed form has no effect terms: a model with effects is solved by its
        // operator, effect columns included.
        let design = match solver {
            McSolver::Auto if solution.layout.effects == 0 && !setups => {
                PaperDesign::detect(set).ok()
            }
            McSolver::Auto | McSolver::LeastSquares => None,
        };
        // Where each reading lands: (target, weight).
        let (targets, map): (usize, Vec<(usize, f64)>) = match &design {
            Some(d) => (
                2 * n,
                set.readings
                    .iter()
                    .map(|r| {
                        let slot = usize::from((r.setup, r.ac) == d.second);
                        (slot * n + (r.step + d.offset) % n, 1.0 / d.repeats as f64)
                    })
                    .collect(),
            ),
            // Least squares without effect terms needs the readings only through their
            // sums per cell (one autocollimator's readings of one face at one position):
            // the trial draws those sums.
            None if solution.layout.effects == 0 => {
                let (cell, cells) = op.cell_of();
                (cells, cell.iter().map(|&c| (c, 1.0)).collect())
            }
            None => (
                set.readings.len(),
                (0..set.readings.len()).map(|i| (i, 1.0)).collect(),
            ),
        };
        let by_cells = design.is_none() && solution.layout.effects == 0;
        let mut centre = Vec::with_capacity(3 * n - 1);
        centre.extend_from_slice(&solution.pitch_deviation);
        centre.extend_from_slice(&solution.face_deviation[..n - 1]);
        centre.extend_from_slice(&solution.encoder_error);
        let setup_outputs = if setups { op.streams } else { 0 };
        if setups {
            centre.extend(solution.setup_error.iter().map(|s| s.value));
        }
        let solver = match design {
            Some(d) => TrialSolver::ClosedForm {
                offset: d.offset,
                solve: closed_form_fn(n),
            },
            None => TrialSolver::LeastSquares {
                op: Box::new(op),
                cells: by_cells,
            },
        };
        let start = Start {
            residuals: &solution.residuals,
            sigma: (sigma, source),
            dof: solution.dof,
            targets,
            map,
            faces: n,
            setup_outputs,
            centre,
        };
        Self::assemble(set, start, budget, corrections, solver)
    }

    /// The trial model of `start` and `solver`: the fitted model and the reading noise
    /// of each target, the budget's draws by scope, the known corrections' draws, and the
    /// rectangular errors of each reading paired into trapezoids.
    fn assemble(
        set: &MeasurementSet,
        start: Start<'_>,
        budget: &InstrumentBudget,
        corrections: &[KnownCorrection],
        solver: TrialSolver,
    ) -> Result<Self, CalibrationError> {
        let Start {
            residuals,
            sigma: (sigma, source),
            dof,
            targets,
            map,
            faces: n,
            setup_outputs,
            centre,
        } = start;
        let mut base = vec![0.0; targets];
        let mut noise_var = vec![0.0; targets];
        for (i, r) in set.readings.iter().enumerate() {
            let (t, w) = map[i];
            base[t] += w * (r.reading_arcsec - residuals[i]);
            noise_var[t] += w * w;
        }
        let noise = match source {
            SigmaSource::Stated => Noise::Normal,
            SigmaSource::Residual => {
                let dof = dof as f64;
                Noise::ScaledT {
                    sigma,
                    dof,
                    chi: ChiSquared::new(dof).map_err(|e| {
                        CalibrationError::Mismatch(format!("residual dof {dof}: {e}"))
                    })?,
                }
            }
        };
        let mut plans = Vec::new();
        let mut fixed_var = vec![0.0; targets];
        let mut result_draws = Vec::new();
        for c in &budget.components {
            let distribution = c.mc_distribution();
            let sampler = distribution
                .sampler()
                .map_err(|e| CalibrationError::Component {
                    name: c.name.clone(),
                    message: e.to_string(),
                })?;
            if c.scope == Scope::Result {
                result_draws.push((sampler, c.sensitivity));
                continue;
            }
            let mut starts = vec![0];
            let mut entries: Vec<(usize, f64)> = Vec::new();
            for members in groups(set, c.scope) {
                let from = entries.len();
                for i in members {
                    let (t, w) = map[i];
                    match entries[from..].iter_mut().find(|(target, _)| *target == t) {
                        Some((_, weight)) => *weight += w,
                        None => entries.push((t, w)),
                    }
                }
                starts.push(entries.len());
            }
            let single = starts.windows(2).all(|w| w[1] - w[0] == 1);
            for entry in &mut entries {
                entry.1 *= c.sensitivity;
            }
            if let (true, Distribution::Normal { u }) = (single, distribution) {
                // Independent normals per target: one normal with the summed variance.
                for &(t, w) in &entries {
                    fixed_var[t] += (u * w).powi(2);
                }
            } else {
                let spread = if single {
                    Spread::Single(entries)
                } else {
                    let group_of = |i: usize| starts.partition_point(|&s| s <= i) - 1;
                    Spread::Groups {
                        groups: starts.len() - 1,
                        entries: (entries.iter().enumerate())
                            .map(|(i, &(t, w))| (t, w, group_of(i)))
                            .collect(),
                    }
                    .densified(targets)
                };
                plans.push(Plan { sampler, spread });
            }
        }
        // A known correction: one draw shared by every reading its column touches.
        for c in corrections.iter().filter(|c| c.u > 0.0) {
            let mut weights = vec![0.0; targets];
            for (i, &x) in c.column.iter().enumerate() {
                let (t, w) = map[i];
                weights[t] += w * x;
            }
            let entries = (weights.iter().enumerate())
                .filter(|(_, w)| **w != 0.0)
                .map(|(t, &w)| (t, w, 0))
                .collect();
            plans.push(Plan {
                sampler: Distribution::Normal { u: c.u }.sampler().map_err(|e| {
                    CalibrationError::Component {
                        name: c.name.clone(),
                        message: e.to_string(),
                    }
                })?,
                spread: Spread::Groups { groups: 1, entries }.densified(targets),
            });
        }
        let mut model = McModel {
            faces: n,
            solver,
            base,
            normal_sd: noise_var
                .iter()
                .zip(&fixed_var)
                .map(|(v, f)| (sigma * sigma * v + f).sqrt())
                .collect(),
            noise,
            uniform_var: match (noise_var.first(), fixed_var.first()) {
                (Some(&v), Some(&f))
                    if noise_var.iter().all(|&x| x == v) && fixed_var.iter().all(|&x| x == f) =>
                {
                    Some((v, f))
                }
                _ => None,
            },
            noise_var,
            fixed_var,
            trapezoids: Trapezoids::default(),
            trapezoid_starts: vec![0; targets + 1],
            one_trapezoid_each: false,
            plans: Vec::new(),
            result_draws,
            setup_outputs,
            centre,
        };
        // The model is linear: an error that reaches no output (one absorbed by the setup
        // errors, say) is not drawn at all.
        plans.retain(|plan| model.reaches_outputs(plan));
        let (trapezoids, trapezoid_targets, plans) = pair_rectangles(plans);
        // In target order (a stable sort), each target's trapezoids together.
        let mut order: Vec<usize> = (0..trapezoid_targets.len()).collect();
        order.sort_by_key(|&k| trapezoid_targets[k]);
        model.trapezoids = trapezoids.permuted(&order);
        for &t in &trapezoid_targets {
            model.trapezoid_starts[t + 1] += 1;
        }
        for t in 0..targets {
            model.trapezoid_starts[t + 1] += model.trapezoid_starts[t];
        }
        model.one_trapezoid_each = model
            .trapezoid_starts
            .iter()
            .enumerate()
            .all(|(t, &s)| s == t);
        model.plans = plans;
        Ok(model)
    }

    /// Whether some group of `plan` moves some output: the solution of the group's
    /// weights alone (the solvers are linear) is above rounding.
    fn reaches_outputs(&self, plan: &Plan) -> bool {
        let mut scratch = self.scratch();
        let mut out = vec![0.0; self.outputs()];
        (0..plan.spread.groups()).any(|g| {
            let entries = plan.spread.group(g);
            let size: f64 = entries.iter().map(|(_, w)| w.abs()).sum();
            scratch.targets.fill(0.0);
            for (t, w) in entries {
                scratch.targets[t] += w;
            }
            !self.solve(&mut scratch, &mut out) || out.iter().any(|o| o.abs() > 1e-10 * size)
        })
    }

    /// Number of targets a trial draws (2N per-step means for the closed form; for least
    /// squares one sum per cell of readings, or the readings when the model has effect
    /// terms).
    pub fn targets(&self) -> usize {
        self.base.len()
    }

    /// Number of outputs: β (N), φ\[1..N−1\] (φ\[N\] = 0 is not drawn), α (N), and the
    /// setup errors (K) when the model was built to give them.
    pub fn outputs(&self) -> usize {
        3 * self.faces - 1 + self.setup_outputs
    }

    /// `closed-form` or `lsq`.
    pub fn solver_name(&self) -> &'static str {
        match self.solver {
            TrialSolver::ClosedForm { .. } => "closed-form",
            TrialSolver::LeastSquares { .. } | TrialSolver::Cells(_) => "lsq",
        }
    }

    /// `normal` (stated σ) or `t` (σ from the residuals), with the degrees of freedom.
    pub fn reading_noise(&self) -> (&'static str, Option<f64>) {
        match self.noise {
            Noise::Normal => ("normal", None),
            Noise::ScaledT { dof, .. } => ("t", Some(dof)),
        }
    }

    /// A scratch buffer for [`McModel::trial`].
    pub fn scratch(&self) -> McScratch {
        let (faces_len, b_len) = match &self.solver {
            TrialSolver::LeastSquares { op, .. } => (op.sums_len(), op.len()),
            TrialSolver::ClosedForm { .. } | TrialSolver::Cells(_) => (0, 0),
        };
        let draws = self
            .plans
            .iter()
            .map(|p| p.spread.groups())
            .chain([self.outputs(), self.targets(), self.trapezoids.len()])
            .max()
            .unwrap_or(0);
        McScratch {
            targets: vec![0.0; self.targets()],
            offsets: vec![0.0; self.outputs()],
            draws: vec![0.0; draws],
            bits: vec![0; draws],
            sd: vec![0.0; self.targets()],
            uniforms: vec![0.0; self.trapezoids.len()],
            quantiles: vec![0.0; self.trapezoids.len()],
            theta: vec![0.0; 2 * self.faces + self.setup_outputs],
            face_sums: vec![0.0; faces_len],
            b: vec![0.0; b_len],
        }
    }

    /// Draws one trial's targets and the per-output offsets of the `result` components
    /// (into `scratch`), without solving.
    pub fn sample<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        #[cfg(target_arch = "x86_64")]
        if crate::uncertainty::monte_carlo::has_avx2() {
            // SAFETY: the processor has AVX2 (just checked).
            unsafe { self.sample_avx2(rng, scratch) };
            return;
        }
        self.sample_portable(rng, scratch);
    }

    /// [`McModel::sample`] in the AVX2 vector units: the same arithmetic, value by value.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn sample_avx2<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        self.sample_portable(rng, scratch);
    }

    #[inline(always)]
    fn sample_portable<R: Rng + ?Sized>(&self, rng: &mut R, scratch: &mut McScratch) {
        let t = &mut scratch.targets;
        let n = t.len();
        let bits = &mut scratch.bits;
        let sd = match &self.noise {
            Noise::Normal => &self.normal_sd,
            Noise::ScaledT { sigma, dof, chi } => {
                let s2 = sigma * sigma * dof / chi.sample(rng);
                match self.uniform_var {
                    // every target alike (each one reading): one square root, the same
                    // value as per target
                    Some((v, f)) => scratch.sd.fill((s2 * v + f).sqrt()),
                    None => {
                        for ((sd, v), f) in scratch
                            .sd
                            .iter_mut()
                            .zip(&self.noise_var)
                            .zip(&self.fixed_var)
                        {
                            *sd = (s2 * v + f).sqrt();
                        }
                    }
                }
                &scratch.sd
            }
        };
        let z = &mut scratch.draws[..n];
        standard_normals(rng, bits, z);
        let q = &mut scratch.quantiles[..self.trapezoids.len()];
        if !q.is_empty() {
            let u = &mut scratch.uniforms[..q.len()];
            uniforms(rng, bits, u);
            self.trapezoids.quantiles(u, q);
        }
        // The noise, the normal errors and the trapezoids of each target.
        if self.one_trapezoid_each {
            for ((((x, b), sd), z), q) in t
                .iter_mut()
                .zip(&self.base)
                .zip(sd)
                .zip(z.iter())
                .zip(q.iter())
            {
                *x = b + sd * z + q;
            }
        } else {
            let trapezoids = self.trapezoid_starts.windows(2);
            for ((((x, b), sd), z), range) in t
                .iter_mut()
                .zip(&self.base)
                .zip(sd)
                .zip(z.iter())
                .zip(trapezoids)
            {
                *x = b + sd * z + q[range[0]..range[1]].iter().sum::<f64>();
            }
        }
        for plan in &self.plans {
            let draws = &mut scratch.draws[..plan.spread.groups()];
            draw_into(&plan.sampler, rng, bits, draws);
            match &plan.spread {
                Spread::Single(targets) => {
                    for (&(target, w), e) in targets.iter().zip(draws.iter()) {
                        t[target] += w * e;
                    }
                }
                Spread::Groups { entries, .. } => {
                    for &(target, w, group) in entries {
                        t[target] += w * draws[group];
                    }
                }
                Spread::Dense {
                    weights, group_of, ..
                } => {
                    for ((x, w), &g) in t.iter_mut().zip(weights).zip(group_of) {
                        *x += w * draws[g];
                    }
                }
            }
        }
        if !self.result_draws.is_empty() {
            scratch.offsets.fill(0.0);
            let draws = &mut scratch.draws[..scratch.offsets.len()];
            for (sampler, c) in &self.result_draws {
                draw_into(sampler, rng, &mut scratch.bits, draws);
                for (o, d) in scratch.offsets.iter_mut().zip(draws.iter()) {
                    *o += c * d;
                }
            }
        }
    }

    /// Solves the targets drawn by [`McModel::sample`] into `out` ([`McModel::outputs`]
    /// values: β, φ\[1..N−1\], α, and the setup errors when asked for), without the
    /// `result` offsets. False if the solver
    /// failed.
    pub fn solve(&self, scratch: &mut McScratch, out: &mut [f64]) -> bool {
        let n = self.faces;
        match &self.solver {
            TrialSolver::ClosedForm { offset, solve } => solve(&scratch.targets, *offset, out),
            TrialSolver::Cells(map) => {
                map.solve(&scratch.targets, out);
                true
            }
            TrialSolver::LeastSquares { op, cells } => {
                let solve = if *cells {
                    Operator::solve_cells
                } else {
                    Operator::solve
                };
                solve(
                    op,
                    &scratch.targets,
                    &mut scratch.face_sums,
                    &mut scratch.b,
                    0..2 * n + self.setup_outputs,
                    &mut scratch.theta,
                );
                let theta = &scratch.theta;
                out[..n].copy_from_slice(&theta[..n]);
                let mut running = 0.0;
                for f in 0..n - 1 {
                    running += theta[f];
                    out[n + f] = running;
                }
                out[2 * n - 1..3 * n - 1].copy_from_slice(&theta[n..2 * n]);
                let k = self.setup_outputs;
                out[3 * n - 1..3 * n - 1 + k].copy_from_slice(&theta[2 * n..2 * n + k]);
                true
            }
        }
    }

    /// One trial: draw, solve, add the `result` draws. False if the solver failed.
    pub fn trial<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut McScratch,
        out: &mut [f64],
    ) -> bool {
        self.sample(rng, scratch);
        if !self.solve(scratch, out) {
            return false;
        }
        if !self.result_draws.is_empty() {
            for (o, d) in out.iter_mut().zip(&scratch.offsets) {
                *o += d;
            }
        }
        true
    }

    /// The outputs at the fitted values (no noise, no draws): the solution's estimates.
    pub fn estimates(&self) -> &[f64] {
        &self.centre
    }
}

/// Scratch space of one thread for [`McModel`] trials.
pub struct McScratch {
    targets: Vec<f64>,
    offsets: Vec<f64>,
    draws: Vec<f64>,
    bits: Vec<u64>,
    sd: Vec<f64>,
    uniforms: Vec<f64>,
    quantiles: Vec<f64>,
    theta: Vec<f64>,
    face_sums: Vec<f64>,
    b: Vec<f64>,
}

impl McScratch {
    /// The targets of the last [`McModel::sample`].
    pub fn targets(&self) -> &[f64] {
        &self.targets
    }

    /// The `result` components' draws of the last [`McModel::sample`], one independent
    /// draw of their sum per output (zeros without such components).
    pub(crate) fn result_offsets(&self) -> &[f64] {
        &self.offsets
    }
}

/// The engine's view of a trial: [`McModel::trial`], failing when the solver fails.
impl Trial for McModel {
    type Scratch = McScratch;

    fn outputs(&self) -> usize {
        McModel::outputs(self)
    }

    fn centre(&self) -> &[f64] {
        &self.centre
    }

    fn scratch(&self) -> McScratch {
        McModel::scratch(self)
    }

    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut McScratch,
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        if self.trial(rng, scratch, out) {
            Ok(())
        } else {
            Err(TrialFailure::Failed)
        }
    }

    /// The targets of the trial ([`McModel::targets`]).
    fn inputs(&self, scratch: &McScratch) -> Vec<f64> {
        scratch.targets.clone()
    }
}

#[cfg(test)]
mod tests {
    use rand::SeedableRng;

    use super::*;
    use crate::solve::{SolveOptions, solve};
    use crate::uncertainty::calibration::ScopedComponent;
    use crate::uncertainty::calibration::test_support::set;
    use crate::uncertainty::monte_carlo::{self, EngineOptions, Trials};

    /// The closed-form trial and the least-squares trial solve the same targets alike.
    #[test]
    fn closed_form_and_least_squares_trials_agree() {
        let s = set(24, 2, false, 9);
        let solution = solve(&s, &SolveOptions::default()).unwrap();
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "r",
                Distribution::Rectangular { half_width: 0.1 },
                Scope::EachStop,
            ),
            ScopedComponent::type_b("n", Distribution::Normal { u: 0.1 }, Scope::EachReading),
        ]);
        let cf = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        let ls = McModel::new(&s, &solution, &budget, McSolver::LeastSquares).unwrap();
        assert_eq!((cf.solver_name(), ls.solver_name()), ("closed-form", "lsq"));
        let mut scratch = cf.scratch();
        let mut out = vec![0.0; cf.outputs()];
        scratch.targets.copy_from_slice(&cf.base);
        assert!(cf.solve(&mut scratch, &mut out));
        for (a, b) in out.iter().zip(cf.estimates()) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
        let mut ls_scratch = ls.scratch();
        let mut ls_out = vec![0.0; ls.outputs()];
        ls_scratch.targets.copy_from_slice(&ls.base);
        assert!(ls.solve(&mut ls_scratch, &mut ls_out));
        for (a, b) in ls_out.iter().zip(ls.estimates()) {
            assert!((a - b).abs() < 1e-12, "{a} {b}");
        }
    }

    /// The instrument budget on the paper's bare cycle: the two rectangular errors of
    /// each reading become one trapezoid per target, in order; the zero offset of each
    /// autocollimator, which reaches no result, is not drawn; the encoder's error of each
    /// position remains.
    #[test]
    fn instrument_budget_draws() {
        let s = set(24, 1, false, 4);
        let solution = solve(
            &s,
            &SolveOptions::new().with_sigma(crate::measurement::Sigma::new(0.05).unwrap()),
        )
        .unwrap();
        let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
        let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        assert_eq!(model.solver_name(), "closed-form");
        assert_eq!(model.trapezoids.len(), 48);
        assert_eq!(model.trapezoid_starts, (0..=48).collect::<Vec<_>>());
        assert!(model.one_trapezoid_each);
        assert_eq!(model.plans.len(), 1);
        assert!(matches!(model.plans[0].sampler, Sampler::Rectangular(a) if a == 0.02));
        assert_eq!(model.plans[0].spread.groups(), 24);
        // With least squares the same: the offset is absorbed by the setup errors there
        // too.
        let lsq = McModel::new(&s, &solution, &budget, McSolver::LeastSquares).unwrap();
        assert_eq!((lsq.trapezoids.len(), lsq.plans.len()), (48, 1));
    }

    /// Least squares draws one sum per cell (here 24 positions × 2 autocollimators over
    /// three cycles, each cycle's closing readings in the cells of position 0): each
    /// sum's noise variance is its number of readings; the vector units draw the same
    /// bits as the portable code.
    #[test]
    fn least_squares_draws_the_sums_per_cell() {
        let s = set(24, 3, true, 4);
        let solution = solve(&s, &SolveOptions::default()).unwrap();
        let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
        let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        assert_eq!(model.solver_name(), "lsq");
        assert_eq!((model.targets(), s.readings.len()), (48, 150));
        let mut counts = vec![0.0; 48];
        counts[..2].fill(6.0);
        counts[2..].fill(3.0);
        assert_eq!(model.noise_var, counts);
        // 150 readings' trapezoids, six or three per cell, in cell order
        assert_eq!(model.trapezoids.len(), 150);
        assert_eq!(model.trapezoid_starts[..4], [0, 6, 12, 15]);
        assert!(!model.one_trapezoid_each);
        let (mut a, mut b) = (model.scratch(), model.scratch());
        let (mut rng_a, mut rng_b) = (
            rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9),
            rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(9),
        );
        for _ in 0..100 {
            model.sample(&mut rng_a, &mut a);
            model.sample_portable(&mut rng_b, &mut b);
            assert_eq!(a.targets, b.targets);
            assert_eq!(a.offsets, b.offsets);
        }
    }

    /// The calibration trial on the engine: the summary of every trial without storing
    /// them is the summary of the stored trials, for 9 positions (fixed and adaptive), 24
    /// (the paper's polygon, closing readings: least squares, stages after a pilot of J)
    /// and for 1440 positions (4319 outputs: a pilot shorter than `J`, brackets refined
    /// at every doubling of the trials).
    #[test]
    fn the_engine_summarizes_every_trial() {
        let adaptive = Trials::Adaptive {
            significant_digits: 1,
            max_trials: 500_000,
        };
        for (faces, trials) in [
            (9, Trials::Fixed(34_500)),
            (9, adaptive),
            (24, Trials::Fixed(25_000)),
            (1440, Trials::Fixed(9_000)),
        ] {
            the_engine_summarizes(faces, trials);
        }
    }

    fn the_engine_summarizes(faces: usize, trials: Trials) {
        let s = set(faces, 2, true, 5);
        let solution = solve(&s, &SolveOptions::default()).unwrap();
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "r",
                Distribution::Rectangular { half_width: 0.2 },
                Scope::Result,
            ),
            ScopedComponent::type_b(
                "each stop",
                Distribution::Rectangular { half_width: 0.05 },
                Scope::EachStop,
            ),
        ]);
        let model = McModel::new(&s, &solution, &budget, McSolver::Auto).unwrap();
        {
            let options = EngineOptions::new(trials).with_seed(11);
            let summary = monte_carlo::run(&model, &options).unwrap();
            let kept = monte_carlo::run(&model, &options.with_samples(true)).unwrap();
            let m = summary.trials;
            let (r_low, r_high) = monte_carlo::symmetric_interval_positions(m, 0.95);
            let samples = kept.samples.unwrap();
            assert_eq!(samples.len(), model.outputs());
            for (j, column) in samples.iter().enumerate() {
                let mut column = column.clone();
                column.sort_unstable_by(f64::total_cmp);
                let y = summary.outputs[j];
                assert_eq!(y.low, column[r_low]);
                assert_eq!(y.high, column[r_high]);
                let mean = column.iter().sum::<f64>() / m as f64;
                let ss = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
                let u = (ss / (m - 1) as f64).sqrt();
                assert!((y.mean - mean).abs() < 1e-12);
                assert!((y.u - u).abs() < 1e-12 * u);
            }
        }
    }
}
