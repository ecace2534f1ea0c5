//! The result CSV (docs/FORMAT.md §3): written and read back at full precision, its
//! dialect (any column order, comments, extra columns, CRLF, a byte order mark), its
//! refusals at file, line and column, and the writer's refusal of what it could not read
//! back. Its `angle_deg` column is `tests/maths/compare_angles.rs`'s.

use polycal::results::{Quantity, ResultRow, read_results_from, read_results_path, write_results};

use crate::compare_support::{row, temp_file};

#[test]
fn results_round_trip_at_full_precision() {
    let rows = vec![
        ResultRow::new(Quantity::PitchDeviation, 1, 0.1 + 0.2)
            .with_u(0.228_673_894_443_594_07)
            .with_expanded_u(0.455_790_452_351_721_8)
            .with_k(1.993_189_705_631_875_3),
        row("face_deviation", 24, -1e-17, None),
        row("encoder_error", 0, 123_456.789_012_345_6, Some(5e-324)),
        row("setup_error", 2, -0.0, Some(0.0)),
    ];
    let mut out = Vec::new();
    write_results(&mut out, &rows).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert!(text.starts_with("quantity,index,value,U,u,k,angle_deg\n"));
    assert!(text.contains("pitch_deviation,1,0.30000000000000004,0.4557904523517218,0.22867389444359407,1.9931897056318753,\n"));
    assert!(text.contains("face_deviation,24,-0.00000000000000001,,,,\n"));
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
            ResultRow::new(Quantity::PitchDeviation, 1, 0.31)
                .with_expanded_u(0.15)
                .with_k(2.0),
            row("pitch_deviation", 2, -0.2, Some(0.15)),
        ]
    );
    assert_eq!(f.lines, vec![4, 5]);
}

/// The result file's dialect (docs/FORMAT.md §3.2): what other programs write is read as
/// it always was — spaces around fields and names trimmed, a comment line indented,
/// columns polycal does not know passed over whatever their names (near misses of known
/// names, empty names, names twice), a header without rows a result of nothing.
#[test]
fn results_keep_their_dialect() {
    let text = "  # exported\n quantity , index,value ,Value,K,,,note,note\n\
                pitch_deviation , +2 ,0.5 ,x,y,,,a,b\n\n\
                encoder_error,0, -0.25,,,,,,\n";
    let f = read_results_from(text.as_bytes(), "x.csv").unwrap();
    assert_eq!(
        f.rows,
        vec![
            row("pitch_deviation", 2, 0.5, None),
            row("encoder_error", 0, -0.25, None)
        ]
    );
    assert_eq!(f.lines, vec![3, 5]);
    // columns where the trimmed text starts
    assert_eq!(
        (
            f.columns[0].quantity,
            f.columns[0].index,
            f.columns[0].value
        ),
        (1, 19, 23)
    );
    assert_eq!(f.columns[1].value, 18);
    assert_eq!(f.columns[0].expanded_u, None);
    let empty = read_results_from(&b"# nothing yet\nquantity,index,value\n"[..], "x.csv");
    assert_eq!(empty.unwrap().rows, vec![]);
}

#[test]
fn results_accept_crlf_and_a_byte_order_mark() {
    let text = "\u{feff}quantity,index,value,U\r\nsetup_error,2,0.09,0.05\r\n";
    let f = read_results_from(text.as_bytes(), "win.csv").unwrap();
    assert_eq!(f.rows, vec![row("setup_error", 2, 0.09, Some(0.05))]);
    let bad = "\u{feff}quantity,index,value,U\r\nsetup_error,2,x,0.05\r\n";
    let e = read_results_from(bad.as_bytes(), "win.csv").unwrap_err();
    assert!(
        e.to_string()
            .starts_with("win.csv:2:15: column \"value\": \"x\" is not a number"),
        "{e}"
    );
}

#[test]
fn results_are_refused_with_file_line_and_column() {
    let header = "# comment\nquantity,index,value,U,u,k\n";
    for (body, want) in [
        (
            "pitch_deviaton,1,0.5,,,\n",
            "r.csv:3:1: column \"quantity\": \"pitch_deviaton\" is not a quantity; use \"pitch_deviation\" or",
        ),
        (
            "pitch_deviation,x,0.5,,,\n",
            "r.csv:3:17: column \"index\": \"x\" is not an integer",
        ),
        (
            "pitch_deviation,-1,0.5,,,\n",
            "r.csv:3:17: column \"index\": \"-1\" is not allowed; index must be at least 0",
        ),
        (
            "pitch_deviation,0,0.5,,,\n",
            "r.csv:3:17: column \"index\": 0 is not allowed for pitch_deviation: faces are numbered 1 … N",
        ),
        (
            "setup_error,0,0.5,,,\n",
            "r.csv:3:13: column \"index\": 0 is not allowed for setup_error: autocollimator numbers start at 1",
        ),
        (
            "encoder_error,0,abc,,,\n",
            "r.csv:3:17: column \"value\": \"abc\" is not a number",
        ),
        (
            "encoder_error,0,NaN,,,\n",
            "r.csv:3:17: column \"value\": \"NaN\" is not a finite number",
        ),
        (
            "encoder_error,0,inf,,,\n",
            "r.csv:3:17: column \"value\": \"inf\" is not a finite number",
        ),
        (
            "encoder_error,0,0.1,-0.46,,\n",
            "r.csv:3:21: column \"U\": \"-0.46\" is negative; an uncertainty is at least 0",
        ),
        (
            "encoder_error,0,0.1,0.46,0.23,0\n",
            "r.csv:3:31: column \"k\": \"0\" is beyond the limits of a result's k, 0.1 … 1e6 (docs/FORMAT.md §2.2)",
        ),
        (
            "encoder_error,0,0.1,0.46\n",
            "r.csv:3:25: row has 4 fields but the header has 6: no value for column \"u\"",
        ),
        (
            "encoder_error,0,0.1,0.46,,,7\n",
            "r.csv:3:28: row has 7 fields but the header has 6: extra field \"7\"",
        ),
        (
            "face_deviation,3,0.1,,,\nface_deviation,4,0.1,,,\nface_deviation,3,0.2,,,\n",
            "r.csv:5:1: face_deviation 3 appears twice (first on line 3)",
        ),
        (
            "\"pitch, deviation\",1,0.5,,,\n",
            "r.csv:3:1: column \"quantity\": \"pitch, deviation\" is not a quantity",
        ),
        (
            "\"pitch_deviation\",1,\"x,y\",,,\n",
            "r.csv:3:21: column \"value\": \"x,y\" is not a number",
        ),
        (
            "pitch_deviation,  1,  zz,,,\n",
            "r.csv:3:23: column \"value\": \"zz\" is not a number",
        ),
        // finite but absurd: beyond the documented limits (docs/FORMAT.md §2.2)
        (
            "pitch_deviation,1,-1e308,0.1,,\n",
            "r.csv:3:19: column \"value\": \"-1e308\" is beyond the limits of a result's value, −1e12 … 1e12″",
        ),
        (
            "face_deviation,2,0.5,1e13,,\n",
            "r.csv:3:22: column \"U\": \"1e13\" is beyond the limits of a result's U, −1e12 … 1e12″",
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
        (
            "",
            "r.csv:1:1: empty file: expected a header row naming the columns quantity, index, value",
        ),
        (
            "# only a comment\n",
            "r.csv:2:1: no header row: the file has only comment lines",
        ),
        (
            "quantity,value,U\npitch_deviation,1,0.1\n",
            "r.csv:1:1: missing required column \"index\"; the header has \"quantity\", \"value\", \"U\"",
        ),
        (
            "quantity,index,value,U,U\n",
            "r.csv:1:24: column \"U\" appears twice in the header (first at column 22)",
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
