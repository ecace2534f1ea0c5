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
