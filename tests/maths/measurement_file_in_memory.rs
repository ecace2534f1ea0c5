//! The measurement file's rules (docs/FORMAT.md §2) on readings built in memory
//! (`MeasurementSet::from_readings`): a good design kept in its order, every rule refused
//! with line 0 and the reading's number, and a huge number of faces given neither
//! allocated nor overflowing.

use polycal::measurement::{Direction, MeasurementSet, Reading};

use crate::measurement_file_support::{assert_invalid, one_cycle, reading};

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
