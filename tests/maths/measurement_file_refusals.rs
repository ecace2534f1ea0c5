//! The measurement file (docs/FORMAT.md §2), refused: one bad file (or text) per rule,
//! each refusal at its file, line and column with the words that say what is wrong; I/O
//! errors name the file, and a long offending text is cut short.
//!
//! Every expected `file:line:column` below was counted by hand from the file text.

use polycal::input::FileError;
use polycal::measurement::MeasurementSet;

use crate::measurement_file_support::{assert_invalid, assert_refused, data, refused_bytes};

#[test]
fn refuses_an_empty_file() {
    assert_refused("bad_empty.csv", None, 1, 1, &["empty file"]);
    assert_invalid(&refused_bytes(b"", None), "mem.csv", 1, 1, &["empty file"]);
    assert_invalid(
        &refused_bytes(b"\n\n", None),
        "mem.csv",
        1,
        1,
        &["empty file"],
    );
}

#[test]
fn refuses_a_file_of_comments_only() {
    assert_refused("bad_only_comments.csv", None, 3, 1, &["no header row"]);
}

#[test]
fn refuses_a_header_without_data_rows() {
    assert_refused("bad_no_rows.csv", None, 2, 1, &["no data rows"]);
}

#[test]
fn refuses_a_missing_required_column() {
    assert_refused(
        "bad_missing_column.csv",
        None,
        2,
        1,
        &[
            "missing required column \"face\";",
            "\"cycle\", \"step\", \"ac\", \"reading\"",
        ],
    );
    let err = refused_bytes(b"cycle,ac,reading\n1,1,0.5\n", None);
    assert_invalid(
        &err,
        "mem.csv",
        1,
        1,
        &["missing required columns \"step\", \"face\""],
    );
}

#[test]
fn refuses_a_duplicated_column() {
    assert_refused(
        "bad_duplicate_column.csv",
        None,
        1,
        28,
        &["column \"step\" appears twice", "first at column 7"],
    );
}

#[test]
fn refuses_a_column_name_that_differs_from_a_known_one_only_by_case() {
    assert_refused(
        "bad_near_miss_column.csv",
        None,
        1,
        28,
        &["\"Temperature\"", "\"temperature\""],
    );
    let err = refused_bytes(b"cycle,step,ac, face,reading\n1,0,1,1,0.5\n", None);
    assert_invalid(&err, "mem.csv", 1, 15, &["\" face\"", "\"face\""]);
}

#[test]
fn refuses_a_row_with_too_many_fields() {
    assert_refused(
        "bad_too_many_fields.csv",
        None,
        3,
        14,
        &["row has 6 fields but the header has 5", "extra field \"7\""],
    );
}

#[test]
fn refuses_a_row_with_too_few_fields() {
    assert_refused(
        "bad_too_few_fields.csv",
        None,
        3,
        8,
        &[
            "row has 4 fields but the header has 5",
            "column \"reading\"",
        ],
    );
}

#[test]
fn refuses_a_non_integer() {
    assert_refused(
        "bad_non_integer.csv",
        None,
        3,
        1,
        &["column \"cycle\": \"1.5\" is not an integer"],
    );
}

#[test]
fn refuses_a_non_number() {
    assert_refused(
        "bad_non_number.csv",
        None,
        3,
        9,
        &["column \"reading\": \"0.2S\" is not a number"],
    );
}

#[test]
fn refuses_nan() {
    assert_refused(
        "bad_nan.csv",
        None,
        3,
        9,
        &["column \"reading\": \"NaN\" is not a finite number"],
    );
}

#[test]
fn refuses_infinity_in_an_optional_column() {
    assert_refused(
        "bad_infinite_time.csv",
        None,
        3,
        14,
        &["column \"time\": \"inf\" is not a finite number"],
    );
    // Too large for a double is infinite too.
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,0,1,1,1e999\n", None);
    assert_invalid(&err, "mem.csv", 2, 9, &["\"1e999\" is not a finite number"]);
}

#[test]
fn refuses_ac_zero() {
    assert_refused(
        "bad_ac_zero.csv",
        None,
        3,
        5,
        &["column \"ac\": \"0\" is not allowed; ac must be at least 1"],
    );
}

#[test]
fn refuses_a_negative_setup() {
    assert_refused(
        "bad_setup_negative.csv",
        None,
        4,
        1,
        &["column \"setup\": \"-1\" is not allowed; setup must be at least 1"],
    );
}

#[test]
fn refuses_cycle_zero() {
    assert_refused(
        "bad_cycle_zero.csv",
        None,
        2,
        1,
        &["column \"cycle\": \"0\" is not allowed"],
    );
}

#[test]
fn refuses_face_zero() {
    assert_refused(
        "bad_face_zero.csv",
        None,
        2,
        7,
        &["column \"face\": \"0\" is not allowed; face must be at least 1"],
    );
}

#[test]
fn refuses_empty_required_fields_and_huge_integers() {
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,,1,1,0.5\n", None);
    assert_invalid(&err, "mem.csv", 2, 3, &["column \"step\": empty"]);
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,0,1,1,\n", None);
    assert_invalid(&err, "mem.csv", 2, 9, &["column \"reading\": empty"]);
    let err = refused_bytes(b"cycle,step,ac,face,reading\n4294967296,0,1,1,0.5\n", None);
    assert_invalid(&err, "mem.csv", 2, 1, &["\"4294967296\" is too large"]);
    let huge = format!("cycle,step,ac,face,reading\n1,0,1,{},0.5\n", "9".repeat(60));
    let err = refused_bytes(huge.as_bytes(), None);
    assert_invalid(&err, "mem.csv", 2, 7, &["column \"face\"", "is too large"]);
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,-1,1,1,0.5\n", None);
    assert_invalid(
        &err,
        "mem.csv",
        2,
        3,
        &["column \"step\": \"-1\" is not allowed"],
    );
    // Whitespace is not trimmed: a number with a space is not a number.
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,0,1,1, 0.5\n", None);
    assert_invalid(&err, "mem.csv", 2, 9, &["\" 0.5\" is not a number"]);
}

#[test]
fn refuses_an_unknown_direction() {
    assert_refused(
        "bad_direction.csv",
        None,
        3,
        14,
        &["column \"direction\": \"CW\" is not a direction"],
    );
}

#[test]
fn refuses_a_face_beyond_the_faces_given() {
    assert_refused(
        "bad_face_out_of_range.csv",
        Some(4),
        6,
        7,
        &[
            "column \"face\": 5 is outside 1 to 4",
            "the number of faces stated",
        ],
    );
}

#[test]
fn refuses_a_step_beyond_n() {
    assert_refused(
        "bad_step_out_of_range.csv",
        None,
        6,
        3,
        &["column \"step\": 5 is outside 0 to 4", "largest face"],
    );
}

#[test]
fn refuses_fewer_than_three_faces() {
    assert_refused(
        "bad_two_faces.csv",
        None,
        3,
        7,
        &["column \"face\"", "largest face is 2", "at least 3 faces"],
    );
    // --faces 2: pointed at the header's face column ("note,reading," is 13 characters).
    assert_refused(
        "good_4faces.csv",
        Some(2),
        4,
        14,
        &["2 were stated", "at least 3 faces"],
    );
}

#[test]
fn refuses_a_face_never_read() {
    assert_refused(
        "bad_missing_face.csv",
        None,
        2,
        15,
        &["column \"face\": face 4 is never read", "1 to 5"],
    );
    // Faces given beyond those read ("cycle,step,ac," is 14 characters).
    assert_refused(
        "bad_face_out_of_range.csv",
        Some(7),
        1,
        15,
        &[
            "column \"face\": faces 6-7 are never read",
            "N = 7, the number of faces stated",
        ],
    );
    // With a wrong --faces, ac 2 (which wraps from face 4 to face 1) no longer fits
    // one offset: line 12 is ",2,1,2,cw,3,91.5,1,20.1", its face at column 4.
    assert_refused(
        "good_4faces.csv",
        Some(7),
        12,
        4,
        &[
            "face 1 at step 3",
            "face 5 was expected",
            "line 6 set the offset",
        ],
    );
}

#[test]
fn refuses_a_step_never_present() {
    assert_refused(
        "bad_missing_step.csv",
        None,
        1,
        23,
        &["column \"step\": step 2 is never present", "0 to 3"],
    );
}

#[test]
fn refuses_a_duplicate_reading() {
    assert_refused(
        "bad_duplicate_reading.csv",
        None,
        5,
        1,
        &[
            "duplicate reading",
            "setup 1, cycle 1, step 1, ac 1",
            "already read at line 3",
        ],
    );
}

#[test]
fn refuses_a_face_inconsistent_with_the_step() {
    assert_refused(
        "bad_inconsistent_face.csv",
        None,
        5,
        7,
        &[
            "column \"face\": face 4 at step 1",
            "setup 1, ac 2",
            "face 3 was expected",
            "line 3 set the offset",
            "mod 4 = 1",
        ],
    );
}

#[test]
fn refuses_a_cycle_with_two_directions() {
    assert_refused(
        "bad_mixed_direction.csv",
        None,
        6,
        14,
        &[
            "column \"direction\"",
            "\"\" (empty, meaning cw) disagrees with \"ccw\"",
            "setup 1, cycle 2 at line 5",
        ],
    );
}

#[test]
fn refuses_bytes_that_are_not_utf8() {
    // Line 3 is "1,1,1,\xff2,0.25": the bad byte starts column 7.
    let err = refused_bytes(
        b"cycle,step,ac,face,reading\n1,0,1,1,0.5\n1,1,1,\xff2,0.25\n",
        None,
    );
    assert_invalid(&err, "mem.csv", 3, 7, &["not valid UTF-8", "0xff"]);
    // In a comment after a two-byte character: "# café " is 7 characters.
    let err = refused_bytes(b"# caf\xc3\xa9 \xff\ncycle\n", None);
    assert_invalid(&err, "mem.csv", 1, 8, &["not valid UTF-8"]);
    // A character cut off at the end.
    let err = refused_bytes(b"cycle,step,ac,face,reading\n1,0,1,1,\xc3", None);
    assert_invalid(&err, "mem.csv", 2, 9, &["not valid UTF-8"]);
}

#[test]
fn a_comment_after_the_header_is_not_a_comment() {
    let err = refused_bytes(
        b"cycle,step,ac,face,reading\n# late comment\n1,0,1,1,0.5\n",
        None,
    );
    // "# late comment" is 14 characters: the missing fields would start at column 15.
    assert_invalid(
        &err,
        "mem.csv",
        2,
        15,
        &["row has 1 field but the header has 5"],
    );
}

#[test]
fn io_errors_name_the_file() {
    let path = data("no_such_file.csv");
    let err = MeasurementSet::read_path(&path, None).unwrap_err();
    assert!(matches!(err, FileError::Io { .. }), "{err}");
    assert!(
        err.to_string()
            .starts_with(&format!("{}: ", path.display()))
    );

    struct Broken;
    impl std::io::Read for Broken {
        fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("cable unplugged"))
        }
    }
    let err = MeasurementSet::read_from(Broken, "port", None).unwrap_err();
    assert_eq!(err.to_string(), "port: cable unplugged");
}

#[test]
fn long_offending_text_is_cut_short() {
    let text = format!("cycle,step,ac,face,reading\n1,0,1,1,{}\n", "x".repeat(1000));
    let err = refused_bytes(text.as_bytes(), None);
    let message = err.to_string();
    assert!(message.len() < 200, "{message}");
    assert!(
        message.contains("...") && message.contains("not a number"),
        "{message}"
    );
}
