//! The figures of `polycal selfcal`: the graduation error e at every position against its
//! angle with U bars, and the heads' errors c against the heads' angles.

use super::Figure;
use super::chart::{Chart, Point, Series, k_text};
use super::svg::Marker;
use crate::output::selfcal::SelfcalReport;

fn p_text(p: f64) -> String {
    let text = format!("{:.2}", 100.0 * p);
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// `selfcal-encoder-error` and `selfcal-head-error`.
pub(crate) fn figures(report: &SelfcalReport) -> Vec<Figure> {
    let mut out = Vec::new();
    let (bars, text) = match (&report.encoder_error_expanded_u, &report.encoder_error_u) {
        (Some(big), _) => (
            Some(big.clone()),
            format!(
                "error bars: U (p = {} %), {}{}",
                p_text(report.p),
                report
                    .encoder_error_k
                    .as_ref()
                    .map_or("k unknown".into(), |k| k_text(k)),
                if report.uncertainty.is_some() {
                    ", from the instrument budget"
                } else {
                    ", type A of the fit"
                }
            ),
        ),
        (None, Some(u)) => (Some(u.clone()), "error bars: u (k = 1)".to_string()),
        (None, None) => (None, "no error bars: σ of a reading is unknown".to_string()),
    };
    let title = format!(
        "Graduation errors e with U — {}",
        crate::input::document_name(&report.file)
    );
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![format!(
            "{} positions, {} heads, {} cycles; {text}",
            report.positions, report.heads, report.cycles
        )],
        x_label: "angle / °".into(),
        y_label: "graduation error e / ″".into(),
        series: vec![Series {
            id: "e".into(),
            label: "e".into(),
            marker: Marker::FilledCircle,
            dx_px: 0.0,
            points: report
                .encoder_error
                .iter()
                .enumerate()
                .map(|(i, &y)| Point {
                    index: i,
                    x: report.encoder_angle_deg.get(i).copied().unwrap_or(f64::NAN),
                    y,
                    half: bars.as_ref().and_then(|b| b.get(i).copied()),
                })
                .collect(),
        }],
        x_include: vec![0.0, 360.0],
    };
    out.push(Figure::new("selfcal-encoder-error", title, chart.render()));

    if !report.head_error.is_empty() {
        let with_big = report.head_error.iter().all(|h| h.expanded_u.is_some());
        let text = if with_big {
            let ks: Vec<f64> = report.head_error.iter().filter_map(|h| h.k).collect();
            format!(
                "error bars: U (p = {} %), {}",
                p_text(report.p),
                k_text(&ks)
            )
        } else if report.head_error.iter().all(|h| h.u.is_some()) {
            "error bars: u (k = 1)".into()
        } else {
            "no error bars: σ of a reading is unknown".into()
        };
        let title = format!(
            "Head errors c with U — {}",
            crate::input::document_name(&report.file)
        );
        let chart = Chart {
            title: title.clone(),
            subtitles: vec![format!(
                "heads 2 … {} at their angles from head 1 (head 1 is the reference); {text}",
                report.heads
            )],
            x_label: "head angle from head 1 / °".into(),
            y_label: "head error c / ″".into(),
            series: vec![Series {
                id: "c".into(),
                label: "c".into(),
                marker: Marker::Triangle,
                dx_px: 0.0,
                points: report
                    .head_error
                    .iter()
                    .enumerate()
                    .map(|(i, h)| Point {
                        index: i,
                        x: h.angle_deg,
                        y: h.value,
                        half: if with_big { h.expanded_u } else { h.u },
                    })
                    .collect(),
            }],
            x_include: Vec::new(),
        };
        out.push(Figure::new("selfcal-head-error", title, chart.render()));
    }
    out
}
