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
//! autocollimator): the covariance term is `r·U_a·U_b`; by default `r = 0`.
//!
//! **The verdict** is one test of the whole comparison at 5 % ([`vector`]): the differences
//! of the closed quantities (pitch deviations, encoder errors) tested as one vector, χ² with
//! the closed covariance of both results, ν = n − 1 per family. It needs each row's
//! standard uncertainty: its `u`, or `U/k`. Rows with |En| > 1 are counted beside the number
//! expected by chance ([`Comparison::en_expected`]): with 24 rows some |En| > 1 in about two
//! consistent comparisons of three, so the per-row rule ([`VerdictRule::En`]) is kept only
//! for schemes that prescribe it.
//!
//! Encoder errors are matched by their table angle (`angle_deg`, within
//! [`ANGLE_TOLERANCE_DEG`](crate::results::ANGLE_TOLERANCE_DEG) around the circle) when every encoder error of both results
//! carries one, so that results with different numbers of positions (a 24-position
//! two-autocollimator calibration against a 168-position self-calibration) are compared
//! at the angles they share; otherwise by index. Setup errors depend on the mounting: they
//! are listed, but left out of the verdict and of the largest |En| unless
//! [`CompareOptions::with_include_setup`] asks for them.

mod error;
mod matching;
pub mod vector;

use std::collections::HashMap;

use crate::results::{AngleCheck, Quantity};
use serde::Serialize;

use crate::results::{ResultFile, ResultRow};
pub use error::CompareError;
use matching::Matcher;
use vector::{FamilySizes, Pair};
pub use vector::{FamilyTest, UnknownVerdictRule, VectorTest, VerdictRule};

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
    /// Which rule gives the verdict (default [`VerdictRule::Vector`]).
    pub verdict: VerdictRule,
}

impl Default for CompareOptions {
    fn default() -> Self {
        CompareOptions {
            correlation: 0.0,
            label_a: "A".to_string(),
            label_b: "B".to_string(),
            include_setup: false,
            verdict: VerdictRule::Vector,
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

    /// With the rule that gives the verdict: the vector's test (the default) or the
    /// per-row rule [`VerdictRule::En`].
    pub fn with_verdict(mut self, verdict: VerdictRule) -> Self {
        self.verdict = verdict;
        self
    }
}

/// How the encoder errors of two results were matched (JSON `encoder_matched_by`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum EncoderMatching {
    /// By table angle (`angle_deg` within [`ANGLE_TOLERANCE_DEG`](crate::results::ANGLE_TOLERANCE_DEG)): every encoder error
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
    /// (the second's is within [`ANGLE_TOLERANCE_DEG`](crate::results::ANGLE_TOLERANCE_DEG) of it); present only then.
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
    /// Standard uncertainty in the first result, arcseconds: its `u`, or `U/k` (absent
    /// when the row has neither `u` nor `k`, which only the per-row rule accepts).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub u_a: Option<f64>,
    /// Standard uncertainty in the second result, arcseconds (as [`ComparisonRow::u_a`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub u_b: Option<f64>,
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

/// The comparison of two results. Serializes to the JSON of docs/FORMAT.md §5.4
/// (`rows`, `max_abs_en`, `verdict`, `vector`, `en_exceeding`, `en_expected`), plus
/// `U_a`, `U_b`, `u_a`, `u_b`, `in_verdict` (and, for encoder errors matched by angle,
/// `index_b` and `angle_deg`) in each row, `encoder_matched_by`, and, when not empty or
/// zero, `vector_not_formed`, `only_in_a`, `only_in_b` and `correlation`.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct Comparison {
    /// One row per quantity in both results, in the order of the first: by
    /// `(quantity, index)`, encoder errors by angle when both carry angles.
    pub rows: Vec<ComparisonRow>,
    /// The largest `|En|` of the rows in the verdict ([`ComparisonRow::in_verdict`]).
    pub max_abs_en: f64,
    /// The rule that gives the verdict ([`Comparison::verdict_ok`]).
    pub verdict: VerdictRule,
    /// The test of the whole comparison as one vector; always there with
    /// [`VerdictRule::Vector`], `None` (JSON `null`) with [`VerdictRule::En`] when it could
    /// not be formed ([`Comparison::vector_not_formed`] says why).
    pub vector: Option<VectorTest>,
    /// How many rows in the verdict have |En| > 1.
    pub en_exceeding: usize,
    /// How many rows in the verdict are expected to have |En| > 1 by chance when the results
    /// are consistent: Σ P(|En| > 1) over those rows, each 2·(1 − Φ(1/s)),
    /// s = √(u_a² + u_b² − 2·r·u_a·u_b) / √(U_a² + U_b² − 2·r·U_a·U_b) (4.55 % for k = 2).
    /// `None` (JSON `null`) when some row has no standard uncertainty (per-row rule only).
    pub en_expected: Option<f64>,
    /// Why there is no vector test (with [`VerdictRule::En`] only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vector_not_formed: Option<String>,
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

/// Compares two results quantity by quantity: En for every `(quantity, index)` in both,
/// encoder errors by table angle when every encoder error of both carries one
/// ([`EncoderMatching`]), and gives one verdict for the whole comparison
/// ([`Comparison::verdict_ok`], [`Comparison::verdict_sentence`]): by default the vector's
/// test of the closed families ([`vector`]), with [`VerdictRule::En`] the per-row rule.
/// Every row of both must have `U`; with the vector's test every row in the verdict must
/// have its standard uncertainty too (`u`, or `k` for u = U/k). Setup errors are compared
/// but left out of the verdict and of the largest |En| unless
/// [`CompareOptions::with_include_setup`].
///
/// # Errors
///
/// [`CompareError`]: a row without `U` (or, for the vector's test, without `u` and `k`), a
/// duplicate `(quantity, index)` or a row that breaks the angle rules (named by label and
/// row number; use [`compare_files`] for file and line), an encoder error within the
/// tolerance of two of the other result, an undefined En, nothing in common (or only setup
/// errors, left out of the verdict), an invalid correlation coefficient; for the vector's
/// test, nothing to test as a vector, a difference without variance, or a χ² beyond the
/// range of numbers.
///
/// # Examples
///
/// Four faces, one result 0 everywhere (u = 0.1″), the other closed with u = 0.1″ on faces 1
/// and 2 and 0.2″ on faces 3 and 4, k = 2. The closed covariances give the weights
/// w = (3/4)·(50, 50, 20, 20) and χ² = Σ w·d² − (Σ w·d)²/Σ w = 27/4 − 27/140 = 459/70 with
/// ν = 3, below χ²_0.95(3) = 7.81:
///
/// ```
/// use polycal::compare::{compare, CompareOptions};
/// use polycal::results::{Quantity, ResultRow};
///
/// let row = |face, value, u: f64| {
///     ResultRow::new(Quantity::PitchDeviation, face, value)
///         .with_u(u)
///         .with_k(2.0)
///         .with_expanded_u(2.0 * u)
/// };
/// let a = [row(1, 0.3, 0.1), row(2, -0.1, 0.1), row(3, -0.4, 0.2), row(4, 0.2, 0.2)];
/// let b = [row(1, 0.0, 0.1), row(2, 0.0, 0.1), row(3, 0.0, 0.1), row(4, 0.0, 0.1)];
/// let c = compare(&a, &b, &CompareOptions::default())?;
/// let vector = c.vector.as_ref().expect("the vector's test");
/// assert!((vector.chi2 - 459.0 / 70.0).abs() < 1e-12);
/// assert_eq!(vector.dof, 3);
/// assert!(c.verdict_ok());
/// assert_eq!(c.en_exceeding, 1); // face 1: En = 0.3/√0.08 = 1.06
/// assert!(c.verdict_sentence().starts_with("consistent: χ² = 6.56 ≤ χ²_0.95(3) = 7.81"));
/// # Ok::<(), polycal::compare::CompareError>(())
/// ```
///
/// The reference paper's largest pitch-deviation difference, 0.28″ with `U = 0.46″`
/// (two-autocollimator method) and `U = 0.15″` (shift-angle method), judged alone by the
/// per-row rule (one row is no vector, and U alone gives no u):
///
/// ```
/// use polycal::compare::{compare, CompareOptions, VerdictRule};
/// use polycal::results::{Quantity, ResultRow};
///
/// let row = |value, expanded_u| {
///     ResultRow::new(Quantity::PitchDeviation, 7, value).with_expanded_u(expanded_u)
/// };
/// let options = CompareOptions::default().with_verdict(VerdictRule::En);
/// let c = compare(&[row(0.28, 0.46)], &[row(0.0, 0.15)], &options)?;
/// assert_eq!(format!("{:.2}", c.max_abs_en), "0.58"); // the paper's 0.58
/// assert!(c.verdict_ok());
/// assert!(c.vector.is_none());
/// # Ok::<(), polycal::compare::CompareError>(())
/// ```
///
/// Encoder errors at 15° — position 1 of 24 and position 7 of 168 — are compared:
///
/// ```
/// use polycal::compare::{compare, CompareOptions, EncoderMatching, VerdictRule};
/// use polycal::results::{Quantity, ResultRow};
///
/// let at = |index, positions: u32, value| {
///     ResultRow::new(Quantity::EncoderError, index, value)
///         .with_expanded_u(0.1)
///         .with_angle_deg(f64::from(index) * 360.0 / f64::from(positions))
/// };
/// let options = CompareOptions::default().with_verdict(VerdictRule::En);
/// let c = compare(&[at(1, 24, 0.3)], &[at(6, 168, 0.0), at(7, 168, 0.2)], &options)?;
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

/// Compares rows in memory with a result file (see [`compare`]): a row of the file is named
/// by its line (the report's reference).
pub(crate) fn compare_with_file(
    a: &[ResultRow],
    b: &ResultFile,
    options: &CompareOptions,
) -> Result<Comparison, CompareError> {
    compare_located(a, &b.rows, options, None, Some(&b.lines))
}

/// `file:line` of row `i`, or the label and row number for rows given in memory.
fn location(label: &str, lines: Option<&[u64]>, i: usize) -> String {
    match lines.and_then(|l| l.get(i)) {
        Some(line) => format!("{label}:{line}"),
        None => format!("{label} (row {})", i + 1),
    }
}

/// The standard uncertainty of a row, arcseconds: its `u` when given, else `U/k`; `None`
/// when it has neither `u` nor a coverage factor `k > 0` (no k is assumed).
fn standard_u(row: &ResultRow) -> Option<f64> {
    let u = match (row.u, row.expanded_u, row.k) {
        (Some(u), _, _) => u,
        (None, Some(expanded_u), Some(k)) if k > 0.0 => expanded_u / k,
        _ => return None,
    };
    (u.is_finite() && u >= 0.0).then_some(u)
}

/// How many rows of each family a result has.
fn family_sizes(rows: &[ResultRow]) -> FamilySizes {
    let mut sizes = FamilySizes::new();
    for row in rows {
        *sizes.entry(row.quantity).or_insert(0) += 1;
    }
    sizes
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
    check_rows(a, &options.label_a, lines_a)?;
    check_rows(b, &options.label_b, lines_b)?;

    let by = encoder_matching(a, b);
    let in_b = Matcher::new(b, by);
    let in_a = Matcher::new(a, by);
    // Each encoder error of B is matched by one of A at most.
    for rb in b.iter().filter(|rb| in_a.by_angle(rb)) {
        let found = in_a.matches(rb);
        if found.len() > 1 {
            return Err(ambiguous_angle(
                rb,
                &options.label_b,
                &options.label_a,
                &found,
                &in_a,
            ));
        }
    }
    let matched = Matched::of(a, &in_b, options, lines_a, lines_b)?;
    let rows = matched.rows;
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
    let in_verdict = || rows.iter().filter(|row| row.in_verdict);
    let max_abs_en = in_verdict().map(|row| row.en.abs()).fold(0.0, f64::max);
    let en_exceeding = in_verdict().filter(|row| row.en.abs() > 1.0).count();
    let (vector, en_expected, vector_not_formed) =
        vector_verdict(&rows, matched.without_u, (a, b), options)?;
    Ok(Comparison {
        rows,
        max_abs_en,
        verdict: options.verdict,
        vector,
        en_exceeding,
        en_expected,
        vector_not_formed,
        encoder_matched_by: by,
        only_in_a: matched.only_in_a,
        only_in_b,
        correlation: r,
    })
}

/// Every row of one result (named `label`, at `lines`) has U, is there once, and carries
/// its angle as the others do (all or none of its encoder errors).
fn check_rows(rows: &[ResultRow], label: &str, lines: Option<&[u64]>) -> Result<(), CompareError> {
    let place = |i: usize| match lines.and_then(|l| l.get(i)) {
        Some(line) => format!("line {line}"),
        None => format!("row {}", i + 1),
    };
    let mut seen = HashMap::new();
    let mut angles = AngleCheck::default();
    for (i, row) in rows.iter().enumerate() {
        if row.expanded_u.is_none() {
            return Err(CompareError::MissingU {
                location: location(label, lines, i),
                quantity: row.quantity,
                index: row.index,
            });
        }
        if seen.insert((row.quantity, row.index), i).is_some() {
            return Err(CompareError::Duplicate {
                location: location(label, lines, i),
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
                location: location(label, lines, at),
                reason: problem.message(row, &rows[..i], place),
            });
        }
    }
    Ok(())
}

/// By angle when both results have encoder errors and every one carries its angle (the
/// check of [`check_rows`]: in one result, all or none do); else by index.
fn encoder_matching(a: &[ResultRow], b: &[ResultRow]) -> EncoderMatching {
    let angles_in = |rows: &[ResultRow]| {
        let mut encoder = rows
            .iter()
            .filter(|row| row.quantity == Quantity::EncoderError)
            .peekable();
        encoder.peek().is_some() && encoder.all(|row| row.angle_deg.is_some())
    };
    if angles_in(a) && angles_in(b) {
        EncoderMatching::Angle
    } else {
        EncoderMatching::Index
    }
}

/// The error of `row` (of the result `label`) matched by angle by two rows `found` of
/// the result `other` (`of`).
fn ambiguous_angle(
    row: &ResultRow,
    label: &str,
    other: &str,
    found: &[usize],
    of: &Matcher,
) -> CompareError {
    let (first, second) = (of.row(found[0]).index, of.row(found[1]).index);
    CompareError::AmbiguousAngle {
        label: label.to_string(),
        index: row.index,
        angle_deg: row.angle_deg.unwrap_or(f64::NAN),
        other: other.to_string(),
        first: first.min(second),
        second: first.max(second),
    }
}

/// The rows of A matched in B, each compared.
struct Matched {
    rows: Vec<ComparisonRow>,
    /// The first row in the verdict without a standard uncertainty, as the error the
    /// vector's test gives for it.
    without_u: Option<CompareError>,
    only_in_a: Vec<Unmatched>,
}

impl Matched {
    /// Each row of `a` matched in B (`in_b`) and compared: its difference, En from the
    /// expanded uncertainties (correlated by `options.correlation`), its standard
    /// uncertainties.
    fn of(
        a: &[ResultRow],
        in_b: &Matcher,
        options: &CompareOptions,
        lines_a: Option<&[u64]>,
        lines_b: Option<&[u64]>,
    ) -> Result<Matched, CompareError> {
        let r = options.correlation;
        let mut matched = Matched {
            rows: Vec::new(),
            without_u: None,
            only_in_a: Vec::new(),
        };
        for (i, ra) in a.iter().enumerate() {
            let by_angle = in_b.by_angle(ra);
            let found = in_b.matches(ra);
            let j = match found.as_slice() {
                [] => {
                    matched.only_in_a.push(Unmatched {
                        quantity: ra.quantity,
                        index: ra.index,
                        angle_deg: if by_angle { ra.angle_deg } else { None },
                    });
                    continue;
                }
                [j] => *j,
                _ => {
                    return Err(ambiguous_angle(
                        ra,
                        &options.label_a,
                        &options.label_b,
                        &found,
                        in_b,
                    ));
                }
            };
            let rb = in_b.row(j);
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
            let in_verdict = options.include_setup || ra.quantity != Quantity::SetupError;
            let (u_a, u_b) = (standard_u(ra), standard_u(rb));
            if in_verdict && matched.without_u.is_none() {
                let missing = |label: &str, lines: Option<&[u64]>, i: usize, row: &ResultRow| {
                    CompareError::NoStandardU {
                        location: location(label, lines, i),
                        quantity: row.quantity,
                        index: row.index,
                    }
                };
                if u_a.is_none() {
                    matched.without_u = Some(missing(&options.label_a, lines_a, i, ra));
                } else if u_b.is_none() {
                    matched.without_u = Some(missing(&options.label_b, lines_b, j, rb));
                }
            }
            let difference = ra.value - rb.value;
            matched.rows.push(ComparisonRow {
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
                u_a,
                u_b,
                in_verdict,
            });
        }
        Ok(matched)
    }
}

/// The vector's test, the number of |En| > 1 expected by chance, and why the test was
/// not formed (under the En rule).
type VectorVerdict = (Option<VectorTest>, Option<f64>, Option<String>);

/// The vector's test and the number of |En| > 1 expected by chance, both from the
/// standard uncertainties of the `rows` in the verdict; when the test cannot be formed
/// (`without_u`, or its own error), the error under the vector rule, else its reason
/// beside the En verdict.
fn vector_verdict(
    rows: &[ComparisonRow],
    without_u: Option<CompareError>,
    (a, b): (&[ResultRow], &[ResultRow]),
    options: &CompareOptions,
) -> Result<VectorVerdict, CompareError> {
    let r = options.correlation;
    let in_verdict = || rows.iter().filter(|row| row.in_verdict);
    let formed = match without_u {
        Some(error) => Err(error),
        None => {
            let pairs: Vec<Pair> = in_verdict()
                .filter_map(|row| {
                    Some(Pair {
                        quantity: row.quantity,
                        index: row.index,
                        difference_arcsec: row.difference,
                        u_a_arcsec: row.u_a?,
                        u_b_arcsec: row.u_b?,
                    })
                })
                .collect();
            let en_expected: f64 = in_verdict()
                .filter_map(|row| row.probability_en_exceeds_one(r))
                .sum();
            vector::vector_test(
                &pairs,
                &family_sizes(a),
                &family_sizes(b),
                r,
                (&options.label_a, &options.label_b),
            )
            .map(|test| (test, en_expected))
        }
    };
    Ok(match (formed, options.verdict) {
        (Ok((test, expected)), _) => (Some(test), Some(expected), None),
        (Err(error), VerdictRule::Vector) => return Err(error),
        (Err(error), VerdictRule::En) => {
            // The count expected by chance needs only the standard uncertainties.
            let expected = in_verdict()
                .map(|row| row.probability_en_exceeds_one(r))
                .sum::<Option<f64>>();
            (None, expected, Some(error.to_string()))
        }
    })
}
