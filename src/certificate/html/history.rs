//! The section "History of the standard" of a calibration report (`report --history`,
//! docs/FORMAT.md §10.2, §13.2): the calibrations with their days and SHA-256, the drift
//! decision and the fit of every calibration's history, per face the drift per year with
//! its u, the value the earlier calibrations predict for this calibration's day with its
//! U, this calibration's value with its U and En (information), the one decision whether
//! they agree, and the control charts inline. Every number rounded for reading with the
//! history's JSON number in `data-value`.

use std::fmt::Write;

use super::Sections;
use super::tables::{ARCSEC_DECIMALS, decision_pair_cells, en_cell, num, rounded_pair_cells};
use crate::certificate::{CalibrationReport, HistorySection};
use crate::figure::svg::esc;

/// The section, when the report has a history.
pub(super) fn section(s: &mut Sections, report: &CalibrationReport) {
    let Some(h) = &report.history else { return };
    s.open("history", "History of the standard");
    calibrations(&mut s.html, h);
    let all = &h.history;
    let _ = writeln!(
        s.html,
        "<p>Per face, the model x(t) = a + b·(t − t<sub>ref</sub>) fitted to the calibrations' \
         pitch deviations by generalised least squares, each calibration's vector closed with \
         V<sub>i</sub> = N/(N − 1)·P·diag(u<sub>i</sub>²)·P (as <code>polycal history</code>, \
         docs/FORMAT.md §13.2); b in arcseconds per year of 365.25 days. The model is decided \
         by one test of the whole drift vector at 5 %:</p>\n\
         <p class=\"verdict info\" id=\"history-model\" data-model=\"{}\">{}.</p>\n\
         <p class=\"verdict {}\" id=\"history-fit\">{}.</p>",
        all.model.name(),
        esc(&all.verdict_statement()),
        if all.fit.as_ref().is_none_or(|f| f.test.consistent) {
            "info"
        } else {
            "fail"
        },
        esc(&all.fit_statement())
    );
    let _ = writeln!(
        s.html,
        "<p>The prediction for {} is made from the {} earlier calibrations alone, by their own \
         model ({}), u² = u²(a) + 2τ·cov(a, b) + τ²·u²(b) (the drift's extrapolation \
         included), U = 2u. This calibration's value a is compared with it (b): En = (a − b)/\
         √(U<sub>a</sub>² + U<sub>b</sub>²) per face is information; the decision is one test \
         of the closed vector of differences at 5 %, <code>compare</code>'s (docs/FORMAT.md \
         §5.4), the prediction taken as a closed result with its u.</p>",
        esc(&h.date),
        h.earlier.dates.len(),
        h.earlier.model.name()
    );
    table(&mut s.html, h);
    let _ = writeln!(
        s.html,
        "<p class=\"verdict {}\" id=\"history-verdict\">{}.</p>",
        if h.agrees() { "pass" } else { "fail" },
        esc(&h.agreement_statement())
    );
    // the notes besides the statements above: the line-up's, the prediction's
    let stated = [
        all.verdict_statement(),
        all.fit_statement(),
        h.earlier.verdict_statement(),
        h.earlier.fit_statement(),
    ];
    let notes: Vec<&String> = all
        .notes
        .iter()
        .chain(&h.earlier.notes)
        .filter(|n| !stated.contains(n))
        .collect();
    if !notes.is_empty() {
        s.html
            .push_str("<ul class=\"notes\" id=\"history-notes\">\n");
        for note in notes {
            let _ = writeln!(s.html, "<li>{}</li>", esc(note));
        }
        s.html.push_str("</ul>\n");
    }
    for f in crate::figure::history_figures(all) {
        let _ = write!(
            s.html,
            "<figure id=\"figure-{}\">\n{}\n<figcaption>{} — every calibration, this one the \
             newest</figcaption>\n</figure>\n",
            esc(&f.name),
            f.svg,
            esc(&f.title)
        );
    }
    s.close();
}

fn calibrations(out: &mut String, h: &HistorySection) {
    out.push_str(
        "<table id=\"history-calibrations\"><caption>The calibrations of the standard, oldest \
         first</caption><thead><tr><th>Date</th><th>File</th><th>SHA-256</th></tr></thead><tbody>\n",
    );
    for c in &h.calibrations {
        let _ = writeln!(
            out,
            "<tr{}><td>{}</td><td>{}{}</td><td class=\"hash\">{}</td></tr>",
            if c.this_report {
                " class=\"this-report\""
            } else {
                ""
            },
            esc(&c.date),
            esc(&c.file),
            if c.this_report {
                " (this calibration)"
            } else {
                ""
            },
            c.sha256
        );
    }
    out.push_str("</tbody></table>\n");
}

fn table(out: &mut String, h: &HistorySection) {
    let all = &h.history;
    let _ = writeln!(
        out,
        "<table class=\"results\" id=\"history-faces\"><caption>Per face: the drift of every \
         calibration's history, the earlier calibrations' prediction for {} and this \
         calibration's value (k = 2)</caption><thead><tr><th>Face</th><th>drift / ″/yr</th>\
         <th>u(drift) / ″/yr</th><th>predicted / ″</th><th>U(predicted) / ″</th>\
         <th>this / ″</th><th>U(this) / ″</th><th>this − predicted / ″</th>\
         <th>√(U² + U²) / ″</th><th>En</th></tr></thead><tbody>",
        esc(&h.date)
    );
    for (k, index) in all.index.iter().enumerate() {
        let row = h
            .agreement
            .rows
            .iter()
            .find(|r| r.index == *index && r.quantity == all.quantity);
        let Some(row) = row else { continue };
        let _ = writeln!(
            out,
            "<tr data-index=\"{index}\"{}><td>{index}</td>{}{}{}{}{}{}</tr>",
            if row.en.abs() > 1.0 {
                " class=\"fail\""
            } else {
                ""
            },
            num(Some(all.drift[k]), ARCSEC_DECIMALS),
            num(Some(all.drift_u[k]), ARCSEC_DECIMALS),
            rounded_pair_cells(row.b, row.expanded_u_b),
            rounded_pair_cells(row.a, row.expanded_u_a),
            decision_pair_cells(row.difference, row.expanded_u_a.hypot(row.expanded_u_b)),
            en_cell(row.en)
        );
    }
    out.push_str("</tbody></table>\n");
}
