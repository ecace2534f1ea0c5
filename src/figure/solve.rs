//! The figures of `polycal solve`: β and φ per face, α against the table angle, each with
//! its expanded uncertainty U as error bars, and (with a budget) the budget's figures.
//!
//! U is the report's own when it carries one (`*_U` with `*_k`, from an instrument
//! budget); otherwise U = k·u with k Student's t at p = 95 % for the fit's residual
//! degrees of freedom (type A only), or 1.96 for a stated σ (ν = ∞).

use super::Figure;
use super::chart::{Chart, Point, Series, k_text};
use super::svg::Marker;
use crate::output::SolveReport;
use crate::uncertainty::student::t_quantile;

/// Coverage probability of U when the report has no budget.
pub(crate) const P_TYPE_A: f64 = 0.95;

/// The error bars of one family and the sentence that says what they are.
pub(crate) struct Bars {
    /// Half-length of each bar (U), or none when σ is unknown.
    pub expanded_u: Option<Vec<f64>>,
    /// What the bars are.
    pub text: String,
}

/// U of one family of a solve report: the budget's U, else k·u for the fit's type A.
pub(crate) fn bars(
    report: &SolveReport,
    u: Option<&Vec<f64>>,
    expanded_u: Option<&Vec<f64>>,
    k: Option<&Vec<Option<f64>>>,
) -> Bars {
    if let Some(big) = expanded_u {
        let ks: Vec<f64> = k.map_or(Vec::new(), |k| k.iter().flatten().copied().collect());
        let p = report.p.unwrap_or(f64::NAN);
        return Bars {
            expanded_u: Some(big.clone()),
            text: format!(
                "error bars: U from the instrument budget (p = {:.4} %), {} (Welch–Satterthwaite)",
                100.0 * p,
                k_text(&ks)
            )
            .replace(".0000 %", " %"),
        };
    }
    let Some(u) = u else {
        return Bars {
            expanded_u: None,
            text: "no error bars: σ of a reading is unknown (no residual degrees of freedom and none stated)".into(),
        };
    };
    let (dof, nu_text) = match report.sigma_source {
        Some("stated") => (None, "σ stated, ν = ∞".to_string()),
        _ => (Some(report.dof as f64), format!("ν = {}", report.dof)),
    };
    let k = t_quantile(P_TYPE_A, dof);
    if !k.is_finite() {
        return Bars {
            expanded_u: None,
            text: "no error bars: no coverage factor for these degrees of freedom".into(),
        };
    }
    Bars {
        expanded_u: Some(u.iter().map(|u| k * u).collect()),
        text: format!("error bars: U = k·u, k = {k:.2} (p = 95 %, type A only, {nu_text})"),
    }
}

/// Points of a family: index, x, value, bar.
fn points(values: &[f64], x: impl Fn(usize) -> f64, bars: Option<&Vec<f64>>) -> Vec<Point> {
    values
        .iter()
        .enumerate()
        .map(|(i, &y)| Point {
            index: i,
            x: x(i),
            y,
            half: bars.and_then(|b| b.get(i).copied()),
        })
        .collect()
}

fn one_series(id: &str, label: &str, points: Vec<Point>) -> Vec<Series> {
    vec![Series {
        id: id.into(),
        label: label.into(),
        marker: Marker::FilledCircle,
        dx_px: 0.0,
        points,
    }]
}

/// The table angle of each encoder error of a solve report, degrees.
pub(crate) fn encoder_angles_deg(report: &SolveReport) -> Vec<f64> {
    match &report.encoder_angle_deg {
        Some(angles) => angles.clone(),
        None => {
            let n = report.encoder_error.len().max(1) as f64;
            (0..report.encoder_error.len())
                .map(|p| 360.0 * p as f64 / n)
                .collect()
        }
    }
}

/// β, φ and α (and the budget's figures when the report carries one).
pub(crate) fn figures(report: &SolveReport) -> Vec<Figure> {
    let source = report
        .file
        .as_ref()
        // a figure is a document: the file by its name alone
        .map_or(String::new(), |f| {
            format!(" — {}", crate::input::document_name(f))
        });
    let mut out = Vec::new();

    let beta = bars(
        report,
        report.pitch_deviation_u.as_ref(),
        report.pitch_deviation_expanded_u.as_ref(),
        report.pitch_deviation_k.as_ref(),
    );
    let title = format!("Pitch deviations β with U{source}");
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![format!("{} faces; {}", report.faces, beta.text)],
        x_label: "face k".into(),
        y_label: "pitch deviation β / ″".into(),
        series: one_series(
            "beta",
            "β",
            points(
                &report.pitch_deviation,
                |i| (i + 1) as f64,
                beta.expanded_u.as_ref(),
            ),
        ),
        x_include: vec![1.0, report.faces as f64],
    };
    out.push(Figure::new("pitch-deviation", title, chart.render()));

    let phi = bars(
        report,
        report.face_deviation_u.as_ref(),
        report.face_deviation_expanded_u.as_ref(),
        report.face_deviation_k.as_ref(),
    );
    let title = format!("Face deviations φ with U{source}");
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![format!(
            "φ[k] = β[1] + … + β[k], φ[N] = 0 (reference face); {}",
            phi.text
        )],
        x_label: "face k".into(),
        y_label: "face deviation φ / ″".into(),
        series: one_series(
            "phi",
            "φ",
            points(
                &report.face_deviation,
                |i| (i + 1) as f64,
                phi.expanded_u.as_ref(),
            ),
        ),
        x_include: vec![1.0, report.faces as f64],
    };
    out.push(Figure::new("face-deviation", title, chart.render()));

    let alpha = bars(
        report,
        report.encoder_error_u.as_ref(),
        report.encoder_error_expanded_u.as_ref(),
        report.encoder_error_k.as_ref(),
    );
    let angles = encoder_angles_deg(report);
    let title = format!("Encoder errors α with U{source}");
    let mut subtitle = format!("{} positions; {}", report.encoder_error.len(), alpha.text);
    if report.encoder_angle_deg.is_some() {
        subtitle.push_str("; sub-pitch mountings: see the report's notes");
    }
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![subtitle],
        x_label: "table angle / °".into(),
        y_label: "encoder error α / ″".into(),
        series: one_series(
            "alpha",
            "α",
            points(
                &report.encoder_error,
                |i| angles.get(i).copied().unwrap_or(f64::NAN),
                alpha.expanded_u.as_ref(),
            ),
        ),
        x_include: vec![0.0, 360.0],
    };
    out.push(Figure::new("encoder-error", title, chart.render()));

    if let Some(uncertainty) = &report.uncertainty {
        out.extend(super::budget::figures(uncertainty));
    }
    out
}
