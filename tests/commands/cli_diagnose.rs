//! `polycal diagnose` end to end: the JSON of docs/FORMAT.md §5 with a drift found, an
//! inadequate model's status 1, the final model's result CSV going straight into
//! `polycal compare` (against `solve` and against the truth written here by hand), and
//! `--budget`'s table and refusals.

use serde_json::Value;
use std::path::Path;

use crate::cli_support::{EXAMPLE, assert_status, numbers, polycal, temp_dir};

/// `diagnose --truth --format json`: the docs/FORMAT.md §5 object with the drift found on
/// the right autocollimator, the error falling, `adequate` true and status 0.
#[test]
fn diagnose_json_finds_a_drift() {
    let dir = temp_dir("diagnose");
    let data = dir.join("drift.csv");
    let truth = dir.join("drift.truth.json");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "6",
        "--closing",
        "--drift",
        "2:2.0",
        "--seed",
        "3",
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    assert_status(&out, 0);
    let out = polycal(&[
        "diagnose",
        data.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
        "--format",
        "json",
    ]);
    assert_status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in ["before", "after", "effects", "error", "adequate"] {
        assert!(json.get(key).is_some(), "missing {key}");
    }
    assert_eq!(json["adequate"], true);
    assert_eq!(json["before"]["effects"], serde_json::json!([]));
    let effect = &json["effects"][0];
    assert_eq!(effect["kind"], "drift");
    assert_eq!(effect["ac"], 2);
    let (value, u) = (
        effect["value"].as_f64().unwrap(),
        effect["u"].as_f64().unwrap(),
    );
    assert!((value - 2.0).abs() < 3.0 * u, "{value} ± {u}");
    assert_eq!(json["after"]["effects"], json["effects"]);
    let before = json["error"]["before"]["encoder_rms"].as_f64().unwrap();
    let after = json["error"]["after"]["encoder_rms"].as_f64().unwrap();
    assert!(after < 0.5 * before, "{before} → {after}");
    for key in ["pitch_rms", "pitch_max", "encoder_rms", "encoder_max"] {
        assert!(
            json["error"]["after"][key].is_number(),
            "missing error.after.{key}"
        );
    }
}

/// Structure no effect explains: `adequate` false and status 1; the table says where.
#[test]
fn diagnose_inadequate_exits_1() {
    use polycal::measurement::MeasurementSet;
    let dir = temp_dir("inadequate");
    let data = dir.join("clean.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "6",
        "--closing",
        "--seed",
        "9",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let mut set = MeasurementSet::read_path(&data, None).unwrap();
    for r in &mut set.readings {
        if r.ac == 2 {
            r.reading_arcsec +=
                0.8 * (2.0 * std::f64::consts::PI * r.time_seconds.unwrap() / 1500.0).sin();
        }
    }
    let wavy = dir.join("wavy.csv");
    set.write_path(&wavy, &[]).unwrap();
    let out = polycal(&["diagnose", wavy.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("NOT adequate"), "{text}");
    assert!(
        text.contains("structure left: setup 1 autocollimator 2"),
        "{text}"
    );
    let json: Value = serde_json::from_slice(
        &polycal(&["diagnose", wavy.to_str().unwrap(), "--format", "json"]).stdout,
    )
    .unwrap();
    assert_eq!(json["adequate"], false);
}

/// The truth of a simulation as a result file (docs/FORMAT.md §3) with U = 0: β, φ (but
/// the reference face φ[N]) and α, written here from the truth JSON by hand.
fn truth_result(truth: &Path, path: &Path) {
    let t: Value = serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
    let pitch = numbers(&t["pitch_deviation"]);
    let n = pitch.len();
    // The truth is exact: U = u = 0.
    let mut text = String::from("quantity,index,value,U,u\n");
    let mut phi = 0.0;
    for (k, b) in pitch.iter().enumerate() {
        text += &format!("pitch_deviation,{},{b},0,0\n", k + 1);
        phi += b;
        if k + 1 < n {
            text += &format!("face_deviation,{},{phi},0,0\n", k + 1);
        }
    }
    for (p, a) in numbers(&t["encoder_error"]).iter().enumerate() {
        text += &format!("encoder_error,{p},{a},0,0\n");
    }
    std::fs::write(path, text).unwrap();
}

/// The rows of a result CSV by (quantity, index): value, U, u, k (`None` when empty).
type Rows = std::collections::BTreeMap<(String, u32), (f64, Option<f64>, Option<f64>, Option<f64>)>;

fn result_rows(text: &str) -> Rows {
    let mut reader = csv::Reader::from_reader(text.as_bytes());
    assert_eq!(
        reader.headers().unwrap(),
        vec!["quantity", "index", "value", "U", "u", "k", "angle_deg"]
    );
    let field = |v: &str| (!v.is_empty()).then(|| v.parse::<f64>().unwrap());
    let mut rows = Rows::new();
    for record in reader.records() {
        let r = record.unwrap();
        let key = (r[0].to_string(), r[1].parse().unwrap());
        let row = (
            r[2].parse().unwrap(),
            field(&r[3]),
            field(&r[4]),
            field(&r[5]),
        );
        assert!(rows.insert(key, row).is_none(), "a row once");
    }
    rows
}

/// `compare A B --format json`: its rows, each checked against En computed here from the
/// two files' values and U (ISO 13528: (a − b)/√(U_a² + U_b²)), the rows with |En| > 1
/// counted, and its exit status (the vector's verdict).
fn compare_checked(a: &Path, b: &Path, a_rows: &Rows, b_rows: &Rows) -> (Vec<f64>, i32) {
    let out = polycal(&[
        "compare",
        a.to_str().unwrap(),
        b.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let status = out.status.code().unwrap();
    assert!(
        matches!(status, 0 | 1),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let common = a_rows.keys().filter(|k| b_rows.contains_key(*k)).count();
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), common);
    let mut en = Vec::new();
    let mut max = 0.0f64;
    for row in rows {
        let key = (
            row["quantity"].as_str().unwrap().to_string(),
            row["index"].as_u64().unwrap() as u32,
        );
        let (va, ua, _, _) = a_rows[&key];
        let (vb, ub, _, _) = b_rows[&key];
        let expected = (va - vb) / (ua.unwrap().powi(2) + ub.unwrap().powi(2)).sqrt();
        let got = row["en"].as_f64().unwrap();
        assert!(
            (got - expected).abs() <= 1e-12 * expected.abs().max(1.0),
            "{key:?}"
        );
        // Setup errors are listed, but out of the verdict (no --include-setup).
        let in_verdict = row["in_verdict"].as_bool().unwrap();
        assert_eq!(in_verdict, key.0 != "setup_error", "{key:?}");
        if in_verdict {
            max = max.max(got.abs());
        }
        en.push(got);
    }
    assert_eq!(json["max_abs_en"].as_f64().unwrap(), max);
    let exceeding = rows
        .iter()
        .filter(|r| r["in_verdict"] == true && r["en"].as_f64().unwrap().abs() > 1.0)
        .count();
    assert_eq!(json["en_exceeding"].as_u64().unwrap() as usize, exceeding);
    assert_eq!(json["verdict"], "vector");
    let consistent = json["vector"]["consistent"].as_bool().unwrap();
    assert_eq!(status, if consistent { 0 } else { 1 });
    (en, status)
}

/// `diagnose --format csv` writes the final model's result file, as `solve --format csv`
/// does: without a budget the fit's u and no U; with `--budget` u_c, U and k on every row
/// (φ[N] left out), the numbers of `diagnose --format json`'s `after` bit for bit. It goes
/// straight into `compare`: against `solve --budget --format csv` of the same data (the
/// drift left in) and against the truth written here by hand, which the corrected result
/// covers (|En| ≤ 1 for at least 95 % of the quantities) with a U of α less than half
/// the uncorrected one.
#[test]
fn diagnose_csv_goes_into_compare() {
    let dir = temp_dir("diagnose-csv");
    let data = dir.join("drift.csv");
    let truth = dir.join("drift.truth.json");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "6",
        "--closing",
        "--drift",
        "2:2.0",
        "--seed",
        "3",
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    assert_status(&out, 0);
    let data = data.to_str().unwrap();
    let budget = "examples/budgets/instrument.toml";

    // without a budget: the fit's u, U and k empty, as solve writes
    let out = polycal(&["diagnose", data, "--format", "csv"]);
    assert_status(&out, 0);
    let plain = result_rows(&String::from_utf8(out.stdout).unwrap());
    assert_eq!(plain.len(), 24 * 3 + 2);
    assert!(plain.values().all(|r| r.1.is_none() && r.3.is_none()));
    let json: Value =
        serde_json::from_slice(&polycal(&["diagnose", data, "--format", "json"]).stdout).unwrap();
    let after = &json["after"];
    for (k, u) in numbers(&after["pitch_deviation_u"]).iter().enumerate() {
        assert_eq!(plain[&("pitch_deviation".into(), k as u32 + 1)].2, Some(*u));
    }

    // with the budget
    let out = polycal(&["diagnose", data, "--budget", budget, "--format", "csv"]);
    assert_status(&out, 0);
    let text = String::from_utf8(out.stdout).unwrap();
    let rows = result_rows(&text);
    let diagnosed = dir.join("diagnosed.csv");
    std::fs::write(&diagnosed, &text).unwrap();
    let out = polycal(&["diagnose", data, "--budget", budget, "--format", "json"]);
    assert_status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let after = &json["after"];
    assert_eq!(json["effects"][0]["kind"], "drift");
    assert_eq!(after["effects"], json["effects"]);
    assert!(
        json["before"].get("pitch_deviation_U").is_none(),
        "the budget acts on the final model"
    );
    assert_eq!(after["p"], 0.95);
    assert_eq!(rows.len(), 24 * 3 - 1 + 2, "φ[N] left out");
    for (quantity, index0) in [
        ("pitch_deviation", 1),
        ("face_deviation", 1),
        ("encoder_error", 0),
    ] {
        let values = numbers(&after[quantity]);
        let big_u = numbers(&after[format!("{quantity}_U")]);
        let k = &after[format!("{quantity}_k")];
        let u_c = numbers(&after["uncertainty"][quantity]["u"]);
        for (i, value) in values.iter().enumerate() {
            let key = (quantity.to_string(), i as u32 + index0);
            let Some(row) = rows.get(&key) else {
                assert_eq!((quantity, i), ("face_deviation", 23));
                continue;
            };
            assert_eq!(row.0, *value, "{key:?}: full precision");
            assert_eq!(row.1, Some(big_u[i]), "{key:?}");
            assert_eq!(row.2, Some(u_c[i]), "{key:?}");
            assert_eq!(row.3, k[i].as_f64(), "{key:?}");
            assert!((big_u[i] - k[i].as_f64().unwrap() * u_c[i]).abs() < 1e-12);
        }
    }
    for (i, s) in after["setup_error"].as_array().unwrap().iter().enumerate() {
        let row = rows[&("setup_error".into(), i as u32 + 1)];
        assert_eq!(row.0, s["value"].as_f64().unwrap());
        assert_eq!(row.1, s["U"].as_f64());
    }

    // against solve's result of the same data, and against the truth
    let out = polycal(&["solve", data, "--budget", budget, "--format", "csv"]);
    assert_status(&out, 0);
    let solved_text = String::from_utf8(out.stdout).unwrap();
    let solved = dir.join("solved.csv");
    std::fs::write(&solved, &solved_text).unwrap();
    let solved_rows = result_rows(&solved_text);
    let (en, _) = compare_checked(&diagnosed, &solved, &rows, &solved_rows);
    assert_eq!(en.len(), 24 * 3 - 1 + 2);
    let reference = dir.join("truth.csv");
    truth_result(&truth, &reference);
    let truth_rows = result_rows_loose(&reference);
    let (en, _) = compare_checked(&diagnosed, &reference, &rows, &truth_rows);
    assert_eq!(en.len(), 24 * 3 - 1);
    let covered = en.iter().filter(|e| e.abs() <= 1.0).count();
    assert!(covered * 100 >= 95 * en.len(), "{covered} of {}", en.len());
    // The uncorrected result covers the truth too, but only because the drift inflates
    // its residual σ and with it every U: the corrected U of α is less than half of it.
    let (en_solve, _) = compare_checked(&solved, &reference, &solved_rows, &truth_rows);
    assert_eq!(en_solve.len(), en.len());
    for p in 0..24 {
        let key = ("encoder_error".to_string(), p);
        let (corrected, uncorrected) = (rows[&key].1.unwrap(), solved_rows[&key].1.unwrap());
        assert!(
            corrected < 0.5 * uncorrected,
            "α{p}: U {corrected} vs {uncorrected}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A result file with the columns quantity, index, value, U only.
fn result_rows_loose(path: &Path) -> Rows {
    let mut reader = csv::Reader::from_path(path).unwrap();
    let mut rows = Rows::new();
    for record in reader.records() {
        let r = record.unwrap();
        rows.insert(
            (r[0].to_string(), r[1].parse().unwrap()),
            (
                r[2].parse().unwrap(),
                Some(r[3].parse().unwrap()),
                None,
                None,
            ),
        );
    }
    rows
}

/// `diagnose --budget`: the table ends with the final model's calibration and its U and
/// k; several files give one CSV with a `file` column; a bad budget is one `error:` line
/// with status 2 and nothing on standard output; an exactly determined fit without
/// `--sigma` cannot be evaluated (status 2, the option named), and with it can.
#[test]
fn diagnose_budget_table_and_refusals() {
    let budget = "examples/budgets/instrument.toml";
    let out = polycal(&["diagnose", EXAMPLE, "--budget", budget]);
    let text = String::from_utf8(out.stdout).unwrap();
    let heading = text
        .find("Calibration of the final model")
        .expect("the heading");
    let section = &text[heading..];
    for word in ["U(β)", "U(φ)", "U(α)", "u_c(β)", "Combined u_c", budget] {
        assert!(section.contains(word), "{word}: {text}");
    }
    assert!(
        text[..heading].contains("polycal diagnose:"),
        "the diagnosis first"
    );

    let dir = temp_dir("diagnose-budget");
    let bare = dir.join("bare.csv");
    assert_status(
        &polycal(&[
            "simulate",
            "--faces",
            "12",
            "--cycles",
            "1",
            "--seed",
            "5",
            "--out",
            bare.to_str().unwrap(),
        ]),
        0,
    );
    let out = polycal(&[
        "diagnose",
        EXAMPLE,
        bare.to_str().unwrap(),
        "--budget",
        budget,
        "--format",
        "csv",
    ]);
    assert_status(&out, 2);
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("error: ") && stderr.contains("--sigma"),
        "{stderr}"
    );
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(
        text.starts_with("file,quantity,index,value,U,u,k,angle_deg\n"),
        "{text}"
    );
    assert!(
        text.lines()
            .skip(1)
            .all(|l| l.starts_with(&format!("{EXAMPLE},")))
    );
    let out = polycal(&[
        "diagnose",
        bare.to_str().unwrap(),
        "--sigma",
        "0.05",
        "--budget",
        budget,
        "--format",
        "csv",
    ]);
    assert_status(&out, 0);
    assert_eq!(
        String::from_utf8(out.stdout).unwrap().lines().count(),
        1 + 12 * 3 - 1 + 2
    );

    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[[component]]\nname = \"x\"\ntype = \"B\"\nu = 0.1\nacts_on = \"each-face\"\n",
    )
    .unwrap();
    for format in ["table", "json", "csv"] {
        let out = polycal(&[
            "diagnose",
            EXAMPLE,
            "--budget",
            bad.to_str().unwrap(),
            "--format",
            format,
        ]);
        assert_status(&out, 2);
        assert!(out.stdout.is_empty());
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(stderr.lines().count(), 1, "{stderr}");
        assert!(
            stderr.starts_with(&format!("error: {}:5:", bad.display())),
            "{stderr}"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}
