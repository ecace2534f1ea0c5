//! `polycal kc` on the command line (docs/FORMAT.md §12, §8): the bundled example, its
//! JSON and CSV, the exit statuses, and each refusal as one `error:` line naming the file
//! (and line) with status 2.

use std::path::PathBuf;
use std::process::{Command, Output};

use serde_json::Value;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");
const DATA: &str = "examples/data/kc";

fn polycal(args: &[&str]) -> Output {
    Command::new(BIN)
        .args(args)
        .env_remove("NO_COLOR")
        .output()
        .expect("polycal runs")
}

fn example(name: &str) -> String {
    format!("{name}={DATA}/{name}.csv")
}

fn scratch(name: &str, text: &str) -> String {
    let dir = std::env::temp_dir().join(format!("polycal-kc-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path: PathBuf = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_string_lossy().into_owned()
}

/// A result file of `faces` pitch deviations, all with U = 0.2, k = 2; `skip` leaves a
/// face out and `zero_u` writes U = 0 on that face.
fn result(faces: u32, skip: Option<u32>, zero_u: Option<u32>) -> String {
    let mut text = String::from("quantity,index,value,U,k\n");
    for face in 1..=faces {
        if Some(face) == skip {
            continue;
        }
        let expanded_u = if Some(face) == zero_u { 0.0 } else { 0.2 };
        let value = 0.01 * f64::from(face % 3) - 0.01;
        text.push_str(&format!("pitch_deviation,{face},{value},{expanded_u},2\n"));
    }
    text
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

#[test]
fn kc_the_bundled_example_in_json_table_and_csv() {
    let labs: Vec<String> = ["A", "B", "C", "D", "E", "F"]
        .iter()
        .map(|l| example(l))
        .collect();
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    let mut json_args = args.clone();
    json_args.extend(["--format", "json"]);
    let out = polycal(&json_args);
    assert_eq!(out.status.code(), Some(0));
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["version"].is_string());
    for key in [
        "quantity",
        "index",
        "labs",
        "reference",
        "reference_u",
        "chi2",
        "chi2_dof",
        "consistent",
        "vector",
        "excluded",
        "tau",
        "degrees_of_equivalence",
        "pairs",
    ] {
        assert!(json.get(key).is_some(), "{key}");
    }
    assert_eq!(json["index"].as_array().unwrap().len(), 12);
    assert_eq!(json["excluded"][0]["lab"], "F");
    assert_eq!(json["vector"]["dof"], 44);
    assert_eq!(json["pairs"].as_array().unwrap().len(), 15);

    let out = polycal(&args);
    assert_eq!(out.status.code(), Some(0));
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("Excluded (largest consistent subset, in order):"));
    assert!(table.contains("Cox 2002"));

    let mut csv_args = args.clone();
    csv_args.extend(["--format", "csv"]);
    let out = polycal(&csv_args);
    let csv = String::from_utf8(out.stdout).unwrap();
    assert!(csv.starts_with("lab,index,angle_deg,d,U,in_reference\nA,1,,"));
    assert_eq!(csv.lines().count(), 1 + 6 * 12);
    assert!(
        csv.lines()
            .any(|l| l.starts_with("F,4,") && l.ends_with(",false"))
    );
}

#[test]
fn kc_status_1_when_not_consistent_after_the_exclusions() {
    // Two laboratories cannot be reduced: 0.5″ apart with u = 0.1″.
    let a = scratch("far-a.csv", &result(6, None, None));
    let far = result(6, None, None).replace("pitch_deviation,1,0,", "pitch_deviation,1,0.5,");
    let b = scratch("far-b.csv", &far);
    let out = polycal(&["kc", &format!("A={a}"), &format!("B={b}")]);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&out.stdout)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("Not consistent"));
}

#[test]
fn kc_refusals_are_one_error_line_naming_file_and_line() {
    let twelve = scratch("twelve.csv", &result(12, None, None));
    let eight = scratch("eight.csv", &result(8, None, None));
    let missing = scratch("missing.csv", &result(12, Some(5), None));
    let zero = scratch("zero.csv", &result(12, None, Some(3)));
    let lab = |name: &str, path: &str| format!("{name}={path}");

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &eight)]);
    assert!(message.contains(&format!("{eight}:9:")), "{message}");
    assert!(
        message.contains("8 faces") && message.contains("12"),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &missing)]);
    assert!(
        message.contains(&missing) && message.contains("face 5"),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &zero)]);
    assert!(message.contains(&format!("{zero}:4:")), "{message}");
    assert!(message.contains("U = 0"), "{message}");

    let message = refused(&["kc", &lab("A", &twelve), &lab("A", &eight)]);
    assert!(message.contains("\"A\" is given twice"), "{message}");
    assert!(
        message.contains(&twelve) && message.contains(&eight),
        "{message}"
    );

    let message = refused(&["kc", &lab("A", &twelve), &twelve]);
    assert!(message.contains("expected NAME=RESULT.csv"), "{message}");
    assert!(message.contains(&twelve), "{message}");

    let message = refused(&["kc", &lab("A", &twelve)]);
    assert!(
        message.contains("at least 2 laboratories, 1 given"),
        "{message}"
    );

    let message = refused(&[
        "kc",
        &lab("A", &twelve),
        &lab("B", &twelve),
        "--pilot",
        &lab("P", &twelve),
    ]);
    assert!(message.contains("--pilot"), "{message}");

    // A row the result reader refuses is named with its column.
    let bad = scratch(
        "bad.csv",
        "quantity,index,value,U,k\npitch_deviation,1,x,0.2,2\n",
    );
    let message = refused(&["kc", &lab("A", &twelve), &lab("B", &bad)]);
    assert!(message.contains(&format!("{bad}:2:")), "{message}");
}
