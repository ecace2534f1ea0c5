//! What the tests of the measurement file (`tests/maths/measurement_file_*.rs`) share: the
//! files of tests/data/measurement read or refused, bytes read as a file, the assertion on
//! a refusal's place and words, readings built by hand, and a set written and read back.

use std::path::{Path, PathBuf};

pub use crate::file_error_support::assert_invalid;
use polycal::input::FileError;
use polycal::measurement::{Direction, MeasurementSet, Reading};

pub fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/measurement")
        .join(name)
}

/// Reads a good file from tests/data/measurement.
pub fn read_good(name: &str, faces: Option<usize>) -> MeasurementSet {
    match MeasurementSet::read_path(&data(name), faces) {
        Ok(set) => set,
        Err(e) => panic!("{name} should read: {e}"),
    }
}

/// The error `MeasurementSet::read_path` gives for a bad file.
pub fn refusal(name: &str, faces: Option<usize>) -> FileError {
    match MeasurementSet::read_path(&data(name), faces) {
        Ok(set) => panic!(
            "{name} should be refused, read {} readings",
            set.readings.len()
        ),
        Err(e) => e,
    }
}

/// Asserts that bad file `name` is refused at `line:column` with `words` in the message.
pub fn assert_refused(name: &str, faces: Option<usize>, line: u64, column: u64, words: &[&str]) {
    let err = refusal(name, faces);
    let file = data(name).display().to_string();
    assert_invalid(&err, &file, line, column, words);
}

pub fn read_bytes(bytes: &[u8], faces: Option<usize>) -> Result<MeasurementSet, FileError> {
    MeasurementSet::read_from(bytes, "mem.csv", faces)
}

pub fn refused_bytes(bytes: &[u8], faces: Option<usize>) -> FileError {
    match read_bytes(bytes, faces) {
        Ok(set) => panic!("should be refused, read {} readings", set.readings.len()),
        Err(e) => e,
    }
}

/// The readings with `line` cleared, to compare sets apart from where they came from.
pub fn without_lines(readings: &[Reading]) -> Vec<Reading> {
    readings
        .iter()
        .map(|r| Reading {
            line: 0,
            ..r.clone()
        })
        .collect()
}

pub fn reading(cycle: u32, step: usize, ac: u32, face: usize, value: f64) -> Reading {
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
pub fn one_cycle(n: usize) -> Vec<Reading> {
    (0..n)
        .map(|p| reading(1, p, 1, p + 1, p as f64 * 0.25))
        .collect()
}

pub fn assert_same_set(a: &MeasurementSet, b: &MeasurementSet) {
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

pub fn round_trip(set: &MeasurementSet) -> MeasurementSet {
    let mut out = Vec::new();
    set.write_to(&mut out, &["round trip".to_string()]).unwrap();
    match MeasurementSet::read_from(&out[..], "written", None) {
        Ok(back) => back,
        Err(e) => panic!("{e}\n{}", String::from_utf8_lossy(&out)),
    }
}
