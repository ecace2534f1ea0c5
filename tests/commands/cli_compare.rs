//! `polycal compare` end to end: the paper's En numbers and the status, the vector's
//! verdict and the per-row rule (`--verdict en`), `--include-setup` and results matched by
//! angle, a negative `--correlation`, and `--format csv`.

use serde_json::Value;
use std::path::{Path, PathBuf};

use crate::cli_support::{assert_status, polycal, temp_dir};

/// `compare --verdict en` reproduces the paper's En numbers (0.58 and 0.59, status 0) and
/// says 1 when some |En| > 1; the vector's verdict refuses rows with U alone (no u, no k:
/// status 2, file and line named, `--verdict en` offered); a result without U is refused
/// (status 2, file and line named).
#[test]
fn compare_en_and_status() {
    let dir = temp_dir("compare");
    let a = dir.join("a.csv");
    let b = dir.join("b.csv");
    std::fs::write(
        &a,
        "quantity,index,value,U\npitch_deviation,1,0.28,0.46\nencoder_error,0,0.27,0.46\n",
    )
    .unwrap();
    std::fs::write(
        &b,
        "quantity,index,value,U\npitch_deviation,1,0,0.15\nencoder_error,0,0,0.02\n",
    )
    .unwrap();
    let out = polycal(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--format",
        "json",
        "--verdict",
        "en",
    ]);
    assert_eq!(out.status.code(), Some(0));
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["verdict"], "en");
    assert!(json["vector"].is_null() && json["en_expected"].is_null());
    assert!(json["vector_not_formed"].is_string());
    let en: Vec<f64> = json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["en"].as_f64().unwrap())
        .collect();
    assert_eq!(format!("{:.2} {:.2}", en[0], en[1]), "0.58 0.59");
    assert_eq!(
        format!("{:.2}", json["max_abs_en"].as_f64().unwrap()),
        "0.59"
    );

    let far = dir.join("far.csv");
    std::fs::write(&far, "quantity,index,value,U\npitch_deviation,1,0.9,0.1\n").unwrap();
    let out = polycal(&[
        "compare",
        far.to_str().unwrap(),
        b.to_str().unwrap(),
        "--verdict",
        "en",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let out = polycal(&["compare", far.to_str().unwrap(), b.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with(&format!(
            "error: {}:2: pitch_deviation 1 has U but no standard uncertainty",
            far.display()
        )) && stderr.contains("--verdict en"),
        "{stderr}"
    );

    let no_u = dir.join("no-u.csv");
    std::fs::write(&no_u, "quantity,index,value,u\npitch_deviation,1,0.9,0.1\n").unwrap();
    let out = polycal(&["compare", no_u.to_str().unwrap(), b.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: ") && stderr.contains(&format!("{}:2", no_u.display())),
        "{stderr}"
    );
}

/// The status of the two verdicts on two small files of 4 faces (u = 0.1″, k = 2): one
/// result 0.25″ off on every face in turn (+, −, +, −) passes every |En| (0.88) but fails
/// the vector (χ² = 4·0.25²/((4/3)·0.02) = 9.375 > χ²_0.95(3) = 7.81); the hand case of
/// tests/maths/compare_verdict.rs (one |En| = 1.06, χ² = 459/70 = 6.56) the other way
/// round.
#[test]
fn compare_vector_verdict_and_the_per_row_rule_through_the_binary() {
    let dir = temp_dir("compare-vector");
    let write = |name: &str, values: [f64; 4], u: [f64; 4]| {
        let path = dir.join(name);
        let mut text = String::from("quantity,index,value,U,u,k\n");
        for (face, (v, u)) in values.iter().zip(u).enumerate() {
            text += &format!("pitch_deviation,{},{v},{},{u},2\n", face + 1, 2.0 * u);
        }
        std::fs::write(&path, text).unwrap();
        path
    };
    let zero = write("zero.csv", [0.0; 4], [0.1; 4]);
    let alternating = write("alternating.csv", [0.25, -0.25, 0.25, -0.25], [0.1; 4]);
    let one_off = write("one-off.csv", [0.3, -0.1, -0.4, 0.2], [0.1, 0.1, 0.2, 0.2]);
    let run = |a: &Path, extra: &[&str]| -> (Value, i32) {
        let mut args = vec![
            "compare",
            a.to_str().unwrap(),
            zero.to_str().unwrap(),
            "--format",
            "json",
        ];
        args.extend_from_slice(extra);
        let out = polycal(&args);
        (
            serde_json::from_slice(&out.stdout).unwrap(),
            out.status.code().unwrap(),
        )
    };
    let (json, status) = run(&alternating, &[]);
    assert_eq!(status, 1);
    assert!((json["vector"]["chi2"].as_f64().unwrap() - 9.375).abs() < 1e-12);
    assert_eq!(json["vector"]["dof"], 3);
    assert_eq!(json["vector"]["consistent"], false);
    assert!((json["vector"]["critical"].as_f64().unwrap() - 7.814_727_903_251_178).abs() < 1e-9);
    assert_eq!(json["en_exceeding"], 0);
    assert!((json["en_expected"].as_f64().unwrap() - 0.182).abs() < 1e-3);
    assert_eq!(run(&alternating, &["--verdict", "en"]).1, 0);
    assert_eq!(run(&alternating, &["--verdict", "vector"]).1, 1);

    let (json, status) = run(&one_off, &[]);
    assert_eq!(status, 0);
    assert_eq!(json["vector"]["consistent"], true);
    assert_eq!(json["en_exceeding"], 1);
    let (json, status) = run(&one_off, &["--verdict", "en"]);
    assert_eq!(status, 1);
    assert_eq!(json["verdict"], "en");
    assert_eq!(
        json["vector"]["consistent"], true,
        "stated beside the per-row rule"
    );

    // The table states the verdict in one line.
    let out = polycal(&[
        "compare",
        alternating.to_str().unwrap(),
        zero.to_str().unwrap(),
    ]);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains(
            "Verdict: NOT consistent: χ² = 9.38 > χ²_0.95(3) = 7.81, the differences tested as \
             one vector at 5 %; 0 rows of 4 with |En| > 1, about 0.2 expected by chance\n"
        ),
        "{table}"
    );
    // An unknown rule is a usage error.
    let out = polycal(&[
        "compare",
        alternating.to_str().unwrap(),
        zero.to_str().unwrap(),
        "--verdict",
        "max",
    ]);
    assert_eq!(out.status.code(), Some(2));
}

/// `compare --include-setup` through the binary: on results where only a setup error has
/// |En| > 1 (tests/data/results/setup-a.csv and setup-b.csv, En = 1.1), the status is 0
/// without it (the setup error listed, in parentheses, out of the verdict); with it the
/// vector (χ² = 6.0, ν = 4) still passes, the per-row rule (`--verdict en`) does not.
/// A 24-position result against a 168-position one is matched by angle, and the table
/// says so.
#[test]
fn compare_include_setup_and_angles_through_the_binary() {
    let (a, b) = (
        "tests/data/results/setup-a.csv",
        "tests/data/results/setup-b.csv",
    );
    let out = polycal(&["compare", a, b]);
    assert_status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("(1.10)"), "{table}");
    assert!(table.contains("Largest |En| = 0.40"), "{table}");
    assert!(table.contains("left out of the verdict"), "{table}");
    let out = polycal(&["compare", a, b, "--include-setup"]);
    assert_status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("1.10 *"), "{table}");
    assert!(
        table.contains("Largest |En| = 1.10 (|En| > 1 marked *)"),
        "{table}"
    );
    assert!(
        table.contains("Verdict: consistent: χ² = 6.00 ≤ χ²_0.95(4) = 9.49"),
        "{table}"
    );
    assert!(table.contains("1 row of 6 with |En| > 1"), "{table}");
    assert_status(
        &polycal(&["compare", a, b, "--include-setup", "--verdict", "en"]),
        1,
    );

    let json = |extra: &[&str]| -> (Value, i32) {
        let mut args = vec!["compare", a, b, "--format", "json"];
        args.extend_from_slice(extra);
        let out = polycal(&args);
        (
            serde_json::from_slice(&out.stdout).unwrap(),
            out.status.code().unwrap(),
        )
    };
    let (without, status) = json(&[]);
    assert_eq!(status, 0);
    assert_eq!(without["rows"][5]["quantity"], "setup_error");
    assert_eq!(without["rows"][5]["in_verdict"], false);
    assert!((without["max_abs_en"].as_f64().unwrap() - 0.4).abs() < 1e-12);
    let (with, status) = json(&["--include-setup"]);
    assert_eq!(status, 0);
    assert_eq!(with["rows"][5]["in_verdict"], true);
    assert!((with["max_abs_en"].as_f64().unwrap() - 1.1).abs() < 1e-12);
    assert_eq!(with["vector"]["dof"], 4);
    assert_eq!(with["en_exceeding"], 1);
    let (_, status) = json(&["--include-setup", "--verdict", "en"]);
    assert_eq!(status, 1);
    let out = polycal(&[
        "compare",
        a,
        b,
        "--include-setup",
        "--verdict",
        "en",
        "--format",
        "csv",
    ]);
    assert_status(&out, 1);
    assert!(
        String::from_utf8(out.stdout)
            .unwrap()
            .ends_with(",,,true\n")
    );

    // Only setup errors in common: nothing to judge without --include-setup (named).
    let dir = temp_dir("only-setup");
    let (sa, sb) = (dir.join("a.csv"), dir.join("b.csv"));
    std::fs::write(&sa, "quantity,index,value,U\nsetup_error,1,1.3,0.6\n").unwrap();
    std::fs::write(&sb, "quantity,index,value,U\nsetup_error,1,0.2,0.8\n").unwrap();
    let (sa, sb) = (sa.to_str().unwrap(), sb.to_str().unwrap());
    let out = polycal(&["compare", sa, sb]);
    assert_status(&out, 2);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("--include-setup"),
        "{stderr}"
    );
    assert_status(
        &polycal(&["compare", sa, sb, "--include-setup", "--verdict", "en"]),
        1,
    );

    // By angle: 24 positions against 168.
    let (two_ac, selfcal) = (
        "tests/data/results/two-ac-24.csv",
        "tests/data/results/selfcal-168.csv",
    );
    let out = polycal(&["compare", two_ac, selfcal]);
    assert_status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains(
            "Encoder errors matched by angle (angle_deg within 1e-6°): 24 shared angles of 24 and 168"
        ),
        "{table}"
    );
    assert!(
        table.contains("1 row of 24 with |En| > 1, about 1.1 expected by chance"),
        "{table}"
    );
    assert_status(
        &polycal(&["compare", two_ac, selfcal, "--verdict", "en"]),
        1,
    );
}

/// Two result files for `compare`: the paper's numbers (see `compare_en_and_status`), U
/// alone, for the per-row rule (`--verdict en`).
fn two_results(name: &str) -> (PathBuf, PathBuf) {
    let dir = temp_dir(name);
    let a = dir.join("a.csv");
    let b = dir.join("b.csv");
    std::fs::write(
        &a,
        "quantity,index,value,U\npitch_deviation,1,0.28,0.46\nencoder_error,0,0.27,0.46\nencoder_error,1,0.1,0.2\n",
    )
    .unwrap();
    std::fs::write(
        &b,
        "quantity,index,value,U\npitch_deviation,1,0,0.15\nencoder_error,0,-0.1,0.02\n",
    )
    .unwrap();
    (a, b)
}

/// `compare --correlation -0.5`: the negative coefficient is used (it is in the JSON,
/// and En is the one of r = −0.5).
#[test]
fn negative_correlation_is_accepted() {
    let (a, b) = two_results("neg-correlation");
    let out = polycal(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--correlation",
        "-0.5",
        "--format",
        "json",
        "--verdict",
        "en",
    ]);
    assert_status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["correlation"], -0.5);
    let en = json["rows"][0]["en"].as_f64().unwrap();
    let expected = 0.28 / (0.46f64.powi(2) + 0.15f64.powi(2) + 0.46 * 0.15).sqrt();
    assert!((en - expected).abs() < 1e-12, "{en} vs {expected}");
}

/// `compare --format csv`: one row per compared quantity, the documented columns, the
/// JSON's numbers bit for bit; the status is the verdict's, as for the other formats.
#[test]
fn compare_csv() {
    let (a, b) = two_results("compare-csv");
    let (a, b) = (a.to_str().unwrap(), b.to_str().unwrap());
    let en = ["--verdict", "en"];
    let json: Value = serde_json::from_slice(
        &polycal(&[&["compare", a, b, "--format", "json"][..], &en].concat()).stdout,
    )
    .unwrap();
    let out = polycal(&[&["compare", a, b, "--format", "csv"][..], &en].concat());
    assert_eq!(out.status.code(), Some(0));
    assert!(
        out.stdout.as_slice().starts_with(
            b"quantity,index,a,b,difference,U_a,U_b,en,index_b,angle_deg,in_verdict\n"
        )
    );
    let mut reader = csv::Reader::from_reader(out.stdout.as_slice());
    let records: Vec<csv::StringRecord> = reader.records().map(Result::unwrap).collect();
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(records.len(), 2, "encoder_error 1 is in one result only");
    for record in &records {
        // matched by index (no angle_deg in these files), every row in the verdict
        assert_eq!((&record[8], &record[9], &record[10]), ("", "", "true"));
    }
    assert_eq!(records.len(), rows.len());
    for (record, row) in records.iter().zip(rows) {
        assert_eq!(&record[0], row["quantity"].as_str().unwrap());
        assert_eq!(
            record[1].parse::<u64>().unwrap(),
            row["index"].as_u64().unwrap()
        );
        for (i, key) in ["a", "b", "difference", "U_a", "U_b", "en"]
            .iter()
            .enumerate()
        {
            assert_eq!(
                record[i + 2].parse::<f64>().unwrap(),
                row[key].as_f64().unwrap(),
                "{key}"
            );
        }
    }
}
