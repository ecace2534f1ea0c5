//! `polycal solve` end to end: the bundled example data checked against its truth file,
//! the output formats of docs/FORMAT.md §3 and §5 (JSON, the result CSV, the table for
//! people), several files and standard input, refusals with exit status 2 (a bad file, an
//! unobservable design, a design too large for the machine), `--method` and `--sigma`.

use serde_json::Value;
use std::path::Path;

use crate::cli_support::{EXAMPLE, assert_status, numbers, polycal, polycal_stdin, temp_dir};

const EXAMPLE_TRUTH: &str = "examples/data/polygon24-2ac-6cycles.truth.json";

/// The JSON of the example run agrees with the truth the data were simulated from,
/// within the uncertainties the fit states (every β and α within 4.5 u, and RMS of the
/// normalised errors plausible), and carries every field docs/FORMAT.md §5 names.
#[test]
fn solve_example_json_matches_truth() {
    let out = polycal(&["solve", EXAMPLE, "--format", "json"]);
    assert_status(&out, 0);
    let text = String::from_utf8(out.stdout).unwrap();
    assert_eq!(text.lines().count(), 1, "one JSON object for one file");
    let json: Value = serde_json::from_str(&text).unwrap();
    let truth_json: Value = serde_json::from_str(
        &std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE_TRUTH))
            .unwrap(),
    )
    .unwrap();

    assert_eq!(json["faces"], 24);
    assert_eq!(json["readings"], 300);
    // 6 cycles × 25 stops × 2 autocollimators; 2N − 2 + K = 48 free parameters
    assert_eq!(json["dof"], 300 - 48);
    for key in [
        "residual_rms",
        "pitch_deviation",
        "pitch_deviation_u",
        "face_deviation",
        "encoder_error",
        "encoder_error_u",
        "setup_error",
        "effects",
    ] {
        assert!(json.get(key).is_some(), "missing {key}");
    }
    assert_eq!(json["effects"], serde_json::json!([]));
    let rms = json["residual_rms"].as_f64().unwrap();
    assert!(
        (0.04..0.06).contains(&rms),
        "residual RMS {rms} for a noise of 0.05"
    );

    for (estimate, u, truth) in [
        ("pitch_deviation", "pitch_deviation_u", "pitch_deviation"),
        ("encoder_error", "encoder_error_u", "encoder_error"),
    ] {
        let estimate = numbers(&json[estimate]);
        let u = numbers(&json[u]);
        let truth = numbers(&truth_json[truth]);
        assert_eq!(estimate.len(), 24);
        let mut sum = 0.0;
        for k in 0..24 {
            let z = (estimate[k] - truth[k]) / u[k];
            assert!(
                z.abs() < 4.5,
                "index {k}: estimate {} truth {} u {}",
                estimate[k],
                truth[k],
                u[k]
            );
            sum += z * z;
        }
        let z_rms = (sum / 24.0).sqrt();
        assert!((0.4..1.6).contains(&z_rms), "normalised RMS {z_rms}");
    }
    let setup = json["setup_error"].as_array().unwrap();
    assert_eq!(setup.len(), 2);
    assert_eq!(setup[0]["ac"], 1);
    assert_eq!(setup[1]["ac"], 2);
    assert!(setup[0]["u"].as_f64().unwrap() > 0.0);
}

/// The result CSV (docs/FORMAT.md §3) carries the same numbers as the JSON, at full precision.
#[test]
fn solve_csv_is_the_result_file() {
    let json: Value =
        serde_json::from_slice(&polycal(&["solve", EXAMPLE, "--format", "json"]).stdout).unwrap();
    let out = polycal(&["solve", EXAMPLE, "--format", "csv"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    let headers = reader.headers().unwrap().clone();
    for column in ["quantity", "index", "value", "U", "u", "k"] {
        assert!(
            headers.iter().any(|h| h == column),
            "missing column {column}"
        );
    }
    let col = |name: &str| headers.iter().position(|h| h == name).unwrap();
    let mut pitch = Vec::new();
    let mut count = 0;
    for record in reader.records() {
        let record = record.unwrap();
        count += 1;
        // angle_deg: 15·p on encoder error p of 24 (docs/FORMAT.md §3.1), empty elsewhere
        let angle = &record[col("angle_deg")];
        if &record[col("quantity")] == "encoder_error" {
            let p: f64 = record[col("index")].parse().unwrap();
            assert_eq!(angle.parse::<f64>().unwrap(), 15.0 * p);
        } else {
            assert_eq!(angle, "");
        }
        if &record[col("quantity")] == "pitch_deviation" {
            pitch.push((
                record[col("index")].parse::<usize>().unwrap(),
                record[col("value")].parse::<f64>().unwrap(),
            ));
        }
    }
    assert_eq!(count, 24 * 3 + 2);
    let expected = numbers(&json["pitch_deviation"]);
    for (index, value) in pitch {
        assert_eq!(value, expected[index - 1], "full precision, bit for bit");
    }
}

/// Several files give JSON Lines with a "file" field; `-` reads standard input.
#[test]
fn several_files_and_stdin() {
    let data = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE)).unwrap();
    let out = polycal_stdin(&["solve", EXAMPLE, "-", "--format", "json"], &data);
    assert_status(&out, 0);
    let text = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0]["file"], EXAMPLE);
    assert_eq!(lines[1]["file"], "-");
    assert_eq!(lines[0]["pitch_deviation"], lines[1]["pitch_deviation"]);
}

/// The table shows every face and position, the dof and the residual RMS.
#[test]
fn table_for_people() {
    let out = polycal(&["solve", EXAMPLE]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("24 faces, 300 readings"), "{text}");
    assert!(text.contains("dof 252"), "{text}");
    assert!(text.contains("residual RMS"));
    assert!(text.contains("345.0000"), "the last position's angle");
}

/// A refused input: one `error:` line naming file, line and column; exit status 2.
#[test]
fn bad_file_is_refused_with_location() {
    let dir = temp_dir("bad");
    let path = dir.join("bad.csv");
    std::fs::write(
        &path,
        "cycle,step,ac,face,reading\n1,0,1,1,0.1\n1,0,2,2,abc\n",
    )
    .unwrap();
    let out = polycal(&["solve", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.contains(&format!("{}:3:9", path.display())),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
}

/// A design that cannot determine everything is refused (status 2), naming the lost
/// harmonics: the second autocollimator three faces away on a 24-faced polygon.
#[test]
fn unobservable_design_is_refused() {
    let dir = temp_dir("unobservable");
    let path = dir.join("ac-3-apart.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--ac-faces",
        "1,4",
        "--cycles",
        "2",
        "--closing",
        "--out",
        path.to_str().unwrap(),
    ]);
    assert_status(&out, 0);
    let out = polycal(&["solve", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(stderr.contains("harmonics 8 and 16"), "{stderr}");
}

/// `--method closed-form` refuses a design it does not cover; `--sigma` gives
/// uncertainties to an exactly determined fit.
#[test]
fn method_and_sigma_options() {
    let out = polycal(&["solve", EXAMPLE, "--method", "closed-form"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("closing readings"));

    let dir = temp_dir("bare");
    let path = dir.join("bare.csv");
    let path = path.to_str().unwrap();
    assert!(
        polycal(&["simulate", "--faces", "12", "--cycles", "1", "--out", path])
            .status
            .success()
    );
    let json: Value =
        serde_json::from_slice(&polycal(&["solve", path, "--format", "json"]).stdout).unwrap();
    assert_eq!(json["dof"], 0);
    assert_eq!(json["residual_rms"], Value::Null);
    assert_eq!(json["pitch_deviation_u"], Value::Null);
    assert_eq!(json["method"], "closed-form");
    let json: Value = serde_json::from_slice(
        &polycal(&["solve", path, "--format", "json", "--sigma", "0.05"]).stdout,
    )
    .unwrap();
    // Hand-derived: on the bare cycle eqs. (7)–(8) give β_k = δ[π(k)] − mean(δ) with
    // independent differences δ of variance 2σ², so u(β_k) = σ·√(2(1 − 1/N)).
    let expected = 0.05 * (2.0 * (1.0 - 1.0 / 12.0f64)).sqrt();
    for u in numbers(&json["pitch_deviation_u"]) {
        assert!(
            (u - expected).abs() < 1e-12,
            "u(β) = {u}, expected {expected}"
        );
    }
    assert_eq!(json["sigma_source"], "stated");
}

/// A design too large for the dense reference (50 000 positions: about 522 GiB) is
/// refused up front with status 2 and one `error:` line naming the file, the size and
/// the memory; `--method lsq` solves the same file on the circulant engine, and `auto`
/// by the closed form; `diagnose` evaluates it on the structured geometry.
#[test]
fn designs_too_large_for_the_machine_are_refused_up_front() {
    let dir = temp_dir("too-large");
    let file = dir.join("big.csv");
    let file_text = file.to_str().unwrap();
    let out = polycal(&[
        "simulate", "--faces", "50000", "--cycles", "1", "--out", file_text, "-q",
    ]);
    assert_status(&out, 0);
    let out = polycal(&["solve", file_text, "--method", "dense", "--format", "json"]);
    assert_status(&out, 2);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    assert!(stderr.contains("big.csv"), "{stderr}");
    assert!(stderr.contains("50000 positions"), "{stderr}");
    assert!(stderr.contains("521.6 GiB"), "{stderr}");
    assert!(stderr.contains("available on this machine"), "{stderr}");
    assert!(out.stdout.is_empty());
    // diagnose's geometry is the engine's structured cofactor, never the dense matrix:
    // the same file is diagnosed (a bare cycle: nothing can be tested, and it says so)
    let out = polycal(&["diagnose", file_text, "--sigma", "0.05", "--format", "json"]);
    assert_status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["testable"], false);
    assert_eq!(json["before"]["engine"], "circulant");
    for (method, engine) in [("lsq", "circulant"), ("auto", "closed-form")] {
        let out = polycal(&[
            "solve", file_text, "--method", method, "--sigma", "0.05", "--format", "json",
        ]);
        assert_status(&out, 0);
        let json: Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["engine"], engine);
        assert_eq!(numbers(&json["encoder_error_u"]).len(), 50_000);
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// The solve table's `nominal/°` column is the angle φ is defined against: face f at
/// f·360°/N from face N, whose φ is 0 (docs/FORMAT.md §1), so face N at 360°. By hand for
/// N = 24: 15° per face; and φ of face N printed as 0.
#[test]
fn the_solve_table_puts_face_f_at_f_times_360_over_n() {
    for args in [
        vec!["solve", EXAMPLE],
        vec![
            "solve",
            EXAMPLE,
            "--budget",
            "examples/budgets/instrument.toml",
        ],
    ] {
        let out = polycal(&args);
        assert_status(&out, 0);
        let text = String::from_utf8_lossy(&out.stdout).into_owned();
        let lines: Vec<&str> = text.lines().collect();
        let title = lines
            .iter()
            .position(|l| l.starts_with("Polygon (arcsec"))
            .unwrap_or_else(|| panic!("a polygon section:\n{text}"));
        assert!(
            lines[title].contains("f·360°/N") && lines[title].contains("face N at 360°"),
            "the title says which angle the column is: {}",
            lines[title]
        );
        assert_eq!(
            lines[title + 1]
                .split_whitespace()
                .take(2)
                .collect::<Vec<_>>(),
            ["face", "nominal/°"]
        );
        for f in 1..=24usize {
            let row: Vec<&str> = lines[title + 1 + f].split_whitespace().collect();
            assert_eq!(row[0], f.to_string(), "{}", lines[title + 1 + f]);
            assert_eq!(row[1], format!("{:.4}", f as f64 * 15.0), "face {f}");
        }
        let last: Vec<&str> = lines[title + 1 + 24].split_whitespace().collect();
        let phi_column = if args.len() > 2 { 7 } else { 4 };
        assert_eq!(
            last[phi_column].trim_start_matches('-'),
            "0.0000",
            "{last:?}"
        );
    }
}
