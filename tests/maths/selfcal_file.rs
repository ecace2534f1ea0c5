//! The self-calibration file (docs/FORMAT.md §9.2): reading, refusing, writing, round
//! trips.
//!
//! Every expected `file:line:column` below was counted by hand from the file text; the
//! bad files under tests/data/selfcal are the two-head file of `BASE` with one thing
//! broken (one rule each).

use std::path::{Path, PathBuf};

use polycal::input::FileError;
use polycal::measurement::Direction;
use polycal::selfcal::{Head, HeadReading, SelfcalSet};
use proptest::prelude::*;

/// The file the bad files are made from: heads 1 and 2 at 0° and 180°, P = 3, one cycle.
const BASE: &str = "cycle,step,head,head_angle,reading\n\
                    1,0,1,0,0.5\n\
                    1,0,2,180,-0.25\n\
                    1,1,1,0,0.125\n\
                    1,1,2,180,0\n\
                    1,2,1,0,-0.5\n\
                    1,2,2,180,0.75\n";

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/selfcal")
        .join(name)
}

fn read_good(name: &str, positions: Option<usize>) -> SelfcalSet {
    match SelfcalSet::read_path(data(name), positions) {
        Ok(set) => set,
        Err(e) => panic!("{name} should read: {e}"),
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

/// Asserts that bad file `name` is refused with the message starting
/// `FILE:line:column: ` + `start`, and holding `words`.
fn assert_refused(
    name: &str,
    positions: Option<usize>,
    (line, column): (u64, u64),
    start: &str,
    words: &[&str],
) {
    let err = match SelfcalSet::read_path(data(name), positions) {
        Ok(set) => panic!(
            "{name} should be refused, read {} readings",
            set.readings.len()
        ),
        Err(e) => e,
    };
    let file = data(name).display().to_string();
    assert_invalid(&err, &file, line, column, words);
    let prefix = format!("{file}:{line}:{column}: {start}");
    assert!(
        err.to_string().starts_with(&prefix),
        "{err}\nexpected {prefix}"
    );
}

fn read_bytes(bytes: &[u8], positions: Option<usize>) -> Result<SelfcalSet, FileError> {
    SelfcalSet::read_from(bytes, "mem.csv", positions)
}

fn refused_bytes(bytes: &[u8], positions: Option<usize>) -> FileError {
    match read_bytes(bytes, positions) {
        Ok(set) => panic!("should be refused, read {} readings", set.readings.len()),
        Err(e) => e,
    }
}

/// The readings with `line` cleared, to compare sets apart from where they came from.
fn without_lines(readings: &[HeadReading]) -> Vec<HeadReading> {
    readings
        .iter()
        .map(|r| HeadReading {
            line: 0,
            ..r.clone()
        })
        .collect()
}

fn reading(cycle: u32, step: usize, head: u32, angle: f64, value: f64) -> HeadReading {
    HeadReading {
        cycle,
        step,
        head,
        head_angle_deg: angle,
        reading_arcsec: value,
        direction: Direction::Cw,
        time_seconds: None,
        line: 0,
    }
}

/// One cycle of P positions read by heads 1 and 2 at 0° and 180°.
fn two_heads(p: usize) -> Vec<HeadReading> {
    let mut readings = Vec::new();
    for step in 0..p {
        readings.push(reading(1, step, 1, 0.0, step as f64 * 0.25));
        readings.push(reading(1, step, 2, 180.0, -(step as f64) * 0.5));
    }
    readings
}

// ---------------------------------------------------------------------------------------
// The good file

#[test]
fn good_file_reads_field_by_field() {
    let set = read_good("good_3heads.csv", None);
    assert_eq!(set.positions, 6);
    assert_eq!(set.readings.len(), 36);
    assert_eq!(
        set.heads(),
        vec![
            Head {
                head: 1,
                angle_deg: 0.0
            },
            Head {
                head: 2,
                angle_deg: 120.0
            },
            Head {
                head: 3,
                angle_deg: 240.0
            },
        ]
    );
    assert_eq!(set.cycles(), vec![1, 2]);

    // Line 5: ,-0.375,1,0,cw,0,0,1 (columns note,reading,head,head_angle,direction,step,
    // time,cycle).
    assert_eq!(
        set.readings[0],
        HeadReading {
            cycle: 1,
            step: 0,
            head: 1,
            head_angle_deg: 0.0,
            reading_arcsec: -0.375,
            direction: Direction::Cw,
            time_seconds: Some(0.0),
            line: 5,
        }
    );
    // Line 9: a quoted note holding a comma.
    assert_eq!(
        set.readings[4],
        HeadReading {
            cycle: 1,
            step: 1,
            head: 2,
            head_angle_deg: 120.0,
            reading_arcsec: -0.625,
            direction: Direction::Cw,
            time_seconds: Some(6.0),
            line: 9,
        }
    );
    // Line 11: ,0.125,1,0,,2,9,1 — an empty direction is cw.
    let r = &set.readings[6];
    assert_eq!((r.line, r.cycle, r.step, r.head), (11, 1, 2, 1));
    assert_eq!(
        (r.direction, r.reading_arcsec, r.time_seconds),
        (Direction::Cw, 0.125, Some(9.0))
    );
    // Line 16: ,-0.625,3,240.0,cw,3,,1 — "240.0" is the same angle as "240"; no time.
    let r = &set.readings[11];
    assert_eq!(
        (r.line, r.step, r.head, r.head_angle_deg),
        (16, 3, 3, 240.0)
    );
    assert_eq!((r.reading_arcsec, r.time_seconds), (-0.625, None));
    // Line 17 is blank; line 18 follows.
    let r = &set.readings[12];
    assert_eq!(
        (r.line, r.step, r.head, r.reading_arcsec),
        (18, 4, 1, 0.625)
    );
    // Line 24: ,1,1,0,ccw,5,27,2 — cycle 2 turns counter-clockwise from step 5.
    assert_eq!(
        set.readings[18],
        HeadReading {
            cycle: 2,
            step: 5,
            head: 1,
            head_angle_deg: 0.0,
            reading_arcsec: 1.0,
            direction: Direction::Ccw,
            time_seconds: Some(27.0),
            line: 24,
        }
    );
    // Line 41, the last: ,-1.25,3,240,ccw,0,52.5,2.
    let r = &set.readings[35];
    assert_eq!((r.line, r.cycle, r.step, r.head), (41, 2, 0, 3));
    assert_eq!((r.head_angle_deg, r.reading_arcsec), (240.0, -1.25));
    assert_eq!((r.direction, r.time_seconds), (Direction::Ccw, Some(52.5)));

    let ccw: Vec<u32> = set
        .readings
        .iter()
        .filter(|r| r.direction == Direction::Ccw)
        .map(|r| r.cycle)
        .collect();
    assert_eq!(ccw, vec![2; 18]);
    assert_eq!(
        set.readings
            .iter()
            .filter(|r| r.time_seconds.is_none())
            .count(),
        1
    );
}

#[test]
fn good_file_with_positions_given() {
    assert_eq!(read_good("good_3heads.csv", Some(6)).positions, 6);
    // Steps 0 … 3 are all read: P = 4 without --positions.
    assert_eq!(
        read_good("bad_step_beyond_positions.csv", None).positions,
        4
    );
}

#[test]
fn byte_order_mark_crlf_quotes_and_blank_lines() {
    let text = "\u{feff}# comment\r\n\r\n  \r\n\"cycle\",step,head,head_angle,reading\r\n\
                1,0,1,0,0.5\r\n   \r\n1,0,2,180,-0.25\r\n1,1,1,0,0.125\r1,1,2,180,0\n\
                1,2,1,0,-0.5\n1,2,2,\"180\",0.75";
    let set = read_bytes(text.as_bytes(), None).unwrap();
    let lines: Vec<u64> = set.readings.iter().map(|r| r.line).collect();
    assert_eq!(lines, vec![5, 7, 8, 9, 10, 11]);
    let base = read_bytes(BASE.as_bytes(), None).unwrap();
    assert_eq!(without_lines(&set.readings), without_lines(&base.readings));
    // Columns count characters, after the byte-order mark: "1,0,2,é" on line 3.
    let err = refused_bytes(
        "\u{feff}cycle,step,head,head_angle,reading\n1,0,1,0,0.5\n1,0,2,é,0\n".as_bytes(),
        None,
    );
    assert_invalid(
        &err,
        "mem.csv",
        3,
        7,
        &["column \"head_angle\": \"é\" is not a number"],
    );
    let err = refused_bytes(
        "note,cycle,step,head,head_angle,reading\nété,1,0,1,0,zéro\n".as_bytes(),
        None,
    );
    assert_invalid(&err, "mem.csv", 2, 13, &["column \"reading\": \"zéro\""]);
}

#[test]
fn read_from_names_its_source_and_io_errors_name_the_file() {
    let err = SelfcalSet::read_from(&b"cycle\n"[..], "<stdin>", None).unwrap_err();
    assert!(
        err.to_string()
            .starts_with("<stdin>:1:1: missing required columns"),
        "{err}"
    );

    let path = data("no_such_file.csv");
    let err = SelfcalSet::read_path(&path, None).unwrap_err();
    assert!(matches!(err, FileError::Io { .. }), "{err}");
    assert_eq!(err.location(), None);
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
    let err = SelfcalSet::read_from(Broken, "port", None).unwrap_err();
    assert_eq!(err.to_string(), "port: cable unplugged");
}

// ---------------------------------------------------------------------------------------
// Refusals: one file per rule

#[test]
fn refuses_bytes_that_are_not_utf8() {
    // Line 3 is "1,0,2,18\xff0,-0.25": the bad byte is at column 9.
    assert_refused(
        "bad_not_utf8.csv",
        None,
        (3, 9),
        "not valid UTF-8 (byte 0xff)",
        &[],
    );
    let err = refused_bytes(b"cycle,step,head,head_angle,reading\n1,0,1,0,\xc3", None);
    assert_invalid(&err, "mem.csv", 2, 9, &["not valid UTF-8", "cut off"]);
}

#[test]
fn refuses_an_empty_file() {
    assert_refused("bad_empty.csv", None, (1, 1), "empty file", &["head_angle"]);
    assert_invalid(
        &refused_bytes(b"\n \n", None),
        "mem.csv",
        1,
        1,
        &["empty file"],
    );
}

#[test]
fn refuses_a_file_of_comments_only() {
    assert_refused(
        "bad_only_comments.csv",
        None,
        (3, 1),
        "no header row",
        &["comment"],
    );
}

#[test]
fn refuses_a_header_without_data_rows() {
    assert_refused(
        "bad_no_rows.csv",
        None,
        (2, 1),
        "no data rows after the header",
        &[],
    );
    let err = refused_bytes(b"cycle,step,head,head_angle,reading\n\n  \n", None);
    assert_invalid(&err, "mem.csv", 1, 1, &["no data rows"]);
}

#[test]
fn refuses_a_missing_required_column() {
    assert_refused(
        "bad_missing_column.csv",
        None,
        (2, 1),
        "missing required column \"head_angle\";",
        &["the header has \"cycle\", \"step\", \"head\", \"reading\""],
    );
    let err = refused_bytes(b"head,reading\n1,0.5\n", None);
    assert_invalid(
        &err,
        "mem.csv",
        1,
        1,
        &["missing required columns \"cycle\", \"step\", \"head_angle\""],
    );
}

#[test]
fn refuses_a_duplicated_column() {
    // "cycle,step,head,head_angle,reading," is 35 characters; "cycle,step," 11.
    assert_refused(
        "bad_duplicate_column.csv",
        None,
        (1, 36),
        "column \"head\" appears twice in the header",
        &["first at column 12"],
    );
    // Unknown columns are ignored, but not twice.
    let err = refused_bytes(b"note,cycle,step,head,head_angle,reading,note\n", None);
    assert_invalid(&err, "mem.csv", 1, 41, &["column \"note\" appears twice"]);
}

#[test]
fn refuses_a_near_miss_of_a_column_name() {
    assert_refused(
        "bad_near_miss_column.csv",
        None,
        (1, 17),
        "column \"Head_Angle\" is not a known column name but looks like \"head_angle\"",
        &[],
    );
    for (header, column, name) in [
        ("cycle,step,head,head-angle,reading", 17, "\"head-angle\""),
        ("cycle,step,head,head angle,reading", 17, "\"head angle\""),
        ("cycle,step, head,head_angle,reading", 12, "\" head\""),
        ("cycle,step,head,head_angle,reading,Time", 36, "\"Time\""),
        (
            "cycle,step,head,head_angle,reading,DIRECTION",
            36,
            "\"DIRECTION\"",
        ),
    ] {
        let err = refused_bytes(format!("{header}\n1,0,1,0,0.5\n").as_bytes(), None);
        assert_invalid(&err, "mem.csv", 1, column, &[name, "looks like"]);
    }
    // Columns polycal does not know at all are ignored.
    let text = BASE
        .replace("reading\n", "reading,ac,operator\n")
        .replace('\n', ",x,y\n");
    let text = text.replacen(",x,y", "", 1);
    assert_eq!(read_bytes(text.as_bytes(), None).unwrap().readings.len(), 6);
}

#[test]
fn refuses_rows_with_too_many_or_too_few_fields() {
    // Line 4 "1,1,1,0,0.125,7": the extra field at column 15.
    assert_refused(
        "bad_too_many_fields.csv",
        None,
        (4, 15),
        "row has 6 fields but the header has 5: extra field \"7\"",
        &[],
    );
    // Line 4 "1,1,1,0": the missing field would start at column 8.
    assert_refused(
        "bad_too_few_fields.csv",
        None,
        (4, 8),
        "row has 4 fields but the header has 5: no value for column \"reading\"",
        &[],
    );
    // A comment after the header is a row ("# late" is 6 characters).
    let err = refused_bytes(b"cycle,step,head,head_angle,reading\n# late\n", None);
    assert_invalid(
        &err,
        "mem.csv",
        2,
        7,
        &["row has 1 field but the header has 5"],
    );
}

#[test]
fn refuses_a_bad_cycle() {
    assert_refused(
        "bad_cycle_zero.csv",
        None,
        (4, 1),
        "column \"cycle\": \"0\" is not allowed; cycle must be at least 1",
        &[],
    );
    assert_refused(
        "bad_cycle_not_integer.csv",
        None,
        (4, 1),
        "column \"cycle\": \"1.0\" is not an integer",
        &[],
    );
    let err = refused_bytes(
        BASE.replace("\n1,0,2,", "\n4294967296,0,2,").as_bytes(),
        None,
    );
    assert_invalid(
        &err,
        "mem.csv",
        3,
        1,
        &["column \"cycle\": \"4294967296\" is too large"],
    );
    let err = refused_bytes(BASE.replace("\n1,0,2,", "\n,0,2,").as_bytes(), None);
    assert_invalid(&err, "mem.csv", 3, 1, &["column \"cycle\": empty"]);
}

#[test]
fn refuses_a_bad_step() {
    assert_refused(
        "bad_step_negative.csv",
        None,
        (3, 3),
        "column \"step\": \"-1\" is not allowed; step must be at least 0",
        &[],
    );
    let err = refused_bytes(BASE.replace("\n1,0,2,", "\n1,0.5,2,").as_bytes(), None);
    assert_invalid(
        &err,
        "mem.csv",
        3,
        3,
        &["column \"step\": \"0.5\" is not an integer"],
    );
    let huge = BASE.replace("\n1,0,2,", &format!("\n1,{},2,", "9".repeat(45)));
    let err = refused_bytes(huge.as_bytes(), None);
    assert_invalid(&err, "mem.csv", 3, 3, &["column \"step\"", "is too large"]);
    // Whitespace is not trimmed.
    let err = refused_bytes(BASE.replace("\n1,0,2,", "\n1, 0,2,").as_bytes(), None);
    assert_invalid(
        &err,
        "mem.csv",
        3,
        3,
        &["column \"step\": \" 0\" is not an integer"],
    );
}

#[test]
fn refuses_a_step_beyond_the_positions_given() {
    assert_refused(
        "bad_step_beyond_positions.csv",
        Some(3),
        (8, 3),
        "column \"step\": 3 is outside 0 to 2 (P = 3, the number of positions stated)",
        &[],
    );
}

#[test]
fn refuses_a_bad_head() {
    assert_refused(
        "bad_head_zero.csv",
        None,
        (3, 5),
        "column \"head\": \"0\" is not allowed; head must be at least 1",
        &[],
    );
    assert_refused(
        "bad_head_not_integer.csv",
        None,
        (3, 5),
        "column \"head\": \"two\" is not an integer",
        &[],
    );
}

#[test]
fn refuses_a_head_angle_that_is_not_a_finite_number() {
    assert_refused(
        "bad_head_angle_not_number.csv",
        None,
        (5, 7),
        "column \"head_angle\": \"180°\" is not a number",
        &[],
    );
    assert_refused(
        "bad_head_angle_nan.csv",
        None,
        (5, 7),
        "column \"head_angle\": \"NaN\" is not a finite number",
        &[],
    );
    let err = refused_bytes(BASE.replace("1,1,2,180,", "1,1,2,,").as_bytes(), None);
    assert_invalid(&err, "mem.csv", 5, 7, &["column \"head_angle\": empty"]);
}

#[test]
fn refuses_a_head_angle_outside_0_to_360() {
    assert_refused(
        "bad_head_angle_360.csv",
        None,
        (5, 7),
        "column \"head_angle\": \"360\" is outside 0 to 360 degrees",
        &[],
    );
    let err = refused_bytes(BASE.replace("1,1,2,180,", "1,1,2,-90,").as_bytes(), None);
    assert_invalid(
        &err,
        "mem.csv",
        5,
        7,
        &["column \"head_angle\": \"-90\" is outside"],
    );
    // Just below 360 is an angle; -0 is 0.
    let text = BASE
        .replace(",180,", ",359.99999,")
        .replace("\n1,0,1,0,", "\n1,0,1,-0,");
    let set = read_bytes(text.as_bytes(), None).unwrap();
    assert_eq!(set.heads()[1].angle_deg, 359.99999);
}

#[test]
fn refuses_a_reference_head_not_at_0() {
    assert_refused(
        "bad_head1_angle.csv",
        None,
        (4, 7),
        "column \"head_angle\": \"0.5\" for head 1; head 1 is the reference and its angle must be 0",
        &[],
    );
}

#[test]
fn refuses_a_head_whose_angle_changes() {
    assert_refused(
        "bad_head_angle_changes.csv",
        None,
        (5, 7),
        "column \"head_angle\": \"180.5\" disagrees with \"180\" set for head 2 at line 3",
        &["a head has one angle"],
    );
}

#[test]
fn refuses_two_heads_at_the_same_angle() {
    assert_refused(
        "bad_same_angle.csv",
        None,
        (4, 7),
        "column \"head_angle\": head 3 at \"120.0000000001\" is at the angle of head 2 \
         (\"120\" at line 3)",
        &["modulo 360 within 1e-9 degrees"],
    );
    // Modulo 360: 359.9999999999 is 1e-10 degrees from head 1's 0.
    assert_refused(
        "bad_same_angle_wrap.csv",
        None,
        (3, 7),
        "column \"head_angle\": head 2 at \"359.9999999999\" is at the angle of head 1 \
         (\"0\" at line 2)",
        &[],
    );
    // Two heads 2e-9 degrees apart are two places.
    let text = "cycle,step,head,head_angle,reading\n\
                1,0,1,0,0\n1,0,2,120,0\n1,0,3,120.000000002,0\n\
                1,1,1,0,0\n1,1,2,120,0\n1,1,3,120.000000002,0\n\
                1,2,1,0,0\n1,2,2,120,0\n1,2,3,120.000000002,0\n";
    assert_eq!(read_bytes(text.as_bytes(), None).unwrap().heads().len(), 3);
}

#[test]
fn refuses_a_reading_that_is_not_a_finite_number() {
    // Line 5 "1,1,2,180,": the reading at column 11.
    assert_refused(
        "bad_reading_not_number.csv",
        None,
        (5, 11),
        "column \"reading\": \"0.2S\" is not a number",
        &[],
    );
    assert_refused(
        "bad_reading_infinite.csv",
        None,
        (5, 11),
        "column \"reading\": \"inf\" is not a finite number",
        &[],
    );
    let err = refused_bytes(
        BASE.replace("1,1,2,180,0\n", "1,1,2,180,1e999\n")
            .as_bytes(),
        None,
    );
    assert_invalid(
        &err,
        "mem.csv",
        5,
        11,
        &["\"1e999\" is not a finite number"],
    );
    let err = refused_bytes(
        BASE.replace("1,1,2,180,0\n", "1,1,2,180,\n").as_bytes(),
        None,
    );
    assert_invalid(&err, "mem.csv", 5, 11, &["column \"reading\": empty"]);
}

#[test]
fn refuses_an_unknown_direction() {
    // Line 5 "1,1,2,180,0,CW": the direction at column 13.
    assert_refused(
        "bad_direction.csv",
        None,
        (5, 13),
        "column \"direction\": \"CW\" is not a direction; use \"cw\" or \"ccw\"",
        &[],
    );
}

#[test]
fn refuses_a_cycle_with_two_directions() {
    // Line 6 "1,2,1,0,-0.5,": the empty direction (cw) at column 14.
    assert_refused(
        "bad_mixed_direction.csv",
        None,
        (6, 14),
        "column \"direction\": \"\" (empty, meaning cw) disagrees with \"ccw\" set for cycle 1 \
         at line 2",
        &["a cycle has one direction"],
    );
}

#[test]
fn refuses_a_time_that_is_not_a_finite_number() {
    assert_refused(
        "bad_time_infinite.csv",
        None,
        (4, 1),
        "column \"time\": \"inf\" is not a finite number",
        &[],
    );
    let err = refused_bytes(
        b"time,cycle,step,head,head_angle,reading\nnow,1,0,1,0,0\n",
        None,
    );
    assert_invalid(
        &err,
        "mem.csv",
        2,
        1,
        &["column \"time\": \"now\" is not a number"],
    );
}

#[test]
fn refuses_a_duplicate_reading() {
    assert_refused(
        "bad_duplicate_reading.csv",
        None,
        (6, 1),
        "duplicate reading: cycle 1, step 1, head 2 was already read at line 5",
        &[],
    );
}

#[test]
fn refuses_a_single_head() {
    // "cycle,step," is 11 characters: the header's head at column 12.
    assert_refused(
        "bad_one_head.csv",
        None,
        (1, 12),
        "column \"head\": only head 1 is read; self-calibration needs at least 2 heads",
        &[],
    );
}

#[test]
fn refuses_a_set_without_head_1() {
    assert_refused(
        "bad_no_head1.csv",
        None,
        (1, 12),
        "column \"head\": head 1, the reference, is never read (the heads read are 2, 3)",
        &[],
    );
}

#[test]
fn refuses_fewer_than_three_positions() {
    // The largest step (1) is first read on line 4, column 3.
    assert_refused(
        "bad_two_positions.csv",
        None,
        (4, 3),
        "column \"step\": the largest step is 1, so P = 2; self-calibration needs at least 3 \
         positions",
        &[],
    );
    // --positions 2: the header's step ("note,reading,head,head_angle,direction," is 39
    // characters).
    assert_refused(
        "good_3heads.csv",
        Some(2),
        (4, 40),
        "column \"step\": 2 positions were stated; self-calibration needs at least 3 positions",
        &[],
    );
}

#[test]
fn refuses_a_step_some_head_never_reads() {
    // "cycle," is 6 characters: the header's step at column 7.
    assert_refused(
        "bad_missing_reading.csv",
        None,
        (1, 7),
        "column \"step\": cycle 1, step 1 is never read by head 2; every head must read every \
         step 0 to 2 in every cycle (P = 3, the largest step + 1)",
        &[],
    );
    assert_refused(
        "bad_missing_cycle.csv",
        None,
        (1, 7),
        "column \"step\": cycle 2, step 0 is never read by head 2",
        &[],
    );
    // Positions given beyond those read.
    assert_refused(
        "bad_step_beyond_positions.csv",
        Some(5),
        (1, 7),
        "column \"step\": cycle 1, step 4 is never read by head 1",
        &["P = 5, the number of positions stated"],
    );
    // A huge P allocates nothing.
    let err = refused_bytes(BASE.as_bytes(), Some(usize::MAX));
    assert_invalid(
        &err,
        "mem.csv",
        1,
        7,
        &["cycle 1, step 3 is never read by head 1"],
    );
}

#[test]
fn long_offending_text_is_cut_short() {
    let text = BASE.replace(
        "1,1,2,180,0\n",
        &format!("1,1,2,180,{}\n", "x".repeat(1000)),
    );
    let message = refused_bytes(text.as_bytes(), None).to_string();
    assert!(
        message.len() < 200 && message.contains("\"... is not a number"),
        "{message}"
    );
}

// ---------------------------------------------------------------------------------------
// Readings built in memory

#[test]
fn from_readings_accepts_a_good_design() {
    let readings = two_heads(4);
    let set = SelfcalSet::from_readings(readings.clone(), None).unwrap();
    assert_eq!((set.positions, set.readings.clone()), (4, readings));
    let file = read_good("good_3heads.csv", None);
    let again = SelfcalSet::from_readings(file.readings.clone(), Some(6)).unwrap();
    assert_eq!(again, file);
}

#[test]
fn from_readings_applies_every_rule() {
    let sim = |readings: Vec<HeadReading>, positions| {
        SelfcalSet::from_readings(readings, positions).unwrap_err()
    };
    let check = |readings: Vec<HeadReading>, positions, words: &[&str]| {
        let err = sim(readings, positions);
        assert_invalid(&err, "<readings>", 0, 0, words);
    };

    check(Vec::new(), None, &["no readings"]);
    let mut r = two_heads(3);
    r[2].cycle = 0;
    check(
        r,
        None,
        &["<readings>: reading 3: column \"cycle\": 0 is not allowed"],
    );
    let mut r = two_heads(3);
    r[3].head = 0;
    check(r, None, &["reading 4: column \"head\": 0 is not allowed"]);
    let mut r = two_heads(3);
    r[1].head_angle_deg = f64::NAN;
    check(
        r,
        None,
        &["reading 2: column \"head_angle\": NaN is not a finite number"],
    );
    let mut r = two_heads(3);
    r[1].head_angle_deg = 360.0;
    check(
        r,
        None,
        &["reading 2: column \"head_angle\": 360 is outside 0 to 360"],
    );
    let mut r = two_heads(3);
    r[1].reading_arcsec = f64::INFINITY;
    check(
        r,
        None,
        &["reading 2: column \"reading\": inf is not a finite number"],
    );
    let mut r = two_heads(3);
    r[5].time_seconds = Some(f64::NEG_INFINITY);
    check(
        r,
        None,
        &["reading 6: column \"time\": -inf is not a finite number"],
    );
    check(
        two_heads(2),
        None,
        &["reading 3: column \"step\": the largest step is 1, so P = 2"],
    );
    check(
        two_heads(3),
        Some(1),
        &["column \"step\": 1 positions were stated"],
    );
    check(
        two_heads(4),
        Some(3),
        &["reading 7: column \"step\": 3 is outside 0 to 2"],
    );
    let mut r = two_heads(3);
    r.push(reading(1, 1, 2, 180.0, 0.0));
    check(
        r,
        None,
        &["reading 7: duplicate reading: cycle 1, step 1, head 2 was already read at reading 4"],
    );
    let mut r = two_heads(3);
    r[4].direction = Direction::Ccw;
    check(
        r,
        None,
        &[
            "reading 5: column \"direction\": \"ccw\" disagrees with \"cw\" set for cycle 1 at reading 1",
        ],
    );
    let mut r = two_heads(3);
    r[2].head_angle_deg = 1.0;
    check(r, None, &["reading 3: column \"head_angle\": 1 for head 1"]);
    let mut r = two_heads(3);
    r[3].head_angle_deg = 90.0;
    check(
        r,
        None,
        &["reading 4: column \"head_angle\": 90 disagrees with 180 set for head 2 at reading 2"],
    );
    let mut r = two_heads(3);
    r.iter_mut()
        .filter(|x| x.head == 2)
        .for_each(|x| x.head_angle_deg = 5e-10);
    check(
        r,
        None,
        &[
            "reading 2: column \"head_angle\": head 2 at 0.0000000005 is at the angle of head 1 (0 at reading 1)",
        ],
    );
    let r: Vec<HeadReading> = two_heads(3).into_iter().filter(|x| x.head == 1).collect();
    check(r, None, &["column \"head\": only head 1 is read"]);
    let mut r = two_heads(3);
    r.iter_mut().filter(|x| x.head == 1).for_each(|x| {
        x.head = 3;
        x.head_angle_deg = 90.0;
    });
    check(
        r,
        None,
        &["column \"head\": head 1, the reference, is never read (the heads read are 2, 3)"],
    );
    let mut r = two_heads(3);
    r.remove(3);
    check(
        r,
        None,
        &["column \"step\": cycle 1, step 1 is never read by head 2"],
    );
    check(
        two_heads(3),
        Some(4),
        &["cycle 1, step 3 is never read by head 1"],
    );

    // A reading that came from a file keeps its line, and no "reading K" is added.
    let mut r = two_heads(3);
    r[2].cycle = 0;
    r[2].line = 17;
    let err = sim(r, None);
    assert_invalid(&err, "<readings>", 17, 0, &["column \"cycle\""]);
    assert!(!err.to_string().contains("reading 3"), "{err}");
}

#[test]
fn huge_steps_do_not_overflow() {
    let mut r = two_heads(3);
    r[0].step = usize::MAX;
    let err = SelfcalSet::from_readings(r, None).unwrap_err();
    assert_invalid(
        &err,
        "<readings>",
        0,
        0,
        &["reading 1: column \"step\"", "is too large"],
    );
}

// ---------------------------------------------------------------------------------------
// Writing and round trips

fn written(set: &SelfcalSet, comments: &[String]) -> String {
    let mut out = Vec::new();
    set.write_with_comments(&mut out, comments).unwrap();
    String::from_utf8(out).unwrap()
}

#[test]
fn writes_the_documented_header_and_rows() {
    let mut readings = two_heads(3);
    let set = SelfcalSet::from_readings(readings.clone(), None).unwrap();
    let mut out = Vec::new();
    set.write_to(&mut out).unwrap();
    assert_eq!(
        String::from_utf8(out).unwrap(),
        "cycle,step,head,head_angle,reading\n\
         1,0,1,0,0\n1,0,2,180,-0\n1,1,1,0,0.25\n1,1,2,180,-0.5\n1,2,1,0,0.5\n1,2,2,180,-1\n"
    );

    for r in &mut readings {
        r.direction = Direction::Ccw;
    }
    readings[1].time_seconds = Some(1.5);
    readings[2].head_angle_deg = -0.0;
    let set = SelfcalSet::from_readings(readings, None).unwrap();
    let comments = [
        "simulated".to_string(),
        "two\r\nlines".to_string(),
        String::new(),
    ];
    assert_eq!(
        written(&set, &comments),
        "# simulated\n# two\n# lines\n#\n\
         cycle,step,head,head_angle,reading,direction,time\n\
         1,0,1,0,0,ccw,\n1,0,2,180,-0,ccw,1.5\n1,1,1,-0,0.25,ccw,\n1,1,2,180,-0.5,ccw,\n\
         1,2,1,0,0.5,ccw,\n1,2,2,180,-1,ccw,\n"
    );
}

fn bits(set: &SelfcalSet) -> Vec<[Option<u64>; 3]> {
    set.readings
        .iter()
        .map(|r| {
            [
                Some(r.head_angle_deg.to_bits()),
                Some(r.reading_arcsec.to_bits()),
                r.time_seconds.map(f64::to_bits),
            ]
        })
        .collect()
}

fn assert_round_trip(set: &SelfcalSet) {
    let text = written(set, &["round trip".to_string()]);
    let back = match read_bytes(text.as_bytes(), None) {
        Ok(back) => back,
        Err(e) => panic!("{e}\n{text}"),
    };
    assert_eq!(back.positions, set.positions);
    assert_eq!(without_lines(&back.readings), without_lines(&set.readings));
    // Bit for bit, so that -0 stays -0.
    assert_eq!(bits(&back), bits(set));
    // The comment is line 1, the header line 2.
    assert_eq!(back.readings.first().map(|r| r.line), Some(3));
}

#[test]
fn the_good_file_round_trips() {
    assert_round_trip(&read_good("good_3heads.csv", None));
}

#[test]
fn write_path_and_read_path_round_trip() {
    let set = read_good("good_3heads.csv", None);
    let dir = std::env::temp_dir().join(format!("polycal-selfcal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("written.csv");
    set.write_path(&path, &[]).unwrap();
    let back = SelfcalSet::read_path(&path, None).unwrap();
    assert_eq!(without_lines(&back.readings), without_lines(&set.readings));
    assert_eq!(back.readings[0].line, 2);
    let err = set
        .write_path(dir.join("no/such/dir.csv"), &[])
        .unwrap_err();
    assert!(matches!(err, FileError::Io { .. }), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();

    struct Full;
    impl std::io::Write for Full {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk full"))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let err = set.write_to(Full).unwrap_err();
    assert_eq!(err.to_string(), "<output>: disk full");
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
    let mut readings = Vec::new();
    for (step, &x) in values.iter().enumerate() {
        for (head, angle) in [(1, 0.0), (2, 1.0 / 3.0), (3, 360.0 - 1e-6)] {
            readings.push(HeadReading {
                time_seconds: Some(-x),
                ..reading(1, step, head, angle, x)
            });
        }
    }
    assert_round_trip(&SelfcalSet::from_readings(readings, None).unwrap());
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

/// A valid random set: 2 to 5 heads at distinct angles (head 1 at 0), P = 3 … 8, one to
/// three cycles of random direction, random values and times, shuffled rows.
fn valid_set() -> impl Strategy<Value = SelfcalSet> {
    (
        prop::collection::btree_set(1u64..360_000_000, 1..5),
        3usize..9,
        1u32..4,
        prop::collection::vec(any::<bool>(), 3),
    )
        .prop_flat_map(|(micro, p, cycles, ccw)| {
            let mut angles = vec![0.0];
            angles.extend(micro.iter().map(|&m| m as f64 * 1e-6));
            let count = angles.len() * p * cycles as usize;
            let values = prop::collection::vec((finite(), prop::option::of(finite())), count);
            (Just((angles, p, cycles, ccw)), values)
        })
        .prop_flat_map(|((angles, p, cycles, ccw), values)| {
            let mut readings = Vec::new();
            let mut values = values.into_iter();
            for cycle in 1..=cycles {
                for step in 0..p {
                    for (k, &angle) in angles.iter().enumerate() {
                        let (x, t) = values.next().unwrap_or((0.0, None));
                        readings.push(HeadReading {
                            direction: if ccw[cycle as usize - 1] {
                                Direction::Ccw
                            } else {
                                Direction::Cw
                            },
                            time_seconds: t,
                            ..reading(cycle, step, k as u32 + 1, angle, x)
                        });
                    }
                }
            }
            Just(readings).prop_shuffle()
        })
        .prop_map(|readings| {
            SelfcalSet::from_readings(readings, None)
                .unwrap_or_else(|e| panic!("generated set refused: {e}"))
        })
}

/// A read either gives a set that passes `from_readings` unchanged, or an error with a
/// line and a column — a file that breaks the rules, or one of another kind (`[` or `{`
/// first: a budget, a JSON document; docs/FORMAT.md §8); it never panics.
fn check_outcome(result: Result<SelfcalSet, FileError>) {
    match result {
        Ok(set) => {
            let again = SelfcalSet::from_readings(set.readings.clone(), Some(set.positions));
            assert_eq!(again.ok().as_ref(), Some(&set));
        }
        Err(
            FileError::Invalid { location, message }
            | FileError::WrongKind {
                location, message, ..
            },
        ) => {
            assert!(
                location.line() >= 1 && location.column() >= 1,
                "{location}: {message}"
            );
            assert_eq!(location.file(), "mem.csv");
            assert!(!message.is_empty() && !message.contains('\n'), "{message}");
        }
        Err(e) => panic!("unexpected error: {e}"),
    }
}

/// One edit of a file: delete, insert or replace a byte at a place.
#[derive(Debug, Clone)]
enum Edit {
    Delete(prop::sample::Index),
    Insert(prop::sample::Index, u8),
    Replace(prop::sample::Index, u8),
}

fn edit() -> impl Strategy<Value = Edit> {
    let byte = prop_oneof![
        any::<u8>(),
        prop::sample::select(b",\n\r\"#-.0123456789e ".to_vec()),
    ];
    prop_oneof![
        any::<prop::sample::Index>().prop_map(Edit::Delete),
        (any::<prop::sample::Index>(), byte.clone()).prop_map(|(i, b)| Edit::Insert(i, b)),
        (any::<prop::sample::Index>(), byte).prop_map(|(i, b)| Edit::Replace(i, b)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_sets_round_trip(set in valid_set()) {
        assert_round_trip(&set);
    }

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        check_outcome(read_bytes(&bytes, None));
        check_outcome(read_bytes(&bytes, Some(3)));
    }

    #[test]
    fn csv_like_text_never_panics(text in "[-#a-z0-9,.\"\r\n ]{0,200}") {
        let with_header = format!("cycle,step,head,head_angle,reading,direction,time\n{text}");
        check_outcome(read_bytes(with_header.as_bytes(), None));
        check_outcome(read_bytes(text.as_bytes(), None));
    }

    #[test]
    fn mutated_good_files_never_panic(
        edits in prop::collection::vec(edit(), 1..6),
        which in 0usize..2,
        positions in prop::option::of(0usize..8),
    ) {
        let good = std::fs::read(data("good_3heads.csv")).unwrap();
        let mut bytes = if which == 0 { good } else { BASE.as_bytes().to_vec() };
        for e in edits {
            match e {
                Edit::Delete(i) if !bytes.is_empty() => {
                    bytes.remove(i.index(bytes.len()));
                }
                Edit::Insert(i, b) => bytes.insert(i.index(bytes.len() + 1), b),
                Edit::Replace(i, b) if !bytes.is_empty() => {
                    let k = i.index(bytes.len());
                    bytes[k] = b;
                }
                _ => {}
            }
        }
        check_outcome(read_bytes(&bytes, positions));
    }
}
