//! Monte Carlo of a self-calibration (JCGM 101; docs/FORMAT.md §9.3.2): the GUM budget of
//! [`super::evaluate_budget`] checked by propagating the distributions themselves.
//!
//! Every trial draws the readings as the fitted model (the table's error at every stop,
//! e and the heads' errors) plus the reading noise plus every budget error with its scope
//! — `each-reading` on one reading, `each-autocollimator` on every reading of one head,
//! `each-position` on every reading at one table position, `each-stop` on every reading
//! of one stop — and solves them through the closure model's least-squares operator with
//! the lost harmonics set to zero, as [`super::solve`] does (the heads on the grid): the
//! table's per-stop nuisance absorbs an error shared by a stop, and the heads' errors one
//! shared by a head, in every trial as in the fit (heads between the positions: the
//! band-limited fit, as a map of the readings' sums per head and
//! step). e is then referenced to the solution's
//! gauge and the heads' errors to head 1, and the `result` errors are added. The noise is
//! normal for a stated σ; for σ from the residuals its scale is drawn per trial as
//! s·√(ν/χ²_ν), ν the self-calibration's residual degrees of freedom.
//!
//! What the solution adds beyond its fit is drawn as well: with a bound A on the lost
//! harmonics, each lost harmonic h as A·cos(2πhx/P + ψ) with ψ uniform (the arcsine the
//! GUM's u = A/√2 stands for); with an uncertainty of the heads' angles, the normal
//! contribution it makes to each e and each head error (each result's own draw: the
//! intervals are per result, so only each result's distribution matters).

use std::f64::consts::TAU;

use rand::Rng;
use rand_distr::{Distribution as _, StandardNormal};
use serde::Serialize;

use super::budget::SelfcalUncertainty;
use super::fourier::OffGridMap;
use super::fourier::design::{OffGridDesign, OffGridFitMap};
use super::solve::{closure_set, grid_offsets};
use super::{Head, HeadGrid, SelfcalSet, SelfcalSolution};
use crate::measurement::MeasurementSet;
use crate::solve::least_squares::least_squares_zeroing_lost;
use crate::solve::{Solution, SolveOptions};
use crate::uncertainty::calibration::{
    CalibrationError, CellRoute, InstrumentBudget, McFamily, McModel, McOptions, McScratch,
};
use crate::uncertainty::monte_carlo::{self, EngineOptions, Trial, TrialFailure};

/// The Monte Carlo evaluation of a self-calibration ([`monte_carlo()`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelfcalMonteCarlo {
    /// Trials M run.
    pub trials: usize,
    /// Sequences of the adaptive procedure (`null` for a fixed M).
    pub sequences: Option<usize>,
    /// The seed.
    pub seed: u64,
    /// Coverage probability of the intervals.
    pub p: f64,
    /// Significant digits of u_c for the validation (JCGM 101 §8).
    pub significant_digits: u32,
    /// `normal` (stated σ) or `t` (σ from the residuals).
    pub reading_noise: &'static str,
    /// ν of the t noise; `None` for normal noise.
    pub reading_noise_dof: Option<f64>,
    /// Whether every GUM interval is validated.
    pub validated: bool,
    /// The encoder errors e, in the solution's gauge.
    pub encoder_error: McFamily,
    /// The heads' errors c\[j\] − c\[1\], heads 2 … M.
    pub head_error: McFamily,
}

/// Monte Carlo of a self-calibration under an instrument budget (module documentation):
/// per e and per head error the mean, u and the probabilistically symmetric coverage
/// interval at the budget's p, and the validation of the GUM result `gum`
/// ([`super::evaluate_budget`] of the same solution and budget; JCGM 101 §8).
///
/// ```
/// use polycal::selfcal::{self, SelfcalOptions};
/// use polycal::simulate::{SelfcalSimConfig, simulate_selfcal};
/// use polycal::uncertainty::calibration::{InstrumentBudget, McOptions};
/// use polycal::uncertainty::monte_carlo::Trials;
///
/// // SelfA's twelve heads on 168 positions, two cycles
/// let (set, _truth) = simulate_selfcal(&SelfcalSimConfig::default())?;
/// let solution = selfcal::solve(&set, &SelfcalOptions::new())?;
/// let budget = InstrumentBudget::from_toml_str(
///     "[[component]]\nname = \"r\"\ntype = \"B\"\ndistribution = \"rectangular\"\nhalf_width = 0.05\nacts_on = \"each-reading\"\n",
///     "budget.toml",
/// )?;
/// let gum = selfcal::evaluate_budget(&solution, &budget)?;
/// let mc = selfcal::monte_carlo(&set, &solution, &budget, &gum, &McOptions::new(Trials::Fixed(5_000)))?;
/// assert_eq!((mc.encoder_error.u.len(), mc.head_error.u.len()), (168, 11));
/// assert!((mc.encoder_error.u[3] / gum.encoder_error.u[3] - 1.0).abs() < 0.1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`CalibrationError::NoSigma`] without σ, an invalid budget, and
/// [`CalibrationError::MonteCarlo`] for too few trials, a non-finite trial, an adaptive
/// run that does not stabilise or a run too large for the memory.
pub fn monte_carlo(
    set: &SelfcalSet,
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
    gum: &SelfcalUncertainty,
    options: &McOptions<'_>,
) -> Result<SelfcalMonteCarlo, CalibrationError> {
    let trial = SelfcalTrial::new(set, solution, budget)?;
    run(trial, solution, budget, gum, options)
}

/// Monte Carlo of a self-calibration fitted by the closure model `fit` of the readings
/// `closure` (its heads as setups, effect columns included: a diagnosis's final model),
/// `solution` the self-calibration it gives; otherwise as [`monte_carlo()`].
pub(crate) fn monte_carlo_of_closure_fit(
    closure: &MeasurementSet,
    fit: &Solution,
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
    gum: &SelfcalUncertainty,
    options: &McOptions<'_>,
) -> Result<SelfcalMonteCarlo, CalibrationError> {
    let model = McModel::with_setup_outputs(closure, fit, budget)?;
    let trial = SelfcalTrial::with_model(model, solution);
    run(trial, solution, budget, gum, options)
}

/// Monte Carlo of a self-calibration whose heads sit between the positions, fitted by
/// the band-limited design `design` with effect columns (`fit`, a diagnosis's final model
/// of the readings `closure`): every trial's readings solved by that fit's linear map
/// ([`OffGridFitMap`]); otherwise as [`monte_carlo()`].
pub(crate) fn monte_carlo_of_off_grid_fit(
    closure: &MeasurementSet,
    design: OffGridDesign,
    fit: &Solution,
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
    gum: &SelfcalUncertainty,
    options: &McOptions<'_>,
) -> Result<SelfcalMonteCarlo, CalibrationError> {
    let n = closure.readings.len();
    let (p, heads) = (design.positions(), design.heads());
    let map = OffGridFitMap::new(design, fit)
        .ok_or_else(|| mismatch("a final model not fitted by the band-limited design".into()))?;
    let route = CellRoute {
        residuals: &fit.residuals,
        sigma: fit.sigma,
        dof: fit.dof,
        cell: (0..n).collect(),
        cells: n,
        faces: p,
        setups: heads,
        map: Box::new(map),
    };
    let model = McModel::with_cell_map(closure, route, budget)?;
    run(
        SelfcalTrial::with_model(model, solution),
        solution,
        budget,
        gum,
        options,
    )
}

fn run(
    trial: SelfcalTrial,
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
    gum: &SelfcalUncertainty,
    options: &McOptions<'_>,
) -> Result<SelfcalMonteCarlo, CalibrationError> {
    let mut engine = EngineOptions::new(options.trials)
        .with_coverage(budget.p)
        .with_seed(options.seed);
    engine.progress = options.progress;
    let summary = monte_carlo::run(&trial, &engine)?;
    let digits = options.significant_digits.max(1);
    let p = solution.positions;
    let encoder_error =
        McFamily::validating(&solution.encoder_error, &gum.encoder_error, digits, |x| {
            summary.outputs[x]
        });
    let head_values: Vec<f64> = solution.head_error.iter().map(|h| h.value).collect();
    let head_error = McFamily::validating(&head_values, &gum.head_error, digits, |j| {
        summary.outputs[p + j]
    });
    let (reading_noise, reading_noise_dof) = trial.model.reading_noise();
    Ok(SelfcalMonteCarlo {
        trials: summary.trials,
        sequences: summary.sequences,
        seed: options.seed,
        p: budget.p,
        significant_digits: digits,
        reading_noise,
        reading_noise_dof,
        validated: encoder_error.all_passed() && head_error.all_passed(),
        encoder_error,
        head_error,
    })
}

/// One trial of a self-calibration: the closure model's trial (its outputs β, φ\[1..P−1\],
/// α and the heads' setup errors) turned into e in the solution's gauge and the heads'
/// errors relative to head 1, with the draws the solution adds.
struct SelfcalTrial {
    model: McModel,
    positions: usize,
    heads: usize,
    /// The positions whose mean of e is 0.
    gauge: Vec<usize>,
    /// The bound A on every lost harmonic, and their orders.
    lost: Option<(f64, Vec<usize>)>,
    /// The heads' angle uncertainty's contribution to each e and each head error.
    head_angle: Option<(Vec<f64>, Vec<f64>)>,
    centre: Vec<f64>,
}

impl SelfcalTrial {
    fn new(
        set: &SelfcalSet,
        solution: &SelfcalSolution,
        budget: &InstrumentBudget,
    ) -> Result<Self, CalibrationError> {
        let heads = set.heads();
        let model = match solution.grid {
            HeadGrid::OnGrid => {
                let offsets = grid_offsets(set, &heads).ok_or_else(|| {
                    mismatch("a solution on the grid of heads off the grid".into())
                })?;
                let closure =
                    closure_set(set, &heads, &offsets).map_err(|e| mismatch(e.to_string()))?;
                let (mut fit, _) = least_squares_zeroing_lost(&closure, &SolveOptions::new())
                    .map_err(|e| mismatch(e.to_string()))?;
                // The trials start from the self-calibration's fit (the table's error at
                // every stop), with its σ and degrees of freedom.
                if fit.readings != solution.residuals.len() {
                    return Err(mismatch(format!(
                        "{} readings, the solution {}",
                        fit.readings,
                        solution.residuals.len()
                    )));
                }
                fit.residuals.clone_from(&solution.residuals);
                fit.sigma = solution.sigma;
                fit.dof = solution.dof;
                McModel::with_setup_outputs(&closure, &fit, budget)?
            }
            _ => off_grid_model(set, &heads, solution, budget)?,
        };
        Ok(Self::with_model(model, solution))
    }

    /// The trial of a closure model's trial `model` (outputs β, φ\[1..P−1\], α and the
    /// heads' setup errors) for the self-calibration `solution`.
    fn with_model(model: McModel, solution: &SelfcalSolution) -> Self {
        let p = solution.positions;
        let stride = solution.gauge_positions.map_or(1, |n| p / n.max(1));
        let lost = solution.lost_harmonic_u.and_then(|u| {
            let count = solution.lost_harmonics.len();
            (count > 0 && u > 0.0).then(|| {
                (
                    u * 2f64.sqrt() / (count as f64).sqrt(),
                    solution.lost_harmonics.clone(),
                )
            })
        });
        let head_angle = solution.head_angle_u.clone().map(|on_e| {
            let on_c = solution
                .head_error
                .iter()
                .map(|h| h.head_angle_u.unwrap_or(0.0))
                .collect();
            (on_e, on_c)
        });
        let mut centre = solution.encoder_error.clone();
        centre.extend(solution.head_error.iter().map(|h| h.value));
        SelfcalTrial {
            model,
            positions: p,
            heads: solution.heads.len(),
            gauge: (0..p).step_by(stride.max(1)).collect(),
            lost,
            head_angle,
            centre,
        }
    }
}

/// The trial model of heads between the positions: the readings' sums per (head, step)
/// solved by the band-limited closure ([`OffGridMap`], what [`super::solve`] fits). The
/// budget's scopes group the readings as the closure set does (by head, stop and table
/// position; no scope looks at the faces, which stand at the nearest whole offsets).
fn off_grid_model(
    set: &SelfcalSet,
    heads: &[Head],
    solution: &SelfcalSolution,
    budget: &InstrumentBudget,
) -> Result<McModel, CalibrationError> {
    let p = set.positions;
    let offsets: Vec<f64> = heads
        .iter()
        .map(|h| h.angle_deg * p as f64 / 360.0)
        .collect();
    let nearest: Vec<usize> = offsets
        .iter()
        .map(|d| (d.round() as i64).rem_euclid(p as i64) as usize)
        .collect();
    let closure = closure_set(set, heads, &nearest).map_err(|e| mismatch(e.to_string()))?;
    let head_index = |head: u32| heads.binary_search_by_key(&head, |h| h.head).ok();
    let cell = set
        .readings
        .iter()
        .map(|r| head_index(r.head).map(|j| j * p + r.step))
        .collect::<Option<Vec<usize>>>()
        .ok_or_else(|| mismatch("a reading of no listed head".into()))?;
    let mut count = vec![0; heads.len() * p];
    for &c in &cell {
        count[c] += 1;
    }
    let map = OffGridMap::new(p, &offsets, &count);
    let route = CellRoute {
        residuals: &solution.residuals,
        sigma: solution.sigma,
        dof: solution.dof,
        cell,
        cells: heads.len() * p,
        faces: p,
        setups: heads.len(),
        map: Box::new(map),
    };
    McModel::with_cell_map(&closure, route, budget)
}

fn mismatch(message: String) -> CalibrationError {
    CalibrationError::Mismatch(message)
}

impl Trial for SelfcalTrial {
    /// The closure model's scratch and outputs.
    type Scratch = (McScratch, Vec<f64>);

    fn outputs(&self) -> usize {
        self.positions + self.heads - 1
    }

    fn centre(&self) -> &[f64] {
        &self.centre
    }

    fn scratch(&self) -> Self::Scratch {
        (self.model.scratch(), vec![0.0; self.model.outputs()])
    }

    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        (scratch, closure): &mut Self::Scratch,
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        self.model.sample(rng, scratch);
        if !self.model.solve(scratch, closure) {
            return Err(TrialFailure::Failed);
        }
        let p = self.positions;
        // The closure model's φ (faces 1 … P−1; φ[P] = 0), referenced to the gauge.
        let phi = |x: usize| if x + 1 < p { closure[p + x] } else { 0.0 };
        let mean = self.gauge.iter().map(|&x| phi(x)).sum::<f64>() / self.gauge.len() as f64;
        for (x, e) in out[..p].iter_mut().enumerate() {
            *e = phi(x) - mean;
        }
        // The heads' setup errors follow α: c[j] − c[1].
        let setups = &closure[3 * p - 1..];
        for (c, s) in out[p..].iter_mut().zip(&setups[1..]) {
            *c = s - setups[0];
        }
        for (o, d) in out.iter_mut().zip(scratch.result_offsets()) {
            *o += d;
        }
        if let Some((amplitude, orders)) = &self.lost {
            for &h in orders {
                let phase = rng.random::<f64>() * TAU;
                for (x, e) in out[..p].iter_mut().enumerate() {
                    *e += amplitude * (TAU * (h * x) as f64 / p as f64 + phase).cos();
                }
            }
        }
        if let Some((on_e, on_c)) = &self.head_angle {
            for (o, u) in out.iter_mut().zip(on_e.iter().chain(on_c)) {
                let z: f64 = StandardNormal.sample(rng);
                *o += u * z;
            }
        }
        Ok(())
    }

    fn inputs(&self, (scratch, _): &Self::Scratch) -> Vec<f64> {
        scratch.targets().to_vec()
    }
}
