//! Readings and the measurement file (FORMAT.md §2).
//!
//! A [`MeasurementSet`] is a validated list of [`Reading`]s of one polygon with `faces`
//! faces. It is read from the measurement CSV with [`MeasurementSet::read_path`] (or
//! [`MeasurementSet::read_from`] for any reader, e.g. standard input) and written with
//! [`MeasurementSet::write_to`].

use std::fmt;

/// Rotation direction of a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Default)]
pub enum Direction {
    /// Clockwise (`cw`), the default.
    #[default]
    Cw,
    /// Counter-clockwise (`ccw`).
    Ccw,
}

impl Direction {
    /// The file spelling, `cw` or `ccw`.
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Cw => "cw",
            Direction::Ccw => "ccw",
        }
    }
}

impl fmt::Display for Direction {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// One autocollimator reading: one row of the measurement file.
#[derive(Debug, Clone, PartialEq)]
pub struct Reading {
    /// Polygon mounting on the table (shift-angle data), ≥ 1; default 1.
    pub setup: u32,
    /// Repeat number, ≥ 1.
    pub cycle: u32,
    /// Table stop 0 … N; N is the closing reading (table back at 360°).
    pub step: usize,
    /// Autocollimator number, ≥ 1.
    pub ac: u32,
    /// Polygon face read, 1 … N.
    pub face: usize,
    /// Autocollimator measuring-axis (X) value, arcseconds.
    pub reading_arcsec: f64,
    /// Rotation direction of the cycle.
    pub direction: Direction,
    /// Time since the run started, seconds, if recorded.
    pub time_seconds: Option<f64>,
    /// Second (elevation) axis, arcseconds, if recorded.
    pub reading_y_arcsec: Option<f64>,
    /// Air or instrument temperature, °C, if recorded.
    pub temperature_celsius: Option<f64>,
    /// Position the table reported at that stop, degrees, if recorded.
    pub encoder_degrees: Option<f64>,
    /// Line of the source file the reading came from (1-based); 0 when not from a file.
    pub line: u64,
}

impl Reading {
    /// The encoder position index `step mod N` (the closing step N is position 0).
    pub fn position(&self, faces: usize) -> usize {
        self.step % faces
    }
}

/// A validated set of readings of an N-faced polygon.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementSet {
    /// Number of polygon faces N (= number of encoder positions).
    pub faces: usize,
    /// The readings, in file order.
    pub readings: Vec<Reading>,
    /// Where the readings came from (a path, `-` for standard input, or a label).
    pub source: String,
}
