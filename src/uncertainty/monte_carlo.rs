//! Propagation of distributions by Monte Carlo (GUM Supplement 1, JCGM 101:2008).
//!
//! A model maps one draw of the inputs to the outputs: `Fn(&[f64], &mut Vec<f64>)`, the
//! first argument the inputs in the order of [`MonteCarlo::inputs`] (estimate plus a
//! draw from each input's [`Distribution`]), the second a vector, cleared before each
//! call, to push the outputs onto. Any computation fits: a closed form, or the
//! least-squares closure solver run on simulated readings.
//!
//! - [`Trials::Fixed`] runs `M` trials; [`Trials::Adaptive`] runs the adaptive procedure
//!   of JCGM 101 §7.9: sequences of `max(10⁴, ⌈100/(1 − p)⌉)` trials until twice the
//!   standard deviation of the sequence estimates of the mean, standard uncertainty and
//!   both coverage interval endpoints of every output is within the numerical tolerance
//!   `δ` of its standard uncertainty for the requested number of significant digits.
//! - Results are reproducible from the seed regardless of the number of threads: trials
//!   are grouped in blocks of [`BLOCK_SIZE`], block `b` draws from its own ChaCha12
//!   stream (`seed`, stream `b`), and the blocks, spread over rayon's threads, are put
//!   back in order. Trial `t` therefore gets the same inputs whatever `M` and however
//!   many threads run.
//! - For each output: the mean, the standard uncertainty, the probabilistically symmetric
//!   coverage interval and the shortest one (JCGM 101 §7.7).
//! - [`validate_gum`] compares the GUM result with the Monte Carlo interval (JCGM 101 §8).

use rand::SeedableRng;
use rand_chacha::ChaCha12Rng;
use rayon::prelude::*;
use serde::Serialize;

use super::budget::{Budget, EvaluationType, Source};
use super::distribution::{Distribution, Sampler};

/// Number of trials drawn from one random stream; the unit of parallel work.
pub const BLOCK_SIZE: usize = 1000;

/// An input quantity: its estimate and the distribution of its deviation from it.
#[derive(Debug, Clone, PartialEq)]
pub struct McInput {
    /// Name (for messages).
    pub name: String,
    /// Estimate (the expectation of the input).
    pub estimate: f64,
    /// Distribution of the input around the estimate.
    pub distribution: Distribution,
}

impl McInput {
    /// An input with the given estimate and distribution.
    pub fn new(name: impl Into<String>, estimate: f64, distribution: Distribution) -> Self {
        McInput {
            name: name.into(),
            estimate,
            distribution,
        }
    }
}

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

/// A Monte Carlo run: inputs, number of trials, coverage probability and seed.
#[derive(Debug, Clone, PartialEq)]
pub struct MonteCarlo {
    /// The inputs, in the order the model receives them.
    pub inputs: Vec<McInput>,
    /// Number of trials.
    pub trials: Trials,
    /// Coverage probability of the intervals (default 0.95).
    pub p: f64,
    /// Seed of the random streams (default 1).
    pub seed: u64,
    /// Whether to return the output values of every trial (default no).
    pub keep_samples: bool,
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
    /// Lower end of the shortest coverage interval.
    pub shortest_low: f64,
    /// Upper end of the shortest coverage interval.
    pub shortest_high: f64,
}

impl OutputSummary {
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
    /// The output values of every trial, per output (only with `keep_samples`).
    #[serde(skip)]
    pub samples: Option<Vec<Vec<f64>>>,
}

/// Why a run failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum McError {
    /// An input's distribution is invalid.
    #[error("input {name:?}: {message}")]
    Input {
        /// The input's name.
        name: String,
        /// What is wrong.
        message: String,
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
    /// The model produced a NaN or an infinity.
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
    /// A budget cannot be turned into a Monte Carlo model.
    #[error("{0}")]
    Budget(String),
}

impl MonteCarlo {
    /// A run with the given inputs, `10⁶` fixed trials, `p = 0.95`, seed 1.
    pub fn new(inputs: Vec<McInput>) -> MonteCarlo {
        MonteCarlo {
            inputs,
            trials: Trials::Fixed(1_000_000),
            p: 0.95,
            seed: 1,
            keep_samples: false,
        }
    }

    /// The same run with another number of trials.
    pub fn with_trials(mut self, trials: Trials) -> Self {
        self.trials = trials;
        self
    }

    /// The same run with another seed.
    pub fn with_seed(mut self, seed: u64) -> Self {
        self.seed = seed;
        self
    }

    /// The same run with another coverage probability.
    pub fn with_coverage(mut self, p: f64) -> Self {
        self.p = p;
        self
    }

    /// The same run, keeping (or not) the output values of every trial.
    pub fn with_samples(mut self, keep: bool) -> Self {
        self.keep_samples = keep;
        self
    }

    /// The number of trials per sequence of the adaptive procedure:
    /// `max(10⁴, ⌈100/(1 − p)⌉)` (JCGM 101 §7.9.4 b), rounded up to whole blocks.
    pub fn sequence_length(&self) -> usize {
        adaptive_sequence_length(self.p)
    }

    /// Runs the model.
    ///
    /// # Errors
    ///
    /// [`McError`] for invalid inputs or `p`, too few trials, a model producing no, a
    /// varying number of, or non-finite outputs, or an adaptive run that does not
    /// stabilize.
    pub fn run<F>(&self, model: F) -> Result<McResult, McError>
    where
        F: Fn(&[f64], &mut Vec<f64>) + Sync,
    {
        if !(self.p > 0.0 && self.p < 1.0) {
            return Err(McError::Coverage(self.p));
        }
        let samplers = self
            .inputs
            .iter()
            .map(|input| {
                if !input.estimate.is_finite() {
                    return Err(McError::Estimate(input.name.clone()));
                }
                input
                    .distribution
                    .sampler()
                    .map(|s| (input.estimate, s))
                    .map_err(|message| McError::Input {
                        name: input.name.clone(),
                        message,
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let needed = minimum_trials(self.p);
        match self.trials {
            Trials::Fixed(m) => {
                if m < needed {
                    return Err(McError::TooFewTrials {
                        trials: m,
                        p: self.p,
                        needed,
                    });
                }
                let samples = run_trials(&samplers, self.seed, 0, m, &model)?;
                let outputs = samples.iter().map(|v| summarize(v, self.p)).collect();
                Ok(McResult {
                    trials: m,
                    sequences: None,
                    outputs,
                    samples: self.keep_samples.then_some(samples),
                })
            }
            Trials::Adaptive {
                significant_digits,
                max_trials,
            } => self.run_adaptive(&samplers, &model, significant_digits.max(1), max_trials),
        }
    }

    fn run_adaptive<F>(
        &self,
        samplers: &[(f64, Sampler)],
        model: &F,
        digits: u32,
        max_trials: usize,
    ) -> Result<McResult, McError>
    where
        F: Fn(&[f64], &mut Vec<f64>) + Sync,
    {
        let m = self.sequence_length();
        let mut samples: Vec<Vec<f64>> = Vec::new();
        // Per output, per sequence: (mean, u, low, high).
        let mut estimates: Vec<Vec<[f64; 4]>> = Vec::new();
        let mut h = 0;
        loop {
            if (h + 1) * m > max_trials.max(2 * m) {
                return Err(McError::NotStabilized {
                    trials: h * m,
                    digits,
                });
            }
            let sequence = run_trials(samplers, self.seed, h * m, (h + 1) * m, model)?;
            if samples.is_empty() {
                samples = vec![Vec::new(); sequence.len()];
                estimates = vec![Vec::new(); sequence.len()];
            } else if samples.len() != sequence.len() {
                return Err(McError::OutputCount {
                    trial: h * m,
                    expected: samples.len(),
                    got: sequence.len(),
                });
            }
            for (j, values) in sequence.into_iter().enumerate() {
                let s = summarize(&values, self.p);
                estimates[j].push([s.mean, s.u, s.low, s.high]);
                samples[j].extend_from_slice(&values);
            }
            h += 1;
            if h < 2 {
                continue;
            }
            let stable = samples.iter().zip(&estimates).all(|(values, seq)| {
                let delta = numerical_tolerance(standard_deviation(values), digits);
                (0..4).all(|q| {
                    let xs: Vec<f64> = seq.iter().map(|e| e[q]).collect();
                    2.0 * standard_deviation_of_mean(&xs) <= delta
                })
            });
            if stable {
                let outputs = samples.iter().map(|v| summarize(v, self.p)).collect();
                return Ok(McResult {
                    trials: h * m,
                    sequences: Some(h),
                    outputs,
                    samples: self.keep_samples.then_some(samples),
                });
            }
        }
    }
}

/// The number of trials per sequence of the adaptive procedure at coverage probability
/// `p`: `max(10⁴, ⌈100/(1 − p)⌉)` (JCGM 101 §7.9.4 b), rounded up to whole blocks of
/// [`BLOCK_SIZE`].
///
/// ```
/// use polycal::uncertainty::monte_carlo::adaptive_sequence_length;
/// assert_eq!(adaptive_sequence_length(0.95), 10_000);
/// assert_eq!(adaptive_sequence_length(0.999), 100_000);
/// ```
pub fn adaptive_sequence_length(p: f64) -> usize {
    let j = (100.0 / (1.0 - p)).ceil().max(10_000.0) as usize;
    j.div_ceil(BLOCK_SIZE) * BLOCK_SIZE
}

/// The 0-based positions, in the sorted values of `m` trials, of the ends of the
/// probabilistically symmetric `p` coverage interval (JCGM 101 §7.7): with `q = pM` if
/// an integer, else `⌊pM + 1/2⌋`, the interval is `[y_(r), y_(r+q)]` with `r = (M − q)/2`
/// if an integer, else `⌊(M − q + 1)/2⌋` (1-based), clamped to the sample.
///
/// ```
/// use polycal::uncertainty::monte_carlo::symmetric_interval_positions;
/// // M = 10⁶, p = 0.95: q = 950 000, r = 25 000: y_(25 000) and y_(975 000).
/// assert_eq!(symmetric_interval_positions(1_000_000, 0.95), (24_999, 974_999));
/// ```
pub fn symmetric_interval_positions(m: usize, p: f64) -> (usize, usize) {
    let pm = p * m as f64;
    let q = if (pm - pm.round()).abs() < 1e-9 * m as f64 {
        pm.round() as usize
    } else {
        (pm + 0.5).floor() as usize
    };
    let q = q.min(m - 1);
    let r = (m - q).div_ceil(2).max(1);
    (r - 1, (r + q - 1).min(m - 1))
}

/// The fewest trials for which the coverage interval has both ends: `⌈1/(1 − p)⌉`.
pub(crate) fn minimum_trials(p: f64) -> usize {
    (1.0 / (1.0 - p)).ceil() as usize
}

/// Runs trials `start..end` (`start` a multiple of `BLOCK_SIZE`) and returns the values per
/// output.
fn run_trials<F>(
    samplers: &[(f64, Sampler)],
    seed: u64,
    start: usize,
    end: usize,
    model: &F,
) -> Result<Vec<Vec<f64>>, McError>
where
    F: Fn(&[f64], &mut Vec<f64>) + Sync,
{
    debug_assert_eq!(start % BLOCK_SIZE, 0);
    let first_block = start / BLOCK_SIZE;
    let last_block = end.div_ceil(BLOCK_SIZE);
    let blocks: Vec<(usize, Vec<f64>)> = (first_block..last_block)
        .into_par_iter()
        .map(|b| {
            let from = b * BLOCK_SIZE;
            let to = ((b + 1) * BLOCK_SIZE).min(end);
            let mut rng = ChaCha12Rng::seed_from_u64(seed);
            rng.set_stream(b as u64);
            let mut x = vec![0.0; samplers.len()];
            let mut y = Vec::new();
            let mut n_out = None;
            let mut values = Vec::new();
            for trial in from..to {
                for (xi, (estimate, sampler)) in x.iter_mut().zip(samplers) {
                    *xi = estimate + sampler.sample(&mut rng);
                }
                y.clear();
                model(&x, &mut y);
                match n_out {
                    None => {
                        if y.is_empty() {
                            return Err(McError::NoOutputs);
                        }
                        n_out = Some(y.len());
                        values.reserve(y.len() * (to - from));
                    }
                    Some(n) if n != y.len() => {
                        return Err(McError::OutputCount {
                            trial,
                            expected: n,
                            got: y.len(),
                        });
                    }
                    Some(_) => {}
                }
                if let Some((output, &value)) = y.iter().enumerate().find(|(_, v)| !v.is_finite()) {
                    return Err(McError::NonFinite {
                        trial,
                        output,
                        value,
                        inputs: x.clone(),
                    });
                }
                values.extend_from_slice(&y);
            }
            Ok((n_out.unwrap_or(0), values))
        })
        .collect::<Result<_, _>>()?;
    let n_out = blocks.first().map_or(0, |b| b.0);
    let mut out = vec![Vec::with_capacity(end - start); n_out];
    for (b, (n, values)) in blocks.into_iter().enumerate() {
        if n != n_out {
            return Err(McError::OutputCount {
                trial: (first_block + b) * BLOCK_SIZE,
                expected: n_out,
                got: n,
            });
        }
        for row in values.chunks_exact(n_out) {
            for (column, &v) in out.iter_mut().zip(row) {
                column.push(v);
            }
        }
    }
    Ok(out)
}

/// Mean, standard uncertainty and coverage intervals of one output's values.
fn summarize(values: &[f64], p: f64) -> OutputSummary {
    let m = values.len();
    let mean = mean(values);
    let u = standard_deviation(values);
    let mut sorted = values.to_vec();
    sorted.sort_unstable_by(f64::total_cmp);
    // JCGM 101 §7.7, see `symmetric_interval_positions`.
    let (r_low, r_high) = symmetric_interval_positions(m, p);
    let q = r_high - r_low;
    let low = sorted[r_low];
    let high = sorted[r_high];
    // Shortest: the r* minimizing y_(r+q) − y_(r), r = 1 … M − q.
    let (best, _) = (0..m - q).fold((0, f64::INFINITY), |(best, width), i| {
        let w = sorted[i + q] - sorted[i];
        if w < width { (i, w) } else { (best, width) }
    });
    OutputSummary {
        mean,
        u,
        p,
        low,
        high,
        shortest_low: sorted[best],
        shortest_high: sorted[best + q],
    }
}

fn mean(values: &[f64]) -> f64 {
    // Pairwise-ish: sum in chunks to keep rounding small for millions of values.
    let sum: f64 = values.chunks(4096).map(|c| c.iter().sum::<f64>()).sum();
    sum / values.len() as f64
}

fn standard_deviation(values: &[f64]) -> f64 {
    let n = values.len();
    if n < 2 {
        return 0.0;
    }
    let m = mean(values);
    let ss: f64 = values
        .chunks(4096)
        .map(|c| c.iter().map(|v| (v - m) * (v - m)).sum::<f64>())
        .sum();
    (ss / (n - 1) as f64).sqrt()
}

/// `s(x̄) = √(Σ(x_r − x̄)²/(h(h − 1)))` (JCGM 101 §7.9.4 f).
pub(crate) fn standard_deviation_of_mean(xs: &[f64]) -> f64 {
    standard_deviation(xs) / (xs.len() as f64).sqrt()
}

/// The numerical tolerance `δ` of a standard uncertainty `u` to `n_dig` significant
/// digits (JCGM 101 §7.9.2): write `u = c × 10^ℓ` with `c` an `n_dig`-digit integer;
/// `δ = 10^ℓ / 2`. E.g. `u = 0.02847`, 2 digits: `c = 28`, `ℓ = −3`, `δ = 0.0005`.
pub fn numerical_tolerance(u: f64, significant_digits: u32) -> f64 {
    if !(u > 0.0 && u.is_finite()) {
        return 0.0;
    }
    let n = significant_digits.max(1) as i32;
    let mut l = u.log10().floor() as i32 - (n - 1);
    if (u / 10f64.powi(l)).round() >= 10f64.powi(n) {
        l += 1;
    }
    0.5 * 10f64.powi(l)
}

/// The comparison of a GUM result with Monte Carlo (JCGM 101 §8.2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GumValidation {
    /// Numerical tolerance `δ` of the GUM standard uncertainty.
    pub delta: f64,
    /// `|y − U_p − y_low|`.
    pub d_low: f64,
    /// `|y + U_p − y_high|`.
    pub d_high: f64,
    /// Whether both are within `δ`: the GUM uncertainty framework is validated.
    pub passed: bool,
}

/// Validates the GUM result `y ± U_p` (standard uncertainty `u`) against the Monte Carlo
/// probabilistically symmetric interval, to `significant_digits` digits of `u`
/// (JCGM 101 §8.2).
///
/// ```
/// use polycal::uncertainty::monte_carlo::{validate_gum, OutputSummary};
/// let mc = OutputSummary { mean: 0.0, u: 2.0, p: 0.95, low: -3.88, high: 3.88,
///                          shortest_low: -3.88, shortest_high: 3.88 };
/// // u = 2.0 to two digits: δ = 0.05; the GUM ends ±3.92 differ by 0.04: validated.
/// let v = validate_gum(0.0, 2.0, 3.92, &mc, 2);
/// assert!(v.passed && (v.delta - 0.05).abs() < 1e-15);
/// assert!(!validate_gum(0.0, 2.0, 3.92, &mc, 3).passed);
/// ```
pub fn validate_gum(
    estimate: f64,
    u: f64,
    expanded_u: f64,
    mc: &OutputSummary,
    significant_digits: u32,
) -> GumValidation {
    let delta = numerical_tolerance(u, significant_digits);
    let d_low = (estimate - expanded_u - mc.low).abs();
    let d_high = (estimate + expanded_u - mc.high).abs();
    GumValidation {
        delta,
        d_low,
        d_high,
        passed: d_low <= delta && d_high <= delta,
    }
}

/// The inputs of the linear model `Y = Σ cᵢ Xᵢ` of a budget (all estimates 0), with the
/// sensitivities `cᵢ`, nested budgets flattened (sensitivities multiplied), for comparing a
/// budget with Monte Carlo. A Type A input with a normal distribution and finite `ν`
/// becomes a t distribution with `ν` degrees of freedom and scale `u` (JCGM 101
/// §6.4.9.2); other inputs keep their distribution.
///
/// # Errors
///
/// [`McError::Budget`] when the budget has correlations (not supported here).
pub fn linear_budget_inputs(budget: &Budget) -> Result<(Vec<McInput>, Vec<f64>), McError> {
    fn walk(
        budget: &Budget,
        factor: f64,
        prefix: &str,
        inputs: &mut Vec<McInput>,
        c: &mut Vec<f64>,
    ) -> Result<(), McError> {
        if budget.correlations.iter().any(|r| r.r != 0.0) {
            return Err(McError::Budget(
                "correlated budget components are not supported by the linear Monte Carlo \
                 model"
                    .into(),
            ));
        }
        for comp in &budget.components {
            let name = format!("{prefix}{}", comp.name);
            match &comp.source {
                Source::Input {
                    evaluation,
                    distribution,
                    dof,
                } => {
                    let distribution = match (evaluation, distribution, dof) {
                        (EvaluationType::A, Distribution::Normal { u }, Some(nu)) => {
                            Distribution::StudentT {
                                scale: *u,
                                dof: *nu,
                            }
                        }
                        _ => *distribution,
                    };
                    inputs.push(McInput::new(name, 0.0, distribution));
                    c.push(factor * comp.sensitivity);
                }
                Source::Budget(inner) => walk(
                    inner,
                    factor * comp.sensitivity,
                    &format!("{name} / "),
                    inputs,
                    c,
                )?,
            }
        }
        Ok(())
    }
    let mut inputs = Vec::new();
    let mut c = Vec::new();
    walk(budget, 1.0, "", &mut inputs, &mut c)?;
    Ok((inputs, c))
}
