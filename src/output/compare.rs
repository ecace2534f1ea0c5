//! The table of `polycal compare` for people, and its CSV.

use crate::compare::{Comparison, EncoderMatching, Unmatched};
use crate::results::{ANGLE_TOLERANCE_DEG, Quantity};
use std::fmt::{self, Write};

/// Writes a comparison as a table: quantity, index (with encoder errors matched by angle,
/// also the second result's index and the angle), a, b, a − b, U_a, U_b, En, then how the
/// encoder errors were matched, which rows are left out of the verdict, the largest |En|,
/// the vector's families and the verdict in one line ([`Comparison::verdict_sentence`]).
/// Numbers are rounded for reading (0.001″, En to 0.01, angles to 0.0001°); JSON and CSV
/// carry them at full precision. An En marked `*` has |En| > 1; an En in parentheses is a
/// setup error's, left out of the verdict.
///
/// # Errors
///
/// The writer's error.
pub fn write_table<W: Write>(out: &mut W, comparison: &Comparison) -> fmt::Result {
    let by_angle = comparison.encoder_matched_by == EncoderMatching::Angle;
    let rows: Vec<Vec<String>> = comparison
        .rows
        .iter()
        .map(|r| {
            let en = if !r.in_verdict {
                format!("({:.2})", r.en)
            } else if r.en.abs() > 1.0 {
                format!("{:.2} *", r.en)
            } else {
                format!("{:.2}", r.en)
            };
            let mut row = vec![r.quantity.to_string(), r.index.to_string()];
            if by_angle {
                row.push(r.index_b.unwrap_or(r.index).to_string());
                row.push(r.angle_deg.map_or(String::new(), |a| format!("{a:.4}")));
            }
            row.extend([
                format!("{:.3}", r.a),
                format!("{:.3}", r.b),
                format!("{:.3}", r.difference),
                format!("{:.3}", r.expanded_u_a),
                format!("{:.3}", r.expanded_u_b),
                en,
            ]);
            row
        })
        .collect();
    let mut header = vec!["Quantity".to_string(), "Index".into()];
    if by_angle {
        header.extend(["Index b".into(), "Angle °".into()]);
    }
    header.extend([
        "a".into(),
        "b".into(),
        "a − b".into(),
        "U_a".into(),
        "U_b".into(),
        "En".into(),
    ]);
    let table = if by_angle {
        columns::<10>(header, rows)
    } else {
        columns::<8>(header, rows)
    };
    writeln!(out, "{table}")?;
    if comparison.correlation != 0.0 {
        writeln!(
            out,
            "Correlation between the results r = {}",
            comparison.correlation
        )?;
    }

    // How the encoder errors were matched, when there are any.
    let encoder = |list: &[crate::compare::Unmatched]| {
        list.iter()
            .filter(|u| u.quantity == Quantity::EncoderError)
            .count()
    };
    let shared = comparison
        .rows
        .iter()
        .filter(|r| r.quantity == Quantity::EncoderError)
        .count();
    let (in_a, in_b) = (
        shared + encoder(&comparison.only_in_a),
        shared + encoder(&comparison.only_in_b),
    );
    if in_a + in_b > 0 {
        match comparison.encoder_matched_by {
            EncoderMatching::Angle => writeln!(
                out,
                "Encoder errors matched by angle (angle_deg within {ANGLE_TOLERANCE_DEG:e}°): \
                 {shared} shared angles of {in_a} and {in_b}"
            )?,
            EncoderMatching::Index => writeln!(
                out,
                "Encoder errors matched by index (angle_deg is not in both results): \
                 {shared} shared indices of {in_a} and {in_b}"
            )?,
        }
    }
    if comparison.rows.iter().any(|r| !r.in_verdict) {
        writeln!(
            out,
            "Setup errors depend on the mounting: their En (in parentheses) is left out of the \
             verdict and of the largest |En|"
        )?;
    }

    writeln!(
        out,
        "Largest |En| = {:.2}{}",
        comparison.max_abs_en,
        if comparison.en_exceeding > 0 {
            " (|En| > 1 marked *)"
        } else {
            ""
        }
    )?;
    match (&comparison.vector, &comparison.vector_not_formed) {
        (Some(vector), _) => writeln!(
            out,
            "The vector: {}{}",
            vector
                .families
                .iter()
                .map(|f| format!(
                    "{} {} rows, χ² = {:.2}, ν = {}",
                    f.quantity, f.rows, f.chi2, f.dof
                ))
                .collect::<Vec<_>>()
                .join("; "),
            if comparison
                .rows
                .iter()
                .any(|r| r.quantity == Quantity::FaceDeviation)
            {
                " (face deviations are the pitch deviations accumulated: not in the vector)"
            } else {
                ""
            }
        )?,
        (None, Some(why)) => writeln!(out, "No vector test: {why}")?,
        (None, None) => {}
    }
    writeln!(out, "Verdict: {}", comparison.verdict_sentence())?;
    for (label, list) in [
        ("first", &comparison.only_in_a),
        ("second", &comparison.only_in_b),
    ] {
        if !list.is_empty() {
            writeln!(
                out,
                "Only in the {label} result (not compared): {}",
                unmatched_names(list)
            )?;
        }
    }
    Ok(())
}

/// How many names of unmatched quantities the table lists before it summarises.
const UNMATCHED_LISTED: usize = 6;

/// The quantities found in one result only, as the table names them: every one when
/// there are at most [`UNMATCHED_LISTED`], otherwise their number, the first few and
/// where the full list is (the JSON's `only_in_a`/`only_in_b`), so that a 24-position
/// result against a 168-position one is one readable line, not 144 names.
fn unmatched_names(list: &[Unmatched]) -> String {
    let names = list
        .iter()
        .take(UNMATCHED_LISTED)
        .map(|u| format!("{} {}", u.quantity, u.index))
        .collect::<Vec<_>>()
        .join(", ");
    if list.len() <= UNMATCHED_LISTED {
        names
    } else {
        format!(
            "{} quantities: {names}, … (every one in the JSON output's only_in_a/only_in_b)",
            list.len()
        )
    }
}

/// The table of N columns, the first left-aligned.
fn columns<const N: usize>(header: Vec<String>, rows: Vec<Vec<String>>) -> String {
    fn fixed<const N: usize>(cells: Vec<String>) -> [String; N] {
        let mut out: [String; N] = std::array::from_fn(|_| String::new());
        for (slot, cell) in out.iter_mut().zip(cells) {
            *slot = cell;
        }
        out
    }
    let rows: Vec<[String; N]> = rows.into_iter().map(fixed).collect();
    let mut right = [true; N];
    right[0] = false;
    crate::uncertainty::format::table(&fixed(header), &rows, &right)
}

/// Writes a comparison as CSV, one row per compared quantity in the order of
/// [`Comparison::rows`], under the header
/// `quantity,index,a,b,difference,U_a,U_b,en,index_b,angle_deg,in_verdict`. Numbers are
/// written at full precision in Rust's shortest round-trip representation (`{}`), so that
/// reading them back gives the same `f64`; an `en` that is not a finite number is written
/// as an empty field, and so are `index_b` and `angle_deg` but for encoder errors matched
/// by angle. `in_verdict` is `true` or `false` (setup errors left out of the verdict).
/// The quantities in one result only ([`Comparison::only_in_a`],
/// [`Comparison::only_in_b`]) are not compared and not written.
///
/// # Errors
///
/// The I/O error of the writer, as a [`csv::Error`].
///
/// # Examples
///
/// ```
/// use polycal::compare::{compare, CompareOptions, VerdictRule};
/// use polycal::output::compare::write_csv;
/// use polycal::results::{Quantity, ResultRow};
///
/// let row = |value, expanded_u| {
///     ResultRow::new(Quantity::PitchDeviation, 7, value).with_expanded_u(expanded_u)
/// };
/// let options = CompareOptions::default().with_verdict(VerdictRule::En);
/// let c = compare(&[row(0.28, 0.46)], &[row(0.0, 0.15)], &options)?;
/// let mut csv = Vec::new();
/// write_csv(&mut csv, &c)?;
/// let text = String::from_utf8(csv)?;
/// assert!(text.starts_with(
///     "quantity,index,a,b,difference,U_a,U_b,en,index_b,angle_deg,in_verdict\n\
///      pitch_deviation,7,0.28,0,0.28,0.46,0.15,0.5"
/// ));
/// assert!(text.ends_with(",,,true\n"));
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
        "index_b",
        "angle_deg",
        "in_verdict",
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
            row.index_b.map_or(String::new(), |i| i.to_string()),
            row.angle_deg.map_or(String::new(), |a| a.to_string()),
            row.in_verdict.to_string(),
        ])?;
    }
    csv.flush()?;
    Ok(())
}

#[cfg(test)]
mod write_csv_tests {
    use super::*;
    use crate::compare::{CompareOptions, VerdictRule, compare};
    use crate::results::{Quantity, ResultRow};

    fn row(quantity: &str, index: u32, value: f64, expanded_u: f64) -> ResultRow {
        ResultRow::new(
            Quantity::from_name(quantity).expect("a quantity"),
            index,
            value,
        )
        .with_expanded_u(expanded_u)
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
        let options = CompareOptions::default().with_verdict(VerdictRule::En);
        let mut comparison = compare(&a, &b, &options).unwrap();
        assert_eq!(comparison.only_in_a.len(), 1);
        let mut out = Vec::new();
        write_csv(&mut out, &comparison).unwrap();
        assert!(out.as_slice().starts_with(
            b"quantity,index,a,b,difference,U_a,U_b,en,index_b,angle_deg,in_verdict\n"
        ));
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
        assert!(
            text.lines().nth(1).unwrap().ends_with(",0.15,,,,true"),
            "{text}"
        );
    }
}
