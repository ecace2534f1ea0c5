//! Outputs of `polycal diagnose` for programs: the JSON object of docs/FORMAT.md §5.2,
//! and the words every output uses for an effect (its label, the pattern that pointed to
//! it). The table for people is in [`super::diagnose_table`].

use crate::diagnose::lack_of_fit::LackOfFit;
use crate::diagnose::noise::NoiseTest;
use crate::diagnose::{Alternative, Clock, Diagnosis, FoundEffect, TriedEffect};
use crate::effects::{Effect, EffectContext};
use crate::measurement::{Direction, MeasurementSet};
use crate::output::SolveReport;
use crate::simulate::Truth;
use crate::solve::Solution;

use crate::solve::sub_pitch::SubPitchSolution;
use serde::Serialize;
use serde_json::{Map, Value};

/// RMS and largest absolute error of the pitch deviations and encoder errors against a
/// truth, arcsec (docs/FORMAT.md §5 `error`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorSummary {
    /// RMS of β − β_true.
    pub pitch_rms: f64,
    /// max |β − β_true|.
    pub pitch_max: f64,
    /// RMS of α − α_true.
    pub encoder_rms: f64,
    /// max |α − α_true|.
    pub encoder_max: f64,
}

impl ErrorSummary {
    /// Compares a solution with a truth of the same number of faces (`None` otherwise).
    pub fn new(solution: &Solution, truth: &Truth) -> Option<Self> {
        if truth.pitch_deviation.len() != solution.faces
            || truth.encoder_error.len() != solution.faces
        {
            return None;
        }
        let stats = |a: &[f64], b: &[f64]| {
            let n = a.len() as f64;
            let rms = (a.iter().zip(b).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / n).sqrt();
            let max = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            (rms, max)
        };
        let (pitch_rms, pitch_max) = stats(&solution.pitch_deviation, &truth.pitch_deviation);
        let (encoder_rms, encoder_max) = stats(&solution.encoder_error, &truth.encoder_error);
        Some(Self {
            pitch_rms,
            pitch_max,
            encoder_rms,
            encoder_max,
        })
    }
}

impl ErrorSummary {
    /// Compares a solution of sub-pitch mountings with a truth: β as [`ErrorSummary::new`],
    /// α at every table angle of every coset against the truth's encoder error at that
    /// angle, each coset's differences taken after removing their mean (a coset's
    /// encoder errors are determined up to a constant, docs/FORMAT.md §9.1). `None` when
    /// the faces differ or the truth has no encoder error at some angle.
    pub fn sub_pitch(solved: &SubPitchSolution, truth: &Truth) -> Option<Self> {
        let beta = &solved.solution.pitch_deviation;
        if truth.pitch_deviation.len() != beta.len() {
            return None;
        }
        let n = beta.len().max(1) as f64;
        let pitch_rms = (beta
            .iter()
            .zip(&truth.pitch_deviation)
            .map(|(x, y)| (x - y).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let pitch_max = beta
            .iter()
            .zip(&truth.pitch_deviation)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        let mut summary = ErrorSummary {
            pitch_rms,
            pitch_max,
            encoder_rms: 0.0,
            encoder_max: 0.0,
        };
        let cosets = solved.cosets.len().max(1);
        let mut differences = vec![Vec::new(); cosets];
        for (j, (alpha, angle)) in solved
            .encoder_error
            .iter()
            .zip(&solved.encoder_angle_deg)
            .enumerate()
        {
            differences[j % cosets].push(alpha - truth.encoder_error_at_deg(*angle)?);
        }
        let (mut sum_squares, mut count, mut max) = (0.0, 0usize, 0.0_f64);
        for d in &differences {
            let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
            for x in d {
                let e = x - mean;
                sum_squares += e * e;
                max = max.max(e.abs());
                count += 1;
            }
        }
        summary.encoder_rms = (sum_squares / count.max(1) as f64).sqrt();
        summary.encoder_max = max;
        Some(summary)
    }
}

/// Errors before and after diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorReport {
    /// Base model.
    pub before: ErrorSummary,
    /// Final model.
    pub after: ErrorSummary,
}

/// One adequacy check in the JSON (an addition to docs/FORMAT.md §5).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CheckReport {
    /// What was checked.
    pub name: String,
    /// The statistic.
    pub statistic: f64,
    /// The limit it must not exceed.
    pub limit: f64,
    /// Whether it passed.
    pub passed: bool,
}

/// The JSON object of `polycal diagnose` (docs/FORMAT.md §5).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnoseReport {
    /// The input file, present when several files were diagnosed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// The base model's fit.
    pub before: SolveReport,
    /// The final model's fit, its `effects` filled.
    pub after: SolveReport,
    /// The effects added, in the order they were found: docs/FORMAT.md §6 objects with `u`,
    /// and the evidence `F`, `p`, `p_adjusted`, `residual_rms_before`,
    /// `residual_rms_after`, `pitch_change_max`, `encoder_change_max`, `explanation`.
    pub effects: Vec<Value>,
    /// Errors against the truth (only with `--truth`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<ErrorReport>,
    /// Whether the final residuals are consistent with noise.
    pub adequate: bool,
    /// The limit that ended the search while something more was significant
    /// (`max-effects`, `too-few-degrees-of-freedom`, `jumps-per-zero`,
    /// `attempts-per-round`); `null` when it ended because nothing more was significant
    /// (docs/FORMAT.md §5). A stopped search is never adequate.
    pub search_stopped: Option<&'static str>,
    /// Whether the data had the redundancy to test effects (an addition).
    pub testable: bool,
    /// The adequacy checks (an addition).
    pub checks: Vec<CheckReport>,
    /// Plain statements: what could not be tested and why (an addition).
    pub notes: Vec<String>,
    /// The lack-of-fit test of the final model against pure error, `null` when no cell is
    /// read more than once (an addition).
    pub lack_of_fit: Option<Value>,
    /// The scatter the autocollimators share at a stop beyond the final model (an
    /// addition, docs/FORMAT.md §5): `{"significant", "sigma", "noise_sigma", "F", "dof",
    /// "dof_denominator", "p"}`, `null` when it could not be evaluated; when significant,
    /// `after`'s `encoder_error_u` carries `sigma`.
    pub stop_scatter: Option<Value>,
    /// Where structure is left when a check fails (an addition).
    pub structure: Vec<Value>,
    /// The test of equal noise of every (setup, autocollimator, cycle) group and the
    /// noise as groups (docs/FORMAT.md §5, `noise`): `equal`, `statistic`, `dof`, `p`,
    /// `sigma` (with `alpha`, `groups`, `changes`, `weighted` added); `null` when the test
    /// could not run.
    pub noise: Option<Value>,
    /// Terms tried and not added, with F, p and the reason (an addition).
    pub tried: Vec<Value>,
    /// Outliers the data cannot attribute to one reading: each a list of the readings of
    /// which one is bad (an addition).
    pub unattributed: Vec<Vec<Value>>,
    /// The cycles that disagree with the others (docs/FORMAT.md §5, `cycles`): `setup`,
    /// `cycle`, `statistic`, `dof`, `p`, `consistent`, `cause`, `action`, and the
    /// additions `dof_denominator`, `level`, `alternatives`, `acs` (swapped-acs), `by`
    /// (faces-shifted), `repaired` (F and p undone), `pitch_change_max`,
    /// `encoder_change_max` and `set_aside` (the readings that left the fit, with the
    /// reason). Always present, empty when none.
    pub cycles: Vec<Value>,
    /// The mountings that disagree with the others (an addition, docs/FORMAT.md §5.2,
    /// `mountings`): `setup`, `statistic`, `dof`, `dof_denominator`, `p`, `level`,
    /// `cause`, `action`, `alternatives`, `acs` (swapped-acs), `by` (faces-shifted),
    /// `repaired` and `set_aside`, as in `cycles`. Always present, empty when none.
    pub mountings: Vec<Value>,
    /// Every reading's residual before and after, in file order (an addition; present
    /// when built with [`DiagnoseReport::with_residuals`], as `polycal diagnose` does).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residuals: Option<ResidualsReport>,
}

/// The residual (reading − model, arcsec) of every reading under the base and the final
/// model, in the order of the measurement file, with the bookkeeping that places it
/// (docs/FORMAT.md §5, `residuals`; the source of `diagnose --plot`).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ResidualsReport {
    /// Setup of each reading.
    pub setup: Vec<u32>,
    /// Cycle of each reading.
    pub cycle: Vec<u32>,
    /// Step of each reading.
    pub step: Vec<usize>,
    /// Autocollimator of each reading.
    pub ac: Vec<u32>,
    /// `cw` or `ccw`.
    pub direction: Vec<&'static str>,
    /// Time of each reading, seconds; `null` when no reading has one (then a reading
    /// without one is `null`).
    pub time: Option<Vec<Option<f64>>>,
    /// Residual under the base model.
    pub before: Vec<f64>,
    /// Residual under the final model. A reading the final model leaves out (an outlier
    /// term) has the residual its own term absorbs: reading − (final model without that
    /// term), so it shows how far it stands, not 0.
    pub after: Vec<f64>,
    /// Indices (0-based, file order) of the readings the final model leaves out.
    pub left_out: Vec<usize>,
}

impl ResidualsReport {
    /// The residuals of `diagnosis` over the readings of `set` (the set it was made
    /// from); `None` when their numbers do not match.
    pub fn new(diagnosis: &Diagnosis, set: &MeasurementSet) -> Option<Self> {
        let readings = &set.readings;
        if diagnosis.before.residuals.len() != readings.len()
            || diagnosis.after.residuals.len() != readings.len()
        {
            return None;
        }
        let context = EffectContext::of(readings);
        let mut after = diagnosis.after.residuals.clone();
        let mut left_out = Vec::new();
        for found in &diagnosis.effects {
            if let Effect::Outlier { .. } = found.effect {
                for (i, reading) in readings.iter().enumerate() {
                    let x = found.effect.regressor(reading, &context);
                    if x != 0.0 {
                        after[i] += found.effect.value() * x;
                        left_out.push(i);
                    }
                }
            }
        }
        left_out.sort_unstable();
        left_out.dedup();
        let any_time = readings.iter().any(|r| r.time_seconds.is_some());
        Some(Self {
            setup: readings.iter().map(|r| r.setup).collect(),
            cycle: readings.iter().map(|r| r.cycle).collect(),
            step: readings.iter().map(|r| r.step).collect(),
            ac: readings.iter().map(|r| r.ac).collect(),
            direction: readings
                .iter()
                .map(|r| direction_text(r.direction))
                .collect(),
            time: any_time.then(|| readings.iter().map(|r| r.time_seconds).collect()),
            before: diagnosis.before.residuals.clone(),
            after,
            left_out,
        })
    }
}

/// [`explanation`] with a drift's unit of time on the diagnosis's clock (per stop in a
/// file without `time`), and a drift's order when it has a shape beyond its curvature.
pub fn explanation_on(found: &FoundEffect, clock: Clock) -> String {
    let mut text = explanation(found);
    if clock == Clock::StopOrder {
        text = text
            .replace("per hour²", "per stop²")
            .replace("per hour", "per stop")
            .replace("with time", "with the stop order");
    }
    if let Some(order) = found.drift_order.filter(|&k| k >= 3) {
        text.push_str(&format!(
            "; its shape over the run is a polynomial of order {order}, picked by F tests"
        ));
    }
    if let Some(kink) = &found.kink {
        let (at, unit) = match clock {
            Clock::Time => (format!("{:.0} s", kink.at_seconds), "″ per hour"),
            Clock::StopOrder => (
                format!("stop {:.0}", kink.at_seconds / 3600.0),
                "″ per stop",
            ),
        };
        text.push_str(&format!(
            "; its rate changes by {:+.4}{unit} at {at} (a kink the data locate among {} positions)",
            kink.rate_change, kink.positions_tried
        ));
    }
    text
}

/// One sentence on the pattern behind an effect (and, when it changes no β or α by more
/// than its uncertainty, a second saying so).
pub fn explanation(found: &FoundEffect) -> String {
    let pattern = pattern(found);
    if found.changes_calibration {
        pattern
    } else {
        format!(
            "{pattern}. Found, but it does not change β or α: no pitch deviation or encoder error moved by more than its standard uncertainty"
        )
    }
}

fn pattern(found: &FoundEffect) -> String {
    match &found.effect {
        Effect::Drift {
            ac,
            value,
            quadratic: None,
        } => format!(
            "the residuals of autocollimator {ac} trend linearly with time: its zero drifts {value:+.4}″ per hour"
        ),
        Effect::Drift {
            ac,
            value,
            quadratic: Some(q),
        } => format!(
            "the residuals of autocollimator {ac} trend with time along a curve: its zero drifts {value:+.4}″ per hour at the start, changing by {q:+.4}″ per hour² (times t²)"
        ),
        Effect::OffsetStep {
            ac,
            cycle,
            step,
            setup,
            value,
        } => format!(
            "the residuals of autocollimator {ac} jump from {}cycle {cycle}{} on: its zero moved by {value:+.4}″",
            setup.map_or(String::new(), |s| format!("setup {s}, ")),
            step.map_or(String::new(), |s| format!(", step {s}"))
        ),
        Effect::Temperature { ac, value } => format!(
            "the residuals of autocollimator {ac} follow the temperature: {value:+.4}″ per °C"
        ),
        Effect::CrossTalk { ac, value } => format!(
            "the residuals of autocollimator {ac} follow its elevation reading: {value:+.5}″ per arcsecond of reading_y"
        ),
        Effect::Rezero {
            ac, offsets, value, ..
        } => format!(
            "the residuals of autocollimator {ac} shift from cycle to cycle: its zero was set anew at the start of each of {} cycles, by up to {value:.4}″ against the first",
            offsets.len()
        ),
        Effect::Direction { ac, value } => format!(
            "counter-clockwise cycles read {value:+.4}″ against clockwise ones{}",
            ac.map_or(String::new(), |ac| format!(" on autocollimator {ac}"))
        ),
        Effect::Outlier {
            cycle,
            step,
            ac,
            value,
            ..
        } => format!(
            "the reading of autocollimator {ac} at cycle {cycle}, step {step} stands {:.1} standard deviations from the model ({value:+.4}″); it is left out of the fit",
            found.studentized_residual.unwrap_or(f64::NAN).abs()
        ),
    }
}

fn number(v: f64) -> Value {
    serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)
}

fn effect_object(effect: &Effect) -> Map<String, Value> {
    match serde_json::to_value(effect) {
        Ok(Value::Object(map)) => map,
        _ => Map::new(),
    }
}

pub(super) fn direction_text(direction: Direction) -> &'static str {
    match direction {
        Direction::Cw => "cw",
        Direction::Ccw => "ccw",
    }
}

fn noise_json(noise: &NoiseTest, several_setups: bool) -> Value {
    let sigma: Vec<Value> = noise
        .sigma
        .iter()
        .map(|g| {
            let mut object = serde_json::json!({
                "ac": g.ac, "cycles": g.cycles, "sigma": number(g.sigma_arcsec),
            });
            if let (true, Value::Object(map)) = (several_setups, &mut object) {
                map.insert("setup".into(), g.setup.into());
            }
            object
        })
        .collect();
    let changes: Vec<Value> = noise
        .changes
        .iter()
        .map(|c| {
            let mut object = serde_json::json!({
                "ac": c.ac, "from_cycle": c.from_cycle,
                "sigma_before": number(c.sigma_before_arcsec),
                "sigma_after": number(c.sigma_after_arcsec),
            });
            if let (true, Value::Object(map)) = (several_setups, &mut object) {
                map.insert("setup".into(), c.setup.into());
            }
            object
        })
        .collect();
    serde_json::json!({
        "equal": noise.equal,
        "statistic": number(noise.statistic),
        "dof": noise.dof,
        "p": number(noise.p_value),
        "alpha": number(noise.alpha),
        "groups": noise.groups,
        "sigma": sigma,
        "changes": changes,
        "weighted": noise.weighted,
    })
}

fn lack_of_fit_json(lof: &LackOfFit) -> Value {
    let cells: Vec<Value> = lof
        .worst_cells
        .iter()
        .map(|c| {
            serde_json::json!({
                "setup": c.setup, "step": c.step, "ac": c.ac,
                "direction": direction_text(c.direction), "face": c.face,
                "readings": c.readings, "mean_residual": number(c.mean_residual_arcsec),
                "z": number(c.z),
            })
        })
        .collect();
    let mut object = serde_json::json!({
        "F": number(lof.f_statistic),
        "dof_lack": lof.dof_lack,
        "dof_pure": lof.dof_pure,
        "limit": number(lof.limit),
        "p": number(lof.p_value),
        "passed": lof.passed(),
        "lower_limit": number(lof.lower_limit),
        "too_good": lof.too_good(),
        "pure_error_sigma": number(lof.pure_error_sigma),
        "cells": lof.cells,
        "replicated_cells": lof.replicated_cells,
        "worst_cells": cells,
        "carriers": lof.carriers,
    });
    if let (Some(order), Value::Object(map)) = (lof.band_limit_order, &mut object) {
        map.insert("band_limit_order".into(), order.into());
    }
    object
}

fn tried_json(tried: &TriedEffect) -> Value {
    let mut object = effect_object(&tried.effect);
    if tried.quadratic {
        object.insert("term".into(), Value::String("quadratic".into()));
    }
    object.insert("F".into(), number(tried.evidence.f_statistic));
    object.insert("p".into(), number(tried.evidence.p_value));
    object.insert("p_adjusted".into(), number(tried.evidence.p_adjusted));
    object.insert(
        "reason".into(),
        Value::String(tried.rejection.as_str().into()),
    );
    Value::Object(object)
}

fn alternative_json(alternative: &Alternative, clock: Clock) -> Value {
    let mut effects = alternative.effects.iter();
    let mut object = effects
        .next()
        .map_or_else(Map::new, |e| effect_with_unit(e, clock));
    let together: Vec<Value> = effects
        .map(|e| Value::Object(effect_with_unit(e, clock)))
        .collect();
    if !together.is_empty() {
        object.insert("together_with".into(), Value::Array(together));
    }
    object.insert("F".into(), number(alternative.f_statistic));
    object.insert("p".into(), number(alternative.p_value));
    object.insert(
        "pitch_change_max".into(),
        number(alternative.pitch_change_max),
    );
    object.insert(
        "encoder_change_max".into(),
        number(alternative.encoder_change_max),
    );
    object.insert(
        "change_over_expanded_u".into(),
        number(alternative.change_over_expanded_u),
    );
    object.insert("equivalent".into(), Value::Bool(alternative.equivalent));
    Value::Object(object)
}

/// An effect's object with the `unit` of a drift's value on the diagnosis's clock.
fn effect_with_unit(effect: &Effect, clock: Clock) -> Map<String, Value> {
    let mut object = effect_object(effect);
    if matches!(effect, Effect::Drift { .. }) {
        object.insert("unit".into(), Value::String(clock.drift_unit().into()));
    }
    object
}

fn effect_json(found: &FoundEffect, clock: Clock) -> Value {
    let mut object = effect_with_unit(&found.effect, clock);
    object.insert("u".into(), found.u.map_or(Value::Null, number));
    if let Some(order) = found.drift_order {
        object.insert("order".into(), Value::from(order));
        if order >= 3 {
            object.insert(
                "shape".into(),
                Value::Array(found.shape.iter().map(|&v| number(v)).collect()),
            );
            object.insert(
                "shape_u".into(),
                found.shape_u.as_ref().map_or(Value::Null, |u| {
                    Value::Array(u.iter().map(|&v| number(v)).collect())
                }),
            );
        }
    }
    if let Some(kink) = &found.kink {
        let at = match clock {
            Clock::Time => kink.at_seconds,
            Clock::StopOrder => kink.at_seconds / 3600.0,
        };
        object.insert(
            "kink".into(),
            serde_json::json!({
                "at": number(at),
                "rate_change": number(kink.rate_change),
                "rate_change_u": kink.rate_change_u.map_or(Value::Null, number),
                "F": number(kink.evidence.f_statistic),
                "p_adjusted": number(kink.evidence.p_adjusted),
                "positions_tried": kink.positions_tried,
            }),
        );
    }
    if found.dof_numerator > 1 {
        object.insert("df".into(), Value::from(found.dof_numerator));
    }
    if !found.alternatives.is_empty() {
        object.insert(
            "alternatives".into(),
            Value::Array(
                found
                    .alternatives
                    .iter()
                    .map(|a| alternative_json(a, clock))
                    .collect(),
            ),
        );
        object.insert("ambiguous".into(), Value::Bool(found.ambiguous()));
    }
    if matches!(
        found.effect,
        Effect::Drift {
            quadratic: Some(_),
            ..
        }
    ) {
        object.insert(
            "quadratic_u".into(),
            found.quadratic_u.map_or(Value::Null, number),
        );
        if let Some(e) = found.quadratic_evidence {
            object.insert("quadratic_F".into(), number(e.f_statistic));
            object.insert("quadratic_p".into(), number(e.p_value));
        }
    }
    object.insert("F".into(), number(found.f_statistic));
    object.insert("p".into(), number(found.p_value));
    object.insert("p_adjusted".into(), number(found.p_adjusted));
    object.insert(
        "residual_rms_before".into(),
        number(found.residual_rms_before),
    );
    object.insert(
        "residual_rms_after".into(),
        number(found.residual_rms_after),
    );
    object.insert("pitch_change_max".into(), number(found.pitch_change_max));
    object.insert(
        "encoder_change_max".into(),
        number(found.encoder_change_max),
    );
    object.insert(
        "changes_calibration".into(),
        Value::Bool(found.changes_calibration),
    );
    object.insert(
        "explanation".into(),
        Value::String(explanation_on(found, clock)),
    );
    Value::Object(object)
}

impl DiagnoseReport {
    /// Builds the report; `truth` adds the `error` section.
    pub fn new(diagnosis: &Diagnosis, truth: Option<&Truth>, file: Option<String>) -> Self {
        let effects: Vec<Value> = diagnosis
            .effects
            .iter()
            .map(|f| effect_json(f, diagnosis.clock))
            .collect();
        let report_of = |solution: &Solution, shifted: Option<&SubPitchSolution>| match shifted {
            Some(solved) => SolveReport::sub_pitch(solved, None),
            None => SolveReport::new(solution, None),
        };
        let mut after = report_of(&diagnosis.after, diagnosis.after_sub_pitch.as_ref());
        after.effects = effects.clone();
        let error = truth.and_then(|t| {
            Some(
                match (&diagnosis.before_sub_pitch, &diagnosis.after_sub_pitch) {
                    (Some(before), Some(after)) => ErrorReport {
                        before: ErrorSummary::sub_pitch(before, t)?,
                        after: ErrorSummary::sub_pitch(after, t)?,
                    },
                    _ => ErrorReport {
                        before: ErrorSummary::new(&diagnosis.before, t)?,
                        after: ErrorSummary::new(&diagnosis.after, t)?,
                    },
                },
            )
        });
        Self {
            file,
            before: report_of(&diagnosis.before, diagnosis.before_sub_pitch.as_ref()),
            after,
            effects,
            error,
            adequate: diagnosis.adequacy.adequate,
            search_stopped: diagnosis.search_stopped.map(|stop| stop.as_str()),
            testable: diagnosis.testable,
            checks: diagnosis
                .adequacy
                .checks
                .iter()
                .map(|c| CheckReport {
                    name: c.name.clone(),
                    statistic: c.statistic,
                    limit: c.limit,
                    passed: c.passed,
                })
                .collect(),
            notes: diagnosis.notes.clone(),
            lack_of_fit: diagnosis.lack_of_fit.as_ref().map(lack_of_fit_json),
            stop_scatter: diagnosis.stop_scatter.as_ref().map(|s| {
                serde_json::json!({
                    "significant": s.significant,
                    "sigma": number(s.sigma_arcsec),
                    "noise_sigma": number(s.noise_sigma_arcsec),
                    "F": number(s.f_statistic),
                    "dof": s.dof_numerator,
                    "dof_denominator": s.dof_denominator,
                    "p": number(s.p_value),
                })
            }),
            noise: diagnosis.noise.as_ref().map(|noise| {
                let several_setups = diagnosis
                    .before
                    .setup_error
                    .iter()
                    .any(|s| s.setup != diagnosis.before.setup_error[0].setup);
                noise_json(noise, several_setups)
            }),
            structure: diagnosis
                .adequacy
                .structure
                .iter()
                .map(|s| {
                    serde_json::json!({
                        "setup": s.setup, "ac": s.ac,
                        "from": {"cycle": s.from.0, "step": s.from.1, "time": s.from.2.map(number)},
                        "to": {"cycle": s.to.0, "step": s.to.1, "time": s.to.2.map(number)},
                        "mean_residual": number(s.mean_residual_arcsec),
                        "readings": s.readings,
                    })
                })
                .collect(),
            tried: diagnosis.tried.iter().map(tried_json).collect(),
            unattributed: diagnosis
                .unattributed
                .iter()
                .map(|group| {
                    group
                        .iter()
                        .map(|r| {
                            serde_json::json!({
                                "setup": r.setup, "cycle": r.cycle, "step": r.step, "ac": r.ac,
                                "residual": number(r.residual_arcsec),
                                "studentized_residual": number(r.studentized_residual),
                            })
                        })
                        .collect()
                })
                .collect(),
            cycles: diagnosis.cycles.iter().map(cycle_json).collect(),
            mountings: diagnosis.mountings.iter().map(mounting_json).collect(),
            residuals: None,
        }
    }

    /// With every reading's residuals before and after (`set`: the measurement set the
    /// diagnosis was made from).
    pub fn with_residuals(mut self, diagnosis: &Diagnosis, set: &MeasurementSet) -> Self {
        self.residuals = ResidualsReport::new(diagnosis, set);
        self
    }

    /// One line of JSON, with the software version ([`crate::output::to_json`]).
    ///
    /// # Errors
    ///
    /// serde_json's error (not expected for this plain data).
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        crate::output::to_json(self)
    }
}

/// One cycle that disagrees, as in docs/FORMAT.md §5 (`cycles`).
fn cycle_json(c: &crate::diagnose::cycles::CycleFinding) -> Value {
    let mut object = serde_json::json!({
        "setup": c.setup,
        "cycle": c.cycle,
        "statistic": number(c.f_statistic),
        "dof": c.dof_numerator,
        "dof_denominator": c.dof_denominator,
        "p": number(c.p_value),
        "level": number(c.level),
        "consistent": c.consistent,
        "cause": c.cause.as_str(),
        "action": c.action.as_str(),
        "alternatives": c.alternatives.iter().map(|a| a.as_str()).collect::<Vec<_>>(),
        "repaired": c.repaired.map(|(f, p)| serde_json::json!({"statistic": number(f), "p": number(p)})),
        "pitch_change_max": number(c.pitch_change_max),
        "encoder_change_max": number(c.encoder_change_max),
        "set_aside": set_aside_json(&c.set_aside),
    });
    cause_details(&mut object, c.cause);
    object
}

/// The pair of a swapped-acs cause (`acs`) and the shift of a faces-shifted one (`by`).
fn cause_details(object: &mut Value, cause: crate::diagnose::cycles::CycleCause) {
    use crate::diagnose::cycles::CycleCause;
    match cause {
        CycleCause::SwappedAcs { a, b } => object["acs"] = serde_json::json!([a, b]),
        CycleCause::FacesShifted { by } => object["by"] = serde_json::json!(by),
        _ => {}
    }
}

/// The readings that left the fit with a cycle or a mounting.
fn set_aside_json(readings: &[crate::diagnose::cycles::SetAsideReading]) -> Vec<Value> {
    readings
        .iter()
        .map(|r| {
            serde_json::json!({
                "setup": r.setup, "cycle": r.cycle, "step": r.step, "ac": r.ac, "line": r.line,
                "reading": number(r.reading_arcsec), "reason": r.reason,
            })
        })
        .collect()
}

/// One mounting that disagrees (docs/FORMAT.md §5.2, `mountings`).
fn mounting_json(m: &crate::diagnose::cycles::mountings::MountingFinding) -> Value {
    let mut object = serde_json::json!({
        "setup": m.setup,
        "statistic": number(m.f_statistic),
        "dof": m.dof_numerator,
        "dof_denominator": m.dof_denominator,
        "p": number(m.p_value),
        "level": number(m.level),
        "consistent": false,
        "cause": m.cause.as_str(),
        "action": m.action.as_str(),
        "alternatives": m.alternatives.iter().map(|a| a.as_str()).collect::<Vec<_>>(),
        "repaired": m.repaired.map(|(f, p)| serde_json::json!({"statistic": number(f), "p": number(p)})),
        "set_aside": set_aside_json(&m.set_aside),
    });
    cause_details(&mut object, m.cause);
    object
}
