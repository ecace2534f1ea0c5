//! `polycal diagnose` as a user runs it on the situations of issue 21: a run simulated
//! with cross-talk on both autocollimators in two mountings (the elevation axis without
//! a mounting tilt), whose finding the data cannot place; the same run with a tilt that
//! lets the data decide; the same ambiguous run decided by a stated cross-talk
//! (`--cross-talk AC:C[:U]` on `diagnose`, `report` and `solve --budget`).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .output()
        .expect("the polycal binary runs")
}

/// `polycal diagnose FILE --format json`, its status checked.
fn diagnose_json(file: &str, status: i32) -> serde_json::Value {
    let o = polycal(&["diagnose", file, "--format", "json"]);
    assert_eq!(
        o.status.code(),
        Some(status),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-identify-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn simulate(dir: &Path, extra: &[&str]) -> String {
    let out = dir.join("run.csv");
    let out_text = out.to_str().unwrap().to_string();
    let mut args = vec![
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "4",
        "--closing",
        "--setups",
        "2",
        "--setup-shift",
        "5",
        "--seed",
        "7",
        "--out",
        &out_text,
    ];
    args.extend_from_slice(extra);
    let o = polycal(&args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out_text
}

/// Cross-talk on both autocollimators (+0.010, −0.006) and `reading_y = Y[face] +
/// W[step] + offsets`: status 1, the cross-talk found carries `alternatives` with
/// `ambiguous: true`, an `identifiability` check fails, and the table says CANNOT TELL.
#[test]
fn cross_talk_the_closure_cannot_place_gives_status_1_with_alternatives() {
    let dir = scratch("ambiguous");
    let file = simulate(
        &dir,
        &[
            "--elevation",
            "10:0:1:5:0.05",
            "--cross-talk",
            "1:0.01",
            "--cross-talk",
            "2:-0.006",
        ],
    );
    let json = diagnose_json(&file, 1);
    assert_eq!(json["adequate"], false);
    let effects = json["effects"].as_array().unwrap();
    let cross_talk = effects
        .iter()
        .find(|e| e["kind"] == "cross-talk")
        .expect("a cross-talk is found");
    assert_eq!(cross_talk["ambiguous"], true, "{cross_talk}");
    let alternative = &cross_talk["alternatives"][0];
    assert_eq!(alternative["kind"], "cross-talk");
    assert_ne!(alternative["ac"], cross_talk["ac"]);
    // the two differ by c·Y in φ: tenths of an arcsecond with Y of about 10″
    assert!(
        alternative["pitch_change_max"].as_f64().unwrap() > 0.03,
        "{alternative}"
    );
    assert!(alternative["change_over_expanded_u"].as_f64().unwrap() > 1.0);
    let checks = json["checks"].as_array().unwrap();
    assert!(
        checks.iter().any(
            |c| c["name"].as_str().unwrap().starts_with("identifiability") && c["passed"] == false
        ),
        "{checks:?}"
    );
    let notes = json["notes"].as_array().unwrap();
    assert!(
        notes.iter().any(|n| n
            .as_str()
            .unwrap()
            .contains("A cross-talk common to all autocollimators cannot be seen by closure")),
        "{notes:?}"
    );
    let table = polycal(&["diagnose", &file]);
    assert_eq!(table.status.code(), Some(1));
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(text.contains("CANNOT TELL"), "{text}");
    assert!(text.contains("cannot tell the cross-talk"), "{text}");
}

/// With a tilt of each mounting (the default elevation model) the common part of the
/// cross-talk shows in the residuals: the data decide, no alternative fits as well, and
/// the run is adequate.
#[test]
fn cross_talk_the_design_can_place_is_certified() {
    let dir = scratch("decided");
    let file = simulate(&dir, &["--elevation", "--cross-talk", "1:0.01"]);
    let json = diagnose_json(&file, 0);
    let cross_talk = json["effects"]
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["kind"] == "cross-talk")
        .expect("a cross-talk is found");
    assert_eq!(cross_talk["ac"], 1);
    assert!(cross_talk.get("alternatives").is_none(), "{cross_talk}");
}

/// On a run whose cross-talk the closure cannot place, `diagnose --cross-talk 2:0` and
/// `report --diagnose --cross-talk 2:0` decide it (status 0, the note says so); a bad
/// spec is one `error:` line, status 2; `solve --budget` lists the stated U as a
/// component.
#[test]
fn the_command_line_states_it() {
    let dir = scratch("stated");
    let file = simulate(
        &dir,
        &["--elevation", "10:0:1:5:0.05", "--cross-talk", "1:0.01"],
    );
    let file = file.as_str();
    assert_eq!(polycal(&["diagnose", file]).status.code(), Some(1));
    let o = polycal(&["diagnose", file, "--cross-talk", "2:0", "--format", "json"]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stdout)
    );
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(
        json["notes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("follows from the data")),
        "{}",
        json["notes"]
    );
    let o = polycal(&[
        "solve",
        file,
        "--cross-talk",
        "1:0.01:0.001",
        "--budget",
        "examples/budgets/instrument.toml",
        "--format",
        "json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let json: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let names: Vec<&str> = json["uncertainty"]["components"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["name"].as_str().unwrap())
        .collect();
    assert!(
        names.contains(&"cross-talk of autocollimator 1 (stated)"),
        "{names:?}"
    );
    // the report states it as diagnose does
    let html = dir.join("report.html");
    let html = html.to_str().unwrap();
    let o = polycal(&["report", file, "--diagnose", "--out", html]);
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let o = polycal(&[
        "report",
        file,
        "--diagnose",
        "--cross-talk",
        "2:0",
        "--out",
        html,
    ]);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(html).unwrap();
    assert!(text.contains("follows from the data"));
    for bad in ["1:x", "9:0.1"] {
        let o = polycal(&["solve", file, "--cross-talk", bad]);
        assert_eq!(o.status.code(), Some(2));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(
            stderr.lines().filter(|l| l.starts_with("error:")).count(),
            1,
            "{stderr}"
        );
    }
}
