//! The measurement file (docs/FORMAT.md §2): reading, refusing, writing, round trips.
//!
//! Every expected `file:line:column` below was counted by hand from the file text.

use std::path::{Path, PathBuf};

use polycal::input::FileError;
use polycal::measurement::{Direction, MeasurementSet, Reading};
use proptest::prelude::*;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/measurement")
        .join(name)
}

/// Reads a good file from tests/data/measurement.
fn read_good(name: &str, faces: Option<usize>) -> MeasurementSet {
    match MeasurementSet::read_path(&data(name), faces) {
        Ok(set) => set,
        Err(e) => panic!("{name} should read: {e}"),
    }
}

/// The error `MeasurementSet::read_path` gives for a bad file.
fn refusal(name: &str, faces: Option<usize>) -> FileError {
    match MeasurementSet::read_path(&data(name), faces) {
        Ok(set) => panic!(
            "{name} should be refused, read {} readings",
            set.readings.len()
        ),
        Err(e) => e,
    }
}

/// Asserts that `err` is `Invalid` at `file:line:column` and its message holds `words`.
fn assert_invalid(err: &FileError, file: &str, line: u64, column: u64, words: &[&str]) {
    let text = err.to_string();
    let FileError::Invalid { location, message } = err else {
        panic!("expected Invalid, got {text}");
    };
    assert_eq!(
        (location.file(), location.line(), location.column()),
        (file, line, column),
        "wrong location in: {text}"
    );
    assert_eq!(err.location(), Some(location));
    assert!(
        text.starts_with(&format!("{location}: ")),
        "bad prefix: {text}"
    );
    assert!(!message.contains('\n'), "message is not one line: {text}");
    for word in words {
        assert!(text.contains(word), "{word:?} not in: {text}");
    }
}

/// Asserts that bad file `name` is refused at `line:column` with `words` in the message.
fn assert_refused(name: &str, faces: Option<usize>, line: u64, column: u64, words: &[&str]) {
    let err = refusal(name, faces);
    let file = data(name).display().to_string();
    assert_invalid(&err, &file, line, column, words);
}

fn read_bytes(bytes: &[u8], faces: Option<usize>) -> Result<MeasurementSet, FileError> {
    MeasurementSet::read_from(bytes, "mem.csv", faces)
}

fn refused_bytes(bytes: &[u8], faces: Option<usize>) -> FileError {
    match read_bytes(bytes, faces) {
        Ok(set) => panic!("should be refused, read {} readings", set.readings.len()),
        Err(e) => e,
    }
}

/// The readings with `line` cleared, to compare sets apart from where they came from.
fn without_lines(readings: &[Reading]) -> Vec<Reading> {
    readings
        .iter()
        .map(|r| Reading {
            line: 0,
            ..r.clone()
        })
        .collect()
}

fn reading(cycle: u32, step: usize, ac: u32, face: usize, value: f64) -> Reading {
    Reading {
        setup: 1,
        cycle,
        step,
        ac,
        face,
        reading_arcsec: value,
        direction: Direction::Cw,
        time_seconds: None,
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line: 0,
    }
}

/// One cycle on an N-faced polygon, one autocollimator reading face p+1 at step p.
fn one_cycle(n: usize) -> Vec<Reading> {
    (0..n)
        .map(|p| reading(1, p, 1, p + 1, p as f64 * 0.25))
        .collect()
}

// ---------------------------------------------------------------------------------------
// Good files

#[test]
fn good_file_reads_with_the_right_values() {
    let set = read_good("good_4faces.csv", None);
    assert_eq!(set.faces, 4);
    assert_eq!(set.source, data("good_4faces.csv").display().to_string());
    assert_eq!(set.readings.len(), 20);

    // Line 5: start,0.5,1,1,cw,0,0,1,20.0
    let first = &set.readings[0];
    assert_eq!(
        *first,
        Reading {
            setup: 1,
            cycle: 1,
            step: 0,
            ac: 1,
            face: 1,
            reading_arcsec: 0.5,
            direction: Direction::Cw,
            time_seconds: Some(0.0),
            reading_y_arcsec: None,
            temperature_celsius: Some(20.0),
            encoder_degrees: None,
            line: 5,
        }
    );
    // Line 7: ,0.25,2,1,cw,1,30,1,   (empty temperature)
    let r = &set.readings[2];
    assert_eq!((r.line, r.cycle, r.step, r.ac, r.face), (7, 1, 1, 1, 2));
    assert_eq!(r.reading_arcsec, 0.25);
    assert_eq!(r.time_seconds, Some(30.0));
    assert_eq!(r.temperature_celsius, None);
    // Line 9 has a quoted note with a comma inside.
    let r = &set.readings[4];
    assert_eq!((r.line, r.step, r.face, r.reading_arcsec), (9, 2, 3, -0.5));
    // Line 12: ,2,1,2,cw,3,91.5,1,20.1 (ac 2 wraps to face 1)
    let r = &set.readings[7];
    assert_eq!(
        (r.line, r.step, r.ac, r.face, r.reading_arcsec),
        (12, 3, 2, 1, 2.0)
    );
    // Line 14 is the closing reading of ac 2; line 15 is blank.
    assert_eq!(set.readings[9].line, 14);
    assert_eq!(set.readings[9].step, 4);
    // Line 16 starts cycle 2, counter-clockwise, from the closing step.
    let r = &set.readings[10];
    assert_eq!((r.line, r.cycle, r.step, r.face), (16, 2, 4, 1));
    assert_eq!(r.direction, Direction::Ccw);
    assert_eq!(r.reading_arcsec, 0.625);
    // Line 25, the last.
    let r = &set.readings[19];
    assert_eq!((r.line, r.cycle, r.step, r.ac, r.face), (25, 2, 0, 2, 2));
    assert_eq!(r.time_seconds, Some(321.5));
    assert_eq!(r.temperature_celsius, Some(20.3));

    assert!(set.readings.iter().all(|r| r.setup == 1));
    assert_eq!(
        set.readings
            .iter()
            .filter(|r| r.direction == Direction::Ccw)
            .count(),
        10
    );
    assert_eq!(set.streams(), vec![(1, 1), (1, 2)]);
    assert_eq!(set.face_offsets(), vec![((1, 1), 0), ((1, 2), 1)]);
}

#[test]
fn good_file_with_faces_given() {
    let set = read_good("good_4faces.csv", Some(4));
    assert_eq!(set.faces, 4);
}

#[test]
fn good_file_with_setups_crlf_and_byte_order_mark() {
    let set = read_good("good_setups_crlf.csv", None);
    assert_eq!(set.faces, 4);
    assert_eq!(set.readings.len(), 8);
    let r = &set.readings[0];
    assert_eq!((r.line, r.setup, r.direction), (3, 1, Direction::Cw));
    assert_eq!(r.reading_y_arcsec, Some(-1.5));
    assert_eq!(r.encoder_degrees, Some(0.0));
    let r = &set.readings[1];
    assert_eq!(r.reading_y_arcsec, None);
    assert_eq!(r.encoder_degrees, Some(90.0001));
    let r = &set.readings[4];
    assert_eq!((r.line, r.setup, r.face), (7, 2, 2));
    assert_eq!(r.direction, Direction::Ccw);
    assert_eq!(r.reading_y_arcsec, Some(1e-3));
    assert_eq!(set.readings[5].reading_y_arcsec, Some(2e-3));
    assert_eq!(set.readings[7].line, 10);
    assert_eq!(set.streams(), vec![(1, 1), (2, 1)]);
    assert_eq!(set.face_offsets(), vec![((1, 1), 0), ((2, 1), 1)]);
}

#[test]
fn a_face_beyond_the_others_sets_n_when_faces_is_not_given() {
    // With --faces 4 this file is refused (face 5); without, N is 5 and it is complete.
    let set = read_good("bad_face_out_of_range.csv", None);
    assert_eq!(set.faces, 5);
}

#[test]
fn blank_lines_of_spaces_and_quoted_line_breaks_keep_line_numbers() {
    let text = "note,cycle,step,ac,face,reading\n\
                ,1,0,1,1,0.5\n   \n\
                \"two\nlines\",1,1,1,2,0.25\n\
                ,1,2,1,3,-0.5\n";
    let set = read_bytes(text.as_bytes(), None).unwrap();
    let lines: Vec<u64> = set.readings.iter().map(|r| r.line).collect();
    assert_eq!(lines, vec![2, 4, 6]);

    // A field after a quoted line break is located on its own line.
    let text = "note,cycle,step,ac,face,reading\n\"two\nlines\",1,0,1,x,0.5\n";
    let err = refused_bytes(text.as_bytes(), None);
    assert_invalid(
        &err,
        "mem.csv",
        3,
        14,
        &["column \"face\"", "\"x\"", "not an integer"],
    );
}

#[test]
fn columns_are_counted_in_characters_not_bytes() {
    // "é" is two bytes in UTF-8 but one character.
    let text = "note,cycle,step,ac,face,reading\nété,1,0,1,1,zéro\n";
    let err = refused_bytes(text.as_bytes(), None);
    // "été,1,0,1,1," is 12 characters: the reading starts at column 13.
    assert_invalid(
        &err,
        "mem.csv",
        2,
        13,
        &["column \"reading\"", "\"zéro\"", "not a number"],
    );
}

#[test]
fn read_from_reads_standard_input_style_readers() {
    let text = "cycle,step,ac,face,reading\n1,0,1,1,0.5\n1,1,1,2,0.25\n1,2,1,3,-0.5\n";
    let set = MeasurementSet::read_from(std::io::Cursor::new(text), "-", None).unwrap();
    assert_eq!(set.source, "-");
    assert_eq!(set.faces, 3);
    assert_eq!(set.readings[2].reading_arcsec, -0.5);
}

// ---------------------------------------------------------------------------------------
// Refusals, one file each

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

// ---------------------------------------------------------------------------------------
// Readings built in memory

#[test]
fn from_readings_accepts_a_good_design_and_keeps_the_order() {
    let mut readings = Vec::new();
    for cycle in 1..=2 {
        for p in 0..=5 {
            for (ac, d) in [(1, 0), (2, 1)] {
                readings.push(reading(cycle, p, ac, (p + d) % 5 + 1, 0.1 * p as f64));
            }
        }
    }
    let set = MeasurementSet::from_readings(readings.clone(), None, "sim").unwrap();
    assert_eq!(set.faces, 5);
    assert_eq!(set.source, "sim");
    assert_eq!(set.readings, readings);
    assert_eq!(set.face_offsets(), vec![((1, 1), 0), ((1, 2), 1)]);
}

#[test]
fn from_readings_refuses_with_line_zero_and_the_reading_number() {
    let sim = |readings: Vec<Reading>, faces| {
        MeasurementSet::from_readings(readings, faces, "sim").unwrap_err()
    };

    let err = sim(Vec::new(), None);
    assert_invalid(&err, "sim", 0, 0, &["no readings"]);

    let mut r = one_cycle(4);
    r[2].cycle = 0;
    let err = sim(r, None);
    assert_invalid(
        &err,
        "sim",
        0,
        0,
        &["reading 3: column \"cycle\": 0 is not allowed"],
    );

    let mut r = one_cycle(4);
    r[1].reading_arcsec = f64::NAN;
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &["reading 2: column \"reading\": NaN"],
    );

    let mut r = one_cycle(4);
    r[3].encoder_degrees = Some(f64::NEG_INFINITY);
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &["column \"encoder\": -inf is not a finite"],
    );

    let mut r = one_cycle(4);
    r[3].setup = 0;
    assert_invalid(&sim(r, None), "sim", 0, 0, &["column \"setup\": 0"]);

    assert_invalid(
        &sim(one_cycle(4), Some(3)),
        "sim",
        0,
        0,
        &["reading 4: column \"face\": 4 is outside 1 to 3"],
    );
    assert_invalid(&sim(one_cycle(2), None), "sim", 0, 0, &["at least 3 faces"]);
    assert_invalid(&sim(one_cycle(4), Some(1)), "sim", 0, 0, &["1 were stated"]);

    let mut r = one_cycle(4);
    r.push(reading(1, 1, 1, 2, 0.0));
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &["reading 5: duplicate reading", "at reading 2"],
    );

    let mut r = one_cycle(4);
    r[2].face = 4;
    r[3].face = 3;
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &[
            "reading 3: column \"face\"",
            "face 3 was expected",
            "reading 1 set",
        ],
    );

    let mut r = one_cycle(4);
    r[3].direction = Direction::Ccw;
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &["reading 4: column \"direction\": \"ccw\" disagrees with \"cw\""],
    );

    let mut r = one_cycle(4);
    r.pop();
    r.push(reading(1, 4, 1, 1, 0.0));
    // Faces 1-3 read with N = 3 would pass; with --faces 4 face 4 is missing.
    assert_invalid(&sim(r, Some(4)), "sim", 0, 0, &["face 4 is never read"]);

    let mut r = one_cycle(4);
    r[2].step = 6;
    assert_invalid(
        &sim(r, None),
        "sim",
        0,
        0,
        &["column \"step\": 6 is outside 0 to 4"],
    );

    // A reading that came from a file keeps its line, and no "reading K" is added.
    let mut r = one_cycle(4);
    r[2].cycle = 0;
    r[2].line = 17;
    let err = sim(r, None);
    assert_invalid(&err, "sim", 17, 0, &["column \"cycle\""]);
    assert!(!err.to_string().contains("reading 3"), "{err}");
}

#[test]
fn huge_faces_given_do_not_allocate_or_overflow() {
    let err = MeasurementSet::from_readings(one_cycle(4), Some(usize::MAX), "sim").unwrap_err();
    assert_invalid(
        &err,
        "sim",
        0,
        0,
        &[&format!("faces 5-{} are never read", usize::MAX)],
    );
}

// ---------------------------------------------------------------------------------------
// Writing and round trips

#[test]
fn writes_the_documented_header_and_rows() {
    let mut readings = one_cycle(3);
    readings[0].time_seconds = Some(1.5);
    readings[2].direction = Direction::Cw;
    readings[1].encoder_degrees = Some(120.0);
    let set = MeasurementSet::from_readings(readings, None, "sim").unwrap();
    let mut out = Vec::new();
    set.write_to(
        &mut out,
        &[
            "simulated".to_string(),
            "two\nlines".to_string(),
            String::new(),
        ],
    )
    .unwrap();
    let expected = "# simulated\n# two\n# lines\n#\n\
                    cycle,step,ac,face,reading,direction,setup,time,encoder\n\
                    1,0,1,1,0,cw,1,1.5,\n\
                    1,1,1,2,0.25,cw,1,,120\n\
                    1,2,1,3,0.5,cw,1,,\n";
    assert_eq!(String::from_utf8(out).unwrap(), expected);
}

fn assert_same_set(a: &MeasurementSet, b: &MeasurementSet) {
    assert_eq!(a.faces, b.faces);
    assert_eq!(without_lines(&a.readings), without_lines(&b.readings));
    // Bit for bit, so that -0 stays -0.
    let bits = |s: &MeasurementSet| -> Vec<[Option<u64>; 5]> {
        s.readings
            .iter()
            .map(|r| {
                [
                    Some(r.reading_arcsec.to_bits()),
                    r.time_seconds.map(f64::to_bits),
                    r.reading_y_arcsec.map(f64::to_bits),
                    r.temperature_celsius.map(f64::to_bits),
                    r.encoder_degrees.map(f64::to_bits),
                ]
            })
            .collect()
    };
    assert_eq!(bits(a), bits(b));
}

fn round_trip(set: &MeasurementSet) -> MeasurementSet {
    let mut out = Vec::new();
    set.write_to(&mut out, &["round trip".to_string()]).unwrap();
    match MeasurementSet::read_from(&out[..], "written", None) {
        Ok(back) => back,
        Err(e) => panic!("{e}\n{}", String::from_utf8_lossy(&out)),
    }
}

#[test]
fn good_files_round_trip() {
    for name in ["good_4faces.csv", "good_setups_crlf.csv"] {
        let set = read_good(name, None);
        let back = round_trip(&set);
        assert_same_set(&set, &back);
        // Lines of the written file: comment on line 1, header on line 2.
        assert_eq!(back.readings[0].line, 3);
    }
}

#[test]
fn write_path_and_read_path_round_trip() {
    let set = read_good("good_setups_crlf.csv", None);
    let dir = std::env::temp_dir().join(format!("polycal-measurement-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("written.csv");
    set.write_path(&path, &[]).unwrap();
    let back = MeasurementSet::read_path(&path, None).unwrap();
    assert_same_set(&set, &back);
    assert_eq!(back.readings[0].line, 2);
    std::fs::remove_dir_all(&dir).unwrap();

    let err = set
        .write_path(&dir.join("no/such/dir.csv"), &[])
        .unwrap_err();
    assert!(matches!(err, FileError::Io { .. }), "{err}");
}

#[test]
fn extreme_floats_round_trip() {
    let values = [
        0.0,
        -0.0,
        f64::MIN_POSITIVE,
        5e-324,
        // the limits of a reading (docs/FORMAT.md §2.2), the widest values a file holds
        1e6,
        -1e6,
        999_999.999_999_999_9,
        0.1 + 0.2,
        1.0 / 3.0,
        -123456.789e-10,
    ];
    let readings: Vec<Reading> = values
        .iter()
        .enumerate()
        .map(|(p, &x)| Reading {
            time_seconds: Some(-x),
            reading_y_arcsec: Some(x),
            ..reading(1, p, 1, p + 1, x)
        })
        .collect();
    let set = MeasurementSet::from_readings(readings, None, "sim").unwrap();
    assert_same_set(&set, &round_trip(&set));
}

/// Finite values of every kind (normal with any mantissa, subnormal, ±0) within the
/// limits of every numeric column (docs/FORMAT.md §2.2: a temperature is at least
/// −273.15 °C), which a file round-trips exactly.
fn finite() -> impl Strategy<Value = f64> {
    (prop::num::f64::POSITIVE
        | prop::num::f64::NEGATIVE
        | prop::num::f64::NORMAL
        | prop::num::f64::SUBNORMAL
        | prop::num::f64::ZERO)
        .prop_map(|x| x % 273.0)
}

type Values = (f64, Option<f64>, Option<f64>, Option<f64>, Option<f64>);

/// A valid random set: N faces, some autocollimators at random offsets, one or two
/// setups, one or two cycles of random direction, perhaps a closing step, random
/// finite values, shuffled rows.
fn valid_set() -> impl Strategy<Value = MeasurementSet> {
    (
        3usize..8,
        prop::collection::vec(0usize..8, 1..4),
        1u32..3,
        1u32..3,
        any::<bool>(),
        prop::collection::vec(any::<bool>(), 4),
    )
        .prop_flat_map(|(n, offsets, setups, cycles, closing, ccw)| {
            let steps = if closing { n + 1 } else { n };
            let count = steps * offsets.len() * (setups * cycles) as usize;
            let values = prop::collection::vec(
                (
                    finite(),
                    prop::option::of(finite()),
                    prop::option::of(finite()),
                    prop::option::of(finite()),
                    prop::option::of(finite()),
                ),
                count,
            );
            let mut shape = Vec::with_capacity(count);
            for setup in 1..=setups {
                for cycle in 1..=cycles {
                    let direction = if ccw[((setup - 1) * 2 + cycle - 1) as usize] {
                        Direction::Ccw
                    } else {
                        Direction::Cw
                    };
                    for step in 0..steps {
                        for (k, d) in offsets.iter().enumerate() {
                            let face = (step + d + setup as usize) % n + 1;
                            shape.push((setup, cycle, step, k as u32 + 1, face, direction));
                        }
                    }
                }
            }
            (Just(n), Just(shape), values).prop_flat_map(|(n, shape, values)| {
                let readings: Vec<Reading> = shape
                    .into_iter()
                    .zip(values)
                    .map(
                        |((setup, cycle, step, ac, face, direction), v): (_, Values)| Reading {
                            setup,
                            cycle,
                            step,
                            ac,
                            face,
                            reading_arcsec: v.0,
                            direction,
                            time_seconds: v.1,
                            reading_y_arcsec: v.2,
                            temperature_celsius: v.3,
                            encoder_degrees: v.4,
                            line: 0,
                        },
                    )
                    .collect();
                (Just(n), Just(readings).prop_shuffle())
            })
        })
        .prop_map(|(n, readings)| {
            let set = MeasurementSet::from_readings(readings, None, "proptest")
                .unwrap_or_else(|e| panic!("generated set refused: {e}"));
            assert_eq!(set.faces, n);
            set
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_sets_round_trip(set in valid_set()) {
        let back = round_trip(&set);
        assert_same_set(&set, &back);
    }

    #[test]
    fn random_shifts_round_trip(
        set in valid_set(),
        shifts in prop::collection::vec(prop_oneof![Just(0.0), 0.0..360.0f64], 2),
    ) {
        let setups = set.readings.iter().map(|r| r.setup).max().unwrap_or(1);
        let set = set.with_setup_shifts((1..=setups).zip(shifts)).unwrap();
        let back = round_trip(&set);
        assert_same_set(&set, &back);
        prop_assert_eq!(&back.setup_shift_deg, &set.setup_shift_deg);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        let _ = read_bytes(&bytes, None);
        let _ = read_bytes(&bytes, Some(3));
    }

    #[test]
    fn csv_like_text_never_panics(text in "[-#a-z0-9,.\"\r\n ]{0,200}") {
        let with_header = format!("cycle,step,ac,face,reading,direction\n{text}");
        let _ = read_bytes(with_header.as_bytes(), None);
        let _ = read_bytes(text.as_bytes(), None);
    }
}

/// A `shift` column (docs/FORMAT.md §2, §9.1): the table's angle at step 0 of each
/// mounting, kept per setup by the set; an empty field is 0, and a 0 is not stored.
#[test]
fn shifts_are_read_per_mounting() {
    let set = read_good("good_shifts.csv", None);
    assert_eq!(set.readings.len(), 9);
    assert_eq!(
        set.setup_shift_deg
            .iter()
            .map(|(&s, &d)| (s, d))
            .collect::<Vec<_>>(),
        [(2, 10.0), (3, 130.0)]
    );
    assert_eq!(
        (set.shift_deg(1), set.shift_deg(2), set.shift_deg(3)),
        (0.0, 10.0, 130.0)
    );
    assert_eq!(set.shift_deg(9), 0.0);
    assert!(set.has_shifts());

    // 0, empty and -0 are all "no shift", one value: nothing stored, nothing written
    let zero =
        b"cycle,step,ac,face,reading,shift\n1,0,1,1,0.5,0\n1,1,1,2,-0.25,\n1,2,1,3,0.125,-0\n";
    let set = read_bytes(zero, None).unwrap();
    assert!(set.setup_shift_deg.is_empty() && !set.has_shifts());
    let mut out = Vec::new();
    set.write_to(&mut out, &[]).unwrap();
    assert!(!String::from_utf8(out).unwrap().contains("shift"));

    // A near miss of the name is refused like any other ("cycle,step,ac,face,reading," is
    // 27 characters).
    let near = b"cycle,step,ac,face,reading,Shift\n1,0,1,1,0.5,0\n";
    assert_invalid(&refused_bytes(near, None), "mem.csv", 1, 28, &["\"shift\""]);
}

#[test]
fn refuses_a_shift_that_is_not_a_number() {
    assert_refused(
        "bad_shift_not_number.csv",
        None,
        3,
        14,
        &["column \"shift\"", "\"five\" is not a number"],
    );
}

#[test]
fn refuses_an_infinite_shift() {
    assert_refused(
        "bad_shift_infinite.csv",
        None,
        5,
        15,
        &["column \"shift\"", "\"inf\" is not a finite number"],
    );
}

#[test]
fn refuses_a_negative_shift() {
    assert_refused(
        "bad_shift_negative.csv",
        None,
        3,
        13,
        &["column \"shift\"", "\"-5\" is outside 0 to 360 degrees"],
    );
}

#[test]
fn refuses_a_shift_of_a_full_turn() {
    // the shift column is the fourth: "1,0,1," is 6 characters
    assert_refused(
        "bad_shift_full_turn.csv",
        None,
        2,
        7,
        &[
            "column \"shift\"",
            "\"360\" is outside 0 to 360 degrees",
            "0 <= shift < 360",
        ],
    );
}

#[test]
fn refuses_two_shifts_in_one_mounting() {
    // "1,2,0,1,1,0.5," is 14 characters: the shift of line 8 starts at column 15
    assert_refused(
        "bad_shift_disagrees.csv",
        None,
        8,
        15,
        &[
            "column \"shift\"",
            "\"7.5\" disagrees with \"\" (empty, meaning 0) set for setup 1 at line 2",
            "a mounting has one shift",
        ],
    );
}

/// The shifts of the mountings are written (a `shift` column after the others) and read
/// back; in memory they are set with `with_setup_shifts`, checked like the column.
#[test]
fn shifts_round_trip() {
    let set = read_good("good_shifts.csv", None);
    let mut out = Vec::new();
    set.write_to(&mut out, &[]).unwrap();
    let text = String::from_utf8(out).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("cycle,step,ac,face,reading,direction,setup,shift")
    );
    assert_eq!(lines.next(), Some("1,0,1,1,0.5,cw,1,0"));
    assert_eq!(lines.nth(7), Some("1,2,1,2,-0.5,cw,3,130"));
    let back = round_trip(&set);
    assert_same_set(&set, &back);
    assert_eq!(back.setup_shift_deg, set.setup_shift_deg);

    let plain = MeasurementSet::from_readings(set.readings.clone(), None, "memory").unwrap();
    assert!(plain.setup_shift_deg.is_empty());
    let shifted = plain
        .clone()
        .with_setup_shifts([(2, 10.0), (3, 130.0), (1, 0.0)])
        .unwrap();
    assert_eq!(shifted.setup_shift_deg, set.setup_shift_deg);
    for (setup, shift, words) in [
        (2, 360.0, "360 is outside 0 to 360 degrees"),
        (2, -1.0, "-1 is outside"),
        (2, f64::NAN, "NaN is not a finite number"),
        (4, 1.0, "no reading of this setup"),
    ] {
        let err = plain
            .clone()
            .with_setup_shifts([(setup, shift)])
            .unwrap_err();
        assert_invalid(
            &err,
            "memory",
            0,
            0,
            &["column \"shift\"", &format!("setup {setup}"), words],
        );
    }
}
