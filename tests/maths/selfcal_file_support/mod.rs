//! What the tests of the self-calibration file (`tests/maths/selfcal_file_*.rs`) share:
//! the two-head file `BASE` the bad files are made from, the files of tests/data/selfcal
//! read, bytes read or refused as a file, the assertion on a refusal's place and words,
//! and readings built by hand.

use std::path::{Path, PathBuf};

pub use crate::file_error_support::assert_invalid;
use polycal::input::FileError;
use polycal::measurement::Direction;
use polycal::selfcal::{HeadReading, SelfcalSet};

/// The file the bad files are made from: heads 1 and 2 at 0° and 180°, P = 3, one cycle.
pub const BASE: &str = "cycle,step,head,head_angle,reading\n\
                    1,0,1,0,0.5\n\
                    1,0,2,180,-0.25\n\
                    1,1,1,0,0.125\n\
                    1,1,2,180,0\n\
                    1,2,1,0,-0.5\n\
                    1,2,2,180,0.75\n";

pub fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/selfcal")
        .join(name)
}

pub fn read_good(name: &str, positions: Option<usize>) -> SelfcalSet {
    match SelfcalSet::read_path(data(name), positions) {
        Ok(set) => set,
        Err(e) => panic!("{name} should read: {e}"),
    }
}

pub fn read_bytes(bytes: &[u8], positions: Option<usize>) -> Result<SelfcalSet, FileError> {
    SelfcalSet::read_from(bytes, "mem.csv", positions)
}

pub fn refused_bytes(bytes: &[u8], positions: Option<usize>) -> FileError {
    match read_bytes(bytes, positions) {
        Ok(set) => panic!("should be refused, read {} readings", set.readings.len()),
        Err(e) => e,
    }
}

/// The readings with `line` cleared, to compare sets apart from where they came from.
pub fn without_lines(readings: &[HeadReading]) -> Vec<HeadReading> {
    readings
        .iter()
        .map(|r| HeadReading {
            line: 0,
            ..r.clone()
        })
        .collect()
}

pub fn reading(cycle: u32, step: usize, head: u32, angle: f64, value: f64) -> HeadReading {
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
pub fn two_heads(p: usize) -> Vec<HeadReading> {
    let mut readings = Vec::new();
    for step in 0..p {
        readings.push(reading(1, step, 1, 0.0, step as f64 * 0.25));
        readings.push(reading(1, step, 2, 180.0, -(step as f64) * 0.5));
    }
    readings
}
