//! The figures of `polycal diagnose`: per autocollimator, its readings' residuals against
//! time (or against their order in the file when it has no time), under the base model
//! (upper panel `before`) and the final model (lower panel `after`), with each effect
//! found drawn where it acts; with no effect found the final model is the base model,
//! and one panel (`before`) shows its residuals.
//!
//! Classes (docs/FORMAT.md §10): `point` with `data-series` `before`/`after` and
//! `data-index` the reading's index in the file; `effect-drift` and `effect-step-level`
//! (a `<polyline>` of the effect's contribution to this autocollimator's readings, centred
//! on its mean over them, since the base model's setup error absorbs a constant), with
//! `data-value` the effect's value; `effect-step` (a dashed vertical `<line>` at the
//! first reading with the new zero); `effect-outlier` (a ring, `data-index`, in both panels).

use std::fmt::Write;

use serde_json::Value;

use super::Figure;
use super::chart::{Point, Series, draw_series, marker_px};
use super::svg::{
    Axis, LEFT_PX, LegendKey, Marker, Panel, RIGHT_PX, WIDTH_PX, document, header_px, legend,
    number_text, px,
};
use crate::effects::{Effect, EffectContext};
use crate::measurement::{Direction, Reading};
use crate::output::diagnose::{DiagnoseReport, ResidualsReport};

/// An effect's line: its class, its value, its (x, contribution) points.
type EffectLine = (&'static str, f64, Vec<(f64, f64)>);

/// Times beyond this are drawn in hours, s.
const HOURS_FROM_S: f64 = 2.0 * 3600.0;

/// The reading (bookkeeping only) at index `i` of the residuals, for an effect's regressor.
fn reading_at(r: &ResidualsReport, i: usize) -> Option<Reading> {
    Some(Reading {
        setup: *r.setup.get(i)?,
        cycle: *r.cycle.get(i)?,
        step: *r.step.get(i)?,
        ac: *r.ac.get(i)?,
        face: 0,
        reading_arcsec: 0.0,
        direction: if r.direction.get(i)? == &"ccw" {
            Direction::Ccw
        } else {
            Direction::Cw
        },
        time_seconds: r.time.as_ref().and_then(|t| t.get(i).copied().flatten()),
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line: 0,
    })
}

fn effect_of(value: &Value) -> Option<Effect> {
    serde_json::from_value(value.clone()).ok()
}

fn effect_ac(effect: &Effect) -> Option<u32> {
    match *effect {
        Effect::Drift { ac, .. }
        | Effect::OffsetStep { ac, .. }
        | Effect::Outlier { ac, .. }
        | Effect::Temperature { ac, .. }
        | Effect::CrossTalk { ac, .. }
        | Effect::Rezero { ac, .. } => Some(ac),
        Effect::Direction { ac, .. } => ac,
    }
}

/// `diagnose-residuals-ac<j>` for every autocollimator; none without residuals.
pub(crate) fn figures(report: &DiagnoseReport) -> Vec<Figure> {
    let Some(residuals) = &report.residuals else {
        return Vec::new();
    };
    let mut acs: Vec<u32> = residuals.ac.clone();
    acs.sort_unstable();
    acs.dedup();
    // a drift on the stop clock (a file without `time`, docs/FORMAT.md §6) cannot be
    // drawn against time: the figure leaves it out (the table and the JSON carry it)
    let effects: Vec<Effect> = report
        .effects
        .iter()
        .filter(|v| v.get("unit").and_then(Value::as_str) != Some("arcsec/stop"))
        .filter_map(effect_of)
        .collect();
    acs.into_iter()
        .map(|ac| one_ac(report, residuals, &effects, ac))
        .collect()
}

fn one_ac(
    report: &DiagnoseReport,
    residuals: &ResidualsReport,
    effects: &[Effect],
    ac: u32,
) -> Figure {
    let indices: Vec<usize> = (0..residuals.ac.len())
        .filter(|&i| residuals.ac[i] == ac)
        .collect();
    let (xs, x_label, x_note) = x_axis(residuals, &indices);
    // no effect found: the final model is the base model, and one panel shows its
    // residuals (two would be the same panel twice)
    let one_model = report.effects.is_empty();
    let (title, mut subtitles) = titles(report, ac, one_model, indices.len());
    subtitles.extend(x_note);
    let mine: Vec<&Effect> = effects
        .iter()
        .filter(|e| effect_ac(e).is_none_or(|a| a == ac))
        .collect();
    let entries = model_entries(one_model);
    let readings: Vec<Option<Reading>> =
        indices.iter().map(|&i| reading_at(residuals, i)).collect();
    let marks = EffectMarks::of(&mine, &xs, &readings, entries);
    if marks.step_x.is_empty() && mine.iter().any(|e| matches!(e, Effect::OffsetStep { .. })) {
        subtitles.push("the offset step acts on none of these readings".into());
    }
    let mut body = String::new();
    let top = header_px(&subtitles);
    let legend_px = legend(&mut body, &marks.entries, top);
    let before: Vec<f64> = indices.iter().map(|&i| residuals.before[i]).collect();
    let after: Vec<f64> = indices.iter().map(|&i| residuals.after[i]).collect();
    let y_values = before
        .iter()
        .chain(&after)
        .copied()
        .chain(marks.lines.iter().flat_map(|l| l.2.iter().map(|p| p.1)));
    let y = Axis::covering(y_values, &[0.0], 5, "residual / ″");
    let x = Axis::covering(xs.iter().copied(), &[], 8, x_label);
    let (upper, lower) = residual_panels(top + legend_px + 8.0, x, y, one_model);
    // the panels drawn: the lower only when the final model differs
    let panels: Vec<&Panel> = if one_model {
        vec![&upper]
    } else {
        vec![&upper, &lower]
    };
    upper.draw_axes(&mut body, one_model);
    if !one_model {
        lower.draw_axes(&mut body, true);
    }
    let series = |id: &str, marker, values: &[f64]| Series {
        id: id.into(),
        label: id.into(),
        marker,
        dx_px: 0.0,
        points: indices
            .iter()
            .zip(&xs)
            .zip(values)
            .map(|((&i, &x), &y)| Point {
                index: i,
                x,
                y,
                half: None,
            })
            .collect(),
    };
    draw_series(
        &mut body,
        &upper,
        &[series("before", Marker::FilledCircle, &before)],
    );
    if !one_model {
        draw_series(
            &mut body,
            &lower,
            &[series("after", Marker::OpenSquare, &after)],
        );
    }
    marks.draw(&mut body, ac, &panels, &indices, &xs, [&before, &after]);
    let bottom = panels.last().map_or(upper.bottom_px(), |p| p.bottom_px());
    let svg = document(bottom + 42.0, &title, &subtitles, &body);
    Figure::new(format!("diagnose-residuals-ac{ac}"), title, svg)
}

/// The legend's entries of the models' residuals: one model, or before and after.
fn model_entries(one_model: bool) -> Vec<(LegendKey, String)> {
    if one_model {
        vec![(
            LegendKey::Marker(Marker::FilledCircle, false),
            "residual (base model = final model)".to_string(),
        )]
    } else {
        vec![
            (
                LegendKey::Marker(Marker::FilledCircle, false),
                "before (base model)".to_string(),
            ),
            (
                LegendKey::Marker(Marker::OpenSquare, false),
                "after (final model)".to_string(),
            ),
        ]
    }
}

/// The residual panels on the axes `x` and `y`: the upper (`before`: the base model's,
/// or the one model's) at `top_px`, the lower (`after`: the final model's) below it.
fn residual_panels(top_px: f64, x: Axis, y: Axis, one_model: bool) -> (Panel, Panel) {
    let upper = Panel {
        id: "before",
        left_px: LEFT_PX,
        top_px,
        width_px: WIDTH_PX - LEFT_PX - RIGHT_PX,
        height_px: 150.0,
        x,
        y: Axis {
            label: if one_model {
                "residual / ″".into()
            } else {
                "before: residual / ″".into()
            },
            ..y.clone()
        },
    };
    let lower = Panel {
        id: "after",
        top_px: upper.bottom_px() + 26.0,
        y: Axis {
            label: "after: residual / ″".into(),
            ..y
        },
        ..upper.clone()
    };
    (upper, lower)
}

/// The x of the readings `indices`: their time in s (in h beyond [`HOURS_FROM_S`]), or
/// their number in file order when some has no time (with a note saying so); and the
/// axis's label.
fn x_axis(residuals: &ResidualsReport, indices: &[usize]) -> (Vec<f64>, String, Option<String>) {
    let times: Option<Vec<f64>> = residuals.time.as_ref().and_then(|t| {
        indices
            .iter()
            .map(|&i| t.get(i).copied().flatten())
            .collect()
    });
    match times {
        Some(t) if t.iter().copied().fold(0.0, f64::max) > HOURS_FROM_S => (
            t.iter().map(|t| t / 3600.0).collect(),
            "time / h".into(),
            None,
        ),
        Some(t) => (t, "time / s".into(), None),
        None => (
            indices.iter().map(|&i| (i + 1) as f64).collect(),
            "reading number in file order".into(),
            Some(
                "the file has no time for every reading: residuals against reading order"
                    .to_string(),
            ),
        ),
    }
}

/// The title and first subtitle of autocollimator `ac`'s figure: the models' residual
/// RMS (arcsec) and the number of its `readings`.
fn titles(
    report: &DiagnoseReport,
    ac: u32,
    one_model: bool,
    readings: usize,
) -> (String, Vec<String>) {
    let rms = |r: Option<f64>| r.map_or("—".to_string(), |r| format!("{r:.4}″"));
    if one_model {
        (
            format!("Residuals of autocollimator {ac} (no effect found)"),
            vec![format!(
                "no effect found: the final model is the base model (residual RMS {}); {} readings",
                rms(report.before.residual_rms),
                readings
            )],
        )
    } else {
        (
            format!("Residuals of autocollimator {ac}, before and after the effects"),
            vec![format!(
                "upper: base model (residual RMS {}); lower: final model (RMS {}); {} readings",
                rms(report.before.residual_rms),
                rms(report.after.residual_rms),
                readings
            )],
        )
    }
}

/// The effects' marks on one autocollimator's figure, drawn after the panels, with the
/// legend's entries.
struct EffectMarks {
    /// The legend: the models' markers, then one entry per effect.
    entries: Vec<(LegendKey, String)>,
    /// A drift's or an offset step's centred contribution.
    lines: Vec<EffectLine>,
    /// The x of an offset step's first reading with the new zero.
    step_x: Vec<f64>,
    /// The readings (place among the figure's) an outlier leaves out.
    rings: Vec<usize>,
}

impl EffectMarks {
    /// The marks of the effects `mine` on the readings at `xs`; `entries`: the legend's
    /// entries before the effects'.
    fn of(
        mine: &[&Effect],
        xs: &[f64],
        readings: &[Option<Reading>],
        entries: Vec<(LegendKey, String)>,
    ) -> EffectMarks {
        let context = EffectContext::default();
        let mut marks = EffectMarks {
            entries,
            lines: Vec::new(),
            step_x: Vec::new(),
            rings: Vec::new(),
        };
        for effect in mine {
            let name = effect.label();
            match effect {
                Effect::Drift { value, .. } | Effect::OffsetStep { value, .. } => {
                    let class = if matches!(effect, Effect::Drift { .. }) {
                        "effect-drift"
                    } else {
                        "effect-step-level"
                    };
                    let line = centred_contribution(effect, xs, readings, &context);
                    if let Effect::OffsetStep { .. } = effect
                        && let Some(first) = xs
                            .iter()
                            .zip(readings)
                            .filter(|(_, r)| {
                                r.as_ref()
                                    .is_some_and(|r| effect.regressor(r, &context) != 0.0)
                            })
                            .map(|(x, _)| *x)
                            .filter(|x| x.is_finite())
                            .reduce(f64::min)
                    {
                        marks.step_x.push(first);
                    }
                    let unit = if class == "effect-drift" {
                        "″/h"
                    } else {
                        "″"
                    };
                    marks.entries.push((
                        LegendKey::Line(Some(if class == "effect-drift" {
                            "6,3"
                        } else {
                            "2,2"
                        })),
                        format!("{name}: {}{unit} (centred)", number_text(*value, 4)),
                    ));
                    marks.lines.push((class, *value, line));
                }
                Effect::Outlier { value, .. } => {
                    for (k, r) in readings.iter().enumerate() {
                        if r.as_ref()
                            .is_some_and(|r| effect.regressor(r, &context) != 0.0)
                        {
                            marks.rings.push(k);
                        }
                    }
                    marks.entries.push((
                        LegendKey::Ring,
                        format!("{name}: {}″, left out", number_text(*value, 3)),
                    ));
                }
                _ => marks.entries.push((
                    LegendKey::Text,
                    format!("{name}: {} (not drawn)", number_text(effect.value(), 4)),
                )),
            }
        }
        marks
    }

    /// Draws the marks on the `panels` (the first's scales for the lines): the effects'
    /// lines, the steps' dashed verticals, the outliers' rings (on `values`, the
    /// residuals before and after, arcsec, of the readings `indices` at `xs`).
    fn draw(
        &self,
        body: &mut String,
        ac: u32,
        panels: &[&Panel],
        indices: &[usize],
        xs: &[f64],
        values: [&[f64]; 2],
    ) {
        let upper = panels[0];
        for (class, value, line) in &self.lines {
            let points: Vec<String> = line
                .iter()
                .map(|(x, c)| format!("{},{}", px(upper.x_px(*x)), px(upper.y_px(*c))))
                .collect();
            let _ = writeln!(
                body,
                r##"<polyline class="{class}" data-ac="{ac}" data-value="{value}" points="{}" fill="none" stroke="#000" stroke-width="1.5" stroke-dasharray="{}"/>"##,
                points.join(" "),
                if *class == "effect-drift" {
                    "6,3"
                } else {
                    "2,2"
                }
            );
        }
        for x in &self.step_x {
            for panel in panels {
                let xp = px(panel.x_px(*x));
                let _ = writeln!(
                    body,
                    r##"<line class="effect-step" data-panel="{}" data-x="{x}" x1="{xp}" y1="{}" x2="{xp}" y2="{}" stroke="#000" stroke-width="1" stroke-dasharray="5,3"/>"##,
                    panel.id,
                    px(panel.top_px),
                    px(panel.bottom_px())
                );
            }
        }
        let (r_px, _) = marker_px(indices.len());
        for &k in &self.rings {
            for (panel, values) in panels.iter().zip(values) {
                let (x, y) = (xs[k], values[k]);
                if x.is_finite() && y.is_finite() {
                    let _ = writeln!(
                        body,
                        r##"<circle class="effect-outlier" data-panel="{}" data-index="{}" cx="{}" cy="{}" r="{}" fill="none" stroke="#000" stroke-width="1.2"/>"##,
                        panel.id,
                        indices[k],
                        px(panel.x_px(x)),
                        px(panel.y_px(y)),
                        px(r_px + 4.0)
                    );
                }
            }
        }
    }
}

/// An effect's contribution to the readings at `xs`, centred on its mean over them (the
/// base model's setup error absorbs a constant), in arcsec, sorted by x.
fn centred_contribution(
    effect: &Effect,
    xs: &[f64],
    readings: &[Option<Reading>],
    context: &EffectContext,
) -> Vec<(f64, f64)> {
    let contribution: Vec<(f64, f64)> = xs
        .iter()
        .zip(readings)
        .filter_map(|(x, r)| Some((*x, effect.contribution(r.as_ref()?, context))))
        .filter(|(x, c)| x.is_finite() && c.is_finite())
        .collect();
    let mean = contribution.iter().map(|(_, c)| c).sum::<f64>() / contribution.len().max(1) as f64;
    let mut line: Vec<(f64, f64)> = contribution.iter().map(|(x, c)| (*x, c - mean)).collect();
    line.sort_by(|a, b| a.0.total_cmp(&b.0));
    line
}
