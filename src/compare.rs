//! En numbers between two results (docs/FORMAT.md §5, `polycal compare`).
//!
//! For every `(quantity, index)` present in both results,
//!
//! ```text
//! En = (a − b) / √(U_a² + U_b² − 2·r·U_a·U_b)
//! ```
//!
//! (ISO 13528; the reference paper's equations (14)–(15) print a minus between the squares,
//! but its numbers use the plus). `r` is an optional correlation coefficient between the
//! two results, for results that share inputs (the same reference standard, the same
//! autocollimator): the covariance term is `r·U_a·U_b`; by default `r = 0`. `|En| ≤ 1`
//! means the results agree within their uncertainties.

use std::collections::HashMap;

use crate::results::Quantity;
use serde::Serialize;

use crate::results::{ResultFile, ResultRow};

/// Options of a comparison: [`CompareOptions::new`] (or `default()`) and the `with_…`
/// methods.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct CompareOptions {
    /// Correlation coefficient `r` between the two results (`−1 ≤ r ≤ 1`, default 0).
    pub correlation: f64,
    /// Name of the first result in messages (default `A`; the path for files).
    pub label_a: String,
    /// Name of the second result in messages (default `B`).
    pub label_b: String,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            correlation: 0.0,
            label_a: "A".to_string(),
            label_b: "B".to_string(),
        }
    }
}

impl CompareOptions {
    /// No correlation, results named `A` and `B`.
    pub fn new() -> Self {
        Self::default()
    }

    /// With a correlation coefficient r between the results (checked by [`compare`]).
    pub fn with_correlation(mut self, correlation: f64) -> Self {
        self.correlation = correlation;
        self
    }

    /// With the names of the two results in messages (e.g. their paths).
    pub fn with_labels(mut self, label_a: impl Into<String>, label_b: impl Into<String>) -> Self {
        self.label_a = label_a.into();
        self.label_b = label_b.into();
        self
    }
}

/// One compared quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComparisonRow {
    /// The quantity (`pitch_deviation`, …).
    pub quantity: Quantity,
    /// Its index.
    pub index: u32,
    /// Value in the first result.
    pub a: f64,
    /// Value in the second result.
    pub b: f64,
    /// `a − b`.
    pub difference: f64,
    /// The En number.
    pub en: f64,
    /// Expanded uncertainty in the first result.
    #[serde(rename = "U_a")]
    pub expanded_u_a: f64,
    /// Expanded uncertainty in the second result.
    #[serde(rename = "U_b")]
    pub expanded_u_b: f64,
}

/// A `(quantity, index)` present in one result only.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Unmatched {
    /// The quantity.
    pub quantity: Quantity,
    /// Its index.
    pub index: u32,
}

/// The comparison of two results. Serializes to the JSON of docs/FORMAT.md §5
/// (`rows`, `max_abs_en`), plus `U_a`, `U_b` in each row, and, when not empty or zero,
/// `only_in_a`, `only_in_b` and `correlation`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Comparison {
    /// One row per `(quantity, index)` in both results, in the order of the first.
    pub rows: Vec<ComparisonRow>,
    /// The largest `|En|`.
    pub max_abs_en: f64,
    /// Rows of the first result missing from the second.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub only_in_a: Vec<Unmatched>,
    /// Rows of the second result missing from the first.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub only_in_b: Vec<Unmatched>,
    /// The correlation coefficient used.
    #[serde(skip_serializing_if = "is_zero")]
    pub correlation: f64,
}

fn is_zero(x: &f64) -> bool {
    *x == 0.0
}

impl Comparison {
    /// Whether every `|En| ≤ 1` (the comparison passes; otherwise `polycal compare`
    /// exits with status 1).
    pub fn verdict_ok(&self) -> bool {
        self.rows.iter().all(|r| r.en.abs() <= 1.0)
    }
}

/// Why two results cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CompareError {
    /// A row has no expanded uncertainty.
    #[error(
        "{location}: {quantity} {index} has no expanded uncertainty U: compare needs U for \
         every row (column U)"
    )]
    MissingU {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// A `(quantity, index)` appears twice in one result.
    #[error("{location}: {quantity} {index} appears twice")]
    Duplicate {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// The denominator of En is zero.
    #[error(
        "{quantity} {index}: En is undefined, U_a² + U_b² − 2·r·U_a·U_b = {denominator} \
         (U_a = {expanded_u_a}, U_b = {expanded_u_b}, r = {r})"
    )]
    Undefined {
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// `U_a² + U_b² − 2·r·U_a·U_b`.
        denominator: f64,
        /// `U_a`.
        expanded_u_a: f64,
        /// `U_b`.
        expanded_u_b: f64,
        /// `r`.
        r: f64,
    },
    /// No quantity is in both results.
    #[error("{a} and {b} have no (quantity, index) in common: nothing to compare")]
    NothingInCommon {
        /// First label.
        a: String,
        /// Second label.
        b: String,
    },
    /// The correlation coefficient is not in [−1, 1].
    #[error("the correlation coefficient must be between -1 and 1, got {0}")]
    Correlation(f64),
}

/// Compares two results quantity by quantity: En for every `(quantity, index)` in both.
/// Every row of both must have `U`.
///
/// # Errors
///
/// [`CompareError`]: a row without `U` or a duplicate `(quantity, index)` (named by
/// label and row number; use [`compare_files`] for file and line), an undefined En,
/// nothing in common, an invalid correlation coefficient.
///
/// # Examples
///
/// The reference paper's largest pitch-deviation difference, 0.28″ with
/// `U = 0.46″` (two-autocollimator method) and `U = 0.15″` (shift-angle method):
///
/// ```
/// use polycal::compare::{compare, CompareOptions};
/// use polycal::results::{Quantity, ResultRow};
///
/// let row = |value, expanded_u| ResultRow {
///     quantity: Quantity::PitchDeviation, index: 7, value,
///     u: None, expanded_u: Some(expanded_u), k: None,
/// };
/// let c = compare(&[row(0.28, 0.46)], &[row(0.0, 0.15)], &CompareOptions::default())?;
/// assert_eq!(format!("{:.2}", c.max_abs_en), "0.58"); // the paper's 0.58
/// assert!(c.verdict_ok());
/// # Ok::<(), polycal::compare::CompareError>(())
/// ```
pub fn compare(
    a: &[ResultRow],
    b: &[ResultRow],
    options: &CompareOptions,
) -> Result<Comparison, CompareError> {
    compare_located(a, b, options, None, None)
}

/// Compares two result files (see [`compare`]); a row without `U` is named by its file
/// and line. The labels of `options` are replaced by the files' names.
///
/// # Errors
///
/// As [`compare`].
pub fn compare_files(
    a: &ResultFile,
    b: &ResultFile,
    options: &CompareOptions,
) -> Result<Comparison, CompareError> {
    let options = CompareOptions {
        label_a: a.source.clone(),
        label_b: b.source.clone(),
        ..options.clone()
    };
    compare_located(&a.rows, &b.rows, &options, Some(&a.lines), Some(&b.lines))
}

fn compare_located(
    a: &[ResultRow],
    b: &[ResultRow],
    options: &CompareOptions,
    lines_a: Option<&[u64]>,
    lines_b: Option<&[u64]>,
) -> Result<Comparison, CompareError> {
    let r = options.correlation;
    if !(r.is_finite() && (-1.0..=1.0).contains(&r)) {
        return Err(CompareError::Correlation(r));
    }
    let check = |rows: &[ResultRow], label: &str, lines: Option<&[u64]>| {
        let location = |i: usize| match lines.and_then(|l| l.get(i)) {
            Some(line) => format!("{label}:{line}"),
            None => format!("{label} (row {})", i + 1),
        };
        let mut seen = HashMap::new();
        for (i, row) in rows.iter().enumerate() {
            if row.expanded_u.is_none() {
                return Err(CompareError::MissingU {
                    location: location(i),
                    quantity: row.quantity,
                    index: row.index,
                });
            }
            if seen.insert((row.quantity, row.index), i).is_some() {
                return Err(CompareError::Duplicate {
                    location: location(i),
                    quantity: row.quantity,
                    index: row.index,
                });
            }
        }
        Ok(())
    };
    check(a, &options.label_a, lines_a)?;
    check(b, &options.label_b, lines_b)?;

    let in_b: HashMap<(Quantity, u32), &ResultRow> = b
        .iter()
        .map(|row| ((row.quantity, row.index), row))
        .collect();
    let in_a: HashMap<(Quantity, u32), &ResultRow> = a
        .iter()
        .map(|row| ((row.quantity, row.index), row))
        .collect();
    let mut rows = Vec::new();
    let mut only_in_a = Vec::new();
    for ra in a {
        let Some(rb) = in_b.get(&(ra.quantity, ra.index)) else {
            only_in_a.push(Unmatched {
                quantity: ra.quantity,
                index: ra.index,
            });
            continue;
        };
        let ua = ra.expanded_u.expect("checked above");
        let ub = rb.expanded_u.expect("checked above");
        let denominator = ua * ua + ub * ub - 2.0 * r * ua * ub;
        if denominator.is_nan() || denominator <= 0.0 {
            return Err(CompareError::Undefined {
                quantity: ra.quantity,
                index: ra.index,
                denominator,
                expanded_u_a: ua,
                expanded_u_b: ub,
                r,
            });
        }
        let difference = ra.value - rb.value;
        rows.push(ComparisonRow {
            quantity: ra.quantity,
            index: ra.index,
            a: ra.value,
            b: rb.value,
            difference,
            en: difference / denominator.sqrt(),
            expanded_u_a: ua,
            expanded_u_b: ub,
        });
    }
    let only_in_b = b
        .iter()
        .filter(|rb| !in_a.contains_key(&(rb.quantity, rb.index)))
        .map(|rb| Unmatched {
            quantity: rb.quantity,
            index: rb.index,
        })
        .collect();
    if rows.is_empty() {
        return Err(CompareError::NothingInCommon {
            a: options.label_a.clone(),
            b: options.label_b.clone(),
        });
    }
    let max_abs_en = rows.iter().map(|r| r.en.abs()).fold(0.0, f64::max);
    Ok(Comparison {
        rows,
        max_abs_en,
        only_in_a,
        only_in_b,
        correlation: r,
    })
}
