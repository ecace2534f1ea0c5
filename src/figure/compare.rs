//! The figures of `polycal compare` (the reference paper's Figs. 4–7), per family of
//! quantities present: both results with their U bars (`compare-<family>`), and their
//! difference a − b with the band ±√(U_a² + U_b² − 2·r·U_a·U_b) (the En denominator;
//! √(U_a² + U_b²) for r = 0) and, below it, En per point with lines at ±1
//! (`compare-<family>-difference`).
//!
//! Classes (docs/FORMAT.md §10): `point` with `data-series` `a`, `b` (panel `main`),
//! `difference` (panel `difference`), `en` or `en-exceeds` (panel `en`, |En| > 1 filled);
//! `band` (a `<rect>` from −half-width to +half-width, `data-index`); `en-exceeds-ring`
//! (a ring around every difference with |En| > 1, `data-index`); `en-limit` (±1).

use std::fmt::Write;

use super::Figure;
use super::chart::{Chart, Point, Series, draw_series, marker_px};
use super::svg::{
    Axis, LEFT_PX, LegendKey, Marker, Panel, RIGHT_PX, WIDTH_PX, document, header_px, legend, px,
};
use crate::compare::{Comparison, ComparisonRow};
use crate::results::Quantity;

/// The marker of a − b in the difference figure: its own, apart from the En markers
/// (open squares within ±1, filled circles beyond) below it.
const DIFFERENCE_MARKER: Marker = Marker::Triangle;

/// The family's name in file names, e.g. `pitch-deviation`.
pub(crate) fn family_slug(quantity: Quantity) -> String {
    quantity.name().replace('_', "-")
}

fn family_words(quantity: Quantity) -> (&'static str, &'static str) {
    match quantity {
        Quantity::PitchDeviation => ("Pitch deviations β", "β"),
        Quantity::FaceDeviation => ("Face deviations φ", "φ"),
        Quantity::EncoderError => ("Encoder errors α", "α"),
        Quantity::SetupError => ("Setup errors", "setup error"),
        Quantity::AngleBlock => ("Angle blocks", "angle block"),
    }
}

/// The x of a row: its table angle when matched by angle, else its index.
fn x_of(row: &ComparisonRow) -> f64 {
    row.angle_deg.unwrap_or(row.index as f64)
}

fn x_label(quantity: Quantity, by_angle: bool) -> String {
    match quantity {
        _ if by_angle => "table angle / °".into(),
        Quantity::PitchDeviation | Quantity::FaceDeviation => "face k".into(),
        Quantity::EncoderError => "position p".into(),
        Quantity::SetupError => "autocollimator (setup·1000 + ac with several setups)".into(),
        Quantity::AngleBlock => "angle block b".into(),
    }
}

/// Half-width of the band of a row: the En denominator.
pub(crate) fn band_half_width(row: &ComparisonRow, correlation: f64) -> f64 {
    let (a, b) = (row.expanded_u_a, row.expanded_u_b);
    (a * a + b * b - 2.0 * correlation * a * b).max(0.0).sqrt()
}

/// Every figure of a comparison, the results named `label_a` and `label_b`.
pub(crate) fn figures(comparison: &Comparison, label_a: &str, label_b: &str) -> Vec<Figure> {
    let mut out = Vec::new();
    for quantity in Quantity::ALL {
        let rows: Vec<&ComparisonRow> = comparison
            .rows
            .iter()
            .filter(|r| r.quantity == quantity)
            .collect();
        if rows.is_empty() {
            continue;
        }
        out.push(both(quantity, &rows, label_a, label_b));
        out.push(difference(
            quantity,
            &rows,
            comparison.correlation,
            label_a,
            label_b,
        ));
    }
    out
}

fn both(quantity: Quantity, rows: &[&ComparisonRow], label_a: &str, label_b: &str) -> Figure {
    let by_angle = rows.iter().all(|r| r.angle_deg.is_some());
    let (words, symbol) = family_words(quantity);
    let title = format!("{words}: both results with U");
    let series =
        |id: &str, label: &str, marker, dx_px, pick: fn(&ComparisonRow) -> (f64, f64)| Series {
            id: id.into(),
            label: format!("{label} (U bars)"),
            marker,
            dx_px,
            points: rows
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let (y, u) = pick(r);
                    Point {
                        index: i,
                        x: x_of(r),
                        y,
                        half: Some(u),
                    }
                })
                .collect(),
        };
    let dx = if rows.len() > 200 { 0.0 } else { 3.0 };
    let chart = Chart {
        title: title.clone(),
        subtitles: vec![format!(
            "{} compared rows; a: {label_a}, b: {label_b}; bars: each result's expanded uncertainty U (points offset ±{dx} px)",
            rows.len()
        )],
        x_label: x_label(quantity, by_angle),
        y_label: format!("{symbol} / ″"),
        series: vec![
            series(
                "a",
                &format!("a: {label_a}"),
                Marker::FilledCircle,
                -dx,
                |r| (r.a, r.expanded_u_a),
            ),
            series("b", &format!("b: {label_b}"), Marker::OpenSquare, dx, |r| {
                (r.b, r.expanded_u_b)
            }),
        ],
        x_include: if by_angle {
            vec![0.0, 360.0]
        } else {
            Vec::new()
        },
    };
    Figure::new(
        format!("compare-{}", family_slug(quantity)),
        title,
        chart.render(),
    )
}

fn difference(
    quantity: Quantity,
    rows: &[&ComparisonRow],
    correlation: f64,
    label_a: &str,
    label_b: &str,
) -> Figure {
    let by_angle = rows.iter().all(|r| r.angle_deg.is_some());
    let (words, symbol) = family_words(quantity);
    let title = format!("{words}: difference a − b and En");
    let subtitles = difference_subtitles(rows, correlation, label_a, label_b);
    let mut body = String::new();
    let entries = difference_legend(rows);
    let top = header_px(&subtitles);
    let legend_px = legend(&mut body, &entries, top);
    let halves: Vec<f64> = rows
        .iter()
        .map(|r| band_half_width(r, correlation))
        .collect();
    let x_axis = |label: String| {
        let xs = rows.iter().filter(|r| drawable(r)).map(|r| x_of(r));
        if by_angle {
            Axis::full_turn_deg(xs, label)
        } else {
            Axis::covering(xs, &[], 8, label)
        }
    };
    let upper = Panel {
        id: "difference",
        left_px: LEFT_PX,
        top_px: top + legend_px + 8.0,
        width_px: WIDTH_PX - LEFT_PX - RIGHT_PX,
        height_px: 220.0,
        x: x_axis(String::new()),
        y: Axis::covering(
            rows.iter()
                .zip(&halves)
                .filter(|(r, _)| drawable(r))
                .flat_map(|(r, h)| [r.difference, *h, -*h]),
            &[0.0],
            6,
            format!("difference a − b in {symbol} / ″"),
        ),
    };
    let lower = Panel {
        id: "en",
        top_px: upper.bottom_px() + 26.0,
        height_px: 110.0,
        x: x_axis(x_label(quantity, by_angle)),
        y: Axis::covering(
            rows.iter().map(|r| r.en).filter(|e| e.is_finite()),
            &[-1.2, 1.2],
            4,
            "En",
        ),
        ..upper.clone()
    };
    // The band first, under everything.
    draw_band(&mut body, rows, &halves, &upper);
    upper.draw_axes(&mut body, false);
    lower.draw_axes(&mut body, true);
    for limit in [-1.0, 1.0] {
        let y = px(lower.y_px(limit));
        let _ = writeln!(
            body,
            r##"<line class="en-limit" x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#000" stroke-width="1" stroke-dasharray="5,3"/>"##,
            px(lower.left_px),
            px(lower.left_px + lower.width_px)
        );
    }
    draw_differences(&mut body, rows, &upper);
    let en_series = |id: &str, marker, over: bool| Series {
        id: id.into(),
        label: id.into(),
        marker,
        dx_px: 0.0,
        points: rows
            .iter()
            .enumerate()
            .filter(|(_, r)| (r.en.abs() > 1.0) == over)
            .map(|(i, r)| point_of(i, r, r.en))
            .collect(),
    };
    draw_series(
        &mut body,
        &lower,
        &[
            en_series("en", Marker::OpenSquare, false),
            en_series("en-exceeds", Marker::FilledCircle, true),
        ],
    );
    let svg = document(lower.bottom_px() + 42.0, &title, &subtitles, &body);
    Figure::new(
        format!("compare-{}-difference", family_slug(quantity)),
        title,
        svg,
    )
}

/// Whether a row's difference can be drawn: its x and a − b finite.
fn drawable(r: &ComparisonRow) -> bool {
    x_of(r).is_finite() && r.difference.is_finite()
}

/// Row `i`'s point at `y` (a − b or En) with its x.
fn point_of(i: usize, r: &ComparisonRow, y: f64) -> Point {
    Point {
        index: i,
        x: x_of(r),
        y,
        half: None,
    }
}

/// The difference figure's subtitles: the results, the band, how many |En| > 1 against
/// the number expected by chance when the results are consistent (docs/FORMAT.md §5.4),
/// and the rows not drawn.
fn difference_subtitles(
    rows: &[&ComparisonRow],
    correlation: f64,
    label_a: &str,
    label_b: &str,
) -> Vec<String> {
    let exceeding = rows.iter().filter(|r| r.en.abs() > 1.0).count();
    // The number expected by chance when the results are consistent (docs/FORMAT.md §5.4).
    let expected: Option<f64> = rows
        .iter()
        .map(|r| r.probability_en_exceeds_one(correlation))
        .sum();
    let mut subtitles = vec![
        format!("a: {label_a}, b: {label_b}"),
        if correlation == 0.0 {
            "band: ±√(U_a² + U_b²), the En denominator".to_string()
        } else {
            format!("band: ±√(U_a² + U_b² − 2·r·U_a·U_b), r = {correlation}, the En denominator")
        },
        match expected {
            Some(expected) => format!(
                "{exceeding} of {} rows with |En| > 1, about {expected:.1} expected by chance \
                 (ringed above, filled below)",
                rows.len()
            ),
            None => format!(
                "{exceeding} of {} rows with |En| > 1 (ringed above, filled below)",
                rows.len()
            ),
        },
    ];
    let skipped = rows
        .iter()
        .filter(|r| !(x_of(r).is_finite() && r.difference.is_finite() && r.en.is_finite()))
        .count();
    if skipped > 0 {
        subtitles.push(format!(
            "{skipped} row(s) with a non-finite value are not drawn"
        ));
    }
    subtitles
}

/// The difference figure's legend: one marker per series, and a key only for what the
/// figure shows: the ring and the filled En only where some |En| > 1, the open En only
/// where some |En| ≤ 1.
fn difference_legend(rows: &[&ComparisonRow]) -> Vec<(LegendKey, String)> {
    let drawn: Vec<f64> = rows
        .iter()
        .filter(|r| x_of(r).is_finite() && r.difference.is_finite() && r.en.is_finite())
        .map(|r| r.en.abs())
        .collect();
    let some_over = drawn.iter().any(|&en| en > 1.0);
    let some_within = drawn.iter().any(|&en| en <= 1.0);
    let mut entries = vec![
        (
            LegendKey::Marker(DIFFERENCE_MARKER, false),
            "a − b".to_string(),
        ),
        (LegendKey::Band, "±√(U_a² + U_b²)".to_string()),
    ];
    if some_over {
        entries.push((LegendKey::Ring, "a − b with |En| > 1".to_string()));
    }
    if some_within {
        entries.push((
            LegendKey::Marker(Marker::OpenSquare, false),
            "En, |En| ≤ 1".to_string(),
        ));
    }
    if some_over {
        entries.push((
            LegendKey::Marker(Marker::FilledCircle, false),
            "En, |En| > 1".to_string(),
        ));
    }
    entries.push((LegendKey::Line(Some("5,3")), "En = ±1".to_string()));
    entries
}

/// The band ±half-width (`halves`, arcsec) on the `upper` panel: a step outline, one
/// cell per point, at most 14 px either side and half-way to its neighbours.
fn draw_band(body: &mut String, rows: &[&ComparisonRow], halves: &[f64], upper: &Panel) {
    let xs_px: Vec<f64> = rows.iter().map(|r| upper.x_px(x_of(r))).collect();
    let _ = writeln!(body, r#"<g class="band-group">"#);
    for (i, (r, half)) in rows.iter().zip(halves).enumerate() {
        if !(drawable(r) && half.is_finite()) {
            continue;
        }
        let neighbour = |j: Option<usize>| {
            j.and_then(|j| xs_px.get(j))
                .map(|x| (x - xs_px[i]).abs() / 2.0)
                .filter(|d| *d > 0.0)
        };
        let w = neighbour(i.checked_sub(1))
            .into_iter()
            .chain(neighbour(Some(i + 1)))
            .fold(f64::INFINITY, f64::min)
            .min(14.0);
        let w = if w.is_finite() { w } else { 14.0 };
        let (y_top, y_bottom) = (upper.y_px(*half), upper.y_px(-*half));
        let _ = writeln!(
            body,
            r##"<rect class="band" data-index="{i}" x="{}" y="{}" width="{}" height="{}" fill="#d9d9d9" stroke="none"/>"##,
            px(xs_px[i] - w),
            px(y_top),
            px(2.0 * w),
            px(y_bottom - y_top)
        );
    }
    let _ = writeln!(body, "</g>");
}

/// The differences a − b on the `upper` panel, each with |En| > 1 ringed.
fn draw_differences(body: &mut String, rows: &[&ComparisonRow], upper: &Panel) {
    let diff = Series {
        id: "difference".into(),
        label: "a − b".into(),
        marker: DIFFERENCE_MARKER,
        dx_px: 0.0,
        points: rows
            .iter()
            .enumerate()
            .map(|(i, r)| point_of(i, r, r.difference))
            .collect(),
    };
    draw_series(body, upper, &[diff]);
    let (r_px, _) = marker_px(rows.len());
    for (i, r) in rows.iter().enumerate() {
        if r.en.abs() > 1.0 && drawable(r) {
            let _ = writeln!(
                body,
                r##"<circle class="en-exceeds-ring" data-index="{i}" cx="{}" cy="{}" r="{}" fill="none" stroke="#000" stroke-width="1.2"/>"##,
                px(upper.x_px(x_of(r))),
                px(upper.y_px(r.difference)),
                px(r_px + 3.5)
            );
        }
    }
}
