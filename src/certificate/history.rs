//! The history of the standard in a report (`polycal report --history`, docs/FORMAT.md
//! §10.2, §13.2): the run's own calibration as the newest of the standard's calibrations,
//! dated by the metadata's `date_of_measurement`; the history of them all (its drift
//! decision, its fit, the drift per face); the value the *earlier* calibrations predict
//! for that day, with its U; and the one decision whether today's value agrees with it.
//!
//! **The decision** is `compare`'s vector test (docs/FORMAT.md §5.4), today's pitch
//! deviations against the prediction taken as a closed result with u = the prediction's
//! u, as `compare` takes a result file: χ² = Σ w_k·(d_k − d̄_w)², w_k = 1/(c·u_today,k² +
//! c·u_pred,k²), c = N/(N − 1), ν = N − 1, at 5 %. With one u per calibration on every face
//! (the usual case) the prediction's covariance is exactly c·u²·P, so the test is the
//! exact test of the closed difference; otherwise it takes the prediction's correlations
//! as those of a closed result, as `compare` takes any result file's. En per face is
//! information.

use std::collections::HashMap;

use super::{InputFile, ReportError, read_input};
use crate::compare::{CompareOptions, Comparison, compare_with_file};
use crate::history::{COVERAGE_FACTOR, Calibration, DatedPath, History, HistoryOptions, evaluate};
use crate::results::{Quantity, ResultFile, ResultRow};

/// One calibration of the standard as the report lists it.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct HistoryCalibration {
    /// The day, `YYYY-MM-DD`.
    pub date: String,
    /// The file's name without its directories.
    pub file: String,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
    /// Whether it is this report's own calibration (the newest).
    pub this_report: bool,
}

/// The history of the standard as a report shows it.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct HistorySection {
    /// Every calibration, oldest first, this report's last.
    pub calibrations: Vec<HistoryCalibration>,
    /// This calibration's day (the metadata's `date_of_measurement`).
    pub date: String,
    /// The history of every calibration, this one the newest, evaluated at `date`: the
    /// drift decision, the fit, the drift per face (`polycal history` of the same files).
    pub history: History,
    /// The history of the earlier calibrations alone, predicted at `date`.
    pub earlier: History,
    /// This calibration's pitch deviations (a) against the earlier calibrations'
    /// prediction (b): En per face and the one vector test.
    pub agreement: Comparison,
}

impl HistorySection {
    /// Whether this calibration agrees with the earlier calibrations' prediction: the
    /// vector test at 5 %.
    pub fn agrees(&self) -> bool {
        self.agreement.verdict_ok()
    }

    /// The decision in words; no final stop.
    pub fn agreement_statement(&self) -> String {
        format!(
            "This calibration {} the value its {} earlier calibrations predict for {}: {}",
            if self.agrees() {
                "agrees with"
            } else {
                "does NOT agree with"
            },
            self.earlier.dates.len(),
            self.date,
            self.agreement.verdict_sentence()
        )
    }
}

/// This calibration's pitch deviations (`today`, with U or u) against the value the
/// `earlier` calibrations predict for `date` (`polycal history` of them at that day): the
/// earlier history, and `compare`'s comparison of today (a) with the prediction (b),
/// whose vector test at 5 % is the report's one decision (docs/FORMAT.md §10.2 item 10;
/// its false-alarm rate and power are measured in `tests/maths/history.rs`).
///
/// # Errors
///
/// [`ReportError::History`] when the earlier calibrations cannot be evaluated (fewer
/// than two, positions that differ, a bad date), [`ReportError::Compare`] when today's
/// rows cannot be compared with the prediction (another set of faces, no U).
pub fn agreement_with_prediction(
    earlier: &[Calibration],
    today: &ResultFile,
    date: &str,
) -> Result<(History, Comparison), ReportError> {
    let prior = evaluate(earlier, &HistoryOptions::new(date)?)?;
    let prediction = ResultFile {
        source: "the prediction".to_string(),
        rows: prior
            .index
            .iter()
            .zip(prior.predicted.iter().zip(&prior.predicted_u))
            .map(|(index, (value, u))| {
                ResultRow::new(Quantity::PitchDeviation, *index, *value)
                    .with_u(*u)
                    .with_expanded_u(COVERAGE_FACTOR * u)
                    .with_k(COVERAGE_FACTOR)
            })
            .collect(),
        lines: Vec::new(),
        columns: Vec::new(),
    };
    let options =
        CompareOptions::new().with_labels(today.source.clone(), "the prediction".to_string());
    let agreement = compare_with_file(&today.rows, &prediction, &options).map_err(|source| {
        ReportError::Compare {
            reference: "the earlier calibrations' prediction".to_string(),
            source,
        }
    })?;
    Ok((prior, agreement))
}

/// What the section is built from: the earlier calibrations as given, this calibration's
/// result rows (`None`: no U, no budget), its name and fingerprint, and its day.
pub(super) struct HistoryInputs<'a> {
    pub dated: &'a [DatedPath],
    pub rows: Option<&'a [ResultRow]>,
    pub measurement: &'a InputFile,
    pub date: Option<&'a str>,
}

/// Reads the earlier calibrations (fingerprinted into `files`) and evaluates the section.
pub(super) fn build(
    inputs: &HistoryInputs,
    files: &mut Vec<InputFile>,
) -> Result<HistorySection, ReportError> {
    let shown = inputs.measurement.path.clone();
    let Some(date) = inputs.date else {
        return Err(ReportError::HistoryNoDate { file: shown });
    };
    let today_days = crate::clock::days_from_date(date).ok_or_else(|| ReportError::History {
        source: crate::history::HistoryError::Date {
            text: date.to_string(),
            of: "the metadata's date_of_measurement".to_string(),
        },
    })?;
    let Some(rows) = inputs.rows else {
        return Err(ReportError::HistoryNoExpandedUncertainty { file: shown });
    };
    // name as given → (name shown, SHA-256)
    let mut shown_as: HashMap<String, (String, String)> = HashMap::new();
    let mut earlier = Vec::with_capacity(inputs.dated.len());
    for dated in inputs.dated {
        let (bytes, file, given) = read_input(&dated.path, "history calibration")?;
        let calibration = dated
            .calibration(&bytes, &given)
            .map_err(|source| ReportError::HistoryFile { source })?;
        if calibration.days >= today_days {
            return Err(ReportError::HistoryNotEarlier {
                file: given,
                date: calibration.date,
                today: date.to_string(),
            });
        }
        shown_as.insert(given, (file.path.clone(), file.sha256.clone()));
        files.push(file);
        earlier.push(calibration);
    }
    let pitch: Vec<ResultRow> = rows
        .iter()
        .filter(|r| r.quantity == Quantity::PitchDeviation)
        .cloned()
        .collect();
    let today = ResultFile {
        source: shown.clone(),
        rows: pitch,
        lines: Vec::new(),
        columns: Vec::new(),
    };
    shown_as.insert(
        shown.clone(),
        (shown.clone(), inputs.measurement.sha256.clone()),
    );
    let (prior, agreement) = agreement_with_prediction(&earlier, &today, date)?;
    let mut all = earlier;
    all.push(Calibration::new(date, today)?);
    let history = evaluate(&all, &HistoryOptions::new(date)?)?;
    let calibrations = history
        .files
        .iter()
        .zip(&history.dates)
        .map(|(source, date)| {
            let (file, sha256) = shown_as.get(source).cloned().unwrap_or_default();
            HistoryCalibration {
                date: date.clone(),
                this_report: *source == shown,
                file,
                sha256,
            }
        })
        .collect();
    Ok(HistorySection {
        calibrations,
        date: date.to_string(),
        history,
        earlier: prior,
        agreement,
    })
}
