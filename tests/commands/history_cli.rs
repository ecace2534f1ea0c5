//! `polycal history` on the command line (docs/FORMAT.md §13.2, §8): the bundled example's
//! JSON fields against numbers derived here, the table, `--plot`, `--max-u`, and each
//! refusal as one `error:` line naming the argument or file:line:column with status 2.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const DATA: &str = "examples/data/history";
const DATES: [&str; 6] = [
    "2019-03-12",
    "2020-03-10",
    "2021-03-02",
    "2022-03-15",
    "2023-03-07",
    "2024-03-05",
];

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env_remove("NO_COLOR")
        .env_remove("SOURCE_DATE_EPOCH")
        .output()
        .expect("polycal runs")
}

fn all() -> Vec<String> {
    DATES
        .iter()
        .map(|d| format!("{DATA}/{}.csv@{d}", &d[..4]))
        .collect()
}

fn scratch(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("polycal-history-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path: PathBuf = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

/// The one `error:` line of a refused run with status 2.
fn refused(args: &[&str]) -> String {
    let out = polycal(args);
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(out.stdout.is_empty(), "{args:?}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "{args:?}: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    lines[0].to_string()
}

fn json(args: &[&str]) -> Value {
    let out = polycal(args);
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("one JSON object")
}

/// The example's JSON: every field of the contract, the calibrations oldest first, and
/// per face the drift of the weighted straight line through the six files' values (all
/// u = 0.05″, so the plain least-squares slope of the closed values), computed here from
/// the files.
#[test]
fn history_json_of_the_bundled_example() {
    let mut args: Vec<String> = all().into_iter().rev().collect(); // given newest first
    args.extend(["--at", "2025-03-01", "--format", "json", "--max-u", "0.3"].map(String::from));
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let h = json(&[&["history"], refs.as_slice()].concat());
    for field in [
        "version",
        "quantity",
        "index",
        "dates",
        "model",
        "drift",
        "drift_u",
        "predicted",
        "predicted_u",
        "vector",
        "at",
        "k",
        "fit",
        "max_u_date",
        "recalibrate_by",
        "files",
    ] {
        assert!(h.get(field).is_some(), "{field}");
    }
    for field in ["chi2", "dof", "consistent"] {
        assert!(h["vector"].get(field).is_some(), "vector.{field}");
    }
    let dates: Vec<&str> = h["dates"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_str().unwrap())
        .collect();
    assert_eq!(dates, DATES);
    assert_eq!(h["model"], "linear");
    assert_eq!(h["vector"]["dof"], 23);
    assert_eq!(h["k"], 2.0);
    // the files' values, by a reader written here
    let values: Vec<Vec<f64>> = DATES
        .iter()
        .map(|d| {
            std::fs::read_to_string(format!("{DATA}/{}.csv", &d[..4]))
                .unwrap()
                .lines()
                .filter(|l| l.starts_with("pitch_deviation,"))
                .map(|l| l.split(',').nth(2).unwrap().parse().unwrap())
                .collect::<Vec<f64>>()
        })
        // closed vectors: each file's mean (0 to its rounding) taken out
        .map(|v| {
            let mean = v.iter().sum::<f64>() / v.len() as f64;
            v.iter().map(|x| x - mean).collect()
        })
        .collect();
    let epoch = |d: &str| polycal::clock::days_from_date(d).unwrap() as f64 / 365.25;
    let t: Vec<f64> = DATES.iter().map(|d| epoch(d)).collect();
    let t_bar = t.iter().sum::<f64>() / 6.0;
    let stt: f64 = t.iter().map(|t| (t - t_bar).powi(2)).sum();
    for k in 0..24 {
        let x_bar = values.iter().map(|v| v[k]).sum::<f64>() / 6.0;
        let slope = (0..6).map(|i| (t[i] - t_bar) * values[i][k]).sum::<f64>() / stt;
        let drift = h["drift"][k].as_f64().unwrap();
        assert!(
            (drift - slope).abs() < 1e-9,
            "face {}: {drift} vs {slope}",
            k + 1
        );
        let u_slope = 0.05 / stt.sqrt();
        assert!((h["drift_u"][k].as_f64().unwrap() - u_slope).abs() < 1e-9);
        let at = epoch("2025-03-01");
        let predicted = x_bar + slope * (at - t_bar);
        assert!((h["predicted"][k].as_f64().unwrap() - predicted).abs() < 1e-9);
        let u = 0.05 * (1.0 / 6.0 + (at - t_bar).powi(2) / stt).sqrt();
        assert!((h["predicted_u"][k].as_f64().unwrap() - u).abs() < 1e-9);
    }
    assert!(h["recalibrate_by"].as_str().unwrap() > "2025-03-01");
}

/// The table names the decision with its statistic and one line per face; `--plot`
/// writes the control charts, one chart per face.
#[test]
fn history_table_and_plot() {
    let dir = std::env::temp_dir().join(format!("polycal-history-plot-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let mut args = vec!["history".to_string()];
    args.extend(all());
    args.extend(["--at", "2025-03-01", "--plot"].map(String::from));
    args.push(dir.display().to_string());
    let refs: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = polycal(&refs);
    assert_eq!(out.status.code(), Some(0));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("Drift found: the drift vector's χ² = "),
        "{table}"
    );
    assert!(table.contains("χ²_0.95(23) = 35.17"));
    assert_eq!(
        table
            .lines()
            .filter(|l| l.split_whitespace().count() == 6
                && l.trim_start().starts_with(char::is_numeric))
            .count(),
        24,
        "{table}"
    );
    let svg = std::fs::read_to_string(dir.join("history-control-charts.svg")).unwrap();
    assert!(svg.starts_with("<svg"));
    assert_eq!(svg.matches(r#"<g class="position""#).count(), 24);
    assert_eq!(
        svg.matches(r#"class="point" data-panel="main" data-series="calibrations""#)
            .count(),
        24 * 6
    );
    assert_eq!(svg.matches(r#"data-series="prediction""#).count(), 24 * 2);
    assert_eq!(svg.matches("model-band").count(), 24);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Each refusal: one `error:` line, status 2, naming what is wrong.
#[test]
fn history_refusals() {
    let a = format!("{DATA}/2019.csv@2019-03-12");
    let b = format!("{DATA}/2024.csv@2024-03-05");
    assert!(refused(&["history", &a]).contains("at least 2 calibrations"));
    let e = refused(&["history", &a, &format!("{DATA}/2024.csv")]);
    assert!(
        e.contains("a result file carries no date") && e.contains("FILE@DATE"),
        "{e}"
    );
    let e = refused(&["history", &a, &format!("{DATA}/2024.csv@2023-02-29")]);
    assert!(e.contains("2023-02-29") && e.contains("not a day"), "{e}");
    let e = refused(&["history", &a, &b, "--at", "2025-3-1"]);
    assert!(e.contains("--at"), "{e}");
    let e = refused(&["history", &a, &format!("{DATA}/2019.csv@2020-01-01")]);
    assert!(e.contains("given twice"), "{e}");
    let e = refused(&["history", &a, &format!("{DATA}/2024.csv@2019-03-12")]);
    assert!(e.contains("at least 2 different days"), "{e}");
    let e = refused(&["history", &a, &b, "--quantity", "setup_error"]);
    assert!(e.contains("--quantity"), "{e}");
    // a row without u: file:line:column
    let no_u = scratch(
        "no-u.csv",
        "quantity,index,value,U,u,k\npitch_deviation,1,0.1,0.1,0.05,2\npitch_deviation,2,-0.1,,,\n",
    );
    let two = scratch(
        "two.csv",
        "quantity,index,value,u\npitch_deviation,1,0.12,0.05\npitch_deviation,2,-0.12,0.05\n",
    );
    let e = refused(&[
        "history",
        &format!("{two}@2020-01-01"),
        &format!("{no_u}@2021-01-01"),
    ]);
    assert!(
        e.contains(&format!("{no_u}:3:")) && e.contains("no standard uncertainty"),
        "{e}"
    );
    // another number of faces
    let e = refused(&["history", &a, &format!("{two}@2021-01-01")]);
    assert!(
        e.contains(&format!("{two}:3:")) && e.contains("faces"),
        "{e}"
    );
}
