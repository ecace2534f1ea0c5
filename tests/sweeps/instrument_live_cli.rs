//! Checked while it runs (docs/FORMAT.md §7.3): `polycal run` against `polycal sim-lab`
//! on pseudo-terminals, with a reading made 2″ off mid-run (the lab's `--outlier`) or a
//! jump of an autocollimator's zero. The reading is measured again in the same run, its
//! first value kept in `remeasured.csv` and the manifest and left out of the measurement
//! file, whose evaluation equals that of the same run without the fault within noise;
//! the jump is a `warning:` line when its cycle ends.

#![cfg(unix)]

use std::path::{Path, PathBuf};

use crate::instrument_support::*;
use crate::lab_support::expected_at;
use polycal::measurement::MeasurementSet;
use polycal::simulate::Truth;
use serde_json::Value;

const SIGMA: f64 = 0.05;

/// A run of 8 faces, `cycles` cycles with the closing step, against a lab of seed 7
/// with `effects` (sim-lab options); the run directory, the truth and the output.
fn run(name: &str, cycles: &str, effects: &[&str]) -> (PathBuf, Truth, std::process::Output) {
    let dir = scratch(name);
    let mut lab_args = vec![
        "--noise",
        "0.05",
        "--seed",
        "7",
        "--cycles",
        cycles,
        "--closing",
    ];
    lab_args.extend_from_slice(effects);
    let lab = SimLab::start(&dir, &lab_args);
    let out = dir.join("run");
    let args = lab.run_args(
        &out,
        &[
            "--faces",
            "8",
            "--cycles",
            cycles,
            "--closing",
            "--settle",
            "0",
            "--timeout",
            "0.3",
            "--reading-noise",
            "0.05",
        ],
    );
    let result = polycal(&args);
    let truth = Truth::read_path(&lab.truth).unwrap();
    (out, truth, result)
}

/// `solve --format json` of the run's measurement file.
fn solve(out: &Path) -> Value {
    let result = polycal(&[
        "solve".to_string(),
        out.join("measurements.csv").display().to_string(),
        "--format".into(),
        "json".into(),
    ]);
    assert!(result.status.success(), "{}", stderr(&result));
    serde_json::from_slice(&result.stdout).unwrap()
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// β and α of two runs agree within four standard uncertainties of their difference.
fn assert_same_within_noise(a: &Value, b: &Value) {
    for key in ["pitch_deviation", "encoder_error"] {
        let (x, y) = (numbers(&a[key]), numbers(&b[key]));
        let (ux, uy) = (
            numbers(&a[format!("{key}_u")]),
            numbers(&b[format!("{key}_u")]),
        );
        for k in 0..x.len() {
            let limit = 4.0 * (ux[k] * ux[k] + uy[k] * uy[k]).sqrt();
            assert!(
                (x[k] - y[k]).abs() <= limit,
                "{key}[{k}]: {} vs {} (limit {limit})",
                x[k],
                y[k]
            );
        }
    }
}

/// The reading of (cycle, step, ac) in the run's measurement file is within 6σ of the
/// truth at its stop.
fn assert_at_truth(out: &Path, truth: &Truth, key: (u32, usize, u32)) {
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    let r = set
        .readings
        .iter()
        .find(|r| (r.cycle, r.step, r.ac) == key)
        .unwrap();
    let want = expected_at(truth, r.step, r.ac, r.encoder_degrees.unwrap());
    assert!(
        (r.reading_arcsec - want).abs() <= 6.0 * SIGMA,
        "{key:?}: {} but {want}",
        r.reading_arcsec
    );
}

/// The first value's row in `remeasured.csv`: (cycle, step, ac, reading).
fn kept_first(out: &Path) -> Vec<(u32, usize, u32, f64)> {
    let text = std::fs::read_to_string(out.join("remeasured.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some(RUN_HEADER));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
                f[4].parse().unwrap(),
            )
        })
        .collect()
}

#[test]
fn a_reading_two_arcseconds_off_is_measured_again_in_the_same_run() {
    let (clean, _, clean_run) = run("live-clean", "3", &[]);
    assert_eq!(clean_run.status.code(), Some(0), "{}", stderr(&clean_run));
    assert!(!clean.join("remeasured.csv").exists());

    let (out, truth, result) = run("live-outlier", "3", &["--outlier", "2:3:1:2"]);
    let text = stderr(&result);
    // Completed, with a reading measured again: status 1.
    assert_eq!(result.status.code(), Some(1), "{text}");
    assert!(
        text.contains("measured again: cycle 2, step 3, autocollimator 1:"),
        "{text}"
    );
    // Found when cycle 2 ended, before cycle 3 began.
    let at_cycle_2 = text.find("cycle 2: closure").unwrap();
    let again = text.find("measured again").unwrap();
    let at_cycle_3 = text.find("cycle 3: closure").unwrap();
    assert!(at_cycle_2 < again && again < at_cycle_3, "{text}");

    let m = manifest(&out);
    let remeasured = m["remeasured"].as_array().unwrap();
    assert_eq!(remeasured.len(), 1, "{m:#}");
    assert_eq!(
        (
            &remeasured[0]["cycle"],
            &remeasured[0]["step"],
            &remeasured[0]["ac"]
        ),
        (&Value::from(2), &Value::from(3), &Value::from(1))
    );
    assert_eq!(remeasured[0]["found_after_cycle"], 2);
    assert_eq!(m["suspect"].as_array().unwrap().len(), 0);
    // The first value is kept, 2″ off the truth; the file holds the new one.
    let kept = kept_first(&out);
    assert_eq!(kept.len(), 1);
    let (c, s, a, first) = kept[0];
    assert_eq!((c, s, a), (2, 3, 1));
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    let encoder = set
        .readings
        .iter()
        .find(|r| (r.cycle, r.step, r.ac) == (2, 3, 1))
        .unwrap()
        .encoder_degrees
        .unwrap();
    let off = first - expected_at(&truth, 3, 1, encoder);
    assert!((off - 2.0).abs() < 6.0 * SIGMA, "{off}");
    assert_at_truth(&out, &truth, (2, 3, 1));
    assert_eq!(set.readings.len(), 54);
    assert_eq!(
        rows(&out),
        plan_readings(&polycal::lab::run::RunSettings::new(8, 3).with_closing(true))
    );

    // The evaluation equals that of the run without the fault, within noise.
    assert_same_within_noise(&solve(&out), &solve(&clean));
    let events = sessions(&out).concat();
    assert_eq!(
        events.iter().filter(|r| r["event"] == "remeasured").count(),
        1
    );
}

#[test]
fn with_two_cycles_the_reading_that_is_off_is_told_from_its_twin() {
    // Cycle 1's reading is off; the check after cycle 2 sees it and its twin of cycle 2
    // with residuals of the same size, and the stop measured again tells them apart.
    let (out, truth, result) = run("live-twin", "2", &["--outlier", "1:5:2:2"]);
    assert_eq!(result.status.code(), Some(1), "{}", stderr(&result));
    let kept = kept_first(&out);
    assert_eq!(kept.len(), 1, "{kept:?}");
    assert_eq!((kept[0].0, kept[0].1, kept[0].2), (1, 5, 2));
    assert_at_truth(&out, &truth, (1, 5, 2));
    assert_at_truth(&out, &truth, (2, 5, 2));
}

#[test]
fn a_jump_of_a_zero_is_a_warning_when_its_cycle_ends() {
    let (out, _, result) = run("live-jump", "3", &["--offset-step", "2:3:0.5"]);
    let text = stderr(&result);
    assert_eq!(result.status.code(), Some(0), "{text}");
    let warning = text
        .lines()
        .position(|l| l.starts_with("warning: autocollimator 2: its readings of cycle 3 sit +"))
        .unwrap_or_else(|| panic!("{text}"));
    let cycle_3 = text
        .lines()
        .position(|l| l.starts_with("cycle 3:"))
        .unwrap();
    assert_eq!(warning, cycle_3 + 1, "{text}");
    // Explained as a whole, its readings are not measured again one by one.
    assert!(!out.join("remeasured.csv").exists(), "{text}");
}
