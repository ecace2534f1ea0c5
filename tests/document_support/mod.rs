//! What the tests of the documents (`tests/report.rs`, `tests/certificate_dcc.rs`) share:
//! the binary run from the repository root, a fresh temporary directory, and a command's
//! JSON.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

/// `polycal ARGS`, run in the repository root.
pub fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

/// An empty directory of this test process, `polycal-<kind>-<pid>-<name>`.
pub fn temp_dir(kind: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-{kind}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The JSON a command prints (status 0 or 1).
pub fn json(args: &[&str]) -> Value {
    let out = polycal(args);
    assert!(
        out.status.code().is_some_and(|c| c <= 1),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}
