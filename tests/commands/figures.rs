//! The figures of `--plot DIR` (docs/FORMAT.md §10), checked numerically against the
//! command's own JSON output and independently of the plotting code's mapping: each
//! axis's pixel ↔ value map is fitted from its tick marks and tick labels as they appear
//! in the SVG, every plotted point and error bar is mapped back through it, and must equal
//! the JSON value within half a pixel.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use statrs::distribution::{ContinuousCDF, StudentsT};

const HALF_PX: f64 = 0.5;

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-figures-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn json_of(out: &Output) -> Value {
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "status {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

/// The text of a figure, which must parse as XML and hold no non-finite number.
fn svg_text(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert!(
        !text.contains("NaN") && !text.contains("inf\""),
        "{}",
        path.display()
    );
    text
}

fn attr(node: roxmltree::Node, name: &str) -> f64 {
    node.attribute(name)
        .unwrap_or_else(|| panic!("no {name}"))
        .parse()
        .unwrap()
}

fn class_is(node: &roxmltree::Node, class: &str) -> bool {
    node.attribute("class") == Some(class)
}

/// A linear map value → px fitted from the ticks and their labels.
#[derive(Debug, Clone, Copy)]
struct Map {
    offset: f64,
    slope: f64,
}

impl Map {
    fn px(&self, value: f64) -> f64 {
        self.offset + self.slope * value
    }
    fn value(&self, px: f64) -> f64 {
        (px - self.offset) / self.slope
    }
}

/// Fits the map of one axis (`x` or `y`) of one panel from its ticks and labels.
fn axis_map(doc: &roxmltree::Document, panel: &str, axis: &str) -> Map {
    axis_map_in(doc.root(), panel, axis)
}

/// [`axis_map`] of the ticks under `root` alone (one graph of several).
fn axis_map_in(root: roxmltree::Node, panel: &str, axis: &str) -> Map {
    let in_panel = |n: &roxmltree::Node, class: &str| {
        class_is(n, class) && n.attribute("data-panel") == Some(panel)
    };
    let positions: Vec<f64> = root
        .descendants()
        .filter(|n| in_panel(n, &format!("tick-{axis}")))
        .map(|n| attr(n, if axis == "x" { "x1" } else { "y1" }))
        .collect();
    let values: Vec<f64> = root
        .descendants()
        .filter(|n| in_panel(n, &format!("tick-label-{axis}")))
        .map(|n| n.text().unwrap().replace('−', "-").parse::<f64>().unwrap())
        .collect();
    assert_eq!(positions.len(), values.len(), "{panel} {axis}");
    assert!(positions.len() >= 2, "{panel} {axis}: ticks");
    // Ticks are "nice": consecutive differences of 1, 2 or 5 × 10^k, or 45° on a full
    // turn's axis.
    let step = values[1] - values[0];
    let mantissa = step / 10f64.powf(step.log10().floor());
    assert!(
        step == 45.0
            || [1.0, 2.0, 5.0, 10.0]
                .iter()
                .any(|m| (mantissa - m).abs() < 1e-6),
        "{panel} {axis}: step {step}"
    );
    let n = positions.len() as f64;
    let (mv, mp) = (
        values.iter().sum::<f64>() / n,
        positions.iter().sum::<f64>() / n,
    );
    let sxy: f64 = values
        .iter()
        .zip(&positions)
        .map(|(v, p)| (v - mv) * (p - mp))
        .sum();
    let sxx: f64 = values.iter().map(|v| (v - mv).powi(2)).sum();
    let slope = sxy / sxx;
    let map = Map {
        offset: mp - slope * mv,
        slope,
    };
    for (v, p) in values.iter().zip(&positions) {
        assert!(
            (map.px(*v) - p).abs() < 0.02,
            "{panel} {axis}: ticks not linear"
        );
    }
    map
}

/// The points of a series: (data-index, x px, y px), in document order.
fn points(doc: &roxmltree::Document, panel: &str, series: &str) -> Vec<(usize, f64, f64)> {
    doc.descendants()
        .filter(|n| {
            class_is(n, "point")
                && n.attribute("data-panel") == Some(panel)
                && n.attribute("data-series") == Some(series)
        })
        .map(|n| {
            let t = n.attribute("transform").unwrap();
            let inner = t.trim_start_matches("translate(").trim_end_matches(')');
            let (x, y) = inner.split_once(',').unwrap();
            (
                n.attribute("data-index").unwrap().parse().unwrap(),
                x.parse().unwrap(),
                y.parse().unwrap(),
            )
        })
        .collect()
}

/// The error bars of a series: data-index → (x px, y1 px, y2 px).
fn bars(doc: &roxmltree::Document, panel: &str, series: &str) -> Vec<(usize, f64, f64, f64)> {
    doc.descendants()
        .filter(|n| {
            class_is(n, "error-bar")
                && n.attribute("data-panel") == Some(panel)
                && n.attribute("data-series") == Some(series)
        })
        .map(|n| {
            (
                n.attribute("data-index").unwrap().parse().unwrap(),
                attr(n, "x1"),
                attr(n, "y1"),
                attr(n, "y2"),
            )
        })
        .collect()
}

/// Checks that the series' points sit at (xs[i], ys[i]) and, with `half`, that each bar
/// is centred on the point with half-length half[i], all within half a pixel.
#[allow(clippy::too_many_arguments)]
fn check_series(
    text: &str,
    panel: &str,
    series: &str,
    xs: &[f64],
    ys: &[f64],
    half: Option<&[f64]>,
    x_tolerance_px: f64,
) {
    let doc = roxmltree::Document::parse(text).unwrap();
    let (mx, my) = (axis_map(&doc, panel, "x"), axis_map(&doc, panel, "y"));
    let pts = points(&doc, panel, series);
    assert_eq!(pts.len(), ys.len(), "{series}: every point drawn");
    for &(i, x, y) in &pts {
        assert!(
            (mx.px(xs[i]) - x).abs() <= x_tolerance_px,
            "{series}[{i}]: x {} px for {}",
            x,
            xs[i]
        );
        assert!(
            (my.px(ys[i]) - y).abs() <= HALF_PX,
            "{series}[{i}]: y maps back to {}, JSON {}",
            my.value(y),
            ys[i]
        );
    }
    let drawn = bars(&doc, panel, series);
    match half {
        None => assert!(drawn.is_empty(), "{series}: no bars without U"),
        Some(half) => {
            assert_eq!(drawn.len(), half.len(), "{series}: every bar drawn");
            for (i, _, y1, y2) in drawn {
                let half_px = (y1 - y2).abs() / 2.0;
                assert!(
                    (half_px - half[i] * my.slope.abs()).abs() <= HALF_PX,
                    "{series}[{i}]: bar half-length {} for U {}",
                    half_px / my.slope.abs(),
                    half[i]
                );
                assert!((my.px(ys[i]) - (y1 + y2) / 2.0).abs() <= HALF_PX);
            }
        }
    }
}

const DATA: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";

fn solve(dir: &Path, extra: &[&str]) -> Value {
    let d = dir.to_str().unwrap();
    let mut args = vec!["solve", DATA, "--format", "json", "--plot", d];
    args.extend_from_slice(extra);
    json_of(&polycal(&args))
}

#[test]
fn solve_without_budget_bars_are_students_t_times_u() {
    let dir = temp_dir("solve");
    let json = solve(&dir, &[]);
    let n = json["faces"].as_u64().unwrap() as usize;
    let dof = json["dof"].as_f64().unwrap();
    assert_eq!(json["sigma_source"], "residual");
    // Independent of the project's Student t: statrs.
    let k = StudentsT::new(0.0, 1.0, dof).unwrap().inverse_cdf(0.975);
    let beta = floats(&json["pitch_deviation"]);
    let u_beta: Vec<f64> = floats(&json["pitch_deviation_u"])
        .iter()
        .map(|u| k * u)
        .collect();
    let faces: Vec<f64> = (1..=n).map(|f| f as f64).collect();
    let text = svg_text(&dir.join("pitch-deviation.svg"));
    assert!(text.contains(&format!("k = {k:.2}")), "the figure states k");
    assert!(text.contains("pitch deviation β / ″"));
    check_series(&text, "main", "beta", &faces, &beta, Some(&u_beta), HALF_PX);

    let alpha = floats(&json["encoder_error"]);
    let u_alpha: Vec<f64> = floats(&json["encoder_error_u"])
        .iter()
        .map(|u| k * u)
        .collect();
    let angles: Vec<f64> = (0..n).map(|p| 360.0 * p as f64 / n as f64).collect();
    let text = svg_text(&dir.join("encoder-error.svg"));
    assert!(text.contains("table angle / °"));
    check_series(
        &text,
        "main",
        "alpha",
        &angles,
        &alpha,
        Some(&u_alpha),
        HALF_PX,
    );

    let phi = floats(&json["face_deviation"]);
    let u_phi: Vec<f64> = floats(&json["face_deviation_u"])
        .iter()
        .map(|u| k * u)
        .collect();
    let text = svg_text(&dir.join("face-deviation.svg"));
    check_series(&text, "main", "phi", &faces, &phi, Some(&u_phi), HALF_PX);
    assert!(!dir.join("budget-pitch-deviation.svg").exists());
}

#[test]
fn solve_with_budget_bars_are_the_budgets_u_and_budget_bars_its_indices() {
    let dir = temp_dir("solve-budget");
    let json = solve(&dir, &["--budget", BUDGET]);
    let n = json["faces"].as_u64().unwrap() as usize;
    let faces: Vec<f64> = (1..=n).map(|f| f as f64).collect();
    let text = svg_text(&dir.join("pitch-deviation.svg"));
    assert!(text.contains("from the instrument budget"));
    check_series(
        &text,
        "main",
        "beta",
        &faces,
        &floats(&json["pitch_deviation"]),
        Some(&floats(&json["pitch_deviation_U"])),
        HALF_PX,
    );
    let angles: Vec<f64> = (0..n).map(|p| 360.0 * p as f64 / n as f64).collect();
    check_series(
        &svg_text(&dir.join("encoder-error.svg")),
        "main",
        "alpha",
        &angles,
        &floats(&json["encoder_error"]),
        Some(&floats(&json["encoder_error_U"])),
        HALF_PX,
    );

    for (family, index_base) in [("pitch_deviation", 1), ("encoder_error", 0)] {
        let unc = &json["uncertainty"];
        let big_u = floats(&unc[family]["U"]);
        let j = (0..big_u.len())
            .max_by(|&a, &b| big_u[a].total_cmp(&big_u[b]))
            .unwrap();
        let u_c = floats(&unc[family]["u"])[j];
        let mut expected: Vec<(String, f64)> = vec![(
            "type A".into(),
            100.0 * (floats(&unc[family]["u_a"])[j] / u_c).powi(2),
        )];
        for c in unc["components"].as_array().unwrap() {
            let u = floats(&c[family])[j];
            expected.push((
                c["name"].as_str().unwrap().into(),
                100.0 * (u / u_c).powi(2),
            ));
        }
        let path = dir.join(format!("budget-{}.svg", family.replace('_', "-")));
        let text = svg_text(&path);
        let symbol = if family == "pitch_deviation" {
            "β"
        } else {
            "α"
        };
        assert!(
            text.contains(&format!("{symbol}[{}]", j + index_base)),
            "the title names the quantity"
        );
        let doc = roxmltree::Document::parse(&text).unwrap();
        let mx = axis_map(&doc, "main", "x");
        let drawn: Vec<(String, f64)> = doc
            .descendants()
            .filter(|n| class_is(n, "bar"))
            .map(|n| {
                let x0 = mx.value(attr(n, "x"));
                assert!(x0.abs() * mx.slope.abs() <= HALF_PX, "bars start at 0");
                (
                    n.attribute("data-component").unwrap().to_string(),
                    attr(n, "width") / mx.slope,
                )
            })
            .collect();
        assert_eq!(drawn.len(), expected.len(), "every component and type A");
        for w in drawn.windows(2) {
            assert!(w[0].1 >= w[1].1 - 1e-9, "largest first");
        }
        for (name, index) in &expected {
            let (_, width) = drawn
                .iter()
                .find(|(d, _)| d == name || (name == "type A" && d.starts_with("type A")))
                .unwrap_or_else(|| panic!("{name} drawn"));
            assert!(
                ((width - index) * mx.slope).abs() <= HALF_PX,
                "{family} {name}: bar {width} %, index {index} %"
            );
        }
    }
}

#[test]
fn compare_band_is_the_en_denominator_and_every_en_over_one_is_marked() {
    let dir = temp_dir("compare");
    let a = dir.join("a.csv");
    let b = dir.join("b.csv");
    let out = polycal(&["solve", DATA, "--budget", BUDGET, "--format", "csv"]);
    std::fs::write(&a, &out.stdout).unwrap();
    let sim = polycal(&[
        "simulate",
        "--closing",
        "--seed",
        "2",
        "--out",
        dir.join("sim.csv").to_str().unwrap(),
    ]);
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
    let out = polycal(&[
        "solve",
        dir.join("sim.csv").to_str().unwrap(),
        "--budget",
        BUDGET,
        "--format",
        "csv",
    ]);
    std::fs::write(&b, &out.stdout).unwrap();
    let plot = dir.join("plot");
    let json = json_of(&polycal(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--format",
        "json",
        "--plot",
        plot.to_str().unwrap(),
    ]));
    let rows = json["rows"].as_array().unwrap();
    let mut some_over = false;
    let mut some_under = false;
    for family in ["pitch_deviation", "encoder_error"] {
        let rows: Vec<&Value> = rows.iter().filter(|r| r["quantity"] == family).collect();
        assert!(!rows.is_empty());
        let get = |k: &str| {
            rows.iter()
                .map(|r| r[k].as_f64().unwrap())
                .collect::<Vec<f64>>()
        };
        // Encoder errors matched by angle are drawn against it.
        let xs: Vec<f64> = rows
            .iter()
            .map(|r| r.get("angle_deg").unwrap_or(&r["index"]).as_f64().unwrap())
            .collect();
        let slug = family.replace('_', "-");
        let text = svg_text(&plot.join(format!("compare-{slug}.svg")));
        check_series(
            &text,
            "main",
            "a",
            &xs,
            &get("a"),
            Some(&get("U_a")),
            3.0 + HALF_PX,
        );
        check_series(
            &text,
            "main",
            "b",
            &xs,
            &get("b"),
            Some(&get("U_b")),
            3.0 + HALF_PX,
        );

        let text = svg_text(&plot.join(format!("compare-{slug}-difference.svg")));
        // the rows with |En| > 1 beside the number expected by chance: 4.55 % a row when
        // U = k·u with k near 2 on both sides (docs/FORMAT.md §5.4)
        let exceeding = rows
            .iter()
            .filter(|r| r["en"].as_f64().unwrap().abs() > 1.0)
            .count();
        assert!(
            text.contains(&format!(
                "{exceeding} of {} rows with |En| &gt; 1, about ",
                rows.len()
            )) && text.contains("expected by chance"),
            "{slug}"
        );
        check_series(
            &text,
            "difference",
            "difference",
            &xs,
            &get("difference"),
            None,
            HALF_PX,
        );
        let doc = roxmltree::Document::parse(&text).unwrap();
        let my = axis_map(&doc, "difference", "y");
        let (ua, ub) = (get("U_a"), get("U_b"));
        let bands: Vec<_> = doc.descendants().filter(|n| class_is(n, "band")).collect();
        assert_eq!(bands.len(), rows.len());
        for band in bands {
            let i: usize = band.attribute("data-index").unwrap().parse().unwrap();
            let half = (ua[i].powi(2) + ub[i].powi(2)).sqrt();
            let (y, h) = (attr(band, "y"), attr(band, "height"));
            assert!(
                (my.value(y) - half).abs() * my.slope.abs() <= HALF_PX,
                "band top {i}"
            );
            assert!(
                (my.value(y + h) + half).abs() * my.slope.abs() <= HALF_PX,
                "band bottom {i}"
            );
        }
        let en = get("en");
        let over: BTreeSet<usize> = (0..en.len()).filter(|&i| en[i].abs() > 1.0).collect();
        some_over |= !over.is_empty();
        some_under |= over.len() < en.len();
        let ringed: BTreeSet<usize> = doc
            .descendants()
            .filter(|n| class_is(n, "en-exceeds-ring"))
            .map(|n| n.attribute("data-index").unwrap().parse().unwrap())
            .collect();
        assert_eq!(ringed, over, "{family}: ringed = |En| > 1");
        let filled: BTreeSet<usize> = points(&doc, "en", "en-exceeds")
            .iter()
            .map(|p| p.0)
            .collect();
        assert_eq!(filled, over, "{family}: filled En markers = |En| > 1");
        let en_over: Vec<f64> = en.clone();
        let mut all: Vec<(usize, f64, f64)> = points(&doc, "en", "en");
        all.extend(points(&doc, "en", "en-exceeds"));
        assert_eq!(all.len(), en.len());
        let (mx, my) = (axis_map(&doc, "en", "x"), axis_map(&doc, "en", "y"));
        for (i, x, y) in all {
            assert!((mx.px(xs[i]) - x).abs() <= HALF_PX);
            assert!((my.px(en_over[i]) - y).abs() <= HALF_PX, "En[{i}]");
        }
        let limits: Vec<f64> = doc
            .descendants()
            .filter(|n| class_is(n, "en-limit"))
            .map(|n| my.value(attr(n, "y1")))
            .collect();
        assert_eq!(limits.len(), 2);
        assert!(
            limits
                .iter()
                .any(|v| (v - 1.0).abs() * my.slope.abs() <= HALF_PX)
        );
        assert!(
            limits
                .iter()
                .any(|v| (v + 1.0).abs() * my.slope.abs() <= HALF_PX)
        );
    }
    assert!(some_over && some_under, "the data exercise both cases");
}

#[test]
fn diagnose_residuals_and_the_effects_where_they_act() {
    let dir = temp_dir("diagnose");
    let sim = dir.join("sim.csv");
    let out = polycal(&[
        "simulate",
        "--closing",
        "--drift",
        "2:1.5",
        "--offset-step",
        "1:4:0.8",
        "--outlier",
        "3:7:1:3.0",
        "--seed",
        "5",
        "--out",
        sim.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let plot = dir.join("plot");
    let json = json_of(&polycal(&[
        "diagnose",
        sim.to_str().unwrap(),
        "--format",
        "json",
        "--plot",
        plot.to_str().unwrap(),
    ]));
    let res = &json["residuals"];
    let acs: Vec<u64> = res["ac"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    let time: Vec<f64> = floats(&res["time"]);
    let (before, after) = (floats(&res["before"]), floats(&res["after"]));
    let hours = time.iter().copied().fold(0.0, f64::max) > 7200.0;
    let scale = if hours { 1.0 / 3600.0 } else { 1.0 };
    let xs: Vec<f64> = time.iter().map(|t| t * scale).collect();
    let effects = json["effects"].as_array().unwrap();
    let kinds: Vec<&str> = effects
        .iter()
        .map(|e| e["kind"].as_str().unwrap())
        .collect();
    assert!(
        kinds.contains(&"drift") && kinds.contains(&"offset-step") && kinds.contains(&"outlier"),
        "{kinds:?}"
    );
    for ac in [1u64, 2] {
        let text = svg_text(&plot.join(format!("diagnose-residuals-ac{ac}.svg")));
        let doc = roxmltree::Document::parse(&text).unwrap();
        assert!(text.contains(if hours { "time / h" } else { "time / s" }));
        // Points by file index; only this ac's.
        let mine: BTreeSet<usize> = (0..acs.len()).filter(|&i| acs[i] == ac).collect();
        for (panel, values) in [("before", &before), ("after", &after)] {
            let (mx, my) = (axis_map(&doc, panel, "x"), axis_map(&doc, panel, "y"));
            let pts = points(&doc, panel, panel);
            assert_eq!(pts.iter().map(|p| p.0).collect::<BTreeSet<_>>(), mine);
            for (i, x, y) in pts {
                assert!((mx.px(xs[i]) - x).abs() <= HALF_PX);
                assert!((my.px(values[i]) - y).abs() <= HALF_PX, "{panel}[{i}]");
            }
        }
        let (mx, my) = (axis_map(&doc, "before", "x"), axis_map(&doc, "before", "y"));
        for effect in effects {
            if effect["ac"].as_u64() != Some(ac) {
                continue;
            }
            match effect["kind"].as_str().unwrap() {
                "drift" => {
                    // The line's slope is the drift rate, arcsec per hour.
                    let line = doc
                        .descendants()
                        .find(|n| class_is(n, "effect-drift"))
                        .expect("drift line");
                    let pts: Vec<(f64, f64)> = line
                        .attribute("points")
                        .unwrap()
                        .split_whitespace()
                        .map(|p| {
                            let (x, y) = p.split_once(',').unwrap();
                            (mx.value(x.parse().unwrap()), my.value(y.parse().unwrap()))
                        })
                        .collect();
                    let (first, last) = (pts[0], pts[pts.len() - 1]);
                    let per_hour = (last.1 - first.1) / ((last.0 - first.0) / scale / 3600.0);
                    let value = effect["value"].as_f64().unwrap();
                    assert!(effect.get("quadratic").is_none());
                    assert!(
                        (per_hour - value).abs() < 0.01 * value.abs(),
                        "drift slope {per_hour} for {value}"
                    );
                }
                "offset-step" => {
                    // At the first reading of this ac in the jump's cycle.
                    let cycle = effect["cycle"].as_u64().unwrap();
                    let first = (0..acs.len())
                        .filter(|&i| acs[i] == ac && res["cycle"][i].as_u64() == Some(cycle))
                        .map(|i| xs[i])
                        .fold(f64::INFINITY, f64::min);
                    let lines: Vec<_> = doc
                        .descendants()
                        .filter(|n| class_is(n, "effect-step"))
                        .collect();
                    assert_eq!(lines.len(), 2, "one line per panel");
                    for l in lines {
                        assert!(
                            (mx.px(first) - attr(l, "x1")).abs() <= HALF_PX,
                            "step at the jump"
                        );
                    }
                    assert!(doc.descendants().any(|n| class_is(&n, "effect-step-level")));
                }
                "outlier" => {
                    let left: Vec<usize> = res["left_out"]
                        .as_array()
                        .unwrap()
                        .iter()
                        .map(|v| v.as_u64().unwrap() as usize)
                        .collect();
                    assert_eq!(left.len(), 1);
                    let i = left[0];
                    assert_eq!(res["cycle"][i].as_u64(), effect["cycle"].as_u64());
                    assert_eq!(res["step"][i].as_u64(), effect["step"].as_u64());
                    // Its residual after is what its term absorbs: reading − model, not 0.
                    assert!((after[i] - effect["value"].as_f64().unwrap()).abs() < 0.2);
                    let rings: Vec<usize> = doc
                        .descendants()
                        .filter(|n| class_is(n, "effect-outlier"))
                        .map(|n| n.attribute("data-index").unwrap().parse().unwrap())
                        .collect();
                    assert_eq!(rings, vec![i, i], "ringed in both panels");
                }
                _ => {}
            }
        }
        if ac == 2 {
            assert!(
                !doc.descendants().any(|n| class_is(&n, "effect-outlier")),
                "the outlier is ac 1's"
            );
        }
    }
}

#[test]
fn selfcal_168_positions_with_u_bars() {
    let dir = temp_dir("selfcal");
    let json = json_of(&polycal(&[
        "selfcal",
        "examples/data/selfa-168.csv",
        "--format",
        "json",
        "--plot",
        dir.to_str().unwrap(),
    ]));
    let e = floats(&json["encoder_error"]);
    assert_eq!(e.len(), 168);
    let text = svg_text(&dir.join("selfcal-encoder-error.svg"));
    check_series(
        &text,
        "main",
        "e",
        &floats(&json["encoder_angle_deg"]),
        &e,
        Some(&floats(&json["encoder_error_U"])),
        HALF_PX,
    );
    let heads = json["head_error"].as_array().unwrap();
    let text = svg_text(&dir.join("selfcal-head-error.svg"));
    let get = |k: &str| {
        heads
            .iter()
            .map(|h| h[k].as_f64().unwrap())
            .collect::<Vec<f64>>()
    };
    check_series(
        &text,
        "main",
        "c",
        &get("angle_deg"),
        &get("value"),
        Some(&get("U")),
        HALF_PX,
    );
}

#[test]
fn plot_refuses_several_files_and_reports_an_unwritable_directory() {
    let out = polycal(&["solve", DATA, DATA, "--plot", "/tmp/x"]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "{err}"
    );
    assert!(err.contains("--plot"));
    let dir = temp_dir("unwritable");
    let file = dir.join("a-file");
    std::fs::write(&file, "x").unwrap();
    let out = polycal(&["solve", DATA, "--plot", file.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("error:") && err.contains("a-file"), "{err}");
}

/// `kc --plot`: every laboratory's d_i with its U(d_i) bar, the reference with
/// U = 2·u_ref and each laboratory's x_ref + d_i, and the pilot's repeats' d_r with U(d_r),
/// read back through the axes' ticks and checked against the JSON's numbers; the
/// laboratory left out is drawn with open squares and said so in the legend.
#[test]
fn kc_degrees_of_equivalence_reference_and_pilot_against_the_json() {
    let dir = temp_dir("kc");
    let d = dir.to_str().unwrap();
    let k = "examples/data/kc";
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|n| format!("{n}={k}/{n}.csv"))
        .collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    // the first two repeats agree (the artefact stable): F is left out
    let start = format!("start={k}/pilot-start.csv");
    let middle = format!("middle={k}/pilot-middle.csv");
    args.extend([
        "--pilot",
        &start,
        "--pilot",
        &middle,
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
        "--plot",
        d,
    ]);
    let json = json_of(&polycal(&args));
    let faces = floats(&json["index"]);
    let reference = floats(&json["reference"]);
    let reference_u = floats(&json["reference_u"]);
    let text = svg_text(&dir.join("kc-degrees-of-equivalence.svg"));
    let doe = json["degrees_of_equivalence"].as_array().unwrap();
    for (i, lab) in doe.iter().enumerate() {
        let series = format!("lab{i}");
        let (dd, u) = (floats(&lab["d"]), floats(&lab["U"]));
        check_series(&text, "main", &series, &faces, &dd, Some(&u), 10.0);
        if lab["in_reference"] == false {
            let name = lab["lab"].as_str().unwrap();
            assert!(text.contains(&format!("{name} (left out of the reference)")));
        }
    }
    assert_eq!(json["excluded"][0]["lab"], "F");
    let text = svg_text(&dir.join("kc-reference.svg"));
    let twice: Vec<f64> = reference_u.iter().map(|u| 2.0 * u).collect();
    check_series(
        &text,
        "main",
        "reference",
        &faces,
        &reference,
        Some(&twice),
        10.0,
    );
    for (i, lab) in doe.iter().enumerate() {
        let x: Vec<f64> = floats(&lab["d"])
            .iter()
            .zip(&reference)
            .map(|(d, r)| r + d)
            .collect();
        check_series(&text, "main", &format!("lab{i}"), &faces, &x, None, 10.0);
    }
    let text = svg_text(&dir.join("kc-pilot-stability.svg"));
    for (r, repeat) in json["pilot"]["degrees_of_equivalence"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let (dd, u) = (floats(&repeat["d"]), floats(&repeat["U"]));
        check_series(
            &text,
            "main",
            &format!("repeat{r}"),
            &faces,
            &dd,
            Some(&u),
            10.0,
        );
    }
    assert!(text.contains("k = 2") && text.contains("″"));
}

/// The point of a `<g class="point">` (its translation), px.
fn translation(node: roxmltree::Node) -> (f64, f64) {
    let t = node.attribute("transform").unwrap();
    let inner = t.trim_start_matches("translate(").trim_end_matches(')');
    let (x, y) = inner.split_once(',').unwrap();
    (x.parse().unwrap(), y.parse().unwrap())
}

/// Checks `kc-kcdb.svg` against the comparison's JSON: one graph per position drawn
/// (`drawn`, positions in `index`), in each every laboratory's d_i and U(d_i) read back
/// through the graph's own y ticks within half a pixel, its name under its bar, the
/// laboratories not in the reference drawn as open squares with their names in italics.
fn check_kcdb(text: &str, json: &Value, drawn: &[usize]) {
    let doc = roxmltree::Document::parse(text).unwrap();
    let graphs: Vec<roxmltree::Node> = doc
        .descendants()
        .filter(|n| class_is(n, "position"))
        .collect();
    let indices: Vec<usize> = graphs
        .iter()
        .map(|g| g.attribute("data-index").unwrap().parse().unwrap())
        .collect();
    assert_eq!(indices, drawn);
    let labs = json["degrees_of_equivalence"].as_array().unwrap();
    for (g, &k) in graphs.iter().zip(drawn) {
        let my = axis_map_in(*g, "main", "y");
        // no x ticks: the laboratories are the x axis, by name
        assert_eq!(g.descendants().filter(|n| class_is(n, "tick-x")).count(), 0);
        let zero = g.descendants().find(|n| class_is(n, "zero"));
        if let Some(zero) = zero {
            assert!(my.value(attr(zero, "y1")).abs() < 1e-9 + HALF_PX / my.slope.abs());
        }
        let mut last_x = f64::NEG_INFINITY;
        for (i, lab) in labs.iter().enumerate() {
            let series = format!("lab{i}");
            let (d, u) = (floats(&lab["d"])[k], floats(&lab["U"])[k]);
            let point = g
                .descendants()
                .find(|n| class_is(n, "point") && n.attribute("data-series") == Some(&series))
                .unwrap_or_else(|| panic!("position {k}: {series} drawn"));
            assert_eq!(point.attribute("data-index"), Some(k.to_string().as_str()));
            let (x, y) = translation(point);
            assert!(
                x > last_x,
                "the laboratories left to right in the JSON's order"
            );
            last_x = x;
            assert!(
                (my.px(d) - y).abs() <= HALF_PX,
                "position {k} {series}: y maps back to {}, JSON {d}",
                my.value(y)
            );
            let bar = g
                .descendants()
                .find(|n| class_is(n, "error-bar") && n.attribute("data-series") == Some(&series))
                .unwrap();
            let (y1, y2) = (attr(bar, "y1"), attr(bar, "y2"));
            assert!(((y1 - y2).abs() / 2.0 - u * my.slope.abs()).abs() <= HALF_PX);
            assert!((my.px(d) - (y1 + y2) / 2.0).abs() <= HALF_PX);
            assert!((attr(bar, "x1") - x).abs() < 1e-9);
            let label = g
                .descendants()
                .find(|n| {
                    class_is(n, "lab-label") && n.attribute("data-lab") == Some(&i.to_string())
                })
                .unwrap();
            assert_eq!(label.text(), lab["lab"].as_str());
            assert!(
                (attr(label, "x") - x).abs() <= 4.0,
                "{series}: its name under it"
            );
            let in_reference = lab["in_reference"].as_bool().unwrap();
            assert_eq!(
                label.attribute("data-in-reference"),
                Some(in_reference.to_string().as_str())
            );
            assert_eq!(
                label.attribute("font-style") == Some("italic"),
                !in_reference
            );
            let square = point.descendants().any(|n| n.has_tag_name("rect"));
            assert_eq!(
                square, !in_reference,
                "{series}: □ when not in the reference"
            );
        }
    }
}

/// `kc --plot`: the KCDB graphs of the bundled comparison, one per face, against the JSON;
/// F, left out, drawn apart and named under the title.
#[test]
fn kc_kcdb_graphs_one_per_face_against_the_json() {
    let dir = temp_dir("kcdb");
    let k = "examples/data/kc";
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|n| format!("{n}={k}/{n}.csv"))
        .collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend([
        "--quantity",
        "pitch_deviation",
        "--format",
        "json",
        "--plot",
        dir.to_str().unwrap(),
    ]);
    let json = json_of(&polycal(&args));
    assert_eq!(json["excluded"][0]["lab"], "F");
    let text = svg_text(&dir.join("kc-kcdb.svg"));
    let all: Vec<usize> = (0..12).collect();
    check_kcdb(&text, &json, &all);
    assert!(text.contains("not in it (F)"), "the laboratory out named");
    assert!(!text.contains(" drawn: "), "every face drawn");
}

/// With more than 24 positions the KCDB graphs are those of the 24 positions where some
/// laboratory's |d_i|/U(d_i) is largest — found here from the JSON — and the figure says
/// so. A comparison of 30 faces, one laboratory far off on faces 7 and 23.
#[test]
fn kc_kcdb_graphs_of_many_positions_are_the_24_largest_and_say_so() {
    let dir = temp_dir("kcdb-many");
    let mut args = vec!["kc".to_string()];
    for (l, name) in ["P", "Q", "R", "S"].iter().enumerate() {
        let mut text = String::from("quantity,index,value,U,k\n");
        for face in 1..=30u32 {
            // small, different values; S off by 1.5″ on faces 7 and 23 (they close)
            let mut value = 0.013 * f64::from((face * (l as u32 + 3)) % 7) - 0.039;
            if *name == "S" && face == 7 {
                value += 1.5;
            }
            if *name == "S" && face == 23 {
                value -= 1.5;
            }
            text.push_str(&format!("pitch_deviation,{face},{value},0.2,2\n"));
        }
        let path = dir.join(format!("{name}.csv"));
        std::fs::write(&path, text).unwrap();
        args.push(format!("{name}={}", path.display()));
    }
    let plot = dir.join("plot");
    args.extend(["--format", "json", "--plot"].map(String::from));
    args.push(plot.display().to_string());
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let json = json_of(&polycal(&args));
    let labs = json["degrees_of_equivalence"].as_array().unwrap();
    let ratio = |k: usize| {
        labs.iter()
            .map(|l| (floats(&l["d"])[k] / floats(&l["U"])[k]).abs())
            .fold(0.0, f64::max)
    };
    let mut order: Vec<usize> = (0..30).collect();
    order.sort_by(|a, b| ratio(*b).total_cmp(&ratio(*a)));
    let mut drawn: Vec<usize> = order[..24].to_vec();
    drawn.sort_unstable();
    assert!(drawn.contains(&6) && drawn.contains(&22), "{drawn:?}");
    let text = svg_text(&plot.join("kc-kcdb.svg"));
    check_kcdb(&text, &json, &drawn);
    assert!(
        text.contains("24 of 30 faces drawn"),
        "the figure says what it draws"
    );
}
