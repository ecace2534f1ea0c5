//! The figures of `polycal plan`: the predicted u along the circle for each design —
//! u(α) against the table angle and u(β) against the face's angle — one series per
//! design (markers cycle through the three greyscale shapes, `data-series` is the
//! design's position in the list, from 0).

use super::Figure;
use super::chart::{Chart, Point, Series};
use super::svg::Marker;

/// The x values and u values of one design's series.
type Values<'a> = &'a dyn Fn(&PlanReport) -> (Vec<f64>, Vec<f64>);
use crate::output::plan::PlanReport;

const MARKERS: [Marker; 3] = [Marker::FilledCircle, Marker::OpenSquare, Marker::Triangle];

/// u(α) and u(β) of every design that determines them.
pub(crate) fn figures(reports: &[PlanReport]) -> Vec<Figure> {
    let planned: Vec<(usize, &PlanReport)> = reports
        .iter()
        .enumerate()
        .filter(|(_, r)| r.encoder_error_u.is_some())
        .collect();
    if planned.is_empty() {
        return Vec::new();
    }
    let left_out = reports.len() - planned.len();
    let mut subtitles = vec![format!(
        "predicted standard uncertainties (k = 1) for σ = {}″ of one reading",
        reports[0].sigma
    )];
    if left_out > 0 {
        subtitles.push(format!(
            "{left_out} design(s) that cannot calibrate (lost harmonics) are not drawn"
        ));
    }
    let count = planned.len();
    let series = |values: Values| -> Vec<Series> {
        planned
            .iter()
            .map(|&(index, r)| {
                let (x, y) = values(r);
                Series {
                    id: index.to_string(),
                    label: r.name.clone(),
                    marker: MARKERS[index % MARKERS.len()],
                    dx_px: if count > 1 {
                        (index as f64 - (count as f64 - 1.0) / 2.0) * 2.0
                    } else {
                        0.0
                    },
                    points: x
                        .iter()
                        .zip(&y)
                        .enumerate()
                        .map(|(i, (&x, &y))| Point {
                            index: i,
                            x,
                            y,
                            half: None,
                        })
                        .collect(),
                }
            })
            .collect()
    };
    let title = "Predicted u(α) along the circle".to_string();
    let alpha = Chart {
        title: title.clone(),
        subtitles: subtitles.clone(),
        x_label: "table angle / °".into(),
        y_label: "u(α) / ″".into(),
        series: series(&|r: &PlanReport| {
            (
                r.encoder_angle_deg.clone().unwrap_or_default(),
                r.encoder_error_u.clone().unwrap_or_default(),
            )
        }),
        x_include: vec![0.0, 360.0, 0.0],
    };
    let mut out = vec![Figure::new("plan-encoder-error-u", title, alpha.render())];
    let title = "Predicted u(β) along the circle".to_string();
    let beta = Chart {
        title: title.clone(),
        subtitles,
        x_label: "face angle / °".into(),
        y_label: "u(β) / ″".into(),
        series: series(&|r: &PlanReport| {
            let u = r.pitch_deviation_u.clone().unwrap_or_default();
            let n = u.len().max(1) as f64;
            ((0..u.len()).map(|k| 360.0 * k as f64 / n).collect(), u)
        }),
        x_include: vec![0.0, 360.0, 0.0],
    };
    out.push(Figure::new("plan-pitch-deviation-u", title, beta.render()));
    out
}
