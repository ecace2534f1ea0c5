//! `polycal simulate` end to end: reproducible (same seed, same bytes), and negative
//! effect values — `--direction -0.3`, negative amplitudes inside the other effect
//! specifications, `--harmonic 1:-0.5` — reaching the truth it writes.

use serde_json::Value;

use crate::cli_support::{numbers, polycal, temp_dir};

/// `simulate`: same seed, same bytes; another seed, other bytes.
#[test]
fn simulate_is_reproducible() {
    let run = |seed: &str| {
        polycal(&[
            "simulate",
            "--faces",
            "8",
            "--cycles",
            "2",
            "--closing",
            "--seed",
            seed,
        ])
        .stdout
    };
    let a = run("7");
    assert!(!a.is_empty());
    assert_eq!(a, run("7"));
    assert_ne!(a, run("8"));
}

/// The truth JSON `simulate` writes with these extra arguments (8 faces, 2 cycles,
/// bidirectional, so that every effect applies).
fn simulated_truth(name: &str, extra: &[&str]) -> Value {
    let dir = temp_dir(name);
    let truth = dir.join("truth.json");
    let mut args = vec![
        "simulate",
        "--faces",
        "8",
        "--cycles",
        "2",
        "--bidirectional",
        "--truth-out",
        truth.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let out = polycal(&args);
    assert!(
        out.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap()
}

/// The one effect of a simulated truth.
fn only_effect(truth: &Value) -> &Value {
    let effects = truth["effects"].as_array().expect("effects");
    assert_eq!(effects.len(), 1, "{effects:?}");
    &effects[0]
}

/// Negative numbers are values, not options: `--direction -0.3` alone, and the negative
/// value inside the other effect specifications, reach the truth the simulation writes.
#[test]
fn negative_effect_values_are_accepted() {
    let effect = only_effect(&simulated_truth("neg-direction", &["--direction", "-0.3"])).clone();
    assert_eq!(effect["kind"], "direction");
    assert_eq!(effect["value"], -0.3);

    let truth = simulated_truth("neg-offset", &["--offset-step", "1:2:-0.3"]);
    let effect = only_effect(&truth);
    assert_eq!(effect["kind"], "offset-step");
    assert_eq!((&effect["ac"], &effect["cycle"]), (&1.into(), &2.into()));
    assert_eq!(effect["value"], -0.3);

    let truth = simulated_truth("neg-drift", &["--drift", "2:-1.5"]);
    let effect = only_effect(&truth);
    assert_eq!(
        (&effect["kind"], &effect["ac"]),
        (&"drift".into(), &2.into())
    );
    assert_eq!(effect["value"], -1.5);

    let truth = simulated_truth("neg-outlier", &["--outlier", "1:3:1:-2"]);
    let effect = only_effect(&truth);
    assert_eq!(effect["kind"], "outlier");
    assert_eq!(effect["value"], -2.0);
}

/// `--harmonic 1:-0.5` gives the encoder errors of `--harmonic 1:0.5` with the sign
/// turned (same seed), so the negative amplitude reached the simulation.
#[test]
fn negative_harmonic_amplitude_is_accepted() {
    let minus = simulated_truth("neg-harmonic", &["--harmonic", "1:-0.5"]);
    let plus = simulated_truth("pos-harmonic", &["--harmonic", "1:0.5"]);
    let (minus, plus) = (
        numbers(&minus["encoder_error"]),
        numbers(&plus["encoder_error"]),
    );
    assert_eq!(minus.len(), 8);
    assert!(plus.iter().any(|e| e.abs() > 0.1), "{plus:?}");
    for (m, p) in minus.iter().zip(&plus) {
        assert!((m + p).abs() < 1e-12, "{m} vs {p}");
    }
}
