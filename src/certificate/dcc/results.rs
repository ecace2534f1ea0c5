//! `measurementResults` of a DCC: the method, the software, the equipment, the
//! conditions and the results — β, φ, α (or a self-calibration's e and head errors) as
//! D-SI lists with U, k and p per value, the fit, the diagnosis, the comparison, the key
//! comparison (`kc`) — and the SHA-256 of every input.

use super::calibrated::{Column, Form, Stage, polygon_results, real_quantity, selfcal_results};
use super::xml::Xml;
use super::{DccError, METHOD_REFERENCE, equipment, software};
use crate::certificate::{
    CalibrationReport, DesignSummary, DiagnosisReport, Evaluation, effect_text,
};

/// The uncertainty statement: GUM, p, how k is found, the budget.
pub(super) fn uncertainty_statement(report: &CalibrationReport) -> String {
    let (budget, p) = match &report.evaluation {
        Evaluation::Polygon { uncertainty, .. } => (
            uncertainty.as_ref().map(|u| u.budget.clone()),
            uncertainty.as_ref().map(|u| u.p),
        ),
        Evaluation::Selfcal {
            uncertainty,
            report: r,
        } => (
            uncertainty.as_ref().map(|u| u.budget.clone()),
            Some(uncertainty.as_ref().map_or(r.p, |u| u.p)),
        ),
    };
    let p = p.map_or_else(String::new, |p| format!(" {}", p));
    let source = match budget {
        Some(b) => format!(
            "combining the type A uncertainty of the least-squares fit with the instrument budget {b}"
        ),
        None => "from the type A uncertainty of the fit alone (no instrument budget was given)"
            .to_string(),
    };
    format!(
        "The uncertainties were evaluated according to the GUM (JCGM 100:2008), {source}. Each expanded uncertainty U = k·u is stated for the coverage probability{p}; each value's coverage factor k is Student's t for its effective degrees of freedom (Welch–Satterthwaite). U is stated to two significant digits, rounded up, each value rounded to the decimal place of its U (GUM 7.2.6), and k to three significant digits. The results relate only to the items calibrated."
    )
}

/// The polygon design in words.
fn design_words(d: &DesignSummary) -> String {
    let faces: Vec<String> = d
        .face_offsets
        .iter()
        .map(|((setup, ac), offset)| {
            format!(
                "autocollimator {ac} (mounting {setup}) on face {} at step 0",
                offset + 1
            )
        })
        .collect();
    format!(
        "{} faces; {}; {} cycle(s){}{}; {} mounting(s); {} readings.",
        d.faces,
        faces.join(", "),
        d.cycles,
        if d.closing {
            ", with closing readings"
        } else {
            ""
        },
        if d.bidirectional {
            ", both directions"
        } else {
            ""
        },
        d.setups,
        d.readings
    )
}

/// `measurementResults`.
pub(super) fn measurement_results(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let meta = &report.metadata;
    if let Evaluation::Polygon { solve, .. } = &report.evaluation
        && solve.p.is_none()
    {
        return Err(DccError::NoExpandedUncertainty {
            what: "the polygon calibration",
        });
    }
    x.open("dcc:measurementResults", &[]);
    let (refs, items) = match &report.evaluation {
        Evaluation::Polygon { .. } => ("polycal_polygonAndEncoder", "polygon encoder"),
        Evaluation::Selfcal { .. } => ("polycal_encoderSelfCalibration", "encoder"),
    };
    x.open(
        "dcc:measurementResult",
        &[("refType", refs), ("refId", items)],
    );
    x.content(
        "dcc:name",
        match &report.evaluation {
            Evaluation::Polygon { .. } => {
                "Pitch deviations of the polygon and encoder errors of the rotary table by the two-autocollimator method"
            }
            Evaluation::Selfcal { .. } => {
                "Encoder errors of the rotary table by multi-head self-calibration"
            }
        },
    )?;
    x.open("dcc:usedMethods", &[]);
    x.open("dcc:usedMethod", &[("refType", "polycal_closureMethod")]);
    match &report.evaluation {
        Evaluation::Polygon { design, solve, .. } => {
            x.content(
                "dcc:name",
                "Two-autocollimator method: polygon and encoder calibrated at the same time by closure",
            )?;
            x.content(
                "dcc:description",
                &format!(
                    "Each reading is modelled as α[p mod N] + φ[face] + s[mounting, autocollimator] + noise, s the setup errors (the reference's U), with Σα = 0 and Σβ = 0 (the reference's eqs. (1)–(3)); solved by polycal's {} solver ({} engine). Design: {}",
                    solve.method,
                    solve.engine,
                    design_words(design)
                ),
            )?;
        }
        Evaluation::Selfcal { report: r, .. } => {
            x.content(
                "dcc:name",
                "Multi-head self-calibration of the rotary encoder (closure)",
            )?;
            x.content(
                "dcc:description",
                &format!(
                    "{} positions, {} heads, {} cycle(s), {} readings; heads {}.",
                    r.positions, r.heads, r.cycles, r.readings, r.head_grid
                ),
            )?;
        }
    }
    x.text("dcc:reference", &[], METHOD_REFERENCE)?;
    x.close();
    x.open(
        "dcc:usedMethod",
        &[("refType", "basic_uncertaintyEvaluation")],
    );
    x.content(
        "dcc:name",
        "Evaluation of the uncertainty according to the GUM",
    )?;
    x.content("dcc:description", &uncertainty_statement(report))?;
    x.text("dcc:norm", &[], "JCGM 100:2008")?;
    x.close();
    x.close();
    software(x, "dcc:usedSoftware")?;
    if !meta.instruments.is_empty() {
        x.open("dcc:measuringEquipments", &[]);
        for (i, entry) in meta.instruments.iter().enumerate() {
            equipment(x, entry, i)?;
        }
        x.close();
    }
    influence_conditions(x, report)?;
    x.open("dcc:results", &[]);
    match &report.evaluation {
        Evaluation::Polygon { solve, .. } => polygon_results(x, solve, Stage::Evaluation)?,
        Evaluation::Selfcal { report: r, .. } => selfcal_results(x, r, Stage::Evaluation)?,
    }
    setup_errors(x, report)?;
    diagnosis(x, report)?;
    final_model(x, report)?;
    comparison(x, report)?;
    super::kc::key_comparison(x, report)?;
    x.close();
    x.open("dcc:measurementMetaData", &[]);
    for input in &report.inputs {
        x.open("dcc:metaData", &[("refType", "polycal_inputFileSha256")]);
        x.text("dcc:convention", &[], "SHA-256")?;
        x.text("dcc:reference", &[], &input.path)?;
        x.content(
            "dcc:declaration",
            &format!(
                "{} ({}, {} bytes): SHA-256 {}",
                input.path, input.role, input.bytes, input.sha256
            ),
        )?;
        x.close();
    }
    x.open("dcc:metaData", &[("refType", "polycal_written")]);
    x.content(
        "dcc:declaration",
        &match &report.command_line {
            Some(line) => format!(
                "Written by polycal {} at {} UTC: {line}",
                crate::SOFTWARE_VERSION,
                report.generated_utc
            ),
            None => format!(
                "Written by polycal {} at {} UTC.",
                crate::SOFTWARE_VERSION,
                report.generated_utc
            ),
        },
    )?;
    x.close();
    x.close();
    x.close();
    x.close();
    Ok(())
}

/// `influenceConditions`: temperature, humidity, pressure, environment, a stated
/// cross-talk. None given: no element.
fn influence_conditions(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let meta = &report.metadata;
    let mut any = false;
    let mut begin = |x: &mut Xml| {
        if !any {
            x.open("dcc:influenceConditions", &[]);
            any = true;
        }
    };
    for (key, refs, name, unit) in [
        (
            "temperature_c",
            "basic_temperature",
            "Air temperature",
            "\\degreecelsius",
        ),
        (
            "humidity_percent",
            "basic_humidityRelative",
            "Relative humidity",
            "\\percent",
        ),
        (
            "pressure_hpa",
            "basic_pressure",
            "Air pressure",
            "\\hecto\\pascal",
        ),
    ] {
        let Some(value) = meta.value(key).and_then(|v| v.parse::<f64>().ok()) else {
            continue;
        };
        begin(x);
        x.open("dcc:influenceCondition", &[("refType", refs)]);
        x.content("dcc:name", name)?;
        x.open("dcc:data", &[]);
        real_quantity(x, value, unit, name)?;
        x.close();
        x.close();
    }
    let mut texts: Vec<(&str, &str, String)> = Vec::new();
    if let Some(environment) = meta.value("environment") {
        texts.push((
            "polycal_environment",
            "Environment",
            environment.to_string(),
        ));
    }
    if !report.stated_cross_talk.is_empty() {
        let each: Vec<String> = report
            .stated_cross_talk
            .iter()
            .map(crate::measurement::cross_talk::StatedCrossTalk::describe)
            .collect();
        texts.push((
            "polycal_statedCrossTalk",
            "Cross-talk stated from the autocollimators' calibrations",
            format!(
                "The readings were corrected by C·reading_y, and u(C) entered the budget: {}",
                each.join("; ")
            ),
        ));
    }
    for (refs, name, text) in texts {
        begin(x);
        x.open("dcc:influenceCondition", &[("refType", refs)]);
        x.content("dcc:name", name)?;
        x.open("dcc:data", &[]);
        x.content("dcc:text", &text)?;
        x.close();
        x.close();
    }
    if any {
        x.close();
    }
    Ok(())
}

/// The setup errors of the autocollimators: estimated with β and α, so a result (not an
/// influence condition), named apart from the expanded uncertainty U.
fn setup_errors(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let Evaluation::Polygon { solve, .. } = &report.evaluation else {
        return Ok(());
    };
    if solve.setup_error.is_empty() {
        return Ok(());
    }
    let setup = &solve.setup_error;
    let expanded = setup
        .iter()
        .map(|s| s.expanded_u.zip(s.k))
        .collect::<Option<Vec<_>>>()
        .ok_or(DccError::NoExpandedUncertainty {
            what: "a setup error",
        })?;
    let p = solve.p.ok_or(DccError::NoExpandedUncertainty {
        what: "the setup errors",
    })?;
    x.open("dcc:result", &[("refType", "polycal_setupErrors")]);
    x.content("dcc:name", "Setup errors of the autocollimators")?;
    x.content(
        "dcc:description",
        "The zero of each autocollimator in each mounting of the polygon, estimated with β and α (the reference's U₁, U₂; not an uncertainty); labelled mounting_autocollimator. They depend on the mounting and are not a property of the items.",
    )?;
    x.open("dcc:data", &[]);
    x.open("dcc:list", &[]);
    Column {
        refs: crate::results::certificate::quantity_ref_type(crate::results::Quantity::SetupError),
        name: "Setup error",
        unit: "\\arcsecond",
        labels: Some(
            setup
                .iter()
                .map(|s| format!("setup{}_ac{}", s.setup, s.ac))
                .collect(),
        ),
        values: setup.iter().map(|s| s.value).collect(),
        expanded: Some((
            expanded.iter().map(|e| e.0).collect(),
            expanded.iter().map(|e| e.1).collect(),
            p,
        )),
        form: Form::Real,
    }
    .write(x)?;
    x.close();
    x.close();
    x.close();
    Ok(())
}

/// The diagnosis: the verdict, the checks and the effects found, in words.
fn diagnosis(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let Some(d) = &report.diagnosis else {
        return Ok(());
    };
    let (adequate, checks, effects, notes) = d.parts();
    x.open("dcc:result", &[("refType", "polycal_diagnosis")]);
    x.content("dcc:name", "Diagnosis of the measurement model")?;
    x.content(
        "dcc:description",
        "The residuals of the fit examined for effects the model lacks (drifts, jumps of an autocollimator's zero, outliers, direction offsets, cross-talk, temperature); the effects found are added to the model and the final model checked. The results above are those of the evaluation without the effects; when effects were found, the final model's results follow (refType polycal_finalModel…).",
    )?;
    x.open("dcc:data", &[]);
    x.open("dcc:quantity", &[("refType", "polycal_adequacy")]);
    x.content("dcc:name", "The final model is adequate")?;
    x.content(
        "dcc:noQuantity",
        if adequate { "adequate" } else { "not adequate" },
    )?;
    x.close();
    let mut lines: Vec<String> = Vec::new();
    if effects.is_empty() {
        lines.push("Effects found: none.".into());
    }
    for e in effects {
        let (kind, fields, value, u) = effect_text(e);
        // the value with its standard uncertainty as GUM 7.2.6 states them
        let value = match (value, u) {
            (Some(v), Some(u)) => match crate::certificate::rounding::round_result(v, u) {
                Some(r) => format!(": {} (u = {})", r.value, r.expanded_u),
                None => format!(": {v} (u = {u})"),
            },
            (Some(v), None) => format!(": {v}"),
            _ => String::new(),
        };
        lines.push(format!("Effect found: {kind} ({fields}){value}."));
    }
    for c in checks {
        lines.push(format!(
            "Check {}: statistic {:.3}, limit {:.3}, {}.",
            c.name,
            c.statistic,
            c.limit,
            if c.passed { "passed" } else { "failed" }
        ));
    }
    lines.extend(notes.iter().cloned());
    for line in lines {
        x.content("dcc:text", &line)?;
    }
    x.close();
    x.close();
    Ok(())
}

/// The diagnosis's final model, when it added effects: its results as the evaluation's,
/// under the `polycal_finalModel…` refTypes.
fn final_model(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    match &report.diagnosis {
        Some(DiagnosisReport::Polygon(d)) if !d.effects.is_empty() => {
            polygon_results(x, &d.after, Stage::FinalModel)
        }
        Some(DiagnosisReport::Selfcal(d)) if !d.effects.is_empty() => {
            selfcal_results(x, &d.after, Stage::FinalModel)
        }
        _ => Ok(()),
    }
}

/// The comparison with the reference: En of every row and the verdict.
fn comparison(x: &mut Xml, report: &CalibrationReport) -> Result<(), DccError> {
    let Some((c, reference)) = &report.comparison else {
        return Ok(());
    };
    x.open("dcc:result", &[("refType", "polycal_comparison")]);
    x.content("dcc:name", "Comparison with the reference result by En")?;
    x.content(
        "dcc:description",
        &format!(
            "En = (a − b)/√(U_a² + U_b²) (ISO 13528) against {reference}; correlation {}. Rows labelled quantity_index.",
            c.correlation
        ),
    )?;
    x.open("dcc:data", &[]);
    x.open("dcc:list", &[]);
    Column {
        refs: "polycal_en",
        name: "En",
        unit: "\\one",
        labels: Some(
            c.rows
                .iter()
                .map(|r| format!("{}_{}", r.quantity.name(), r.index))
                .collect(),
        ),
        values: c.rows.iter().map(|r| r.en).collect(),
        expanded: None,
        // to two decimals (more where two would hide |En| > 1), as the report shows it
        form: Form::En,
    }
    .write(x)?;
    x.close();
    x.content(
        "dcc:text",
        &format!(
            "Verdict: {}. Largest |En| = {}.",
            c.verdict_sentence(),
            crate::certificate::rounding::en_text(c.max_abs_en)
        ),
    )?;
    x.close();
    x.close();
    Ok(())
}
