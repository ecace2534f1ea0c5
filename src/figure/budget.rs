//! The figures of an instrument budget: for one quantity of a family (the one with the
//! largest U), each component's index — its share of the combined variance,
//! 100 · u_i² / u_c², per cent — as a horizontal bar, largest first, the fit's type A
//! among them.
//!
//! Classes: `bar` (a `<rect>` from 0 to the index, `data-component`, `data-rank` from 0),
//! `tick-x`/`tick-label-x` of the per-cent axis (docs/FORMAT.md §10).

use std::fmt::Write;

use super::Figure;
use super::svg::{Axis, LEFT_PX, Panel, RIGHT_PX, WIDTH_PX, document, esc, header_px, px};
use crate::uncertainty::calibration::{
    CalibrationUncertainty, ComponentContribution, FamilyUncertainty,
};

/// The name of the fit's type A in the bars.
pub(crate) const TYPE_A_NAME: &str = "type A of the fit (σ·√Q)";

/// One family's figure for its quantity `j` (`contributions`: each component's u
/// contribution to it), or none when its u_c is zero or not finite.
pub(crate) fn family_figure(
    family_name: &str,
    symbol: &str,
    index_base: usize,
    family: &FamilyUncertainty,
    j: usize,
    contributions: &[(String, f64)],
) -> Option<Figure> {
    let big_u = *family.expanded_u.get(j)?;
    let u_c = *family.u.get(j)?;
    if !(u_c.is_finite() && u_c > 0.0) {
        return None;
    }
    let u_a = family.u_a.get(j).copied().unwrap_or(0.0);
    let mut bars: Vec<(String, f64)> = std::iter::once((TYPE_A_NAME.to_string(), u_a))
        .chain(contributions.iter().cloned())
        .filter(|(_, u)| u.is_finite())
        .map(|(name, u)| (name, 100.0 * (u / u_c).powi(2)))
        .collect();
    bars.sort_by(|a, b| b.1.total_cmp(&a.1));
    let title = format!(
        "Uncertainty budget of {symbol}[{}] ({family_name} with the largest U)",
        j + index_base
    );
    let subtitles = vec![format!(
        "index = 100·u_i²/u_c² per component; u_c = {u_c:.4}″, U = {big_u:.4}″, k = {}",
        family
            .k
            .get(j)
            .copied()
            .flatten()
            .map_or("—".into(), |k| format!("{k:.2}"))
    )];
    let mut body = String::new();
    let top = header_px(&subtitles) + 10.0;
    let label_px = 210.0;
    let row_px = 18.0;
    let panel = Panel {
        id: "main",
        left_px: LEFT_PX + label_px - 60.0,
        top_px: top,
        width_px: WIDTH_PX - (LEFT_PX + label_px - 60.0) - RIGHT_PX,
        height_px: row_px * bars.len().max(1) as f64 + 8.0,
        x: Axis::covering(
            bars.iter().map(|b| b.1),
            &[0.0],
            6,
            "index (share of u_c²) / %",
        ),
        y: Axis {
            lo: 0.0,
            hi: 1.0,
            ticks: Vec::new(),
            decimals: 0,
            label: String::new(),
        },
    };
    panel.draw_axes(&mut body, true);
    let x0 = panel.x_px(0.0);
    for (rank, (name, index)) in bars.iter().enumerate() {
        let y = panel.top_px + 4.0 + row_px * rank as f64;
        let x1 = panel.x_px(*index);
        let shown: String = name.chars().take(34).collect();
        let _ = writeln!(
            body,
            r##"<rect class="bar" data-component="{}" data-rank="{rank}" x="{}" y="{}" width="{}" height="{}" fill="{}" stroke="#000" stroke-width="0.6"/>"##,
            esc(name),
            px(x0),
            px(y + 2.0),
            px((x1 - x0).max(0.0)),
            px(row_px - 4.0),
            if name == TYPE_A_NAME {
                "#fff"
            } else {
                "#9a9a9a"
            }
        );
        let _ = writeln!(
            body,
            r#"<text class="bar-label" x="{}" y="{}" font-size="10" text-anchor="end">{}</text>"#,
            px(panel.left_px - 6.0),
            px(y + row_px / 2.0 + 3.5),
            esc(&shown)
        );
        let _ = writeln!(
            body,
            r#"<text class="bar-value" x="{}" y="{}" font-size="9.5">{:.1} %</text>"#,
            px(x1 + 4.0),
            px(y + row_px / 2.0 + 3.5),
            index
        );
    }
    let svg = document(panel.bottom_px() + 42.0, &title, &subtitles, &body);
    Some(Figure::new(
        format!("budget-{}", family_name.replace(' ', "-")),
        title,
        svg,
    ))
}

/// The index of the quantity with the largest finite, positive U.
fn largest_u(family: &FamilyUncertainty) -> Option<usize> {
    family
        .expanded_u
        .iter()
        .copied()
        .enumerate()
        .filter(|(_, u)| u.is_finite() && *u > 0.0)
        .fold(None, |best: Option<(usize, f64)>, (i, u)| match best {
            Some((_, b)) if b >= u => best,
            _ => Some((i, u)),
        })
        .map(|(i, _)| i)
}

/// `budget-pitch-deviation`, `budget-face-deviation`, `budget-encoder-error`.
pub(crate) fn figures(uncertainty: &CalibrationUncertainty) -> Vec<Figure> {
    type Pick = fn(&ComponentContribution) -> &Vec<f64>;
    let families: [(&str, &str, usize, &FamilyUncertainty, Pick); 3] = [
        (
            "pitch deviation",
            "β",
            1,
            &uncertainty.pitch_deviation,
            |c| &c.pitch_deviation,
        ),
        (
            "face deviation",
            "φ",
            1,
            &uncertainty.face_deviation,
            |c| &c.face_deviation,
        ),
        ("encoder error", "α", 0, &uncertainty.encoder_error, |c| {
            &c.encoder_error
        }),
    ];
    families
        .into_iter()
        .filter_map(|(name, symbol, base, family, pick)| {
            let j = largest_u(family)?;
            let parts: Vec<(String, f64)> = uncertainty
                .components
                .iter()
                .filter_map(|c| pick(c).get(j).map(|u| (c.name.clone(), *u)))
                .collect();
            family_figure(name, symbol, base, family, j, &parts)
        })
        .collect()
}
