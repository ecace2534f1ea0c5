//! The validation record as a table for people.

use std::fmt::{self, Write};

use super::ValidationRecord;

/// A deviation or tolerance as the table shows it.
pub(super) fn number(value: Option<f64>) -> String {
    value.map_or_else(|| "—".to_string(), |v| format!("{v:.3e}"))
}

/// Writes the record: the build, one line per case, the failures' reasons, the summary.
///
/// # Errors
///
/// Only those of `out`.
pub fn write_table(out: &mut impl Write, record: &ValidationRecord) -> fmt::Result {
    let b = &record.build;
    writeln!(
        out,
        "polycal {} validation, {}",
        record.version, record.date
    )?;
    writeln!(
        out,
        "build: commit {}, {}, target {}, profile {}, features [{}]",
        b.commit,
        b.compiler,
        b.target,
        b.profile,
        b.features.join(", ")
    )?;
    let p = &record.platform;
    writeln!(out, "platform: {} {}, {} threads", p.os, p.arch, p.threads)?;
    writeln!(out)?;
    let width = record
        .cases
        .iter()
        .map(|c| c.name.len())
        .max()
        .unwrap_or(4)
        .max(4);
    writeln!(
        out,
        "{:<width$}  {:<12}  {:>10}  {:>10}  {:<13}  result",
        "case", "evaluation", "deviation", "tolerance", "measure"
    )?;
    for case in &record.cases {
        writeln!(
            out,
            "{:<width$}  {:<12}  {:>10}  {:>10}  {:<13}  {}",
            case.name,
            case.evaluation,
            number(case.deviation),
            number(Some(case.tolerance)),
            serde_json::to_value(case.tolerance_kind)
                .ok()
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_default(),
            if case.pass { "pass" } else { "FAIL" }
        )?;
    }
    for case in record.cases.iter().filter(|c| !c.pass) {
        let why = case.problem.clone().unwrap_or_else(|| {
            format!(
                "largest deviation {} at {} exceeds {}",
                number(case.deviation),
                case.worst.as_deref().unwrap_or("?"),
                number(Some(case.tolerance))
            )
        });
        writeln!(out, "FAIL {}: {why}", case.name)?;
    }
    writeln!(out)?;
    writeln!(
        out,
        "{} of {} cases passed{}",
        record.passed,
        record.passed + record.failed,
        if record.failed == 0 {
            String::new()
        } else {
            format!("; {} failed", record.failed)
        }
    )
}
