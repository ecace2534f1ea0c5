//! The diagnosis section's body of a calibration report (`report --diagnose`,
//! docs/FORMAT.md §10.2 item 7): adequacy, the checks, the effects found (each u the
//! fit's own, labelled so), the fit before and after (and against a truth), the notes,
//! and the final model's results only when it differs from the base model.

use std::fmt::Write;

use super::tables::{ARCSEC_DECIMALS, num, rounded_pair_cells, selfcal_tables, solve_tables};
use crate::certificate::DiagnosisReport;
use crate::figure::svg::esc;

pub(super) fn diagnosis_body(out: &mut String, report: &DiagnosisReport) {
    let (adequate, checks, effects, notes) = report.parts();
    let (rms_before, rms_after, dof_before, dof_after) = match report {
        DiagnosisReport::Polygon(d) => (
            d.before.residual_rms,
            d.after.residual_rms,
            d.before.dof,
            d.after.dof,
        ),
        DiagnosisReport::Selfcal(d) => (
            d.before.residual_rms,
            d.after.residual_rms,
            d.before.dof,
            d.after.dof,
        ),
    };
    // against a truth: (label, before, after)
    let errors: Vec<(&str, f64, f64)> = match report {
        DiagnosisReport::Polygon(d) => d.error.as_ref().map_or_else(Vec::new, |e| {
            vec![
                (
                    "Pitch deviation error, RMS / ″",
                    e.before.pitch_rms,
                    e.after.pitch_rms,
                ),
                (
                    "Pitch deviation error, largest / ″",
                    e.before.pitch_max,
                    e.after.pitch_max,
                ),
                (
                    "Encoder error error, RMS / ″",
                    e.before.encoder_rms,
                    e.after.encoder_rms,
                ),
                (
                    "Encoder error error, largest / ″",
                    e.before.encoder_max,
                    e.after.encoder_max,
                ),
            ]
        }),
        DiagnosisReport::Selfcal(d) => d.error.as_ref().map_or_else(Vec::new, |e| {
            vec![
                (
                    "Graduation error e error, RMS / ″",
                    e.before.encoder_rms,
                    e.after.encoder_rms,
                ),
                (
                    "Graduation error e error, largest / ″",
                    e.before.encoder_max,
                    e.after.encoder_max,
                ),
                (
                    "Head error error, RMS / ″",
                    e.before.head_rms,
                    e.after.head_rms,
                ),
                (
                    "Head error error, largest / ″",
                    e.before.head_max,
                    e.after.head_max,
                ),
            ]
        }),
    };
    let _ = writeln!(
        out,
        "<p class=\"verdict {}\" id=\"adequacy\">The final model is {}adequate: {}.</p>",
        if adequate { "pass" } else { "fail" },
        if adequate { "" } else { "NOT " },
        if adequate {
            "its residuals are consistent with noise"
        } else {
            "structure is left that no known effect explains"
        },
    );
    out.push_str("<table id=\"checks\"><caption>Checks of the final model</caption><thead><tr><th>Check</th><th>Statistic</th><th>Limit</th><th>Passed</th></tr></thead><tbody>\n");
    for c in checks {
        let _ = writeln!(
            out,
            "<tr><td>{}</td>{}{}<td>{}</td></tr>",
            esc(&c.name),
            num(Some(c.statistic), 3),
            num(Some(c.limit), 3),
            if c.passed { "yes" } else { "no" }
        );
    }
    out.push_str("</tbody></table>\n");
    out.push_str("<table id=\"effects\"><caption>Effects found and added to the model</caption><thead><tr><th>Effect</th><th>Where</th><th>Value</th><th>u of the fit (type A)</th></tr></thead><tbody>\n");
    if effects.is_empty() {
        out.push_str("<tr><td colspan=\"4\">none</td></tr>\n");
    }
    for e in effects {
        let (kind, fields, value, u) = crate::certificate::effect_text(e);
        let _ = writeln!(
            out,
            "<tr><td>{}</td><td>{}</td>{}</tr>",
            esc(&kind),
            esc(&fields),
            // the value with its u as section 10.4 states them, as the DCC's text does
            match (value, u) {
                (Some(value), Some(u)) if u > 0.0 => rounded_pair_cells(value, u),
                _ => format!("{}{}", num(value, ARCSEC_DECIMALS), num(u, ARCSEC_DECIMALS)),
            }
        );
    }
    out.push_str("</tbody></table>\n");
    let _ = write!(
        out,
        "<table id=\"diagnosis-fit\"><thead><tr><th></th><th>Before (base model)</th><th>After (final model)</th></tr></thead><tbody>\n\
         <tr><th>Residual RMS / ″</th>{}{}</tr>\n<tr><th>Residual degrees of freedom</th><td>{}</td><td>{}</td></tr>\n",
        num(rms_before, ARCSEC_DECIMALS),
        num(rms_after, ARCSEC_DECIMALS),
        dof_before,
        dof_after
    );
    for (label, before, after) in errors {
        let _ = writeln!(
            out,
            "<tr class=\"truth\"><th>{label} (against the truth)</th>{}{}</tr>",
            num(Some(before), ARCSEC_DECIMALS),
            num(Some(after), ARCSEC_DECIMALS)
        );
    }
    out.push_str("</tbody></table>\n");
    for note in notes {
        let _ = writeln!(out, "<p class=\"note\">{}</p>", esc(note));
    }
    out.push_str("<h3>Results of the final model</h3>\n");
    if effects.is_empty() {
        // the final model is the base model: its results are the Results section's
        out.push_str(
            "<p id=\"final-model-same\">No effect was found: the final model is the base \
             model, and its results are those of the section Results above.</p>\n",
        );
        return;
    }
    match report {
        DiagnosisReport::Polygon(d) => solve_tables(out, &d.after, "final-"),
        DiagnosisReport::Selfcal(d) => selfcal_tables(out, &d.after, "final-"),
    }
}
