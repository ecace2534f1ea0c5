//! The result CSV's `angle_deg` column (docs/FORMAT.md §3) and comparisons matched by angle
//! (docs/FORMAT.md §5): a 24-position result against a 168-position self-calibration, a
//! file without angles matched by index, setup errors left out of the verdict unless
//! included, the matching tolerance and its refusals, and the angle rules of the writer
//! and the reader.

use std::path::{Path, PathBuf};

use polycal::compare::{
    CompareError, CompareOptions, EncoderMatching, VerdictRule, compare, compare_files,
};
use polycal::results::{Quantity, ResultRow, read_result_file, read_results_from, write_results};

use crate::compare_support::{en_rule, row};

/// A file of `tests/data/results/`.
fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/results")
        .join(name)
}

/// The encoder errors of a result file read here without polycal's reader (the csv crate
/// and the header's names): index → (value, U, angle_deg).
fn encoder_rows(path: &Path) -> std::collections::BTreeMap<u32, (f64, f64, Option<f64>)> {
    let text = std::fs::read_to_string(path).unwrap();
    let body: String = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| format!("{l}\n"))
        .collect();
    let mut reader = csv::Reader::from_reader(body.as_bytes());
    let headers = reader.headers().unwrap().clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let (q, i, v, u, angle) = (
        col("quantity").unwrap(),
        col("index").unwrap(),
        col("value").unwrap(),
        col("U").unwrap(),
        col("angle_deg"),
    );
    let mut rows = std::collections::BTreeMap::new();
    for record in reader.records() {
        let r = record.unwrap();
        if &r[q] != "encoder_error" {
            continue;
        }
        let angle = angle.and_then(|c| r[c].parse::<f64>().ok());
        rows.insert(
            r[i].parse().unwrap(),
            (r[v].parse().unwrap(), r[u].parse().unwrap(), angle),
        );
    }
    rows
}

/// A 24-position result (angles 15·p) against a 168-position self-calibration (angles
/// k·360/168): the 24 shared angles are compared, position p of the first with position
/// 7·p of the second, among them 0° (written 359.9999996 in the second, across the wrap)
/// and 345° (written 345.0000008); the 144 other positions of the second are unmatched,
/// and so are the first's pitch, face and setup rows. Every En is derived here from the
/// two files' values: (a − b)/√(U_a² + U_b²) with U = 0.3 and 0.4, so 2·(a − b). The
/// shared angles differ by 0.1 but at 45° by 0.6: the vector (its mean difference taken
/// out, encoder errors being defined up to a constant) is consistent, the per-row rule not.
#[test]
fn encoder_errors_are_matched_by_angle_24_against_168() {
    let (pa, pb) = (data("two-ac-24.csv"), data("selfcal-168.csv"));
    let (fa, fb) = (
        read_result_file(&pa).unwrap(),
        read_result_file(&pb).unwrap(),
    );
    let c = compare_files(&fa, &fb, &CompareOptions::default()).unwrap();
    assert_eq!(c.encoder_matched_by, EncoderMatching::Angle);
    let encoder: Vec<_> = c
        .rows
        .iter()
        .filter(|r| r.quantity == Quantity::EncoderError)
        .collect();
    assert_eq!(encoder.len(), 24);
    assert_eq!(c.rows.len(), 24, "nothing else is in both");

    let (ea, eb) = (encoder_rows(&pa), encoder_rows(&pb));
    assert_eq!((ea.len(), eb.len()), (24, 168));
    for (p, row) in encoder.iter().enumerate() {
        let p = p as u32;
        let (a, ua, angle) = ea[&p];
        let (b, ub, _) = eb[&(7 * p)];
        let en = (a - b) / (ua * ua + ub * ub).sqrt();
        assert_eq!((row.index, row.index_b), (p, Some(7 * p)));
        assert_eq!(row.angle_deg, angle, "the first result's angle");
        assert_eq!(row.angle_deg, Some(15.0 * f64::from(p)));
        assert_eq!((row.a, row.b), (a, b));
        assert!((row.en - en).abs() < 1e-12, "p = {p}: {} vs {en}", row.en);
        assert!(row.in_verdict);
    }
    // By hand: 0° is 0 − (−0.1) = 0.1 → En 0.2; 45° is 0.03 − (−0.57) = 0.6 → En 1.2;
    // 345° is 0.23 − 0.13 = 0.1 → En 0.2.
    assert!((encoder[0].en - 0.2).abs() < 1e-12, "{}", encoder[0].en);
    assert!((encoder[3].en - 1.2).abs() < 1e-12, "{}", encoder[3].en);
    assert!((encoder[23].en - 0.2).abs() < 1e-12, "{}", encoder[23].en);
    assert!((c.max_abs_en - 1.2).abs() < 1e-12);
    // The vector by hand: u = 0.15 and 0.2 (k = 2), each result closed over its own 24
    // and 168 positions, so every difference has the variance
    // v = (24/23)·0.15² + (168/167)·0.2²; about their mean, the differences are one 0.5
    // among 24, Σ (d − d̄)² = 0.5²·23/24, and χ² = 0.5²·(23/24)/v = 3.76, ν = 23.
    let v = 24.0 / 23.0 * 0.15f64.powi(2) + 168.0 / 167.0 * 0.2f64.powi(2);
    let vector = c.vector.as_ref().unwrap();
    assert!(
        (vector.chi2 - 0.25 * 23.0 / 24.0 / v).abs() < 1e-12,
        "{}",
        vector.chi2
    );
    assert_eq!(vector.dof, 23);
    assert!(c.verdict_ok(), "one row at 1.2 U among 24 is chance");
    assert_eq!(c.en_exceeding, 1);
    // Each row: s = 1/2 (k = 2 on both sides), P(|En| > 1) = erfc(2/√2) = 4.55 % (statrs's
    // erfc is good to about 1e-10 here).
    let expected = c.en_expected.unwrap();
    assert!(
        (expected - 24.0 * 0.045_500_263_896_358_4).abs() < 1e-9,
        "{expected}"
    );
    assert!(
        !compare_files(&fa, &fb, &en_rule()).unwrap().verdict_ok(),
        "45° differs by 1.2 U"
    );

    // The unmatched rows, as unmatched rows always are.
    assert_eq!(c.only_in_b.len(), 144);
    assert!(
        c.only_in_b
            .iter()
            .all(|u| u.quantity == Quantity::EncoderError
                && u.index % 7 != 0
                && u.angle_deg.is_some())
    );
    assert_eq!(c.only_in_a.len(), 24 + 23 + 2);
    assert!(
        c.only_in_a
            .iter()
            .all(|u| u.quantity != Quantity::EncoderError && u.angle_deg.is_none())
    );

    // JSON: angle_deg and index_b on the encoder rows, the way of matching.
    let json = serde_json::to_value(&c).unwrap();
    assert_eq!(json["encoder_matched_by"], "angle");
    assert_eq!(json["rows"][1]["angle_deg"], 15.0);
    assert_eq!(json["rows"][1]["index_b"], 7);
    assert_eq!(json["rows"][1]["in_verdict"], true);
    assert_eq!(json["only_in_b"][0]["index"], 1);
    assert_eq!(json["only_in_b"][0]["angle_deg"], 360.0 / 168.0);

    // The table says how the matching was done.
    let mut table = String::new();
    polycal::output::compare::write_table(&mut table, &c).unwrap();
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
    assert!(table.contains("Angle °"), "{table}");
    // The 144 positions only in the 168-position result: their number, the first six
    // (the positions not a multiple of 7: 1 … 6) and where every one is, on one short
    // line; the 49 rows only in the first (24 β, 23 φ, 2 U) likewise counted.
    let line = table
        .lines()
        .find(|l| l.starts_with("Only in the second result"))
        .unwrap_or_else(|| panic!("no line for the second result's rows:\n{table}"));
    assert_eq!(
        line,
        "Only in the second result (not compared): 144 quantities: encoder_error 1, \
         encoder_error 2, encoder_error 3, encoder_error 4, encoder_error 5, encoder_error 6, \
         … (every one in the JSON output's only_in_a/only_in_b)"
    );
    assert!(
        table.contains("Only in the first result (not compared): 49 quantities: "),
        "{table}"
    );

    // The other way round: the same pairs, the first result's index and angle.
    let c = compare_files(&fb, &fa, &CompareOptions::default()).unwrap();
    assert_eq!(c.rows.len(), 24);
    assert_eq!((c.rows[0].index, c.rows[0].index_b), (0, Some(0)));
    assert_eq!(c.rows[0].angle_deg, Some(359.999_999_6));
    assert_eq!(c.rows[1].index_b, Some(1));
    assert_eq!(c.rows[1].index, 7);
    assert!((c.rows[0].en + 0.2).abs() < 1e-12);
}

/// One file with angles and one without: encoder errors by index, as before angles were
/// written (position p against position p, whatever their angles), and nothing says
/// angle in the rows.
#[test]
fn a_file_without_angles_is_matched_by_index() {
    let (pa, pb) = (data("two-ac-24-no-angle.csv"), data("selfcal-168.csv"));
    let (fa, fb) = (
        read_result_file(&pa).unwrap(),
        read_result_file(&pb).unwrap(),
    );
    assert!(fa.rows.iter().all(|r| r.angle_deg.is_none()));
    // The first file gives U without k or u: the vector's test refuses it at its first
    // row in the verdict, by file and line; the per-row rule takes it.
    let e = compare_files(&fa, &fb, &CompareOptions::default()).unwrap_err();
    assert_eq!(
        e.to_string(),
        format!(
            "{}:51: encoder_error 0 has U but no standard uncertainty (neither u nor k): the \
             verdict's vector test needs u, or U with its coverage factor k (columns u, k)",
            pa.display()
        )
    );
    for (x, y) in [(&fa, &fb), (&fb, &fa)] {
        let c = compare_files(x, y, &en_rule()).unwrap();
        assert_eq!(c.encoder_matched_by, EncoderMatching::Index);
        assert_eq!(c.rows.len(), 24);
        assert!(
            c.rows
                .iter()
                .all(|r| r.index_b.is_none() && r.angle_deg.is_none())
        );
        assert!(
            c.only_in_a
                .iter()
                .chain(&c.only_in_b)
                .all(|u| u.angle_deg.is_none())
        );
        let json = serde_json::to_value(&c).unwrap();
        assert_eq!(json["encoder_matched_by"], "index");
        assert!(json["rows"][0].get("angle_deg").is_none());
        assert!(json["rows"][0].get("index_b").is_none());
    }
    let c = compare_files(&fa, &fb, &en_rule()).unwrap();
    let (ea, eb) = (encoder_rows(&pa), encoder_rows(&pb));
    for row in &c.rows {
        let (a, ua, _) = ea[&row.index];
        let (b, ub, _) = eb[&row.index];
        assert!((row.en - (a - b) / (ua * ua + ub * ub).sqrt()).abs() < 1e-12);
    }
    // By hand: position 1 is 0.01 against 5 (the self-calibration at 2.14°): En = −9.98.
    assert!((c.rows[1].en + 9.98).abs() < 1e-12, "{}", c.rows[1].en);
    // position 0 is 0 against −0.1, as by angle
    assert!((c.rows[0].en - 0.2).abs() < 1e-12);
    let mut table = String::new();
    polycal::output::compare::write_table(&mut table, &c).unwrap();
    assert!(
        table.contains(
            "Encoder errors matched by index (angle_deg is not in both results): 24 shared indices of 24 and 168"
        ),
        "{table}"
    );
    assert!(!table.contains("Angle °"), "{table}");
}

/// Setup errors are listed but left out of the verdict and of max_abs_en; with
/// `with_include_setup(true)` they count. Here only setup error 2 has |En| > 1:
/// (1.3 − 0.2)/√(0.6² + 0.8²) = 1.1; the largest other is pitch 1, 0.2/0.5 = 0.4.
#[test]
fn setup_errors_are_left_out_of_the_verdict_unless_included() {
    let (fa, fb) = (
        read_result_file(data("setup-a.csv")).unwrap(),
        read_result_file(data("setup-b.csv")).unwrap(),
    );
    let c = compare_files(&fa, &fb, &CompareOptions::default()).unwrap();
    assert_eq!(c.rows.len(), 6, "setup errors are listed");
    let setup: Vec<_> = c
        .rows
        .iter()
        .filter(|r| r.quantity == Quantity::SetupError)
        .collect();
    assert_eq!(setup.len(), 2);
    assert!(setup.iter().all(|r| !r.in_verdict));
    assert!((setup[1].en - 1.1).abs() < 1e-12, "{}", setup[1].en);
    assert!(
        c.rows
            .iter()
            .filter(|r| r.quantity != Quantity::SetupError)
            .all(|r| r.in_verdict)
    );
    assert!((c.max_abs_en - 0.4).abs() < 1e-12, "{}", c.max_abs_en);
    assert!(c.verdict_ok());
    let json = serde_json::to_value(&c).unwrap();
    assert_eq!(json["rows"][4]["quantity"], "setup_error");
    assert_eq!(json["rows"][4]["in_verdict"], false);
    assert_eq!(json["rows"][0]["in_verdict"], true);
    let mut table = String::new();
    polycal::output::compare::write_table(&mut table, &c).unwrap();
    assert!(table.contains("(1.10)"), "{table}");
    assert!(!table.contains("1.10 *"), "{table}");
    assert!(table.contains("left out of the verdict"), "{table}");
    assert!(table.contains("Largest |En| = 0.40\n"), "{table}");
    // The vector by hand (u = U/2, each family closed over its 2 rows, c = 2): pitch
    // d = ±0.2, encoder d = ±0.1, v = 2·(0.15² + 0.2²) = 0.125; χ² = 2·0.2²/v + 2·0.1²/v
    // = 0.64 + 0.16 = 0.8, ν = 2.
    let vector = c.vector.as_ref().unwrap();
    assert!((vector.chi2 - 0.8).abs() < 1e-12, "{}", vector.chi2);
    assert_eq!(vector.dof, 2);
    assert!(
        table.contains("Verdict: consistent: χ² = 0.80 ≤ χ²_0.95(2) = 5.99"),
        "{table}"
    );

    let included = CompareOptions::new().with_include_setup(true);
    let c = compare_files(&fa, &fb, &included).unwrap();
    assert!(c.rows.iter().all(|r| r.in_verdict));
    assert!((c.max_abs_en - 1.1).abs() < 1e-12);
    // Setup errors as independent rows: d = 0.3, 1.1 with v = 0.3² + 0.4² = 0.25, so
    // χ² = 0.8 + (0.09 + 1.21)/0.25 = 6.0 with ν = 4: consistent (χ²_0.95(4) = 9.49), though
    // setup error 2 has |En| = 1.1, which the per-row rule fails.
    let vector = c.vector.as_ref().unwrap();
    assert!((vector.chi2 - 6.0).abs() < 1e-12, "{}", vector.chi2);
    assert_eq!(vector.dof, 4);
    assert!(c.verdict_ok());
    assert!(
        !compare_files(&fa, &fb, &included.clone().with_verdict(VerdictRule::En))
            .unwrap()
            .verdict_ok()
    );
    let mut table = String::new();
    polycal::output::compare::write_table(&mut table, &c).unwrap();
    assert!(table.contains("1.10 *"), "{table}");
    assert!(table.contains("1 row of 6 with |En| > 1"), "{table}");
    assert!(!table.contains("left out of the verdict"), "{table}");

    // Only setup errors in common: nothing to judge unless they are included.
    let only_setup = |f: &polycal::results::ResultFile| -> Vec<ResultRow> {
        f.rows
            .iter()
            .filter(|r| r.quantity == Quantity::SetupError)
            .cloned()
            .collect()
    };
    let (sa, sb) = (only_setup(&fa), only_setup(&fb));
    let e = compare(&sa, &sb, &CompareOptions::default()).unwrap_err();
    assert!(matches!(e, CompareError::OnlySetupInCommon { .. }), "{e}");
    assert!(e.to_string().contains("only setup errors in common"), "{e}");
    assert!(compare(&sa, &sb, &included).unwrap().max_abs_en > 1.0);
}

/// Matching by angle within 1e-6° and not beyond; an angle within the tolerance of two
/// of the other result is refused rather than guessed; rows given as slices follow the
/// file's angle rules.
#[test]
fn angle_matching_tolerance_and_refusals() {
    let at = |index: u32, value: f64, angle: f64| {
        ResultRow::new(Quantity::EncoderError, index, value)
            .with_expanded_u(0.3)
            .with_angle_deg(angle)
    };
    let a = [at(0, 0.0, 0.0), at(1, 0.1, 90.0), at(2, 0.2, 180.0)];
    let b = [
        at(5, 0.0, 359.999_999_1), // 9e-7° from 0 across the wrap: matched
        at(6, 0.1, 90.000_002),    // 2e-6° from 90: not matched
        at(7, 0.2, 179.999_999_5), // 5e-7° from 180: matched
    ];
    let c = compare(&a, &b, &en_rule()).unwrap();
    let pairs: Vec<_> = c.rows.iter().map(|r| (r.index, r.index_b)).collect();
    assert_eq!(pairs, vec![(0, Some(5)), (2, Some(7))]);
    assert_eq!(c.only_in_a.len(), 1);
    assert_eq!(
        (c.only_in_a[0].index, c.only_in_a[0].angle_deg),
        (1, Some(90.0))
    );
    assert_eq!(c.only_in_b[0].index, 6);

    // 90° of the first is within 1e-6° of two angles of the second (1.6e-6° apart).
    let b2 = [at(8, 0.1, 89.999_999_2), at(9, 0.1, 90.000_000_8)];
    let e = compare(&a, &b2, &CompareOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            CompareError::AmbiguousAngle {
                index: 1,
                first: 8,
                second: 9,
                ..
            }
        ),
        "{e}"
    );
    assert!(
        e.to_string()
            .starts_with("A: encoder_error 1 at 90° is within 1e-6° of two encoder errors of B"),
        "{e}"
    );
    // And the other way round: two of the first near one of the second.
    let a2 = [at(1, 0.1, 89.999_999_2), at(2, 0.1, 90.000_000_8)];
    let b3 = [at(4, 0.1, 90.0)];
    let e = compare(&a2, &b3, &CompareOptions::default()).unwrap_err();
    assert!(
        matches!(e, CompareError::AmbiguousAngle { index: 4, .. }),
        "{e}"
    );
    assert!(
        e.to_string().starts_with("B: encoder_error 4 at 90°"),
        "{e}"
    );

    // Slices follow the rules of the file: all encoder errors with an angle or none.
    let mixed = [at(0, 0.0, 0.0), row("encoder_error", 1, 0.1, Some(0.3))];
    let e = compare(&mixed, &a, &CompareOptions::default()).unwrap_err();
    assert!(matches!(e, CompareError::Angle { .. }), "{e}");
    assert!(
        e.to_string().starts_with(
            "A (row 2): encoder_error 1 has no angle_deg, but encoder_error 0 on row 1 has one"
        ),
        "{e}"
    );
    let beyond = [at(0, 0.0, 360.0)];
    let e = compare(&beyond, &a, &CompareOptions::default()).unwrap_err();
    assert!(
        e.to_string().starts_with("A (row 1): angle_deg must be"),
        "{e}"
    );
    let on_pitch = [row("pitch_deviation", 1, 0.0, Some(0.3)).with_angle_deg(15.0)];
    let e = compare(&a, &on_pitch, &CompareOptions::default()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("B (row 1): angle_deg is given for pitch_deviation 1"),
        "{e}"
    );
}

/// Angles round-trip through the writer and the reader bit for bit, on encoder rows only;
/// the writer refuses what the reader would refuse.
#[test]
fn angles_round_trip_and_the_writer_refuses_what_cannot_be_read_back() {
    let rows = vec![
        row("pitch_deviation", 1, 0.1, Some(0.3)),
        row("encoder_error", 0, 0.2, Some(0.3)).with_angle_deg(0.0),
        row("encoder_error", 1, 0.3, Some(0.3)).with_angle_deg(360.0 / 168.0),
        row("encoder_error", 167, 0.4, Some(0.3)).with_angle_deg(167.0 * 360.0 / 168.0),
    ];
    let mut out = Vec::new();
    write_results(&mut out, &rows).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.contains("pitch_deviation,1,0.1,0.3,,,\n"), "{text}");
    assert!(
        text.contains("encoder_error,1,0.3,0.3,,,2.142857142857143\n"),
        "{text}"
    );
    let back = read_results_from(text.as_bytes(), "mem.csv").unwrap();
    assert_eq!(back.rows, rows);

    for (bad, want) in [
        (
            vec![row("encoder_error", 0, 0.0, None).with_angle_deg(f64::NAN)],
            "row 1: angle_deg must be",
        ),
        (
            vec![row("encoder_error", 0, 0.0, None).with_angle_deg(-1.0)],
            "row 1: angle_deg must be",
        ),
        (
            vec![row("setup_error", 1, 0.0, None).with_angle_deg(1.0)],
            "row 1: angle_deg is given for setup_error 1",
        ),
        (
            vec![
                row("encoder_error", 0, 0.0, None),
                row("encoder_error", 1, 0.0, None).with_angle_deg(15.0),
            ],
            "row 2: encoder_error 0 has no angle_deg, but encoder_error 1 on row 2 has one",
        ),
        (
            vec![
                row("encoder_error", 0, 0.0, None).with_angle_deg(15.0),
                row("encoder_error", 1, 0.0, None).with_angle_deg(15.000_000_5),
            ],
            "row 2: encoder_error 1 at angle_deg 15.0000005 is the position of encoder_error 0 on row 1",
        ),
    ] {
        let e = write_results(Vec::new(), &bad).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
        assert!(e.to_string().starts_with(want), "{e}\nwant: {want}");
    }
}

/// Each angle rule of the reader has its file, refused with file:line:column at the
/// angle_deg field and the column named.
#[test]
fn angle_rules_are_refused_with_file_line_and_column() {
    for (file, want) in [
        (
            "bad_angle_not_a_number.csv",
            ":4:25: column \"angle_deg\": \"fifteen\" is not a number",
        ),
        (
            "bad_angle_360.csv",
            ":3:17: column \"angle_deg\": \"360\" is outside 0 ≤ angle_deg < 360 degrees; write 0, not 360",
        ),
        (
            "bad_angle_negative.csv",
            ":4:26: column \"angle_deg\": \"-15\" is outside 0 ≤ angle_deg < 360 degrees",
        ),
        (
            "bad_angle_not_encoder.csv",
            ":4:27: angle_deg is given for pitch_deviation 1: only encoder_error rows carry a \
             table angle (leave the field empty)",
        ),
        (
            "bad_angle_duplicate.csv",
            ":5:25: encoder_error 2 at angle_deg 359.9999995 is the position of encoder_error 0 \
             on line 3 (angles within 1e-6° around the circle are one position)",
        ),
        (
            "bad_angle_missing.csv",
            ":5:25: encoder_error 1 has no angle_deg, but encoder_error 0 on line 3 has one: \
             either every encoder_error row carries its table angle or none does",
        ),
        (
            "bad_angle_missing_first.csv",
            ":3:15: encoder_error 0 has no angle_deg, but encoder_error 1 on line 5 has one",
        ),
        (
            "bad_angle_column_twice.csv",
            ":2:34: column \"angle_deg\" appears twice in the header (first at column 24)",
        ),
    ] {
        let path = data(file);
        let e = read_result_file(&path).unwrap_err();
        let location = e.location().expect("a location");
        let text = e.to_string();
        let want = format!("{}{want}", path.display());
        assert!(
            text.starts_with(&want),
            "{file}\n got: {text}\nwant: {want}"
        );
        assert!(text.contains("angle_deg"), "{text}");
        assert_eq!(
            format!(
                "{}:{}:{}",
                path.display(),
                location.line(),
                location.column()
            ),
            want.split(": ").next().unwrap(),
            "{file}"
        );
    }
}
