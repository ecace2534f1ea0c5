//! `polycal diagnose` and `polycal report --diagnose` on shifted mountings, as a user
//! runs them: accepted, the effects named by the file's mounting, cycle and step, the
//! sub-pitch encoder errors at every table angle as `solve` prints them, and `--budget`
//! refused with one line.

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
    let dir = std::env::temp_dir().join(format!("polycal-diag-shift-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn json(out: &Output) -> Value {
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().next().expect("a JSON line")).expect("JSON")
}

#[test]
fn a_sub_pitch_run_is_diagnosed_and_reported_at_every_table_angle() {
    let file = scratch("subpitch.csv");
    let file = file.to_str().unwrap();
    let made = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "4",
        "--closing",
        "--setups",
        "2",
        "--shift-deg",
        "0,7.5",
        "--offset-step",
        "2:2:2:9:0.4",
        "--seed",
        "5",
        "--out",
        file,
    ]);
    assert!(made.status.success());
    let out = polycal(&["diagnose", file, "--format", "json"]);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let d = json(&out);
    let effects = d["effects"].as_array().unwrap();
    assert_eq!(effects.len(), 1, "{effects:?}");
    let e = &effects[0];
    assert_eq!(
        (&e["kind"], &e["ac"], &e["setup"], &e["cycle"], &e["step"]),
        (
            &Value::from("offset-step"),
            &Value::from(2),
            &Value::from(2),
            &Value::from(2),
            &Value::from(9)
        )
    );
    assert!((e["value"].as_f64().unwrap() - 0.4).abs() < 0.05);
    // 2 cosets of 24 angles, as solve reports a sub-pitch run
    let angles = d["after"]["encoder_angle_deg"].as_array().unwrap();
    assert_eq!(angles.len(), 48);
    assert_eq!(angles[1], 7.5);
    assert_eq!(d["after"]["encoder_error"].as_array().unwrap().len(), 48);
    assert!(d["after"]["notes"][0].as_str().unwrap().contains("cosets"));

    // the table names the jump by the file's mounting, cycle and step
    let table = polycal(&["diagnose", file]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("offset-step of autocollimator 2 from setup 2, cycle 2, step 9"),
        "{text}"
    );
    assert!(
        text.contains("7.5000"),
        "α at the sub-pitch angles:\n{text}"
    );

    // --budget is refused for shifted mountings, as by solve
    let refused = polycal(&[
        "diagnose",
        file,
        "--budget",
        "examples/budgets/instrument.toml",
    ]);
    assert_eq!(refused.status.code(), Some(2));
    let err = String::from_utf8_lossy(&refused.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("error: ") && err.contains("--budget"),
        "{err}"
    );

    // and the calibration report carries the diagnosis
    let html = scratch("subpitch.html");
    let report = polycal(&[
        "report",
        file,
        "--diagnose",
        "--out",
        html.to_str().unwrap(),
    ]);
    assert_eq!(
        report.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&report.stderr)
    );
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(page.contains("offset-step"), "the report names the jump");
}
