//! A standard's history (docs/FORMAT.md §13.2, `polycal history`): the calibrations of one
//! polygon or encoder over the years, the drift model they support, the drift per year,
//! and the value predicted at a date with its uncertainty, the extrapolation included.
//!
//! Each calibration is a result (docs/FORMAT.md §3) with its date. Per position k the
//! constant model x_ik = a_k + e_ik and the linear model x_ik = a_k + b_k·τ_i + e_ik
//! (τ_i the calibration's date in years of 365.25 days) are fitted by generalized least
//! squares over every position at once, each calibration's vector with its covariance:
//! pitch deviations and encoder errors are closed vectors (Σ = 0; an encoder result's
//! mean is taken out first, its zero being a convention), taken as closed with
//! V_i = N/(N − 1)·P·diag(u_i²)·P as `polycal kc` takes them; face deviations are not
//! closed (V_i = diag(u_i²)). With one u per calibration on every face this is the
//! per-face weighted straight line, weights 1/u².
//!
//! **One decision.** The drift vector b is tested as a whole, χ² = bᵀ Cov(b)⁺ b with
//! N − 1 degrees of freedom (closed) or N, at 5 %: the model is `linear` for every
//! position when the test rejects b = 0, else `constant` (its rates measured in
//! docs/verdicts.md). The chosen model's own fit (residual χ²) is tested too and, when it
//! fails, said plainly: the calibrations scatter beyond their stated uncertainties.
//!
//! **The prediction** at a date t: the constant model's GLS mean with its variance, or
//! a + b·τ with Var(a) + 2τ·Cov(a, b) + τ²·Var(b) (the drift's extrapolation), U = 2u.
//! With a largest U, the date at which the prediction's U reaches it (the method of drift
//! of ILAC-G24: a recalibration interval).
//!
//! ```
//! use polycal::history::{Calibration, HistoryOptions, evaluate};
//! use polycal::results::{Quantity, ResultFile, ResultRow};
//!
//! // A 3-face polygon calibrated three times, face 1 drifting +0.1″ a year.
//! let calibration = |date: &str, drift: f64| {
//!     let rows = [drift, -drift / 2.0, -drift / 2.0]
//!         .iter()
//!         .enumerate()
//!         .map(|(k, x)| ResultRow::new(Quantity::PitchDeviation, k as u32 + 1, *x).with_u(0.01))
//!         .collect();
//!     let result = ResultFile { source: date.to_string(), rows, lines: vec![], columns: vec![] };
//!     Calibration::new(date, result)
//! };
//! let history = evaluate(
//!     &[
//!         calibration("2020-01-01", 0.0)?,
//!         calibration("2021-01-01", 0.1)?,
//!         calibration("2022-01-01", 0.2)?,
//!     ],
//!     &HistoryOptions::new("2023-01-01")?,
//! )?;
//! assert_eq!(history.model.name(), "linear");
//! assert!((history.predicted[0] - 0.3).abs() < 0.001);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod dated;
mod error;
mod fit;

use serde::{Deserialize, Serialize};

pub use dated::{DatedPath, DatedReadError, NotDated};
pub use error::HistoryError;

use crate::kc::LabResult;
use crate::kc::input::{self, Aligned};
use crate::results::{Quantity, ResultFile};

/// The coverage factor of every U a history states.
pub const COVERAGE_FACTOR: f64 = 2.0;

/// The days of a year in which drifts are stated (the Julian year).
pub const DAYS_PER_YEAR: f64 = 365.25;

/// The most positions a history fits (its normal matrix is 2N × 2N, dense).
pub const MAX_POSITIONS: usize = 1000;

/// One calibration of the standard: a result and the day it was calibrated.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Calibration {
    /// The day, `YYYY-MM-DD`.
    pub date: String,
    /// Days since 1970-01-01.
    pub days: i64,
    /// The result.
    pub result: ResultFile,
}

impl Calibration {
    /// A calibration of `date` (`YYYY-MM-DD`, a day of the calendar).
    ///
    /// # Errors
    ///
    /// [`HistoryError::Date`] when `date` is not a day `YYYY-MM-DD`.
    pub fn new(date: &str, result: ResultFile) -> Result<Calibration, HistoryError> {
        let days = crate::clock::days_from_date(date).ok_or_else(|| HistoryError::Date {
            text: date.to_string(),
            of: result.source.clone(),
        })?;
        Ok(Calibration {
            date: date.to_string(),
            days,
            result,
        })
    }
}

/// What `evaluate` is asked.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct HistoryOptions {
    /// The quantity: pitch deviations (default), face deviations or encoder errors.
    pub quantity: Quantity,
    /// The day of the prediction, `YYYY-MM-DD`.
    pub at: String,
    /// Days since 1970-01-01 of `at`.
    pub at_days: i64,
    /// The largest expanded uncertainty (k = 2) of the prediction that is acceptable,
    /// arcseconds: the date at which it is reached is stated.
    pub max_expanded_u: Option<f64>,
}

impl HistoryOptions {
    /// Pitch deviations predicted at `at` (`YYYY-MM-DD`).
    ///
    /// # Errors
    ///
    /// [`HistoryError::Date`] when `at` is not a day `YYYY-MM-DD`.
    pub fn new(at: &str) -> Result<HistoryOptions, HistoryError> {
        let at_days = crate::clock::days_from_date(at).ok_or_else(|| HistoryError::Date {
            text: at.to_string(),
            of: "the prediction".to_string(),
        })?;
        Ok(HistoryOptions {
            quantity: Quantity::PitchDeviation,
            at: at.to_string(),
            at_days,
            max_expanded_u: None,
        })
    }

    /// With the quantity (pitch_deviation, face_deviation or encoder_error; `evaluate`
    /// refuses another).
    pub fn with_quantity(mut self, quantity: Quantity) -> Self {
        self.quantity = quantity;
        self
    }

    /// With the largest acceptable expanded uncertainty of the prediction, arcseconds.
    pub fn with_max_expanded_u(mut self, max_expanded_u: f64) -> Self {
        self.max_expanded_u = Some(max_expanded_u);
        self
    }
}

/// The drift model the calibrations support.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[non_exhaustive]
pub enum DriftModel {
    /// No drift found: the value is constant.
    Constant,
    /// A drift found: the value changes linearly with time.
    Linear,
}

impl DriftModel {
    /// `constant` or `linear`.
    pub fn name(self) -> &'static str {
        match self {
            DriftModel::Constant => "constant",
            DriftModel::Linear => "linear",
        }
    }
}

/// A χ² test at 5 %.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct ChiSquareTest {
    /// The statistic.
    pub chi2: f64,
    /// Its degrees of freedom.
    pub dof: usize,
    /// Whether χ² ≤ χ²_0.95(ν).
    pub consistent: bool,
    /// χ²_0.95(ν).
    pub chi2_critical: f64,
}

impl ChiSquareTest {
    fn new(chi2: f64, dof: usize) -> ChiSquareTest {
        let chi2_critical = crate::kc::chi2_quantile_95(dof);
        ChiSquareTest {
            chi2,
            dof,
            consistent: chi2 <= chi2_critical,
            chi2_critical,
        }
    }
}

/// The chosen model's fit to the calibrations.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct FitTest {
    /// The model fitted.
    pub model: DriftModel,
    /// Its residual χ² over every calibration's vector, and its test.
    #[serde(flatten)]
    pub test: ChiSquareTest,
}

/// A standard's history evaluated. Serializes to the JSON of docs/FORMAT.md §13.2.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct History {
    /// The quantity.
    pub quantity: Quantity,
    /// Face 1 … N, or the first calibration's index of each encoder position.
    pub index: Vec<u32>,
    /// The table angle of each encoder position, degrees (encoder errors matched by
    /// angle only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<Vec<f64>>,
    /// The calibrations' files, oldest first.
    pub files: Vec<String>,
    /// Their dates, `YYYY-MM-DD`, oldest first.
    pub dates: Vec<String>,
    /// Every calibration's values, `values[i][k]`, oldest first, arcseconds (encoder
    /// errors with each calibration's mean taken out).
    pub values: Vec<Vec<f64>>,
    /// Their standard uncertainties, arcseconds.
    pub values_u: Vec<Vec<f64>>,
    /// The model the data support: one decision for the standard.
    pub model: DriftModel,
    /// The linear fit's drift per position, arcseconds per year (whatever the model).
    pub drift: Vec<f64>,
    /// Its standard uncertainty, arcseconds per year.
    pub drift_u: Vec<f64>,
    /// The day of the prediction.
    pub at: String,
    /// The value predicted at `at` by the model, arcseconds.
    pub predicted: Vec<f64>,
    /// Its standard uncertainty, arcseconds.
    pub predicted_u: Vec<f64>,
    /// The coverage factor of every U stated (2).
    pub k: f64,
    /// The test of the drift vector b = 0 at 5 %: `consistent` when no drift is found.
    pub vector: ChiSquareTest,
    /// The chosen model's residual test at 5 % (`None` with no degrees of freedom: a
    /// linear model through 2 calibrations).
    pub fit: Option<FitTest>,
    /// The largest acceptable U of the prediction, arcseconds, when asked.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_u: Option<f64>,
    /// Per position, the day after which the prediction's U exceeds `max_u` (`None`:
    /// never, the constant model; or already at every date).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_u_date: Option<Vec<Option<String>>>,
    /// The earliest of `max_u_date` when every position has one: the standard's
    /// recalibration date.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recalibrate_by: Option<String>,
    /// The fitted model per position for drawing: the value at the reference date
    /// `reference_date`, and the variance terms of a + b·τ.
    pub line: ModelLine,
    /// What the reader must know, in words.
    pub notes: Vec<String>,
}

/// The chosen model's line per position, to draw it and its band at any date:
/// value(τ) = value + drift·τ, u²(τ) = var_value + 2τ·cov + τ²·var_drift, τ in years
/// from `reference_date` (drift and its terms 0 for the constant model).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct ModelLine {
    /// The reference date, `YYYY-MM-DD`.
    pub reference_date: String,
    /// The value at the reference date, arcseconds.
    pub value: Vec<f64>,
    /// The drift per year, arcseconds (0 for the constant model).
    pub drift: Vec<f64>,
    /// Var(value), arcsec².
    pub var_value: Vec<f64>,
    /// Cov(value, drift), arcsec²/year.
    pub cov: Vec<f64>,
    /// Var(drift), arcsec²/year².
    pub var_drift: Vec<f64>,
}

impl ModelLine {
    /// The model's value and standard uncertainty at position k, `years` after the
    /// reference date.
    pub fn at(&self, k: usize, years: f64) -> (f64, f64) {
        let value = self.value[k] + self.drift[k] * years;
        let variance =
            self.var_value[k] + 2.0 * years * self.cov[k] + years * years * self.var_drift[k];
        (value, variance.max(0.0).sqrt())
    }
}

/// The calibrations lined up by position (oldest first), as `polycal kc` lines up
/// laboratories; refusals in the history's words.
fn line_up(sorted: &[&Calibration], quantity: Quantity) -> Result<Aligned, HistoryError> {
    let labs: Vec<LabResult> = sorted
        .iter()
        .map(|c| LabResult::from_file(c.result.source.clone(), c.result.clone()))
        .collect();
    let refs: Vec<&LabResult> = labs.iter().collect();
    let aligned = match quantity {
        Quantity::PitchDeviation | Quantity::FaceDeviation => input::faces(&refs, quantity),
        Quantity::EncoderError => input::encoder(&refs),
        other => return Err(HistoryError::Quantity(other)),
    }
    .map_err(HistoryError::from_line_up)?;
    if quantity == Quantity::EncoderError {
        // every position in every calibration: the kc alignment leaves some out
        let counts: Vec<usize> = sorted
            .iter()
            .map(|c| {
                c.result
                    .rows
                    .iter()
                    .filter(|r| r.quantity == quantity)
                    .count()
            })
            .collect();
        if let Some((i, _)) = counts
            .iter()
            .enumerate()
            .find(|(_, n)| **n != aligned.index.len())
        {
            return Err(HistoryError::PositionsDiffer {
                file: sorted[i].result.source.clone(),
                detail: aligned.notes.join("; "),
            });
        }
    }
    Ok(aligned)
}

/// The day after which U(τ) = 2·√(A + 2Bτ + Cτ²) exceeds `max_u`, `None` when it never
/// does (C = 0 and A below) or does at every date.
fn crossing(a: f64, b: f64, c: f64, max_u: f64, reference_days: f64) -> Option<String> {
    let target = (max_u / COVERAGE_FACTOR).powi(2);
    if c <= 0.0 {
        return None;
    }
    let minimum = a - b * b / c;
    if minimum >= target {
        return None;
    }
    let years = (-b + (b * b - c * (a - target)).sqrt()) / c;
    let days = reference_days + years * DAYS_PER_YEAR;
    (days.is_finite() && days.abs() < 3.0e6)
        .then(|| crate::clock::date_of_days(days.floor() as i64))
}

/// Evaluates a standard's history: lines the calibrations up, fits both models, decides
/// by the one test of the drift vector, predicts at `options.at`.
///
/// # Errors
///
/// [`HistoryError`]: fewer than 2 calibrations, one file given twice, all on one day, a
/// quantity that is not pitch_deviation, face_deviation or encoder_error, results that
/// cannot be lined up (a row without u or U and k, other faces or positions: each with
/// its file, line and column), more than [`MAX_POSITIONS`], a fit that cannot be computed.
pub fn evaluate(
    calibrations: &[Calibration],
    options: &HistoryOptions,
) -> Result<History, HistoryError> {
    if calibrations.len() < 2 {
        return Err(HistoryError::TooFewCalibrations(calibrations.len()));
    }
    for (i, a) in calibrations.iter().enumerate() {
        if let Some(b) = calibrations[..i]
            .iter()
            .find(|b| b.result.source == a.result.source)
        {
            return Err(HistoryError::FileTwice {
                file: a.result.source.clone(),
                first: b.date.clone(),
                second: a.date.clone(),
            });
        }
    }
    let mut sorted: Vec<&Calibration> = calibrations.iter().collect();
    sorted.sort_by_key(|c| c.days);
    if sorted.first().map(|c| c.days) == sorted.last().map(|c| c.days) {
        return Err(HistoryError::NoTimeSpan(sorted[0].date.clone()));
    }
    let aligned = line_up(&sorted, options.quantity)?;
    let n = aligned.index.len();
    if n < 2 {
        return Err(HistoryError::TooFewPositions(n));
    }
    if n > MAX_POSITIONS {
        return Err(HistoryError::TooManyPositions(n));
    }
    let closed = options.quantity != Quantity::FaceDeviation;
    let values: Vec<Vec<f64>> = if options.quantity == Quantity::EncoderError {
        aligned
            .values
            .iter()
            .map(|x| crate::kc::closed::closed(x))
            .collect()
    } else {
        aligned.values.clone()
    };
    evaluate_aligned(&sorted, aligned, values, closed, options)
}

/// The fits, the decision and the prediction of lined-up calibrations.
fn evaluate_aligned(
    sorted: &[&Calibration],
    aligned: Aligned,
    values: Vec<Vec<f64>>,
    closed: bool,
    options: &HistoryOptions,
) -> Result<History, HistoryError> {
    let n = aligned.index.len();
    let calibrations = sorted.len();
    let scale = aligned.u.iter().flatten().copied().fold(0.0_f64, f64::max);
    let reference_days = sorted.iter().map(|c| c.days as f64).sum::<f64>() / calibrations as f64;
    let reference_days = reference_days.round();
    let years: Vec<f64> = sorted
        .iter()
        .map(|c| (c.days as f64 - reference_days) / DAYS_PER_YEAR)
        .collect();
    let x: Vec<Vec<f64>> = values
        .iter()
        .map(|x| x.iter().map(|v| v / scale).collect())
        .collect();
    let u: Vec<Vec<f64>> = aligned
        .u
        .iter()
        .map(|u| u.iter().map(|v| v / scale).collect())
        .collect();
    let series = fit::Series {
        x: &x,
        u: &u,
        years: &years,
        closed,
    };
    let not_computable = || HistoryError::NotComputable;
    let constant = fit::fit(&series, 1).ok_or_else(not_computable)?;
    let linear = fit::fit(&series, 2).ok_or_else(not_computable)?;
    let drift_chi2 = linear.drift_chi2(closed).ok_or_else(not_computable)?;
    let vector = ChiSquareTest::new(drift_chi2, if closed { n - 1 } else { n });
    let model = if vector.consistent {
        DriftModel::Constant
    } else {
        DriftModel::Linear
    };
    let chosen = match model {
        DriftModel::Constant => &constant,
        DriftModel::Linear => &linear,
    };
    let fit = (chosen.dof > 0).then(|| FitTest {
        model,
        test: ChiSquareTest::new(chosen.chi2, chosen.dof),
    });
    let at_years = (options.at_days as f64 - reference_days) / DAYS_PER_YEAR;
    let s2 = scale * scale;
    let mut line = ModelLine {
        reference_date: crate::clock::date_of_days(reference_days as i64),
        value: Vec::with_capacity(n),
        drift: Vec::with_capacity(n),
        var_value: Vec::with_capacity(n),
        cov: Vec::with_capacity(n),
        var_drift: Vec::with_capacity(n),
    };
    let (mut predicted, mut predicted_u) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for k in 0..n {
        let (a, ab, b) = chosen.variance_terms(k);
        line.value.push(chosen.value[k] * scale);
        line.drift
            .push(chosen.drift.get(k).copied().unwrap_or(0.0) * scale);
        line.var_value.push(a * s2);
        line.cov.push(ab * s2);
        line.var_drift.push(b * s2);
        let (p, pu) = line.at(k, at_years);
        predicted.push(p);
        predicted_u.push(pu);
    }
    let drift: Vec<f64> = linear.drift.iter().map(|b| b * scale).collect();
    let drift_u: Vec<f64> = (0..n)
        .map(|k| linear.variance_terms(k).2.max(0.0).sqrt() * scale)
        .collect();
    let max_u_date = options.max_expanded_u.map(|max_u| {
        (0..n)
            .map(|k| {
                crossing(
                    line.var_value[k],
                    line.cov[k],
                    line.var_drift[k],
                    max_u,
                    reference_days,
                )
            })
            .collect::<Vec<_>>()
    });
    // the earliest crossing; none when some position never crosses (the constant model,
    // or U above the limit at every date)
    let recalibrate_by = max_u_date.as_ref().and_then(|dates| {
        dates
            .iter()
            .map(Option::as_ref)
            .collect::<Option<Vec<&String>>>()
            .and_then(|all| all.into_iter().min().cloned())
    });
    let mut history = History {
        quantity: options.quantity,
        index: aligned.index,
        angle_deg: aligned.angle_deg,
        files: sorted.iter().map(|c| c.result.source.clone()).collect(),
        dates: sorted.iter().map(|c| c.date.clone()).collect(),
        values,
        values_u: aligned.u,
        model,
        drift,
        drift_u,
        at: options.at.clone(),
        predicted,
        predicted_u,
        k: COVERAGE_FACTOR,
        vector,
        fit,
        max_u: options.max_expanded_u,
        max_u_date,
        recalibrate_by,
        line,
        notes: aligned.notes,
    };
    history.notes.extend(notes::notes(&history, sorted));
    Ok(history)
}

mod notes;
