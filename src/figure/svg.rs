//! The drawing primitives of every figure: text escaping, numbers as SVG coordinates,
//! "nice" axes (ticks at 1, 2, 5 × 10^k with labels), a panel (a plotting area with its two
//! axes and their linear maps), greyscale markers and the document frame.
//!
//! Stable classes for programs that read the figures (docs/FORMAT.md §10): `tick-x`,
//! `tick-y` (a tick mark, a `<line>`) each followed in document order by its
//! `tick-label-x`, `tick-label-y` (a `<text>` holding the value), all with `data-panel`;
//! `point` (a `<g>` translated to the point's centre, with `data-series`, `data-index`,
//! `data-panel`); `error-bar` (a vertical `<line>` from y − U to y + U).

use std::fmt::Write;

/// Width of every figure, px (an A4 page's text width at 96 dpi is about 680 px).
pub(crate) const WIDTH_PX: f64 = 680.0;

/// Left margin of a panel (room for the y tick labels and the axis title), px.
pub(crate) const LEFT_PX: f64 = 78.0;

/// Right margin of a panel, px.
pub(crate) const RIGHT_PX: f64 = 18.0;

/// Escapes text for SVG/XML content and attribute values as people read it (the figures
/// and the HTML report): [`esc_data`], and a bidirectional formatting character, which
/// would reorder the text around it on screen (a name displayed as another), shown as its
/// escape, `\u{202e}`, as [`crate::input::escaped`] shows it.
pub(crate) fn esc(text: &str) -> String {
    escape_xml(text, true)
}

/// Escapes text for XML content and attribute values as data (the DCC, which carries a
/// text as written): `&`, `<`, `>`, `"`, `'`, and a control character XML 1.0 cannot
/// carry as a space.
pub(crate) fn esc_data(text: &str) -> String {
    escape_xml(text, false)
}

/// [`esc`] (`bidi_shown`) or [`esc_data`].
fn escape_xml(text: &str, bidi_shown: bool) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // Control characters are not allowed in XML 1.0.
            c if (c as u32) < 0x20 && c != '\t' && c != '\n' && c != '\r' => out.push(' '),
            c if bidi_shown && crate::input::is_bidi_control(c) => out.extend(c.escape_default()),
            c => out.push(c),
        }
    }
    out
}

/// A coordinate in px, two decimals (finite by construction: callers map finite values).
pub(crate) fn px(value: f64) -> String {
    if value.is_finite() {
        format!("{value:.2}")
    } else {
        "0".into()
    }
}

/// A number for people in a label or title: a few significant digits, `−` for minus.
pub(crate) fn number_text(value: f64, decimals: usize) -> String {
    let text = format!("{value:.decimals$}");
    // "-0.00" is zero.
    let text = if text
        .trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        text.trim_start_matches('-').to_string()
    } else {
        text
    };
    text.replace('-', "−")
}

/// A linear axis with "nice" ticks.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Axis {
    /// Lowest value of the axis.
    pub lo: f64,
    /// Highest value of the axis (> `lo`).
    pub hi: f64,
    /// Tick values, ascending, within [lo, hi].
    pub ticks: Vec<f64>,
    /// Decimals of the tick labels.
    pub decimals: usize,
    /// Axis title with unit, e.g. "angle / °".
    pub label: String,
}

/// The largest magnitude a figure plots; larger values are left out like non-finite ones.
pub(crate) const PLOTTABLE_MAGNITUDE: f64 = 1e300;

impl Axis {
    /// An axis covering every finite value of `values` (and `include`, e.g. 0), with about
    /// `target` ticks at 1, 2, 5 × 10^k; a sane axis for no value, one value or equal values.
    pub(crate) fn covering(
        values: impl IntoIterator<Item = f64>,
        include: &[f64],
        target: usize,
        label: impl Into<String>,
    ) -> Self {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in values.into_iter().chain(include.iter().copied()) {
            // a value near ±f64::MAX (possible only from the library's API, not from a
            // file within its limits) would overflow the margin and the steps: left out
            // as a non-finite value is
            if v.is_finite() && v.abs() <= PLOTTABLE_MAGNITUDE {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
        if !lo.is_finite() || !hi.is_finite() {
            (lo, hi) = (-1.0, 1.0);
        }
        if hi - lo <= f64::EPSILON * hi.abs().max(lo.abs()).max(1e-300) {
            let pad = if lo == 0.0 { 1.0 } else { 0.1 * lo.abs() };
            (lo, hi) = (lo - pad, hi + pad);
        } else {
            // a margin, but never across zero: times, angles, faces and shares that start
            // at 0 keep their axis at 0
            let pad = 0.04 * (hi - lo);
            let (raw_lo, raw_hi) = (lo, hi);
            (lo, hi) = (lo - pad, hi + pad);
            if raw_lo >= 0.0 && lo < 0.0 {
                lo = 0.0;
            }
            if raw_hi <= 0.0 && hi > 0.0 {
                hi = 0.0;
            }
        }
        let step = nice_step((hi - lo) / target.max(2) as f64);
        let first = (lo / step).floor();
        let last = (hi / step).ceil();
        let count = (last - first).clamp(1.0, 1000.0) as usize;
        let ticks: Vec<f64> = (0..=count).map(|i| (first + i as f64) * step).collect();
        let decimals = (-(step.log10() + 1e-9).floor()).max(0.0) as usize;
        Axis {
            lo: first * step,
            hi: last * step,
            ticks,
            decimals,
            label: label.into(),
        }
    }

    /// The axis of a full turn, 0° … 360° with a tick every 45°, when every finite value
    /// of `values` lies in it; else [`Axis::covering`] them and the turn.
    pub(crate) fn full_turn_deg(
        values: impl IntoIterator<Item = f64> + Clone,
        label: impl Into<String>,
    ) -> Self {
        let within = values
            .clone()
            .into_iter()
            .filter(|v| v.is_finite())
            .all(|v| (0.0..=360.0).contains(&v));
        if !within {
            return Axis::covering(values, &[0.0, 360.0], 8, label);
        }
        Axis {
            lo: 0.0,
            hi: 360.0,
            ticks: (0..=8).map(|i| f64::from(i) * 45.0).collect(),
            decimals: 0,
            label: label.into(),
        }
    }

    /// The tick label of `value`.
    pub(crate) fn tick_text(&self, value: f64) -> String {
        number_text(value, self.decimals)
    }
}

/// The step 1, 2 or 5 × 10^k at or above `raw`.
pub(crate) fn nice_step(raw: f64) -> f64 {
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let magnitude = 10f64.powf(raw.log10().floor());
    let fraction = raw / magnitude;
    let nice = if fraction <= 1.0 + 1e-9 {
        1.0
    } else if fraction <= 2.0 + 1e-9 {
        2.0
    } else if fraction <= 5.0 + 1e-9 {
        5.0
    } else {
        10.0
    };
    nice * magnitude
}

/// A plotting area and its two axes.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Panel {
    /// Name in `data-panel`, e.g. `main`, `difference`, `en`.
    pub id: &'static str,
    /// Left edge, px.
    pub left_px: f64,
    /// Top edge, px.
    pub top_px: f64,
    /// Width, px.
    pub width_px: f64,
    /// Height, px.
    pub height_px: f64,
    /// Horizontal axis.
    pub x: Axis,
    /// Vertical axis.
    pub y: Axis,
}

impl Panel {
    /// The x pixel of a value.
    pub(crate) fn x_px(&self, value: f64) -> f64 {
        self.left_px + (value - self.x.lo) / (self.x.hi - self.x.lo) * self.width_px
    }

    /// The y pixel of a value (up is larger).
    pub(crate) fn y_px(&self, value: f64) -> f64 {
        self.top_px + (self.y.hi - value) / (self.y.hi - self.y.lo) * self.height_px
    }

    /// Bottom edge, px.
    pub(crate) fn bottom_px(&self) -> f64 {
        self.top_px + self.height_px
    }

    /// The frame, grid, ticks with labels, the axis titles (the x title only when
    /// `x_title`), and a line at y = 0 when 0 is inside the axis.
    pub(crate) fn draw_axes(&self, out: &mut String, x_title: bool) {
        let (l, t, w, h) = (self.left_px, self.top_px, self.width_px, self.height_px);
        let b = t + h;
        let id = self.id;
        let _ = writeln!(
            out,
            r##"<rect class="frame" x="{}" y="{}" width="{}" height="{}" fill="none" stroke="#000" stroke-width="1"/>"##,
            px(l),
            px(t),
            px(w),
            px(h)
        );
        for &v in &self.x.ticks {
            let x = px(self.x_px(v));
            let _ = writeln!(
                out,
                r##"<line class="grid" x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#ddd" stroke-width="0.5"/>"##,
                px(t),
                px(b)
            );
            let _ = writeln!(
                out,
                r##"<line class="tick-x" data-panel="{id}" x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#000"/>"##,
                px(b),
                px(b + 4.0)
            );
            let _ = writeln!(
                out,
                r#"<text class="tick-label-x" data-panel="{id}" x="{x}" y="{}" font-size="10" text-anchor="middle">{}</text>"#,
                px(b + 15.0),
                esc(&self.x.tick_text(v))
            );
        }
        for &v in &self.y.ticks {
            let y = px(self.y_px(v));
            let _ = writeln!(
                out,
                r##"<line class="grid" x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#ddd" stroke-width="0.5"/>"##,
                px(l),
                px(l + w)
            );
            let _ = writeln!(
                out,
                r##"<line class="tick-y" data-panel="{id}" x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#000"/>"##,
                px(l - 4.0),
                px(l)
            );
            let _ = writeln!(
                out,
                r#"<text class="tick-label-y" data-panel="{id}" x="{}" y="{}" font-size="10" text-anchor="end">{}</text>"#,
                px(l - 6.0),
                px(self.y_px(v) + 3.5),
                esc(&self.y.tick_text(v))
            );
        }
        if self.y.lo < 0.0 && self.y.hi > 0.0 {
            let y = px(self.y_px(0.0));
            let _ = writeln!(
                out,
                r##"<line class="zero" x1="{}" y1="{y}" x2="{}" y2="{y}" stroke="#888" stroke-width="0.8"/>"##,
                px(l),
                px(l + w)
            );
        }
        if x_title {
            let _ = writeln!(
                out,
                r#"<text class="axis-title-x" x="{}" y="{}" font-size="11" text-anchor="middle">{}</text>"#,
                px(l + w / 2.0),
                px(b + 32.0),
                esc(&self.x.label)
            );
        }
        let (cx, cy) = (l - 58.0, t + h / 2.0);
        let _ = writeln!(
            out,
            r#"<text class="axis-title-y" x="{}" y="{}" font-size="11" text-anchor="middle" transform="rotate(-90 {} {})">{}</text>"#,
            px(cx),
            px(cy),
            px(cx),
            px(cy),
            esc(&self.y.label)
        );
    }
}

/// A marker shape, distinct in greyscale.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Marker {
    /// Filled black circle.
    FilledCircle,
    /// Open square.
    OpenSquare,
    /// Open triangle, apex up.
    Triangle,
    /// Laboratory i's own marker in a figure of many laboratories: one of eight shapes in
    /// one of eight colours (colour-blind-safe, none black), no two of the first 64 alike
    /// ([`lab_marker`]).
    Lab(u16),
}

/// The shapes of laboratories' markers, in turn.
const LAB_SHAPES: [&str; 8] = [
    "circle",
    "square",
    "triangle",
    "diamond",
    "triangle-down",
    "open-circle",
    "open-square",
    "open-diamond",
];

/// The colours of laboratories' markers (Okabe & Ito's palette without its black and
/// yellow, with a grey and a brown): black stays the reference's.
const LAB_COLOURS: [&str; 8] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#7F7F7F", "#8C564B",
];

/// Laboratory `i`'s shape and colour: shape i mod 8, colour (i + ⌊i/8⌋) mod 8, so the
/// first 64 laboratories each have their own pair.
pub(crate) fn lab_marker(i: usize) -> (&'static str, &'static str) {
    (LAB_SHAPES[i % 8], LAB_COLOURS[(i + i / 8) % 8])
}

impl Marker {
    /// The shape centred on (0, 0), of half-size `r` px.
    pub(crate) fn shape(self, r: f64) -> String {
        match self {
            Marker::FilledCircle => format!(r##"<circle r="{}" fill="#000"/>"##, px(r)),
            Marker::OpenSquare => format!(
                r##"<rect x="{}" y="{}" width="{}" height="{}" fill="#fff" stroke="#000" stroke-width="1"/>"##,
                px(-r),
                px(-r),
                px(2.0 * r),
                px(2.0 * r)
            ),
            Marker::Triangle => format!(
                r##"<path d="M0,{} L{},{} L{},{} Z" fill="#fff" stroke="#000" stroke-width="1"/>"##,
                px(-1.2 * r),
                px(1.1 * r),
                px(0.8 * r),
                px(-1.1 * r),
                px(0.8 * r)
            ),
            Marker::Lab(i) => {
                let (shape, colour) = lab_marker(usize::from(i));
                let open = shape.starts_with("open-");
                let fill = if open { "#fff" } else { colour };
                let attributes = format!(
                    r#"class="marker" data-shape="{shape}" data-colour="{colour}" fill="{fill}" stroke="{colour}" stroke-width="1.2""#
                );
                let (rr, h) = (px(r), px(1.25 * r));
                match shape.trim_start_matches("open-") {
                    "circle" => format!(r#"<circle r="{rr}" {attributes}/>"#),
                    "square" => format!(
                        r#"<rect x="{}" y="{}" width="{}" height="{}" {attributes}/>"#,
                        px(-r),
                        px(-r),
                        px(2.0 * r),
                        px(2.0 * r)
                    ),
                    "diamond" => {
                        format!(r#"<path d="M0,-{h} L{h},0 L0,{h} L-{h},0 Z" {attributes}/>"#)
                    }
                    "triangle-down" => format!(
                        r#"<path d="M0,{} L{},{} L{},{} Z" {attributes}/>"#,
                        px(1.2 * r),
                        px(1.1 * r),
                        px(-0.8 * r),
                        px(-1.1 * r),
                        px(-0.8 * r)
                    ),
                    _ => format!(
                        r#"<path d="M0,{} L{},{} L{},{} Z" {attributes}/>"#,
                        px(-1.2 * r),
                        px(1.1 * r),
                        px(0.8 * r),
                        px(-1.1 * r),
                        px(0.8 * r)
                    ),
                }
            }
        }
    }
}

/// One entry of a legend.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum LegendKey {
    /// A marker with a vertical bar through it when `bar`.
    Marker(Marker, bool),
    /// A line with an SVG dash pattern (`None`: solid).
    Line(Option<&'static str>),
    /// A grey band.
    Band,
    /// A ring around a point.
    Ring,
    /// Text only (an effect named, not drawn).
    Text,
}

/// Draws a legend in rows from (`left`, `top`), wrapping at the figure's width; returns
/// the height used, px.
pub(crate) fn legend(out: &mut String, entries: &[(LegendKey, String)], top_px: f64) -> f64 {
    if entries.is_empty() {
        return 0.0;
    }
    let (mut x, mut y) = (LEFT_PX, top_px + 8.0);
    let _ = writeln!(out, r#"<g class="legend">"#);
    for (key, text) in entries {
        let width = 26.0 + 6.0 * text.chars().count() as f64 + 14.0;
        if x + width > WIDTH_PX - RIGHT_PX && x > LEFT_PX {
            x = LEFT_PX;
            y += 16.0;
        }
        let (kx, ky) = (x + 10.0, y);
        match key {
            LegendKey::Marker(m, bar) => {
                if *bar {
                    let _ = writeln!(
                        out,
                        r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#000" stroke-width="0.8"/>"##,
                        px(kx),
                        px(ky - 6.0),
                        px(kx),
                        px(ky + 6.0)
                    );
                }
                let _ = writeln!(
                    out,
                    r#"<g transform="translate({},{})">{}</g>"#,
                    px(kx),
                    px(ky),
                    m.shape(3.5)
                );
            }
            LegendKey::Line(dash) => {
                let _ = writeln!(
                    out,
                    r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#000" stroke-width="1.2"{}/>"##,
                    px(kx - 9.0),
                    px(ky),
                    px(kx + 9.0),
                    px(ky),
                    dash.map_or(String::new(), |d| format!(r#" stroke-dasharray="{d}""#))
                );
            }
            LegendKey::Band => {
                let _ = writeln!(
                    out,
                    r##"<rect x="{}" y="{}" width="18" height="10" fill="#d9d9d9" stroke="#999" stroke-width="0.5"/>"##,
                    px(kx - 9.0),
                    px(ky - 5.0)
                );
            }
            LegendKey::Ring => {
                let _ = writeln!(
                    out,
                    r##"<circle cx="{}" cy="{}" r="5" fill="none" stroke="#000" stroke-width="1.2"/>"##,
                    px(kx),
                    px(ky)
                );
            }
            LegendKey::Text => {}
        }
        let _ = writeln!(
            out,
            r#"<text x="{}" y="{}" font-size="10.5">{}</text>"#,
            px(x + 24.0),
            px(y + 3.5),
            esc(text)
        );
        x += width;
    }
    let _ = writeln!(out, "</g>");
    y - top_px + 10.0
}

/// Draws one point: a `<g class="point">` translated to its centre.
pub(crate) fn point(
    out: &mut String,
    panel: &Panel,
    series: &str,
    index: usize,
    (x_px, y_px): (f64, f64),
    marker: Marker,
    r_px: f64,
) {
    let _ = writeln!(
        out,
        r#"<g class="point" data-panel="{}" data-series="{}" data-index="{index}" transform="translate({},{})">{}</g>"#,
        panel.id,
        esc(series),
        px(x_px),
        px(y_px),
        marker.shape(r_px)
    );
}

/// Draws a vertical error bar from `y − half` to `y + half` (values) at `x_px`, with caps
/// when `cap_px` > 0.
#[allow(clippy::too_many_arguments)]
pub(crate) fn error_bar(
    out: &mut String,
    panel: &Panel,
    series: &str,
    index: usize,
    x_px: f64,
    y: f64,
    half: f64,
    cap_px: f64,
) {
    let (y1, y2) = (panel.y_px(y - half), panel.y_px(y + half));
    let _ = writeln!(
        out,
        r##"<line class="error-bar" data-panel="{}" data-series="{}" data-index="{index}" x1="{x}" y1="{}" x2="{x}" y2="{}" stroke="#000" stroke-width="0.8"/>"##,
        panel.id,
        esc(series),
        px(y1),
        px(y2),
        x = px(x_px),
    );
    if cap_px > 0.0 {
        for yy in [y1, y2] {
            let _ = writeln!(
                out,
                r##"<line x1="{}" y1="{}" x2="{}" y2="{}" stroke="#000" stroke-width="0.8"/>"##,
                px(x_px - cap_px),
                px(yy),
                px(x_px + cap_px),
                px(yy)
            );
        }
    }
}

/// The whole document: an `<svg>` of `height_px` with a title, subtitle lines and `body`.
pub(crate) fn document(height_px: f64, title: &str, subtitles: &[String], body: &str) -> String {
    let mut out = String::with_capacity(body.len() + 1024);
    let _ = writeln!(
        out,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" role="img">"#,
        w = px(WIDTH_PX),
        h = px(height_px)
    );
    let _ = writeln!(out, "<title>{}</title>", esc(title));
    let _ = writeln!(
        out,
        r##"<rect x="0" y="0" width="{}" height="{}" fill="#fff"/>"##,
        px(WIDTH_PX),
        px(height_px)
    );
    let _ = writeln!(
        out,
        r#"<text class="title" x="{}" y="20" font-size="14" font-weight="bold">{}</text>"#,
        px(LEFT_PX),
        esc(title)
    );
    for (i, line) in subtitle_lines(subtitles).iter().enumerate() {
        let _ = writeln!(
            out,
            r##"<text class="subtitle" x="{}" y="{}" font-size="10.5" fill="#333">{}</text>"##,
            px(LEFT_PX),
            px(35.0 + 13.0 * i as f64),
            esc(line)
        );
    }
    out.push_str(body);
    out.push_str("</svg>\n");
    out
}

/// Where the legend begins below the `subtitles` (as [`document`] wraps them), px.
pub(crate) fn header_px(subtitles: &[String]) -> f64 {
    30.0 + 13.0 * subtitle_lines(subtitles).len() as f64
}

/// The most characters of a subtitle line: what 10.5 px sans-serif fits in the width.
const SUBTITLE_CHARS: usize = 100;

/// The subtitles wrapped at spaces into lines of at most [`SUBTITLE_CHARS`] characters (a
/// longer word stands alone on its line).
fn subtitle_lines(subtitles: &[String]) -> Vec<String> {
    let mut lines = Vec::new();
    for subtitle in subtitles {
        let mut line = String::new();
        for word in subtitle.split(' ') {
            if !line.is_empty() && line.chars().count() + 1 + word.chars().count() > SUBTITLE_CHARS
            {
                lines.push(std::mem::take(&mut line));
            }
            if !line.is_empty() {
                line.push(' ');
            }
            line.push_str(word);
        }
        lines.push(line);
    }
    lines
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nice_steps_are_one_two_five() {
        assert_eq!(nice_step(0.7), 1.0);
        assert_eq!(nice_step(1.3), 2.0);
        assert_eq!(nice_step(3.0), 5.0);
        assert!((nice_step(0.031) - 0.05).abs() < 1e-15);
        assert_eq!(nice_step(60.0), 100.0);
        assert_eq!(nice_step(f64::NAN), 1.0);
    }

    #[test]
    fn values_near_the_largest_float_are_left_out_not_overflowed() {
        // the margin of ±f64::MAX overflowed, and the tick count became usize::MAX
        let axis = Axis::covering([0.0, f64::MAX, 2.0, -f64::MAX], &[], 5, "β");
        assert_eq!((axis.lo, axis.hi), (0.0, 2.5));
        assert!(axis.ticks.len() <= 10, "{:?}", axis.ticks);
        let axis = Axis::covering([1e300, -1e300], &[0.0], 5, "β");
        assert!(axis.lo.is_finite() && axis.hi.is_finite() && axis.ticks.len() < 20);
    }

    #[test]
    fn degenerate_ranges_give_sane_axes() {
        for values in [
            vec![],
            vec![0.0, 0.0],
            vec![5.0],
            vec![f64::NAN, f64::INFINITY],
        ] {
            let axis = Axis::covering(values.clone(), &[], 5, "v");
            assert!(axis.hi > axis.lo, "{values:?}");
            assert!(axis.ticks.len() >= 2, "{values:?}");
            assert!(axis.ticks.iter().all(|t| t.is_finite()));
        }
        let axis = Axis::covering([-0.33, 0.41], &[0.0], 6, "v");
        assert!(axis.lo <= -0.33 && axis.hi >= 0.41);
        assert_eq!(axis.tick_text(-0.2), "−0.2");
        assert_eq!(axis.tick_text(-0.0), "0.0");
    }

    #[test]
    fn text_is_escaped() {
        assert_eq!(esc(r#"a<b>&"c'"#), "a&lt;b&gt;&amp;&quot;c&apos;");
        // bidirectional formatting characters shown, every one of them
        assert_eq!(esc("PTB\u{202e}LPN"), "PTB\\u{202e}LPN");
        for c in [
            '\u{61c}', '\u{200e}', '\u{200f}', '\u{202a}', '\u{202e}', '\u{2066}', '\u{2069}',
        ] {
            assert_eq!(esc(&c.to_string()), format!("\\u{{{:x}}}", c as u32));
        }
        assert_eq!(esc("\u{2065}\u{2029}é"), "\u{2065}\u{2029}é");
        // as data (the DCC): as written
        assert_eq!(esc_data("a<\u{202e}"), "a&lt;\u{202e}");
    }

    #[test]
    fn long_subtitles_wrap_at_spaces_and_lose_nothing() {
        let long = "word ".repeat(50).trim_end().to_string(); // 249 characters
        let lines = subtitle_lines(&[long.clone(), "short".into()]);
        assert_eq!(lines.len(), 4);
        assert!(lines.iter().all(|l| l.chars().count() <= SUBTITLE_CHARS));
        assert_eq!(lines[..3].join(" "), long);
        assert_eq!(header_px(&[long, "short".into()]), 30.0 + 13.0 * 4.0);
    }
}
