//! The tables of a calibration report: every number through one cell ([`num`]) that
//! shows it rounded and keeps the JSON's full-precision value in `data-value`; the result
//! tables of a family (value, u, U, k), the fit, the budget of the quantity with the
//! largest U; a difference or a degree of equivalence beside the U it is judged against,
//! and En (the diagnosis's body is in `diagnosis`).

use std::fmt::Write;

use crate::figure::svg::esc;
use crate::output::SolveReport;
use crate::output::selfcal::SelfcalReport;
use crate::selfcal::{SelfcalContribution, SelfcalUncertainty};
use crate::uncertainty::calibration::{
    CalibrationUncertainty, ComponentContribution, FamilyUncertainty,
};

/// Decimals of values and uncertainties in arcseconds.
pub(super) const ARCSEC_DECIMALS: usize = 4;

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
pub(super) fn num(value: Option<f64>, decimals: usize) -> String {
    match value.filter(|v| v.is_finite()) {
        Some(v) => format!(
            "<td class=\"num\" data-value=\"{v}\">{}</td>",
            rounded(v, decimals)
        ),
        None => "<td class=\"num none\">—</td>".to_string(),
    }
}

/// Two cells, a value and its uncertainty (standard or expanded), stated as GUM 7.2.6
/// states them ([`crate::certificate::rounding::round_result`]: the uncertainty to two
/// significant digits rounded up, the value at its place), each with its full-precision
/// `data-value`; the arcsecond decimals when they cannot be rounded so.
pub(super) fn rounded_pair_cells(value: f64, uncertainty: f64) -> String {
    match crate::certificate::rounding::round_result(value, uncertainty) {
        Some(r) => format!(
            "<td class=\"num\" data-value=\"{value}\">{}</td><td class=\"num\" data-value=\"{uncertainty}\">{}</td>",
            r.value.replace('-', "−"),
            r.expanded_u.replace('-', "−")
        ),
        None => format!(
            "{}{}",
            num(Some(value), ARCSEC_DECIMALS),
            num(Some(uncertainty), ARCSEC_DECIMALS)
        ),
    }
}

/// Two cells, a value and the expanded uncertainty it is judged against (a difference
/// and En's denominator, a degree of equivalence and its U), with the digits it takes
/// for the shown numbers to say what the unrounded ones decide
/// ([`crate::certificate::rounding::round_against`]); each with its `data-value`.
pub(super) fn decision_pair_cells(value: f64, uncertainty: f64) -> String {
    match crate::certificate::rounding::round_against(value, uncertainty) {
        Some(r) => format!(
            "<td class=\"num\" data-value=\"{value}\">{}</td><td class=\"num\" data-value=\"{uncertainty}\">{}</td>",
            r.value.replace('-', "−"),
            r.expanded_u.replace('-', "−")
        ),
        None => rounded_pair_cells(value, uncertainty),
    }
}

/// The cell of an En number ([`crate::certificate::rounding::en_text`]), its value in
/// `data-value`.
pub(super) fn en_cell(en: f64) -> String {
    if !en.is_finite() {
        return num(None, 2);
    }
    format!(
        "<td class=\"num\" data-value=\"{en}\">{}</td>",
        crate::certificate::rounding::en_text(en).replace('-', "−")
    )
}

/// A result's cells as a certificate states them ([`crate::certificate::rounding`]):
/// value and U rounded by GUM 7.2.6, u to two significant digits rounded up, k to three
/// significant digits; each with its unrounded number in `data-value`. Without U, the
/// value rounded at the place of u's second significant digit.
pub(super) fn result_cells(
    value: f64,
    u: Option<f64>,
    expanded_u: Option<f64>,
    k: Option<f64>,
) -> String {
    use crate::certificate::rounding::{round_coverage_factor, round_result};
    let cell = |v: f64, text: &str| {
        format!(
            "<td class=\"num\" data-value=\"{v}\">{}</td>",
            text.replace('-', "−")
        )
    };
    let u_text = u.and_then(|u| round_result(0.0, u)).map(|r| r.expanded_u);
    let u_cell = match (u, u_text) {
        (Some(u), Some(text)) => cell(u, &text),
        _ => num(u, ARCSEC_DECIMALS),
    };
    let k_cell = match (k, k.and_then(round_coverage_factor)) {
        (Some(k), Some(text)) => cell(k, &text),
        _ => num(k, 2),
    };
    match expanded_u.and_then(|eu| round_result(value, eu).map(|r| (eu, r))) {
        Some((eu, r)) => format!(
            "{}{u_cell}{}{k_cell}",
            cell(value, &r.value),
            cell(eu, &r.expanded_u)
        ),
        // no U: the value with its standard uncertainty u as GUM 7.2.6 states them
        None => match u.and_then(|u| round_result(value, u).map(|r| (u, r))) {
            Some((u, r)) => format!(
                "{}{}{}{k_cell}",
                cell(value, &r.value),
                cell(u, &r.expanded_u),
                num(expanded_u, ARCSEC_DECIMALS)
            ),
            None => format!(
                "{}{u_cell}{}{k_cell}",
                num(Some(value), ARCSEC_DECIMALS),
                num(expanded_u, ARCSEC_DECIMALS)
            ),
        },
    }
}

/// The heading of the u column: the combined standard uncertainty behind U (U = k·u)
/// where U is stated; the fit's own type A u, labelled as such, where it is not
/// (docs/FORMAT.md §10.4).
pub(super) fn u_header(combined: bool) -> &'static str {
    if combined {
        "u / ″"
    } else {
        "u of the fit (type A) / ″"
    }
}

/// One family's table: index (and angle) columns, value, u, U, k.
pub(super) struct FamilyTable<'a> {
    pub(super) id: &'a str,
    pub(super) caption: &'a str,
    pub(super) index_header: &'a str,
    pub(super) indices: Vec<String>,
    pub(super) angles_deg: Option<&'a [f64]>,
    pub(super) values: &'a [f64],
    /// The standard uncertainty shown: the one behind U where U is stated
    /// ([`u_header`]).
    pub(super) u: Option<&'a [f64]>,
    /// Whether `u` is the combined standard uncertainty behind U (else the fit's own).
    pub(super) u_combined: bool,
    pub(super) expanded_u: Option<&'a [f64]>,
    pub(super) k: Option<Vec<Option<f64>>>,
}

pub(super) fn family_table(out: &mut String, t: &FamilyTable) {
    let _ = writeln!(
        out,
        "<table class=\"results\" id=\"{}\"><caption>{}</caption><thead><tr><th>{}</th>{}\
         <th class=\"num\">value / ″</th><th class=\"num\">{}</th><th class=\"num\">U / ″</th><th class=\"num\">k</th></tr></thead><tbody>",
        t.id,
        esc(t.caption),
        esc(t.index_header),
        if t.angles_deg.is_some() {
            "<th class=\"num\">angle / °</th>"
        } else {
            ""
        },
        u_header(t.u_combined),
    );
    for (i, value) in t.values.iter().enumerate() {
        let _ = writeln!(
            out,
            "<tr><td>{}</td>{}{}</tr>",
            t.indices.get(i).map_or("", String::as_str),
            t.angles_deg
                .map_or(String::new(), |a| num(a.get(i).copied(), 3)),
            result_cells(
                *value,
                t.u.and_then(|u| u.get(i).copied()),
                t.expanded_u.and_then(|u| u.get(i).copied()),
                t.k.as_ref().and_then(|k| k.get(i).copied().flatten()),
            ),
        );
    }
    out.push_str("</tbody></table>\n");
}

/// The result tables of a `solve` object (the report's results, and the diagnosis's final
/// model); `prefix` makes the ids unique.
pub(super) fn solve_tables(out: &mut String, r: &SolveReport, prefix: &str) {
    let n = r.faces;
    let faces: Vec<String> = (1..=n).map(|k| k.to_string()).collect();
    let id = |name: &str| format!("{prefix}{name}");
    let angles: Vec<f64> = match &r.encoder_angle_deg {
        Some(a) => a.clone(),
        None => (0..r.encoder_error.len())
            .map(|p| crate::measurement::step_angle_deg(p as u32, r.encoder_error.len()))
            .collect(),
    };
    // with a budget, the u beside U and k is its combined u_c (U = k·u_c); without one,
    // the fit's own type A u, labelled so
    let budget = r.uncertainty.as_ref();
    let combined = budget.is_some();
    let pick =
        |family: Option<&FamilyUncertainty>, fit: Option<&'_ Vec<f64>>| -> Option<Vec<f64>> {
            match family {
                Some(f) => Some(f.u.clone()),
                None => fit.cloned(),
            }
        };
    let pitch_u = pick(
        budget.map(|b| &b.pitch_deviation),
        r.pitch_deviation_u.as_ref(),
    );
    let face_u = pick(
        budget.map(|b| &b.face_deviation),
        r.face_deviation_u.as_ref(),
    );
    let encoder_u = pick(budget.map(|b| &b.encoder_error), r.encoder_error_u.as_ref());
    family_table(
        out,
        &FamilyTable {
            id: &id("pitch-deviation"),
            caption: "Pitch deviations β",
            index_header: "face",
            indices: faces.clone(),
            angles_deg: None,
            values: &r.pitch_deviation,
            u: pitch_u.as_deref(),
            u_combined: combined,
            expanded_u: r.pitch_deviation_expanded_u.as_deref(),
            k: r.pitch_deviation_k.clone(),
        },
    );
    family_table(
        out,
        &FamilyTable {
            id: &id("face-deviation"),
            caption: "Face deviations φ (φ[N] = 0 by definition)",
            index_header: "face",
            indices: faces,
            angles_deg: None,
            values: &r.face_deviation,
            u: face_u.as_deref(),
            u_combined: combined,
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
            u: encoder_u.as_deref(),
            u_combined: combined,
            expanded_u: r.encoder_error_expanded_u.as_deref(),
            k: r.encoder_error_k.clone(),
        },
    );
    let setup_values: Vec<f64> = r.setup_error.iter().map(|s| s.value).collect();
    let setup_u: Option<Vec<f64>> = match budget {
        Some(b) => Some(b.setup_error.u.clone()),
        None => r.setup_error.iter().map(|s| s.u).collect(),
    };
    let setup_expanded: Option<Vec<f64>> = r.setup_error.iter().map(|s| s.expanded_u).collect();
    family_table(
        out,
        &FamilyTable {
            id: &id("setup-error"),
            caption: "Setup errors of the autocollimators (they depend on the mounting)",
            index_header: "mounting / autocollimator",
            indices: r
                .setup_error
                .iter()
                .map(|s| format!("{} / {}", s.setup, s.ac))
                .collect(),
            angles_deg: None,
            values: &setup_values,
            u: setup_u.as_deref(),
            u_combined: combined,
            expanded_u: setup_expanded.as_deref(),
            k: Some(r.setup_error.iter().map(|s| s.k).collect()),
        },
    );
}

pub(super) fn fit_summary(
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

/// The index of the largest U of a family (its first, when none is larger).
fn largest(family: &FamilyUncertainty) -> Option<usize> {
    (0..family.expanded_u.len())
        .filter(|&i| family.expanded_u[i].is_finite())
        .max_by(|&a, &b| family.expanded_u[a].total_cmp(&family.expanded_u[b]))
}

/// One component's line of a budget table, at the quantity the table is about.
pub(super) struct BudgetRow {
    /// Its name.
    pub(super) name: String,
    /// `A` or `B` (`—` when not known).
    pub(super) evaluation: String,
    /// Its distribution (`—` when not known).
    pub(super) distribution: String,
    /// Its scope.
    pub(super) acts_on: String,
    /// |c|·u(x) of one draw as it enters a reading, arcsec.
    pub(super) u: f64,
    /// Its sensitivity coefficient, when known.
    pub(super) sensitivity: Option<f64>,
    /// Its degrees of freedom (`None`: infinite).
    pub(super) dof: Option<f64>,
    /// Its contribution to the quantity, arcsec.
    pub(super) contribution: f64,
}

/// One family's budget table at its quantity with the largest U.
pub(super) struct BudgetTable<'a> {
    /// The caption's name of the family, e.g. "Pitch deviations β".
    pub(super) name: &'a str,
    /// The table's `id`.
    pub(super) id: &'a str,
    /// The quantity, e.g. `β[21]`.
    pub(super) quantity: String,
    /// The family's uncertainties.
    pub(super) family: &'a FamilyUncertainty,
    /// The quantity's index in the family.
    pub(super) j: usize,
    /// Degrees of freedom of the fit's type A (`None`: infinite).
    pub(super) type_a_dof: Option<f64>,
    /// The components.
    pub(super) rows: Vec<BudgetRow>,
}

/// The budget of one quantity: the fit's type A and every component, their
/// contributions and indices (share of u_c², per cent), then u_c, ν_eff, k and U.
pub(super) fn budget_table(out: &mut String, t: &BudgetTable) {
    let (family, j) = (t.family, t.j);
    let uc = family.u[j];
    let share = |c: f64| {
        if uc > 0.0 {
            Some(100.0 * c * c / (uc * uc))
        } else {
            None
        }
    };
    let _ = writeln!(
        out,
        "<table class=\"budget\" id=\"{}\"><caption>{} — the quantity with the largest U: {}</caption>\
         <thead><tr><th>Component</th><th>Type</th><th>Distribution</th><th>Acts on</th>\
         <th>u / ″</th><th>Sensitivity</th><th>ν</th><th>Contribution / ″</th><th>Index / %</th></tr></thead><tbody>",
        t.id,
        esc(t.name),
        esc(&t.quantity),
    );
    let _ = writeln!(
        out,
        "<tr><td>type A of the fit (σ·√Q)</td><td>A</td><td>normal</td><td>—</td>{}<td class=\"num\">1</td>{}{}{}</tr>",
        num(Some(family.u_a[j]), ARCSEC_DECIMALS),
        num(t.type_a_dof, 0),
        num(Some(family.u_a[j]), ARCSEC_DECIMALS),
        num(share(family.u_a[j]), 1),
    );
    for r in &t.rows {
        let _ = writeln!(
            out,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td>{}{}{}{}{}</tr>",
            esc(&r.name),
            esc(&r.evaluation),
            esc(&r.distribution),
            esc(&r.acts_on),
            num(Some(r.u), ARCSEC_DECIMALS),
            num(r.sensitivity, 3),
            num(r.dof, 0),
            num(Some(r.contribution), ARCSEC_DECIMALS),
            num(share(r.contribution), 1),
        );
    }
    // the combination, each number on its own labelled line, under the contributions
    // it combines (u_c is their root sum of squares)
    let k_text = family.k[j]
        .and_then(crate::certificate::rounding::round_coverage_factor)
        .unwrap_or_else(|| "—".to_string());
    let u_text = crate::certificate::rounding::round_result(0.0, family.expanded_u[j])
        .map_or_else(|| "—".to_string(), |r| r.expanded_u);
    let line = |label: &str, cell: String| {
        format!("<tr><th colspan=\"7\">{label}</th>{cell}<td></td></tr>")
    };
    let _ = writeln!(
        out,
        "</tbody><tfoot>{}{}{}{}</tfoot></table>",
        line(
            "Combined standard uncertainty u<sub>c</sub> / ″",
            num(Some(uc), ARCSEC_DECIMALS)
        ),
        line(
            "Effective degrees of freedom ν<sub>eff</sub>",
            num(family.dof_eff[j], 1)
        ),
        line(
            "Coverage factor k",
            match family.k[j] {
                Some(k) => format!("<td class=\"num\" data-value=\"{k}\">{k_text}</td>"),
                None => num(None, 0),
            }
        ),
        line(
            "Expanded uncertainty U = k·u<sub>c</sub> / ″",
            format!(
                "<td class=\"num\" data-value=\"{}\">{u_text}</td>",
                family.expanded_u[j]
            )
        ),
    );
}

/// The budget table of a polygon family at its largest U (nothing for an empty family).
pub(super) fn polygon_budget(
    out: &mut String,
    u: &CalibrationUncertainty,
    (name, id, symbol, first_index): (&str, &str, &str, usize),
    family: &FamilyUncertainty,
    contribution: fn(&ComponentContribution, usize) -> f64,
) {
    let Some(j) = largest(family) else { return };
    let rows = u
        .components
        .iter()
        .map(|c| BudgetRow {
            name: c.name.clone(),
            evaluation: c.evaluation.to_string(),
            distribution: c.distribution.to_string(),
            acts_on: c.acts_on.as_str().to_string(),
            u: c.u,
            sensitivity: Some(c.sensitivity),
            dof: c.dof,
            contribution: contribution(c, j),
        })
        .collect();
    budget_table(
        out,
        &BudgetTable {
            name,
            id,
            quantity: format!("{symbol}[{}]", j + first_index),
            family,
            j,
            type_a_dof: u.type_a_dof,
            rows,
        },
    );
}

/// The budget table of a self-calibration family at its largest U; `label` names quantity
/// `j`.
pub(super) fn selfcal_budget(
    out: &mut String,
    u: &SelfcalUncertainty,
    (name, id): (&str, &str),
    family: &FamilyUncertainty,
    contribution: fn(&SelfcalContribution, usize) -> f64,
    label: impl Fn(usize) -> String,
) {
    let Some(j) = largest(family) else { return };
    let rows = u
        .components
        .iter()
        .map(|c| BudgetRow {
            name: c.name.clone(),
            evaluation: "—".into(),
            distribution: "—".into(),
            acts_on: c.acts_on.as_str().to_string(),
            u: c.u,
            sensitivity: None,
            dof: c.dof,
            contribution: contribution(c, j),
        })
        .collect();
    budget_table(
        out,
        &BudgetTable {
            name,
            id,
            quantity: label(j),
            family,
            j,
            type_a_dof: u.type_a_dof,
            rows,
        },
    );
}

/// The result tables of a `selfcal` object: e at every position and the heads' errors
/// (the report's results, and a self-calibration diagnosis's final model with
/// `id_prefix`).
pub(super) fn selfcal_tables(out: &mut String, r: &SelfcalReport, id_prefix: &str) {
    let (encoder_id, head_id) = (
        format!("{id_prefix}encoder-error"),
        format!("{id_prefix}head-error"),
    );
    // the u behind U = k·u: the budget's u_c with a budget, else the fit's u (with the
    // lost harmonics' and the head angles' parts), from which U is formed
    let encoder_u = match &r.uncertainty {
        Some(b) => Some(b.encoder_error.u.clone()),
        None => r.encoder_error_u.clone(),
    };
    family_table(
        out,
        &FamilyTable {
            id: &encoder_id,
            caption: "Graduation errors e of the disc",
            index_header: "position",
            indices: (0..r.encoder_error.len()).map(|p| p.to_string()).collect(),
            angles_deg: Some(&r.encoder_angle_deg),
            values: &r.encoder_error,
            u: encoder_u.as_deref(),
            u_combined: true,
            expanded_u: r.encoder_error_expanded_u.as_deref(),
            k: r.encoder_error_k
                .as_ref()
                .map(|k| k.iter().map(|v| Some(*v)).collect()),
        },
    );
    let values: Vec<f64> = r.head_error.iter().map(|h| h.value).collect();
    let angles: Vec<f64> = r.head_error.iter().map(|h| h.angle_deg).collect();
    let u: Option<Vec<f64>> = match &r.uncertainty {
        Some(b) => Some(b.head_error.u.clone()),
        None => r.head_error.iter().map(|h| h.u).collect(),
    };
    let expanded: Option<Vec<f64>> = r.head_error.iter().map(|h| h.expanded_u).collect();
    family_table(
        out,
        &FamilyTable {
            id: &head_id,
            caption: "Head placement errors c (head 1 is the reference)",
            index_header: "head",
            indices: r.head_error.iter().map(|h| h.head.to_string()).collect(),
            angles_deg: Some(&angles),
            values: &values,
            u: u.as_deref(),
            u_combined: true,
            expanded_u: expanded.as_deref(),
            k: Some(r.head_error.iter().map(|h| h.k).collect()),
        },
    );
}
