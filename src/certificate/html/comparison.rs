//! The comparison section of a calibration report (`report --reference`, docs/FORMAT.md
//! §10.2 item 8): the verdict in `compare`'s words, and every row — a and b each with its
//! U as GUM 7.2.6 states a result, a − b beside U(a − b) with the digits its mark needs,
//! En.

use std::fmt::Write;

use super::Sections;
use super::tables::{decision_pair_cells, en_cell, num, rounded_pair_cells};
use crate::certificate::CalibrationReport;
use crate::figure::svg::esc;

pub(super) fn section(s: &mut Sections, report: &CalibrationReport) {
    let Some((c, reference)) = &report.comparison else {
        return;
    };
    s.open("comparison", "Comparison with a reference");
    let _ = write!(
        s.html,
        "<p>a: this calibration; b: {}. Encoder errors matched by {}. Setup errors are listed but left out of the verdict.</p>\n\
         <p class=\"verdict {}\" id=\"comparison-verdict\">Verdict: {}. Largest |En| = {}.</p>\n",
        esc(reference),
        match c.encoder_matched_by {
            crate::compare::EncoderMatching::Angle => "angle",
            _ => "index",
        },
        if c.verdict_ok() { "pass" } else { "fail" },
        esc(&c.verdict_sentence()),
        crate::certificate::rounding::en_text(c.max_abs_en).replace('-', "−")
    );
    s.html.push_str(
        "<table class=\"comparison\" id=\"comparison-rows\"><caption>Each value with its U as \
         GUM 7.2.6 states it; a − b beside U(a − b) = √(U<sub>a</sub>² + U<sub>b</sub>²), the En \
         denominator, with the digits it takes to see whether |a − b| exceeds it</caption>\
         <thead><tr><th>Quantity</th><th>Index</th>\
         <th>angle / °</th><th>a / ″</th><th>U<sub>a</sub> / ″</th><th>b / ″</th>\
         <th>U<sub>b</sub> / ″</th><th>a − b / ″</th><th>U(a − b) / ″</th><th>En</th></tr></thead><tbody>\n",
    );
    for r in &c.rows {
        let class = if !r.in_verdict {
            " class=\"out-of-verdict\""
        } else if r.en.abs() > 1.0 {
            " class=\"fail\""
        } else {
            ""
        };
        // the report compares without a correlation: En's denominator
        let expanded_d = r.expanded_u_a.hypot(r.expanded_u_b);
        let _ = writeln!(
            s.html,
            "<tr{class}><td>{}</td><td>{}</td>{}{}{}{}{}</tr>",
            r.quantity.name(),
            r.index,
            num(r.angle_deg, 3),
            rounded_pair_cells(r.a, r.expanded_u_a),
            rounded_pair_cells(r.b, r.expanded_u_b),
            decision_pair_cells(r.difference, expanded_d),
            en_cell(r.en),
        );
    }
    s.html.push_str("</tbody></table>\n");
    s.close();
}
