//! The self-calibration file (docs/FORMAT.md §9.2), refused: one file per rule, each
//! refusal at its file, line and column with the words that say what is wrong, and a long
//! offending text cut short.
//!
//! Every expected `file:line:column` below was counted by hand from the file text; the
//! bad files under tests/data/selfcal are the two-head file of `BASE` with one thing
//! broken (one rule each).

use polycal::selfcal::SelfcalSet;

use crate::selfcal_file_support::{BASE, assert_invalid, data, read_bytes, refused_bytes};

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
