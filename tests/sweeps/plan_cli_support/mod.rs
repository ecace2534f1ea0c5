//! What the tests of `polycal plan` through the binary (`tests/sweeps/plan_cli_*.rs`)
//! share: the binary run from the repository root, a fresh temporary directory, its output
//! as text or as JSON, its one error line, and a JSON array of numbers.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

pub fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-plan-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

pub fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Runs `args`, checks the exit status and parses every line of standard output as one
/// JSON object (JSON Lines).
pub fn json_lines(args: &[&str], status: i32) -> Vec<Value> {
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
pub fn json_one(args: &[&str], status: i32) -> Value {
    let mut lines = json_lines(args, status);
    assert_eq!(lines.len(), 1, "one JSON line from polycal {args:?}");
    lines.remove(0)
}

/// Status 2 and exactly one line on standard error, which begins `error:`; returns it.
pub fn one_error_line(out: &Output) -> String {
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

pub fn f64s(value: &Value, what: &str) -> Vec<f64> {
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
