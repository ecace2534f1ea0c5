//! `polycal kc --quantity angle_block` end to end (docs/FORMAT.md §12, angle blocks): on
//! small result files written here, the table's "—" where a laboratory did not measure a
//! block, the JSON's null there, the CSV without those rows, the exit statuses, and every
//! refusal as one `error:` line with status 2 naming the file, line and column.

use std::path::Path;
use std::process::Output;

use serde_json::Value;

use crate::hardening_support::{one_error_line, polycal, temp_dir, write};

/// A result file of angle blocks: (block, value, U at k = 2, nominal_deg) per row.
fn blocks_file(rows: &[(u32, f64, f64, Option<f64>)]) -> String {
    let mut text = String::from("quantity,index,value,U,k,nominal_deg\n");
    for (block, value, expanded_u, nominal) in rows {
        let nominal = nominal.map_or(String::new(), |n| n.to_string());
        text.push_str(&format!(
            "angle_block,{block},{value},{expanded_u},2,{nominal}\n"
        ));
    }
    text
}

/// Laboratories A, B, C of three blocks (nominal 15°, 30°, 45°), consistent; B without
/// block 2.
fn three_labs(dir: &Path) -> Vec<String> {
    let a = blocks_file(&[
        (1, 0.31, 0.10, Some(15.0)),
        (2, -0.12, 0.12, Some(30.0)),
        (3, 0.69, 0.10, Some(45.0)),
    ]);
    let b = blocks_file(&[(1, 0.26, 0.16, Some(15.0)), (3, 0.75, 0.20, None)]);
    let c = blocks_file(&[
        (1, 0.36, 0.14, Some(15.0)),
        (2, -0.15, 0.14, Some(30.0)),
        (3, 0.62, 0.18, Some(45.0)),
    ]);
    [("A", a), ("B", b), ("C", c)]
        .iter()
        .map(|(name, text)| format!("{name}={}", write(dir, &format!("{name}.csv"), text)))
        .collect()
}

fn run(labs: &[String], more: &[&str]) -> Output {
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend(["--quantity", "angle_block"]);
    args.extend(more);
    polycal(&args)
}

fn status(out: &Output, code: i32) {
    assert_eq!(
        out.status.code(),
        Some(code),
        "stdout:\n{}\nstderr:\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The 1-based column where field `field` (0-based) of `line` starts.
fn column_of(line: &str, field: usize) -> usize {
    let mut column = 1;
    for (i, text) in line.split(',').enumerate() {
        if i == field {
            return column;
        }
        column += text.chars().count() + 1;
    }
    panic!("{line:?} has no field {field}");
}

#[test]
fn kc_blocks_table_json_and_csv_with_a_block_not_measured() {
    let dir = temp_dir("kc-blocks-outputs");
    let labs = three_labs(&dir);

    let out = run(&labs, &[]);
    status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("Key comparison of angle_block, 3 laboratories: A, B, C"));
    assert!(table.contains("Consistent: the blocks' joint χ² of all 3 laboratories passes"));
    // the degrees of equivalence: block 2 (30°) has "—" for B's d and U
    let row = table
        .lines()
        .skip_while(|l| !l.starts_with("Degrees of equivalence"))
        .find(|l| l.trim_start().starts_with("2 (30°)"))
        .unwrap_or_else(|| panic!("no row of block 2 in\n{table}"));
    assert_eq!(row.matches('—').count(), 2, "{row}");
    let row1 = table
        .lines()
        .skip_while(|l| !l.starts_with("Degrees of equivalence"))
        .find(|l| l.trim_start().starts_with("1 (15°)"))
        .unwrap();
    assert!(!row1.contains('—'), "{row1}");

    let out = run(&labs, &["--format", "json"]);
    status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["quantity"], "angle_block");
    assert_eq!(json["index"], serde_json::json!([1, 2, 3]));
    assert_eq!(json["nominal_deg"], serde_json::json!([15.0, 30.0, 45.0]));
    let b = &json["degrees_of_equivalence"][1];
    assert_eq!(b["lab"], "B");
    assert!(b["d"][1].is_null() && b["U"][1].is_null(), "{b}");
    assert!(b["d"][0].is_f64() && b["d"][2].is_f64());
    assert_eq!(json["vector_all"]["dof"], 2 + 1 + 2);
    // pair A–B is tested on blocks 1 and 3
    assert_eq!(json["pairs"][0]["b"], "B");
    assert_eq!(json["pairs"][0]["vector"]["dof"], 2);
    assert!(json["pairs"][0]["d"][1].is_null());

    let out = run(&labs, &["--format", "csv"]);
    status(&out, 0);
    let csv = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "lab,index,angle_deg,d,U,in_reference,quantity");
    assert_eq!(rows.len(), 1 + 3 + 2 + 3, "{csv}");
    assert!(!rows.iter().any(|r| r.starts_with("B,2,")), "{csv}");
    assert!(rows.iter().any(|r| r.starts_with("B,3,")), "{csv}");
    assert!(
        rows[1..]
            .iter()
            .all(|r| !r.contains("NaN") && r.ends_with(",true,angle_block"))
    );
}

#[test]
fn kc_blocks_status_1_when_the_blocks_disagree() {
    let dir = temp_dir("kc-blocks-apart");
    // two laboratories 1″ apart on block 2 with U = 0.1″: nothing to leave out
    let a = write(
        &dir,
        "A.csv",
        &blocks_file(&[(1, 0.1, 0.1, None), (2, 0.2, 0.1, None)]),
    );
    let b = write(
        &dir,
        "B.csv",
        &blocks_file(&[(1, 0.1, 0.1, None), (2, 1.2, 0.1, None)]),
    );
    let out = run(&[format!("A={a}"), format!("B={b}")], &[]);
    status(&out, 1);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(
        table.contains("NOT consistent: the blocks' joint χ² of all 2 laboratories fails"),
        "{table}"
    );
}

#[test]
fn kc_blocks_refusals_name_file_line_and_column() {
    let dir = temp_dir("kc-blocks-refusals");
    let labs = three_labs(&dir);
    let refused = |labs: &[String], more: &[&str]| one_error_line(&run(labs, more));
    let with = |name: &str, text: &str| {
        let path = write(&dir, &format!("{name}.csv"), text);
        (format!("{name}={path}"), path)
    };

    // nominal_deg on a pitch deviation's row: at its field
    let line = "pitch_deviation,1,0.1,0.2,2,15";
    let (pitch, path) = with(
        "pitch-nominal",
        &format!("quantity,index,value,U,k,nominal_deg\n{line}\n"),
    );
    let error = refused(&[labs[0].clone(), pitch], &[]);
    let at = format!("{path}:2:{}: ", column_of(line, 5));
    assert!(
        error.starts_with(&at) && error.contains("nominal_deg"),
        "{error}"
    );

    // nominal_deg 0 and 400
    for nominal in ["0", "400"] {
        let line = format!("angle_block,1,0.1,0.2,2,{nominal}");
        let (lab, path) = with(
            &format!("nominal-{nominal}"),
            &format!("quantity,index,value,U,k,nominal_deg\n{line}\n"),
        );
        let error = refused(&[labs[0].clone(), lab], &[]);
        let at = format!("{path}:2:{}: ", column_of(&line, 5));
        assert!(error.starts_with(&at), "{error}");
        assert!(error.contains("0 < nominal_deg < 360"), "{error}");
    }

    // angle_block 0: at the index
    let line = "angle_block,0,0.1,0.2,2,";
    let (zero, path) = with(
        "block-zero",
        &format!("quantity,index,value,U,k,nominal_deg\n{line}\n"),
    );
    let error = refused(&[labs[0].clone(), zero], &[]);
    assert!(error.starts_with(&format!("{path}:2:13: ")), "{error}");
    assert!(error.contains("angle blocks are numbered 1, 2"), "{error}");

    // two nominal angles of block 2: at the second, naming the first
    let text = blocks_file(&[(1, 0.3, 0.1, Some(15.0)), (2, -0.1, 0.1, Some(30.5))]);
    let (other, path) = with("other-nominal", &text);
    let error = refused(&[labs[0].clone(), other], &[]);
    let a_path = labs[0].trim_start_matches("A=");
    let expected =
        format!("{path}:3:26: angle_block 2 has nominal_deg 30.5, but 30 at {a_path}:3:28");
    assert!(error.starts_with(&expected), "{error}");

    // a file without angle_block rows
    let (pitch_only, path) = with(
        "pitch-only",
        "quantity,index,value,U,k\npitch_deviation,1,0.1,0.2,2\npitch_deviation,2,-0.1,0.2,2\n",
    );
    let error = refused(&[labs[0].clone(), pitch_only], &[]);
    assert!(
        error.contains(&format!(
            "{path} (laboratory pitch-only) has no angle_block rows"
        )),
        "{error}"
    );
}

/// A pilot's repeat without block 2 is refused at its last angle_block row's line and
/// column; the repeats of every block are taken.
#[test]
fn kc_blocks_a_pilot_repeat_missing_a_block_is_refused() {
    let dir = temp_dir("kc-blocks-pilot");
    let labs = three_labs(&dir);
    let start = write(
        &dir,
        "start.csv",
        &blocks_file(&[
            (1, 0.3, 0.04, None),
            (2, -0.1, 0.04, None),
            (3, 0.7, 0.04, None),
        ]),
    );
    let end = write(
        &dir,
        "end.csv",
        &blocks_file(&[(1, 0.31, 0.04, None), (3, 0.69, 0.04, None)]),
    );
    let full = write(
        &dir,
        "full.csv",
        &blocks_file(&[
            (1, 0.32, 0.04, None),
            (2, -0.12, 0.04, None),
            (3, 0.7, 0.04, None),
        ]),
    );
    let pilot = |p: &str, q: &str| vec![format!("start={p}"), format!("end={q}")];
    let args = |p: &[String]| -> Vec<String> {
        p.iter()
            .flat_map(|p| ["--pilot".to_string(), p.clone()])
            .collect()
    };
    let good = args(&pilot(&start, &full));
    let good: Vec<&str> = good.iter().map(String::as_str).collect();
    status(&run(&labs, &good), 0);
    let bad = args(&pilot(&start, &end));
    let bad: Vec<&str> = bad.iter().map(String::as_str).collect();
    let error = one_error_line(&run(&labs, &bad));
    // at its last angle_block row (line 3), the index field (after "angle_block,": 13)
    assert!(
        error.starts_with(&format!(
            "{end}:3:13: the pilot's repeat end has no angle_block 2"
        )),
        "{error}"
    );
}
