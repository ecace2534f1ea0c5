//! `polycal diagnose` and `polycal report --diagnose` on self-calibration files, as a
//! user runs them: recognised by their columns, the effects named by head, cycle and step,
//! the base model what `selfcal` prints, the errors against a self-calibration truth,
//! the verdict in the exit status, and what does not apply refused with one line.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-diag-selfcal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn json(out: &Output) -> Value {
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().next().expect("a JSON line")).expect("JSON")
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .expect("an array")
        .iter()
        .map(|x| x.as_f64().expect("a number"))
        .collect()
}

/// A SelfA run on 84 positions, 3 cycles, 20 s per stop, with `edit` applied to every
/// data row's (cycle, step, head) and reading; returns the file and its truth.
fn selfa_run(name: &str, edit: impl Fn(u32, usize, u32, f64) -> f64) -> (String, String) {
    let file = scratch(&format!("{name}.csv"));
    let truth = scratch(&format!("{name}.truth.json"));
    let made = polycal(&[
        "simulate",
        "--selfcal",
        "--positions",
        "84",
        "--cycles",
        "3",
        "--step-seconds",
        "20",
        "--seed",
        "3",
        "--out",
        file.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    assert!(
        made.status.success(),
        "{}",
        String::from_utf8_lossy(&made.stderr)
    );
    let text = std::fs::read_to_string(&file).unwrap();
    let mut lines = text.lines();
    let mut out = String::new();
    for line in lines.by_ref() {
        out.push_str(line);
        out.push('\n');
        if line.starts_with("cycle,") {
            assert_eq!(line, "cycle,step,head,head_angle,reading,time");
            break;
        }
    }
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let (cycle, step, head) = (
            f[0].parse().unwrap(),
            f[1].parse().unwrap(),
            f[2].parse().unwrap(),
        );
        let reading = edit(cycle, step, head, f[4].parse().unwrap());
        out.push_str(&format!(
            "{},{},{},{},{reading},{}\n",
            f[0], f[1], f[2], f[3], f[5]
        ));
    }
    std::fs::write(&file, out).unwrap();
    (
        file.to_str().unwrap().to_string(),
        truth.to_str().unwrap().to_string(),
    )
}

/// Whether any object in `v` has the key `key`.
fn has_key(v: &Value, key: &str) -> bool {
    match v {
        Value::Object(map) => map.iter().any(|(k, x)| k == key || has_key(x, key)),
        Value::Array(items) => items.iter().any(|x| has_key(x, key)),
        _ => false,
    }
}

#[test]
fn a_jump_of_a_head_is_found_by_head_cycle_and_step_and_reported_in_heads_words() {
    // head 9's zero jumps by 0.15″ at cycle 2, step 40
    let (file, truth) = selfa_run("jump", |cycle, step, head, reading| {
        if head == 9 && (cycle, step) >= (2, 40) {
            reading + 0.15
        } else {
            reading
        }
    });
    let out = polycal(&["diagnose", &file, "--truth", &truth, "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let j = json(&out);
    assert_eq!(j["kind"], "self-calibration");
    assert_eq!(j["adequate"], true);
    let effects = j["effects"].as_array().unwrap();
    assert_eq!(effects.len(), 1, "{effects:?}");
    let jump = &effects[0];
    assert_eq!(jump["kind"], "offset-step");
    assert_eq!(
        (
            jump["head"].as_u64(),
            jump["cycle"].as_u64(),
            jump["step"].as_u64()
        ),
        (Some(9), Some(2), Some(40))
    );
    let (value, u) = (jump["value"].as_f64().unwrap(), jump["u"].as_f64().unwrap());
    assert!((value - 0.15).abs() < 4.0 * u, "{value} ± {u}");
    assert!(jump.get("encoder_change_max").is_some() && jump.get("head_change_max").is_some());
    // the polygon's names are not used anywhere in the object
    for key in ["ac", "setup", "pitch_change_max", "face_deviation"] {
        assert!(!has_key(&j, key), "{key} in {j}");
    }
    assert!(!j.to_string().contains("autocollimator"));
    // before and after are selfcal objects; the jump moved head 9's error
    let head_9 = |v: &Value| {
        v["head_error"]
            .as_array()
            .unwrap()
            .iter()
            .find(|h| h["head"] == 9)
            .unwrap()["value"]
            .as_f64()
            .unwrap()
    };
    let error = &j["error"];
    let (before, after) = (&error["before"], &error["after"]);
    assert!(after["head_max"].as_f64().unwrap() < 0.01, "{error}");
    assert!(before["head_max"].as_f64().unwrap() > 0.03, "{error}");
    assert!((head_9(&j["before"]) - head_9(&j["after"])).abs() > 0.03);
    // the table speaks of heads too
    let table = polycal(&["diagnose", &file]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("offset-step of head 9 from cycle 2, step 40"),
        "{text}"
    );
    assert!(
        !text.contains("autocollimator") && !text.contains(" ac "),
        "{text}"
    );
    assert!(text.contains("Self-calibration of the final model"));
}

#[test]
fn a_clean_run_before_the_diagnosis_is_what_selfcal_prints() {
    let (file, _) = selfa_run("clean", |_, _, _, reading| reading);
    let diagnosed = polycal(&["diagnose", &file, "--format", "json"]);
    assert_eq!(diagnosed.status.code(), Some(0));
    let d = json(&diagnosed);
    let solved = json(&polycal(&["selfcal", &file, "--format", "json"]));
    for side in ["before", "after"] {
        for key in ["encoder_error", "encoder_error_u", "encoder_error_U"] {
            let (a, b) = (numbers(&d[side][key]), numbers(&solved[key]));
            assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                assert!((x - y).abs() < 1e-9, "{side} {key}: {x} against {y}");
            }
        }
        assert_eq!(d[side]["dof"], solved["dof"]);
        assert_eq!(d[side]["lost_harmonics"], solved["lost_harmonics"]);
    }
    // the result file of the final model is selfcal's
    let csv = polycal(&["diagnose", &file, "--format", "csv"]);
    let reference = polycal(&["selfcal", &file, "--format", "csv"]);
    let rows = |o: &Output| -> Vec<Vec<String>> {
        String::from_utf8_lossy(&o.stdout)
            .lines()
            .map(|l| l.split(',').map(str::to_string).collect())
            .collect()
    };
    let (a, b) = (rows(&csv), rows(&reference));
    assert_eq!(a.len(), b.len());
    assert_eq!(a[0], b[0]);
    for (x, y) in a.iter().zip(&b).skip(1) {
        for (p, q) in x.iter().zip(y) {
            match (p.parse::<f64>(), q.parse::<f64>()) {
                (Ok(p), Ok(q)) => assert!((p - q).abs() < 1e-9, "{x:?} {y:?}"),
                _ => assert_eq!(p, q),
            }
        }
    }
}

#[test]
fn a_head_pattern_no_term_expresses_gives_status_1() {
    let (file, _) = selfa_run("pattern", |_, step, head, reading| {
        if head == 6 {
            reading + 0.05 * (std::f64::consts::TAU * 5.0 * step as f64 / 84.0).sin()
        } else {
            reading
        }
    });
    let out = polycal(&["diagnose", &file, "--format", "json"]);
    assert_eq!(out.status.code(), Some(1));
    let j = json(&out);
    assert_eq!(j["adequate"], false);
    assert_eq!(j["lack_of_fit"]["passed"], false);
    // the report says so, with the diagnosis of the self-calibration in it
    let html = scratch("pattern.html");
    let out = polycal(&[
        "report",
        &file,
        "--diagnose",
        "--out",
        html.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&html).unwrap();
    assert!(text.contains("id=\"diagnosis\""));
    assert!(text.contains("The final model is NOT adequate"));
    // no term found: the final model is the base model, said once, its tables not repeated
    // (issue 48)
    assert!(text.contains("id=\"final-model-same\""));
    assert!(!text.contains("id=\"final-encoder-error\""));
    assert!(!text.contains("id=\"final-head-error\""));
}

#[test]
fn the_report_carries_the_diagnosis_numbers_of_the_json() {
    let (file, truth) = selfa_run("report", |cycle, step, head, reading| {
        if head == 4 && (cycle, step) == (2, 17) {
            reading + 0.4
        } else {
            reading
        }
    });
    let j = json(&polycal(&[
        "diagnose",
        &file,
        "--budget",
        "examples/budgets/selfcal.toml",
        "--format",
        "json",
    ]));
    assert_eq!(j["effects"][0]["kind"], "outlier");
    assert_eq!(j["effects"][0]["head"], 4);
    let html = scratch("report.html");
    let out = polycal(&[
        "report",
        &file,
        "--diagnose",
        "--truth",
        &truth,
        "--budget",
        "examples/budgets/selfcal.toml",
        "--out",
        html.to_str().unwrap(),
    ]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&html).unwrap();
    // the final model's first U(e) in the HTML is the JSON's
    let table = &text[text.find("id=\"final-encoder-error\"").unwrap()..];
    let expanded = numbers(&j["after"]["encoder_error_U"])[0];
    assert!(
        table.contains(&format!("data-value=\"{expanded}\"")),
        "U(e) {expanded} not in the final model's table"
    );
    assert!(text.contains("Graduation error e error, RMS"));
}

#[test]
fn what_does_not_apply_is_refused_with_one_line() {
    let (file, _) = selfa_run("refuse", |_, _, _, reading| reading);
    // a polygon truth for a self-calibration file
    let out = polycal(&[
        "diagnose",
        &file,
        "--truth",
        "examples/data/polygon24-2ac-6cycles.truth.json",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("the truth is a polygon run's"), "{err}");
    // cross-talk
    let out = polycal(&["diagnose", &file, "--cross-talk", "1:0.01"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--cross-talk does not apply"));
}

/// Heads between the positions (SelfA on 360 positions: the group of 7 sits between
/// them) are diagnosed on the band-limited model, as `selfcal` solves them.
#[test]
fn heads_between_the_positions_are_diagnosed_on_the_band_limited_model() {
    let off = scratch("off-grid.csv");
    let made = polycal(&[
        "simulate",
        "--selfcal",
        "--positions",
        "360",
        "--seed",
        "2",
        "--out",
        off.to_str().unwrap(),
    ]);
    assert!(made.status.success());
    let out = polycal(&["diagnose", off.to_str().unwrap(), "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["before"]["head_grid"], "off-grid");
    assert_eq!(json["after"]["head_grid"], "off-grid");
    assert_eq!(json["effects"].as_array().map(Vec::len), Some(0));
    assert_eq!(json["adequate"], true, "{json:#}");
}
