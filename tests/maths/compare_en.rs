//! En comparisons (docs/FORMAT.md §5), against the reference paper's En values (Hsieh
//! et al., Appl. Sci. 2023, 13, 1865, section 3.2): the paper's pitch deviations and encoder
//! errors, the correlation between the results, the JSON and the verdict, and the refusal
//! of rows without an expanded uncertainty.

use polycal::compare::{CompareError, CompareOptions, compare, compare_files};
use polycal::results::read_result_file;

use crate::compare_support::{en_rule, row, temp_file};

#[test]
fn en_of_the_paper_pitch_deviations() {
    // Largest pitch-deviation difference 0.28″; U = 0.46″ (two-autocollimator method)
    // and U = 0.15″ (shift-angle method): the paper's maximum En = 0.58.
    let a = [row("pitch_deviation", 5, 0.28, Some(0.46))];
    let b = [row("pitch_deviation", 5, 0.0, Some(0.15))];
    // One row given with U alone: the per-row rule, the vector not formed (and said why).
    let e = compare(&a, &b, &CompareOptions::default()).unwrap_err();
    assert!(matches!(e, CompareError::NoStandardU { .. }), "{e}");
    let c = compare(&a, &b, &en_rule()).unwrap();
    assert!(c.vector.is_none() && c.en_expected.is_none());
    assert!(c.vector_not_formed.is_some());
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
    let c = compare(&a, &b, &en_rule()).unwrap();
    assert_eq!(format!("{:.2}", c.rows[0].en), "-0.59"); // En is signed: (a − b)/…
    assert_eq!(format!("{:.2}", c.max_abs_en), "0.59");
    assert_eq!(c.rows[0].difference, -0.27);
}

#[test]
fn correlation_between_results_reduces_the_denominator() {
    // cov = r·U_a·U_b: En = d/√(U_a² + U_b² − 2 r U_a U_b).
    let a = [row("face_deviation", 2, 0.30, Some(0.4))];
    let b = [row("face_deviation", 2, 0.10, Some(0.3))];
    let options = en_rule().with_correlation(0.5);
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
    let c = compare(&a, &b, &en_rule()).unwrap();
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
    polycal::output::compare::write_table(&mut table, &c).unwrap();
    assert!(
        table.contains(
            "Verdict: NOT consistent by the per-row rule (|En| ≤ 1): 1 row of 2 with |En| > 1\n"
        ),
        "{table}"
    );
    assert!(table.contains("No vector test: "), "{table}");
    assert_eq!(json["verdict"], "en");
    assert!(json["vector"].is_null() && json["en_expected"].is_null());
    assert_eq!(json["en_exceeding"], 1);
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
    let c = compare_files(&fc, &fc, &en_rule()).unwrap();
    assert_eq!(c.max_abs_en, 0.0);
}
