//! The HTML document of a [`CalibrationReport`]: numbered sections (details, method,
//! results, budget, figures, diagnosis, comparison, key comparison, history, provenance,
//! signatures), every number rounded for reading with its full-precision value in
//! `data-value` (the JSON's number), every text from a file escaped, the style inline and
//! made for A4.

use std::fmt::Write;

mod comparison;
mod diagnosis;
mod history;
mod kc;
mod tables;

use super::{CalibrationReport, DesignSummary, Evaluation};
use crate::SOFTWARE_VERSION;
use crate::figure::svg::esc;
use crate::measurement::cross_talk::StatedCrossTalk;
use crate::output::SolveReport;
use crate::output::selfcal::SelfcalReport;
use diagnosis::diagnosis_body;
use tables::{fit_summary, polygon_budget, selfcal_budget, selfcal_tables, solve_tables};

/// The style sheet: print on A4, repeated table headers, no figure split over two pages.
const STYLE: &str = include_str!("style.css");

/// What a missing field shows.
const MISSING: &str = "<span class=\"missing\">not given</span>";

/// A sequence of numbered sections.
struct Sections {
    html: String,
    count: usize,
}

impl Sections {
    fn open(&mut self, id: &str, title: &str) {
        self.count += 1;
        let _ = writeln!(
            self.html,
            "<section id=\"{id}\"><h2><span class=\"secno\">{}</span> {}</h2>",
            self.count,
            esc(title)
        );
    }
    fn close(&mut self) {
        self.html.push_str("</section>\n");
    }
}

/// The whole document.
pub fn document(report: &CalibrationReport) -> String {
    let title = report
        .metadata
        .value("title")
        .map(str::to_string)
        .unwrap_or_else(|| match report.evaluation {
            Evaluation::Polygon { .. } => {
                "Calibration of an optical polygon and a rotary encoder".to_string()
            }
            Evaluation::Selfcal { .. } => "Self-calibration of a rotary encoder".to_string(),
        });
    let mut s = Sections {
        html: String::new(),
        count: 0,
    };
    title_block(&mut s.html, report, &title);
    details(&mut s, report);
    method(&mut s, report);
    results(&mut s, report);
    budget(&mut s, report);
    figures(&mut s, report);
    diagnosis(&mut s, report);
    comparison::section(&mut s, report);
    kc::section(&mut s, report);
    history::section(&mut s, report);
    provenance(&mut s, report);
    signatures(&mut s, report);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"generator\" content=\"polycal {SOFTWARE_VERSION}\">\n\
         <title>{}</title>\n<style>\n{STYLE}{}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
        esc(&title),
        page_margins(report.metadata.value("certificate")),
        s.html
    )
}

/// A text as a CSS string literal: quotes, backslashes and line ends escaped, and `<` as
/// `\3C ` so that no `</style>` can end the style sheet.
fn css_string(text: &str) -> String {
    let mut out = String::from("\"");
    for c in text.chars() {
        match c {
            '"' | '\\' => {
                out.push('\\');
                out.push(c);
            }
            '<' => out.push_str("\\3C "),
            '\n' | '\r' | '\t' => out.push(' '),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// The printed page's margin boxes: the certificate number at the top of every page and
/// "Page x of y" at the bottom (CSS Paged Media `@page` margin boxes).
fn page_margins(certificate: Option<&str>) -> String {
    let number = certificate.map_or_else(
        || "\"Certificate number not given\"".to_string(),
        |c| css_string(&format!("Certificate {c}")),
    );
    format!(
        "@page {{ @top-right {{ content: {number}; font: 8pt sans-serif; color: #333; }} \
         @bottom-right {{ content: \"Page \" counter(page) \" of \" counter(pages); font: 8pt sans-serif; color: #333; }} }}\n"
    )
}

fn title_block(out: &mut String, report: &CalibrationReport, title: &str) {
    let field = |key: &str| report.metadata.value(key).map(esc);
    // the item calibrated: a self-calibration has no polygon, its item is the encoder
    let (item_label, item) = match report.evaluation {
        Evaluation::Polygon { .. } => ("Artefact", field("artefact")),
        Evaluation::Selfcal { .. } => ("Encoder", field("encoder")),
    };
    let _ = write!(
        out,
        "<header class=\"title-block\">\n<p class=\"lab\">{}</p>\n<h1>{}</h1>\n\
         <table class=\"ident\"><tr><th>Certificate number</th><td id=\"certificate\">{}</td>\
         <th>Date of issue</th><td id=\"date-of-issue\">{}</td></tr>\n\
         <tr><th>Customer</th><td id=\"customer\">{}</td><th>{item_label}</th><td id=\"artefact\">{}</td></tr></table>\n",
        field("laboratory").unwrap_or_else(|| MISSING.to_string()),
        esc(title),
        field("certificate").unwrap_or_else(|| MISSING.to_string()),
        field("date_of_issue").unwrap_or_else(|| MISSING.to_string()),
        field("customer").unwrap_or_else(|| MISSING.to_string()),
        item.unwrap_or_else(|| MISSING.to_string()),
    );
    if let Some(accreditation) = report.metadata.accreditation() {
        let _ = writeln!(
            out,
            "<p class=\"accreditation\" id=\"accreditation\">{}</p>",
            esc(&accreditation)
        );
    }
    let verdict = report.verdict();
    let mut checks = Vec::new();
    if let Some(d) = &report.diagnosis {
        checks.push(if d.adequate() {
            "diagnosis: the final model is adequate".to_string()
        } else {
            "diagnosis: the final model is NOT adequate".to_string()
        });
    }
    if let Some((c, _)) = &report.comparison {
        checks.push(format!("comparison: {}", c.verdict_sentence()));
    }
    if let Some(h) = &report.history {
        checks.push(format!("history: {}", h.agreement_statement()));
    }
    if !checks.is_empty() {
        let _ = writeln!(
            out,
            "<p class=\"verdict {}\" id=\"verdict\">{}</p>",
            if verdict.passed() { "pass" } else { "fail" },
            esc(&checks.join("; "))
        );
    }
    out.push_str("</header>\n");
}

fn details(s: &mut Sections, report: &CalibrationReport) {
    let m = &report.metadata;
    s.open("details", "Calibration details");
    s.html.push_str(
        "<table class=\"meta\"><thead><tr><th>Item</th><th>Value</th><th>Source</th></tr></thead><tbody>\n",
    );
    // the title, the certificate number and the customer stand in the title block; a
    // missing free-text environment is no gap when its quantities are given
    let conditions = ["temperature_c", "humidity_percent", "pressure_hpa"]
        .iter()
        .any(|k| m.value(k).is_some());
    // a self-calibration has no polygon: no artefact rows (the encoder is its item)
    let polygon = matches!(report.evaluation, Evaluation::Polygon { .. });
    let shown = |f: &&super::meta::MetaField| {
        let in_title = matches!(f.key, "title" | "certificate" | "customer");
        let no_environment = f.key == "environment" && f.value.is_none() && conditions;
        let no_polygon = !polygon && f.key.starts_with("artefact");
        !(in_title || no_environment || no_polygon)
    };
    for f in m.fields.iter().filter(shown) {
        let _ = writeln!(
            s.html,
            "<tr data-key=\"{}\"><th>{}</th><td>{}</td><td class=\"source\">{}</td></tr>",
            f.key,
            esc(f.label),
            f.value.as_deref().map_or_else(|| MISSING.to_string(), esc),
            f.source.as_deref().map(esc).unwrap_or_default()
        );
    }
    s.html.push_str("</tbody></table>\n");
    for conflict in &m.conflicts {
        let _ = writeln!(
            s.html,
            "<p class=\"note\">Two sources differ: {}</p>",
            esc(conflict)
        );
    }
    s.html.push_str("<h3>Instruments</h3>\n");
    if m.instruments.is_empty() {
        let _ = writeln!(s.html, "<p id=\"instruments\">{MISSING}</p>");
    } else {
        s.html.push_str(
            "<table id=\"instruments\"><thead><tr><th>Role</th><th>Name / identification</th><th>Model</th>\
             <th>Serial number</th><th>Calibration</th><th>Source</th></tr></thead><tbody>\n",
        );
        for i in &m.instruments {
            let cell = |v: &Option<String>| v.as_deref().map_or_else(|| MISSING.to_string(), esc);
            let _ = writeln!(
                s.html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"source\">{}</td></tr>",
                cell(&i.role),
                cell(&i.name),
                cell(&i.model),
                cell(&i.serial),
                cell(&i.calibration),
                esc(&i.source)
            );
        }
        s.html.push_str("</tbody></table>\n");
    }
    if let Some(run) = &m.run {
        let _ = write!(s.html, "<h3>The run</h3>\n<table id=\"run\"><tbody>\n");
        for (label, value) in &run.facts {
            let _ = writeln!(
                s.html,
                "<tr><th>{}</th><td>{}</td></tr>",
                esc(label),
                esc(value)
            );
        }
        let _ = write!(
            s.html,
            "</tbody></table>\n<p class=\"source\">From {}.</p>\n",
            esc(&run.source)
        );
    }
    if !m.file_notes.is_empty() {
        s.html
            .push_str("<h3>Comments in the measurement file</h3>\n<ul class=\"notes\">\n");
        for note in &m.file_notes {
            let _ = writeln!(s.html, "<li>{}</li>", esc(note));
        }
        s.html.push_str("</ul>\n");
    }
    s.close();
}

fn method(s: &mut Sections, report: &CalibrationReport) {
    s.open("method", "Method");
    if let Some(traceability) = report.metadata.value("traceability") {
        let _ = writeln!(
            s.html,
            "<p id=\"traceability\"><strong>Traceability.</strong> {}</p>",
            esc(traceability)
        );
    }
    match &report.evaluation {
        Evaluation::Polygon { solve, design, .. } => {
            polygon_method(&mut s.html, solve, design);
            stated_cross_talk(&mut s.html, &report.stated_cross_talk);
        }
        Evaluation::Selfcal { report, .. } => selfcal_method(&mut s.html, report),
    }
    s.html.push_str(
        "<p>Standard uncertainties u (k = 1) of the fit are σ·√Q<sub>jj</sub>, with σ from the \
         residuals (or stated) and Q the cofactor of the closure solution (eqs. (11)–(13)). With an \
         instrument budget, every component is propagated through the design and combined with \
         the type A part (JCGM 100, eq. (10)); the effective degrees of freedom follow \
         Welch–Satterthwaite (JCGM 100, eq. (G.2b)) and U = k·u<sub>c</sub> with k Student's t at \
         the coverage probability p. U is stated to two significant digits, rounded up, each \
         value rounded to the decimal place of its U (GUM 7.2.6), and k to three significant \
         digits. A comparison uses En = (a − b)/√(U<sub>a</sub>² + \
         U<sub>b</sub>²) (eqs. (14)–(15), ISO 13528; the paper prints a minus under the root, its \
         numbers use the plus); |En| ≤ 1 is agreement.</p>\n",
    );
    s.close();
}

fn polygon_method(out: &mut String, solve: &SolveReport, d: &DesignSummary) {
    let offsets: Vec<String> = d
        .face_offsets
        .iter()
        .map(|((setup, ac), offset)| {
            if d.setups > 1 {
                format!(
                    "mounting {setup}, autocollimator {ac}: face p+{}",
                    offset + 1
                )
            } else {
                format!("autocollimator {ac}: face p+{}", offset + 1)
            }
        })
        .collect();
    let solver = match solve.method {
        "closed-form" => "the paper's closed form, eqs. (6)–(10)".to_string(),
        _ => format!(
            "constrained least squares (engine: {}), the closed form's generalisation to this design",
            solve.engine
        ),
    };
    let _ = write!(
        out,
        "<p>Two-autocollimator closure method (Hsieh, Lin, Yeh, Watanabe, Appl. Sci. 2023, 13, 1865). \
         Each reading is modelled as (eq. (2))</p>\n<p class=\"eq\">reading = α[p mod N] + φ[face] + \
         s[setup, ac] + noise</p>\n<p>with the encoder errors α and the pitch deviations β closed \
         over a full turn: Σα = 0 (eq. (3)) and Σβ = 0 (eq. (1)); φ[f] = β[1] + … + β[f] is the face \
         deviation, φ[N] = 0. s is the setup error of each autocollimator in each mounting (the \
         paper's U; here U is only ever the expanded uncertainty).</p>\n\
         <table class=\"design\" id=\"design\"><tbody>\n\
         <tr><th>Faces N</th><td>{}</td></tr>\n<tr><th>Autocollimators (face read at step p)</th><td>{}</td></tr>\n\
         <tr><th>Cycles</th><td>{}</td></tr>\n<tr><th>Closing reading (step N)</th><td>{}</td></tr>\n\
         <tr><th>Directions</th><td>{}</td></tr>\n<tr><th>Mountings</th><td>{}</td></tr>\n\
         <tr><th>Readings</th><td>{}</td></tr>\n<tr><th>Solver</th><td>{}</td></tr>\n\
         <tr><th>Harmonics the design cannot see</th><td>{}</td></tr>\n</tbody></table>\n",
        d.faces,
        esc(&offsets.join("; ")),
        d.cycles,
        if d.closing { "yes" } else { "no" },
        if d.bidirectional {
            "clockwise and counter-clockwise"
        } else {
            "clockwise"
        },
        d.setups,
        d.readings,
        esc(&solver),
        match &solve.notes {
            // sub-pitch mountings: each coset's constant (docs/FORMAT.md §9.1)
            Some(notes) if !notes.is_empty() => esc(&notes.join(" ")),
            _ => "none: the design determines every β and α (a design that loses a Fourier \
                  harmonic is refused)"
                .to_string(),
        }
    );
}

/// The cross-talk stated from the autocollimators' calibrations (docs/FORMAT.md §6), one
/// paragraph; nothing when none is stated.
fn stated_cross_talk(out: &mut String, stated: &[StatedCrossTalk]) {
    if stated.is_empty() {
        return;
    }
    let each: Vec<String> = stated.iter().map(StatedCrossTalk::describe).collect();
    let _ = writeln!(
        out,
        "<p id=\"stated-cross-talk\">Cross-talk stated from the autocollimators' calibrations \
         (C: arcsec of reading per arcsec of reading_y); their readings are corrected to reading − \
         C·reading_y before the fit, and a stated u(C) enters the budget: {}.</p>",
        esc(&each.join("; "))
    );
}

fn selfcal_method(out: &mut String, r: &SelfcalReport) {
    let lost: Vec<String> = r.lost_harmonics.iter().map(|h| h.to_string()).collect();
    let _ = write!(
        out,
        "<p>Multi-head self-calibration: the closure model of the two-autocollimator method, with \
         the encoder's graduated disc as the artefact calibrated and its read heads in the \
         autocollimators' place. Each reading is</p>\n\
         <p class=\"eq\">reading = t[cycle, step] + e(step·360°/P + head angle) + c[head] + noise</p>\n\
         <p>with t the table's error at each stop (a nuisance), e the disc's graduation error (Σe = 0) \
         and c the heads' placement errors (c[1] = 0).</p>\n<table class=\"design\" id=\"design\"><tbody>\n\
         <tr><th>Positions P</th><td>{}</td></tr>\n<tr><th>Heads</th><td>{}</td></tr>\n\
         <tr><th>Cycles</th><td>{}</td></tr>\n<tr><th>Readings</th><td>{}</td></tr>\n\
         <tr><th>Head layout</th><td>{} (engine: {})</td></tr>\n\
         <tr><th>Harmonics the design cannot see (set to 0)</th><td id=\"lost-harmonics\">{}</td></tr>\n</tbody></table>\n",
        r.positions,
        r.heads,
        r.cycles,
        r.readings,
        r.head_grid,
        r.engine,
        if lost.is_empty() {
            "none".to_string()
        } else {
            esc(&lost.join(", "))
        }
    );
    for note in &r.notes {
        let _ = writeln!(out, "<p class=\"note\">{}</p>", esc(note));
    }
}

fn results(s: &mut Sections, report: &CalibrationReport) {
    s.open("results", "Results");
    // ISO/IEC 17025 7.8.2.1 o)
    let _ = writeln!(
        s.html,
        "<p id=\"results-relate\">{}</p>",
        esc(&report.results_relate_statement())
    );
    match &report.evaluation {
        Evaluation::Polygon { solve, .. } => {
            fit_summary(
                &mut s.html,
                solve.readings,
                solve.dof,
                solve.residual_rms,
                solve.sigma,
                solve.sigma_source,
                solve.p,
            );
            if solve.p.is_none() {
                s.html.push_str(
                    "<p class=\"note\">No instrument budget was given: u is the fit's type A \
                     uncertainty alone, and U and k are not stated.</p>\n",
                );
            }
            solve_tables(&mut s.html, solve, "");
        }
        Evaluation::Selfcal { report: r, .. } => {
            fit_summary(
                &mut s.html,
                r.readings,
                r.dof,
                r.residual_rms,
                r.sigma,
                r.sigma_source,
                Some(r.p),
            );
            selfcal_tables(&mut s.html, r, "");
        }
    }
    s.close();
}

fn budget(s: &mut Sections, report: &CalibrationReport) {
    match &report.evaluation {
        Evaluation::Polygon {
            uncertainty: Some(u),
            ..
        } => {
            s.open("budget", "Uncertainty budget");
            let _ = writeln!(
                s.html,
                "<p>Budget {} (p = {}, degrees-of-freedom policy {}). Each component's \
                 contribution is |c|·u propagated through the design to the quantity; its index \
                 is its share of u<sub>c</sub>².</p>",
                esc(&u.budget),
                u.p,
                esc(u.dof_policy.as_str())
            );
            polygon_budget(
                &mut s.html,
                u,
                ("Pitch deviations β", "budget-pitch-deviation", "β", 1),
                &u.pitch_deviation,
                |c, j| c.pitch_deviation[j],
            );
            polygon_budget(
                &mut s.html,
                u,
                ("Encoder errors α", "budget-encoder-error", "α", 0),
                &u.encoder_error,
                |c, j| c.encoder_error[j],
            );
            s.close();
        }
        Evaluation::Selfcal {
            report: r,
            uncertainty: Some(u),
        } => {
            s.open("budget", "Uncertainty budget");
            let _ = writeln!(
                s.html,
                "<p>Budget {} (p = {}, degrees-of-freedom policy {}). Each component's \
                 contribution is propagated through the head layout to the quantity; its index \
                 is its share of u<sub>c</sub>².</p>",
                esc(&u.budget),
                u.p,
                esc(u.dof_policy.as_str())
            );
            selfcal_budget(
                &mut s.html,
                u,
                ("Graduation errors e", "budget-encoder-error"),
                &u.encoder_error,
                |c, j| c.encoder_error[j],
                |j| {
                    r.encoder_angle_deg
                        .get(j)
                        .map_or_else(String::new, |a| format!("e at {a}°"))
                },
            );
            selfcal_budget(
                &mut s.html,
                u,
                ("Head errors c", "budget-head-error"),
                &u.head_error,
                |c, j| c.head_error[j],
                |j| {
                    r.head_error
                        .get(j)
                        .map_or_else(String::new, |h| format!("c[{}]", h.head))
                },
            );
            s.close();
        }
        _ => {}
    }
}

fn figures(s: &mut Sections, report: &CalibrationReport) {
    if report.figures.is_empty() {
        return;
    }
    s.open("figures", "Figures");
    for (i, f) in report.figures.iter().enumerate() {
        let _ = write!(
            s.html,
            "<figure id=\"figure-{}\">\n{}\n<figcaption>Figure {} — {}</figcaption>\n</figure>\n",
            esc(&f.name),
            f.svg,
            i + 1,
            esc(&f.title)
        );
    }
    s.close();
}

fn diagnosis(s: &mut Sections, report: &CalibrationReport) {
    let Some(d) = &report.diagnosis else { return };
    s.open("diagnosis", "Diagnosis of unmodelled effects");
    diagnosis_body(&mut s.html, d);
    s.close();
}

fn provenance(s: &mut Sections, report: &CalibrationReport) {
    s.open("provenance", "Provenance");
    let _ = write!(
        s.html,
        "<p>Evaluated by polycal {SOFTWARE_VERSION} on <span id=\"generated\">{}</span> (UTC). The input files are identified by \
         their SHA-256.</p>\n<table id=\"inputs\"><thead><tr><th>Input</th><th>File</th>\
         <th>Bytes</th><th>SHA-256</th></tr></thead><tbody>\n",
        esc(&report.generated_utc)
    );
    for f in &report.inputs {
        let _ = writeln!(
            s.html,
            "<tr><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"hash\">{}</td></tr>",
            f.role,
            esc(&f.path),
            f.bytes,
            f.sha256
        );
    }
    s.html.push_str("</tbody></table>\n");
    if let Some(command) = &report.command_line {
        let _ = writeln!(
            s.html,
            "<p>Command: <code id=\"command\">{}</code></p>",
            esc(command)
        );
    }
    s.close();
}

fn signatures(s: &mut Sections, report: &CalibrationReport) {
    let m = &report.metadata;
    let _ = writeln!(
        s.html,
        "<section id=\"signatures\" class=\"signatures\"><div><p class=\"sigline\"></p><p>Prepared by: {}</p></div>\
         <div><p class=\"sigline\"></p><p>Approved by: {}</p></div></section>",
        m.value("operator").map_or_else(|| MISSING.to_string(), esc),
        m.value("approved_by")
            .map_or_else(|| MISSING.to_string(), esc),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A certificate number with CSS's and HTML's specials stays one string of the style
    /// sheet: quotes and backslashes escaped, `<` as `\3C ` (no `</style>`), line ends as
    /// spaces.
    #[test]
    fn the_certificate_number_is_one_css_string() {
        assert_eq!(
            css_string("A\"B\\C</style>\nD"),
            "\"A\\\"B\\\\C\\3C /style> D\""
        );
        let margins = page_margins(Some("K-1"));
        assert!(margins.contains("@top-right { content: \"Certificate K-1\";"));
        assert!(margins.contains("\"Page \" counter(page) \" of \" counter(pages)"));
        assert!(page_margins(None).contains("\"Certificate number not given\""));
    }
}
