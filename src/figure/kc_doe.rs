//! The degrees of equivalence of a key comparison as the BIPM KCDB draws them
//! (`kc-kcdb`, docs/FORMAT.md §10.1): one small graph per compared position (face,
//! encoder position, angle block), the laboratories along the x axis by name (or code letter), each
//! laboratory's d_i with its U(d_i) bar (k = 2), the line at 0 (the reference), and the
//! laboratories not in the reference drawn apart (open squares, their names in italics).
//! One document of small graphs, so that a Draft A report takes them as one figure.
//!
//! At most [`MAX_GRAPHS`] positions are drawn: with more (a long encoder comparison),
//! those where some laboratory's |d_i|/U(d_i) is largest, in their order, and the
//! subtitle says so; every position is in `kc-degrees-of-equivalence` and the JSON.
//!
//! Classes: each graph is a `<g class="position" data-index="k">` (k in the comparison's
//! `index` list, from 0); in it `point` and `error-bar` with `data-series` `lab<i>`
//! (laboratory i of `labs`, from 0) and `data-index` k, ticks of panel `main`, and a
//! `<text class="lab-label" data-lab="i" data-in-reference="true|false">` under each
//! laboratory's bar.

use std::fmt::Write;

use super::Figure;
use super::chart::marker_px;
use super::svg::{
    Axis, LegendKey, Marker, Panel, WIDTH_PX, document, error_bar, esc, header_px, legend, point,
    px,
};
use crate::kc::KeyComparison;
use crate::results::Quantity;

/// The figure's name.
pub(crate) const NAME: &str = "kc-kcdb";

/// The most graphs drawn.
pub(crate) const MAX_GRAPHS: usize = 24;

/// The longest laboratory label, characters (a longer name is cut, ending in `…`).
const LABEL_CHARS: usize = 16;

/// Width of a label's character at its font size, px (9 px sans-serif).
const CHAR_PX: f64 = 5.4;

/// Room left of a graph for the y tick labels and title, px.
const Y_AXIS_PX: f64 = 64.0;

/// A graph's plotting height, px.
const GRAPH_HEIGHT_PX: f64 = 120.0;

/// The figures of this module: the one document.
pub(crate) fn figures(kc: &KeyComparison) -> Vec<Figure> {
    vec![kcdb(kc)]
}

/// Graphs side by side: three for up to 12 laboratories, two for up to 24, else one.
fn columns(labs: usize) -> usize {
    match labs {
        0..=12 => 3,
        13..=24 => 2,
        _ => 1,
    }
}

/// The positions drawn: all, or the [`MAX_GRAPHS`] where the largest |d_i|/U(d_i) of
/// any laboratory is largest, in their order.
pub(crate) fn drawn(kc: &KeyComparison) -> Vec<usize> {
    let n = kc.index.len();
    let mut all: Vec<usize> = (0..n).collect();
    if n > MAX_GRAPHS {
        let score = |k: usize| {
            kc.degrees_of_equivalence
                .iter()
                .map(|doe| {
                    let (d, u) = (doe.d[k], doe.expanded_u[k]);
                    if u > 0.0 { (d / u).abs() } else { 0.0 }
                })
                .filter(|r| r.is_finite())
                .fold(0.0, f64::max)
        };
        all.sort_by(|a, b| score(*b).total_cmp(&score(*a)).then(a.cmp(b)));
        all.truncate(MAX_GRAPHS);
        all.sort_unstable();
    }
    all
}

/// The graph's title: the face, or the encoder position (with its angle when matched
/// by angle).
fn position_title(kc: &KeyComparison, k: usize) -> String {
    match (&kc.angle_deg, kc.quantity) {
        (_, Quantity::PitchDeviation) => format!("face {}", kc.index[k]),
        (_, Quantity::AngleBlock) => {
            match kc
                .nominal_deg
                .as_ref()
                .and_then(|n| n.get(k).copied().flatten())
            {
                Some(nominal) => format!("block {} ({nominal}°)", kc.index[k]),
                None => format!("block {}", kc.index[k]),
            }
        }
        (Some(angles), _) => format!("index {} ({:.3}°)", kc.index[k], angles[k]),
        (None, _) => format!("index {}", kc.index[k]),
    }
}

/// A laboratory's label: its name, cut to [`LABEL_CHARS`] characters.
fn label(name: &str) -> String {
    if name.chars().count() <= LABEL_CHARS {
        return name.to_string();
    }
    let mut cut: String = name.chars().take(LABEL_CHARS - 1).collect();
    cut.push('…');
    cut
}

fn kcdb(kc: &KeyComparison) -> Figure {
    let (family, position_word) = match kc.quantity {
        Quantity::PitchDeviation => ("pitch deviations β", "face"),
        Quantity::AngleBlock => ("angle blocks' deviations from nominal", "block"),
        _ => ("encoder errors α", "position"),
    };
    let title = format!("Degrees of equivalence per {position_word} (KCDB graphs), {family}");
    let labs = &kc.degrees_of_equivalence;
    let positions = drawn(kc);
    let out: Vec<&str> = labs
        .iter()
        .filter(|d| !d.in_reference)
        .map(|d| d.lab.as_str())
        .collect();
    let mut subtitles = vec![format!(
        "each graph: every laboratory's d_i = x_i − x_ref with its U(d_i) bar (k = 2) against \
         the reference (the line at 0); {}",
        if out.is_empty() {
            "every laboratory is in the reference".to_string()
        } else {
            format!("● in the reference, □ not in it ({})", out.join(", "))
        }
    )];
    if positions.len() < kc.index.len() {
        subtitles.push(format!(
            "{} of {} {position_word}s drawn: those where some laboratory's |d_i|/U(d_i) is \
             largest; every {position_word} in kc-degrees-of-equivalence and the JSON",
            positions.len(),
            kc.index.len()
        ));
    }
    let mut body = String::new();
    let mut entries = vec![(
        LegendKey::Marker(Marker::FilledCircle, true),
        "in the reference".to_string(),
    )];
    if !out.is_empty() {
        entries.push((
            LegendKey::Marker(Marker::OpenSquare, true),
            "not in the reference".to_string(),
        ));
    }
    let legend_px = legend(&mut body, &entries, header_px(&subtitles));
    let top = header_px(&subtitles) + legend_px + 6.0;

    let shown: Vec<String> = labs.iter().map(|d| label(&d.lab)).collect();
    let longest = shown.iter().map(|s| s.chars().count()).max().unwrap_or(1);
    let rotated = longest > 2;
    let label_px = if rotated {
        longest as f64 * CHAR_PX + 10.0
    } else {
        16.0
    };
    let columns = columns(labs.len());
    let column_px = (WIDTH_PX - 20.0) / columns as f64;
    let row_px = 22.0 + GRAPH_HEIGHT_PX + label_px + 10.0;
    let (r, cap) = marker_px(labs.len());
    for (slot, &k) in positions.iter().enumerate() {
        let (row, column) = (slot / columns, slot % columns);
        let ys = labs
            .iter()
            .flat_map(|d| [d.d[k] - d.expanded_u[k], d.d[k] + d.expanded_u[k]]);
        let panel = Panel {
            id: "main",
            left_px: 10.0 + column as f64 * column_px + Y_AXIS_PX,
            top_px: top + row as f64 * row_px + 22.0,
            width_px: column_px - Y_AXIS_PX - 12.0,
            height_px: GRAPH_HEIGHT_PX,
            x: Axis {
                lo: 0.5,
                hi: labs.len() as f64 + 0.5,
                ticks: Vec::new(),
                decimals: 0,
                label: String::new(),
            },
            y: Axis::covering(ys, &[0.0], 4, "d / ″"),
        };
        let _ = writeln!(body, r#"<g class="position" data-index="{k}">"#);
        let _ = writeln!(
            body,
            r#"<text class="chart-title" x="{}" y="{}" font-size="11" font-weight="bold">{}</text>"#,
            px(panel.left_px),
            px(panel.top_px - 6.0),
            esc(&position_title(kc, k))
        );
        panel.draw_axes(&mut body, false);
        for (i, doe) in labs.iter().enumerate() {
            let x = panel.x_px(i as f64 + 1.0);
            let series = format!("lab{i}");
            let (d, u) = (doe.d[k], doe.expanded_u[k]);
            if d.is_finite() && u.is_finite() {
                error_bar(&mut body, &panel, &series, k, x, d, u, cap);
            }
            if d.is_finite() {
                let marker = if doe.in_reference {
                    Marker::FilledCircle
                } else {
                    Marker::OpenSquare
                };
                point(&mut body, &panel, &series, k, (x, panel.y_px(d)), marker, r);
            }
            let y = panel.bottom_px() + 6.0;
            let (anchor, transform, y) = if rotated {
                (
                    "end",
                    format!(r#" transform="rotate(-90 {} {})""#, px(x + 3.0), px(y)),
                    y,
                )
            } else {
                ("middle", String::new(), y + 9.0)
            };
            let _ = writeln!(
                body,
                r#"<text class="lab-label" data-lab="{i}" data-in-reference="{}" x="{}" y="{}" font-size="9" text-anchor="{anchor}"{}{transform}>{}</text>"#,
                doe.in_reference,
                px(if rotated { x + 3.0 } else { x }),
                px(y),
                if doe.in_reference {
                    ""
                } else {
                    r#" font-style="italic""#
                },
                esc(&shown[i])
            );
        }
        let _ = writeln!(body, "</g>");
    }
    let rows = positions.len().div_ceil(columns);
    let height = top + rows as f64 * row_px + 10.0;
    Figure::new(
        NAME,
        title.clone(),
        document(height, &title, &subtitles, &body),
    )
}
