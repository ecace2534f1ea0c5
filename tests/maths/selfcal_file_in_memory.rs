//! The self-calibration file's rules (docs/FORMAT.md §9.2) on readings built in memory
//! (`SelfcalSet::from_readings`): a good design accepted, every rule applied, and huge
//! steps not overflowing.

use polycal::measurement::Direction;
use polycal::selfcal::{HeadReading, SelfcalSet};

use crate::selfcal_file_support::{assert_invalid, read_good, reading, two_heads};

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
