//! The measurement file's `shift` column (docs/FORMAT.md §2, §9.1): the table's angle at
//! step 0 of each mounting, read per mounting, refused when it is not a number, infinite,
//! negative, a full turn or two in one mounting, and written and read back.
//!
//! Every expected `file:line:column` below was counted by hand from the file text.

use polycal::measurement::MeasurementSet;

use crate::measurement_file_support::{
    assert_invalid, assert_refused, assert_same_set, read_bytes, read_good, refused_bytes,
    round_trip,
};

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
