//! Propagation of distributions by Monte Carlo (GUM Supplement 1, JCGM 101:2008): one
//! engine, generic over the trial.
//!
//! - The engine ([`run`], [`Trial`], [`EngineOptions`]) runs any [`Trial`] — one draw of
//!   the inputs and the model's outputs — in seeded blocks over rayon's threads: a fixed
//!   number of trials (JCGM 101 §7.2) or the adaptive procedure of §7.9, with the same
//!   numbers for the same seed whatever the number of threads (one random stream per
//!   block, [`block_rng`]), and an optional
//!   [`Progress`] observer told after every block.
//! - Its statistics, per output ([`OutputSummary`]): the mean, the standard uncertainty,
//!   the probabilistically symmetric coverage interval from the exact order statistics
//!   (§7.6, §7.7), and, when every trial is kept, the shortest interval.
//! - [`validate_gum`] compares a GUM result with the Monte Carlo interval (§8).
//!
//! Two users run on it: [`MonteCarlo::run`], for a model given as a function of input
//! quantities with distributions (and [`linear_budget_inputs`], a budget's linear model),
//! and the Monte Carlo of a calibration through its solver,
//! [`crate::uncertainty::calibration::monte_carlo`].

mod engine;
mod model;
mod statistics;
mod stream;
mod validation;

use serde::Serialize;

pub use crate::progress::Progress;
pub use engine::{BLOCK_SIZE, EngineOptions, Trial, TrialFailure, adaptive_sequence_length, run};
pub(crate) use model::monte_carlo_distribution;
pub use model::{McInput, MonteCarlo, linear_budget_inputs};
pub use statistics::{numerical_tolerance, symmetric_interval_positions};
#[cfg(target_arch = "x86_64")]
pub(crate) use stream::has_avx2;
pub use stream::{BlockRng, block_rng};
pub use validation::{GumValidation, validate_gum};

use super::distribution::DistributionError;

/// How many trials to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Trials {
    /// A fixed number `M` of trials (JCGM 101 §7.2; `M ≥ 10⁴/(1 − p)` is a sound choice).
    Fixed(usize),
    /// The adaptive procedure of JCGM 101 §7.9.
    Adaptive {
        /// Number of significant decimal digits of the standard uncertainty to stabilize
        /// (`n_dig`, usually 1 or 2).
        significant_digits: u32,
        /// Give up (with [`McError::NotStabilized`]) beyond this many trials.
        max_trials: usize,
    },
}

/// The summary of one output (JCGM 101 §7.6, §7.7).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct OutputSummary {
    /// Mean of the output values: the estimate `y`.
    pub mean: f64,
    /// Standard deviation of the output values (divisor `M − 1`): `u(y)`.
    pub u: f64,
    /// Coverage probability of the intervals.
    pub p: f64,
    /// Lower end of the probabilistically symmetric coverage interval.
    pub low: f64,
    /// Upper end of the probabilistically symmetric coverage interval.
    pub high: f64,
    /// The shortest coverage interval (JCGM 101 §7.7.2), low and high end; known when
    /// every trial's outputs were kept.
    pub shortest: Option<(f64, f64)>,
}

impl OutputSummary {
    /// A summary without the shortest interval.
    pub fn new(mean: f64, u: f64, p: f64, low: f64, high: f64) -> Self {
        OutputSummary {
            mean,
            u,
            p,
            low,
            high,
            shortest: None,
        }
    }

    /// Half the length of the probabilistically symmetric interval.
    pub fn half_width(&self) -> f64 {
        0.5 * (self.high - self.low)
    }
}

/// The result of a run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct McResult {
    /// Number of trials `M` run.
    pub trials: usize,
    /// Number of sequences the adaptive procedure ran (`None` for a fixed `M`).
    pub sequences: Option<usize>,
    /// One summary per model output, in model order.
    pub outputs: Vec<OutputSummary>,
    /// The output values of every trial, per output (only when kept).
    #[serde(skip)]
    pub samples: Option<Vec<Vec<f64>>>,
}

/// Why a run failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum McError {
    /// An input's distribution is invalid.
    #[error("input {name:?}: {problem}")]
    Input {
        /// The input's name.
        name: String,
        /// What is wrong (part of the message, not a separate source).
        problem: DistributionError,
    },
    /// The estimate of an input is not finite.
    #[error("input {0:?}: the estimate must be a finite number")]
    Estimate(String),
    /// The coverage probability is not in (0, 1).
    #[error("coverage probability p must be between 0 and 1 (exclusive), got {0}")]
    Coverage(f64),
    /// Too few trials for the coverage interval.
    #[error(
        "{trials} trials are too few for a {p} coverage interval: use at least {needed} \
         (JCGM 101 §7.2 recommends 10⁴/(1 − p) or more)"
    )]
    TooFewTrials {
        /// Trials asked for.
        trials: usize,
        /// Coverage probability.
        p: f64,
        /// Minimum.
        needed: usize,
    },
    /// The run would need more memory than it may use (the values inside the coverage
    /// interval's brackets grow with the trials, and kept samples with trials × outputs).
    #[error(
        "{trials} trials of {outputs} outputs need about {} of memory; {} {limit_source}: \
         ask for fewer trials",
        crate::solve::memory::human_bytes(*needed_bytes),
        crate::solve::memory::human_bytes(u128::from(*limit_bytes))
    )]
    TooLarge {
        /// Trials asked for (the most an adaptive run may take).
        trials: usize,
        /// Outputs per trial.
        outputs: usize,
        /// Bytes the run would need.
        needed_bytes: u128,
        /// Bytes it may use.
        limit_bytes: u64,
        /// Where the limit comes from (`are available on this machine`).
        limit_source: &'static str,
    },
    /// The model gave no outputs.
    #[error("the model produced no outputs")]
    NoOutputs,
    /// The model gave different numbers of outputs in different trials.
    #[error("trial {trial}: the model produced {got} outputs, earlier trials {expected}")]
    OutputCount {
        /// Trial index (0-based).
        trial: usize,
        /// Outputs of earlier trials.
        expected: usize,
        /// Outputs of this trial.
        got: usize,
    },
    /// The model produced a NaN or an infinity, or could not be evaluated.
    #[error("trial {trial}: output {output} is {value} (inputs {inputs:?})")]
    NonFinite {
        /// Trial index (0-based).
        trial: usize,
        /// Output index (0-based).
        output: usize,
        /// The value.
        value: f64,
        /// The inputs of that trial.
        inputs: Vec<f64>,
    },
    /// The adaptive procedure did not stabilize within the trial limit.
    #[error(
        "the adaptive procedure did not stabilize within {trials} trials (at {digits} \
         significant digits); raise max_trials or ask for fewer digits"
    )]
    NotStabilized {
        /// Trials run.
        trials: usize,
        /// Significant digits asked for.
        digits: u32,
    },
    /// The adaptive procedure's largest number of trials is below two of its sequences,
    /// the fewest with which it can judge stability (JCGM 101 §7.9.4).
    #[error(
        "the adaptive procedure may run at most {max_trials} trials, fewer than the {fewest} \
         of two sequences with which it can judge stability (JCGM 101 §7.9.4): allow at least {fewest}"
    )]
    AdaptiveLimitTooLow {
        /// The largest number of trials allowed.
        max_trials: usize,
        /// Two sequences' trials.
        fewest: usize,
    },
    /// A budget cannot be turned into a Monte Carlo model.
    #[error("{0}")]
    Budget(String),
}
