//! The self-calibration file (docs/FORMAT.md §9.2) written: the documented header and rows,
//! and round trips through the writer and the reader — the good file, `write_path` and
//! `read_path`, extreme floats and random sets (proptest) — and arbitrary bytes, CSV-like
//! text and mutated good files read without a panic: a set that passes `from_readings`,
//! or an error with a line and a column.

use polycal::input::FileError;
use polycal::measurement::Direction;
use polycal::selfcal::{HeadReading, SelfcalSet};
use proptest::prelude::*;

use crate::selfcal_file_support::{
    BASE, data, read_bytes, read_good, reading, two_heads, without_lines,
};

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
