//! `polycal plan` (docs/FORMAT.md §5.6) on one design, as a user runs it, end to end
//! through the binary: the uncertainties of the paper's design, those `polycal solve`
//! reports for a run of the design, the harmonics a design loses, the effects a diagnosis
//! can see, and designs with few residual degrees of freedom answered. Every expected
//! number comes from outside the command: the paper's closed form, a count of readings
//! and parameters by hand, the lost-harmonic rule of the README worked out with a gcd, or
//! `polycal solve` on a simulated run of the same design — never from the output of the
//! run under test recorded as "expected".

use std::process::{Command, Output};

use serde_json::Value;

use crate::plan_cli_support::{f64s, json_one, polycal, stderr, stdout, temp_dir};

const BUDGET: &str = "examples/budgets/instrument.toml";

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
