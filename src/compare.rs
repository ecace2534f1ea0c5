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
//!
//! Encoder errors are matched by their table angle (`angle_deg`, within
//! [`ANGLE_TOLERANCE_DEG`] around the circle) when every encoder error of both results
//! carries one, so that results with different numbers of positions (a 24-position
//! two-autocollimator calibration against a 168-position self-calibration) are compared
//! at the angles they share; otherwise by index. Setup errors depend on the mounting: they
//! are listed, but left out of the verdict and of the largest |En| unless
//! [`CompareOptions::with_include_setup`] asks for them.

use std::collections::HashMap;

use crate::results::{ANGLE_TOLERANCE_DEG, AngleCheck, Quantity, angle_distance_deg};
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
    /// Whether setup errors count in the verdict and in the largest |En| (default
    /// `false`: they depend on the mounting, so they are listed but not judged).
    pub include_setup: bool,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            correlation: 0.0,
            label_a: "A".to_string(),
            label_b: "B".to_string(),
            include_setup: false,
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

    /// With setup errors counted in the verdict and in the largest |En| (`true`), or only
    /// listed (`false`, the default).
    pub fn with_include_setup(mut self, include_setup: bool) -> Self {
        self.include_setup = include_setup;
        self
    }
}

/// How the encoder errors of two results were matched (JSON `encoder_matched_by`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EncoderMatching {
    /// By table angle (`angle_deg` within [`ANGLE_TOLERANCE_DEG`]): every encoder error
    /// of both results carries one.
    Angle,
    /// By index: at least one of the results has encoder errors without an angle (or has
    /// none at all).
    Index,
}

/// One compared quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct ComparisonRow {
    /// The quantity (`pitch_deviation`, …).
    pub quantity: Quantity,
    /// Its index (in the first result, when matched by angle).
    pub index: u32,
    /// The index in the second result of an encoder error matched by angle (JSON
    /// `index_b`, present only then).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub index_b: Option<u32>,
    /// The table angle of an encoder error matched by angle, degrees: the first result's
    /// (the second's is within [`ANGLE_TOLERANCE_DEG`] of it); present only then.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
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
    /// Whether the row counts in the verdict and in the largest |En|: every row but the
    /// setup errors, and those too with [`CompareOptions::with_include_setup`].
    pub in_verdict: bool,
}

/// A row present in one result only: a `(quantity, index)`, or an encoder error whose
/// angle the other result does not have when matched by angle.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Unmatched {
    /// The quantity.
    pub quantity: Quantity,
    /// Its index.
    pub index: u32,
    /// The table angle of an encoder error when matched by angle, degrees (present only
    /// then).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angle_deg: Option<f64>,
}

/// The comparison of two results. Serializes to the JSON of docs/FORMAT.md §5
/// (`rows`, `max_abs_en`), plus `U_a`, `U_b`, `in_verdict` (and, for encoder errors
/// matched by angle, `index_b` and `angle_deg`) in each row, `encoder_matched_by`, and,
/// when not empty or zero, `only_in_a`, `only_in_b` and `correlation`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Comparison {
    /// One row per quantity in both results, in the order of the first: by
    /// `(quantity, index)`, encoder errors by angle when both carry angles.
    pub rows: Vec<ComparisonRow>,
    /// The largest `|En|` of the rows in the verdict ([`ComparisonRow::in_verdict`]).
    pub max_abs_en: f64,
    /// How the encoder errors were matched.
    pub encoder_matched_by: EncoderMatching,
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
    /// Whether every `|En| ≤ 1` among the rows in the verdict (the comparison passes;
    /// otherwise `polycal compare` exits with status 1). Setup errors left out of the
    /// verdict do not count, whatever their En.
    pub fn verdict_ok(&self) -> bool {
        self.rows
            .iter()
            .filter(|r| r.in_verdict)
            .all(|r| r.en.abs() <= 1.0)
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
    #[error(
        "the correlation coefficient must be between -1 and 1, got {}",
        crate::input::limits::show(*.0)
    )]
    Correlation(f64),
    /// The rows in common are setup errors only, and they are left out of the verdict:
    /// there is nothing to judge.
    #[error(
        "{a} and {b} have only setup errors in common, and setup errors are left out of the \
         verdict (they depend on the mounting): nothing to judge"
    )]
    OnlySetupInCommon {
        /// First label.
        a: String,
        /// Second label.
        b: String,
    },
    /// A row breaks the angle rules of a result (docs/FORMAT.md §3.2): an angle outside
    /// 0 ≤ angle < 360 or on a row that is not an encoder error, encoder errors with and
    /// without angles in one result, two at one position. (Only rows given as slices can;
    /// a result file that does is refused when read.)
    #[error("{location}: {reason}")]
    Angle {
        /// The label and row number.
        location: String,
        /// What is wrong.
        reason: String,
    },
    /// An encoder error is within the matching tolerance of two encoder errors of the
    /// other result, so matching by angle would have to guess.
    #[error(
        "{label}: encoder_error {index} at {angle_deg}° is within {tolerance:e}° of two encoder \
         errors of {other}, {first} and {second}: matching by angle would be a guess",
        tolerance = ANGLE_TOLERANCE_DEG
    )]
    AmbiguousAngle {
        /// The result of the encoder error.
        label: String,
        /// Its index.
        index: u32,
        /// Its angle, degrees.
        angle_deg: f64,
        /// The other result.
        other: String,
        /// The smaller index of two encoder errors of the other result near it.
        first: u32,
        /// The larger.
        second: u32,
    },
}

/// Compares two results quantity by quantity: En for every `(quantity, index)` in both,
/// encoder errors by table angle when every encoder error of both carries one
/// ([`EncoderMatching`]). Every row of both must have `U`. Setup errors are compared but
/// left out of the verdict and of the largest |En| unless
/// [`CompareOptions::with_include_setup`].
///
/// # Errors
///
/// [`CompareError`]: a row without `U`, a duplicate `(quantity, index)` or a row that
/// breaks the angle rules (named by label and row number; use [`compare_files`] for file
/// and line), an encoder error within the tolerance of two of the other result, an
/// undefined En, nothing in common (or only setup errors, left out of the verdict), an
/// invalid correlation coefficient.
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
/// let row = |value, expanded_u| {
///     ResultRow::new(Quantity::PitchDeviation, 7, value).with_expanded_u(expanded_u)
/// };
/// let c = compare(&[row(0.28, 0.46)], &[row(0.0, 0.15)], &CompareOptions::default())?;
/// assert_eq!(format!("{:.2}", c.max_abs_en), "0.58"); // the paper's 0.58
/// assert!(c.verdict_ok());
/// # Ok::<(), polycal::compare::CompareError>(())
/// ```
///
/// Encoder errors at 15° — position 1 of 24 and position 7 of 168 — are compared:
///
/// ```
/// use polycal::compare::{compare, CompareOptions, EncoderMatching};
/// use polycal::results::{Quantity, ResultRow};
///
/// let at = |index, positions: u32, value| {
///     ResultRow::new(Quantity::EncoderError, index, value)
///         .with_expanded_u(0.1)
///         .with_angle_deg(f64::from(index) * 360.0 / f64::from(positions))
/// };
/// let c = compare(&[at(1, 24, 0.3)], &[at(6, 168, 0.0), at(7, 168, 0.2)], &CompareOptions::default())?;
/// assert_eq!(c.encoder_matched_by, EncoderMatching::Angle);
/// assert_eq!((c.rows[0].index, c.rows[0].index_b, c.rows[0].angle_deg), (1, Some(7), Some(15.0)));
/// assert_eq!(c.only_in_b[0].index, 6);
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

/// The rows of the other result matched to one row: by `(quantity, index)`, or the
/// encoder errors by angle.
struct Matcher<'r> {
    by_key: HashMap<(Quantity, u32), &'r ResultRow>,
    /// The encoder errors sorted by angle (when matching by angle).
    by_angle: Vec<(f64, &'r ResultRow)>,
    by: EncoderMatching,
}

impl<'r> Matcher<'r> {
    fn new(rows: &'r [ResultRow], by: EncoderMatching) -> Matcher<'r> {
        let by_angle_here = |row: &ResultRow| {
            by == EncoderMatching::Angle && row.quantity == Quantity::EncoderError
        };
        let by_key = rows
            .iter()
            .filter(|row| !by_angle_here(row))
            .map(|row| ((row.quantity, row.index), row))
            .collect();
        let mut by_angle: Vec<(f64, &ResultRow)> = rows
            .iter()
            .filter(|row| by_angle_here(row))
            .filter_map(|row| row.angle_deg.map(|angle| (angle, row)))
            .collect();
        by_angle.sort_by(|x, y| x.0.total_cmp(&y.0));
        Matcher {
            by_key,
            by_angle,
            by,
        }
    }

    /// Whether `row` (of the other result) is matched by angle.
    fn by_angle(&self, row: &ResultRow) -> bool {
        self.by == EncoderMatching::Angle && row.quantity == Quantity::EncoderError
    }

    /// The rows matching `row` of the other result: at most one by key; by angle, every
    /// encoder error within the tolerance around the circle, nearest first.
    fn matches(&self, row: &ResultRow) -> Vec<&'r ResultRow> {
        if !self.by_angle(row) {
            return self
                .by_key
                .get(&(row.quantity, row.index))
                .copied()
                .into_iter()
                .collect();
        }
        let Some(angle) = row.angle_deg else {
            return Vec::new();
        };
        let tolerance = ANGLE_TOLERANCE_DEG;
        let mut windows = vec![(angle - tolerance, angle + tolerance)];
        if angle - tolerance < 0.0 {
            windows.push((angle - tolerance + 360.0, f64::INFINITY));
        }
        if angle + tolerance >= 360.0 {
            windows.push((f64::NEG_INFINITY, angle + tolerance - 360.0));
        }
        let mut found: Vec<(f64, &ResultRow)> = Vec::new();
        for (low, high) in windows {
            // Widened by a hair, then judged by the distance itself.
            let (low, high) = (low - tolerance, high + tolerance);
            let from = self.by_angle.partition_point(|(a, _)| *a < low);
            for &(a, other) in self.by_angle[from..].iter().take_while(|(a, _)| *a <= high) {
                let distance = angle_distance_deg(a, angle);
                if distance <= tolerance && !found.iter().any(|(_, r)| std::ptr::eq(*r, other)) {
                    found.push((distance, other));
                }
            }
        }
        found.sort_by(|x, y| x.0.total_cmp(&y.0));
        found.into_iter().map(|(_, r)| r).collect()
    }
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
        let place = |i: usize| match lines.and_then(|l| l.get(i)) {
            Some(line) => format!("line {line}"),
            None => format!("row {}", i + 1),
        };
        let mut seen = HashMap::new();
        let mut angles = AngleCheck::default();
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
            if let Err(problem) = angles.admit(i, row) {
                let at = match problem {
                    crate::results::AngleProblem::Missing { without, .. } => without,
                    _ => i,
                };
                return Err(CompareError::Angle {
                    location: location(at),
                    reason: problem.message(row, &rows[..i], place),
                });
            }
        }
        Ok(())
    };
    check(a, &options.label_a, lines_a)?;
    check(b, &options.label_b, lines_b)?;

    // By angle when both results have encoder errors and every one carries its angle
    // (the check above: in one result, all or none do).
    let angles_in = |rows: &[ResultRow]| {
        let mut encoder = rows
            .iter()
            .filter(|row| row.quantity == Quantity::EncoderError)
            .peekable();
        encoder.peek().is_some() && encoder.all(|row| row.angle_deg.is_some())
    };
    let by = if angles_in(a) && angles_in(b) {
        EncoderMatching::Angle
    } else {
        EncoderMatching::Index
    };
    let in_b = Matcher::new(b, by);
    let in_a = Matcher::new(a, by);
    let ambiguous = |row: &ResultRow, label: &str, other: &str, found: &[&ResultRow]| {
        CompareError::AmbiguousAngle {
            label: label.to_string(),
            index: row.index,
            angle_deg: row.angle_deg.unwrap_or(f64::NAN),
            other: other.to_string(),
            first: found[0].index.min(found[1].index),
            second: found[0].index.max(found[1].index),
        }
    };
    // Each encoder error of B is matched by one of A at most.
    for rb in b.iter().filter(|rb| in_a.by_angle(rb)) {
        let found = in_a.matches(rb);
        if found.len() > 1 {
            return Err(ambiguous(rb, &options.label_b, &options.label_a, &found));
        }
    }

    let mut rows = Vec::new();
    let mut only_in_a = Vec::new();
    for ra in a {
        let by_angle = in_b.by_angle(ra);
        let found = in_b.matches(ra);
        let rb = match found.as_slice() {
            [] => {
                only_in_a.push(Unmatched {
                    quantity: ra.quantity,
                    index: ra.index,
                    angle_deg: if by_angle { ra.angle_deg } else { None },
                });
                continue;
            }
            [rb] => *rb,
            _ => {
                return Err(ambiguous(ra, &options.label_a, &options.label_b, &found));
            }
        };
        // Every row has U (checked above).
        let (Some(ua), Some(ub)) = (ra.expanded_u, rb.expanded_u) else {
            continue;
        };
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
            index_b: by_angle.then_some(rb.index),
            angle_deg: if by_angle { ra.angle_deg } else { None },
            a: ra.value,
            b: rb.value,
            difference,
            en: difference / denominator.sqrt(),
            expanded_u_a: ua,
            expanded_u_b: ub,
            in_verdict: options.include_setup || ra.quantity != Quantity::SetupError,
        });
    }
    let only_in_b = b
        .iter()
        .filter(|rb| in_a.matches(rb).is_empty())
        .map(|rb| Unmatched {
            quantity: rb.quantity,
            index: rb.index,
            angle_deg: if in_a.by_angle(rb) {
                rb.angle_deg
            } else {
                None
            },
        })
        .collect();
    if rows.is_empty() {
        return Err(CompareError::NothingInCommon {
            a: options.label_a.clone(),
            b: options.label_b.clone(),
        });
    }
    if !rows.iter().any(|row| row.in_verdict) {
        return Err(CompareError::OnlySetupInCommon {
            a: options.label_a.clone(),
            b: options.label_b.clone(),
        });
    }
    let max_abs_en = rows
        .iter()
        .filter(|row| row.in_verdict)
        .map(|row| row.en.abs())
        .fold(0.0, f64::max);
    Ok(Comparison {
        rows,
        max_abs_en,
        encoder_matched_by: by,
        only_in_a,
        only_in_b,
        correlation: r,
    })
}
