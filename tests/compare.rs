//! The result CSV (docs/FORMAT.md §3) and En comparisons (docs/FORMAT.md §5), against the reference
//! paper's En values (Hsieh et al., Appl. Sci. 2023, 13, 1865, section 3.2).

use std::path::PathBuf;

use polycal::compare::{CompareError, CompareOptions, compare, compare_files};
use polycal::results::{
    Quantity, ResultRow, read_result_file, read_results_from, read_results_path, write_results,
};

fn row(quantity: &str, index: u32, value: f64, expanded_u: Option<f64>) -> ResultRow {
    ResultRow {
        quantity: Quantity::from_name(quantity).expect("a quantity"),
        index,
        value,
        u: None,
        expanded_u,
        k: None,
    }
}

fn temp_file(name: &str, contents: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-compare-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    path
}

// ---------------------------------------------------------------- En, the paper

#[test]
fn en_of_the_paper_pitch_deviations() {
    // Largest pitch-deviation difference 0.28″; U = 0.46″ (two-autocollimator method)
    // and U = 0.15″ (shift-angle method): the paper's maximum En = 0.58.
    let a = [row("pitch_deviation", 5, 0.28, Some(0.46))];
    let b = [row("pitch_deviation", 5, 0.0, Some(0.15))];
    let c = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert_eq!(format!("{:.2}", c.rows[0].en), "0.58");
    assert_eq!(format!("{:.2}", c.max_abs_en), "0.58");
    assert!(c.verdict_ok());
    // Equation (14) as printed, with a minus under the root, would give 0.64, not 0.58.
    assert_eq!(
        format!("{:.2}", 0.28 / (0.46f64.powi(2) - 0.15f64.powi(2)).sqrt()),
        "0.64"
    );
}

#[test]
fn en_of_the_paper_encoder_errors() {
    // Largest angle-error difference 0.27″; U = 0.46″ and U = 0.02″ (self-calibration):
    // the paper's maximum En = 0.59.
    let a = [row("encoder_error", 3, -0.27, Some(0.46))];
    let b = [row("encoder_error", 3, 0.0, Some(0.02))];
    let c = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert_eq!(format!("{:.2}", c.rows[0].en), "-0.59"); // En is signed: (a − b)/…
    assert_eq!(format!("{:.2}", c.max_abs_en), "0.59");
    assert_eq!(c.rows[0].difference, -0.27);
}

#[test]
fn correlation_between_results_reduces_the_denominator() {
    // cov = r·U_a·U_b: En = d/√(U_a² + U_b² − 2 r U_a U_b).
    let a = [row("face_deviation", 2, 0.30, Some(0.4))];
    let b = [row("face_deviation", 2, 0.10, Some(0.3))];
    let options = CompareOptions::new().with_correlation(0.5);
    let c = compare(&a, &b, &options).unwrap();
    let want = (0.30f64 - 0.10) / (0.16f64 + 0.09 - 2.0 * 0.5 * 0.4 * 0.3).sqrt();
    assert!((c.rows[0].en - want).abs() < 1e-15);
    let json = serde_json::to_value(&c).unwrap();
    assert_eq!(json["correlation"], 0.5);
    // Identical uncertainties fully correlated: En undefined, refused.
    let same = [row("face_deviation", 2, 0.1, Some(0.3))];
    let options = CompareOptions::new().with_correlation(1.0);
    assert!(matches!(
        compare(&same, &b, &options),
        Err(CompareError::Undefined { .. })
    ));
    let options = CompareOptions::new().with_correlation(1.5);
    assert!(matches!(
        compare(&same, &b, &options),
        Err(CompareError::Correlation(_))
    ));
}

#[test]
fn comparison_json_and_verdict() {
    let a = [
        row("pitch_deviation", 1, 0.52, Some(0.46)),
        row("pitch_deviation", 2, -1.20, Some(0.10)),
        row("encoder_error", 0, 0.1, Some(0.46)),
    ];
    let b = [
        row("pitch_deviation", 2, 0.0, Some(0.10)),
        row("pitch_deviation", 1, 0.31, Some(0.15)),
        row("setup_error", 1, 0.0, Some(0.1)),
    ];
    let c = compare(&a, &b, &CompareOptions::default()).unwrap();
    assert!(!c.verdict_ok()); // |En| = 8.5 for face 2
    assert_eq!(c.rows.len(), 2);
    let json = serde_json::to_value(&c).unwrap();
    let r0 = &json["rows"][0];
    for key in ["quantity", "index", "a", "b", "difference", "en"] {
        assert!(!r0[key].is_null(), "missing {key}");
    }
    assert_eq!(r0["quantity"], "pitch_deviation");
    assert_eq!(r0["index"], 1);
    assert_eq!(r0["a"], 0.52);
    assert_eq!(r0["b"], 0.31);
    assert_eq!(r0["difference"].as_f64().unwrap(), 0.52 - 0.31);
    assert_eq!(json["max_abs_en"].as_f64().unwrap(), c.rows[1].en.abs());
    assert_eq!(json["only_in_a"][0]["quantity"], "encoder_error");
    assert_eq!(json["only_in_b"][0]["quantity"], "setup_error");
    assert!(json.get("correlation").is_none());
    let mut table = String::new();
    polycal::report::compare::write_table(&mut table, &c).unwrap();
    assert!(table.contains("1 of 2 rows have |En| > 1"), "{table}");
    assert!(table.contains("-8.49 *"), "{table}");
    assert!(table.contains("Only in the first result (not compared): encoder_error 0"));
    // A duplicate row.
    let dup = [a[0].clone(), a[0].clone()];
    let e = compare(&dup, &b, &CompareOptions::default()).unwrap_err();
    assert_eq!(e.to_string(), "A (row 2): pitch_deviation 1 appears twice");
    // Nothing in common.
    let e = compare(&a[2..], &b[2..], &CompareOptions::default()).unwrap_err();
    assert!(matches!(e, CompareError::NothingInCommon { .. }));
}

#[test]
fn compare_refuses_rows_without_expanded_uncertainty_naming_file_and_line() {
    let a = temp_file(
        "a.csv",
        "# two-autocollimator result\nquantity,index,value,U\npitch_deviation,1,0.5,0.46\npitch_deviation,2,0.1,\n",
    );
    let b = temp_file(
        "b.csv",
        "quantity,index,value,U\npitch_deviation,1,0.4,0.15\n",
    );
    let fa = read_result_file(&a).unwrap();
    let fb = read_result_file(&b).unwrap();
    let e = compare_files(&fa, &fb, &CompareOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:4: pitch_deviation 2 has no expanded uncertainty U: compare needs U for every row (column U)",
            a.display()
        )
    );
    // Without a U column at all.
    let b = temp_file(
        "b2.csv",
        "quantity,index,value,u\npitch_deviation,1,0.4,0.07\n",
    );
    let fb = read_result_file(&b).unwrap();
    let e = compare_files(&fb, &fa, &CompareOptions::default()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with(&format!("{}:2: pitch_deviation 1 has no", b.display()))
    );
    // On slices, the label and the row number.
    let e = compare(&fa.rows, &fa.rows, &CompareOptions::default()).unwrap_err();
    assert!(
        e.to_string().starts_with("A (row 2): pitch_deviation 2"),
        "{e}"
    );
    // Files that do have U compare.
    let good = temp_file(
        "c.csv",
        "quantity,index,value,U\npitch_deviation,1,0.4,0.15\n",
    );
    let fc = read_result_file(&good).unwrap();
    let c = compare_files(&fc, &fc, &CompareOptions::default()).unwrap();
    assert_eq!(c.max_abs_en, 0.0);
}

// ---------------------------------------------------------------- result CSV

#[test]
fn results_round_trip_at_full_precision() {
    let rows = vec![
        ResultRow {
            quantity: Quantity::PitchDeviation,
            index: 1,
            value: 0.1 + 0.2,
            u: Some(0.228_673_894_443_594_07),
            expanded_u: Some(0.455_790_452_351_721_8),
            k: Some(1.993_189_705_631_875_3),
        },
        row("face_deviation", 24, -1e-17, None),
        row("encoder_error", 0, 123_456.789_012_345_6, Some(5e-324)),
        row("setup_error", 2, -0.0, Some(0.0)),
    ];
    let mut out = Vec::new();
    write_results(&mut out, &rows).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.starts_with("quantity,index,value,U,u,k\n"));
    assert!(text.contains("pitch_deviation,1,0.30000000000000004,0.4557904523517218,0.22867389444359407,1.9931897056318753\n"));
    assert!(text.contains("face_deviation,24,-0.00000000000000001,,,\n"));
    let back = read_results_from(text.as_bytes(), "mem.csv").unwrap();
    assert_eq!(back.rows, rows);
    for (a, b) in back.rows.iter().zip(&rows) {
        assert_eq!(a.value.to_bits(), b.value.to_bits());
    }
    assert_eq!(back.lines, vec![2, 3, 4, 5]);
    // Through a file.
    let path = temp_file("round.csv", &text);
    assert_eq!(read_results_path(&path).unwrap(), rows);
}

#[test]
fn results_accept_any_column_order_comments_and_extra_columns() {
    let text = "# reference result from the shift-angle method\n#\nk,U,value,index,quantity,note\n2,0.15, 0.31 ,1,pitch_deviation,first face\n,0.15,-0.2,2,pitch_deviation,\n";
    let f = read_results_from(text.as_bytes(), "ref.csv").unwrap();
    assert_eq!(
        f.rows,
        vec![
            ResultRow {
                quantity: Quantity::PitchDeviation,
                index: 1,
                value: 0.31,
                u: None,
                expanded_u: Some(0.15),
                k: Some(2.0)
            },
            row("pitch_deviation", 2, -0.2, Some(0.15)),
        ]
    );
    assert_eq!(f.lines, vec![4, 5]);
}

#[test]
fn results_accept_crlf_and_a_byte_order_mark() {
    let text = "\u{feff}quantity,index,value,U\r\nsetup_error,2,0.09,0.05\r\n";
    let f = read_results_from(text.as_bytes(), "win.csv").unwrap();
    assert_eq!(f.rows, vec![row("setup_error", 2, 0.09, Some(0.05))]);
    let bad = "\u{feff}quantity,index,value,U\r\nsetup_error,2,x,0.05\r\n";
    let e = read_results_from(bad.as_bytes(), "win.csv").unwrap_err();
    assert!(
        e.to_string().starts_with("win.csv:2:15: value must be"),
        "{e}"
    );
}

#[test]
fn results_are_refused_with_file_line_and_column() {
    let header = "# comment\nquantity,index,value,U,u,k\n";
    for (body, want) in [
        (
            "pitch_deviaton,1,0.5,,,\n",
            "r.csv:3:1: unknown quantity \"pitch_deviaton\"",
        ),
        (
            "pitch_deviation,x,0.5,,,\n",
            "r.csv:3:17: index must be a whole number ≥ 0, got \"x\"",
        ),
        (
            "pitch_deviation,-1,0.5,,,\n",
            "r.csv:3:17: index must be a whole number",
        ),
        (
            "pitch_deviation,0,0.5,,,\n",
            "r.csv:3:17: index 0 for pitch_deviation: faces are numbered 1 … N",
        ),
        (
            "setup_error,0,0.5,,,\n",
            "r.csv:3:13: index 0 for setup_error: autocollimator numbers start at 1",
        ),
        (
            "encoder_error,0,abc,,,\n",
            "r.csv:3:17: value must be a finite number, got \"abc\"",
        ),
        (
            "encoder_error,0,NaN,,,\n",
            "r.csv:3:17: value must be a finite number, got \"NaN\"",
        ),
        (
            "encoder_error,0,inf,,,\n",
            "r.csv:3:17: value must be a finite number, got \"inf\"",
        ),
        (
            "encoder_error,0,0.1,-0.46,,\n",
            "r.csv:3:21: U must not be negative, got -0.46",
        ),
        (
            "encoder_error,0,0.1,0.46,0.23,0\n",
            "r.csv:3:31: k must be greater than 0, got 0",
        ),
        (
            "encoder_error,0,0.1,0.46\n",
            "r.csv:3:25: this row has 4 fields, the header 6",
        ),
        (
            "encoder_error,0,0.1,0.46,,,7\n",
            "r.csv:3:28: this row has 7 fields, the header 6",
        ),
        (
            "face_deviation,3,0.1,,,\nface_deviation,4,0.1,,,\nface_deviation,3,0.2,,,\n",
            "r.csv:5:1: face_deviation 3 appears twice (first on line 3)",
        ),
        (
            "\"pitch, deviation\",1,0.5,,,\n",
            "r.csv:3:1: unknown quantity \"pitch, deviation\"",
        ),
        (
            "\"pitch_deviation\",1,\"x,y\",,,\n",
            "r.csv:3:21: value must be a finite number, got \"x,y\"",
        ),
        (
            "pitch_deviation,  1,  zz,,,\n",
            "r.csv:3:23: value must be a finite number, got \"zz\"",
        ),
    ] {
        let text = format!("{header}{body}");
        let got = read_results_from(text.as_bytes(), "r.csv")
            .map(|_| "ok".to_string())
            .unwrap_or_else(|e| e.to_string());
        assert!(
            got.starts_with(want),
            "for {body:?}\n got: {got}\nwant: {want}"
        );
    }
    for (text, want) in [
        ("", "r.csv:1:1: no header"),
        ("# only a comment\n", "r.csv:2:1: no header"),
        (
            "quantity,value,U\npitch_deviation,1,0.1\n",
            "r.csv:1:1: the header has no \"index\" column",
        ),
        (
            "quantity,index,value,U,U\n",
            "r.csv:1:24: the column \"U\" appears twice",
        ),
        ("quantity,index,value\n", "ok"),
    ] {
        let got = read_results_from(text.as_bytes(), "r.csv")
            .map(|_| "ok".to_string())
            .unwrap_or_else(|e| e.to_string());
        assert!(
            got.starts_with(want),
            "for {text:?}\n got: {got}\nwant: {want}"
        );
    }
    let e = read_results_path("no/such/result.csv")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("no/such/result.csv: "), "{e}");
}

#[test]
fn write_results_refuses_what_cannot_be_read_back() {
    let mut out = Vec::new();
    assert!(write_results(&mut out, &[row("pitch_deviation", 1, f64::NAN, None)]).is_err());
    assert!(
        write_results(
            &mut out,
            &[row("pitch_deviation", 1, 0.0, Some(f64::INFINITY))]
        )
        .is_err()
    );
}
