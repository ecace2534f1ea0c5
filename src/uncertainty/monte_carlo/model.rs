//! Monte Carlo of a measurement model given as a function of input quantities, each with
//! an estimate and a distribution (JCGM 101 §5, §6.4): [`MonteCarlo::run`].

use rand::Rng;

use super::engine::{self, EngineOptions, Trial, TrialFailure};
use super::{McError, McResult, Trials, adaptive_sequence_length};
use crate::progress::Progress;
use crate::uncertainty::budget::{Budget, EvaluationType, Source};
use crate::uncertainty::distribution::{Distribution, Sampler};

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

/// A Monte Carlo run of a model of input quantities: the inputs and the options of the
/// engine (number of trials, coverage probability, seed, whether to keep the samples, a
/// progress observer).
///
/// The model maps one draw of the inputs to the outputs: `Fn(&[f64], &mut Vec<f64>)`,
/// the first argument the inputs in the order of [`MonteCarlo::inputs`] (estimate plus a
/// draw from each input's [`Distribution`]), the second a vector, cleared before each
/// call, to push the outputs onto. Any computation fits: a closed form, or a solver run
/// on simulated readings. The trials run on the engine of this module ([`run`](super::run)):
/// reproducible from the seed whatever the number of threads. Every trial's outputs are
/// kept for the shortest coverage interval (JCGM 101 §7.7.2), which every output
/// summary carries.
///
/// ```
/// use polycal::uncertainty::distribution::Distribution;
/// use polycal::uncertainty::monte_carlo::{McInput, MonteCarlo, Trials};
///
/// // JCGM 101 §9.2.2: Y = X₁ + X₂ + X₃ + X₄ with standard normal inputs.
/// let inputs = (1..=4)
///     .map(|i| McInput::new(format!("X{i}"), 0.0, Distribution::Normal { u: 1.0 }))
///     .collect();
/// let r = MonteCarlo::new(inputs)
///     .with_trials(Trials::Fixed(200_000))
///     .with_seed(7)
///     .run(|x, y| y.push(x.iter().sum()))?;
/// assert!((r.outputs[0].half_width() - 3.92).abs() < 0.05);
/// # Ok::<(), polycal::uncertainty::monte_carlo::McError>(())
/// ```
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct MonteCarlo<'a> {
    /// The inputs, in the order the model receives them.
    pub inputs: Vec<McInput>,
    /// How the engine runs (default: `10⁶` fixed trials, `p = 0.95`, seed 1).
    pub options: EngineOptions<'a>,
}

impl<'a> MonteCarlo<'a> {
    /// A run with the given inputs, `10⁶` fixed trials, `p = 0.95`, seed 1.
    pub fn new(inputs: Vec<McInput>) -> Self {
        MonteCarlo {
            inputs,
            options: EngineOptions::new(Trials::Fixed(1_000_000)),
        }
    }

    /// The same run with other engine options.
    pub fn with_options(mut self, options: EngineOptions<'a>) -> Self {
        self.options = options;
        self
    }

    /// The same run with another number of trials.
    pub fn with_trials(mut self, trials: Trials) -> Self {
        self.options.trials = trials;
        self
    }

    /// The same run with another seed.
    pub fn with_seed(self, seed: u64) -> Self {
        let options = self.options.with_seed(seed);
        self.with_options(options)
    }

    /// The same run with another coverage probability.
    pub fn with_coverage(self, p: f64) -> Self {
        let options = self.options.with_coverage(p);
        self.with_options(options)
    }

    /// The same run, keeping (or not) the output values of every trial.
    pub fn with_samples(self, keep: bool) -> Self {
        let options = self.options.with_samples(keep);
        self.with_options(options)
    }

    /// The same run with a progress observer ([`Progress`]).
    pub fn with_progress(self, progress: &'a dyn Progress) -> Self {
        let options = self.options.with_progress(progress);
        self.with_options(options)
    }

    /// The number of trials per sequence of the adaptive procedure:
    /// `max(10⁴, ⌈100/(1 − p)⌉)` (JCGM 101 §7.9.4 b), rounded up to whole blocks.
    pub fn sequence_length(&self) -> usize {
        adaptive_sequence_length(self.options.p)
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
        let p = self.options.p;
        if !(p > 0.0 && p < 1.0) {
            return Err(McError::Coverage(p));
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
                    .map_err(|problem| McError::Input {
                        name: input.name.clone(),
                        problem,
                    })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let trial = InputTrial::new(samplers, &model)?;
        let mut result = engine::run(&trial, &self.options.with_samples(true))?;
        if !self.options.keep_samples {
            result.samples = None;
        }
        Ok(result)
    }
}

/// One trial of a model of input quantities: estimate plus a draw, per input in order.
struct InputTrial<'a, F> {
    samplers: Vec<(f64, Sampler)>,
    model: &'a F,
    /// The outputs at the estimates (non-finite ones replaced by 0).
    centre: Vec<f64>,
}

/// The inputs and outputs of the last trial of a block.
struct InputScratch {
    x: Vec<f64>,
    y: Vec<f64>,
}

impl<'a, F: Fn(&[f64], &mut Vec<f64>) + Sync> InputTrial<'a, F> {
    /// The trial, its number of outputs and its centre from the model at the estimates.
    fn new(samplers: Vec<(f64, Sampler)>, model: &'a F) -> Result<Self, McError> {
        let estimates: Vec<f64> = samplers.iter().map(|(estimate, _)| *estimate).collect();
        let mut centre = Vec::new();
        model(&estimates, &mut centre);
        if centre.is_empty() {
            return Err(McError::NoOutputs);
        }
        for c in &mut centre {
            if !c.is_finite() {
                *c = 0.0;
            }
        }
        Ok(InputTrial {
            samplers,
            model,
            centre,
        })
    }
}

impl<F: Fn(&[f64], &mut Vec<f64>) + Sync> Trial for InputTrial<'_, F> {
    type Scratch = InputScratch;

    fn outputs(&self) -> usize {
        self.centre.len()
    }

    fn centre(&self) -> &[f64] {
        &self.centre
    }

    fn scratch(&self) -> InputScratch {
        InputScratch {
            x: vec![0.0; self.samplers.len()],
            y: Vec::with_capacity(self.centre.len()),
        }
    }

    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut InputScratch,
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        for (x, (estimate, sampler)) in scratch.x.iter_mut().zip(&self.samplers) {
            *x = estimate + sampler.sample(rng);
        }
        scratch.y.clear();
        (self.model)(&scratch.x, &mut scratch.y);
        if scratch.y.len() != out.len() {
            return Err(TrialFailure::OutputCount(scratch.y.len()));
        }
        out.copy_from_slice(&scratch.y);
        Ok(())
    }

    fn inputs(&self, scratch: &InputScratch) -> Vec<f64> {
        scratch.x.clone()
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
                    let distribution = monte_carlo_distribution(*evaluation, *distribution, *dof);
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

/// The distribution Monte Carlo draws for a budget component: a Type A normal with finite
/// degrees of freedom `ν` becomes a t distribution with `ν` degrees of freedom and scale
/// `u` (JCGM 101 §6.4.9.2); any other keeps its distribution.
pub(crate) fn monte_carlo_distribution(
    evaluation: EvaluationType,
    distribution: Distribution,
    dof: Option<f64>,
) -> Distribution {
    match (evaluation, distribution, dof) {
        (EvaluationType::A, Distribution::Normal { u }, Some(nu)) => {
            Distribution::StudentT { scale: u, dof: nu }
        }
        (_, d, _) => d,
    }
}
