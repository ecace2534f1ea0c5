//! A chart of series of points with error bars on one panel: the shape of most figures
//! (β, φ, α, e, head errors, both results of a comparison). Non-finite values are not
//! drawn, and the chart says how many were left out.

use std::fmt::Write;

use super::svg::{
    Axis, LEFT_PX, LegendKey, Marker, Panel, RIGHT_PX, WIDTH_PX, document, error_bar, header_px,
    legend, point,
};

/// One point: its index in the report's list, its position and the half-length of its
/// error bar (none when unknown).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Point {
    /// Index in the report's list (`data-index`).
    pub index: usize,
    /// x value.
    pub x: f64,
    /// y value.
    pub y: f64,
    /// Half-length of the error bar, in y units.
    pub half: Option<f64>,
}

/// One series.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Series {
    /// `data-series`.
    pub id: String,
    /// Legend text.
    pub label: String,
    /// Marker.
    pub marker: Marker,
    /// Horizontal offset of every point, px (so that bars of two series do not overlap).
    pub dx_px: f64,
    /// Points.
    pub points: Vec<Point>,
}

/// A chart: title, subtitle lines, axis titles, series.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Chart {
    /// Title.
    pub title: String,
    /// Lines under the title (what U is, what is left out).
    pub subtitles: Vec<String>,
    /// x axis title with unit.
    pub x_label: String,
    /// y axis title with unit.
    pub y_label: String,
    /// Series.
    pub series: Vec<Series>,
    /// Values the x axis must include (e.g. 0 and 360 for angles).
    pub x_include: Vec<f64>,
}

/// Marker size for a number of points: small markers for many points, none skipped.
pub(crate) fn marker_px(points: usize) -> (f64, f64) {
    match points {
        0..=60 => (3.5, 3.0),
        61..=400 => (2.2, 1.5),
        401..=2000 => (1.2, 0.0),
        _ => (0.6, 0.0),
    }
}

/// Counts the non-finite points and bars (left out of the drawing).
fn non_finite(series: &[Series]) -> usize {
    series
        .iter()
        .flat_map(|s| &s.points)
        .filter(|p| !(p.x.is_finite() && p.y.is_finite() && p.half.is_none_or(|h| h.is_finite())))
        .count()
}

impl Chart {
    /// The SVG document.
    pub(crate) fn render(&self) -> String {
        let mut subtitles = self.subtitles.clone();
        let skipped = non_finite(&self.series);
        if skipped > 0 {
            subtitles.push(format!(
                "{skipped} point(s) with a non-finite value or uncertainty are not drawn"
            ));
        }
        let mut body = String::new();
        let entries: Vec<(LegendKey, String)> = if self.series.len() > 1 {
            self.series
                .iter()
                .map(|s| {
                    let bars = s.points.iter().any(|p| p.half.is_some());
                    (LegendKey::Marker(s.marker, bars), s.label.clone())
                })
                .collect()
        } else {
            Vec::new()
        };
        let top = header_px(&subtitles);
        let legend_px = legend(&mut body, &entries, top);
        let drawn = |p: &&Point| p.x.is_finite() && p.y.is_finite();
        let xs = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().filter(drawn).map(|p| p.x));
        let ys = self.series.iter().flat_map(|s| {
            s.points.iter().filter(drawn).flat_map(|p| {
                let h = p.half.filter(|h| h.is_finite()).unwrap_or(0.0);
                [p.y - h, p.y + h]
            })
        });
        let panel_top = top + legend_px + 8.0;
        let height_px = 260.0;
        let panel = Panel {
            id: "main",
            left_px: LEFT_PX,
            top_px: panel_top,
            width_px: WIDTH_PX - LEFT_PX - RIGHT_PX,
            height_px,
            x: if self.x_include == [0.0, 360.0] {
                Axis::full_turn_deg(xs, self.x_label.clone())
            } else {
                Axis::covering(xs, &self.x_include, 8, self.x_label.clone())
            },
            y: Axis::covering(ys, &[0.0], 6, self.y_label.clone()),
        };
        panel.draw_axes(&mut body, true);
        draw_series(&mut body, &panel, &self.series);
        document(panel.bottom_px() + 42.0, &self.title, &subtitles, &body)
    }
}

/// Draws every finite point of every series with its error bar.
pub(crate) fn draw_series(out: &mut String, panel: &Panel, series: &[Series]) {
    let total: usize = series.iter().map(|s| s.points.len()).sum();
    let (r, cap) = marker_px(total);
    let _ = writeln!(out, r#"<g class="series-group">"#);
    for s in series {
        for p in &s.points {
            if !(p.x.is_finite() && p.y.is_finite()) {
                continue;
            }
            let x = panel.x_px(p.x) + s.dx_px;
            if let Some(h) = p.half.filter(|h| h.is_finite()) {
                error_bar(out, panel, &s.id, p.index, x, p.y, h, cap);
            }
        }
        for p in &s.points {
            if !(p.x.is_finite() && p.y.is_finite()) {
                continue;
            }
            let x = panel.x_px(p.x) + s.dx_px;
            point(
                out,
                panel,
                &s.id,
                p.index,
                (x, panel.y_px(p.y)),
                s.marker,
                r,
            );
        }
    }
    let _ = writeln!(out, "</g>");
}

/// What U is in a subtitle: one k, or the range of per-point k.
pub(crate) fn k_text(ks: &[f64]) -> String {
    let finite: Vec<f64> = ks.iter().copied().filter(|k| k.is_finite()).collect();
    let lo = finite.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = finite.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if finite.is_empty() {
        "k unknown".into()
    } else if hi - lo < 0.005 {
        format!("k = {lo:.2}")
    } else {
        format!("k = {lo:.2} … {hi:.2} per point")
    }
}
