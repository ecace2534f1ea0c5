//! `measurementResults` of a DCC: the method, the software, the equipment, the
//! conditions and the results — β, φ, α (or a self-calibration's e and head errors) as
//! D-SI lists with U, k and p per value, the fit, the diagnosis, the comparison — and the
//! SHA-256 of every input.

use super::xml::{self, Xml};
use super::{DccError, METHOD_REFERENCE, equipment, software};
use crate::certificate::{CalibrationReport, DesignSummary, Evaluation, effect_text};
use crate::output::SolveReport;
use crate::output::selfcal::SelfcalReport;

/// A D-SI list of values with one unit, and per value its U, k and p when given.
struct Column<'a> {
    refs: &'a str,
    name: &'a str,
    unit: &'a str,
    labels: Option<Vec<String>>,
    values: Vec<f64>,
    /// (U, k) per value, and p.
    expanded: Option<(Vec<f64>, Vec<f64>, f64)>,
}

impl Column<'_> {
    fn write(&self, x: &mut Xml) -> Result<(), DccError> {
        x.open("dcc:quantity", &[("refType", self.refs)]);
        x.content("dcc:name", self.name)?;
        x.open("si:realListXMLList", &[]);
        if let Some(labels) = &self.labels {
            x.text("si:labelXMLList", &[], &labels.join(" "))?;
        }
        let what = |i: usize| format!("{} {}", self.name, i + 1);
        let values = self
            .values
            .iter()
            .enumerate()
            .map(|(i, &v)| xml::real(v, &what(i)))
            .collect::<Result<Vec<_>, _>>()?;
        x.text("si:valueXMLList", &[], &values.join(" "))?;
        x.text("si:unitXMLList", &[], self.unit)?;
        if let Some((expanded_u, k, p)) = &self.expanded {
            let expanded_u = expanded_u
                .iter()
                .enumerate()
                .map(|(i, &u)| xml::uncertainty(u, &format!("U of {}", what(i))))
                .collect::<Result<Vec<_>, _>>()?;
            let k = k
                .iter()
                .enumerate()
                .map(|(i, &k)| xml::coverage_factor(k, &what(i)))
                .collect::<Result<Vec<_>, _>>()?;
            let p = vec![xml::coverage_probability(*p)?; k.len()];
            x.open("si:expandedUncXMLList", &[]);
            x.text("si:uncertaintyXMLList", &[], &expanded_u.join(" "))?;
            x.text("si:coverageFactorXMLList", &[], &k.join(" "))?;
            x.text("si:coverageProbabilityXMLList", &[], &p.join(" "))?;
            x.close();
        }
        x.close();
        x.close();
        Ok(())
    }
}

/// One `result` of a list of columns.
fn list_result(
    x: &mut Xml,
    refs: &str,
    item: Option<&str>,
    name: &str,
    description: &str,
    columns: &[Column],
) -> Result<(), DccError> {
    let mut attributes = vec![("refType", refs)];
    if let Some(item) = item {
        attributes.push(("refId", item));
    }
    x.open("dcc:result", &attributes);
    x.content("dcc:name", name)?;
    x.content("dcc:description", description)?;
    x.open("dcc:data", &[]);
    x.open("dcc:list", &[]);
    for column in columns {
        column.write(x)?;
    }
    x.close();
    x.close();
    x.close();
    Ok(())
}

/// One `result` of a single value.
fn real_result(
    x: &mut Xml,
    refs: &str,
    name: &str,
    value: f64,
    unit: &str,
) -> Result<(), DccError> {
    x.open("dcc:result", &[("refType", refs)]);
    x.content("dcc:name", name)?;
    x.open("dcc:data", &[]);
    x.open("dcc:quantity", &[]);
    x.open("si:real", &[]);
    x.text("si:value", &[], &xml::real(value, name)?)?;
    x.text("si:unit", &[], unit)?;
    x.close();
    x.close();
    x.close();
    x.close();
    Ok(())
}

/// Index labels `prefix1 prefix2 …` from the numbers given.
fn labels(prefix: &str, numbers: impl Iterator<Item = usize>) -> Vec<String> {
    numbers.map(|n| format!("{prefix}{n}")).collect()
}

/// The k of each value, refused when one is missing.
fn every_k(k: &[Option<f64>], what: &'static str) -> Result<Vec<f64>, DccError> {
    k.iter()
        .map(|k| k.ok_or(DccError::NoExpandedUncertainty { what }))
        .collect()
}

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
        "The uncertainties were evaluated according to the GUM (JCGM 100:2008), {source}. Each expanded uncertainty U = k·u is stated for the coverage probability{p}; each value's coverage factor k is Student's t for its effective degrees of freedom (Welch–Satterthwaite). The results relate only to the items calibrated."
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
                    "Each reading is modelled as α[p mod N] + φ[face] + U[mounting, autocollimator] + noise, with Σα = 0 and Σβ = 0 (the reference's eqs. (1)–(3)); solved by polycal's {} solver ({} engine). Design: {}",
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
        Evaluation::Polygon { solve, .. } => polygon_results(x, solve)?,
        Evaluation::Selfcal { report: r, .. } => selfcal_results(x, r)?,
    }
    diagnosis(x, report)?;
    comparison(x, report)?;
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
                crate::output::SOFTWARE_VERSION,
                report.generated_utc
            ),
            None => format!(
                "Written by polycal {} at {} UTC.",
                crate::output::SOFTWARE_VERSION,
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

/// `influenceConditions`: temperature, humidity, pressure, environment, the setup errors,
/// a stated cross-talk. None given: no element.
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
        x.open("dcc:quantity", &[]);
        x.open("si:real", &[]);
        x.text("si:value", &[], &xml::real(value, name)?)?;
        x.text("si:unit", &[], unit)?;
        x.close();
        x.close();
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
    if let Evaluation::Polygon { solve, .. } = &report.evaluation
        && !solve.setup_error.is_empty()
    {
        begin(x);
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
        x.open(
            "dcc:influenceCondition",
            &[("refType", "polycal_setupErrors")],
        );
        x.content("dcc:name", "Setup errors U of the autocollimators")?;
        x.content(
            "dcc:description",
            "The zero of each autocollimator in each mounting of the polygon, estimated with β and α (the reference's U₁, U₂); labelled mounting_autocollimator.",
        )?;
        x.open("dcc:data", &[]);
        Column {
            refs: "polycal_setupError",
            name: "Setup error U",
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
        }
        .write(x)?;
        x.close();
        x.close();
    }
    if any {
        x.close();
    }
    Ok(())
}

/// β, φ and α with U, k, p, and the fit.
fn polygon_results(x: &mut Xml, solve: &SolveReport) -> Result<(), DccError> {
    let missing = DccError::NoExpandedUncertainty {
        what: "the polygon calibration",
    };
    let (
        Some(p),
        Some(beta_u),
        Some(beta_k),
        Some(phi_u),
        Some(phi_k),
        Some(alpha_u),
        Some(alpha_k),
    ) = (
        solve.p,
        &solve.pitch_deviation_expanded_u,
        &solve.pitch_deviation_k,
        &solve.face_deviation_expanded_u,
        &solve.face_deviation_k,
        &solve.encoder_error_expanded_u,
        &solve.encoder_error_k,
    )
    else {
        return Err(missing);
    };
    let n = solve.faces;
    let face_numbers = || (1..=n).map(|f| f as f64).collect::<Vec<_>>();
    list_result(
        x,
        "polycal_pitchDeviations",
        Some("polygon"),
        "Pitch deviations β of the polygon",
        "β[k] is the deviation of the angle between faces k−1 and k (face 0 is face N) from 360°/N, arcseconds; Σβ = 0 (the reference's eq. (1)). One value per face, with its expanded uncertainty U, coverage factor k and coverage probability.",
        &[
            Column {
                refs: "polycal_faceNumber",
                name: "Face",
                unit: "\\one",
                labels: None,
                values: face_numbers(),
                expanded: None,
            },
            Column {
                refs: "basic_measurementError polycal_pitchDeviation",
                name: "Pitch deviation β",
                unit: "\\arcsecond",
                labels: Some(labels("beta", 1..=n)),
                values: solve.pitch_deviation.clone(),
                expanded: Some((beta_u.clone(), every_k(beta_k, "a pitch deviation")?, p)),
            },
        ],
    )?;
    // φ[N] = 0 by definition (the reference face): no uncertainty, not listed
    let m = n.saturating_sub(1);
    list_result(
        x,
        "polycal_faceDeviations",
        Some("polygon"),
        "Face deviations φ of the polygon",
        "φ[f] = β[1] + … + β[f] is the deviation of face f's angle from f·360°/N, arcseconds, with face N the reference (φ[N] = 0 by definition, not listed).",
        &[
            Column {
                refs: "polycal_faceNumber",
                name: "Face",
                unit: "\\one",
                labels: None,
                values: face_numbers()[..m].to_vec(),
                expanded: None,
            },
            Column {
                refs: "basic_measurementError polycal_faceDeviation",
                name: "Face deviation φ",
                unit: "\\arcsecond",
                labels: Some(labels("phi", 1..=m)),
                values: solve.face_deviation[..m].to_vec(),
                expanded: Some((
                    phi_u[..m].to_vec(),
                    every_k(&phi_k[..m], "a face deviation")?,
                    p,
                )),
            },
        ],
    )?;
    let angles = solve.encoder_angle_deg.clone().unwrap_or_else(|| {
        let positions = solve.encoder_error.len();
        (0..positions)
            .map(|step| crate::measurement::step_angle_deg(step as u32, positions))
            .collect()
    });
    list_result(
        x,
        "polycal_encoderErrors",
        Some("encoder"),
        "Encoder errors α of the rotary table",
        "α[p] is the error of the encoder at step p, the table at p·360°/N, arcseconds; Σα = 0 (the reference's eq. (3)).",
        &[
            Column {
                refs: "basic_nominalValue polycal_tableAngle",
                name: "Table angle",
                unit: "\\degree",
                labels: None,
                values: angles,
                expanded: None,
            },
            Column {
                refs: "basic_measurementError polycal_encoderError",
                name: "Encoder error α",
                unit: "\\arcsecond",
                labels: Some(labels("alpha", 0..solve.encoder_error.len())),
                values: solve.encoder_error.clone(),
                expanded: Some((alpha_u.clone(), every_k(alpha_k, "an encoder error")?, p)),
            },
        ],
    )?;
    fit(x, solve.residual_rms, solve.dof)
}

/// The residual RMS and the degrees of freedom of the fit.
fn fit(x: &mut Xml, residual_rms: Option<f64>, dof: usize) -> Result<(), DccError> {
    if let Some(rms) = residual_rms {
        real_result(
            x,
            "polycal_residualRms",
            "Residual RMS of the fit",
            rms,
            "\\arcsecond",
        )?;
    }
    real_result(
        x,
        "polycal_residualDof",
        "Residual degrees of freedom of the fit",
        dof as f64,
        "\\one",
    )
}

/// A self-calibration's e and head errors with U, k, p, and the fit.
fn selfcal_results(x: &mut Xml, r: &SelfcalReport) -> Result<(), DccError> {
    let (Some(expanded_u), Some(k)) = (&r.encoder_error_expanded_u, &r.encoder_error_k) else {
        return Err(DccError::NoExpandedUncertainty {
            what: "the self-calibration (σ of the readings unknown)",
        });
    };
    let mut description =
        "e[p] is the encoder error at position p, arcseconds, with Σe = 0.".to_string();
    for note in &r.notes {
        description.push(' ');
        description.push_str(note);
        description.push('.');
    }
    list_result(
        x,
        "polycal_encoderErrors",
        Some("encoder"),
        "Encoder errors e of the rotary table",
        &description,
        &[
            Column {
                refs: "basic_nominalValue polycal_tableAngle",
                name: "Table angle",
                unit: "\\degree",
                labels: None,
                values: r.encoder_angle_deg.clone(),
                expanded: None,
            },
            Column {
                refs: "basic_measurementError polycal_encoderError",
                name: "Encoder error e",
                unit: "\\arcsecond",
                labels: Some(labels("e", 0..r.encoder_error.len())),
                values: r.encoder_error.clone(),
                expanded: Some((expanded_u.clone(), k.clone(), r.p)),
            },
        ],
    )?;
    if !r.head_error.is_empty() {
        let expanded = r
            .head_error
            .iter()
            .map(|h| h.expanded_u.zip(h.k))
            .collect::<Option<Vec<_>>>()
            .ok_or(DccError::NoExpandedUncertainty {
                what: "a head error",
            })?;
        list_result(
            x,
            "polycal_headErrors",
            Some("encoder"),
            "Errors of the reading heads",
            "c[j] − c[1]: the error of head j's angle relative to head 1, arcseconds, at the head's nominal angle.",
            &[
                Column {
                    refs: "basic_nominalValue polycal_headAngle",
                    name: "Head angle",
                    unit: "\\degree",
                    labels: None,
                    values: r.head_error.iter().map(|h| h.angle_deg).collect(),
                    expanded: None,
                },
                Column {
                    refs: "basic_measurementError polycal_headError",
                    name: "Head error",
                    unit: "\\arcsecond",
                    labels: Some(
                        r.head_error
                            .iter()
                            .map(|h| format!("head{}", h.head))
                            .collect(),
                    ),
                    values: r.head_error.iter().map(|h| h.value).collect(),
                    expanded: Some((
                        expanded.iter().map(|e| e.0).collect(),
                        expanded.iter().map(|e| e.1).collect(),
                        r.p,
                    )),
                },
            ],
        )?;
    }
    fit(x, r.residual_rms, r.dof)
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
        "The residuals of the fit examined for effects the model lacks (drifts, jumps of an autocollimator's zero, outliers, direction offsets, cross-talk, temperature); the effects found are added to the model and the final model checked. The results above are those of the evaluation without the effects.",
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
        let value = match (value, u) {
            (Some(v), Some(u)) => format!(": {v} (u = {u})"),
            (Some(v), None) => format!(": {v}"),
            _ => String::new(),
        };
        lines.push(format!("Effect found: {kind} ({fields}){value}."));
    }
    for c in checks {
        lines.push(format!(
            "Check {}: statistic {}, limit {}, {}.",
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
    }
    .write(x)?;
    x.close();
    x.content(
        "dcc:text",
        &format!(
            "Largest |En| = {}: {}.",
            c.max_abs_en,
            if c.verdict_ok() {
                "every |En| ≤ 1, the results agree"
            } else {
                "some |En| > 1, the results do NOT agree"
            }
        ),
    )?;
    x.close();
    x.close();
    Ok(())
}
