//! Readings and the measurement file (docs/FORMAT.md §2).
//!
//! A [`MeasurementSet`] is a validated list of [`Reading`]s of one polygon with `faces`
//! faces. It is read from the measurement CSV with [`MeasurementSet::read_path`] (or
//! [`MeasurementSet::read_from`] for any reader, e.g. standard input) and written with
//! [`MeasurementSet::write_to`], or one reading at a time with a [`ReadingWriter`].
//! Readings built in memory (by the simulator, say) are checked with the same rules by
//! [`MeasurementSet::from_readings`]; a file still being written is read, row by row,
//! with [`read_rows`].
//!
//! # The rules
//!
//! The file is UTF-8 (a leading byte-order mark is allowed), comma separated, with one
//! header row and one reading per row; the columns may come in any order. Lines that
//! start with `#` before the header are comments; blank lines are skipped. The columns
//! `cycle`, `step`, `ac`, `face` and `reading` are required; `direction`, `time`,
//! `setup`, `reading_y`, `temperature`, `encoder` and `shift` are optional, and an empty
//! field of an optional column means "not recorded" (or the default: `cw`, setup 1,
//! shift 0). Other
//! columns are ignored, except one whose name differs from a known name only by case,
//! spaces or `-` (such as `Face` or `reading y`): that is refused, so that no recorded
//! value is silently dropped.
//!
//! Nothing is guessed. The first problem found is reported as one
//! [`FileError::Invalid`] naming the file, the 1-based line and the 1-based
//! character column where the offending field starts, the column name and the offending
//! text. Row-level problems are reported in file order, before the whole-file checks for
//! faces and steps never read.
//!
//! N, the number of faces, is the largest `face` unless given (`--faces N`); it must be
//! at least 3. Every face 1 … N must be read, every step 0 … N−1 present (step N is the
//! optional closing reading). A (setup, cycle, step, ac) is read at most once, a
//! (setup, cycle) has one direction, and for each (setup, ac) the offset
//! (face − 1 − step) mod N is the same for every reading: each autocollimator looks at
//! the polygon from one fixed place.
//!
//! # Shifted mountings
//!
//! The `shift` column is the table's angle at step 0 of a mounting (`setup`), in degrees,
//! 0 ≤ shift < 360 (docs/FORMAT.md §2, §9.1): the same value on every row of one setup,
//! an empty field meaning 0. A [`Reading`] does not carry it: the set keeps one shift per
//! mounting in [`MeasurementSet::setup_shift_deg`] (the mountings whose shift is not 0;
//! [`MeasurementSet::shift_deg`] answers for any setup). Where a shift puts the encoder —
//! whole positions, or table angles between them — is [`crate::solve::sub_pitch`]'s
//! concern.

use crate::input::FileError;
use std::collections::BTreeMap;
use std::fmt;
use std::io::Read;
use std::path::Path;

mod columns;
pub mod cross_talk;
mod cycles;
mod parse;
mod sigma;
mod validate;
mod write;

pub use write::{Column, Columns, ReadingWriter};

pub use cycles::IncompleteCycle;
pub use sigma::{Sigma, SigmaError};

pub(crate) use columns::{DIRECTION_WORDS, direction_text};

use crate::input::table::Locator;
use columns::{SHIFT_RANGE, valid_shift};
use parse::{Rules, parse_bytes};
use validate::{face_offset, validate};

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

/// One table stop of a run: which cycle, which step, which direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stop {
    /// Cycle, from 1.
    pub cycle: u32,
    /// Step 0 … N (N is the closing reading).
    pub step: usize,
    /// Direction of the cycle.
    pub direction: Direction,
}

/// The stops of a run in the order the table visits them (docs/FORMAT.md §7): cycles 1 … R;
/// a clockwise cycle visits steps 0, 1, …, N−1 (and the closing step N when
/// `closing`); with `bidirectional` every second cycle is counter-clockwise and visits
/// N, N−1, …, 0 (the closing step is then implied for every cycle).
///
/// ```
/// use polycal::measurement::{Direction, run_stops};
/// let stops = run_stops(3, 2, false, true);
/// let steps: Vec<usize> = stops.iter().map(|s| s.step).collect();
/// assert_eq!(steps, [0, 1, 2, 3, 3, 2, 1, 0]);
/// assert_eq!(stops[4].direction, Direction::Ccw);
/// ```
pub fn run_stops(faces: usize, cycles: u32, closing: bool, bidirectional: bool) -> Vec<Stop> {
    let last = if closing || bidirectional {
        faces
    } else {
        faces.saturating_sub(1)
    };
    let mut stops = Vec::with_capacity(cycles as usize * (last + 1));
    for cycle in 1..=cycles {
        let direction = if bidirectional && cycle % 2 == 0 {
            Direction::Ccw
        } else {
            Direction::Cw
        };
        for i in 0..=last {
            let step = match direction {
                Direction::Cw => i,
                Direction::Ccw => last - i,
            };
            stops.push(Stop {
                cycle,
                step,
                direction,
            });
        }
    }
    stops
}

/// Reads the readings of a measurement file that is still being written, such as an
/// interrupted run's: the header and each row are checked as
/// [`MeasurementSet::read_from`] checks them, the rules about the set as a whole (every
/// face and step read, one offset per autocollimator, …) are not, and a file without a
/// header or without rows yet gives no readings. Each [`Reading::line`] is the line its
/// row starts on.
///
/// ```
/// use polycal::measurement::read_rows;
///
/// let partial = b"# cut short\ncycle,step,ac,face,reading\n1,0,1,1,0.5\n";
/// let readings = read_rows(&partial[..], "run.csv")?;
/// assert_eq!((readings.len(), readings[0].line), (1, 3));
/// assert!(read_rows(&b"# only a comment\n"[..], "run.csv")?.is_empty());
/// assert!(read_rows(&b"cycle,step,ac,face,reading\n1,0,1,x,0.5\n"[..], "run.csv").is_err());
/// # Ok::<(), polycal::input::FileError>(())
/// ```
///
/// # Errors
///
/// [`FileError::Io`] if reading fails, [`FileError::Invalid`] for the first
/// header or row that breaks a rule.
pub fn read_rows<R: Read>(reader: R, source: &str) -> Result<Vec<Reading>, FileError> {
    parse_bytes(&read_all(reader, source)?, source, Rules::Rows).map(|set| set.readings)
}

/// The whole input of `reader`; an error names `source`.
fn read_all<R: Read>(reader: R, source: &str) -> Result<Vec<u8>, FileError> {
    crate::input::read_limited(reader).map_err(|e| FileError::Io {
        file: source.to_string(),
        source: e,
    })
}

/// A validated set of readings of an N-faced polygon.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasurementSet {
    /// Number of polygon faces N (= number of encoder positions).
    pub faces: usize,
    /// The readings, in file order.
    pub readings: Vec<Reading>,
    /// Where the readings came from (a path, `<stdin>` for standard input, or a label).
    pub source: String,
    /// The table's angle at step 0 of each mounting whose `shift` is not 0, degrees
    /// (0 < shift < 360), by setup (docs/FORMAT.md §2): a setup not in the map has shift
    /// 0. The reader and [`MeasurementSet::with_setup_shifts`] store no 0; a set built in
    /// memory with [`MeasurementSet::from_readings`] starts with none.
    pub setup_shift_deg: BTreeMap<u32, f64>,
}

impl MeasurementSet {
    /// Reads a measurement CSV from a path; the path `-` reads standard input (named
    /// `<stdin>` in messages).
    ///
    /// `faces` is the `--faces N` option: N is the largest `face` in the file unless
    /// given. The path as displayed (or `<stdin>`) names the file in messages. See
    /// [`MeasurementSet::read_from`] for the rules.
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] if the file cannot be opened or read,
    /// [`FileError::Invalid`] if it breaks a rule of docs/FORMAT.md §2.
    pub fn read_path(path: &Path, faces: Option<usize>) -> Result<Self, FileError> {
        let (bytes, name) = crate::input::read_bytes(path)
            .map_err(|(file, source)| FileError::Io { file, source })?;
        parse_bytes(&bytes, &name, Rules::Set(faces))
    }

    /// Reads from any reader; `source` is the name used in messages.
    ///
    /// The whole input is read, then checked against docs/FORMAT.md §2 (see the
    /// [module documentation](self)); the first problem found is returned as one
    /// [`FileError::Invalid`]. `faces` is the `--faces N` option: N is the
    /// largest `face` unless given. Each [`Reading::line`] is the line its row starts on.
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] if reading fails, [`FileError::Invalid`] if the
    /// input breaks a rule.
    ///
    /// # Example
    ///
    /// ```
    /// use polycal::input::FileError;
    /// use polycal::measurement::MeasurementSet;
    ///
    /// let csv = b"# a 3-faced polygon, one autocollimator\n\
    ///             cycle,step,ac,face,reading\n\
    ///             1,0,1,1,0.5\n\
    ///             1,1,1,2,-0.25\n\
    ///             1,2,1,3,0.125\n";
    /// let set = MeasurementSet::read_from(&csv[..], "example.csv", None)?;
    /// assert_eq!(set.faces, 3);
    /// assert_eq!(set.readings.len(), 3);
    /// assert_eq!(set.readings[1].reading_arcsec, -0.25);
    /// assert_eq!(set.readings[1].line, 4);
    ///
    /// // A refused file names the file, line and column.
    /// let bad = b"cycle,step,ac,face,reading\n1,0,1,one,0.5\n";
    /// let err = MeasurementSet::read_from(&bad[..], "bad.csv", None).unwrap_err();
    /// assert_eq!(err.to_string(), r#"bad.csv:2:7: column "face": "one" is not an integer"#);
    /// # Ok::<(), FileError>(())
    /// ```
    pub fn read_from<R: Read>(
        reader: R,
        source: &str,
        faces: Option<usize>,
    ) -> Result<Self, FileError> {
        parse_bytes(&read_all(reader, source)?, source, Rules::Set(faces))
    }

    /// Validates readings built in memory (e.g. by the simulator) with the same structural rules.
    /// Errors use Reading::line (0 if not from a file) and column 0.
    ///
    /// The checks are those of [`MeasurementSet::read_from`] that apply to values:
    /// cycle, ac, setup and face at least 1, finite floats, N at least 3, face and step
    /// in range, every face and step present, no duplicate reading, one direction per
    /// cycle and one face offset per (setup, ac). When a reading's `line` is 0 the
    /// message starts with `reading K:` (1-based position in `readings`).
    ///
    /// # Errors
    ///
    /// [`FileError::Invalid`] for the first rule broken.
    pub fn from_readings(
        readings: Vec<Reading>,
        faces: Option<usize>,
        source: &str,
    ) -> Result<Self, FileError> {
        let n = validate(&readings, faces, &Locator::Memory, source)?;
        Ok(MeasurementSet {
            faces: n,
            readings,
            source: source.to_string(),
            setup_shift_deg: BTreeMap::new(),
        })
    }

    /// The set with these mountings shifted: `(setup, shift)` pairs, the table's angle at
    /// step 0 of that setup in degrees (the `shift` column, docs/FORMAT.md §2). Each shift
    /// must be finite with 0 ≤ shift < 360 and name a setup the set reads; a shift of 0
    /// is not stored, and a setup given again replaces its shift. Setups not given keep
    /// theirs.
    ///
    /// ```
    /// use polycal::simulate::{simulate, SimulationConfig};
    ///
    /// let (set, _) = simulate(&SimulationConfig { setups: 2, ..SimulationConfig::default() })?;
    /// let set = set.with_setup_shifts([(1, 0.0), (2, 7.5)])?;
    /// assert_eq!((set.shift_deg(1), set.shift_deg(2)), (0.0, 7.5));
    /// assert_eq!(set.setup_shift_deg.len(), 1);
    /// assert!(set.clone().with_setup_shifts([(3, 1.0)]).is_err()); // no setup 3
    /// assert!(set.with_setup_shifts([(2, 360.0)]).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    ///
    /// # Errors
    ///
    /// [`FileError::Invalid`] (line and column 0) naming the setup and the shift.
    pub fn with_setup_shifts(
        mut self,
        shifts: impl IntoIterator<Item = (u32, f64)>,
    ) -> Result<Self, FileError> {
        for (setup, shift) in shifts {
            let refuse = |message: String| {
                Err(FileError::invalid(
                    &self.source,
                    (0, 0),
                    format!("column \"shift\": setup {setup}: {message}"),
                ))
            };
            if !shift.is_finite() {
                return refuse(format!("{shift} is not a finite number"));
            }
            if !valid_shift(shift) {
                return refuse(format!("{shift} {}", SHIFT_RANGE));
            }
            if !self.readings.iter().any(|r| r.setup == setup) {
                return refuse("the set has no reading of this setup".to_string());
            }
            if shift == 0.0 {
                self.setup_shift_deg.remove(&setup);
            } else {
                self.setup_shift_deg.insert(setup, shift);
            }
        }
        Ok(self)
    }

    /// The table's angle at step 0 of `setup`, degrees: its `shift`, 0 unless stored in
    /// [`MeasurementSet::setup_shift_deg`].
    pub fn shift_deg(&self, setup: u32) -> f64 {
        self.setup_shift_deg.get(&setup).copied().unwrap_or(0.0)
    }

    /// Whether some mounting has a shift other than 0 (whole faces or not).
    pub fn has_shifts(&self) -> bool {
        self.setup_shift_deg.values().any(|&s| s != 0.0)
    }

    /// Distinct (setup, ac) pairs in ascending order.
    ///
    /// Each pair is one *stream*: one autocollimator in one mounting of the polygon,
    /// with its own setup error U\[setup, ac\].
    pub fn streams(&self) -> Vec<(u32, u32)> {
        self.distinct_streams()
            .into_iter()
            .map(|(k, _)| k)
            .collect()
    }

    /// Every (setup, ac) pair with its first reading's face offset, ascending: a scan
    /// against the few pairs found so far, a map once there are many.
    fn distinct_streams(&self) -> Vec<((u32, u32), usize)> {
        const SCAN_UP_TO: usize = 64;
        let offset = |r: &Reading| {
            if self.faces == 0 {
                0
            } else {
                face_offset(r.face, r.step, self.faces)
            }
        };
        let mut found: Vec<((u32, u32), usize)> = Vec::new();
        for (i, r) in self.readings.iter().enumerate() {
            let key = (r.setup, r.ac);
            if found.iter().any(|(k, _)| *k == key) {
                continue;
            }
            if found.len() == SCAN_UP_TO {
                let mut map: BTreeMap<(u32, u32), usize> = found.drain(..).collect();
                for r in &self.readings[i..] {
                    map.entry((r.setup, r.ac)).or_insert_with(|| offset(r));
                }
                return map.into_iter().collect();
            }
            found.push((key, offset(r)));
        }
        found.sort_unstable_by_key(|(k, _)| *k);
        found
    }

    /// For each (setup, ac): the face offset d in 0..N such that face = (step + d) mod N + 1
    /// ([`face_at`]).
    ///
    /// Pairs are in ascending order, as [`MeasurementSet::streams`]. In a validated set
    /// every reading of a pair has the same offset; otherwise the first reading's is
    /// given. For the paper's design, autocollimator 1 has d = 0 and autocollimator 2
    /// has d = 1. Empty if `faces` is 0 (a set not built by this module).
    pub fn face_offsets(&self) -> Vec<((u32, u32), usize)> {
        if self.faces == 0 {
            return Vec::new();
        }
        self.distinct_streams()
    }
}

/// The face an autocollimator reads at a step: (step + d) mod N + 1, for its face offset
/// d (0 … N−1) and N faces. This is the crate's one statement of the design's geometry
/// (docs/FORMAT.md §2): in the paper's design autocollimator 1 has d = 0 (face p + 1 at
/// step p) and autocollimator 2 has d = 1 (face p + 2, wrapping); the closing step N reads
/// the faces of step 0. [`MeasurementSet::face_offsets`] gives the inverse.
///
/// ```
/// use polycal::measurement::face_at;
/// assert_eq!(face_at(0, 1, 24), 2);
/// assert_eq!(face_at(23, 1, 24), 1);
/// assert_eq!(face_at(24, 0, 24), 1);
/// ```
pub fn face_at(step: usize, face_offset: usize, faces: usize) -> usize {
    if faces == 0 {
        return 0;
    }
    (step % faces + face_offset % faces) % faces + 1
}

/// The nominal table angle of table stop `step` of `steps` equally spaced stops,
/// step·360/steps degrees (docs/FORMAT.md §1: step p of an N-faced polygon at p·360°/N;
/// the `angle_deg` of encoder error p in a result file, §3). The product is exact and the
/// division rounded once, so equal angles of different spacings agree to the bit (step 1
/// of 24 and step 7 of 168 are both 15°); 0 ≤ angle < 360 for `step < steps`.
///
/// ```
/// use polycal::measurement::step_angle_deg;
/// assert_eq!(step_angle_deg(1, 24), 15.0);
/// assert_eq!(step_angle_deg(7, 168), 15.0);
/// assert_eq!(step_angle_deg(23, 24), 345.0);
/// ```
pub fn step_angle_deg(step: u32, steps: usize) -> f64 {
    f64::from(step) * 360.0 / steps as f64
}
