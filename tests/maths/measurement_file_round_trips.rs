//! The measurement file (docs/FORMAT.md §2) written: the documented header and rows, and
//! round trips through the writer and the reader — the good files, `write_path` and
//! `read_path`, extreme floats and random sets (proptest) — and arbitrary bytes or text
//! read without a panic.

use polycal::input::FileError;
use polycal::measurement::{Direction, MeasurementSet, Reading};
use proptest::prelude::*;

use crate::measurement_file_support::{
    assert_same_set, one_cycle, read_bytes, read_good, reading, round_trip,
};

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
