//! `polycal plan` (docs/FORMAT.md §5.6) as a user runs it, end to end through the binary.
//! Every expected number comes from outside the command: the paper's closed form, a
//! count of readings and parameters by hand, the lost-harmonic rule of the README worked
//! out with a gcd, `polycal solve` on a simulated run of the same design, or other runs
//! of `plan` itself with other cycles (for `--target-u`) — never from the output of the
//! run under test recorded as "expected".

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
const BUDGET: &str = "examples/budgets/instrument.toml";
const DESIGNS: &str = "examples/designs.toml";

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-plan-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `args`, checks the exit status and parses every line of standard output as one
/// JSON object (JSON Lines).
fn json_lines(args: &[&str], status: i32) -> Vec<Value> {
    let out = polycal(args);
    assert_eq!(
        out.status.code(),
        Some(status),
        "status of polycal {args:?}; stderr:\n{}",
        stderr(&out)
    );
    stdout(&out)
        .lines()
        .map(|line| {
            serde_json::from_str(line)
                .unwrap_or_else(|e| panic!("a JSON line from polycal {args:?}: {e}\n{line}"))
        })
        .collect()
}

/// The one JSON object of a single-design run.
fn json_one(args: &[&str], status: i32) -> Value {
    let mut lines = json_lines(args, status);
    assert_eq!(lines.len(), 1, "one JSON line from polycal {args:?}");
    lines.remove(0)
}

/// Status 2 and exactly one line on standard error, which begins `error:`; returns it.
fn one_error_line(out: &Output) -> String {
    let text = stderr(out);
    assert_eq!(out.status.code(), Some(2), "status; stderr:\n{text}");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "one line on standard error, got:\n{text}");
    assert!(
        lines[0].starts_with("error: "),
        "an error: line, got {:?}",
        lines[0]
    );
    lines[0].to_string()
}

fn f64s(value: &Value, what: &str) -> Vec<f64> {
    value
        .as_array()
        .unwrap_or_else(|| panic!("{what} is an array, got {value}"))
        .iter()
        .map(|v| {
            v.as_f64()
                .unwrap_or_else(|| panic!("{what}: a number, got {v}"))
        })
        .collect()
}

/// Two lists of numbers (or `null`s) agree element by element to `rel` relative.
fn assert_rel_eq(a: &Value, b: &Value, rel: f64, what: &str) {
    let a = a
        .as_array()
        .unwrap_or_else(|| panic!("{what}: an array, got {a}"));
    let b = b
        .as_array()
        .unwrap_or_else(|| panic!("{what}: an array, got {b}"));
    assert_eq!(a.len(), b.len(), "{what}: lengths");
    assert!(!a.is_empty(), "{what}: not empty");
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => {
                assert!(
                    x.is_finite() && y.is_finite(),
                    "{what}[{i}]: finite, got {x} and {y}"
                );
                assert!(
                    (x - y).abs() <= rel * x.abs().max(y.abs()),
                    "{what}[{i}]: {x} vs {y}"
                );
            }
            _ => assert!(x.is_null() && y.is_null(), "{what}[{i}]: {x} vs {y}"),
        }
    }
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// 1. The paper's design without closing readings (N = 24, autocollimators at faces 1
///    and 2, R = 6 cycles): u(α_p) = σ·√((N² − 1)/(6·N·R)) for every p (the closed-form
///    covariance of the README at j = 0), and the residual degrees of freedom by hand.
#[test]
fn the_paper_design_gives_the_closed_form_u_and_the_hand_counted_dof() {
    let out = polycal(&["plan", "--sigma", "0.05", "--format", "json"]);
    assert_eq!(out.status.code(), Some(0), "stderr:\n{}", stderr(&out));
    let text = stdout(&out);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "exactly one JSON line, got:\n{text}");
    let json: Value = serde_json::from_str(lines[0]).unwrap();
    assert!(
        json["version"].as_str().is_some_and(|v| !v.is_empty()),
        "a version: {}",
        json["version"]
    );

    let (sigma, n, r) = (0.05_f64, 24.0_f64, 6.0_f64);
    let closed_form = sigma * ((n * n - 1.0) / (6.0 * n * r)).sqrt();
    let u_alpha = f64s(&json["encoder_error_u"], "encoder_error_u");
    assert_eq!(u_alpha.len(), 24, "one u(α) per position");
    for (p, u) in u_alpha.iter().enumerate() {
        assert!(
            (u - closed_form).abs() <= 1e-12,
            "u(α_{p}) = {u}, the paper's closed form {closed_form}"
        );
    }
    assert_eq!(json["lost_harmonics"], serde_json::json!([]));
    // readings: 2 autocollimators × 24 stops × 6 cycles = 288 (no closing reading);
    // parameters: 24 β with Σβ = 0 → 23, 24 α with Σα = 0 → 23, 2 setup errors → 48;
    // dof = 288 − 48 = 240.
    assert_eq!(json["readings"], 2 * 24 * 6);
    assert_eq!(json["dof"], 2 * 24 * 6 - (23 + 23 + 2));
}

/// `polycal solve FILE --format json [extra]`: the object.
fn solve_json(file: &str, extra: &[&str]) -> Value {
    let mut args = vec!["solve", file, "--format", "json"];
    args.extend_from_slice(extra);
    json_one(&args, 0)
}

/// 2. A plan is what `solve` reports for a run of the design whose residuals give σ:
///    the same u of every β, φ, α and setup error (and U, k with the same budget), from
///    the run's file and from the design's options.
#[test]
fn plan_gives_the_uncertainties_solve_reports_for_a_run_of_the_design() {
    let dir = temp_dir("plan-equals-solve");
    let file = dir.join("run.csv").display().to_string();
    let out = polycal(&[
        "simulate",
        "--faces",
        "12",
        "--ac-faces",
        "1,2,5",
        "--cycles",
        "3",
        "--closing",
        "--seed",
        "4",
        "--out",
        &file,
    ]);
    assert_eq!(out.status.code(), Some(0), "simulate: {}", stderr(&out));

    let solved = solve_json(&file, &[]);
    let sigma_hat = solved["sigma"].as_f64().expect("solve estimates σ");
    assert_eq!(solved["sigma_source"], "residual", "σ̂ from the residuals");
    // the shortest text that reads back as the same f64, as serde_json prints it
    let sigma_text = format!("{sigma_hat}");
    assert_eq!(sigma_text.parse::<f64>().unwrap(), sigma_hat);

    let design = [
        "--faces",
        "12",
        "--ac-faces",
        "1,2,5",
        "--cycles",
        "3",
        "--closing",
    ];
    let from_file = json_one(
        &["plan", &file, "--sigma", &sigma_text, "--format", "json"],
        0,
    );
    let mut args = vec!["plan", "--sigma", &sigma_text, "--format", "json"];
    args.extend_from_slice(&design);
    let from_options = json_one(&args, 0);

    for (how, planned) in [("file", &from_file), ("options", &from_options)] {
        assert_eq!(planned["dof"], solved["dof"], "{how}: dof");
        assert_eq!(planned["readings"], solved["readings"], "{how}: readings");
        for key in ["pitch_deviation_u", "face_deviation_u", "encoder_error_u"] {
            assert_rel_eq(&planned[key], &solved[key], 1e-12, &format!("{how}: {key}"));
        }
        let setup_u = |v: &Value| -> Value {
            v["setup_error"]
                .as_array()
                .expect("setup_error")
                .iter()
                .map(|s| s["u"].clone())
                .collect()
        };
        assert_eq!(
            planned["setup_error"].as_array().unwrap().len(),
            3,
            "{how}: one setup error per autocollimator"
        );
        assert_rel_eq(
            &setup_u(planned),
            &setup_u(&solved),
            1e-12,
            &format!("{how}: setup_error[].u"),
        );
    }

    // with the same budget on both
    let solved = solve_json(&file, &["--budget", BUDGET]);
    let from_file = json_one(
        &[
            "plan",
            &file,
            "--sigma",
            &sigma_text,
            "--budget",
            BUDGET,
            "--format",
            "json",
        ],
        0,
    );
    let mut args = vec![
        "plan",
        "--sigma",
        &sigma_text,
        "--budget",
        BUDGET,
        "--format",
        "json",
    ];
    args.extend_from_slice(&design);
    let from_options = json_one(&args, 0);
    for (how, planned) in [("file", &from_file), ("options", &from_options)] {
        for key in ["pitch_deviation_U", "encoder_error_U", "encoder_error_k"] {
            assert_rel_eq(
                &planned[key],
                &solved[key],
                1e-12,
                &format!("{how} with --budget: {key}"),
            );
        }
    }
}

/// 3. Two autocollimators 3 faces apart on 24 faces: harmonic k is lost when 3k is a
///    multiple of 24, i.e. when 24/gcd(24, 3) = 8 divides k: harmonics 8 and 16. The
///    design is reported (status 1, one warning), not refused; its u are null.
#[test]
fn a_design_that_loses_harmonics_is_reported_with_them_and_status_1() {
    let args = [
        "plan",
        "--sigma",
        "0.05",
        "--ac-faces",
        "1,4",
        "--closing",
        "--format",
        "json",
    ];
    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(1), "stderr:\n{}", stderr(&out));
    let err = stderr(&out);
    let err_lines: Vec<&str> = err.lines().collect();
    assert_eq!(err_lines.len(), 1, "one line on standard error:\n{err}");
    assert!(err_lines[0].starts_with("warning:"), "{err}");
    let lines: Vec<&str> = std::str::from_utf8(&out.stdout).unwrap().lines().collect();
    assert_eq!(lines.len(), 1);
    let json: Value = serde_json::from_str(lines[0]).unwrap();

    let period = 24 / gcd(24, 4 - 1);
    let expected: Vec<usize> = (1..24).filter(|k| k % period == 0).collect();
    assert_eq!(expected, vec![8, 16]);
    assert_eq!(json["lost_harmonics"], serde_json::json!(expected));
    assert!(
        json["pitch_deviation_u"].is_null(),
        "{}",
        json["pitch_deviation_u"]
    );
    assert!(
        json["encoder_error_u"].is_null(),
        "{}",
        json["encoder_error_u"]
    );
    assert!(json["worst"].is_null());
    assert!(json["unobservable"].is_string());

    let out = polycal(&args[..args.len() - 2]);
    assert_eq!(out.status.code(), Some(1), "table: {}", stderr(&out));
    assert!(
        stdout(&out).contains("LOST harmonics 8, 16"),
        "the table names the lost harmonics:\n{}",
        stdout(&out)
    );

    // the same rule on other designs: k lost when k·d ≡ 0 (mod N) for every offset
    // difference d, i.e. N/gcd(N, d₁, d₂, …) divides k
    for (faces, ac_faces, differences) in [
        (12usize, "1,5", vec![4usize]),
        (24, "1,9,17", vec![8, 16]),
        (20, "3,8", vec![5]),
    ] {
        let g = differences.iter().fold(faces, |g, &d| gcd(g, d));
        let period = faces / g;
        let expected: Vec<usize> = (1..faces).filter(|k| k % period == 0).collect();
        let faces_text = faces.to_string();
        let json = json_one(
            &[
                "plan",
                "--sigma",
                "0.05",
                "--faces",
                &faces_text,
                "--ac-faces",
                ac_faces,
                "--closing",
                "--format",
                "json",
            ],
            1,
        );
        assert_eq!(
            json["lost_harmonics"],
            serde_json::json!(expected),
            "{faces} faces, autocollimators at {ac_faces}"
        );
    }
}

/// 4. Several designs: one JSON line each, in order, with the changes of each `--design`
///    applied; the table prints one line per design; a designs file gives its designs.
#[test]
fn several_designs_are_planned_in_order_and_compared() {
    let args = [
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "name=A",
        "--design",
        "name=B;ac-faces=1,2,5;cycles=3",
        "--closing",
        "--format",
        "json",
    ];
    let lines = json_lines(&args, 0);
    assert_eq!(lines.len(), 2, "two JSON lines");
    assert_eq!(lines[0]["name"], "A");
    assert_eq!(lines[1]["name"], "B");
    // A is the design of the options; B changes its autocollimators and cycles
    assert_eq!(lines[0]["design"]["ac_faces"], serde_json::json!([1, 2]));
    assert_eq!(lines[0]["design"]["cycles"], 6);
    assert_eq!(lines[1]["design"]["ac_faces"], serde_json::json!([1, 2, 5]));
    assert_eq!(lines[1]["design"]["cycles"], 3);
    for line in &lines {
        assert_eq!(line["design"]["closing"], true);
        assert!(line["version"].is_string());
    }
    // readings by hand: autocollimators × (24 stops + the closing one) × cycles
    assert_eq!(lines[0]["readings"], 2 * 25 * 6);
    assert_eq!(lines[1]["readings"], 3 * 25 * 3);

    let out = polycal(&args[..args.len() - 2]);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    for name in ["A", "B"] {
        let rows: Vec<&str> = table.lines().filter(|l| l.starts_with(name)).collect();
        assert_eq!(rows.len(), 1, "one line for design {name}:\n{table}");
    }

    // the designs file: its names, in its order
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(DESIGNS))
        .expect("the example designs file");
    let file: toml::Table = text.parse().expect("the example designs file is TOML");
    let tables = file["design"].as_array().expect("[[design]] tables");
    let names: Vec<&str> = tables
        .iter()
        .map(|d| d["name"].as_str().expect("a name"))
        .collect();
    assert_eq!(names.len(), 4);
    let lines = json_lines(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--designs",
            DESIGNS,
            "--format",
            "json",
        ],
        0,
    );
    assert_eq!(lines.len(), 4, "four JSON lines");
    for ((line, name), table) in lines.iter().zip(&names).zip(tables) {
        assert_eq!(line["name"], *name);
        let cycles = table
            .get("cycles")
            .and_then(toml::Value::as_integer)
            .unwrap_or(6);
        assert_eq!(line["design"]["cycles"], cycles, "{name}: cycles");
    }
    let out = polycal(&["plan", "--sigma", "0.05", "--designs", DESIGNS]);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    for name in &names {
        let rows = table.lines().filter(|l| l.starts_with(name)).count();
        assert_eq!(rows, 1, "one line for design {name:?}:\n{table}");
    }
}

/// The largest u(α) of the paper's design with closing readings and `cycles` cycles.
fn largest_u_alpha(cycles: u64) -> f64 {
    let cycles = cycles.to_string();
    let json = json_one(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--closing",
            "--cycles",
            &cycles,
            "--format",
            "json",
        ],
        0,
    );
    f64s(&json["encoder_error_u"], "encoder_error_u")
        .into_iter()
        .fold(f64::NEG_INFINITY, f64::max)
}

/// 5. `--target-u`: the cycles found are the fewest, checked by planning them and one
///    fewer.
#[test]
fn target_u_finds_the_fewest_cycles() {
    let json = json_one(
        &[
            "plan",
            "--sigma",
            "0.05",
            "--target-u",
            "0.02",
            "--closing",
            "--format",
            "json",
        ],
        0,
    );
    let target = &json["target"];
    assert_eq!(target["encoder_error_u"], 0.02);
    let c = target["cycles"].as_u64().expect("the target is reached");
    assert!(c >= 2, "more than one cycle is needed here: {c}");
    let with_c = largest_u_alpha(c);
    let with_fewer = largest_u_alpha(c - 1);
    assert!(with_c <= 0.02, "{c} cycles: largest u(α) {with_c}");
    assert!(
        with_fewer > 0.02,
        "{} cycles: largest u(α) {with_fewer}",
        c - 1
    );
    let reached = target["reached_u"].as_f64().expect("reached_u");
    assert!(
        (reached - with_c).abs() <= 1e-12 * with_c,
        "reached_u {reached}, the largest u(α) with {c} cycles {with_c}"
    );
}

/// 6. Refusals: status 2, one `error:` line naming what is wrong.
#[test]
fn invalid_designs_and_options_are_refused_with_one_error_line() {
    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "cycles=abc",
    ]));
    assert!(err.contains("cycles") && err.contains("abc"), "{err}");

    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "colour=red",
    ]));
    assert!(err.contains("colour"), "{err}");
    assert!(err.contains("unknown"), "{err}");

    let dir = temp_dir("refusals");
    let designs = dir.join("designs.toml");
    // line 5 holds the bad value, in the second table
    std::fs::write(
        &designs,
        "[[design]]\nname = \"first\"\n\n[[design]]\ncycles = \"x\"\n",
    )
    .unwrap();
    let designs_text = designs.display().to_string();
    let err = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--designs",
        &designs_text,
    ]));
    assert!(
        err.contains(&format!("{designs_text}:5:")),
        "the file and line 5: {err}"
    );

    let err = one_error_line(&polycal(&[
        "plan", EXAMPLE, "--sigma", "0.05", "--faces", "12",
    ]));
    assert!(err.contains("--faces"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--sigma", "0.05", "--target-u", "-1"]));
    assert!(err.contains("--target-u"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--closing"]));
    assert!(err.contains("--sigma"), "{err}");

    let err = one_error_line(&polycal(&["plan", "--sigma", "-0.1"]));
    assert!(err.contains("--sigma") && err.contains("-0.1"), "{err}");
}

/// The points (`g` of class `point`) of an SVG figure: (series, index, y).
fn points(path: &Path) -> Vec<(String, usize, f64)> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let doc =
        roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    doc.descendants()
        .filter(|n| n.has_tag_name("g") && n.attribute("class") == Some("point"))
        .map(|n| {
            let series = n.attribute("data-series").expect("data-series").to_string();
            let index = n
                .attribute("data-index")
                .expect("data-index")
                .parse()
                .unwrap();
            let transform = n.attribute("transform").expect("transform");
            let inner = transform
                .strip_prefix("translate(")
                .and_then(|t| t.strip_suffix(')'))
                .unwrap_or_else(|| panic!("a translate: {transform}"));
            let y: f64 = inner.split(',').nth(1).unwrap().trim().parse().unwrap();
            (series, index, y)
        })
        .collect()
}

/// 7. `--plot DIR`: the two figures, one series per design; a regular file is refused.
#[test]
fn plot_writes_one_series_per_design_and_refuses_a_file() {
    let dir = temp_dir("plot");
    let plots = dir.join("figures");
    let plots_text = plots.display().to_string();
    let designs = [
        "--design",
        "name=A",
        "--design",
        "name=B;ac-faces=1,2,5;cycles=3",
        "--closing",
    ];
    let mut args = vec!["plan", "--sigma", "0.05", "--plot", &plots_text];
    args.extend_from_slice(&designs);
    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0), "stderr:\n{}", stderr(&out));
    for name in ["plan-encoder-error-u.svg", "plan-pitch-deviation-u.svg"] {
        assert!(plots.join(name).is_file(), "{name} written");
    }

    let alpha = points(&plots.join("plan-encoder-error-u.svg"));
    let series0: Vec<&(String, usize, f64)> = alpha.iter().filter(|p| p.0 == "0").collect();
    let series1: Vec<&(String, usize, f64)> = alpha.iter().filter(|p| p.0 == "1").collect();
    assert_eq!(series0.len(), 24, "one point per position of design A");
    assert!(!series1.is_empty(), "design B drawn");
    let mut indices: Vec<usize> = series0.iter().map(|p| p.1).collect();
    indices.sort_unstable();
    assert_eq!(indices, (0..24).collect::<Vec<_>>());
    let beta = points(&plots.join("plan-pitch-deviation-u.svg"));
    assert!(beta.iter().any(|p| p.0 == "0") && beta.iter().any(|p| p.0 == "1"));

    // every u(α) of B below every u(α) of A (from the JSON of the same designs) puts
    // every point of B lower on the chart (a larger y in SVG coordinates)
    let mut args = vec!["plan", "--sigma", "0.05", "--format", "json"];
    args.extend_from_slice(&designs);
    let lines = json_lines(&args, 0);
    let u_a = f64s(&lines[0]["encoder_error_u"], "A");
    let u_b = f64s(&lines[1]["encoder_error_u"], "B");
    let min_a = u_a.iter().copied().fold(f64::INFINITY, f64::min);
    let max_b = u_b.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(max_b < min_a, "B's u(α) {max_b} below A's {min_a}");
    let lowest_a = series0
        .iter()
        .map(|p| p.2)
        .fold(f64::NEG_INFINITY, f64::max);
    let highest_b = series1.iter().map(|p| p.2).fold(f64::INFINITY, f64::min);
    assert!(
        highest_b > lowest_a,
        "B's points (y ≥ {highest_b}) lie below A's (y ≤ {lowest_a})"
    );

    let file = dir.join("a-file");
    std::fs::write(&file, "").unwrap();
    let file_text = file.display().to_string();
    let err = one_error_line(&polycal(&["plan", "--sigma", "0.05", "--plot", &file_text]));
    assert!(err.contains("is a file, not a directory"), "{err}");
    assert!(file.is_file(), "the file is left as it was");
}

/// 8. What a diagnosis can see: the paper's design with closing readings has a drift
///    and a jump term per autocollimator; one cycle without closing readings has no
///    residual degrees of freedom (48 readings, 23 + 23 + 2 parameters), so nothing.
#[test]
fn detectable_lists_the_effects_a_diagnosis_can_see() {
    let json = json_one(
        &["plan", "--sigma", "0.05", "--closing", "--format", "json"],
        0,
    );
    let detectable = json["detectable"].as_array().expect("detectable");
    for ac in [1, 2] {
        let drifts: Vec<&Value> = detectable
            .iter()
            .filter(|d| d["kind"] == "drift" && d["ac"] == ac && d["order"] == 1)
            .collect();
        assert_eq!(drifts.len(), 1, "one drift of autocollimator {ac}");
        // and its curvature, the drift of order 2, in arcsec/h²
        let curvature: Vec<&Value> = detectable
            .iter()
            .filter(|d| d["kind"] == "drift" && d["ac"] == ac && d["order"] == 2)
            .collect();
        assert_eq!(
            curvature.len(),
            1,
            "one drift curvature of autocollimator {ac}"
        );
        assert_eq!(curvature[0]["unit"], "arcsec/h^2");
        let drift = drifts[0];
        assert_eq!(drift["identifiable"], true, "{drift}");
        assert_eq!(drift["unit"], "arcsec/h", "{drift}");
        let size = drift["size"].as_f64().expect("a drift size");
        assert!(size.is_finite() && size > 0.0, "{drift}");

        let steps: Vec<&Value> = detectable
            .iter()
            .filter(|d| d["kind"] == "offset-step" && d["ac"] == ac)
            .collect();
        assert_eq!(steps.len(), 1, "one offset-step of autocollimator {ac}");
        let cycle = steps[0]["cycle"].as_u64().expect("a cycle");
        assert!((1..=6).contains(&cycle), "{}", steps[0]);
        assert_eq!(steps[0]["unit"], "arcsec");
    }
    assert_eq!(
        detectable.iter().filter(|d| d["kind"] == "drift").count(),
        4,
        "no drift of another autocollimator: a drift and its curvature for each of two"
    );

    let json = json_one(
        &[
            "plan", "--sigma", "0.05", "--cycles", "1", "--format", "json",
        ],
        0,
    );
    assert_eq!(json["readings"], 2 * 24);
    assert_eq!(json["dof"], 2 * 24 - (23 + 23 + 2));
    assert_eq!(json["detectable"], serde_json::json!([]));
    let notes = json["notes"].as_array().expect("notes");
    assert!(
        notes
            .iter()
            .any(|n| n.as_str().is_some_and(|n| n.contains("residual degree"))),
        "a note on the residual degrees of freedom: {notes:?}"
    );
}

/// Runs `args` to its end or kills it after `limit`: a hang guard, not a timing.
fn polycal_guarded(args: &[&str], limit: std::time::Duration) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > limit {
            let _ = child.kill();
            panic!("{args:?} did not end within {limit:?}");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// Designs with 0 … 3 residual degrees of freedom get their answer (issue 34): the
/// paper's single cycle with its closing reading (2 degrees of freedom: 50 readings, 48
/// parameters) searched the power's noncentrality up to 10¹², summing λ/2 Poisson terms
/// at each step, and printed nothing for minutes. Each design ends with status 0 and its
/// uncertainties; the killing watchdog is only there to turn a hang into a failure.
#[test]
fn designs_with_few_residual_degrees_of_freedom_are_answered() {
    let limit = std::time::Duration::from_secs(600);
    for design in [
        &["--cycles", "1"][..],
        &["--closing", "--cycles", "1"],
        &["--bidirectional", "--cycles", "1"],
        &["--faces", "12", "--closing", "--cycles", "1"],
    ] {
        let mut args = vec!["plan", "--sigma", "0.05", "--format", "json"];
        args.extend_from_slice(design);
        let out = polycal_guarded(&args, limit);
        assert_eq!(out.status.code(), Some(0), "{design:?}: {}", stderr(&out));
        let json: Value = serde_json::from_str(stdout(&out).trim()).unwrap();
        let readings = json["readings"].as_u64().unwrap();
        let dof = json["dof"].as_u64().unwrap_or(0);
        assert!(dof <= 3, "{design:?}: dof {dof} of {readings} readings");
    }
}

/// `polycal ARGS` on a pseudo-terminal (util-linux `script`, which Debian always has):
/// what the terminal showed, standard output and error together.
fn on_a_terminal(args: &str) -> String {
    let out = Command::new("script")
        .args([
            "-qec",
            &format!("{} {args}", env!("CARGO_BIN_EXE_polycal")),
            "/dev/null",
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(std::process::Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn a_long_plan_shows_its_progress_on_a_terminal_only() {
    // four autocollimators on 24 faces: seconds of predicting what a diagnosis finds
    let args = "plan --sigma 0.05 --faces 24 --ac-faces 1,2,3,4 --cycles 6";
    let shown = on_a_terminal(args);
    let bar = "Planning 24 faces, autocollimators at 1,2,3,4, 6 cycles [";
    assert!(shown.contains(bar), "no progress bar:\n{shown}");
    assert!(
        shown.contains(" sizes · ") && shown.contains(" left"),
        "{shown}"
    );
    // the bar is cleared (erased, line by line) before the table is printed
    let table = shown
        .find("polycal plan: 24 faces")
        .expect("the table follows");
    assert!(shown[..table].ends_with("\u{1b}[1A"), "{shown}");
    // -q, and standard error not a terminal: no bar
    assert!(!on_a_terminal(&format!("-q {args}")).contains("Planning"));
    let out = polycal(&args.split(' ').collect::<Vec<_>>());
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    assert!(out.stderr.is_empty(), "{}", stderr(&out));
}

/// The stops of a run of the paper's design without closing readings, by hand: every
/// cycle stops at the N steps, one stop every `step_seconds` (20 s by default), the
/// first at time 0; so a run of R cycles lasts (R·N − 1)·20 s from the first stop to the
/// last.
fn hand_duration_seconds(faces: u64, cycles: u64) -> f64 {
    (cycles * faces - 1) as f64 * 20.0
}

/// The fewest cycles of the paper's design (two adjacent autocollimators, no closing
/// readings) with u(α) ≤ u: u(α) = σ·√((N² − 1)/(6·N·R)) for every position, so
/// R = ⌈(N² − 1)/(6·N)·(σ/u)²⌉.
fn hand_cycles(faces: u64, sigma: f64, u: f64) -> u64 {
    let n = faces as f64;
    ((n * n - 1.0) / (6.0 * n) * (sigma / u).powi(2)).ceil() as u64
}

/// 9. The comparison names the cycles planned and the cycles the target needs, with the
///    time each takes, all by hand: 72 faces need 75 cycles for u(α) ≤ 0.02″ at
///    σ = 0.05″ ((72² − 1)/(6·72)·2.5² = 74.99), a run of (75·72 − 1)·20 s = 29.99 h;
///    24 faces need 25 cycles (24.96), 3.33 h. Every column has its legend line.
#[test]
fn the_comparison_shows_the_cycles_the_target_needs_and_their_time() {
    assert_eq!(hand_cycles(72, 0.05, 0.02), 75);
    assert_eq!(hand_cycles(24, 0.05, 0.02), 25);
    let args = [
        "plan",
        "--sigma",
        "0.05",
        "--faces",
        "72",
        "--design",
        "name=N72",
        "--design",
        "name=N24;faces=24",
        "--target-u",
        "0.02",
    ];
    let mut json_args = args.to_vec();
    json_args.extend(["--format", "json"]);
    let lines = json_lines(&json_args, 0);
    for (line, faces) in lines.iter().zip([72u64, 24]) {
        let cycles = hand_cycles(faces, 0.05, 0.02);
        let target = &line["target"];
        assert_eq!(target["cycles"], cycles, "{faces} faces");
        assert_eq!(target["readings"], 2 * faces * cycles, "{faces} faces");
        let seconds = target["duration_seconds"].as_f64().expect("a duration");
        assert!(
            (seconds - hand_duration_seconds(faces, cycles)).abs() < 1e-6,
            "{faces} faces: {seconds} s"
        );
        // the planned run is the 6 cycles of the options
        assert_eq!(line["design"]["cycles"], 6);
        let planned = line["duration_seconds"].as_f64().expect("a duration");
        assert!((planned - hand_duration_seconds(faces, 6)).abs() < 1e-6);
    }
    assert!((hand_duration_seconds(72, 75) / 3600.0 - 29.994).abs() < 1e-3);

    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0), "table: {}", stderr(&out));
    let table = stdout(&out);
    let header: Vec<&str> = table
        .lines()
        .find(|l| l.starts_with("design"))
        .unwrap_or_else(|| panic!("a header line:\n{table}"))
        .split_whitespace()
        .collect();
    assert_eq!(
        header,
        [
            "design",
            "cycles",
            "readings",
            "time",
            "u(β)max",
            "u(α)max",
            "drift″/h",
            "step″",
            "target",
            "cycles",
            "target",
            "time"
        ],
        "{table}"
    );
    for (name, faces) in [("N72", 72u64), ("N24", 24)] {
        let row: Vec<&str> = table
            .lines()
            .find(|l| l.starts_with(name))
            .unwrap_or_else(|| panic!("a row for {name}:\n{table}"))
            .split_whitespace()
            .collect();
        let cycles = hand_cycles(faces, 0.05, 0.02);
        let hours = |s: f64| format!("{:.2}", s / 3600.0);
        assert_eq!(
            (row[1], row[2], row[3], row[4]),
            (
                "6",
                (2 * faces * 6).to_string().as_str(),
                hours(hand_duration_seconds(faces, 6)).as_str(),
                "h"
            ),
            "{name}: {row:?}"
        );
        assert_eq!(
            (row[9], row[10], row[11]),
            (
                cycles.to_string().as_str(),
                hours(hand_duration_seconds(faces, cycles)).as_str(),
                "h"
            ),
            "{name}: {row:?}"
        );
    }
    // a legend line for every column
    for (column, words) in [
        ("cycles:", "planned per mounting"),
        ("u(β)max, u(α)max:", "k = 1"),
        ("drift″/h:", "90 % of runs"),
        ("step″:", "offset step"),
        ("target cycles:", "0.02″"),
        ("target time:", "how long"),
    ] {
        assert!(
            table
                .lines()
                .any(|l| l.contains(column) && l.contains(words)),
            "a legend line with {column:?} and {words:?}:\n{table}"
        );
    }
    assert!(table.contains("0.5 % false alarms per family"), "{table}");
}

/// 10. `--design`'s help lists exactly the keys the parser accepts: the keys of the
///     parser's own refusal of an unknown key, each of which a design takes.
#[test]
fn the_design_help_lists_every_key_the_parser_accepts() {
    let out = polycal(&["plan", "--help"]);
    assert_eq!(out.status.code(), Some(0));
    let help = stdout(&out).replace('\n', " ");
    let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
    let keys_of = |text: &str, after: &str| -> Vec<String> {
        let start = text
            .find(after)
            .unwrap_or_else(|| panic!("{after:?} in {text}"))
            + after.len();
        let rest = &text[start..];
        let end = rest.find([';', ')']).expect("the end of the list");
        rest[..end]
            .split(',')
            .map(|k| k.trim().to_string())
            .collect()
    };
    let in_help = keys_of(&help, "joined by `;` (keys ");
    let refusal = one_error_line(&polycal(&[
        "plan",
        "--sigma",
        "0.05",
        "--design",
        "colour=red",
    ]));
    let in_parser = keys_of(&refusal, "(keys: ");
    assert_eq!(in_help, in_parser, "help:\n{help}\nrefusal: {refusal}");
    assert!(in_help.iter().any(|k| k == "temperature"), "{in_help:?}");
    // each key listed is one a design takes
    let value = |key: &str| match key {
        "name" => "x",
        "faces" => "24",
        "ac-faces" => "1,2",
        "cycles" | "setups" => "2",
        "closing" | "bidirectional" => "true",
        "setup-shift" => "5",
        "shift-deg" => "0,15",
        "step-seconds" => "10",
        "temperature" => "default",
        other => panic!("a key the test does not know: {other}"),
    };
    for key in &in_help {
        let spec = format!("{key}={}", value(key));
        polycal::plan::Design::default()
            .with_spec(&spec)
            .unwrap_or_else(|e| panic!("{spec}: {e}"));
    }
}
