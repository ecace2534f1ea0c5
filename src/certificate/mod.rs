//! The documents a lab hands over, both built from one evaluated [`CalibrationReport`]
//! so that they can never disagree (docs/FORMAT.md §10):
//!
//! - [`html`]: the calibration report for people, one self-contained HTML file (inline
//!   SVG and CSS, nothing fetched, no script) that prints on A4;
//! - [`dcc`]: the Digital Calibration Certificate for programs, XML valid against the
//!   DCC 3.1.2 schema with its results in the D-SI 2.1.0 format (docs/FORMAT.md §10.3).
//!
//! [`CalibrationReport::build`] reads the input files, evaluates them exactly as the
//! commands do (`solve` with `--budget`, `diagnose`, `compare`, `selfcal`), and keeps the
//! same report objects their JSON prints, so that every number in either document is the
//! JSON's; [`CalibrationReport::to_html`] and [`CalibrationReport::to_dcc`] write them;
//! [`meta`] gathers what they say about the calibration besides the numbers.
//!
//! ```
//! use polycal::certificate::{CalibrationReport, ReportInputs};
//!
//! let inputs = ReportInputs::new("examples/data/polygon24-2ac-6cycles.csv")
//!     .with_budget("examples/budgets/instrument.toml")
//!     .with_generated_utc("2026-11-23T12:00:00.000Z");
//! let report = CalibrationReport::build(&inputs)?;
//! let html = report.to_html();
//! assert!(html.starts_with("<!DOCTYPE html>"));
//! assert!(report.verdict().passed());
//! # Ok::<(), polycal::certificate::ReportError>(())
//! ```

pub mod dcc;
mod history;
pub mod html;
mod inputs;
mod kc;
mod manifest;
pub mod meta;
mod record;
pub mod rounding;

use std::path::Path;

use sha2::{Digest, Sha256};

use crate::compare::{CompareOptions, Comparison, compare_with_file};
use crate::diagnose::selfcal::diagnose_selfcal;
use crate::diagnose::{DiagnoseOptions, diagnose};
use crate::figure::{self, Figure};
use crate::input::Location;
use crate::measurement::MeasurementSet;
use crate::output::diagnose::{CheckReport, DiagnoseReport};
use crate::output::diagnose_selfcal::SelfcalDiagnoseReport;
use crate::output::selfcal::SelfcalReport;
use crate::output::{SolveReport, result_rows_with};
use crate::results::read_results_from;
use crate::selfcal::{SelfcalOptions, SelfcalSet, SelfcalUncertainty};
use crate::simulate::{SelfcalTruth, Truth};
use crate::solve::SolveOptions;
use crate::solve::sub_pitch::{ShiftGeometry, solve_shifted};
use crate::uncertainty::calibration::{
    CalibrationUncertainty, InstrumentBudget, KnownCorrection, evaluate_with_corrections,
};

pub use crate::kc::KeyComparisonShapeError;
pub use history::{HistoryCalibration, HistorySection, agreement_with_prediction};
pub use inputs::{ReportError, ReportInputs};
pub use kc::KeyComparisonSection;
pub use meta::Metadata;

/// One input file of a report, with its fingerprint.
#[derive(Debug, Clone, PartialEq)]
pub struct InputFile {
    /// What it is (`measurement`, `budget`, `reference`, …).
    pub role: &'static str,
    /// Its file name, without the directories it was read from
    /// ([`crate::input::document_name`]): the documents name a file by its name and
    /// SHA-256 alone.
    pub path: String,
    /// Its size, bytes.
    pub bytes: u64,
    /// SHA-256 of its bytes, lower-case hex.
    pub sha256: String,
}

/// The design of a polygon measurement, as the method section states it.
#[derive(Debug, Clone, PartialEq)]
pub struct DesignSummary {
    /// N.
    pub faces: usize,
    /// Each (setup, autocollimator) and the face it reads at step 0, minus 1.
    pub face_offsets: Vec<((u32, u32), usize)>,
    /// Number of cycles.
    pub cycles: usize,
    /// Whether closing readings (step N) were taken.
    pub closing: bool,
    /// Whether some cycles ran counter-clockwise.
    pub bidirectional: bool,
    /// Number of polygon mountings.
    pub setups: usize,
    /// Number of readings.
    pub readings: usize,
}

/// What was evaluated: a polygon calibration or a self-calibration.
#[derive(Debug, Clone)]
#[non_exhaustive]
// One per report: the size of the polygon variant does not matter.
#[allow(clippy::large_enum_variant)]
pub enum Evaluation {
    /// Polygon and encoder by the closure method.
    Polygon {
        /// The `solve` JSON object (with the budget's U and k when given).
        solve: SolveReport,
        /// The design.
        design: DesignSummary,
        /// The budget evaluation.
        uncertainty: Option<CalibrationUncertainty>,
    },
    /// Encoder by multi-head self-calibration.
    Selfcal {
        /// The `selfcal` JSON object.
        report: SelfcalReport,
        /// The budget evaluation.
        uncertainty: Option<SelfcalUncertainty>,
    },
}

/// The diagnosis a report shows: the JSON object `polycal diagnose` prints for the file.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub enum DiagnosisReport {
    /// Of a measurement file.
    Polygon(Box<DiagnoseReport>),
    /// Of a self-calibration file.
    Selfcal(Box<SelfcalDiagnoseReport>),
}

impl DiagnosisReport {
    /// Whether the final model is adequate.
    pub fn adequate(&self) -> bool {
        self.parts().0
    }

    /// What both documents show of any diagnosis: whether the final model is adequate,
    /// its checks, the effects added (docs/FORMAT.md §6 objects) and the notes.
    pub fn parts(&self) -> (bool, &[CheckReport], &[serde_json::Value], &[String]) {
        match self {
            DiagnosisReport::Polygon(d) => (d.adequate, &d.checks, &d.effects, &d.notes),
            DiagnosisReport::Selfcal(d) => (d.adequate, &d.checks, &d.effects, &d.notes),
        }
    }
}

/// An effect of the diagnosis JSON in words: its kind, its other fields as `key value`
/// pairs, its value and u (arcsec, or the effect's unit).
pub(crate) fn effect_text(
    effect: &serde_json::Value,
) -> (String, String, Option<f64>, Option<f64>) {
    use serde_json::Value;
    let kind = effect
        .get("kind")
        .and_then(Value::as_str)
        .unwrap_or("effect")
        .to_string();
    let fields: Vec<String> = effect
        .as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !matches!(k.as_str(), "kind" | "value" | "u"))
                .map(|(k, v)| format!("{k} {v}"))
                .collect()
        })
        .unwrap_or_default();
    (
        kind,
        fields.join(", "),
        effect.get("value").and_then(Value::as_f64),
        effect.get("u").and_then(Value::as_f64),
    )
}

/// The verdicts a report carries (docs/FORMAT.md §8: status 1 when one is negative).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct Verdict {
    /// Some |En| > 1 in the comparison.
    pub comparison_failed: bool,
    /// The diagnosis found the final model not adequate.
    pub not_adequate: bool,
    /// This calibration does not agree with the value the standard's earlier calibrations
    /// predict (the vector test at 5 %, docs/FORMAT.md §13.2).
    pub history_disagrees: bool,
}

impl Verdict {
    /// Whether every check passed.
    pub fn passed(&self) -> bool {
        !self.comparison_failed && !self.not_adequate && !self.history_disagrees
    }
}

/// A calibration report, evaluated and ready to write.
#[derive(Debug, Clone)]
#[non_exhaustive]
pub struct CalibrationReport {
    /// Every input file, measurement first.
    pub inputs: Vec<InputFile>,
    /// The metadata.
    pub metadata: Metadata,
    /// The evaluation.
    pub evaluation: Evaluation,
    /// The diagnosis, when asked.
    pub diagnosis: Option<DiagnosisReport>,
    /// The comparison with the reference, and the reference's name.
    pub comparison: Option<(Comparison, String)>,
    /// The figures, in the report's order.
    pub figures: Vec<Figure>,
    /// The report's date and time, RFC 3339 UTC.
    pub generated_utc: String,
    /// The command line that made it, when known.
    pub command_line: Option<String>,
    /// Cross-talk stated from the autocollimators' calibrations, the readings corrected
    /// for it (docs/FORMAT.md §6); shown in the method section.
    pub stated_cross_talk: Vec<crate::measurement::cross_talk::StatedCrossTalk>,
    /// The key comparisons reported (docs/FORMAT.md §10.2): none, or those of the file of
    /// `--kc`, one per compared quantity in the file's order.
    pub key_comparisons: Vec<KeyComparisonSection>,
    /// The history of the standard, when earlier calibrations are given (docs/FORMAT.md
    /// §10.2, §13.2).
    pub history: Option<HistorySection>,
}

/// Reads a whole input file (at most [`crate::input::MAX_INPUT_BYTES`]) and fingerprints
/// it; with its name as given, for messages.
fn read_input(
    path: &Path,
    role: &'static str,
) -> Result<(Vec<u8>, InputFile, String), ReportError> {
    let (bytes, name) = crate::input::read_bytes(path)
        .map_err(|(file, source)| ReportError::Io { file, source })?;
    let given = name.clone();
    let input = InputFile {
        role,
        path: crate::input::document_name(&name),
        bytes: bytes.len() as u64,
        sha256: sha256_hex(&bytes),
    };
    Ok((bytes, input, given))
}

/// SHA-256 of bytes, lower-case hex (FIPS 180-4).
///
/// ```
/// assert_eq!(
///     polycal::certificate::sha256_hex(b"abc"),
///     "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
/// );
/// ```
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// The input files read so far, fingerprinted, with every name as given and as the
/// documents show it.
struct ReadFiles {
    /// (the name as given, the name the documents show).
    names: Vec<(String, String)>,
    files: Vec<InputFile>,
}

impl ReadFiles {
    /// Reads the instrument budget at `path`, parsed from the bytes fingerprinted.
    fn budget(&mut self, path: &Path) -> Result<InstrumentBudget, ReportError> {
        let (bytes, file, given) = read_input(path, "instrument budget")?;
        // parsed from the bytes fingerprinted; not UTF-8: the reader's located error
        let mut budget = match std::str::from_utf8(&bytes) {
            Ok(text) => InstrumentBudget::from_toml_str(text, &given)?,
            Err(_) => InstrumentBudget::read_path(path)?,
        };
        // the documents name the budget by its file name
        budget.source = file.path.clone();
        self.names.push((given, file.path.clone()));
        self.files.push(file);
        Ok(budget)
    }

    /// Reads the truth file at `path`: its bytes and its name as given (parsed later, by
    /// the kind of the measurement file).
    fn truth(&mut self, path: &Path) -> Result<(Vec<u8>, String), ReportError> {
        let (bytes, file, source) = read_input(path, "truth")?;
        self.names.push((source.clone(), file.path.clone()));
        self.files.push(file);
        Ok((bytes, source))
    }

    /// Reads the metadata file at `path`: its text (UTF-8, else a located error) and its
    /// name as given.
    fn meta(&mut self, path: &Path) -> Result<(String, String), ReportError> {
        let (meta_bytes, file, given) = read_input(path, "metadata")?;
        let text = crate::input::text::utf8(&meta_bytes)
            .map_err(|((line, column), message)| ReportError::Meta {
                location: Location::new(given.clone(), line, column),
                message,
            })?
            .to_string();
        self.names.push((given.clone(), file.path.clone()));
        let source = given;
        self.files.push(file);
        Ok((text, source))
    }

    /// Fingerprints the manifest of the run directory `dir`.
    fn run_manifest(&mut self, dir: &Path) -> Result<(), ReportError> {
        let (_, file, given) = read_input(&dir.join("manifest.json"), "run manifest")?;
        self.names.push((
            dir.join("manifest.json").display().to_string(),
            file.path.clone(),
        ));
        self.names.push((given, file.path.clone()));
        self.files.push(file);
        Ok(())
    }
}

/// What a report evaluates a measurement file into: the evaluation, the diagnosis when
/// asked, and the result rows with their expanded uncertainty (for a comparison).
type Evaluated = (
    Evaluation,
    Option<DiagnosisReport>,
    Option<Vec<crate::results::ResultRow>>,
);

/// The measurement file of a report, read, with what its evaluation needs.
struct Measurement<'a> {
    inputs: &'a ReportInputs,
    bytes: &'a [u8],
    /// Its name as given, for messages.
    name: &'a str,
    /// Its name as the documents show it.
    shown: &'a str,
    budget: Option<&'a InstrumentBudget>,
    /// The truth file's bytes and name as given.
    truth_bytes: Option<&'a (Vec<u8>, String)>,
}

impl Measurement<'_> {
    /// A self-calibration file evaluated as `selfcal` (and `diagnose`) does.
    fn evaluate_selfcal(&self) -> Result<Evaluated, ReportError> {
        let (inputs, name, shown) = (self.inputs, self.name, self.shown);
        if !inputs.stated_cross_talk.is_empty() {
            return Err(ReportError::NotSupported {
                file: name.to_string(),
                what: "a stated cross-talk",
                kind: "a self-calibration file",
            });
        }
        let set = SelfcalSet::read_from(self.bytes, name, inputs.faces)?;
        let solution =
            crate::selfcal::solve(&set, &SelfcalOptions::new().with_sigma_opt(inputs.sigma))
                .map_err(|source| ReportError::SelfcalSolve {
                    file: name.to_string(),
                    source,
                })?;
        let uncertainty = self
            .budget
            .map(|b| crate::selfcal::evaluate_budget(&solution, b))
            .transpose()
            .map_err(|source| ReportError::Uncertainty {
                file: name.to_string(),
                source,
            })?;
        let mut report = SelfcalReport::new(&solution, shown);
        if let Some(u) = &uncertainty {
            report = report.with_uncertainty(u);
        }
        let rows = crate::output::selfcal::result_rows(&solution, uncertainty.as_ref());
        let diagnosis = if inputs.diagnose {
            let selfcal_truth = self
                .truth_bytes
                .map(|(bytes, source)| SelfcalTruth::from_json_bytes(bytes, source))
                .transpose()?;
            let found = diagnose_selfcal(
                &set,
                &DiagnoseOptions::new().with_sigma_opt(inputs.sigma),
                &SelfcalOptions::new().with_sigma_opt(inputs.sigma),
            )
            .map_err(|source| ReportError::SelfcalSolve {
                file: name.to_string(),
                source,
            })?;
            let mut d = SelfcalDiagnoseReport::new(&found, selfcal_truth.as_ref(), shown);
            // the budget acts on the final model, as in `polycal diagnose --budget`
            if let Some(b) = self.budget {
                let after = crate::selfcal::evaluate_budget(&found.after, b).map_err(|source| {
                    ReportError::Uncertainty {
                        file: name.to_string(),
                        source,
                    }
                })?;
                d = d.with_uncertainty(&after);
            }
            Some(DiagnosisReport::Selfcal(Box::new(d)))
        } else {
            None
        };
        Ok((
            Evaluation::Selfcal {
                report,
                uncertainty,
            },
            diagnosis,
            Some(rows),
        ))
    }

    /// A polygon measurement file evaluated as `solve --budget` (and `diagnose`) does.
    fn evaluate_polygon(&self) -> Result<Evaluated, ReportError> {
        let (inputs, name) = (self.inputs, self.name);
        let truth = self
            .truth_bytes
            .map(|(bytes, source)| Truth::from_json_bytes(bytes, source))
            .transpose()?;
        let set = MeasurementSet::read_from(self.bytes, name, inputs.faces)?;
        let stated = &inputs.stated_cross_talk;
        let set = if stated.is_empty() {
            set
        } else {
            crate::measurement::cross_talk::correct_cross_talk(&set, stated)?
        };
        let corrections = KnownCorrection::of_stated_cross_talk(&set, stated);
        let solve_error = |source| ReportError::Solve {
            file: name.to_string(),
            source,
        };
        if set.has_shifts() && self.budget.is_some() {
            return Err(ReportError::NotSupported {
                file: name.to_string(),
                what: "an instrument budget",
                kind: "shifted mountings",
            });
        }
        // sub-pitch mountings: α at every table angle of every coset, as `solve` reports
        // them (docs/FORMAT.md §9.1); a budget was refused above
        let sub_pitch = set.has_shifts() && ShiftGeometry::of(&set).is_sub_pitch();
        let (solution, shifted) = if sub_pitch {
            let solved = solve_shifted(&set, &SolveOptions::new().with_sigma_opt(inputs.sigma))
                .map_err(solve_error)?;
            (solved.solution.clone(), Some(solved))
        } else {
            let solution =
                crate::solve::solve(&set, &SolveOptions::new().with_sigma_opt(inputs.sigma))
                    .map_err(solve_error)?;
            (solution, None)
        };
        let uncertainty = self
            .budget
            .map(|b| evaluate_with_corrections(&set, &solution, b, &corrections))
            .transpose()
            .map_err(|source| ReportError::Uncertainty {
                file: name.to_string(),
                source,
            })?;
        let mut solve = match &shifted {
            Some(solved) => SolveReport::sub_pitch(solved, None),
            None => SolveReport::new(&solution, None),
        };
        if let Some(u) = &uncertainty {
            solve = solve.with_uncertainty(u);
        }
        let diagnosis = if inputs.diagnose {
            Some(self.diagnose_polygon(&set, truth.as_ref(), &corrections)?)
        } else {
            None
        };
        let rows = uncertainty
            .as_ref()
            .map(|u| result_rows_with(&solution, Some(u)));
        let design = design_summary(&set);
        Ok((
            Evaluation::Polygon {
                solve,
                design,
                uncertainty,
            },
            diagnosis,
            rows,
        ))
    }

    /// The diagnosis of the polygon measurement `set` (read, cross-talk corrected), as
    /// `polycal diagnose --budget` makes it.
    fn diagnose_polygon(
        &self,
        set: &MeasurementSet,
        truth: Option<&Truth>,
        corrections: &[KnownCorrection],
    ) -> Result<DiagnosisReport, ReportError> {
        let (inputs, name) = (self.inputs, self.name);
        let options = DiagnoseOptions::new()
            .with_sigma_opt(inputs.sigma)
            .with_stated_cross_talk(inputs.stated_cross_talk.iter().map(|s| s.ac).collect());
        let found = diagnose(set, &options).map_err(|source| ReportError::Solve {
            file: name.to_string(),
            source,
        })?;
        let mut report = DiagnoseReport::new(&found, truth, None).with_residuals(&found, set);
        // the budget acts on the final model, as in `polycal diagnose --budget`
        if let Some(b) = self.budget {
            let after =
                evaluate_with_corrections(set, &found.after, b, corrections).map_err(|source| {
                    ReportError::Uncertainty {
                        file: name.to_string(),
                        source,
                    }
                })?;
            report.after = report.after.with_uncertainty(&after);
        }
        Ok(DiagnosisReport::Polygon(Box::new(report)))
    }
}

/// The comparison of the result `rows` (named `shown`) with the reference result at
/// `path`, and the reference's name as the documents show it; the reference is
/// fingerprinted into `files`.
fn compare_with_reference(
    path: &Path,
    rows: Option<Vec<crate::results::ResultRow>>,
    shown: &str,
    files: &mut Vec<InputFile>,
) -> Result<(Comparison, String), ReportError> {
    let (bytes, file, reference_given) = read_input(path, "reference result")?;
    let reference_name = file.path.clone();
    files.push(file);
    let reference = read_results_from(bytes.as_slice(), &reference_given)?;
    let Some(rows) = rows else {
        return Err(ReportError::NoExpandedUncertainty {
            reference: reference_given,
        });
    };
    let options = CompareOptions::new().with_labels(shown.to_string(), reference_name.clone());
    let comparison =
        compare_with_file(&rows, &reference, &options).map_err(|source| ReportError::Compare {
            reference: reference_given.clone(),
            source,
        })?;
    Ok((comparison, reference_name))
}

/// The figures of a report, in its order: the evaluation's (with a budget, the solve
/// figures include the budget's), the diagnosis's, the comparison's, the key
/// comparison's.
fn report_figures(
    evaluation: &Evaluation,
    diagnosis: Option<&DiagnosisReport>,
    comparison: Option<&(Comparison, String)>,
    key_comparisons: &[KeyComparisonSection],
    shown: &str,
) -> Vec<Figure> {
    let mut figures = match evaluation {
        Evaluation::Polygon { solve, .. } => figure::solve_figures(solve),
        Evaluation::Selfcal { report, .. } => figure::selfcal_figures(report),
    };
    if let Some(DiagnosisReport::Polygon(d)) = diagnosis {
        figures.extend(figure::diagnose_figures(d));
    }
    if let Some((c, reference)) = comparison {
        figures.extend(figure::compare_figures_labelled(c, shown, reference));
    }
    for k in key_comparisons {
        let mut these = figure::kc_figures(&k.comparison);
        if key_comparisons.len() > 1 {
            // one name (and HTML id) per figure: each comparison's end in its quantity
            for f in &mut these {
                f.name = format!("{}-{}", f.name, k.comparison.quantity.name());
            }
        }
        figures.extend(these);
    }
    figures
}

impl CalibrationReport {
    /// Reads the inputs and evaluates them as `solve`, `diagnose`, `compare` and
    /// `selfcal` do.
    ///
    /// # Errors
    ///
    /// [`ReportError`]: a file that cannot be read or is invalid (with file, line and
    /// column), a design that cannot be solved, a budget that does not apply, a
    /// comparison that cannot be made.
    pub fn build(inputs: &ReportInputs) -> Result<Self, ReportError> {
        let (bytes, measurement_file, name) = read_input(&inputs.measurement, "measurement")?;
        // the name the documents show: the file name alone
        let shown = measurement_file.path.clone();
        // every name as given and as the documents show it
        let mut read = ReadFiles {
            names: vec![(name.clone(), shown.clone())],
            files: vec![measurement_file],
        };
        let text = String::from_utf8_lossy(&bytes).into_owned();
        let budget = match &inputs.budget {
            Some(path) => Some(read.budget(path)?),
            None => None,
        };
        // the truth of a polygon run (docs/FORMAT.md §4) or of a self-calibration, read by
        // the kind of the measurement file
        let truth_bytes = match &inputs.truth {
            Some(path) => Some(read.truth(path)?),
            None => None,
        };
        let meta_text = match &inputs.meta {
            Some(path) => Some(read.meta(path)?),
            None => None,
        };
        if let Some(dir) = &inputs.run_dir {
            read.run_manifest(dir)?;
        }
        let mut metadata = meta::gather(
            meta_text.as_ref().map(|(t, s)| (t.as_str(), s.as_str())),
            (&text, &name),
            inputs.run_dir.as_deref(),
        )?;
        metadata.name_files(&read.names);
        let measurement = Measurement {
            inputs,
            bytes: &bytes,
            name: &name,
            shown: &shown,
            budget: budget.as_ref(),
            truth_bytes: truth_bytes.as_ref(),
        };
        let (evaluation, diagnosis, rows) = if SelfcalSet::is_selfcal_file(&bytes) {
            measurement.evaluate_selfcal()?
        } else {
            measurement.evaluate_polygon()?
        };
        let mut files = read.files;
        let history = if inputs.history.is_empty() {
            None
        } else {
            if matches!(evaluation, Evaluation::Selfcal { .. }) {
                return Err(ReportError::NotSupported {
                    file: name.clone(),
                    what: "a standard's history",
                    kind: "a self-calibration file (the history follows a polygon's pitch deviations)",
                });
            }
            let measurement = files[0].clone();
            Some(history::build(
                &history::HistoryInputs {
                    dated: &inputs.history,
                    rows: rows.as_deref(),
                    measurement: &measurement,
                    date: metadata.value("date_of_measurement"),
                },
                &mut files,
            )?)
        };
        let comparison = match &inputs.reference {
            Some(path) => Some(compare_with_reference(path, rows, &shown, &mut files)?),
            None => None,
        };
        let key_comparisons = match &inputs.key_comparison {
            Some((path, lab)) => {
                // refusals name the file as given; the documents by its file name and
                // SHA-256 (read_input's `path`), never by its directories
                let (bytes, file, given) = read_input(path, "key comparison")?;
                let sections = kc::parse(&bytes, &given, &file.sha256, lab.as_deref())?;
                files.push(file);
                sections
            }
            None => Vec::new(),
        };
        let figures = report_figures(
            &evaluation,
            diagnosis.as_ref(),
            comparison.as_ref(),
            &key_comparisons,
            &shown,
        );
        let generated_utc = inputs
            .generated_utc
            .clone()
            .unwrap_or_else(|| crate::clock::rfc3339(crate::clock::unix_now()));
        metadata.default_date_of_issue(&generated_utc);
        Ok(Self {
            inputs: files,
            metadata,
            evaluation,
            diagnosis,
            comparison,
            figures,
            generated_utc,
            command_line: inputs.command_line.clone(),
            stated_cross_talk: inputs.stated_cross_talk.clone(),
            key_comparisons,
            history,
        })
    }

    /// The items the results relate to, in words (ISO/IEC 17025 7.8.2.1 o): the polygon
    /// and the encoder of a polygon calibration, the encoder of a self-calibration, each
    /// by its name and serial number where given.
    pub fn items_calibrated(&self) -> String {
        let m = &self.metadata;
        let named = |name: String, serial: Option<&str>| match serial {
            Some(serial) => format!("{name} (serial number {serial})"),
            None => name,
        };
        let encoder = named(
            m.value("encoder")
                .unwrap_or("the rotary table with its encoder")
                .to_string(),
            m.value("encoder_serial"),
        );
        match &self.evaluation {
            Evaluation::Polygon { solve, .. } => format!(
                "{} and {encoder}",
                named(
                    m.value("artefact").map_or_else(
                        || format!("the optical polygon of {} faces", solve.faces),
                        str::to_string
                    ),
                    m.value("artefact_serial")
                )
            ),
            Evaluation::Selfcal { .. } => encoder,
        }
    }

    /// The statement that the results relate only to the items calibrated (ISO/IEC 17025
    /// 7.8.2.1 o), as both documents state it.
    pub fn results_relate_statement(&self) -> String {
        format!(
            "The results relate only to the items calibrated: {}.",
            self.items_calibrated()
        )
    }

    /// The verdicts: a failed comparison, a model not adequate.
    pub fn verdict(&self) -> Verdict {
        Verdict {
            comparison_failed: self
                .comparison
                .as_ref()
                .is_some_and(|(c, _)| !c.verdict_ok()),
            not_adequate: self.diagnosis.as_ref().is_some_and(|d| !d.adequate()),
            history_disagrees: self.history.as_ref().is_some_and(|h| !h.agrees()),
        }
    }

    /// The Digital Calibration Certificate, DCC 3.1.2 XML ([`dcc::document`]).
    ///
    /// # Errors
    ///
    /// [`dcc::DccError`]: what the schema requires and no source gives, named.
    pub fn to_dcc(&self) -> Result<String, dcc::DccError> {
        dcc::document(self)
    }

    /// The HTML document ([`html::document`]).
    pub fn to_html(&self) -> String {
        html::document(self)
    }
}

/// The design of a measurement set.
fn design_summary(set: &MeasurementSet) -> DesignSummary {
    use std::collections::BTreeSet;
    let cycles: BTreeSet<(u32, u32)> = set.readings.iter().map(|r| (r.setup, r.cycle)).collect();
    let setups: BTreeSet<u32> = set.readings.iter().map(|r| r.setup).collect();
    DesignSummary {
        faces: set.faces,
        face_offsets: set.face_offsets(),
        cycles: cycles.len(),
        closing: set.readings.iter().any(|r| r.step == set.faces),
        bidirectional: set
            .readings
            .iter()
            .any(|r| r.direction == crate::measurement::Direction::Ccw),
        setups: setups.len(),
        readings: set.readings.len(),
    }
}
