//! The outputs of `polycal diagnose` on a self-calibration file (docs/FORMAT.md §5.2,
//! "Self-calibration runs"): its JSON object, its table for people, and the errors
//! against a self-calibration truth.
//!
//! The diagnosis runs on the closure model with the heads in the autocollimators' place
//! ([`crate::diagnose::selfcal`]); its outputs speak of heads. In the JSON every `ac` of
//! the polygon diagnosis is `head`, `setup` (always the one mounting) is left out, and an
//! effect's change of the calibration is `encoder_change_max` (of e) and
//! `head_change_max` (of the heads' errors). The sentences (notes, checks, explanations)
//! pass through [`in_head_words`].

use std::fmt::Write;

use serde::Serialize;
use serde_json::{Map, Value};

use super::diagnose::{CheckReport, DiagnoseReport};
use super::selfcal::SelfcalReport;
use crate::diagnose::selfcal::SelfcalDiagnosis;
use crate::selfcal::{SelfcalMonteCarlo, SelfcalSolution, SelfcalUncertainty};
use crate::simulate::SelfcalTruth;

/// The words of a polygon diagnosis that a self-calibration's differ in, in the order
/// they are replaced: the heads stand in the autocollimators' place, the disc's positions
/// in the faces', and the two families an effect is judged by are e and the heads' errors
/// ([`crate::diagnose::base::Base::calibrated`]).
const HEAD_WORDS: &[(&str, &str)] = &[
    (
        "pitch deviations changed by up to",
        "encoder errors (e) changed by up to",
    ),
    ("changes pitch deviations by up to", "changes e by up to"),
    ("encoder errors by up to", "head errors by up to"),
    ("of β or α", "of e or a head error"),
    ("some β or α", "e or a head error"),
    ("β and α", "e and the heads' errors"),
    ("β or α", "e or a head error"),
    ("autocollimators", "heads"),
    ("autocollimator", "head"),
    ("setup 1 ac ", "head "),
    ("setup 1, ", ""),
    ("setup 1 ", ""),
    (" ac ", " head "),
];

/// A sentence of the polygon diagnosis in a self-calibration's words: autocollimators
/// become heads, `setup 1` (the one mounting) goes, and the two families a term is judged
/// by are e and the heads' errors.
///
/// ```
/// use polycal::output::diagnose_selfcal::in_head_words;
/// assert_eq!(
///     in_head_words("serial correlation of residuals, setup 1 ac 5"),
///     "serial correlation of residuals, head 5"
/// );
/// assert_eq!(in_head_words("the drift of autocollimator 2"), "the drift of head 2");
/// ```
pub fn in_head_words(text: &str) -> String {
    HEAD_WORDS
        .iter()
        .fold(text.to_string(), |t, (from, to)| t.replace(from, to))
}

/// The errors of a self-calibration against its truth, arcsec: e against the truth's e
/// with the lost harmonics removed (no self-calibration of this layout can determine
/// them; both are in the gauge Σe = 0), and the heads' errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SelfcalErrorSummary {
    /// RMS of e − e_true over the positions.
    pub encoder_rms: f64,
    /// Largest |e − e_true|.
    pub encoder_max: f64,
    /// RMS of (c_j − c_1) − its truth over heads 2 … M.
    pub head_rms: f64,
    /// Largest |(c_j − c_1) − its truth|.
    pub head_max: f64,
}

impl SelfcalErrorSummary {
    /// The errors of `solution` against `truth`; `None` when the truth is of another
    /// number of positions or lacks a head.
    pub fn new(solution: &SelfcalSolution, truth: &SelfcalTruth) -> Option<Self> {
        let p = solution.positions;
        if truth.positions != p || truth.encoder_error.len() != p {
            return None;
        }
        let true_e = without_harmonics(&truth.encoder_error, &solution.lost_harmonics);
        let e: Vec<f64> = solution
            .encoder_error
            .iter()
            .zip(&true_e)
            .map(|(a, b)| a - b)
            .collect();
        let c: Vec<f64> = solution
            .head_error
            .iter()
            .map(|h| Some(h.value - truth.head_error_of(h.head)?))
            .collect::<Option<_>>()?;
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
        let max = |v: &[f64]| v.iter().fold(0.0, |m: f64, x| m.max(x.abs()));
        Some(Self {
            encoder_rms: rms(&e),
            encoder_max: max(&e),
            head_rms: rms(&c),
            head_max: max(&c),
        })
    }
}

/// `values` (one per position of P, mean zero) without their harmonics of the orders
/// `lost` (1 … P/2): each order's cosine and sine least-squares part removed.
fn without_harmonics(values: &[f64], lost: &[usize]) -> Vec<f64> {
    let p = values.len();
    let mean = values.iter().sum::<f64>() / p.max(1) as f64;
    let mut out: Vec<f64> = values.iter().map(|v| v - mean).collect();
    for &k in lost.iter().filter(|&&k| k >= 1 && 2 * k <= p) {
        let w = std::f64::consts::TAU * k as f64 / p as f64;
        let (mut a, mut b) = (0.0, 0.0);
        for (x, v) in out.iter().enumerate() {
            a += v * (w * x as f64).cos();
            b += v * (w * x as f64).sin();
        }
        let scale = if 2 * k == p { 1.0 } else { 2.0 } / p as f64;
        for (x, v) in out.iter_mut().enumerate() {
            *v -= scale * (a * (w * x as f64).cos() + b * (w * x as f64).sin());
        }
    }
    out
}

/// The errors before and after.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SelfcalErrorReport {
    /// The base model's.
    pub before: SelfcalErrorSummary,
    /// The final model's.
    pub after: SelfcalErrorSummary,
}

/// The JSON object of `polycal diagnose --format json` for a self-calibration file
/// (docs/FORMAT.md §5.2).
#[derive(Debug, Clone, Serialize)]
pub struct SelfcalDiagnoseReport {
    /// The file diagnosed.
    pub file: String,
    /// `self-calibration`.
    pub kind: &'static str,
    /// The base model, as `polycal selfcal` reports it.
    pub before: SelfcalReport,
    /// The final model (base model + the effects found), as `polycal selfcal` reports it.
    pub after: SelfcalReport,
    /// The effects added, in the order found (docs/FORMAT.md §6, `head` for `ac`).
    pub effects: Vec<Value>,
    /// With a truth: the errors before and after.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<SelfcalErrorReport>,
    /// The verdict.
    pub adequate: bool,
    /// The limit that ended the search, `null` when nothing more was significant
    /// (docs/FORMAT.md §5).
    pub search_stopped: Option<&'static str>,
    /// Whether the run had redundancy enough to test any effect.
    pub testable: bool,
    /// The checks of the verdict.
    pub checks: Vec<CheckReport>,
    /// Sentences for people.
    pub notes: Vec<String>,
    /// The lack-of-fit test against pure error.
    pub lack_of_fit: Option<Value>,
    /// Where structure is left.
    pub structure: Vec<Value>,
    /// The terms tried and not added.
    pub tried: Vec<Value>,
    /// Outliers the data cannot attribute to one reading.
    pub unattributed: Vec<Vec<Value>>,
}

/// `value` with the polygon diagnosis's names in a self-calibration's (module
/// documentation).
fn in_head_terms(value: Value) -> Value {
    match value {
        Value::Object(map) => {
            let mut out = Map::new();
            for (key, v) in map {
                let key = match key.as_str() {
                    "ac" => "head".to_string(),
                    "setup" => continue,
                    "pitch_change_max" => "encoder_change_max".to_string(),
                    "encoder_change_max" => "head_change_max".to_string(),
                    _ => key,
                };
                out.insert(key, in_head_terms(v));
            }
            Value::Object(out)
        }
        Value::Array(values) => Value::Array(values.into_iter().map(in_head_terms).collect()),
        Value::String(text) => Value::String(in_head_words(&text)),
        other => other,
    }
}

fn converted<T: Serialize>(value: &T) -> Value {
    serde_json::to_value(value).map_or(Value::Null, in_head_terms)
}

impl SelfcalDiagnoseReport {
    /// The report of `diagnosis` of the file `file`; `truth` adds the errors.
    pub fn new(diagnosis: &SelfcalDiagnosis, truth: Option<&SelfcalTruth>, file: &str) -> Self {
        let d = &diagnosis.diagnosis;
        let polygon = DiagnoseReport::new(d, None, None);
        let effects: Vec<Value> = polygon.effects.iter().map(converted).collect();
        let after = SelfcalReport::new(&diagnosis.after, file);
        let error = truth.and_then(|t| {
            Some(SelfcalErrorReport {
                before: SelfcalErrorSummary::new(&diagnosis.before, t)?,
                after: SelfcalErrorSummary::new(&diagnosis.after, t)?,
            })
        });
        Self {
            file: file.to_string(),
            kind: "self-calibration",
            before: SelfcalReport::new(&diagnosis.before, file),
            after,
            effects,
            error,
            adequate: polygon.adequate,
            search_stopped: polygon.search_stopped,
            testable: polygon.testable,
            checks: polygon
                .checks
                .into_iter()
                .map(|c| CheckReport {
                    name: in_head_words(&c.name),
                    ..c
                })
                .collect(),
            notes: polygon.notes.iter().map(|n| in_head_words(n)).collect(),
            lack_of_fit: polygon.lack_of_fit.map(in_head_terms),
            structure: polygon.structure.into_iter().map(in_head_terms).collect(),
            tried: polygon.tried.into_iter().map(in_head_terms).collect(),
            unattributed: polygon
                .unattributed
                .into_iter()
                .map(|group| group.into_iter().map(in_head_terms).collect())
                .collect(),
        }
    }

    /// With an instrument budget evaluated on the final model: its U and k.
    pub fn with_uncertainty(mut self, uncertainty: &SelfcalUncertainty) -> Self {
        self.after = self.after.with_uncertainty(uncertainty);
        self
    }

    /// With the Monte Carlo of the final model ([`crate::diagnose::selfcal::monte_carlo`]).
    pub fn with_monte_carlo(mut self, monte_carlo: SelfcalMonteCarlo) -> Self {
        self.after = self.after.with_monte_carlo(monte_carlo);
        self
    }

    /// One line of JSON with the software version first ([`super::to_json`]).
    ///
    /// # Errors
    ///
    /// serde_json's error (not expected: every number is finite).
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        super::to_json(self)
    }
}

/// Writes the table of `polycal diagnose` on a self-calibration for people: the
/// diagnosis (as for a polygon run, in heads), the errors against a truth, and the
/// self-calibration of the final model with what the effects changed.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(
    out: &mut W,
    diagnosis: &SelfcalDiagnosis,
    truth: Option<&SelfcalTruth>,
    source: &str,
    uncertainty: Option<&SelfcalUncertainty>,
) -> std::fmt::Result {
    let mut text = String::new();
    super::diagnose_table::write_table(&mut text, &diagnosis.diagnosis, None, source)?;
    let (before, after) = (&diagnosis.before, &diagnosis.after);
    let first = format!(
        "Base model: {} faces, {} readings",
        diagnosis.diagnosis.before.faces, diagnosis.diagnosis.before.readings
    );
    let text = text.replacen(
        &first,
        &format!(
            "Base model (self-calibration, {} heads): {} positions, {} readings",
            before.heads.len(),
            before.positions,
            before.readings
        ),
        1,
    );
    write!(out, "{}", in_head_words(&text))?;
    if let Some(truth) = truth
        && let (Some(b), Some(a)) = (
            SelfcalErrorSummary::new(before, truth),
            SelfcalErrorSummary::new(after, truth),
        )
    {
        writeln!(
            out,
            "\nError against the truth (arcsec)   e RMS      e max      head RMS     head max"
        )?;
        for (label, e) in [("before", b), ("after", a)] {
            writeln!(
                out,
                "  {label:<32} {:>9.4}  {:>9.4}  {:>11.4}  {:>11.4}",
                e.encoder_rms, e.encoder_max, e.head_rms, e.head_max
            )?;
        }
        if !before.lost_harmonics.is_empty() {
            writeln!(
                out,
                "  (e against the truth without the lost harmonics, which no run of this layout determines)"
            )?;
        }
    }
    let change = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .fold(0.0, |m: f64, (x, y)| m.max((x - y).abs()))
    };
    let heads =
        |s: &SelfcalSolution| -> Vec<f64> { s.head_error.iter().map(|h| h.value).collect() };
    if !diagnosis.diagnosis.effects.is_empty() {
        writeln!(
            out,
            "\nThe effects changed e by up to {:.4}″ and the heads' errors by up to {:.4}″ against the base model.",
            change(&after.encoder_error, &before.encoder_error),
            change(&heads(after), &heads(before))
        )?;
    }
    writeln!(
        out,
        "\nSelf-calibration of the final model (base model + the effects found):"
    )?;
    super::selfcal::write_table(out, after, source, uncertainty)
}
