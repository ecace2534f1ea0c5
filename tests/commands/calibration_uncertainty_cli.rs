//! The uncertainty of the calibration results through the binary, end to end:
//! `solve --budget --format csv` fills `U` and `k`, and the file goes straight into
//! `polycal compare` against the simulation's truth; `--monte-carlo` on `solve`,
//! `diagnose` (the final model) and `selfcal`, its statuses, and the refusals.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

use crate::calibration_uncertainty_support::close;

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

/// `polycal args` is refused: status 2 and one `error:` line that contains `wanted`.
fn refused(args: &[&str], wanted: &str) {
    let out = polycal(args);
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: ") && stderr.contains(wanted),
        "{stderr:?} lacks {wanted:?}"
    );
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-unc-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const INSTRUMENT: &str = "examples/budgets/instrument.toml";

/// `solve --budget --format csv` fills U and k on every row (U = k·u), leaves out the
/// reference face φ[N], carries the JSON's numbers, and goes straight into `compare`
/// against the simulation's truth (which it covers: |En| ≤ 1 throughout).
#[test]
fn cli_budget_csv_goes_into_compare() {
    let dir = temp_dir("compare");
    let data = dir.join("run.csv");
    let truth = dir.join("truth.json");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "3",
        "--closing",
        "--seed",
        "5",
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let out = polycal(&[
        "solve",
        data.to_str().unwrap(),
        "--budget",
        INSTRUMENT,
        "--format",
        "csv",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv_text = String::from_utf8(out.stdout).unwrap();
    let result = dir.join("result.csv");
    std::fs::write(&result, &csv_text).unwrap();
    let rows = polycal::results::read_results_path(&result).unwrap();
    assert_eq!(rows.len(), 24 * 3 - 1 + 2);
    assert!(
        !rows
            .iter()
            .any(|r| r.quantity == "face_deviation" && r.index == 24)
    );
    for r in &rows {
        let (u, big_u, k) = (r.u.unwrap(), r.expanded_u.unwrap(), r.k.unwrap());
        assert!(close(big_u, k * u, 1e-12), "{} {}", r.quantity, r.index);
        assert!(k > 1.9 && k < 2.1);
    }
    let json: Value = serde_json::from_slice(
        &polycal(&[
            "solve",
            data.to_str().unwrap(),
            "--budget",
            INSTRUMENT,
            "--format",
            "json",
        ])
        .stdout,
    )
    .unwrap();
    assert_eq!(json["p"], 0.95);
    let big_u = json["pitch_deviation_U"].as_array().unwrap();
    let k = json["pitch_deviation_k"].as_array().unwrap();
    assert_eq!((big_u.len(), k.len()), (24, 24));
    for r in rows.iter().filter(|r| r.quantity == "pitch_deviation") {
        let i = r.index as usize - 1;
        assert_eq!(r.expanded_u.unwrap(), big_u[i].as_f64().unwrap());
        assert_eq!(r.k.unwrap(), k[i].as_f64().unwrap());
    }
    assert!(json["face_deviation_k"][23].is_null());
    assert_eq!(
        json["uncertainty"]["components"].as_array().unwrap().len(),
        5
    );
    assert!(json["setup_error"][0]["U"].as_f64().unwrap() > 0.9); // the zero offset

    // the truth as a reference result with U = u = 0 (exact)
    let t: Value = serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let mut reference = String::from("quantity,index,value,U,u\n");
    let pitch: Vec<f64> = t["pitch_deviation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut phi = 0.0;
    for (k, b) in pitch.iter().enumerate() {
        reference += &format!("pitch_deviation,{},{b},0,0\n", k + 1);
        phi += b;
        if k < 23 {
            reference += &format!("face_deviation,{},{phi},0,0\n", k + 1);
        }
    }
    for (p, a) in t["encoder_error"].as_array().unwrap().iter().enumerate() {
        reference += &format!("encoder_error,{p},{},0,0\n", a.as_f64().unwrap());
    }
    let reference_path = dir.join("truth.csv");
    std::fs::write(&reference_path, reference).unwrap();
    let out = polycal(&[
        "compare",
        result.to_str().unwrap(),
        reference_path.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let comparison: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(comparison["rows"].as_array().unwrap().len(), 24 * 3 - 1);
    let max_en = comparison["max_abs_en"].as_f64().unwrap();
    assert!(
        max_en <= 1.0,
        "the budget's U covers the truth: max |En| = {max_en}"
    );
    assert_eq!(comparison["vector"]["consistent"], true);
    assert_eq!(out.status.code(), Some(0));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--monte-carlo` adds the monte_carlo object (and a table section), with status 0 when
/// validated and 1 when not; it needs --budget; bad budgets and an exactly determined fit
/// without --sigma are refused with status 2 and the place.
#[test]
fn cli_monte_carlo_and_refusals() {
    let dir = temp_dir("mc");
    let data = dir.join("bare.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "12",
        "--cycles",
        "1",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let d = data.to_str().unwrap();
    let out = polycal(&[
        "solve",
        d,
        "--sigma",
        "0.05",
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "1e5",
        "--mc-digits",
        "1",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    assert_eq!(mc["trials"], 100_000);
    assert_eq!(mc["solver"], "closed-form");
    for family in ["pitch_deviation", "face_deviation", "encoder_error"] {
        for key in [
            "mean", "u", "low", "high", "d_low", "d_high", "delta", "passed",
        ] {
            assert_eq!(
                mc[family][key].as_array().unwrap().len(),
                12,
                "{family} {key}"
            );
        }
    }
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    let u_mc = mc["pitch_deviation"]["u"][0].as_f64().unwrap();
    let u_gum = json["uncertainty"]["pitch_deviation"]["u"][0]
        .as_f64()
        .unwrap();
    assert!(close(u_mc, u_gum, 0.02), "{u_mc} vs {u_gum}");

    let table = polycal(&[
        "solve",
        d,
        "--sigma",
        "0.05",
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "20000",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 20000 trials"),
        "{text}"
    );
    assert!(text.contains("U(β)") && text.contains("each-autocollimator"));

    refused(
        &["solve", d, "--sigma", "0.05", "--monte-carlo", "1e5"],
        "--budget",
    );
    refused(&["solve", d, "--budget", INSTRUMENT], "--sigma");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[[component]]\nname = \"a\"\nu = 0.1\nacts_on = \"everywhere\"\n",
    )
    .unwrap();
    refused(
        &[
            "solve",
            d,
            "--sigma",
            "0.05",
            "--budget",
            bad.to_str().unwrap(),
        ],
        "bad.toml:4:11: unknown acts_on",
    );
    refused(
        &[
            "solve",
            d,
            "--sigma",
            "0.05",
            "--budget",
            INSTRUMENT,
            "--monte-carlo",
            "lots",
        ],
        "adaptive",
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `diagnose --budget --monte-carlo` adds the final model's monte_carlo object (its JSON
/// `after`, and a table section after the final model's results) with the effect columns
/// in the trials: its u follows the final model's GUM u_c, not the base model's; status 1
/// when an effect makes the model inadequate or the GUM is not validated, 0 otherwise; it
/// needs --budget; a self-calibration file's diagnosis gets its final model's too.
#[test]
fn cli_diagnose_monte_carlo_on_the_final_model() {
    let dir = temp_dir("diagnose-mc");
    let data = dir.join("drift.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "3",
        "--closing",
        "--drift",
        "2:3",
        "--offset-step",
        "1:2:10:0.6",
        "--seed",
        "3",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let d = data.to_str().unwrap();
    let out = polycal(&[
        "diagnose",
        d,
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "2e4",
        "--mc-digits",
        "1",
        "--seed",
        "7",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["effects"].as_array().unwrap().len() >= 2, "{json}");
    let after = &json["after"];
    let mc = &after["monte_carlo"];
    assert_eq!(mc["trials"], 20_000);
    assert_eq!(mc["seed"], 7);
    assert_eq!(mc["solver"], "lsq");
    for family in ["pitch_deviation", "face_deviation", "encoder_error"] {
        let u_mc = mc[family]["u"].as_array().unwrap();
        let u_gum = after["uncertainty"][family]["u"].as_array().unwrap();
        assert_eq!(u_mc.len(), 24);
        for (a, b) in u_mc.iter().zip(u_gum) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            // the t-scaled noise (JCGM 101 §6.4.9) makes the Monte Carlo u slightly larger
            if b > 0.0 {
                assert!(close(a, b, 0.05), "{family}: {a} vs {b}");
            }
        }
    }
    let verdict = !json["adequate"].as_bool().unwrap() || !mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if verdict { 1 } else { 0 }));
    assert!(json["before"].get("monte_carlo").is_none());

    let table = polycal(&[
        "diagnose",
        d,
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "20000",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    let final_model = text.find("Calibration of the final model").unwrap();
    let monte_carlo = text.find("Monte Carlo (JCGM 101): 20000 trials").unwrap();
    assert!(final_model < monte_carlo, "{text}");

    refused(&["diagnose", d, "--monte-carlo", "1e4"], "--budget");
    // a self-calibration file: the final model's Monte Carlo in its `after`, its u the
    // budget's on the final model
    let out = polycal(&[
        "diagnose",
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--monte-carlo",
        "1e4",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["after"]["monte_carlo"];
    selfcal_mc_follows_the_budget(mc, &json["after"]["uncertainty"], (168, 11), 0.05);
    let verdict = !json["adequate"].as_bool().unwrap() || !mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if verdict { 1 } else { 0 }));
    let table = polycal(&[
        "diagnose",
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--monte-carlo",
        "1e4",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 10000 trials"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A self-calibration's `monte_carlo` JSON object against the budget's `uncertainty`
/// object: (P, M − 1) values of u for e and the heads' errors, each within `tolerance`
/// (relative) of u_c.
fn selfcal_mc_follows_the_budget(
    mc: &Value,
    uncertainty: &Value,
    (positions, heads): (usize, usize),
    tolerance: f64,
) {
    for (family, len) in [("encoder_error", positions), ("head_error", heads)] {
        let u_mc = mc[family]["u"].as_array().unwrap();
        let u_gum = uncertainty[family]["u"].as_array().unwrap();
        assert_eq!((u_mc.len(), u_gum.len()), (len, len));
        for (a, b) in u_mc.iter().zip(u_gum) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(close(a, b, tolerance), "{family}: {a} vs {b}");
        }
    }
}

/// `selfcal --budget --monte-carlo` adds the budget's monte_carlo object (e and the heads'
/// errors; its u that of the budget), a table section, status 1 when some GUM interval is
/// not validated; it needs --budget; heads between the positions are evaluated alike.
#[test]
fn cli_selfcal_monte_carlo() {
    let dir = temp_dir("selfcal-mc");
    let budget = "examples/budgets/selfcal.toml";
    let data = "examples/data/selfa-168.csv";
    let out = polycal(&[
        "selfcal",
        data,
        "--budget",
        budget,
        "--monte-carlo",
        "2e4",
        "--seed",
        "5",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    assert_eq!(
        (mc["trials"].as_u64(), mc["seed"].as_u64()),
        (Some(20_000), Some(5))
    );
    selfcal_mc_follows_the_budget(mc, &json["uncertainty"], (168, 11), 0.03);
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    let table = polycal(&["selfcal", data, "--budget", budget, "--monte-carlo", "2e4"]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 20000 trials"),
        "{text}"
    );

    refused(&["selfcal", data, "--monte-carlo", "1e4"], "--budget");
    let off_grid = dir.join("off-grid.csv");
    let out = polycal(&[
        "simulate",
        "--selfcal",
        "--positions",
        "24",
        "--heads",
        "0,97,180",
        "--cycles",
        "2",
        "--out",
        off_grid.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // heads between the positions: the same evaluation, through the band-limited fit
    let out = polycal(&[
        "selfcal",
        off_grid.to_str().unwrap(),
        "--budget",
        budget,
        "--monte-carlo",
        "1e4",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    selfcal_mc_follows_the_budget(mc, &json["uncertainty"], (24, 2), 0.05);
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    std::fs::remove_dir_all(&dir).ok();
}
