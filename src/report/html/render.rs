//! The HTML document of a [`CalibrationReport`]: numbered sections (details, method,
//! results, budget, figures, diagnosis, comparison, provenance, signatures), every
//! number rounded for reading with its full-precision value in `data-value` (the JSON's
//! number), every text from a file escaped, the style inline and made for A4.

use std::fmt::Write;

use serde_json::Value;

use super::{CalibrationReport, DesignSummary, Evaluation};
use crate::figure::svg::esc;
use crate::report::SOFTWARE_VERSION;
use crate::report::SolveReport;
use crate::report::diagnose::DiagnoseReport;
use crate::report::selfcal::SelfcalReport;
use crate::uncertainty::calibration::{CalibrationUncertainty, FamilyUncertainty};

/// The style sheet: print on A4, repeated table headers, no figure split over two pages.
const STYLE: &str = include_str!("style.css");

/// Decimals of values and uncertainties in arcseconds.
const ARCSEC_DECIMALS: usize = 4;

/// What a missing field shows.
const MISSING: &str = "<span class=\"missing\">not given</span>";

/// A number rounded to `decimals`, with a true minus sign.
pub fn rounded(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    // "-0.0000" is zero
    if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        return text.trim_start_matches('-').to_string();
    }
    text.replace('-', "−")
}

/// A table cell of a number: rounded text, full precision in `data-value`; `—` for none.
fn num(value: Option<f64>, decimals: usize) -> String {
    match value.filter(|v| v.is_finite()) {
        Some(v) => format!(
            "<td class=\"num\" data-value=\"{v}\">{}</td>",
            rounded(v, decimals)
        ),
        None => "<td class=\"num none\">—</td>".to_string(),
    }
}

/// A sequence of numbered sections.
struct Sections {
    html: String,
    count: usize,
}

impl Sections {
    fn open(&mut self, id: &str, title: &str) {
        self.count += 1;
        let _ = write!(
            self.html,
            "<section id=\"{id}\"><h2><span class=\"secno\">{}</span> {}</h2>\n",
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
    comparison(&mut s, report);
    provenance(&mut s, report);
    signatures(&mut s, report);
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <meta name=\"generator\" content=\"polycal {SOFTWARE_VERSION}\">\n\
         <title>{}</title>\n<style>\n{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
        esc(&title),
        s.html
    )
}

fn title_block(out: &mut String, report: &CalibrationReport, title: &str) {
    let field = |key: &str| report.metadata.value(key).map(esc);
    let _ = write!(
        out,
        "<header class=\"title-block\">\n<p class=\"lab\">{}</p>\n<h1>{}</h1>\n\
         <table class=\"ident\"><tr><th>Certificate number</th><td id=\"certificate\">{}</td>\
         <th>Date of report (UTC)</th><td id=\"generated\">{}</td></tr>\n\
         <tr><th>Customer</th><td id=\"customer\">{}</td><th>Artefact</th><td id=\"artefact\">{}</td></tr></table>\n",
        field("laboratory").unwrap_or_else(|| MISSING.to_string()),
        esc(title),
        field("certificate").unwrap_or_else(|| MISSING.to_string()),
        esc(&report.generated_utc),
        field("customer").unwrap_or_else(|| MISSING.to_string()),
        field("artefact").unwrap_or_else(|| MISSING.to_string()),
    );
    let verdict = report.verdict();
    let mut checks = Vec::new();
    if let Some(d) = &report.diagnosis {
        checks.push(if d.adequate {
            "diagnosis: the final model is adequate".to_string()
        } else {
            "diagnosis: the final model is NOT adequate".to_string()
        });
    }
    if let Some((c, _)) = &report.comparison {
        checks.push(format!(
            "comparison: {} (largest |En| {})",
            if c.verdict_ok() {
                "agrees, every |En| ≤ 1"
            } else {
                "FAILS, some |En| > 1"
            },
            rounded(c.max_abs_en, 2)
        ));
    }
    if !checks.is_empty() {
        let _ = write!(
            out,
            "<p class=\"verdict {}\" id=\"verdict\">{}</p>\n",
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
    for f in m.fields.iter().filter(|f| f.key != "title") {
        let _ = write!(
            s.html,
            "<tr data-key=\"{}\"><th>{}</th><td>{}</td><td class=\"source\">{}</td></tr>\n",
            f.key,
            esc(f.label),
            f.value.as_deref().map_or_else(|| MISSING.to_string(), esc),
            f.source.as_deref().map(esc).unwrap_or_default()
        );
    }
    s.html.push_str("</tbody></table>\n");
    for conflict in &m.conflicts {
        let _ = write!(
            s.html,
            "<p class=\"note\">Two sources differ: {}</p>\n",
            esc(conflict)
        );
    }
    s.html.push_str("<h3>Instruments</h3>\n");
    if m.instruments.is_empty() {
        let _ = write!(s.html, "<p id=\"instruments\">{MISSING}</p>\n");
    } else {
        s.html.push_str(
            "<table id=\"instruments\"><thead><tr><th>Role</th><th>Name / identification</th><th>Model</th>\
             <th>Serial number</th><th>Calibration</th><th>Source</th></tr></thead><tbody>\n",
        );
        for i in &m.instruments {
            let cell = |v: &Option<String>| v.as_deref().map_or_else(|| MISSING.to_string(), esc);
            let _ = write!(
                s.html,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td class=\"source\">{}</td></tr>\n",
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
            let _ = write!(
                s.html,
                "<tr><th>{}</th><td>{}</td></tr>\n",
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
            let _ = write!(s.html, "<li>{}</li>\n", esc(note));
        }
        s.html.push_str("</ul>\n");
    }
    s.close();
}

fn method(s: &mut Sections, report: &CalibrationReport) {
    s.open("method", "Method");
    match &report.evaluation {
        Evaluation::Polygon { solve, design, .. } => polygon_method(&mut s.html, solve, design),
        Evaluation::Selfcal { report } => selfcal_method(&mut s.html, report),
    }
    s.html.push_str(
        "<p>Standard uncertainties u (k = 1) of the fit are σ·√Q<sub>jj</sub>, with σ from the \
         residuals (or stated) and Q the cofactor of the closure solution (eqs. (11)–(13)). With an \
         instrument budget, every component is propagated through the design and combined with \
         the type A part (JCGM 100, eq. (10)); the effective degrees of freedom follow \
         Welch–Satterthwaite (JCGM 100, eq. (G.2b)) and U = k·u<sub>c</sub> with k Student's t at \
         the coverage probability p. A comparison uses En = (a − b)/√(U<sub>a</sub>² + \
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
         U[setup, ac] + noise</p>\n<p>with the encoder errors α and the pitch deviations β closed \
         over a full turn: Σα = 0 (eq. (3)) and Σβ = 0 (eq. (1)); φ[f] = β[1] + … + β[f] is the face \
         deviation, φ[N] = 0. U is the setup error of each autocollimator in each mounting.</p>\n\
         <table class=\"design\" id=\"design\"><tbody>\n\
         <tr><th>Faces N</th><td>{}</td></tr>\n<tr><th>Autocollimators (face read at step p)</th><td>{}</td></tr>\n\
         <tr><th>Cycles</th><td>{}</td></tr>\n<tr><th>Closing reading (step N)</th><td>{}</td></tr>\n\
         <tr><th>Directions</th><td>{}</td></tr>\n<tr><th>Mountings</th><td>{}</td></tr>\n\
         <tr><th>Readings</th><td>{}</td></tr>\n<tr><th>Solver</th><td>{}</td></tr>\n\
         <tr><th>Harmonics the design cannot see</th><td>none: the design determines every β and α \
         (a design that loses a Fourier harmonic is refused)</td></tr>\n</tbody></table>\n",
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
        esc(&solver)
    );
}

fn selfcal_method(out: &mut String, r: &SelfcalReport) {
    let lost: Vec<String> = r.lost_harmonics.iter().map(|h| h.to_string()).collect();
    let _ = write!(
        out,
        "<p>Multi-head self-calibration: the closure model with the graduated disc in the polygon's \
         place and the read heads in the autocollimators' place. Each reading is</p>\n\
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
        let _ = write!(out, "<p class=\"note\">{}</p>\n", esc(note));
    }
}

/// One family's table: index (and angle) columns, value, u, U, k.
struct FamilyTable<'a> {
    id: &'a str,
    caption: &'a str,
    index_header: &'a str,
    indices: Vec<String>,
    angles_deg: Option<&'a [f64]>,
    values: &'a [f64],
    u: Option<&'a [f64]>,
    expanded_u: Option<&'a [f64]>,
    k: Option<Vec<Option<f64>>>,
}

fn family_table(out: &mut String, t: &FamilyTable) {
    let _ = write!(
        out,
        "<table class=\"results\" id=\"{}\"><caption>{}</caption><thead><tr><th>{}</th>{}\
         <th>value / ″</th><th>u / ″</th><th>U / ″</th><th>k</th></tr></thead><tbody>\n",
        t.id,
        esc(t.caption),
        esc(t.index_header),
        if t.angles_deg.is_some() {
            "<th>angle / °</th>"
        } else {
            ""
        }
    );
    for (i, value) in t.values.iter().enumerate() {
        let _ = write!(
            out,
            "<tr><td>{}</td>{}{}{}{}{}</tr>\n",
            t.indices.get(i).map_or("", String::as_str),
            t.angles_deg
                .map_or(String::new(), |a| num(a.get(i).copied(), 3)),
            num(Some(*value), ARCSEC_DECIMALS),
            num(t.u.and_then(|u| u.get(i).copied()), ARCSEC_DECIMALS),
            num(
                t.expanded_u.and_then(|u| u.get(i).copied()),
                ARCSEC_DECIMALS
            ),
            num(t.k.as_ref().and_then(|k| k.get(i).copied().flatten()), 2),
        );
    }
    out.push_str("</tbody></table>\n");
}

/// The result tables of a `solve` object (the report's results, and the diagnosis's final
/// model); `prefix` makes the ids unique.
pub(crate) fn solve_tables(out: &mut String, r: &SolveReport, prefix: &str) {
    let n = r.faces;
    let faces: Vec<String> = (1..=n).map(|k| k.to_string()).collect();
    let id = |name: &str| format!("{prefix}{name}");
    let angles: Vec<f64> = match &r.encoder_angle_deg {
        Some(a) => a.clone(),
        None => (0..r.encoder_error.len())
            .map(|p| crate::measurement::step_angle_deg(p as u32, r.encoder_error.len()))
            .collect(),
    };
    family_table(
        out,
        &FamilyTable {
            id: &id("pitch-deviation"),
            caption: "Pitch deviations β",
            index_header: "face k",
            indices: faces.clone(),
            angles_deg: None,
            values: &r.pitch_deviation,
            u: r.pitch_deviation_u.as_deref(),
            expanded_u: r.pitch_deviation_expanded_u.as_deref(),
            k: r.pitch_deviation_k.clone(),
        },
    );
    family_table(
        out,
        &FamilyTable {
            id: &id("face-deviation"),
            caption: "Face deviations φ (φ[N] = 0 by definition)",
            index_header: "face k",
            indices: faces,
            angles_deg: None,
            values: &r.face_deviation,
            u: r.face_deviation_u.as_deref(),
            expanded_u: r.face_deviation_expanded_u.as_deref(),
            k: r.face_deviation_k.clone(),
        },
    );
    family_table(
        out,
        &FamilyTable {
            id: &id("encoder-error"),
            caption: "Encoder errors α",
            index_header: "position p",
            indices: (0..r.encoder_error.len()).map(|p| p.to_string()).collect(),
            angles_deg: Some(&angles),
            values: &r.encoder_error,
            u: r.encoder_error_u.as_deref(),
            expanded_u: r.encoder_error_expanded_u.as_deref(),
            k: r.encoder_error_k.clone(),
        },
    );
    let setup_values: Vec<f64> = r.setup_error.iter().map(|s| s.value).collect();
    let setup_u: Option<Vec<f64>> = r.setup_error.iter().map(|s| s.u).collect();
    let setup_expanded: Option<Vec<f64>> = r.setup_error.iter().map(|s| s.expanded_u).collect();
    family_table(
        out,
        &FamilyTable {
            id: &id("setup-error"),
            caption: "Setup errors U (they depend on the mounting)",
            index_header: "mounting / autocollimator",
            indices: r
                .setup_error
                .iter()
                .map(|s| format!("{} / {}", s.setup, s.ac))
                .collect(),
            angles_deg: None,
            values: &setup_values,
            u: setup_u.as_deref(),
            expanded_u: setup_expanded.as_deref(),
            k: Some(r.setup_error.iter().map(|s| s.k).collect()),
        },
    );
}

fn fit_summary(
    out: &mut String,
    readings: usize,
    dof: usize,
    rms: Option<f64>,
    sigma: Option<f64>,
    source: Option<&str>,
    p: Option<f64>,
) {
    let _ = write!(
        out,
        "<table class=\"summary\" id=\"fit\"><tbody>\n<tr><th>Readings</th><td>{readings}</td>\
         <th>Residual degrees of freedom</th><td>{dof}</td></tr>\n\
         <tr><th>Residual RMS / ″</th>{}<th>σ of one reading / ″</th>{}</tr>\n\
         <tr><th>σ from</th><td>{}</td><th>Coverage probability p</th>{}</tr>\n</tbody></table>\n",
        num(rms, ARCSEC_DECIMALS),
        num(sigma, ARCSEC_DECIMALS),
        source.unwrap_or("—"),
        num(p, 2),
    );
}

fn results(s: &mut Sections, report: &CalibrationReport) {
    s.open("results", "Results");
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
        Evaluation::Selfcal { report: r } => {
            fit_summary(
                &mut s.html,
                r.readings,
                r.dof,
                r.residual_rms,
                r.sigma,
                r.sigma_source,
                Some(r.p),
            );
            family_table(
                &mut s.html,
                &FamilyTable {
                    id: "encoder-error",
                    caption: "Graduation errors e of the disc",
                    index_header: "position",
                    indices: (0..r.encoder_error.len()).map(|p| p.to_string()).collect(),
                    angles_deg: Some(&r.encoder_angle_deg),
                    values: &r.encoder_error,
                    u: r.encoder_error_u.as_deref(),
                    expanded_u: r.encoder_error_expanded_u.as_deref(),
                    k: r.encoder_error_k
                        .as_ref()
                        .map(|k| k.iter().map(|v| Some(*v)).collect()),
                },
            );
            let values: Vec<f64> = r.head_error.iter().map(|h| h.value).collect();
            let angles: Vec<f64> = r.head_error.iter().map(|h| h.angle_deg).collect();
            let u: Option<Vec<f64>> = r.head_error.iter().map(|h| h.u).collect();
            let expanded: Option<Vec<f64>> = r.head_error.iter().map(|h| h.expanded_u).collect();
            family_table(
                &mut s.html,
                &FamilyTable {
                    id: "head-error",
                    caption: "Head placement errors c (head 1 is the reference)",
                    index_header: "head",
                    indices: r.head_error.iter().map(|h| h.head.to_string()).collect(),
                    angles_deg: Some(&angles),
                    values: &values,
                    u: u.as_deref(),
                    expanded_u: expanded.as_deref(),
                    k: Some(r.head_error.iter().map(|h| h.k).collect()),
                },
            );
        }
    }
    s.close();
}

/// The index of the largest U of a family (its first, when none is larger).
fn largest(family: &FamilyUncertainty) -> Option<usize> {
    (0..family.expanded_u.len())
        .filter(|&i| family.expanded_u[i].is_finite())
        .max_by(|&a, &b| family.expanded_u[a].total_cmp(&family.expanded_u[b]))
}

fn budget_table(
    out: &mut String,
    u: &CalibrationUncertainty,
    name: &str,
    id: &str,
    family: &FamilyUncertainty,
    contribution: impl Fn(&crate::uncertainty::calibration::ComponentContribution) -> f64,
    index_label: &str,
) {
    let Some(j) = largest(family) else { return };
    let uc = family.u[j];
    let share = |c: f64| {
        if uc > 0.0 {
            Some(100.0 * c * c / (uc * uc))
        } else {
            None
        }
    };
    let _ = write!(
        out,
        "<table class=\"budget\" id=\"{id}\"><caption>{} — the quantity with the largest U: {}</caption>\
         <thead><tr><th>Component</th><th>Type</th><th>Distribution</th><th>Acts on</th>\
         <th>u / ″</th><th>Sensitivity</th><th>ν</th><th>Contribution / ″</th><th>Index / %</th></tr></thead><tbody>\n",
        esc(name),
        esc(index_label.replace("{j}", &j.to_string()).as_str()),
    );
    let _ = write!(
        out,
        "<tr><td>type A of the fit (σ·√Q)</td><td>A</td><td>normal</td><td>—</td>{}<td class=\"num\">1</td>{}{}{}</tr>\n",
        num(Some(family.u_a[j]), ARCSEC_DECIMALS),
        num(u.type_a_dof, 0),
        num(Some(family.u_a[j]), ARCSEC_DECIMALS),
        num(share(family.u_a[j]), 1),
    );
    for c in &u.components {
        let value = contribution(c);
        let _ = write!(
            out,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td>{}{}{}{}{}</tr>\n",
            esc(&c.name),
            c.evaluation,
            esc(c.distribution),
            esc(c.acts_on.as_str()),
            num(Some(c.u), ARCSEC_DECIMALS),
            num(Some(c.sensitivity), 3),
            num(c.dof, 0),
            num(Some(value), ARCSEC_DECIMALS),
            num(share(value), 1),
        );
    }
    let _ = write!(
        out,
        "</tbody><tfoot><tr><th colspan=\"4\">Combined standard uncertainty u<sub>c</sub>; ν<sub>eff</sub>; k; U</th>\
         {}<td></td>{}<td class=\"num\">k = {}</td><td class=\"num\" data-value=\"{}\">U = {}</td></tr></tfoot></table>\n",
        num(Some(uc), ARCSEC_DECIMALS),
        num(family.dof_eff[j], 1),
        family.k[j].map_or("—".to_string(), |k| rounded(k, 2)),
        family.expanded_u[j],
        rounded(family.expanded_u[j], ARCSEC_DECIMALS),
    );
}

fn budget(s: &mut Sections, report: &CalibrationReport) {
    match &report.evaluation {
        Evaluation::Polygon {
            uncertainty: Some(u),
            ..
        } => {
            s.open("budget", "Uncertainty budget");
            let _ = write!(
                s.html,
                "<p>Budget {} (p = {}, degrees-of-freedom policy {}). Each component's \
                 contribution is |c|·u propagated through the design to the quantity; its index \
                 is its share of u<sub>c</sub>².</p>\n",
                esc(&u.budget),
                u.p,
                esc(u.dof_policy.as_str())
            );
            budget_table(
                &mut s.html,
                u,
                "Pitch deviations β",
                "budget-pitch-deviation",
                &u.pitch_deviation,
                |c| c.pitch_deviation[largest(&u.pitch_deviation).unwrap_or(0)],
                "β[{j}+1]",
            );
            budget_table(
                &mut s.html,
                u,
                "Encoder errors α",
                "budget-encoder-error",
                &u.encoder_error,
                |c| c.encoder_error[largest(&u.encoder_error).unwrap_or(0)],
                "α[{j}]",
            );
            s.close();
        }
        Evaluation::Selfcal { report: r } if r.encoder_error_expanded_u.is_some() => {
            s.open("budget", "Uncertainty");
            let _ = write!(
                s.html,
                "<p>U = k·u of every graduation error is given in the results (p = {}); k is \
                 Student's t for the Welch–Satterthwaite degrees of freedom of each value.</p>\n",
                r.p
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

/// An effect of the diagnosis JSON as text: its kind and fields.
fn effect_text(effect: &Value) -> (String, String, Option<f64>, Option<f64>) {
    let kind = effect
        .get("kind")
        .and_then(Value::as_str)
        .unwrap_or("effect")
        .to_string();
    let fields: Vec<String> = effect
        .as_object()
        .map(|o| {
            o.iter()
                .filter(|(k, _)| !matches!(k.as_str(), "kind" | "value" | "u"))
                .map(|(k, v)| format!("{k} {v}"))
                .collect()
        })
        .unwrap_or_default();
    (
        kind,
        fields.join(", "),
        effect.get("value").and_then(Value::as_f64),
        effect.get("u").and_then(Value::as_f64),
    )
}

fn diagnosis(s: &mut Sections, report: &CalibrationReport) {
    let Some(d) = &report.diagnosis else { return };
    s.open("diagnosis", "Diagnosis of unmodelled effects");
    diagnosis_body(&mut s.html, d);
    s.close();
}

fn diagnosis_body(out: &mut String, d: &DiagnoseReport) {
    let _ = write!(
        out,
        "<p class=\"verdict {}\" id=\"adequacy\">The final model is {}adequate: {}.</p>\n",
        if d.adequate { "pass" } else { "fail" },
        if d.adequate { "" } else { "NOT " },
        if d.adequate {
            "its residuals are consistent with noise"
        } else {
            "structure is left that no known effect explains"
        },
    );
    out.push_str("<table id=\"checks\"><caption>Checks of the final model</caption><thead><tr><th>Check</th><th>Statistic</th><th>Limit</th><th>Passed</th></tr></thead><tbody>\n");
    for c in &d.checks {
        let _ = write!(
            out,
            "<tr><td>{}</td>{}{}<td>{}</td></tr>\n",
            esc(&c.name),
            num(Some(c.statistic), 3),
            num(Some(c.limit), 3),
            if c.passed { "yes" } else { "no" }
        );
    }
    out.push_str("</tbody></table>\n");
    out.push_str("<table id=\"effects\"><caption>Effects found and added to the model</caption><thead><tr><th>Effect</th><th>Where</th><th>Value</th><th>u</th></tr></thead><tbody>\n");
    if d.effects.is_empty() {
        out.push_str("<tr><td colspan=\"4\">none</td></tr>\n");
    }
    for e in &d.effects {
        let (kind, fields, value, u) = effect_text(e);
        let _ = write!(
            out,
            "<tr><td>{}</td><td>{}</td>{}{}</tr>\n",
            esc(&kind),
            esc(&fields),
            num(value, ARCSEC_DECIMALS),
            num(u, ARCSEC_DECIMALS)
        );
    }
    out.push_str("</tbody></table>\n");
    let _ = write!(
        out,
        "<table id=\"diagnosis-fit\"><thead><tr><th></th><th>Before (base model)</th><th>After (final model)</th></tr></thead><tbody>\n\
         <tr><th>Residual RMS / ″</th>{}{}</tr>\n<tr><th>Residual degrees of freedom</th><td>{}</td><td>{}</td></tr>\n",
        num(d.before.residual_rms, ARCSEC_DECIMALS),
        num(d.after.residual_rms, ARCSEC_DECIMALS),
        d.before.dof,
        d.after.dof
    );
    if let Some(e) = &d.error {
        for (label, before, after) in [
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
        ] {
            let _ = write!(
                out,
                "<tr class=\"truth\"><th>{label} (against the truth)</th>{}{}</tr>\n",
                num(Some(before), ARCSEC_DECIMALS),
                num(Some(after), ARCSEC_DECIMALS)
            );
        }
    }
    out.push_str("</tbody></table>\n");
    for note in &d.notes {
        let _ = write!(out, "<p class=\"note\">{}</p>\n", esc(note));
    }
    out.push_str("<h3>Results of the final model</h3>\n");
    solve_tables(out, &d.after, "final-");
}

fn comparison(s: &mut Sections, report: &CalibrationReport) {
    let Some((c, reference)) = &report.comparison else {
        return;
    };
    s.open("comparison", "Comparison with a reference");
    let _ = write!(
        s.html,
        "<p>a: this calibration; b: {}. Encoder errors matched by {}. Setup errors are {}.</p>\n\
         <p class=\"verdict {}\" id=\"comparison-verdict\">{} — largest |En| = {}.</p>\n",
        esc(reference),
        match c.encoder_matched_by {
            crate::compare::EncoderMatching::Angle => "angle",
            _ => "index",
        },
        "listed but left out of the verdict",
        if c.verdict_ok() { "pass" } else { "fail" },
        if c.verdict_ok() {
            "The results agree: every |En| ≤ 1"
        } else {
            "The results do NOT agree: some |En| > 1"
        },
        rounded(c.max_abs_en, 2)
    );
    s.html.push_str(
        "<table class=\"comparison\" id=\"comparison-rows\"><thead><tr><th>Quantity</th><th>Index</th>\
         <th>angle / °</th><th>a / ″</th><th>b / ″</th><th>a − b / ″</th><th>U<sub>a</sub> / ″</th>\
         <th>U<sub>b</sub> / ″</th><th>En</th></tr></thead><tbody>\n",
    );
    for r in &c.rows {
        let class = if !r.in_verdict {
            " class=\"out-of-verdict\""
        } else if r.en.abs() > 1.0 {
            " class=\"fail\""
        } else {
            ""
        };
        let _ = write!(
            s.html,
            "<tr{class}><td>{}</td><td>{}</td>{}{}{}{}{}{}{}</tr>\n",
            r.quantity.name(),
            r.index,
            num(r.angle_deg, 3),
            num(Some(r.a), ARCSEC_DECIMALS),
            num(Some(r.b), ARCSEC_DECIMALS),
            num(Some(r.difference), ARCSEC_DECIMALS),
            num(Some(r.expanded_u_a), ARCSEC_DECIMALS),
            num(Some(r.expanded_u_b), ARCSEC_DECIMALS),
            num(Some(r.en), 2),
        );
    }
    s.html.push_str("</tbody></table>\n");
    s.close();
}

fn provenance(s: &mut Sections, report: &CalibrationReport) {
    s.open("provenance", "Provenance");
    let _ = write!(
        s.html,
        "<p>Evaluated by polycal {SOFTWARE_VERSION} on {} (UTC). The input files are identified by \
         their SHA-256.</p>\n<table id=\"inputs\"><thead><tr><th>Input</th><th>File</th>\
         <th>Bytes</th><th>SHA-256</th></tr></thead><tbody>\n",
        esc(&report.generated_utc)
    );
    for f in &report.inputs {
        let _ = write!(
            s.html,
            "<tr><td>{}</td><td>{}</td><td class=\"num\">{}</td><td class=\"hash\">{}</td></tr>\n",
            f.role,
            esc(&f.path),
            f.bytes,
            f.sha256
        );
    }
    s.html.push_str("</tbody></table>\n");
    if let Some(command) = &report.command_line {
        let _ = write!(
            s.html,
            "<p>Command: <code id=\"command\">{}</code></p>\n",
            esc(command)
        );
    }
    s.close();
}

fn signatures(s: &mut Sections, report: &CalibrationReport) {
    let m = &report.metadata;
    let _ = write!(
        s.html,
        "<section id=\"signatures\" class=\"signatures\"><div><p class=\"sigline\"></p><p>Prepared by: {}</p></div>\
         <div><p class=\"sigline\"></p><p>Approved by: {}</p></div></section>\n",
        m.value("operator").map_or_else(|| MISSING.to_string(), esc),
        m.value("approved_by")
            .map_or_else(|| MISSING.to_string(), esc),
    );
}
