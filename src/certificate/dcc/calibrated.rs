//! The calibrated quantities of a DCC as D-SI lists — β, φ, α, or a self-calibration's e
//! and head errors, each value with its U, k and p — and the fit, for the evaluation and
//! for the diagnosis's final model.

use super::DccError;
use super::xml::{self, Xml};
use crate::certificate::rounding::{round_coverage_factor, round_result};
use crate::output::SolveReport;
use crate::output::selfcal::SelfcalReport;
use crate::results::Quantity;
use crate::results::certificate::{FACE_NUMBER_REF_TYPE, TABLE_ANGLE_REF_TYPE, quantity_ref_type};

/// Whose results: the evaluation's (the HTML report's results section) or the
/// diagnosis's final model (its section's final tables).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Stage {
    /// The evaluation without the diagnosis's effects.
    Evaluation,
    /// The diagnosis's final model, its effects included.
    FinalModel,
}

impl Stage {
    /// The result's `refType`: `polycal_pitchDeviations`, or
    /// `polycal_finalModelPitchDeviations` for the final model.
    pub(super) fn ref_type(self, base: &str) -> String {
        match self {
            Stage::Evaluation => format!("polycal_{base}"),
            Stage::FinalModel => {
                let mut chars = base.chars();
                let first = chars.next().map(|c| c.to_ascii_uppercase());
                format!(
                    "polycal_finalModel{}{}",
                    first.map(String::from).unwrap_or_default(),
                    chars.as_str()
                )
            }
        }
    }

    /// The result's name, `Final model: …` for the final model.
    pub(super) fn name(self, base: &str) -> String {
        match self {
            Stage::Evaluation => base.to_string(),
            Stage::FinalModel => format!("Final model of the diagnosis: {base}"),
        }
    }
}

/// A D-SI list of values with one unit, and per value its U, k and p when given.
pub(super) struct Column<'a> {
    pub(super) refs: &'a str,
    pub(super) name: &'a str,
    pub(super) unit: &'a str,
    pub(super) labels: Option<Vec<String>>,
    pub(super) values: Vec<f64>,
    /// (U, k) per value, and p: the values and U rounded by GUM 7.2.6 and k to three
    /// significant digits ([`crate::certificate::rounding`]).
    pub(super) expanded: Option<(Vec<f64>, Vec<f64>, f64)>,
    /// How the values without U are written.
    pub(super) form: Form,
}

/// How a column's values without an expanded uncertainty are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Form {
    /// At full precision: the shortest text that reads back to the double.
    Real,
    /// Whole numbers (face numbers), without a decimal point.
    Whole,
    /// An En number as the HTML report shows it ([`crate::certificate::rounding::en_text`]).
    En,
}

impl Column<'_> {
    pub(super) fn write(&self, x: &mut Xml) -> Result<(), DccError> {
        x.open("dcc:quantity", &[("refType", self.refs)]);
        x.content("dcc:name", self.name)?;
        x.open("si:realListXMLList", &[]);
        if let Some(labels) = &self.labels {
            x.text("si:labelXMLList", &[], &labels.join(" "))?;
        }
        let what = |i: usize| format!("{} {}", self.name, i + 1);
        let mut values = self
            .values
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let text = xml::real(v, &what(i))?;
                Ok(match self.form {
                    Form::Whole if v.fract() == 0.0 && v.abs() < 1e15 => format!("{v:.0}"),
                    Form::En => crate::certificate::rounding::en_text(v),
                    _ => text,
                })
            })
            .collect::<Result<Vec<_>, DccError>>()?;
        let rounded = match &self.expanded {
            Some((expanded_u, k, p)) => {
                let mut u_texts = Vec::with_capacity(expanded_u.len());
                for (i, &u) in expanded_u.iter().enumerate() {
                    // checked as D-SI takes it, then rounded (GUM 7.2.6)
                    xml::uncertainty(u, &format!("U of {}", what(i)))?;
                    let r = round_result(self.values.get(i).copied().unwrap_or(0.0), u).ok_or(
                        DccError::NotFinite {
                            what: format!("U of {}", what(i)),
                        },
                    )?;
                    if let Some(value) = values.get_mut(i) {
                        *value = r.value;
                    }
                    u_texts.push(r.expanded_u);
                }
                let k = k
                    .iter()
                    .enumerate()
                    .map(|(i, &k)| {
                        xml::coverage_factor(k, &what(i))?;
                        round_coverage_factor(k)
                            .ok_or(DccError::CoverageFactor { what: what(i), k })
                    })
                    .collect::<Result<Vec<_>, _>>()?;
                Some((u_texts, k, *p))
            }
            None => None,
        };
        x.text("si:valueXMLList", &[], &values.join(" "))?;
        x.text("si:unitXMLList", &[], self.unit)?;
        if let Some((expanded_u, k, p)) = rounded {
            let p = vec![xml::coverage_probability(p)?; k.len()];
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
    real_quantity(x, value, unit, name)?;
    x.close();
    x.close();
    Ok(())
}

/// `<dcc:quantity><si:real>` of one value and its unit (`what` names it in a refusal).
pub(super) fn real_quantity(
    x: &mut Xml,
    value: f64,
    unit: &str,
    what: &str,
) -> Result<(), DccError> {
    x.open("dcc:quantity", &[]);
    x.open("si:real", &[]);
    let text = xml::real(value, what)?;
    // a whole number (degrees of freedom) without a decimal point
    let text = if value.fract() == 0.0 && value.abs() < 1e15 {
        format!("{value:.0}")
    } else {
        text
    };
    x.text("si:value", &[], &text)?;
    x.text("si:unit", &[], unit)?;
    x.close();
    x.close();
    Ok(())
}

/// The `refType` of a quantity's values: `basic_measurementError` and polycal's name of
/// the quantity, the one a certificate is read back by (`results::certificate`).
fn measured(quantity: Quantity) -> String {
    format!("basic_measurementError {}", quantity_ref_type(quantity))
}

/// The `refType` of the table angles beside encoder errors.
fn table_angle() -> String {
    format!("basic_nominalValue {TABLE_ANGLE_REF_TYPE}")
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

/// β, φ and α with U, k, p, and the fit.
pub(super) fn polygon_results(
    x: &mut Xml,
    solve: &SolveReport,
    stage: Stage,
) -> Result<(), DccError> {
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
        &stage.ref_type("pitchDeviations"),
        Some("polygon"),
        &stage.name("Pitch deviations β of the polygon"),
        "β[k] is the deviation of the angle between faces k−1 and k (face 0 is face N) from 360°/N, arcseconds; Σβ = 0 (the reference's eq. (1)). One value per face, with its expanded uncertainty U, coverage factor k and coverage probability.",
        &[
            Column {
                refs: FACE_NUMBER_REF_TYPE,
                name: "Face",
                unit: "\\one",
                labels: None,
                values: face_numbers(),
                expanded: None,
                form: Form::Whole,
            },
            Column {
                refs: &measured(Quantity::PitchDeviation),
                name: "Pitch deviation β",
                unit: "\\arcsecond",
                labels: Some(labels("beta", 1..=n)),
                values: solve.pitch_deviation.clone(),
                expanded: Some((beta_u.clone(), every_k(beta_k, "a pitch deviation")?, p)),
                form: Form::Real,
            },
        ],
    )?;
    // φ[N] = 0 by definition (the reference face): no uncertainty, not listed
    let m = n.saturating_sub(1);
    list_result(
        x,
        &stage.ref_type("faceDeviations"),
        Some("polygon"),
        &stage.name("Face deviations φ of the polygon"),
        "φ[f] = β[1] + … + β[f] is the deviation of face f's angle from f·360°/N, arcseconds, with face N the reference (φ[N] = 0 by definition, not listed).",
        &[
            Column {
                refs: FACE_NUMBER_REF_TYPE,
                name: "Face",
                unit: "\\one",
                labels: None,
                values: face_numbers()[..m].to_vec(),
                expanded: None,
                form: Form::Whole,
            },
            Column {
                refs: &measured(Quantity::FaceDeviation),
                name: "Face deviation φ",
                unit: "\\arcsecond",
                labels: Some(labels("phi", 1..=m)),
                values: solve.face_deviation[..m].to_vec(),
                expanded: Some((
                    phi_u[..m].to_vec(),
                    every_k(&phi_k[..m], "a face deviation")?,
                    p,
                )),
                form: Form::Real,
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
        &stage.ref_type("encoderErrors"),
        Some("encoder"),
        &stage.name("Encoder errors α of the rotary table"),
        "α[p] is the error of the encoder at step p, the table at p·360°/N, arcseconds; Σα = 0 (the reference's eq. (3)).",
        &[
            Column {
                refs: &table_angle(),
                name: "Table angle",
                unit: "\\degree",
                labels: None,
                values: angles,
                expanded: None,
                form: Form::Real,
            },
            Column {
                refs: &measured(Quantity::EncoderError),
                name: "Encoder error α",
                unit: "\\arcsecond",
                labels: Some(labels("alpha", 0..solve.encoder_error.len())),
                values: solve.encoder_error.clone(),
                expanded: Some((alpha_u.clone(), every_k(alpha_k, "an encoder error")?, p)),
                form: Form::Real,
            },
        ],
    )?;
    fit(x, solve.residual_rms, solve.dof, stage)
}

/// The residual RMS and the degrees of freedom of the fit.
fn fit(x: &mut Xml, residual_rms: Option<f64>, dof: usize, stage: Stage) -> Result<(), DccError> {
    if let Some(rms) = residual_rms {
        real_result(
            x,
            &stage.ref_type("residualRms"),
            &stage.name("Residual RMS of the fit"),
            rms,
            "\\arcsecond",
        )?;
    }
    real_result(
        x,
        &stage.ref_type("residualDof"),
        &stage.name("Residual degrees of freedom of the fit"),
        dof as f64,
        "\\one",
    )
}

/// A self-calibration's e and head errors with U, k, p, and the fit.
pub(super) fn selfcal_results(
    x: &mut Xml,
    r: &SelfcalReport,
    stage: Stage,
) -> Result<(), DccError> {
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
        &stage.ref_type("encoderErrors"),
        Some("encoder"),
        &stage.name("Encoder errors e of the rotary table"),
        &description,
        &[
            Column {
                refs: &table_angle(),
                name: "Table angle",
                unit: "\\degree",
                labels: None,
                values: r.encoder_angle_deg.clone(),
                expanded: None,
                form: Form::Real,
            },
            Column {
                refs: &measured(Quantity::EncoderError),
                name: "Encoder error e",
                unit: "\\arcsecond",
                labels: Some(labels("e", 0..r.encoder_error.len())),
                values: r.encoder_error.clone(),
                expanded: Some((expanded_u.clone(), k.clone(), r.p)),
                form: Form::Real,
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
            &stage.ref_type("headErrors"),
            Some("encoder"),
            &stage.name("Errors of the reading heads"),
            "c[j] − c[1]: the error of head j's angle relative to head 1, arcseconds, at the head's nominal angle.",
            &[
                Column {
                    refs: "basic_nominalValue polycal_headAngle",
                    name: "Head angle",
                    unit: "\\degree",
                    labels: None,
                    values: r.head_error.iter().map(|h| h.angle_deg).collect(),
                    expanded: None,
                    form: Form::Real,
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
                    form: Form::Real,
                },
            ],
        )?;
    }
    fit(x, r.residual_rms, r.dof, stage)
}
