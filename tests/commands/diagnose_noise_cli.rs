//! `diagnose --budget` on a run whose noise differs between cycles (issue 53): the final
//! model is then weighted by each group's σ, which a budget cannot yet be propagated
//! through, so the file is refused with one `error:` line naming it and status 2 rather
//! than given the U of another fit; without `--budget` the weighted result is reported.

use std::fmt::Write as _;
use std::process::Command;

use crate::fault_runs::{Fault, Run, generate};

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

#[test]
fn a_budget_on_a_weighted_diagnosis_is_refused_with_one_error_line() {
    let pair = generate(
        &Run::typical(6, 0.035),
        &Fault::NoiseRise {
            ac: 2,
            from_cycle: 4,
            factor: 3.0,
        },
        4,
    );
    let mut csv = String::from("cycle,step,ac,face,reading,time\n");
    for r in &pair.faulty.readings {
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{}",
            r.cycle,
            r.step,
            r.ac,
            r.face,
            r.reading_arcsec,
            r.time_seconds.unwrap_or(0.0)
        );
    }
    let dir = std::env::temp_dir().join(format!("polycal-noise-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary folder");
    let file = dir.join("noisy.csv");
    std::fs::write(&file, csv).expect("written");

    let plain = Command::new(BIN)
        .args(["diagnose", "--format", "json"])
        .arg(&file)
        .output()
        .expect("runs");
    let json: serde_json::Value = serde_json::from_slice(&plain.stdout).expect("JSON");
    assert_eq!(json["noise"]["equal"], false, "{json}");
    assert_eq!(json["noise"]["weighted"], true, "{json}");

    let budgeted = Command::new(BIN)
        .args(["diagnose", "--budget", "examples/budgets/instrument.toml"])
        .arg(&file)
        .output()
        .expect("runs");
    assert_eq!(budgeted.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&budgeted.stderr);
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(
        errors[0].contains("noisy.csv: --budget: the noise differs"),
        "{stderr}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
