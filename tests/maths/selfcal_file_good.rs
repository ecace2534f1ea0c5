//! The self-calibration file (docs/FORMAT.md §9.2), the good file: read field by field,
//! with or without the number of positions given, with a byte order mark, CRLF, quotes
//! and blank lines; `read_from` names its source and I/O errors name the file.
//!
//! Every expected `file:line:column` below was counted by hand from the file text.

use polycal::input::FileError;
use polycal::measurement::Direction;
use polycal::selfcal::{Head, HeadReading, SelfcalSet};

use crate::selfcal_file_support::{
    BASE, assert_invalid, data, read_bytes, read_good, refused_bytes, without_lines,
};

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
