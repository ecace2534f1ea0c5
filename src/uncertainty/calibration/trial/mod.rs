//! The Monte Carlo trial model of a calibration (JCGM 101 §7.2 through the solver): draw
//! the readings as the fitted model plus the reading noise plus the scoped type-B errors,
//! solve them, add the `result` components ([`McModel`], the engine's
//! [`Trial`](crate::uncertainty::monte_carlo::Trial)): how a trial is built here, how it
//! is drawn in `sample`, what solves it in `solver`.

use rand::Rng;
use rand_distr::ChiSquared;

use super::draws::{Plan, Spread, Trapezoids, pair_rectangles};
use super::operator::{Operator, groups};
use super::{CalibrationError, InstrumentBudget, KnownCorrection, Scope};
use crate::measurement::MeasurementSet;
use crate::solve::{PaperDesign, SigmaSource, Solution};
use crate::uncertainty::distribution::{Distribution, Sampler};
use crate::uncertainty::monte_carlo::{Trial, TrialFailure};

mod sample;
mod solver;

pub(crate) use solver::CellMap;
use solver::{TrialSolver, closed_form_fn};

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
                    problem: e.into(),
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
                        problem: e.into(),
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
mod tests;
