//! The measurement file (docs/FORMAT.md §2), good files: read with the right values, with
//! or without the number of faces given, with setups, CRLF and a byte order mark; blank
//! lines and quoted line breaks keep the line numbers, columns are counted in characters,
//! and any reader reads like standard input.
//!
//! Every expected `file:line:column` below was counted by hand from the file text.

use polycal::measurement::{Direction, MeasurementSet, Reading};

use crate::measurement_file_support::{assert_invalid, data, read_bytes, read_good, refused_bytes};

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
