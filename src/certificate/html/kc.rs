//! The key comparison section of the HTML report (`report --kc`, docs/FORMAT.md §10.2):
//! the formulas by name, the reference per quantity with its u and χ² test, the closed
//! vector's test, the exclusions with their reasons, the degrees of equivalence (the named
//! laboratory's, or every laboratory's), the pilot's stability and the comparison's notes;
//! every number through the report's one cell ([`num`]) with the JSON's value in
//! `data-value`.

use std::fmt::Write;

use super::Sections;
use super::tables::{ARCSEC_DECIMALS, num, rounded_pair_cells};
use crate::certificate::{CalibrationReport, KeyComparisonSection};
use crate::figure::svg::esc;
use crate::kc::{KeyComparison, ReferenceMethod};
use crate::results::Quantity;

/// Decimals of χ² values.
const CHI2_DECIMALS: usize = 2;

/// Decimals of table angles, degrees (as the comparison table's).
const ANGLE_DECIMALS: usize = 3;

/// The section, when the report has a key comparison.
pub(super) fn section(s: &mut Sections, report: &CalibrationReport) {
    let Some(section) = &report.key_comparison else {
        return;
    };
    let kc = &section.comparison;
    s.open("key-comparison", "Key comparison");
    introduction(&mut s.html, section);
    formulas(&mut s.html, kc);
    reference_table(&mut s.html, kc);
    vector(&mut s.html, kc);
    exclusions(&mut s.html, kc);
    degrees_of_equivalence(&mut s.html, section);
    pilot(&mut s.html, kc);
    if !kc.notes.is_empty() {
        s.html.push_str("<ul class=\"notes\" id=\"kc-notes\">\n");
        for note in &kc.notes {
            let _ = writeln!(s.html, "<li>{}</li>", esc(note));
        }
        s.html.push_str("</ul>\n");
    }
    let failing = kc.consistent.iter().filter(|c| !**c).count();
    let _ = writeln!(
        s.html,
        "<p class=\"verdict {}\" id=\"kc-verdict\">{}</p>",
        if kc.comparison_consistent {
            "pass"
        } else {
            "fail"
        },
        esc(&if kc.comparison_consistent {
            format!(
                "Consistent after the exclusions stated: every {} passes its χ² test{}.",
                quantity_word(kc.quantity),
                if kc.vector.is_some() {
                    ", and so does the closed vector"
                } else {
                    ""
                }
            )
        } else {
            format!(
                "NOT consistent: {failing} of {} fail their χ² test{}.",
                kc.index.len(),
                match &kc.vector {
                    Some(v) if !v.consistent => ", and the closed vector fails its test",
                    _ => "",
                }
            )
        })
    );
    s.close();
}

/// The compared quantity in words, singular.
fn quantity_word(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::PitchDeviation => "pitch deviation β",
        Quantity::EncoderError => "encoder error α",
        Quantity::FaceDeviation => "face deviation φ",
        Quantity::SetupError => "setup error",
    }
}

/// The compared quantity in words, plural.
fn quantity_plural(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::PitchDeviation => "pitch deviations β",
        Quantity::EncoderError => "encoder errors α",
        Quantity::FaceDeviation => "face deviations φ",
        Quantity::SetupError => "setup errors",
    }
}

/// The header of the position column.
fn position_header(kc: &KeyComparison) -> &'static str {
    if kc.quantity == Quantity::PitchDeviation {
        "Face"
    } else {
        "Index"
    }
}

/// The cells of quantity `k`'s position: its index, and its table angle when the
/// comparison matched by angle.
fn position_cells(kc: &KeyComparison, k: usize) -> String {
    let mut cells = format!("<td>{}</td>", kc.index[k]);
    if let Some(angles) = &kc.angle_deg {
        cells.push_str(&num(angles.get(k).copied(), ANGLE_DECIMALS));
    }
    cells
}

/// The header cells of the position columns.
fn position_headers(kc: &KeyComparison) -> String {
    format!(
        "<th>{}</th>{}",
        position_header(kc),
        if kc.angle_deg.is_some() {
            "<th>angle / °</th>"
        } else {
            ""
        }
    )
}

fn introduction(out: &mut String, section: &KeyComparisonSection) {
    let kc = &section.comparison;
    let _ = write!(
        out,
        "<p>Interlaboratory (key) comparison of the {} of {} laboratories ({}), evaluated by \
         <code>polycal kc</code> (docs/FORMAT.md §12); the numbers below are those of its JSON, \
         file <span id=\"kc-file\">{}</span>, SHA-256 <span class=\"hash\" id=\"kc-sha256\">{}</span>.",
        quantity_plural(kc.quantity),
        kc.labs.len(),
        esc(&kc.labs.join(", ")),
        esc(&section.file_name),
        section.sha256
    );
    match &section.lab {
        Some(lab) => {
            let _ = write!(
                out,
                " This report is for laboratory <span id=\"kc-lab\">{}</span>, {}.",
                esc(lab),
                match section.lab_exclusion() {
                    Some(e) => format!("which was left out of the reference: {}", esc(&e.reason)),
                    None => "which was in the reference".to_string(),
                }
            );
        }
        None => out.push_str(
            " No laboratory was named: the degrees of equivalence of every laboratory are shown.",
        ),
    }
    out.push_str("</p>\n");
}

fn formulas(out: &mut String, kc: &KeyComparison) {
    let reference = match kc.method {
        ReferenceMethod::WeightedMean => {
            "the weighted mean (Cox 2002, procedure A): x<sub>ref</sub> = Σ x<sub>i</sub>/u<sub>i</sub>² \
             / Σ 1/u<sub>i</sub>², u<sub>ref</sub> = (Σ 1/u<sub>i</sub>²)<sup>−1/2</sup>, over the \
             laboratories in the reference; a laboratory is left out of the whole comparison while \
             some quantity fails its χ² test and more than two remain (the largest consistent \
             subset, the one with the largest |d<sub>i</sub>|/u(d<sub>i</sub>) on a failing \
             quantity first)"
        }
        ReferenceMethod::DersimonianLaird => {
            "the DerSimonian–Laird random-effects mean: x<sub>ref</sub> = Σ x<sub>i</sub>/(u<sub>i</sub>² + τ²) \
             / Σ 1/(u<sub>i</sub>² + τ²), u<sub>ref</sub>² = 1/Σ 1/(u<sub>i</sub>² + τ²), the dark \
             uncertainty τ² = max(0, (χ² − ν)/(S<sub>1</sub> − S<sub>2</sub>/S<sub>1</sub>)), \
             S<sub>1</sub> = Σ 1/u<sub>i</sub>², S<sub>2</sub> = Σ 1/u<sub>i</sub>⁴; nobody is left out"
        }
    };
    let _ = writeln!(
        out,
        "<p id=\"kc-method\" data-method=\"{}\">Reference value ({}): {reference}. Consistency: \
         χ² = Σ (x<sub>i</sub> − x̄<sub>w</sub>)²/u<sub>i</sub>² with ν = n − 1, consistent when \
         χ² ≤ χ²<sub>0.95</sub>(ν). Degrees of equivalence: d<sub>i</sub> = x<sub>i</sub> − \
         x<sub>ref</sub>, U(d<sub>i</sub>) = 2·√(u<sub>i</sub>² + τ² − u<sub>ref</sub>² + \
         u<sub>stab</sub>²) for a laboratory in the reference, 2·√(u<sub>i</sub>² + τ² + \
         u<sub>ref</sub>² + u<sub>stab</sub>²) for one out of it (k = 2); u<sub>stab</sub> is the \
         pilot's instability (0 without repeats or where they agree). All values in arcseconds.</p>",
        kc.method.name(),
        kc.method.name()
    );
}

fn reference_table(out: &mut String, kc: &KeyComparison) {
    let _ = writeln!(
        out,
        "<table class=\"results\" id=\"kc-reference\"><caption>Reference value per {}</caption>\
         <thead><tr>{}<th>x<sub>ref</sub> / ″</th><th>u<sub>ref</sub> / ″</th><th>τ / ″</th>\
         <th>χ²</th><th>ν</th><th>χ²<sub>0.95</sub>(ν)</th><th>Consistent</th></tr></thead><tbody>",
        position_header(kc).to_lowercase(),
        position_headers(kc)
    );
    for k in 0..kc.index.len() {
        let consistent = kc.consistent[k];
        let _ = writeln!(
            out,
            "<tr{}>{}{}{}{}<td class=\"num\">{}</td>{}<td>{}</td></tr>",
            if consistent { "" } else { " class=\"fail\"" },
            position_cells(kc, k),
            rounded_pair_cells(kc.reference[k], kc.reference_u[k]),
            num(Some(kc.tau[k]), ARCSEC_DECIMALS),
            num(Some(kc.chi2[k]), CHI2_DECIMALS),
            kc.chi2_dof[k],
            num(Some(kc.chi2_critical[k]), CHI2_DECIMALS),
            if consistent { "yes" } else { "NO" }
        );
    }
    out.push_str("</tbody></table>\n");
}

fn vector(out: &mut String, kc: &KeyComparison) {
    match &kc.vector {
        Some(v) => {
            let _ = writeln!(
                out,
                "<p>The closed vector: each laboratory's β sum to 0, so its faces are correlated. \
                 Generalised least squares with each laboratory's covariance V<sub>i</sub> (its own \
                 when it sent one, else V<sub>i</sub> = N/(N − 1)·P·diag(u<sub>i</sub>²)·P, \
                 P = I − J/N): x<sub>ref</sub> = (Σ V<sub>i</sub>⁺)⁺ Σ V<sub>i</sub>⁺ x<sub>i</sub>, \
                 χ² = Σ (x<sub>i</sub> − x<sub>ref</sub>)ᵀ V<sub>i</sub>⁺ (x<sub>i</sub> − \
                 x<sub>ref</sub>), ν = (N − 1)(n − 1).</p>\n\
                 <table id=\"kc-vector\"><thead><tr><th>χ²</th><th>ν</th><th>χ²<sub>0.95</sub>(ν)</th>\
                 <th>Consistent</th></tr></thead><tbody><tr{}>{}<td class=\"num\">{}</td>{}<td>{}</td></tr>\
                 </tbody></table>",
                if v.consistent { "" } else { " class=\"fail\"" },
                num(Some(v.chi2), CHI2_DECIMALS),
                v.dof,
                num(Some(v.chi2_critical), CHI2_DECIMALS),
                if v.consistent { "yes" } else { "NO" }
            );
        }
        None => {
            let _ = writeln!(
                out,
                "<p id=\"kc-vector\">The closed vector is not tested: {} are not closed.</p>",
                quantity_plural(kc.quantity)
            );
        }
    }
}

fn exclusions(out: &mut String, kc: &KeyComparison) {
    if kc.excluded.is_empty() {
        out.push_str(
            "<p id=\"kc-exclusions\">Exclusions: none; every laboratory is in the reference.</p>\n",
        );
        return;
    }
    let _ = writeln!(
        out,
        "<table id=\"kc-exclusions\"><caption>Laboratories left out of the reference, in the \
         order they were</caption><thead><tr><th>Step</th><th>Laboratory</th><th>{}</th>\
         <th>|d<sub>i</sub>|/u(d<sub>i</sub>)</th><th>χ² before</th><th>χ²<sub>0.95</sub>(ν)</th>\
         <th>Reason</th></tr></thead><tbody>",
        position_header(kc)
    );
    for (step, e) in kc.excluded.iter().enumerate() {
        let _ = writeln!(
            out,
            "<tr data-lab=\"{}\"><td>{}</td><td>{}</td><td>{}</td>{}{}{}<td>{}</td></tr>",
            esc(&e.lab),
            step + 1,
            esc(&e.lab),
            e.index,
            num(Some(e.normalised_deviation), CHI2_DECIMALS),
            num(Some(e.chi2_before), CHI2_DECIMALS),
            num(Some(e.chi2_critical), CHI2_DECIMALS),
            esc(&e.reason)
        );
    }
    out.push_str("</tbody></table>\n");
}

fn degrees_of_equivalence(out: &mut String, section: &KeyComparisonSection) {
    let kc = &section.comparison;
    let mut shown = section.shown_degrees_of_equivalence();
    if section.lab.is_none()
        && let Some(p) = &kc.pilot
    {
        shown.extend(&p.degrees_of_equivalence);
    }
    let _ = write!(
        out,
        "<table class=\"results\" id=\"kc-doe\"><caption>Degrees of equivalence d<sub>i</sub> and \
         U(d<sub>i</sub>) (k = 2){}; * where |d<sub>i</sub>| &gt; U(d<sub>i</sub>)</caption>\
         <thead><tr>{}",
        if section.lab.is_none() && kc.pilot.is_some() {
            ", the pilot's repeats last (never in the reference)"
        } else {
            ""
        },
        position_headers(kc)
    );
    for d in &shown {
        let lab = esc(&d.lab);
        let out_mark = if d.in_reference { "" } else { " (out)" };
        let _ = write!(
            out,
            "<th data-lab=\"{lab}\" data-column=\"d\">d {lab}{out_mark} / ″</th>\
             <th data-lab=\"{lab}\" data-column=\"U\">U(d) {lab} / ″</th><th data-lab=\"{lab}\" \
             data-column=\"within\">|d| ≤ U</th>"
        );
    }
    out.push_str("</tr></thead><tbody>\n");
    for k in 0..kc.index.len() {
        let _ = write!(out, "<tr>{}", position_cells(kc, k));
        for d in &shown {
            let within = d.d[k].abs() <= d.expanded_u[k];
            let _ = write!(
                out,
                "{}<td>{}</td>",
                rounded_pair_cells(d.d[k], d.expanded_u[k]),
                if within { "yes" } else { "no *" }
            );
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n");
    if section.lab.is_none() && !kc.pairs.is_empty() {
        out.push_str(
            "<p class=\"note\">The pairs d<sub>ij</sub> = x<sub>i</sub> − x<sub>j</sub> with \
             U(d<sub>ij</sub>) = 2·√(u<sub>i</sub>² + u<sub>j</sub>²) are in the key comparison's \
             JSON (<code>pairs</code>).</p>\n",
        );
    }
}

fn pilot(out: &mut String, kc: &KeyComparison) {
    let Some(p) = &kc.pilot else { return };
    let _ = writeln!(
        out,
        "<table class=\"results\" id=\"kc-pilot\"><caption>The pilot's stability: its repeats {} — \
         χ² about their weighted mean with ν = {}; where χ² &gt; χ²<sub>0.95</sub>(ν), \
         u<sub>stab</sub> = their sample standard deviation s, added in quadrature to u<sub>ref</sub> \
         and to every u(d<sub>i</sub>)</caption><thead><tr>{}<th>mean / ″</th><th>s / ″</th>\
         <th>χ²</th><th>Significant</th><th>u<sub>stab</sub> / ″</th></tr></thead><tbody>",
        esc(&p.repeats.join(", ")),
        p.chi2_dof,
        position_headers(kc)
    );
    for k in 0..kc.index.len() {
        let _ = writeln!(
            out,
            "<tr>{}{}{}{}<td>{}</td>{}</tr>",
            position_cells(kc, k),
            num(Some(p.mean[k]), ARCSEC_DECIMALS),
            num(Some(p.spread[k]), ARCSEC_DECIMALS),
            num(Some(p.chi2[k]), CHI2_DECIMALS),
            if p.significant[k] { "yes" } else { "no" },
            num(Some(p.stability_u[k]), ARCSEC_DECIMALS)
        );
    }
    out.push_str("</tbody></table>\n");
}
