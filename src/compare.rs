//! En numbers between two results (FORMAT.md §5, `polycal compare`).
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

use serde::Serialize;

use crate::results::{ResultFile, ResultRow};

/// Options of a comparison.
#[derive(Debug, Clone, PartialEq)]
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

/// One compared quantity.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ComparisonRow {
    /// The quantity (`pitch_deviation`, …).
    pub quantity: String,
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
    pub quantity: String,
    /// Its index.
    pub index: u32,
}

/// The comparison of two results. Serializes to the JSON of FORMAT.md §5
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
        quantity: String,
        /// Its index.
        index: u32,
    },
    /// A `(quantity, index)` appears twice in one result.
    #[error("{location}: {quantity} {index} appears twice")]
    Duplicate {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: String,
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
        quantity: String,
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
/// use polycal::results::ResultRow;
///
/// let row = |value, expanded_u| ResultRow {
///     quantity: "pitch_deviation".into(), index: 7, value,
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
                    quantity: row.quantity.clone(),
                    index: row.index,
                });
            }
            if seen.insert((row.quantity.as_str(), row.index), i).is_some() {
                return Err(CompareError::Duplicate {
                    location: location(i),
                    quantity: row.quantity.clone(),
                    index: row.index,
                });
            }
        }
        Ok(())
    };
    check(a, &options.label_a, lines_a)?;
    check(b, &options.label_b, lines_b)?;

    let in_b: HashMap<(&str, u32), &ResultRow> = b
        .iter()
        .map(|row| ((row.quantity.as_str(), row.index), row))
        .collect();
    let in_a: HashMap<(&str, u32), &ResultRow> = a
        .iter()
        .map(|row| ((row.quantity.as_str(), row.index), row))
        .collect();
    let mut rows = Vec::new();
    let mut only_in_a = Vec::new();
    for ra in a {
        let Some(rb) = in_b.get(&(ra.quantity.as_str(), ra.index)) else {
            only_in_a.push(Unmatched {
                quantity: ra.quantity.clone(),
                index: ra.index,
            });
            continue;
        };
        let ua = ra.expanded_u.expect("checked above");
        let ub = rb.expanded_u.expect("checked above");
        let denominator = ua * ua + ub * ub - 2.0 * r * ua * ub;
        if denominator.is_nan() || denominator <= 0.0 {
            return Err(CompareError::Undefined {
                quantity: ra.quantity.clone(),
                index: ra.index,
                denominator,
                expanded_u_a: ua,
                expanded_u_b: ub,
                r,
            });
        }
        let difference = ra.value - rb.value;
        rows.push(ComparisonRow {
            quantity: ra.quantity.clone(),
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
        .filter(|rb| !in_a.contains_key(&(rb.quantity.as_str(), rb.index)))
        .map(|rb| Unmatched {
            quantity: rb.quantity.clone(),
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

/// Renders a comparison as a table: quantity, index, a, b, a − b, U_a, U_b, En, and the
/// verdict. Numbers are rounded for reading (0.001″, En to 0.01); JSON carries them at
/// full precision.
pub fn render_table(comparison: &Comparison) -> String {
    let rows: Vec<[String; 8]> = comparison
        .rows
        .iter()
        .map(|r| {
            [
                r.quantity.clone(),
                r.index.to_string(),
                format!("{:.3}", r.a),
                format!("{:.3}", r.b),
                format!("{:.3}", r.difference),
                format!("{:.3}", r.expanded_u_a),
                format!("{:.3}", r.expanded_u_b),
                format!("{:.2}{}", r.en, if r.en.abs() > 1.0 { " *" } else { "" }),
            ]
        })
        .collect();
    let header = [
        "Quantity".to_string(),
        "Index".into(),
        "a".into(),
        "b".into(),
        "a − b".into(),
        "U_a".into(),
        "U_b".into(),
        "En".into(),
    ];
    let mut out = crate::uncertainty::format::table(
        &header,
        &rows,
        &[false, true, true, true, true, true, true, true],
    );
    out.push('\n');
    if comparison.correlation != 0.0 {
        out.push_str(&format!(
            "Correlation between the results r = {}\n",
            comparison.correlation
        ));
    }
    let failing = comparison.rows.iter().filter(|r| r.en.abs() > 1.0).count();
    out.push_str(&format!(
        "Largest |En| = {:.2}: {}\n",
        comparison.max_abs_en,
        if failing == 0 {
            "every |En| ≤ 1, the results agree within their uncertainties".to_string()
        } else {
            format!(
                "{failing} of {} rows have |En| > 1 (marked *)",
                comparison.rows.len()
            )
        }
    ));
    for (label, list) in [
        ("first", &comparison.only_in_a),
        ("second", &comparison.only_in_b),
    ] {
        if !list.is_empty() {
            out.push_str(&format!(
                "Only in the {label} result (not compared): {}\n",
                list.iter()
                    .map(|u| format!("{} {}", u.quantity, u.index))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    out
}

/// Writes a comparison as CSV, one row per compared `(quantity, index)` in the order of
/// [`Comparison::rows`], under the header `quantity,index,a,b,difference,U_a,U_b,en`.
/// Numbers are written at full precision in Rust's shortest round-trip representation
/// (`{}`), so that reading them back gives the same `f64`; an `en` that is not a finite
/// number is written as an empty field. The quantities in one result only
/// ([`Comparison::only_in_a`], [`Comparison::only_in_b`]) are not compared and not
/// written.
///
/// # Errors
///
/// The I/O error of the writer, as a [`csv::Error`].
///
/// # Examples
///
/// ```
/// use polycal::compare::{compare, write_csv, CompareOptions};
/// use polycal::results::ResultRow;
///
/// let row = |value, expanded_u| ResultRow {
///     quantity: "pitch_deviation".into(), index: 7, value,
///     u: None, expanded_u: Some(expanded_u), k: None,
/// };
/// let c = compare(&[row(0.28, 0.46)], &[row(0.0, 0.15)], &CompareOptions::default())?;
/// let mut csv = Vec::new();
/// write_csv(&mut csv, &c)?;
/// let text = String::from_utf8(csv)?;
/// assert!(text.starts_with("quantity,index,a,b,difference,U_a,U_b,en\npitch_deviation,7,0.28,0,0.28,0.46,0.15,0.5"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn write_csv<W: std::io::Write>(writer: W, comparison: &Comparison) -> Result<(), csv::Error> {
    let mut csv = csv::Writer::from_writer(writer);
    csv.write_record([
        "quantity",
        "index",
        "a",
        "b",
        "difference",
        "U_a",
        "U_b",
        "en",
    ])?;
    for row in &comparison.rows {
        let en = if row.en.is_finite() {
            row.en.to_string()
        } else {
            String::new()
        };
        csv.write_record([
            row.quantity.clone(),
            row.index.to_string(),
            row.a.to_string(),
            row.b.to_string(),
            row.difference.to_string(),
            row.expanded_u_a.to_string(),
            row.expanded_u_b.to_string(),
            en,
        ])?;
    }
    csv.flush()?;
    Ok(())
}

#[cfg(test)]
mod write_csv_tests {
    use super::*;

    fn row(quantity: &str, index: u32, value: f64, expanded_u: f64) -> ResultRow {
        ResultRow {
            quantity: quantity.into(),
            index,
            value,
            u: None,
            expanded_u: Some(expanded_u),
            k: None,
        }
    }

    /// Every number reads back bit for bit; the header is the documented one; a
    /// non-finite En is an empty field; unmatched quantities are left out.
    #[test]
    fn write_csv_round_trips_every_number() {
        let a = [
            row("pitch_deviation", 1, 0.1 + 0.2, 0.46),
            row("encoder_error", 0, -1.0 / 3.0, 0.02),
            row("pitch_deviation", 2, 5.0, 1.0),
        ];
        let b = [
            row("pitch_deviation", 1, 1e-300, 0.15),
            row("encoder_error", 0, 2.0f64.sqrt(), 1e-7),
        ];
        let mut comparison = compare(&a, &b, &CompareOptions::default()).unwrap();
        assert_eq!(comparison.only_in_a.len(), 1);
        let mut out = Vec::new();
        write_csv(&mut out, &comparison).unwrap();
        assert!(
            out.as_slice()
                .starts_with(b"quantity,index,a,b,difference,U_a,U_b,en\n")
        );
        let mut reader = csv::Reader::from_reader(out.as_slice());
        let records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
        assert_eq!(records.len(), comparison.rows.len());
        for (record, row) in records.iter().zip(&comparison.rows) {
            let number = |i: usize| record[i].parse::<f64>().unwrap().to_bits();
            assert_eq!(&record[0], row.quantity);
            assert_eq!(record[1].parse::<u32>().unwrap(), row.index);
            assert_eq!(number(2), row.a.to_bits());
            assert_eq!(number(3), row.b.to_bits());
            assert_eq!(number(4), row.difference.to_bits());
            assert_eq!(number(5), row.expanded_u_a.to_bits());
            assert_eq!(number(6), row.expanded_u_b.to_bits());
            assert_eq!(number(7), row.en.to_bits());
        }

        comparison.rows[0].en = f64::NAN;
        let mut out = Vec::new();
        write_csv(&mut out, &comparison).unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.lines().nth(1).unwrap().ends_with(",0.15,"), "{text}");
    }
}
