//! The Monte Carlo of a calibration (GUM Supplement 1, JCGM 101:2008) through its
//! solver, on the crate's one engine, and its validation of the GUM result (JCGM 101 §8):
//! [`monte_carlo()`].

use std::fmt;

use serde::Serialize;

use super::gum::{CalibrationUncertainty, FamilyUncertainty, KnownCorrection};
use super::trial::{McModel, McSolver};
use super::{CalibrationError, InstrumentBudget};
use crate::measurement::MeasurementSet;
use crate::solve::Solution;
use crate::uncertainty::monte_carlo::{
    self, EngineOptions, OutputSummary, Progress, Trials, validate_gum,
};

/// Options of [`monte_carlo()`]: the number of trials, the seed, the significant digits of
/// the validation, the solver of the trials and a progress observer.
///
/// ```
/// use polycal::uncertainty::calibration::McOptions;
/// use polycal::uncertainty::monte_carlo::Trials;
///
/// let bar = |done: u64, total: Option<u64>| eprint!("\r{done} of {total:?} trials");
/// let options = McOptions::new(Trials::Fixed(200_000))
///     .with_seed(4)
///     .with_significant_digits(1)
///     .with_progress(&bar);
/// assert_eq!((options.seed, options.significant_digits), (4, 1));
/// ```
#[derive(Clone, Copy)]
#[non_exhaustive]
pub struct McOptions<'a> {
    /// Fixed M, or the adaptive procedure of JCGM 101 §7.9.
    pub trials: Trials,
    /// Seed of the random streams (default 1).
    pub seed: u64,
    /// Significant digits of u_c for the validation of the GUM result (JCGM 101 §8.2;
    /// default 2).
    pub significant_digits: u32,
    /// Solver of the trials (default automatic).
    pub solver: McSolver,
    /// Told the trials done after every block of trials (default none); see
    /// [`Progress`].
    pub progress: Option<&'a dyn Progress>,
}

impl<'a> McOptions<'a> {
    /// `trials` trials, seed 1, 2 significant digits, automatic solver, no progress
    /// observer.
    pub fn new(trials: Trials) -> Self {
        McOptions {
            trials,
            seed: 1,
            significant_digits: 2,
            solver: McSolver::Auto,
            progress: None,
        }
    }

    /// The same options with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same options with `digits` significant digits of u_c for the validation.
    pub fn with_significant_digits(mut self, digits: u32) -> Self {
        self.significant_digits = digits;
        self
    }

    /// The same options with another solver of the trials.
    pub fn with_solver(mut self, solver: McSolver) -> Self {
        self.solver = solver;
        self
    }

    /// The same options with a progress observer, told after every block of
    /// [`BLOCK_SIZE`](crate::uncertainty::monte_carlo::BLOCK_SIZE) trials how many trials
    /// have run and how many will (`None` for the adaptive procedure): see [`Progress`].
    pub fn with_progress(mut self, progress: &'a dyn Progress) -> Self {
        self.progress = Some(progress);
        self
    }
}

impl Default for McOptions<'_> {
    /// 10⁶ trials, seed 1, 2 significant digits, automatic solver.
    fn default() -> Self {
        McOptions::new(Trials::Fixed(1_000_000))
    }
}

impl fmt::Debug for McOptions<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("McOptions")
            .field("trials", &self.trials)
            .field("seed", &self.seed)
            .field("significant_digits", &self.significant_digits)
            .field("solver", &self.solver)
            .field("progress", &self.progress.map(|_| "observer"))
            .finish()
    }
}

/// Monte Carlo results of one family of quantities, per index.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct McFamily {
    /// Mean of the trials.
    pub mean: Vec<f64>,
    /// Standard deviation of the trials: the standard uncertainty.
    pub u: Vec<f64>,
    /// Lower end of the probabilistically symmetric coverage interval.
    pub low: Vec<f64>,
    /// Upper end.
    pub high: Vec<f64>,
    /// |y − U − low| of the GUM result (JCGM 101 §8.2).
    pub d_low: Vec<f64>,
    /// |y + U − high|.
    pub d_high: Vec<f64>,
    /// Numerical tolerance δ of the GUM u_c.
    pub delta: Vec<f64>,
    /// Whether d_low and d_high are both within δ.
    pub passed: Vec<bool>,
}

impl McFamily {
    /// The Monte Carlo summaries of a family (`summary(i)` of quantity i) with the
    /// validation of its GUM results y ± U (JCGM 101 §8) at `digits` significant digits
    /// of u_c.
    pub(crate) fn validating(
        estimates: &[f64],
        gum: &FamilyUncertainty,
        digits: u32,
        summary: impl Fn(usize) -> OutputSummary,
    ) -> Self {
        let n = estimates.len();
        let mut f = McFamily {
            mean: Vec::with_capacity(n),
            u: Vec::with_capacity(n),
            low: Vec::with_capacity(n),
            high: Vec::with_capacity(n),
            d_low: Vec::with_capacity(n),
            d_high: Vec::with_capacity(n),
            delta: Vec::with_capacity(n),
            passed: Vec::with_capacity(n),
        };
        for (i, &estimate) in estimates.iter().enumerate() {
            let mc = summary(i);
            let v = validate_gum(estimate, gum.u[i], gum.expanded_u[i], &mc, digits);
            f.mean.push(mc.mean);
            f.u.push(mc.u);
            f.low.push(mc.low);
            f.high.push(mc.high);
            f.d_low.push(v.d_low);
            f.d_high.push(v.d_high);
            f.delta.push(v.delta);
            f.passed.push(v.passed);
        }
        f
    }

    /// Whether every quantity's GUM interval is validated.
    pub(crate) fn all_passed(&self) -> bool {
        self.passed.iter().all(|&p| p)
    }
}

/// The Monte Carlo evaluation of a calibration ([`monte_carlo()`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationMonteCarlo {
    /// Trials M run.
    pub trials: usize,
    /// Sequences of the adaptive procedure (`null` for a fixed M).
    pub sequences: Option<usize>,
    /// Seed.
    pub seed: u64,
    /// Coverage probability.
    pub p: f64,
    /// Significant digits of the validation (and of the adaptive procedure).
    pub significant_digits: u32,
    /// `closed-form` or `lsq`.
    pub solver: &'static str,
    /// `normal` (stated σ) or `t` (σ from the residuals: scaled by √(ν/χ²_ν) per trial).
    pub reading_noise: &'static str,
    /// ν of the reading noise, `null` for normal.
    pub reading_noise_dof: Option<f64>,
    /// Whether every quantity's GUM interval is validated.
    pub validated: bool,
    /// Pitch deviations.
    pub pitch_deviation: McFamily,
    /// Face deviations (φ\[N\] = 0 exactly in every trial).
    pub face_deviation: McFamily,
    /// Encoder errors.
    pub encoder_error: McFamily,
}

/// Monte Carlo (GUM Supplement 1) of a calibration through its solver: per quantity the
/// mean, standard uncertainty, 95 % (the budget's p) probabilistically symmetric coverage
/// interval, and the validation of the GUM result `gum` (JCGM 101 §8).
///
/// # Errors
///
/// As [`super::evaluate`]; [`CalibrationError::MonteCarlo`] for too few trials, a
/// non-finite trial, or an adaptive run that does not stabilise.
pub fn monte_carlo(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    gum: &CalibrationUncertainty,
    options: &McOptions<'_>,
) -> Result<CalibrationMonteCarlo, CalibrationError> {
    monte_carlo_with_corrections(set, solution, budget, &[], gum, options)
}

/// [`monte_carlo()`] with the uncertainties of known corrections applied to the readings
/// ([`KnownCorrection`]): every trial draws each correction's error once, normal with its
/// u, shared by the readings its column touches; `gum` is then the result of
/// [`super::evaluate_with_corrections`] with the same corrections.
///
/// # Errors
///
/// As [`monte_carlo()`] and [`super::evaluate_with_corrections`].
pub fn monte_carlo_with_corrections(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    corrections: &[KnownCorrection],
    gum: &CalibrationUncertainty,
    options: &McOptions<'_>,
) -> Result<CalibrationMonteCarlo, CalibrationError> {
    let model = McModel::with_corrections(set, solution, budget, corrections, options.solver)?;
    let mut engine = EngineOptions::new(options.trials)
        .with_coverage(budget.p)
        .with_seed(options.seed);
    engine.progress = options.progress;
    let summary = monte_carlo::run(&model, &engine)?;
    let n = model.faces;
    let digits = options.significant_digits.max(1);
    let family = |estimates: &[f64], gum: &FamilyUncertainty, first: usize, len: usize| {
        McFamily::validating(estimates, gum, digits, |i| {
            if i < len {
                summary.outputs[first + i]
            } else {
                OutputSummary::new(0.0, 0.0, budget.p, 0.0, 0.0) // φ[N] = 0 in every trial
            }
        })
    };
    let pitch = family(&solution.pitch_deviation, &gum.pitch_deviation, 0, n);
    let face = family(&solution.face_deviation, &gum.face_deviation, n, n - 1);
    let encoder = family(&solution.encoder_error, &gum.encoder_error, 2 * n - 1, n);
    let validated = [&pitch, &face, &encoder].iter().all(|f| f.all_passed());
    let (reading_noise, reading_noise_dof) = model.reading_noise();
    Ok(CalibrationMonteCarlo {
        trials: summary.trials,
        sequences: summary.sequences,
        seed: options.seed,
        p: budget.p,
        significant_digits: digits,
        solver: model.solver_name(),
        reading_noise,
        reading_noise_dof,
        validated,
        pitch_deviation: pitch,
        face_deviation: face,
        encoder_error: encoder,
    })
}
