//! Closing the loop: find the residual structure of a fit, trace it to an effect the
//! model lacks, add that effect, and report the calibration before and after.
//!
//! The bare two-autocollimator cycle is exactly determined, so effects such as a
//! drifting autocollimator bias the result without leaving a residual. With redundancy
//! (closing readings, repeated cycles, counter-clockwise cycles) they leave structure in
//! the residuals. [`diagnose`] fits the base model, then repeatedly tries every candidate
//! effect term of docs/FORMAT.md §6 — `drift` and `offset-step` per autocollimator (and
//! cycle), `direction` (all autocollimators and each one), and `outlier` for the reading
//! with the largest studentized residual — as an extra column of the least-squares model,
//! and adds the most significant by an extra-sum-of-squares F test, with a Bonferroni
//! threshold over the candidates of its family so that false alarms stay rare. It stops
//! when nothing significant remains and checks whether the final residuals are
//! consistent with noise ([`residuals::adequacy`]).

pub mod residuals;

use crate::effects::Effect;
use crate::measurement::{Direction, MeasurementSet, Sigma};
use crate::solve::{Solution, SolveError, least_squares_with_regressors};
use crate::uncertainty::student::t_two_sided_tail;
use residuals::Adequacy;

/// Options of [`diagnose`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct DiagnoseOptions {
    /// Family-wise false-alarm probability of each added effect (Bonferroni over the
    /// candidates of a family: systematic effects, and outliers over all readings).
    /// The default 0.005 per family keeps a false effect on clean data to about 1 % of
    /// runs.
    pub family_alpha: f64,
    /// Probability of a false "inadequate" verdict on clean data.
    pub adequacy_alpha: f64,
    /// Most effects to add.
    pub max_effects: usize,
    /// Reading noise σ stated by the caller (uncertainties for dof = 0 and a χ² check of
    /// the final residuals).
    pub sigma: Option<Sigma>,
}

impl DiagnoseOptions {
    /// The defaults (see [`DiagnoseOptions::default`]).
    pub fn new() -> Self {
        Self::default()
    }

    /// With a stated σ of one reading (adds a χ² check).
    pub fn with_sigma(mut self, sigma: Sigma) -> Self {
        self.sigma = Some(sigma);
        self
    }

    /// With a stated σ when given.
    pub fn with_sigma_opt(mut self, sigma: Option<Sigma>) -> Self {
        self.sigma = sigma;
        self
    }

    /// With another family-wise false-alarm probability per family of effects.
    pub fn with_family_alpha(mut self, family_alpha: f64) -> Self {
        self.family_alpha = family_alpha;
        self
    }

    /// With another false-alarm probability of the adequacy checks.
    pub fn with_adequacy_alpha(mut self, adequacy_alpha: f64) -> Self {
        self.adequacy_alpha = adequacy_alpha;
        self
    }

    /// With another largest number of effects.
    pub fn with_max_effects(mut self, max_effects: usize) -> Self {
        self.max_effects = max_effects;
        self
    }
}

impl Default for DiagnoseOptions {
    fn default() -> Self {
        Self {
            family_alpha: 0.005,
            adequacy_alpha: 0.001,
            max_effects: 12,
            sigma: None,
        }
    }
}

/// An effect found in the data, with the evidence for it.
#[derive(Debug, Clone, PartialEq)]
pub struct FoundEffect {
    /// The effect with its fitted value (docs/FORMAT.md §6), in the final model.
    pub effect: Effect,
    /// Standard uncertainty of the value in the final model.
    pub u: Option<f64>,
    /// Extra-sum-of-squares F statistic (1 numerator degree of freedom) when added.
    pub f_statistic: f64,
    /// p-value of that F test.
    pub p_value: f64,
    /// p-value times the number of candidates of its family (Bonferroni), at most 1.
    pub p_adjusted: f64,
    /// Residual RMS before and after adding it, arcsec.
    pub residual_rms_before: f64,
    /// Residual RMS after adding it, arcsec.
    pub residual_rms_after: f64,
    /// Largest change it made to a pitch deviation, arcsec.
    pub pitch_change_max: f64,
    /// Largest change it made to an encoder error, arcsec.
    pub encoder_change_max: f64,
    /// For an outlier: its studentized residual in the model before it was added.
    pub studentized_residual: Option<f64>,
}

/// The result of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct Diagnosis {
    /// Fit of the base model.
    pub before: Solution,
    /// Fit of the final model (base model plus `effects`).
    pub after: Solution,
    /// The effects added, in the order they were found.
    pub effects: Vec<FoundEffect>,
    /// The verdict on the final residuals.
    pub adequacy: Adequacy,
    /// Whether the data had redundancy enough to test any effect.
    pub testable: bool,
    /// Plain statements for people: what could not be tested and which added readings
    /// would make it visible.
    pub notes: Vec<String>,
}

/// The candidates of one round, each with the size of its Bonferroni family.
struct Candidate {
    effect: Effect,
    family_size: usize,
    studentized: Option<f64>,
}

fn regressor(effect: &Effect, set: &MeasurementSet) -> Vec<f64> {
    let context = crate::effects::EffectContext::of(&set.readings);
    set.readings
        .iter()
        .map(|r| effect.regressor(r, &context))
        .collect()
}

/// Fits the base model, then adds the effects the data demand, one at a time.
///
/// ```
/// use polycal::diagnose::{diagnose, DiagnoseOptions};
/// use polycal::effects::Effect;
/// use polycal::simulate::{simulate, SimulationConfig};
///
/// // autocollimator 2 drifts 2″ per hour; nobody tells diagnose
/// let config = SimulationConfig {
///     effects: vec![Effect::Drift { ac: 2, value: 2.0, quadratic: None }],
///     ..SimulationConfig::default()
/// };
/// let (set, _truth) = simulate(&config)?;
/// let diagnosis = diagnose(&set, &DiagnoseOptions::default())?;
/// assert!(matches!(diagnosis.effects[0].effect, Effect::Drift { ac: 2, .. }));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn diagnose(set: &MeasurementSet, options: &DiagnoseOptions) -> Result<Diagnosis, SolveError> {
    let sigma = options.sigma;
    let before = least_squares_with_regressors(set, &[], sigma)?;
    let mut notes = Vec::new();
    let testable = before.dof >= 2;
    if !testable {
        notes.push(format!(
            "The fit has {} residual degree{} of freedom: the readings determine the model exactly, so an effect (drift, a zero jump, a direction offset, an outlier) biases the result without leaving a residual, and none can be detected. To make effects visible, measure with redundancy: closing readings (step N), repeated cycles, and a counter-clockwise cycle.",
            before.dof,
            if before.dof == 1 { "" } else { "s" }
        ));
    }
    notes.extend(untestable_kinds(set));

    let mut regressors: Vec<Vec<f64>> = Vec::new();
    let mut effects: Vec<Effect> = Vec::new();
    let mut found: Vec<FoundEffect> = Vec::new();
    let mut current = before.clone();
    while testable && found.len() < options.max_effects && current.dof >= 2 {
        let candidates = candidates(set, &effects, &current, &regressors);
        let mut best: Option<(FoundEffect, Solution, Vec<f64>)> = None;
        for candidate in candidates {
            let x = regressor(&candidate.effect, set);
            if x.iter().all(|v| *v == 0.0) {
                continue;
            }
            regressors.push(x);
            let fit = least_squares_with_regressors(set, &regressors, sigma);
            let x = regressors.pop().unwrap_or_default();
            let Ok(fit) = fit else { continue };
            if fit.dof == 0 {
                continue;
            }
            let reduction = (current.rss - fit.rss).max(0.0);
            let f_statistic = if fit.rss > 0.0 {
                reduction / (fit.rss / fit.dof as f64)
            } else {
                f64::INFINITY
            };
            let p_value = t_two_sided_tail(f_statistic.sqrt(), Some(fit.dof as f64));
            let p_adjusted = (p_value * candidate.family_size as f64).min(1.0);
            if p_adjusted >= options.family_alpha {
                continue;
            }
            let better = best.as_ref().is_none_or(|(b, _, _)| {
                p_adjusted < b.p_adjusted
                    || (p_adjusted == b.p_adjusted && f_statistic > b.f_statistic)
            });
            if better {
                let value = fit.effect_values.last().copied().unwrap_or(0.0);
                let entry = FoundEffect {
                    effect: candidate.effect.clone().with_value(value),
                    u: None,
                    f_statistic,
                    p_value,
                    p_adjusted,
                    residual_rms_before: current.residual_rms().unwrap_or(0.0),
                    residual_rms_after: fit.residual_rms().unwrap_or(0.0),
                    pitch_change_max: max_change(&fit.pitch_deviation, &current.pitch_deviation),
                    encoder_change_max: max_change(&fit.encoder_error, &current.encoder_error),
                    studentized_residual: candidate.studentized,
                };
                best = Some((entry, fit, x));
            }
        }
        let Some((entry, fit, x)) = best else { break };
        effects.push(entry.effect.clone());
        regressors.push(x);
        found.push(entry);
        current = fit;
    }

    // Final values and uncertainties of every effect come from the final model.
    let u = current.effect_u();
    for (j, entry) in found.iter_mut().enumerate() {
        entry.effect = entry.effect.clone().with_value(current.effect_values[j]);
        entry.u = u.as_ref().map(|u| u[j]);
    }
    let lev = residuals::leverage(&current, set, &regressors);
    let studentized = residuals::studentized(&current, &lev);
    let adequacy = if testable {
        residuals::adequacy(&current, set, &studentized, sigma, options.adequacy_alpha)
    } else {
        Adequacy {
            adequate: true,
            checks: Vec::new(),
            structure: Vec::new(),
        }
    };
    Ok(Diagnosis {
        before,
        after: current,
        effects: found,
        adequacy,
        testable,
        notes,
    })
}

fn max_change(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

/// Effect kinds the data cannot show at all, and what would make them visible.
fn untestable_kinds(set: &MeasurementSet) -> Vec<String> {
    let mut notes = Vec::new();
    if set.readings.iter().any(|r| r.time_seconds.is_none()) {
        notes.push("Drift cannot be tested: the file has no `time` for every reading.".into());
    }
    let first_cycle = set.readings.first().map(|r| r.cycle);
    if set.readings.iter().all(|r| Some(r.cycle) == first_cycle) {
        notes.push("A zero jump between cycles (offset-step) cannot be tested with one cycle: repeat the cycle.".into());
    }
    let has = |d: Direction| set.readings.iter().any(|r| r.direction == d);
    if !(has(Direction::Cw) && has(Direction::Ccw)) {
        notes.push("A direction offset cannot be tested: the run has no cycle in the other direction (add a counter-clockwise cycle).".into());
    }
    notes
}

/// The candidate effects not yet in the model, with their Bonferroni family sizes.
fn candidates(
    set: &MeasurementSet,
    present: &[Effect],
    current: &Solution,
    regressors: &[Vec<f64>],
) -> Vec<Candidate> {
    let mut acs: Vec<u32> = set.readings.iter().map(|r| r.ac).collect();
    acs.sort_unstable();
    acs.dedup();
    let mut cycles: Vec<u32> = set.readings.iter().map(|r| r.cycle).collect();
    cycles.sort_unstable();
    cycles.dedup();
    let mut systematic = Vec::new();
    if set.readings.iter().all(|r| r.time_seconds.is_some()) {
        systematic.extend(acs.iter().map(|&ac| Effect::Drift {
            ac,
            value: 0.0,
            quadratic: None,
        }));
    }
    for &ac in &acs {
        for &cycle in cycles.iter().skip(1) {
            systematic.push(Effect::OffsetStep {
                ac,
                cycle,
                step: None,
                setup: None,
                value: 0.0,
            });
        }
    }
    let has = |d: Direction| set.readings.iter().any(|r| r.direction == d);
    if has(Direction::Cw) && has(Direction::Ccw) {
        systematic.push(Effect::Direction {
            ac: None,
            value: 0.0,
        });
        if acs.len() > 1 {
            systematic.extend(acs.iter().map(|&ac| Effect::Direction {
                ac: Some(ac),
                value: 0.0,
            }));
        }
    }
    let same_term = |a: &Effect, b: &Effect| a.clone().with_value(0.0) == b.clone().with_value(0.0);
    systematic.retain(|c| !present.iter().any(|p| same_term(p, c)));
    let family = systematic.len();
    let mut out: Vec<Candidate> = systematic
        .into_iter()
        .map(|effect| Candidate {
            effect,
            family_size: family,
            studentized: None,
        })
        .collect();

    // The outlier candidate: the reading with the largest |studentized residual|.
    let lev = residuals::leverage(current, set, regressors);
    let studentized = residuals::studentized(current, &lev);
    let several_setups = set.readings.iter().any(|r| r.setup != 1);
    let eligible = studentized.iter().filter(|t| t.is_some()).count();
    if let Some((i, t)) = studentized
        .iter()
        .enumerate()
        .filter_map(|(i, t)| t.map(|t| (i, t)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
    {
        let r = &set.readings[i];
        out.push(Candidate {
            effect: Effect::Outlier {
                cycle: r.cycle,
                step: r.step,
                ac: r.ac,
                setup: several_setups.then_some(r.setup),
                value: 0.0,
            },
            family_size: eligible,
            studentized: Some(t),
        });
    }
    out
}
