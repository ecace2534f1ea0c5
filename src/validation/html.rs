//! The validation record as one self-contained HTML document, the record a laboratory
//! files (ISO/IEC 17025 7.11.2): purpose, scope, the build, every case with its
//! reference and verdict, how to reproduce it.

use std::fmt::{self, Write};

use super::table::number;
use super::{CaseResult, ValidationRecord};
use crate::figure::svg::esc;

const STYLE: &str = "body{font-family:sans-serif;max-width:60em;margin:2em auto;line-height:1.4}\
table{border-collapse:collapse;margin:0.5em 0}td,th{border:1px solid #999;padding:0.2em 0.5em;\
text-align:left;vertical-align:top}code{font-size:0.9em}.pass{color:#060}.fail{color:#a00;\
font-weight:bold}section.case{page-break-inside:avoid;margin-top:1.5em}";

/// Writes the record as HTML (inline CSS, nothing fetched, no script).
///
/// # Errors
///
/// Only those of `out`.
pub fn write_html(out: &mut impl Write, record: &ValidationRecord) -> fmt::Result {
    let total = record.passed + record.failed;
    let verdict = if record.failed == 0 {
        format!("<span class=\"pass\">All {total} cases passed.</span>")
    } else {
        format!(
            "<span class=\"fail\">{} of {total} cases failed.</span>",
            record.failed
        )
    };
    writeln!(
        out,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Validation record: polycal {v}</title><style>{STYLE}</style></head><body>\
         <h1>Validation record: polycal {v}</h1><p>{verdict}</p>",
        v = esc(record.version)
    )?;
    writeln!(
        out,
        "<h2>Purpose and scope</h2><p>This record shows that this build of polycal \
         reproduces, within stated tolerances, reference results computed independently of \
         polycal (ISO/IEC 17025:2017 7.11.2). Each case runs one evaluation of the software \
         (solve for each kind of design, the uncertainty budget, Monte Carlo, \
         self-calibration, diagnosis, comparison, key comparison) on bundled input files through the \
         same library function its command calls, and compares every number the reference \
         holds with the number the command prints. The references were computed by \
         <code>scripts/validation/reference.py</code>, which implements the model in exact \
         rational arithmetic (square roots and Student's t to 50 digits) and does not use \
         polycal.</p>"
    )?;
    let b = &record.build;
    let p = &record.platform;
    writeln!(
        out,
        "<h2>Software and platform</h2><table>\
         <tr><th>software</th><td>polycal {}</td></tr>\
         <tr><th>commit</th><td><code>{}</code></td></tr>\
         <tr><th>compiler</th><td>{}</td></tr>\
         <tr><th>target</th><td>{}</td></tr>\
         <tr><th>profile</th><td>{}</td></tr>\
         <tr><th>features</th><td>{}</td></tr>\
         <tr><th>platform</th><td>{} {}, {} threads</td></tr>\
         <tr><th>date (UTC)</th><td>{}</td></tr></table>",
        esc(record.version),
        esc(b.commit),
        esc(b.compiler),
        esc(b.target),
        esc(b.profile),
        esc(&b.features.join(", ")),
        esc(p.os),
        esc(p.arch),
        p.threads,
        esc(&record.date)
    )?;
    writeln!(
        out,
        "<h2>Summary</h2><table><tr><th>case</th><th>evaluation</th><th>largest deviation</th>\
         <th>tolerance</th><th>result</th></tr>"
    )?;
    for case in &record.cases {
        writeln!(
            out,
            "<tr><td><a href=\"#{id}\">{id}</a></td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&case.evaluation),
            number(case.deviation),
            number(Some(case.tolerance)),
            result(case),
            id = esc(&case.name)
        )?;
    }
    writeln!(out, "</table>")?;
    for case in &record.cases {
        write_case(out, case)?;
    }
    writeln!(
        out,
        "<h2>How to reproduce</h2><p>Rerun this validation with <code>polycal validate \
         --out REPORT.html</code> (a laboratory's own cases: <code>polycal validate --cases \
         DIR</code>). Recompute the bundled references from a source checkout with \
         <code>{}</code>; <code>--check</code> reports any byte that would change. Every \
         figure above follows from the files named with their SHA-256.</p></body></html>",
        esc(record.reference_command)
    )
}

/// `pass` or `FAIL` with its class.
fn result(case: &CaseResult) -> &'static str {
    if case.pass {
        "<span class=\"pass\">pass</span>"
    } else {
        "<span class=\"fail\">FAIL</span>"
    }
}

/// One case's section.
fn write_case(out: &mut impl Write, case: &CaseResult) -> fmt::Result {
    let measure = serde_json::to_value(case.tolerance_kind)
        .ok()
        .and_then(|v| v.as_str().map(str::to_string))
        .unwrap_or_default();
    writeln!(
        out,
        "<section class=\"case\" id=\"{id}\"><h3>{id}: {}</h3><p>{}</p><table>\
         <tr><th>command</th><td><code>{}</code></td></tr>\
         <tr><th>case files</th><td>{}</td></tr>\
         <tr><th>reference</th><td>{} (<code>reference.json</code>, written by {})</td></tr>\
         <tr><th>numbers compared</th><td>{}</td></tr>\
         <tr><th>largest deviation</th><td>{}{}</td></tr>\
         <tr><th>tolerance</th><td>{} ({})<br>{}</td></tr>",
        result(case),
        esc(&case.description),
        esc(&case.command),
        esc(&case.origin),
        esc(&case.reference_method),
        esc(&case.reference_generator),
        case.compared,
        number(case.deviation),
        case.worst
            .as_ref()
            .map_or_else(String::new, |w| format!(" at <code>{}</code>", esc(w))),
        number(Some(case.tolerance)),
        esc(&measure),
        esc(&case.tolerance_reason),
        id = esc(&case.name)
    )?;
    if let Some(problem) = &case.problem {
        writeln!(
            out,
            "<tr><th>problem</th><td class=\"fail\">{}</td></tr>",
            esc(problem)
        )?;
    }
    writeln!(out, "<tr><th>SHA-256</th><td><table>")?;
    for file in &case.files {
        writeln!(
            out,
            "<tr><td><code>{}</code></td><td><code>{}</code></td></tr>",
            esc(&file.name),
            esc(&file.sha256)
        )?;
    }
    writeln!(out, "</table></td></tr></table></section>")
}
