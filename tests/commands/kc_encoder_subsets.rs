//! `polycal kc --quantity encoder_error` with a laboratory that reports a subset of the
//! encoder positions (docs/FORMAT.md §12, "What each laboratory measured"), end to end on
//! result files written here: the table's "—" and the JSON's null where it did not
//! measure, the CSV without those rows, status 0; and the refusals (a laboratory compared
//! on fewer than 2 positions, a pilot's repeat missing a position, a link that leaves a
//! position without a linking laboratory), each one `error:` line with status 2, and a
//! link through a laboratory with missing positions made. The
//! numbers are checked against a dense GLS in tests/maths/kc_encoder_subsets.rs.

use std::path::Path;
use std::process::Output;

use serde_json::Value;

use crate::hardening_support::{one_error_line, polycal, temp_dir, write};

/// A result file of encoder errors: (index, value, U at k = 2, angle_deg) per row.
fn encoder_file(rows: &[(u32, f64, f64, f64)]) -> String {
    let mut text = String::from("quantity,index,value,U,k,angle_deg\n");
    for (index, value, expanded_u, angle) in rows {
        text.push_str(&format!(
            "encoder_error,{index},{value},{expanded_u},2,{angle}\n"
        ));
    }
    text
}

/// Six positions, 60° apart, with `values` (`None`: not reported) and one U.
fn sixty(values: [Option<f64>; 6], expanded_u: f64) -> String {
    let rows: Vec<(u32, f64, f64, f64)> = values
        .iter()
        .enumerate()
        .filter_map(|(p, v)| v.map(|v| (p as u32, v, expanded_u, 60.0 * p as f64)))
        .collect();
    encoder_file(&rows)
}

/// A, B, C of six positions, consistent, each with its own zero; B without 60° and 240°.
fn three_labs(dir: &Path) -> Vec<String> {
    let a = sixty(
        [
            Some(0.10),
            Some(0.25),
            Some(-0.05),
            Some(-0.30),
            Some(0.02),
            Some(-0.02),
        ],
        0.2,
    );
    let b = sixty(
        [Some(3.12), None, Some(2.98), Some(2.71), None, Some(2.96)],
        0.3,
    );
    let c = sixty(
        [
            Some(-1.08),
            Some(-0.95),
            Some(-1.22),
            Some(-1.31),
            Some(-1.15),
            Some(-1.21),
        ],
        0.24,
    );
    [("A", a), ("B", b), ("C", c)]
        .iter()
        .map(|(name, text)| format!("{name}={}", write(dir, &format!("{name}.csv"), text)))
        .collect()
}

fn run(labs: &[String], more: &[&str]) -> Output {
    let mut args: Vec<&str> = vec!["kc"];
    args.extend(labs.iter().map(String::as_str));
    args.extend(["--quantity", "encoder_error"]);
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

/// The table's row of the degrees of equivalence at `angle`.
fn doe_row<'a>(table: &'a str, angle: &str) -> &'a str {
    table
        .lines()
        .skip_while(|l| !l.starts_with("Degrees of equivalence"))
        .find(|l| l.starts_with(angle))
        .unwrap_or_else(|| panic!("no row at {angle} in\n{table}"))
}

#[test]
fn kc_encoder_a_laboratory_missing_two_positions() {
    let dir = temp_dir("kc-encoder-subsets");
    let labs = three_labs(&dir);

    let out = run(&labs, &[]);
    status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("Key comparison of encoder_error, 3 laboratories: A, B, C"));
    // B's d and U are "—" at 60° and 240°, and only there
    for angle in ["60.0000", "240.0000"] {
        let row = doe_row(&table, angle);
        assert_eq!(row.matches('—').count(), 2, "{row}");
    }
    for angle in ["0.0000", "120.0000", "180.0000", "300.0000"] {
        let row = doe_row(&table, angle);
        assert!(!row.contains('—'), "{row}");
    }

    let out = run(&labs, &["--format", "json"]);
    status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["quantity"], "encoder_error");
    assert_eq!(
        json["angle_deg"],
        serde_json::json!([0.0, 60.0, 120.0, 180.0, 240.0, 300.0])
    );
    let b = &json["degrees_of_equivalence"][1];
    assert_eq!(b["lab"], "B");
    for k in 0..6 {
        let missing = k == 1 || k == 4;
        assert_eq!(b["d"][k].is_null(), missing, "{b}");
        assert_eq!(b["U"][k].is_null(), missing, "{b}");
    }
    // B closed over its own four positions
    let sum: f64 = (0..6).filter_map(|k| b["d"][k].as_f64()).sum();
    assert!(sum.abs() < 1e-12, "{sum}");
    // ν = Σ N_i − n − (K − 1) = 6 + 4 + 6 − 3 − 5
    assert_eq!(json["vector_all"]["dof"], 8);
    assert_eq!(json["vector_all"]["consistent"], true);
    // the pairs over the positions both report: A–B 4 (ν 3), A–C 6 (ν 5), B–C 4 (ν 3)
    let dofs: Vec<&Value> = (0..3).map(|p| &json["pairs"][p]["vector"]["dof"]).collect();
    assert_eq!(dofs, [3, 5, 3]);
    assert!(json["pairs"][0]["d"][1].is_null() && json["pairs"][0]["U"][4].is_null());

    let out = run(&labs, &["--format", "csv"]);
    status(&out, 0);
    let csv = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<&str> = csv.lines().collect();
    assert_eq!(rows[0], "lab,index,angle_deg,d,U,in_reference,quantity");
    assert_eq!(rows.len(), 1 + 6 + 4 + 6, "{csv}");
    assert!(
        !rows
            .iter()
            .any(|r| r.starts_with("B,1,") || r.starts_with("B,4,")),
        "{csv}"
    );
    assert!(rows[1..].iter().all(|r| !r.contains("NaN")), "{csv}");
}

#[test]
fn kc_encoder_subsets_refusals_are_one_error_line() {
    let dir = temp_dir("kc-encoder-subsets-refusals");
    let labs = three_labs(&dir);

    // D reports 0° and 90°; 90° no other laboratory reports: compared on 1 position
    let d = write(
        &dir,
        "D.csv",
        &encoder_file(&[(0, 0.1, 0.2, 0.0), (1, 0.0, 0.2, 90.0)]),
    );
    let error = one_error_line(&run(
        &[labs[0].clone(), labs[1].clone(), format!("D={d}")],
        &[],
    ));
    assert!(
        error.starts_with(&format!(
            "{d} (laboratory D): 1 of its encoder_error positions compared, fewer than 2"
        )),
        "{error}"
    );

    // Monte Carlo U over different positions: drawn (not refused), nulls where the formulas'
    let out = run(&labs, &["--monte-carlo", "2000", "--format", "json"]);
    assert_eq!(out.status.code(), Some(0));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["notes"].to_string().contains("Monte Carlo"));
    // B's U drawn where it reports, null where it does not (60°, 240°)
    let b_u = json["degrees_of_equivalence"][1]["U"].as_array().unwrap();
    for (p, u) in b_u.iter().enumerate() {
        assert_eq!(u.is_null(), p == 1 || p == 4, "{p}: {u}");
        assert!(u.is_null() || u.as_f64().unwrap() > 0.0, "{p}: {u}");
    }

    // a pilot's repeat without 180°: at its last encoder_error row (line 6), its index
    let start = write(
        &dir,
        "start.csv",
        &sixty(
            [
                Some(0.1),
                Some(0.2),
                Some(0.0),
                Some(-0.3),
                Some(0.0),
                Some(0.0),
            ],
            0.1,
        ),
    );
    let end = write(
        &dir,
        "end.csv",
        &sixty(
            [Some(0.1), Some(0.2), Some(0.0), None, Some(0.0), Some(0.0)],
            0.1,
        ),
    );
    let start_arg = format!("start={start}");
    let end_arg = format!("end={end}");
    let error = one_error_line(&run(&labs, &["--pilot", &start_arg, "--pilot", &end_arg]));
    assert!(
        error.starts_with(&format!(
            "{end}:6:15: the pilot's repeat end has no encoder_error at 180°"
        )),
        "{error}"
    );

    // a link through B, which misses two positions here
    let b_full = write(
        &dir,
        "B-full.csv",
        &sixty(
            [
                Some(3.12),
                Some(3.20),
                Some(2.98),
                Some(2.71),
                Some(3.03),
                Some(2.96),
            ],
            0.3,
        ),
    );
    let x = write(
        &dir,
        "X.csv",
        &sixty(
            [
                Some(0.0),
                Some(0.1),
                Some(0.0),
                Some(-0.2),
                Some(0.1),
                Some(0.0),
            ],
            0.2,
        ),
    );
    let out = run(
        &[format!("B={b_full}"), format!("X={x}")],
        &["--format", "json"],
    );
    status(&out, 0);
    let linked = write(&dir, "linked.json", &String::from_utf8(out.stdout).unwrap());
    // B alone links the comparisons, and it does not report 60° or 240° here: Δ there
    // cannot be found
    let error = one_error_line(&run(&labs, &["--link", &linked]));
    assert!(
        error.starts_with(
            "the comparisons cannot be linked: no linking laboratory reports 60° in both \
             comparisons"
        ),
        "{error}"
    );
    // with A in the linked comparison too, the link is made: B's offsets over its four
    // positions with a constant of its own, its d_linked closed over them and null where
    // it does not report
    let a_there = write(
        &dir,
        "A-there.csv",
        &sixty(
            [
                Some(-1.0),
                Some(-0.9),
                Some(-1.1),
                Some(-1.2),
                Some(-0.9),
                Some(-1.0),
            ],
            0.2,
        ),
    );
    let out = run(
        &[
            format!("A={a_there}"),
            format!("B={b_full}"),
            format!("X={x}"),
        ],
        &["--format", "json"],
    );
    status(&out, 0);
    let linked = write(
        &dir,
        "linked-a.json",
        &String::from_utf8(out.stdout).unwrap(),
    );
    let out = run(&labs, &["--link", &linked, "--format", "json"]);
    status(&out, 0);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["link"]["labs"], serde_json::json!(["A", "B"]));
    let b = &json["degrees_of_equivalence"][1];
    assert_eq!(b["lab"], "B");
    let d_linked = b["d_linked"].as_array().unwrap();
    let u_linked = b["U_linked"].as_array().unwrap();
    for p in [1, 4] {
        assert!(d_linked[p].is_null() && u_linked[p].is_null(), "{b}");
    }
    let sum: f64 = d_linked.iter().filter_map(Value::as_f64).sum();
    assert!(
        sum.abs() < 1e-9,
        "B's d_linked closed over its own positions: {sum}"
    );
    assert!(
        json["notes"]
            .to_string()
            .contains("the laboratories report different positions"),
        "{}",
        json["notes"]
    );
    // the table too
    let out = run(&labs, &["--link", &linked]);
    status(&out, 0);
}

/// The table states ν = (N − 1)(n − 1) = 8 where the laboratories report different
/// positions and ν = Σ N_i − n − (K − 1) = 8, while (N − 1)(n − 1) = (6 − 1)(3 − 1) = 10.
#[test]
fn kc_encoder_subsets_the_table_states_the_dof_it_used() {
    let dir = temp_dir("kc-encoder-subsets-dof-words");
    let out = run(&three_labs(&dir), &[]);
    status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    assert!(table.contains("ν = Σ N_i − n − (N − 1) = 8"), "{table}");
    assert!(table.contains("χ²_0.95(ν) = "), "{table}");
    assert!(!table.contains("ν = (N − 1)(n − 1) = 8"), "{table}");
}

/// The table's line of the pairs states one ν, the first pair's (3), while A–C is tested
/// with ν = 5 (its six common positions).
#[test]
fn kc_encoder_subsets_the_pairs_line_states_each_pairs_dof() {
    let dir = temp_dir("kc-encoder-subsets-pair-words");
    let out = run(&three_labs(&dir), &[]);
    status(&out, 0);
    let table = String::from_utf8(out.stdout).unwrap();
    let line = table
        .lines()
        .find(|l| l.starts_with("Pairs:"))
        .unwrap_or_else(|| panic!("{table}"));
    assert!(
        line.contains("over the M positions both report (ν = M − 1;"),
        "{line}"
    );
    assert!(!line.contains("(ν = 3;"), "{line}");
}

/// Laboratories whose positions fall into two groups sharing none (A, B at 0°–120°; C, D at
/// 180°–300°): refused, naming the groups, not a reference of u_ref ≈ 10⁶″ printed as if
/// it meant anything (found in review: the singular system was solved by rounding).
#[test]
fn kc_encoder_subsets_groups_sharing_no_position_are_refused() {
    let dir = temp_dir("kc-encoder-subsets-apart");
    let first = sixty([Some(0.1), Some(0.0), Some(-0.1), None, None, None], 0.2);
    let second = sixty([None, None, None, Some(0.2), Some(0.0), Some(-0.2)], 0.2);
    let labs: Vec<String> = [("A", &first), ("B", &first), ("C", &second), ("D", &second)]
        .iter()
        .map(|(name, text)| format!("{name}={}", write(&dir, &format!("{name}.csv"), text)))
        .collect();
    let error = one_error_line(&run(&labs, &[]));
    assert_eq!(
        error,
        "the laboratories fall into groups that share no encoder_error position: \
         {A, B} and {C, D}; results defined up to a constant cannot be put on one reference \
         across such groups"
    );
}
