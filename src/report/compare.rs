//! The table of `polycal compare` for people.

use crate::compare::Comparison;
use std::fmt::{self, Write};

/// Writes a comparison as a table: quantity, index, a, b, a − b, U_a, U_b, En, and the
/// verdict. Numbers are rounded for reading (0.001″, En to 0.01); JSON and CSV carry them
/// at full precision.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(out: &mut W, comparison: &Comparison) -> fmt::Result {
    let rows: Vec<[String; 8]> = comparison
        .rows
        .iter()
        .map(|r| {
            [
                r.quantity.to_string(),
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
    let table = crate::uncertainty::format::table(
        &header,
        &rows,
        &[false, true, true, true, true, true, true, true],
    );
    writeln!(out, "{table}")?;
    if comparison.correlation != 0.0 {
        writeln!(
            out,
            "Correlation between the results r = {}",
            comparison.correlation
        )?;
    }
    let failing = comparison.rows.iter().filter(|r| r.en.abs() > 1.0).count();
    writeln!(
        out,
        "Largest |En| = {:.2}: {}",
        comparison.max_abs_en,
        if failing == 0 {
            "every |En| ≤ 1, the results agree within their uncertainties".to_string()
        } else {
            format!(
                "{failing} of {} rows have |En| > 1 (marked *)",
                comparison.rows.len()
            )
        }
    )?;
    for (label, list) in [
        ("first", &comparison.only_in_a),
        ("second", &comparison.only_in_b),
    ] {
        if !list.is_empty() {
            writeln!(
                out,
                "Only in the {label} result (not compared): {}",
                list.iter()
                    .map(|u| format!("{} {}", u.quantity, u.index))
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
    }
    Ok(())
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
/// use polycal::compare::{compare, CompareOptions};
/// use polycal::report::compare::write_csv;
/// use polycal::results::{Quantity, ResultRow};
///
/// let row = |value, expanded_u| ResultRow {
///     quantity: Quantity::PitchDeviation, index: 7, value,
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
            row.quantity.name().to_string(),
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
    use crate::compare::{CompareOptions, compare};
    use crate::results::{Quantity, ResultRow};

    fn row(quantity: &str, index: u32, value: f64, expanded_u: f64) -> ResultRow {
        ResultRow {
            quantity: Quantity::from_name(quantity).expect("a quantity"),
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
            assert_eq!(&record[0], row.quantity.name());
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
