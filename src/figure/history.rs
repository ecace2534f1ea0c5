//! The figure of `polycal history` (docs/FORMAT.md §13.2): a control chart per position in
//! one document, small charts three to a row, so that 24 faces read at a glance. Each
//! chart: every calibration's value with its U bar (k = 2) against its date, the chosen
//! model's line with its band ±U, from the oldest calibration to the prediction's date,
//! and the prediction with its U.
//!
//! Classes: each chart is a `<g class="position" data-index="k">` (k in the history's
//! `index` list, from 0); in it `point` and `error-bar` with `data-series` `calibrations`
//! (`data-index` the calibration, oldest first) or `prediction`, a `model-line` polyline
//! and a `model-band` polygon.

use std::fmt::Write;

use super::Figure;
use super::chart::marker_px;
use super::svg::{Axis, Marker, Panel, WIDTH_PX, document, error_bar, point, px};
use crate::history::{DAYS_PER_YEAR, History};
use crate::results::Quantity;

/// The figure's name.
pub(crate) const NAME: &str = "history-control-charts";

/// The most charts drawn (a long encoder history: those of the largest |drift|/u(drift)).
const MAX_CHARTS: usize = 60;

/// Charts per row, and their size, px.
const COLUMNS: usize = 3;
const CHART_WIDTH_PX: f64 = 164.0;
const CHART_HEIGHT_PX: f64 = 104.0;
const ROW_PX: f64 = 150.0;
const COLUMN_PX: f64 = (WIDTH_PX - 20.0) / COLUMNS as f64;

/// A date's decimal year, 1970 + days/365.25 (the x axis).
fn decimal_year(days: f64) -> f64 {
    1970.0 + days / DAYS_PER_YEAR
}

/// The figures of a history: its control charts.
pub(crate) fn figures(history: &History) -> Vec<Figure> {
    vec![control_charts(history)]
}

fn words(history: &History) -> (&'static str, &'static str) {
    match history.quantity {
        Quantity::PitchDeviation => ("pitch deviation β", "face"),
        Quantity::FaceDeviation => ("face deviation φ", "face"),
        _ => ("encoder error α", "position"),
    }
}

/// The positions drawn: all, or the [`MAX_CHARTS`] of largest |drift|/u(drift).
fn drawn(history: &History) -> Vec<usize> {
    let n = history.index.len();
    let mut all: Vec<usize> = (0..n).collect();
    if n > MAX_CHARTS {
        let score = |k: usize| {
            let u = history.drift_u[k];
            if u > 0.0 {
                (history.drift[k] / u).abs()
            } else {
                0.0
            }
        };
        all.sort_by(|a, b| score(*b).total_cmp(&score(*a)));
        all.truncate(MAX_CHARTS);
        all.sort_unstable();
    }
    all
}

fn control_charts(history: &History) -> Figure {
    let (family, position_word) = words(history);
    let title = format!("Control charts of the {family}, with U (k = 2)");
    let days: Vec<f64> = history
        .dates
        .iter()
        .filter_map(|d| crate::clock::days_from_date(d))
        .map(|d| d as f64)
        .collect();
    let at_days = crate::clock::days_from_date(&history.at).map_or(f64::NAN, |d| d as f64);
    let reference_days =
        crate::clock::days_from_date(&history.line.reference_date).map_or(f64::NAN, |d| d as f64);
    let positions = drawn(history);
    let mut subtitles = vec![
        format!(
            "{}; points: each calibration's value with U; line and band: the {} model ± U; \
             ◇ the prediction at {} with U",
            history.verdict_statement(),
            history.model.name(),
            history.at
        ),
        format!("x: date (decimal year); y: {family} / arcsec"),
    ];
    if positions.len() < history.index.len() {
        subtitles.push(format!(
            "{} of {} positions drawn: those with the largest |drift|/u(drift)",
            positions.len(),
            history.index.len()
        ));
    }
    let top = super::svg::header_px(&subtitles) + 10.0;
    let first = days.iter().copied().fold(f64::INFINITY, f64::min);
    let last = days
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max)
        .max(at_days);
    let first = first.min(at_days);
    let k = history.k;
    let mut body = String::new();
    for (slot, &p) in positions.iter().enumerate() {
        let (row, column) = (slot / COLUMNS, slot % COLUMNS);
        // the model from the first date to the last (the prediction's, when later)
        let steps = 24;
        let line: Vec<(f64, f64, f64)> = (0..=steps)
            .map(|s| {
                let d = first + (last - first) * s as f64 / steps as f64;
                let (value, u) = history.line.at(p, (d - reference_days) / DAYS_PER_YEAR);
                (d, value, k * u)
            })
            .collect();
        let ys = history
            .values
            .iter()
            .zip(&history.values_u)
            .flat_map(|(x, u)| [x[p] - k * u[p], x[p] + k * u[p]])
            .chain(line.iter().flat_map(|(_, v, h)| [v - h, v + h]))
            .chain([
                history.predicted[p] - k * history.predicted_u[p],
                history.predicted[p] + k * history.predicted_u[p],
            ]);
        let xs = [decimal_year(first), decimal_year(last)];
        let panel = Panel {
            id: "main",
            left_px: 10.0 + column as f64 * COLUMN_PX + 48.0,
            top_px: top + row as f64 * ROW_PX + 16.0,
            width_px: CHART_WIDTH_PX,
            height_px: CHART_HEIGHT_PX,
            x: Axis::covering(xs, &[], 3, ""),
            y: Axis::covering(ys, &[], 4, ""),
        };
        let _ = writeln!(
            body,
            r#"<g class="position" data-index="{slot_index}">"#,
            slot_index = p
        );
        let _ = writeln!(
            body,
            r#"<text class="chart-title" x="{}" y="{}" font-size="11" font-weight="bold">{} {}</text>"#,
            px(panel.left_px),
            px(panel.top_px - 5.0),
            position_word,
            history.index[p]
        );
        panel.draw_axes(&mut body, false);
        let upper: Vec<String> = line
            .iter()
            .map(|(d, v, h)| {
                format!(
                    "{},{}",
                    px(panel.x_px(decimal_year(*d))),
                    px(panel.y_px(v + h))
                )
            })
            .collect();
        let lower: Vec<String> = line
            .iter()
            .rev()
            .map(|(d, v, h)| {
                format!(
                    "{},{}",
                    px(panel.x_px(decimal_year(*d))),
                    px(panel.y_px(v - h))
                )
            })
            .collect();
        let _ = writeln!(
            body,
            r##"<polygon class="model-band" points="{} {}" fill="#9ecae1" fill-opacity="0.45" stroke="none"/>"##,
            upper.join(" "),
            lower.join(" ")
        );
        let centre: Vec<String> = line
            .iter()
            .map(|(d, v, _)| {
                format!(
                    "{},{}",
                    px(panel.x_px(decimal_year(*d))),
                    px(panel.y_px(*v))
                )
            })
            .collect();
        let _ = writeln!(
            body,
            r##"<polyline class="model-line" points="{}" fill="none" stroke="#08519c" stroke-width="1.2"/>"##,
            centre.join(" ")
        );
        let (r, cap) = marker_px(history.values.len() + 1);
        for (i, (x, u)) in history.values.iter().zip(&history.values_u).enumerate() {
            let Some(d) = days.get(i) else { continue };
            let xp = panel.x_px(decimal_year(*d));
            error_bar(
                &mut body,
                &panel,
                "calibrations",
                i,
                xp,
                x[p],
                k * u[p],
                cap,
            );
            point(
                &mut body,
                &panel,
                "calibrations",
                i,
                (xp, panel.y_px(x[p])),
                Marker::FilledCircle,
                r,
            );
        }
        if at_days.is_finite() {
            let xp = panel.x_px(decimal_year(at_days));
            error_bar(
                &mut body,
                &panel,
                "prediction",
                0,
                xp,
                history.predicted[p],
                k * history.predicted_u[p],
                cap,
            );
            point(
                &mut body,
                &panel,
                "prediction",
                0,
                (xp, panel.y_px(history.predicted[p])),
                Marker::OpenSquare,
                r,
            );
        }
        let _ = writeln!(body, "</g>");
    }
    let rows = positions.len().div_ceil(COLUMNS);
    let height = top + rows as f64 * ROW_PX + 10.0;
    Figure::new(
        NAME,
        title.clone(),
        document(height, &title, &subtitles, &body),
    )
}
