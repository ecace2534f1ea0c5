//! The key comparisons in a DCC's results (`report --kc`, docs/FORMAT.md §10.3): per
//! comparison in the file (one per compared quantity, pitch deviations, encoder errors),
//! one `dcc:result` of refType `polycal_keyComparison` whose list holds, per position,
//! the reference value with U = 2·u_ref, the χ² of its test and χ²_0.95(ν), and the
//! degrees of equivalence d_i with U(d_i) (the named laboratory's, or every laboratory's)
//! as D-SI lists; the formulas, the closed vector's test, the exclusions with their reasons
//! and the verdict in words.

use super::DccError;
use super::calibrated::{Column, Form};
use super::xml::Xml;
use crate::certificate::{CalibrationReport, KeyComparisonSection};
use crate::kc::ReferenceMethod;
use crate::results::Quantity;

/// The coverage factor of the comparison's expanded uncertainties (U(d_i) and U_ref).
const K: f64 = 2.0;

/// The coverage probability stated with k = 2: about 95 % for a normal distribution.
const P: f64 = 0.95;

/// The key comparisons' `dcc:result`s, one per comparison (per compared quantity) in the
/// order of the file; nothing without one.
pub(super) fn key_comparison(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    for section in &report.key_comparisons {
        one_comparison(x, section)?;
    }
    Ok(())
}

/// One key comparison's `dcc:result`.
fn one_comparison(x: &mut Xml, section: &KeyComparisonSection) -> Result<(), DccError> {
    let kc = &section.comparison;
    x.open("dcc:result", &[("refType", "polycal_keyComparison")]);
    x.content(
        "dcc:name",
        &format!(
            "Key comparison of the {}: reference values and degrees of equivalence",
            kc.quantity.name()
        ),
    )?;
    x.content("dcc:description", &description(section))?;
    x.open("dcc:data", &[]);
    x.open("dcc:list", &[]);
    let labels: Vec<String> = kc
        .index
        .iter()
        .map(|i| match kc.quantity {
            Quantity::PitchDeviation => format!("face{i}"),
            Quantity::AngleBlock => format!("block{i}"),
            _ => format!("index{i}"),
        })
        .collect();
    if let Some(angles) = &kc.angle_deg {
        Column {
            refs: "polycal_kcTableAngle",
            name: "Table angle of the encoder error",
            unit: "\\degree",
            labels: Some(labels.clone()),
            values: angles.clone(),
            expanded: None,
            form: Form::Real,
        }
        .write(x)?;
    }
    if let Some(nominal) = &kc.nominal_deg {
        let (labels, values) = given(&labels, |k| nominal.get(k).copied().flatten());
        Column {
            refs: "polycal_kcNominalAngle",
            name: "Nominal angle of the angle block",
            unit: "\\degree",
            labels: Some(labels),
            values,
            expanded: None,
            form: Form::Real,
        }
        .write(x)?;
    }
    let (reference_labels, reference) = given(&labels, |k| Some(kc.reference[k]));
    let reference_u: Vec<f64> = kc
        .reference
        .iter()
        .zip(&kc.reference_u)
        .filter(|(r, _)| crate::kc::is_given(**r))
        .map(|(_, u)| K * u)
        .collect();
    Column {
        refs: "polycal_kcReferenceValue",
        name: "Reference value x_ref",
        unit: "\\arcsecond",
        values: reference,
        expanded: Some((reference_u.clone(), vec![K; reference_u.len()], P)),
        labels: Some(reference_labels),
        form: Form::Real,
    }
    .write(x)?;
    Column {
        refs: "polycal_kcChi2",
        name: "χ² of the reference's consistency test",
        unit: "\\one",
        labels: Some(labels.clone()),
        values: kc.chi2.clone(),
        expanded: None,
        form: Form::Real,
    }
    .write(x)?;
    let (critical_labels, critical) = given(&labels, |k| Some(kc.chi2_critical[k]));
    Column {
        refs: "polycal_kcChi2Critical",
        name: "χ²_0.95(ν) of the consistency test",
        unit: "\\one",
        labels: Some(critical_labels),
        values: critical,
        expanded: None,
        form: Form::Real,
    }
    .write(x)?;
    for doe in section.shown_degrees_of_equivalence() {
        let name = format!(
            "Degree of equivalence d of laboratory {}{}",
            doe.lab,
            if doe.in_reference {
                " (in the reference)"
            } else {
                " (left out of the reference)"
            }
        );
        // the positions the laboratory reports (an angle block it did not measure has no d)
        let (doe_labels, d) = given(&labels, |k| Some(doe.d[k]));
        let reported: Vec<usize> = (0..doe.d.len())
            .filter(|&k| crate::kc::is_given(doe.d[k]))
            .collect();
        let expanded_u: Vec<f64> = reported.iter().map(|&k| doe.expanded_u[k]).collect();
        // k = 2, or t_95.45(ν_eff) where the laboratories state degrees of freedom
        let coverage: Vec<f64> = reported
            .iter()
            .map(|&k| doe.k.as_ref().and_then(|f| f.get(k)).copied().unwrap_or(K))
            .collect();
        Column {
            refs: "polycal_kcDegreeOfEquivalence",
            name: &name,
            unit: "\\arcsecond",
            labels: Some(doe_labels),
            values: d,
            expanded: Some((expanded_u, coverage, P)),
            form: Form::Real,
        }
        .write(x)?;
    }
    linked_columns(x, section, &labels)?;
    x.close();
    for line in statements(section) {
        x.content("dcc:text", &line)?;
    }
    if let Some(figure) = crate::figure::kcdb_figure(kc) {
        // the KCDB graphs, as the report draws them
        x.open("dcc:byteData", &[]);
        x.content("dcc:name", &figure.title)?;
        x.text("dcc:fileName", &[], &figure.file_name())?;
        x.text("dcc:mimeType", &[], "image/svg+xml")?;
        x.text(
            "dcc:dataBase64",
            &[],
            &super::xml::base64(figure.svg.as_bytes()),
        )?;
        x.close();
    }
    x.close();
    x.close();
    Ok(())
}

/// With a link to another comparison: the correction Δ with U = 2·u(Δ), and each shown
/// laboratory's degree of equivalence against the linked reference with its U.
fn linked_columns(
    x: &mut Xml,
    section: &KeyComparisonSection,
    labels: &[String],
) -> Result<(), DccError> {
    let kc = &section.comparison;
    let Some(link) = &kc.link else {
        return Ok(());
    };
    // a value and its U where both are given (a position a laboratory does not report,
    // or a block no laboratory links, has neither)
    let column = |x: &mut Xml, refs: &str, name: &str, values: &[f64], u: &[f64], factor: f64| {
        let shown: Vec<usize> = (0..labels.len())
            .filter(|&k| crate::kc::is_given(values[k]) && u.get(k).is_some_and(|u| u.is_finite()))
            .collect();
        Column {
            refs,
            name,
            unit: "\\arcsecond",
            labels: Some(shown.iter().map(|&k| labels[k].clone()).collect()),
            values: shown.iter().map(|&k| values[k]).collect(),
            expanded: Some((
                shown.iter().map(|&k| factor * u[k]).collect(),
                vec![K; shown.len()],
                P,
            )),
            form: Form::Real,
        }
        .write(x)
    };
    column(
        x,
        "polycal_kcLinkCorrection",
        &format!(
            "Correction Δ to the linked reference, through {}",
            link.labs.join(", ")
        ),
        &link.correction,
        &link.correction_u,
        K,
    )?;
    for doe in section.shown_degrees_of_equivalence() {
        let (Some(d), Some(u)) = (&doe.d_linked, &doe.expanded_u_linked) else {
            continue;
        };
        column(
            x,
            "polycal_kcDegreeOfEquivalenceLinked",
            &format!(
                "Degree of equivalence of laboratory {} against the linked reference",
                doe.lab
            ),
            d,
            u,
            1.0,
        )?;
    }
    Ok(())
}

/// The labels and values of the positions where `value` gives a finite number (a
/// degree of equivalence where a laboratory does not report an angle block, a reference
/// no laboratory in it reports, χ²_0.95(0): not given, so not written).
fn given(labels: &[String], value: impl Fn(usize) -> Option<f64>) -> (Vec<String>, Vec<f64>) {
    labels
        .iter()
        .enumerate()
        .filter_map(|(k, label)| {
            value(k)
                .filter(|v| crate::kc::is_given(*v))
                .map(|v| (label.clone(), v))
        })
        .unzip()
}

/// The formulas and the file, in words.
fn description(section: &KeyComparisonSection) -> String {
    let kc = &section.comparison;
    let method = match kc.method {
        ReferenceMethod::WeightedMean => {
            "the closed GLS reference of the laboratories in it (with one u per laboratory the weighted mean, Cox 2002, procedure A, x_ref = Σ x_i/u_i² / Σ 1/u_i², u_ref = (Σ 1/u_i²)^(−1/2)); the comparison decided by one test at 5 %, the closed vector of every laboratory, and when it fails the largest subset that passes"
        }
        ReferenceMethod::MandelPaule => {
            "the Mandel–Paule random-effects reference, every u_i² widened by the dark uncertainty τ² of each quantity such that Σ (x_i − x_ref)²/(u_i² + τ²) = n − 1 (τ = 0 when χ² ≤ n − 1), then the closed GLS reference; nobody left out, the verdict the test of τ = 0 (the closed vector of every laboratory at 5 %)"
        }
        _ => {
            "the DerSimonian–Laird random-effects reference, every u_i² widened by the dark uncertainty τ² = max(0, (χ² − ν)/(S1 − S2/S1)) of each quantity, then the closed GLS reference (with one u per laboratory x_ref = Σ x_i/(u_i² + τ²) / Σ 1/(u_i² + τ²), u_ref² = 1/Σ 1/(u_i² + τ²)); nobody left out, the verdict the test of τ = 0 (the closed vector of every laboratory at 5 %)"
        }
    };
    // angle blocks: the same words of their own reference and test
    let wording = kc.wording();
    let method = method
        .replace("the closed GLS reference", wording.reference())
        .replace("the closed vector", &format!("the {}", wording.whole()));
    format!(
        "Interlaboratory comparison of {} laboratories ({}) evaluated by polycal kc (file {}, SHA-256 {}). Reference per quantity: {method}; its U = 2·u_ref. Per quantity, as information: χ² = Σ (x_i − x̄_w)²/u_i² with ν = n − 1 against χ²_0.95(ν). Degrees of equivalence d_i = x_i − x_ref with U(d_i) = 2·√(u_i² + u_stab² + τ² − u_ref²) in the reference and 2·√(u_i² + u_stab² + τ² + u_ref²) out of it. {} Values in arcseconds, labelled by {}; k = 2{} with the coverage probability stated as 0.95 (normal distribution).",
        kc.labs.len(),
        kc.labs.join(", "),
        section.file_name,
        section.sha256,
        match &section.lab {
            Some(lab) => format!("The degrees of equivalence are those of laboratory {lab}."),
            None => "The degrees of equivalence of every laboratory follow.".to_string(),
        },
        match kc.quantity {
            Quantity::PitchDeviation => "face",
            Quantity::AngleBlock =>
                "angle block (a laboratory's degrees of equivalence only at the blocks it reports)",
            _ => "the first laboratory's encoder index",
        },
        if kc.degrees_of_equivalence.iter().any(|d| d.k.is_some()) {
            " (U(d_i): k = t_95.45(ν_eff) of each value, the Welch–Satterthwaite degrees of freedom from those the laboratories state, written with the value)"
        } else {
            ""
        }
    )
}

/// The closed vector's test, the exclusions with their reasons, the pilot's stability, the
/// notes and the verdict, one statement each.
fn statements(section: &KeyComparisonSection) -> Vec<String> {
    let kc = &section.comparison;
    let mut lines = Vec::new();
    if let Some(v) = &kc.vector_all {
        lines.push(format!("Every laboratory: {}.", kc.vector_statement(v)));
    }
    if let Some(search) = &kc.search {
        for step in &search.steps {
            lines.push(format!(
                "Subset search, {} laboratories: the smallest χ² of {} subsets is {} ({}): χ² = {}, ν = {}, χ²_0.95(ν) = {:.2}: {}.",
                step.size,
                step.subsets,
                step.best.join(", "),
                if step.consistent { "passes" } else { "fails" },
                crate::kc::chi2_text(step.chi2, 2),
                step.dof,
                step.chi2_critical,
                if step.consistent { "consistent" } else { "not consistent" }
            ));
        }
    }
    lines.push(format!(
        "In the reference: {}.",
        kc.closed_vector_statement()
    ));
    if kc.excluded.is_empty() {
        lines.push("Exclusions: none; every laboratory is in the reference.".to_string());
    }
    for e in &kc.excluded {
        lines.push(format!(
            "Exclusion: laboratory {} left out of the reference: {}",
            e.lab, e.reason
        ));
    }
    if let Some(statement) = kc.pilot_statement() {
        lines.push(format!("{statement}."));
    }
    lines.extend(kc.notes.iter().cloned());
    lines.push(format!("Verdict: {}.", kc.verdict_statement()));
    lines
}
