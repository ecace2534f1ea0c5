//! What the hardening tests (issue 13, `tests/commands/hardening_*.rs`) share: the bundled
//! files they start from, the binary run from the repository root, a temporary directory
//! and a file written in it, and the one `error:` line every refusal gives.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";

pub const EXAMPLE_TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";

pub const SELFCAL: &str = "examples/data/selfa-168.csv";

pub const BUDGET: &str = "examples/budgets/instrument.toml";

pub fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-hard-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

pub fn write(dir: &Path, name: &str, text: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.display().to_string()
}

/// Status 2 and exactly one line on standard error, which begins `error:`; returns it
/// without the prefix.
pub fn one_error_line(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "status; stderr:\n{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line on standard error, got:\n{stderr}");
    lines[0]
        .strip_prefix("error: ")
        .unwrap_or_else(|| panic!("an error: line, got {:?}", lines[0]))
        .to_string()
}
