//! The key comparison section of the HTML report (`report --kc`, docs/FORMAT.md §10.2):
//! the formulas by name, the reference per quantity with its u and χ² test, the closed
//! vector's test, the exclusions with their reasons, the degrees of equivalence (the named
//! laboratory's, or every laboratory's), the pilot's stability and the comparison's notes;
//! every number through the report's one cell ([`num`]) with the JSON's value in
//! `data-value`.

use std::fmt::Write;

use super::Sections;
use super::tables::{ARCSEC_DECIMALS, decision_pair_cells, num, rounded_pair_cells};
use crate::certificate::{CalibrationReport, KeyComparisonSection};
use crate::figure::svg::esc;
use crate::kc::{KeyComparison, ReferenceMethod, SearchMethod};
use crate::results::Quantity;

/// Decimals of χ² values.
const CHI2_DECIMALS: usize = 2;

/// A χ² cell: two decimals, and from 10⁶ on three significant digits (`1.23e12`), with
/// the JSON's value in `data-value`.
fn chi2_cell(chi2: f64) -> String {
    if !chi2.is_finite() {
        return num(None, CHI2_DECIMALS);
    }
    format!(
        "<td class=\"num\" data-value=\"{chi2}\">{}</td>",
        crate::kc::chi2_text(chi2, CHI2_DECIMALS)
    )
}

/// Decimals of table angles, degrees (as the comparison table's).
const ANGLE_DECIMALS: usize = 3;

/// The sections of the report's key comparisons, one per comparison in the file's order
/// (one per compared quantity); none without. One comparison is the section
/// `key-comparison` with its elements' ids `kc-…`; of several, each section's ids end in
/// `-` and its quantity (`key-comparison-encoder_error`, `kc-doe-encoder_error`).
pub(super) fn section(s: &mut Sections, report: &CalibrationReport) {
    let several = report.key_comparisons.len() > 1;
    for section in &report.key_comparisons {
        let kc = &section.comparison;
        if several {
            let sfx = format!("-{}", kc.quantity.name());
            let title = format!("Key comparison: {}", quantity_plural(kc.quantity));
            s.open(&format!("key-comparison{sfx}"), &title);
            one_comparison(s, section, &sfx);
        } else {
            s.open("key-comparison", "Key comparison");
            one_comparison(s, section, "");
        }
    }
}

/// One key comparison's section, opened; `sfx` ends each of its ids.
fn one_comparison(s: &mut Sections, section: &KeyComparisonSection, sfx: &str) {
    let kc = &section.comparison;
    introduction(&mut s.html, section, sfx);
    formulas(&mut s.html, kc, sfx);
    reference_table(&mut s.html, kc, sfx);
    vector(&mut s.html, kc, sfx);
    exclusions(&mut s.html, kc, sfx);
    degrees_of_equivalence(&mut s.html, section, sfx);
    linked(&mut s.html, section, sfx);
    pilot(&mut s.html, kc, sfx);
    if !kc.notes.is_empty() {
        let _ = writeln!(s.html, "<ul class=\"notes\" id=\"kc-notes{sfx}\">");
        for note in &kc.notes {
            let _ = writeln!(s.html, "<li>{}</li>", esc(note));
        }
        s.html.push_str("</ul>\n");
    }
    let _ = writeln!(
        s.html,
        "<p class=\"verdict {}\" id=\"kc-verdict{sfx}\">{}.</p>",
        if kc.comparison_consistent {
            "pass"
        } else {
            "fail"
        },
        esc(&kc.verdict_statement())
    );
    s.close();
}

/// The compared quantity in words, plural.
fn quantity_plural(quantity: Quantity) -> &'static str {
    match quantity {
        Quantity::PitchDeviation => "pitch deviations β",
        Quantity::EncoderError => "encoder errors α",
        Quantity::FaceDeviation => "face deviations φ",
        Quantity::SetupError => "setup errors",
        Quantity::AngleBlock => "angle blocks' deviations from nominal",
    }
}

/// The header of the position column.
fn position_header(kc: &KeyComparison) -> &'static str {
    match kc.quantity {
        Quantity::PitchDeviation => "Face",
        Quantity::AngleBlock => "Block",
        _ => "Index",
    }
}

/// The cells of quantity `k`'s position: its index, and its table angle when the
/// comparison matched by angle.
fn position_cells(kc: &KeyComparison, k: usize) -> String {
    let mut cells = format!("<td>{}</td>", kc.index[k]);
    if let Some(angles) = &kc.angle_deg {
        cells.push_str(&num(angles.get(k).copied(), ANGLE_DECIMALS));
    }
    if let Some(nominal) = &kc.nominal_deg {
        cells.push_str(&num(nominal.get(k).copied().flatten(), ANGLE_DECIMALS));
    }
    cells
}

/// The header cells of the position columns.
fn position_headers(kc: &KeyComparison) -> String {
    format!(
        "<th>{}</th>{}",
        position_header(kc),
        match (&kc.angle_deg, &kc.nominal_deg) {
            (Some(_), _) => "<th>angle / °</th>",
            (None, Some(_)) => "<th>nominal / °</th>",
            (None, None) => "",
        }
    )
}

fn introduction(out: &mut String, section: &KeyComparisonSection, sfx: &str) {
    let kc = &section.comparison;
    let _ = write!(
        out,
        "<p>Interlaboratory (key) comparison of the {} of {} laboratories ({}), evaluated by \
         <code>polycal kc</code> (docs/FORMAT.md §12); the numbers below are those of its JSON, \
         file <span id=\"kc-file{sfx}\">{}</span>, SHA-256 <span class=\"hash\" id=\"kc-sha256{sfx}\">{}</span>.",
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
                " This report is for laboratory <span id=\"kc-lab{sfx}\">{}</span>, {}.",
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

fn formulas(out: &mut String, kc: &KeyComparison, sfx: &str) {
    let reference = match kc.method {
        ReferenceMethod::WeightedMean => {
            "the closed GLS reference of the laboratories in it (the weighted mean x<sub>ref</sub> \
             = Σ x<sub>i</sub>/u<sub>i</sub>² / Σ 1/u<sub>i</sub>², u<sub>ref</sub> = (Σ \
             1/u<sub>i</sub>²)<sup>−1/2</sup> of each quantity when every laboratory's u is the \
             same on every quantity). The comparison is decided by one test at 5 %, the closed \
             vector of every laboratory; only when it fails are laboratories left out, each \
             from every quantity: the largest subset whose closed vector passes, every subset \
             tried while that is cheap, ties broken by the smaller χ²"
        }
        ReferenceMethod::MandelPaule => {
            "the Mandel–Paule random-effects reference: every laboratory's variance widened by \
             the dark uncertainty τ² of each quantity such that Σ (x<sub>i</sub> − \
             x<sub>ref</sub>)²/(u<sub>i</sub>² + τ²) = n − 1 (τ = 0 when the χ² is below it), \
             then the closed GLS reference; nobody is left out, and the verdict is the test of \
             τ = 0, the closed vector of every laboratory at 5 %"
        }
        _ => {
            "the DerSimonian–Laird random-effects reference: every laboratory's variance widened \
             by the dark uncertainty τ² = max(0, (χ² − ν)/(S<sub>1</sub> − S<sub>2</sub>/S<sub>1</sub>)) \
             of each quantity, S<sub>1</sub> = Σ 1/u<sub>i</sub>², S<sub>2</sub> = Σ \
             1/u<sub>i</sub>⁴ (the spread of the laboratories beyond their stated uncertainties), \
             then the closed GLS reference (x<sub>ref</sub> = Σ x<sub>i</sub>/(u<sub>i</sub>² + τ²) \
             / Σ 1/(u<sub>i</sub>² + τ²) with the same u on every quantity); nobody is left out, \
             and the verdict is the test of τ = 0, the closed vector of every laboratory at 5 %"
        }
    };
    // angle blocks: their own reference and test, no closure
    let wording = kc.wording();
    let reference = reference
        .replace(
            " (the weighted mean x<sub>ref</sub> = Σ x<sub>i</sub>/u<sub>i</sub>² / Σ \
             1/u<sub>i</sub>², u<sub>ref</sub> = (Σ 1/u<sub>i</sub>²)<sup>−1/2</sup> of each \
             quantity when every laboratory's u is the same on every quantity)",
            if wording.is_closed() {
                " (the weighted mean x<sub>ref</sub> = Σ x<sub>i</sub>/u<sub>i</sub>² / Σ \
                 1/u<sub>i</sub>², u<sub>ref</sub> = (Σ 1/u<sub>i</sub>²)<sup>−1/2</sup> of each \
                 quantity when every laboratory's u is the same on every quantity)"
            } else {
                " that report it: x<sub>ref</sub> = Σ x<sub>i</sub>/u<sub>i</sub>² / Σ \
                 1/u<sub>i</sub>², u<sub>ref</sub> = (Σ 1/u<sub>i</sub>²)<sup>−1/2</sup>"
            },
        )
        .replace("the closed GLS reference", wording.reference())
        .replace(
            "whose closed vector passes",
            &format!("whose {} passes", wording.whole()),
        )
        .replace("the closed vector", &format!("the {}", wording.whole()));
    let (sum_zero, diagonal) = if wording.is_closed() {
        (
            " (Σ d<sub>i</sub> = 0)",
            "u<sub>i</sub>² the diagonal of the laboratory's closed covariance, u<sub>ref</sub>² \
             that of the reference's",
        )
    } else {
        (
            "",
            "at the blocks the laboratory reports, each block on its own; none where it did not \
             measure a block",
        )
    };
    let _ = writeln!(
        out,
        "<p id=\"kc-method{sfx}\" data-method=\"{}\">Reference value ({}): {reference}. Per \
         quantity, as information: χ² = Σ (x<sub>i</sub> − x̄<sub>w</sub>)²/u<sub>i</sub>² with \
         ν = n − 1 against χ²<sub>0.95</sub>(ν) (about one quantity in twenty fails by chance). \
         Degrees of equivalence: d<sub>i</sub> = x<sub>i</sub> − x<sub>ref</sub>{sum_zero}, \
         U(d<sub>i</sub>) = 2·√(u<sub>i</sub>² + u<sub>stab</sub>² + τ² − \
         u<sub>ref</sub>²) for a laboratory in the reference, 2·√(u<sub>i</sub>² + \
         u<sub>stab</sub>² + τ² + u<sub>ref</sub>²) for one out of it ({}; {diagonal}); \
         u<sub>stab</sub> is the pilot's instability (0 without repeats or when \
         they agree; otherwise in every laboratory's u, in the reference and in every test). \
         All values in arcseconds.</p>",
        kc.method.name(),
        kc.method.name(),
        coverage_words(kc)
    );
}

/// The coverage factor of U(d_i) in words: 2, or each value's t_95.45(ν_eff) where the
/// laboratories state degrees of freedom (`k` in the kc JSON).
fn coverage_words(kc: &KeyComparison) -> &'static str {
    if kc.degrees_of_equivalence.iter().any(|d| d.k.is_some()) {
        "k = t<sub>95.45</sub>(ν<sub>eff</sub>) of each value, ν<sub>eff</sub> by \
         Welch–Satterthwaite from the degrees of freedom the laboratories state"
    } else {
        "k = 2"
    }
}

fn reference_table(out: &mut String, kc: &KeyComparison, sfx: &str) {
    let _ = writeln!(
        out,
        "<table class=\"results\" id=\"kc-reference{sfx}\"><caption>Reference value per {}</caption>\
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
            chi2_cell(kc.chi2[k]),
            kc.chi2_dof[k],
            num(Some(kc.chi2_critical[k]), CHI2_DECIMALS),
            if consistent { "yes" } else { "NO" }
        );
    }
    out.push_str("</tbody></table>\n");
}

fn vector(out: &mut String, kc: &KeyComparison, sfx: &str) {
    let rows: Vec<(&str, &crate::kc::VectorTest)> = [
        ("Every laboratory (the decision)", kc.vector_all.as_ref()),
        ("The laboratories in the reference", kc.vector.as_ref()),
    ]
    .into_iter()
    .filter_map(|(name, v)| Some((name, v?)))
    .collect();
    if rows.is_empty() {
        let _ = writeln!(
            out,
            "<p id=\"kc-vector{sfx}\">The closed vector is not tested: {} are not closed.</p>",
            quantity_plural(kc.quantity)
        );
        return;
    }
    if !kc.wording().is_closed() {
        let _ = writeln!(
            out,
            "<p>The blocks' joint test: each angle block a single angle of its own (no \
             closure), its reference the weighted mean of the laboratories in the reference that \
             report it; χ² = Σ<sub>b</sub> Σ<sub>i</sub> (x<sub>ib</sub> − \
             x<sub>ref,b</sub>)²/u<sub>ib</sub>², ν = Σ<sub>b</sub> (n<sub>b</sub> − 1), \
             n<sub>b</sub> the laboratories reporting block b.</p>"
        );
    } else {
        closed_words(out, kc);
    }
    let _ = write!(
        out,
        "<table id=\"kc-vector{sfx}\"><thead><tr><th>Laboratories</th><th>χ²</th><th>ν</th>\
         <th>χ²<sub>0.95</sub>(ν)</th><th>Consistent</th></tr></thead><tbody>"
    );
    for (name, v) in rows {
        let _ = write!(
            out,
            "<tr{}><td>{name}</td>{}<td class=\"num\">{}</td>{}<td>{}</td></tr>",
            if v.consistent { "" } else { " class=\"fail\"" },
            chi2_cell(v.chi2),
            v.dof,
            num(Some(v.chi2_critical), CHI2_DECIMALS),
            if v.consistent { "yes" } else { "NO" }
        );
    }
    out.push_str("</tbody></table>\n");
}

/// The closed vector's test in words (pitch deviations, encoder errors).
fn closed_words(out: &mut String, kc: &KeyComparison) {
    if kc.wording().is_uneven() {
        let _ = writeln!(
            out,
            "<p>The closed vector: encoder errors are defined up to a constant, and the \
             laboratories report different positions: each laboratory's result is closed over \
             the N<sub>i</sub> positions it reports (its mean there taken out), with \
             V<sub>i</sub> = N<sub>i</sub>/(N<sub>i</sub> − 1)·P·diag(u<sub>i</sub>²)·P. \
             Generalised least squares over every position: x<sub>ref</sub> = A⁺ Σ \
             M<sub>i</sub>ᵀV<sub>i</sub>⁺x<sub>i</sub>, A = Σ M<sub>i</sub>ᵀV<sub>i</sub>⁺M<sub>i</sub> \
             (M<sub>i</sub> selecting laboratory i's positions), χ² = Σ (x<sub>i</sub> − \
             M<sub>i</sub>x<sub>ref</sub>)ᵀ V<sub>i</sub>⁺ (x<sub>i</sub> − \
             M<sub>i</sub>x<sub>ref</sub>), ν = Σ N<sub>i</sub> − n − (N − 1); each degree of \
             equivalence is closed over the laboratory's positions, U(d<sub>i</sub>) = \
             2·√diag(V<sub>i</sub> ∓ P·M<sub>i</sub>A⁺M<sub>i</sub>ᵀ·P).</p>"
        );
        return;
    }
    let _ = writeln!(
        out,
        "<p>The closed vector: each laboratory's {} sum to 0 ({}), so its quantities are \
         correlated. Generalised least squares with each laboratory's covariance V<sub>i</sub> \
         (its own when it sent one, else V<sub>i</sub> = N/(N − 1)·P·diag(u<sub>i</sub>²)·P, \
         P = I − J/N): x<sub>ref</sub> = (Σ V<sub>i</sub>⁺)⁺ Σ V<sub>i</sub>⁺ x<sub>i</sub>, \
         χ² = Σ (x<sub>i</sub> − x<sub>ref</sub>)ᵀ V<sub>i</sub>⁺ (x<sub>i</sub> − \
         x<sub>ref</sub>), ν = (N − 1)(n − 1).</p>",
        quantity_plural(kc.quantity),
        if kc.quantity == Quantity::EncoderError {
            "each result's mean over the compared positions taken out: encoder errors are \
             defined up to a constant"
        } else {
            "a polygon closes"
        }
    );
}

fn exclusions(out: &mut String, kc: &KeyComparison, sfx: &str) {
    if let Some(search) = &kc.search {
        let _ = writeln!(
            out,
            "<table id=\"kc-search{sfx}\"><caption>The largest consistent subset ({}, {} subsets \
             fitted): the subset of each size with the smallest χ²</caption><thead><tr>\
             <th>Laboratories</th><th>Subset</th><th>χ²</th><th>ν</th><th>χ²<sub>0.95</sub>(ν)</th>\
             <th>Passes</th></tr></thead><tbody>",
            match search.method {
                SearchMethod::Exhaustive => "every subset tried",
                _ => "greedy: the subsets were too many to try",
            },
            search.subsets_tested
        );
        for step in &search.steps {
            let _ = writeln!(
                out,
                "<tr{}><td>{}</td><td>{}</td>{}<td class=\"num\">{}</td>{}<td>{}</td></tr>",
                if step.consistent {
                    ""
                } else {
                    " class=\"fail\""
                },
                step.size,
                esc(&step.best.join(", ")),
                chi2_cell(step.chi2),
                step.dof,
                num(Some(step.chi2_critical), CHI2_DECIMALS),
                if step.consistent { "yes" } else { "NO" }
            );
        }
        out.push_str("</tbody></table>\n");
    }
    if kc.excluded.is_empty() {
        let _ = writeln!(
            out,
            "<p id=\"kc-exclusions{sfx}\">Exclusions: none; every laboratory is in the reference.</p>",
        );
        return;
    }
    let _ = writeln!(
        out,
        "<table id=\"kc-exclusions{sfx}\"><caption>Laboratories left out of the reference (of \
         every quantity)</caption><thead><tr><th>Laboratory</th><th>Reason</th></tr></thead><tbody>",
    );
    for e in &kc.excluded {
        let _ = writeln!(
            out,
            "<tr data-lab=\"{}\"><td>{}</td><td>{}</td></tr>",
            esc(&e.lab),
            esc(&e.lab),
            esc(&e.reason)
        );
    }
    out.push_str("</tbody></table>\n");
}

fn degrees_of_equivalence(out: &mut String, section: &KeyComparisonSection, sfx: &str) {
    let kc = &section.comparison;
    let mut shown = section.shown_degrees_of_equivalence();
    if section.lab.is_none()
        && let Some(p) = &kc.pilot
    {
        shown.extend(&p.degrees_of_equivalence);
    }
    let _ = write!(
        out,
        "<table class=\"results\" id=\"kc-doe{sfx}\"><caption>Degrees of equivalence d<sub>i</sub> and \
         U(d<sub>i</sub>) ({}){}; * where |d<sub>i</sub>| &gt; U(d<sub>i</sub>)</caption>\
         <thead><tr>{}",
        coverage_words(kc),
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
                // the digits it takes to see whether |d| > U, as the mark says
                decision_pair_cells(d.d[k], d.expanded_u[k]),
                match (crate::kc::is_given(d.d[k]), within) {
                    // an angle block the laboratory did not measure
                    (false, _) => "—",
                    (true, true) => "yes",
                    (true, false) => "no *",
                }
            );
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n");
    if section.lab.is_none() && !kc.pairs.is_empty() {
        out.push_str(
            "<p class=\"note\">The pairs d<sub>ij</sub> = x<sub>i</sub> − x<sub>j</sub> with \
             U(d<sub>ij</sub>) = 2·√(u<sub>i</sub>² + u<sub>j</sub>² + 2u<sub>stab</sub>² + \
             2τ²), and each pair's test at 5 % (χ², ν = N − 1; for angle blocks the blocks both \
             report, ν their number), are in the key \
             comparison's JSON (<code>pairs</code>) and its pairwise figure.</p>\n",
        );
    }
}

/// The link to another comparison, when there is one: the laboratories in both, the
/// link's test, and per position Δ with u(Δ) and each shown laboratory's degree of
/// equivalence against the linked reference (d_linked, U_linked).
fn linked(out: &mut String, section: &KeyComparisonSection, sfx: &str) {
    let kc = &section.comparison;
    let Some(link) = &kc.link else { return };
    let test = match &link.vector {
        Some(v) => format!(
            "the linking laboratories {} on the offset: χ² = {} {} χ²<sub>0.95</sub>({}) = {:.2}",
            if v.consistent { "agree" } else { "DISAGREE" },
            crate::kc::chi2_text(v.chi2, CHI2_DECIMALS),
            if v.consistent { "≤" } else { ">" },
            v.dof,
            v.chi2_critical
        ),
        None => link.untested_reason().to_string(),
    };
    let shown: Vec<_> = section
        .shown_degrees_of_equivalence()
        .into_iter()
        .filter(|d| d.d_linked.is_some())
        .collect();
    let _ = write!(
        out,
        "<p id=\"kc-link{sfx}\">Linked to another comparison through {} (the laboratories \
         in both): Δ is the GLS mean of their offsets d(linked) − d(this), their correlations \
         counted; {test}. Against the linked reference d = d<sub>i</sub> + Δ{} with its U \
         (k = 2).</p>\n<table class=\"results\" id=\"kc-linked{sfx}\"><thead><tr>{}\
         <th>Δ / ″</th><th>u(Δ) / ″</th>",
        esc(&link.labs.join(", ")),
        if kc.linked_over_own_positions() {
            " less Δ's mean over the laboratory's own positions"
        } else {
            ""
        },
        position_headers(kc)
    );
    for d in &shown {
        let lab = esc(&d.lab);
        let _ = write!(
            out,
            "<th data-lab=\"{lab}\" data-column=\"d_linked\">d {lab} linked / ″</th>\
             <th data-lab=\"{lab}\" data-column=\"U_linked\">U {lab} / ″</th>"
        );
    }
    out.push_str("</tr></thead><tbody>\n");
    for k in 0..kc.index.len() {
        let _ = write!(
            out,
            "<tr>{}{}{}",
            position_cells(kc, k),
            num(link.correction.get(k).copied(), ARCSEC_DECIMALS),
            num(link.correction_u.get(k).copied(), ARCSEC_DECIMALS)
        );
        for d in &shown {
            let value = |list: &Option<Vec<f64>>| list.as_ref().and_then(|l| l.get(k).copied());
            let (dl, ul) = (value(&d.d_linked), value(&d.expanded_u_linked));
            match (dl, ul) {
                (Some(dl), Some(ul)) if dl.is_finite() && ul.is_finite() => {
                    out.push_str(&decision_pair_cells(dl, ul));
                }
                _ => {
                    out.push_str(&num(None, ARCSEC_DECIMALS));
                    out.push_str(&num(None, ARCSEC_DECIMALS));
                }
            }
        }
        out.push_str("</tr>\n");
    }
    out.push_str("</tbody></table>\n");
}

fn pilot(out: &mut String, kc: &KeyComparison, sfx: &str) {
    let Some(p) = &kc.pilot else { return };
    let _ = writeln!(
        out,
        "<p id=\"kc-pilot-verdict{sfx}\">{}.</p>\n<table class=\"results\" id=\"kc-pilot{sfx}\"><caption>The pilot's repeats {} per quantity \
         (information): χ² about their weighted mean with ν = {}, and u<sub>stab</sub></caption><thead><tr>{}<th>mean / ″</th><th>s / ″</th>\
         <th>χ²</th><th>Significant</th><th>u<sub>stab</sub> / ″</th></tr></thead><tbody>",
        esc(&kc.pilot_statement().unwrap_or_default()),
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
            chi2_cell(p.chi2[k]),
            if p.significant[k] { "yes" } else { "no" },
            num(Some(p.stability_u[k]), ARCSEC_DECIMALS)
        );
    }
    out.push_str("</tbody></table>\n");
}
