//! Readings and the measurement file (FORMAT.md §2).
//!
//! A [`MeasurementSet`] is a validated list of [`Reading`]s of one polygon with `faces`
//! faces. It is read from the measurement CSV with [`MeasurementSet::read_path`] (or
//! [`MeasurementSet::read_from`] for any reader, e.g. standard input) and written with
//! [`MeasurementSet::write_to`]. Readings built in memory (by the simulator, say) are
//! checked with the same rules by [`MeasurementSet::from_readings`].
//!
//! # The rules
//!
//! The file is UTF-8 (a leading byte-order mark is allowed), comma separated, with one
//! header row and one reading per row; the columns may come in any order. Lines that
//! start with `#` before the header are comments; blank lines are skipped. The columns
//! `cycle`, `step`, `ac`, `face` and `reading` are required; `direction`, `time`,
//! `setup`, `reading_y`, `temperature` and `encoder` are optional, and an empty field
//! of an optional column means "not recorded" (or the default: `cw`, setup 1). Other
//! columns are ignored, except one whose name differs from a known name only by case,
//! spaces or `-` (such as `Face` or `reading y`): that is refused, so that no recorded
//! value is silently dropped.
//!
//! Nothing is guessed. The first problem found is reported as one
//! [`MeasurementError::Invalid`] naming the file, the 1-based line and the 1-based
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

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt;
use std::io::{self, BufWriter, Read, Write};
use std::path::Path;

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

/// Why a measurement file or a set of readings was refused, or could not be read or
/// written.
#[derive(Debug, thiserror::Error)]
pub enum MeasurementError {
    /// A file that breaks the rules: names the file, 1-based line and 1-based character column.
    ///
    /// Displayed as `file:line:column: message`, e.g.
    /// `run.csv:7:9: column "face": "x" is not an integer`.
    #[error("{file}:{line}:{column}: {message}")]
    Invalid {
        /// The file (the `source` name given; `-` for standard input).
        file: String,
        /// 1-based line of the offending field; for readings built in memory, the
        /// reading's [`Reading::line`] (0 when not from a file).
        line: u64,
        /// 1-based character column where the offending field starts on that line; 0
        /// for readings built in memory.
        column: u64,
        /// What is wrong, naming the column and quoting the offending text.
        message: String,
    },
    /// The file could not be opened, read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file (the `source` name given; `-` for standard input).
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl MeasurementSet {
    /// Reads a measurement CSV from a path; the path "-" reads standard input.
    ///
    /// `faces` is the `--faces N` option: N is the largest `face` in the file unless
    /// given. The path as displayed (or `-`) names the file in messages. See
    /// [`MeasurementSet::read_from`] for the rules.
    ///
    /// # Errors
    ///
    /// [`MeasurementError::Io`] if the file cannot be opened or read,
    /// [`MeasurementError::Invalid`] if it breaks a rule of FORMAT.md §2.
    pub fn read_path(path: &Path, faces: Option<usize>) -> Result<Self, MeasurementError> {
        if path == Path::new("-") {
            return Self::read_from(io::stdin().lock(), "-", faces);
        }
        let name = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|source| MeasurementError::Io {
            file: name.clone(),
            source,
        })?;
        Self::read_from(file, &name, faces)
    }

    /// Reads from any reader; `source` is the name used in messages.
    ///
    /// The whole input is read, then checked against FORMAT.md §2 (see the
    /// [module documentation](self)); the first problem found is returned as one
    /// [`MeasurementError::Invalid`]. `faces` is the `--faces N` option: N is the
    /// largest `face` unless given. Each [`Reading::line`] is the line its row starts on.
    ///
    /// # Errors
    ///
    /// [`MeasurementError::Io`] if reading fails, [`MeasurementError::Invalid`] if the
    /// input breaks a rule.
    ///
    /// # Example
    ///
    /// ```
    /// use polycal::measurement::{MeasurementError, MeasurementSet};
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
    /// # Ok::<(), MeasurementError>(())
    /// ```
    pub fn read_from<R: Read>(
        mut reader: R,
        source: &str,
        faces: Option<usize>,
    ) -> Result<Self, MeasurementError> {
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .map_err(|e| MeasurementError::Io {
                file: source.to_string(),
                source: e,
            })?;
        parse_bytes(&bytes, source, faces)
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
    /// [`MeasurementError::Invalid`] for the first rule broken.
    pub fn from_readings(
        readings: Vec<Reading>,
        faces: Option<usize>,
        source: &str,
    ) -> Result<Self, MeasurementError> {
        let n = validate(&readings, faces, &Locator::Memory, source)?;
        Ok(MeasurementSet {
            faces: n,
            readings,
            source: source.to_string(),
        })
    }

    /// Writes the measurement CSV (FORMAT.md §2); `comments` become leading `# ` lines.
    ///
    /// The header is `cycle,step,ac,face,reading,direction,setup`, followed by `time`,
    /// `reading_y`, `temperature` and `encoder`, each only if some reading has that
    /// value (a reading without it gets an empty field). Floats are written with Rust's
    /// `{}` formatting, the shortest text that reads back to the same `f64`, so reading
    /// the output back gives an equal set (apart from [`Reading::line`] and `source`).
    /// A comment holding line breaks becomes several comment lines. Rows keep the set's
    /// order; lines end with `\n`. Non-finite values (possible only in a set not built by
    /// this module) are written as Rust prints them and would be refused on reading.
    ///
    /// # Errors
    ///
    /// Any error of `writer`.
    pub fn write_to<W: Write>(&self, writer: W, comments: &[String]) -> io::Result<()> {
        let mut w = BufWriter::new(writer);
        for comment in comments {
            for line in split_lines(comment) {
                if line.is_empty() {
                    writeln!(w, "#")?;
                } else {
                    writeln!(w, "# {line}")?;
                }
            }
        }
        let has_time = self.readings.iter().any(|r| r.time_seconds.is_some());
        let has_y = self.readings.iter().any(|r| r.reading_y_arcsec.is_some());
        let has_temp = self
            .readings
            .iter()
            .any(|r| r.temperature_celsius.is_some());
        let has_encoder = self.readings.iter().any(|r| r.encoder_degrees.is_some());
        write!(w, "cycle,step,ac,face,reading,direction,setup")?;
        for (present, name) in [
            (has_time, "time"),
            (has_y, "reading_y"),
            (has_temp, "temperature"),
            (has_encoder, "encoder"),
        ] {
            if present {
                write!(w, ",{name}")?;
            }
        }
        writeln!(w)?;
        for r in &self.readings {
            write!(
                w,
                "{},{},{},{},{},{},{}",
                r.cycle, r.step, r.ac, r.face, r.reading_arcsec, r.direction, r.setup
            )?;
            for (present, value) in [
                (has_time, r.time_seconds),
                (has_y, r.reading_y_arcsec),
                (has_temp, r.temperature_celsius),
                (has_encoder, r.encoder_degrees),
            ] {
                if present {
                    match value {
                        Some(x) => write!(w, ",{x}")?,
                        None => write!(w, ",")?,
                    }
                }
            }
            writeln!(w)?;
        }
        w.flush()
    }

    /// Writes the measurement CSV to a file (created or truncated), as
    /// [`MeasurementSet::write_to`] does.
    ///
    /// # Errors
    ///
    /// [`MeasurementError::Io`] naming the path if the file cannot be created or written.
    pub fn write_path(&self, path: &Path, comments: &[String]) -> Result<(), MeasurementError> {
        let io_error = |source| MeasurementError::Io {
            file: path.display().to_string(),
            source,
        };
        let file = std::fs::File::create(path).map_err(io_error)?;
        self.write_to(file, comments).map_err(io_error)
    }

    /// Distinct (setup, ac) pairs in ascending order.
    ///
    /// Each pair is one *stream*: one autocollimator in one mounting of the polygon,
    /// with its own setup error U\[setup, ac\].
    pub fn streams(&self) -> Vec<(u32, u32)> {
        let set: BTreeSet<(u32, u32)> = self.readings.iter().map(|r| (r.setup, r.ac)).collect();
        set.into_iter().collect()
    }

    /// For each (setup, ac): the face offset d in 0..N such that face = (step + d) mod N + 1.
    ///
    /// Pairs are in ascending order, as [`MeasurementSet::streams`]. In a validated set
    /// every reading of a pair has the same offset; otherwise the first reading's is
    /// given. For the paper's design, autocollimator 1 has d = 0 and autocollimator 2
    /// has d = 1. Empty if `faces` is 0 (a set not built by this module).
    pub fn face_offsets(&self) -> Vec<((u32, u32), usize)> {
        let mut offsets = BTreeMap::new();
        if self.faces == 0 {
            return Vec::new();
        }
        for r in &self.readings {
            offsets
                .entry((r.setup, r.ac))
                .or_insert_with(|| face_offset(r.face, r.step, self.faces));
        }
        offsets.into_iter().collect()
    }
}

// ---------------------------------------------------------------------------------------
// Columns

/// The columns this module knows, in the order of FORMAT.md §2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Col {
    Cycle,
    Step,
    Ac,
    Face,
    Reading,
    Direction,
    Time,
    Setup,
    ReadingY,
    Temperature,
    Encoder,
}

const NCOLS: usize = 11;

impl Col {
    const ALL: [Col; NCOLS] = [
        Col::Cycle,
        Col::Step,
        Col::Ac,
        Col::Face,
        Col::Reading,
        Col::Direction,
        Col::Time,
        Col::Setup,
        Col::ReadingY,
        Col::Temperature,
        Col::Encoder,
    ];

    fn name(self) -> &'static str {
        match self {
            Col::Cycle => "cycle",
            Col::Step => "step",
            Col::Ac => "ac",
            Col::Face => "face",
            Col::Reading => "reading",
            Col::Direction => "direction",
            Col::Time => "time",
            Col::Setup => "setup",
            Col::ReadingY => "reading_y",
            Col::Temperature => "temperature",
            Col::Encoder => "encoder",
        }
    }

    fn required(self) -> bool {
        matches!(
            self,
            Col::Cycle | Col::Step | Col::Ac | Col::Face | Col::Reading
        )
    }

    fn from_name(name: &str) -> Option<Col> {
        Col::ALL.into_iter().find(|c| c.name() == name)
    }

    /// A known column that `name` resembles (differs only by case, surrounding spaces,
    /// or `-`/space for `_`), when `name` is not itself a known column.
    fn near_miss(name: &str) -> Option<Col> {
        let normal: String = name
            .trim_matches(|c: char| c.is_whitespace() || c == '\u{feff}')
            .chars()
            .map(|c| match c {
                '-' | ' ' => '_',
                c => c.to_ascii_lowercase(),
            })
            .collect();
        if normal == name {
            return None;
        }
        Col::from_name(&normal)
    }
}

// ---------------------------------------------------------------------------------------
// Positions in the text

/// Start offsets of the lines of a text; a line ends at `\n`, `\r\n` or a lone `\r`
/// (as for the CSV reader).
struct LineIndex<'a> {
    text: &'a str,
    starts: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    fn new(text: &'a str) -> Self {
        let bytes = text.as_bytes();
        let mut starts = vec![0];
        for (i, &b) in bytes.iter().enumerate() {
            if b == b'\n' || (b == b'\r' && bytes.get(i + 1) != Some(&b'\n')) {
                starts.push(i + 1);
            }
        }
        LineIndex { text, starts }
    }

    /// 0-based line index of a byte offset.
    fn line_of(&self, offset: usize) -> usize {
        self.starts
            .partition_point(|&s| s <= offset)
            .saturating_sub(1)
    }

    /// 1-based (line, character column) of a byte offset.
    fn location(&self, offset: usize) -> (u64, u64) {
        let offset = offset.min(self.text.len());
        let line = self.line_of(offset);
        let start = self.starts.get(line).copied().unwrap_or(0);
        let column = self
            .text
            .get(start..offset)
            .map_or(offset.saturating_sub(start), |s| s.chars().count());
        (to_u64(line) + 1, to_u64(column) + 1)
    }

    /// The text of a line (0-based), without its line break.
    fn line_text(&self, line: usize) -> &'a str {
        let start = self.starts.get(line).copied().unwrap_or(self.text.len());
        let end = self
            .starts
            .get(line + 1)
            .copied()
            .unwrap_or(self.text.len());
        self.text
            .get(start..end)
            .unwrap_or("")
            .trim_end_matches(['\r', '\n'])
    }
}

fn to_u64(x: usize) -> u64 {
    u64::try_from(x).unwrap_or(u64::MAX)
}

/// Where a record's fields start in the text, found by following the CSV quoting rules
/// from the position the CSV reader reports (which may lie before skipped blank lines).
struct Span {
    /// Byte offset where the record's first field starts.
    start: usize,
    /// Byte offsets where each field starts.
    fields: Vec<usize>,
    /// Byte offset just after the record's last field.
    end: usize,
}

impl Span {
    fn scan(bytes: &[u8], from: usize, fields: usize) -> Span {
        let mut pos = from;
        while matches!(bytes.get(pos), Some(b'\r' | b'\n')) {
            pos += 1;
        }
        if bytes
            .get(pos..)
            .is_some_and(|b| b.starts_with(b"\xef\xbb\xbf"))
        {
            pos += 3;
        }
        let start = pos;
        let mut starts = vec![pos];
        loop {
            if bytes.get(pos) == Some(&b'"') {
                pos += 1;
                loop {
                    match bytes.get(pos) {
                        None => break,
                        Some(b'"') if bytes.get(pos + 1) == Some(&b'"') => pos += 2,
                        Some(b'"') => {
                            pos += 1;
                            break;
                        }
                        Some(_) => pos += 1,
                    }
                }
            }
            while let Some(&b) = bytes.get(pos) {
                if matches!(b, b',' | b'\r' | b'\n') {
                    break;
                }
                pos += 1;
            }
            if bytes.get(pos) == Some(&b',') {
                pos += 1;
                starts.push(pos);
            } else {
                break;
            }
        }
        if starts.len() != fields {
            // The scan disagrees with the CSV reader: never guess a column.
            starts = vec![start; fields];
        }
        Span {
            start,
            fields: starts,
            end: pos,
        }
    }

    fn field(&self, i: usize) -> usize {
        self.fields.get(i).copied().unwrap_or(self.start)
    }
}

// ---------------------------------------------------------------------------------------
// Reading the file

/// Where the fields of one parsed row are, for messages.
struct RowLoc {
    start: usize,
    fields: [Option<usize>; NCOLS],
    direction_empty: bool,
}

/// Finds where a reading or a header column is, for messages.
enum Locator<'a> {
    File {
        index: &'a LineIndex<'a>,
        header_start: usize,
        header_fields: &'a [Option<usize>; NCOLS],
        rows: &'a [RowLoc],
    },
    Memory,
}

impl Locator<'_> {
    fn row(&self, i: usize, readings: &[Reading], col: Option<Col>) -> (u64, u64) {
        match self {
            Locator::File { index, rows, .. } => match rows.get(i) {
                Some(r) => {
                    let offset = col
                        .and_then(|c| r.fields.get(c as usize).copied().flatten())
                        .unwrap_or(r.start);
                    index.location(offset)
                }
                None => (readings.get(i).map_or(0, |r| r.line), 1),
            },
            Locator::Memory => (readings.get(i).map_or(0, |r| r.line), 0),
        }
    }

    fn header(&self, col: Option<Col>) -> (u64, u64) {
        match self {
            Locator::File {
                index,
                header_start,
                header_fields,
                ..
            } => {
                let offset = col
                    .and_then(|c| header_fields.get(c as usize).copied().flatten())
                    .unwrap_or(*header_start);
                index.location(offset)
            }
            Locator::Memory => (0, 0),
        }
    }

    /// `reading K: ` for an in-memory reading without a line, else nothing.
    fn prefix(&self, i: usize, readings: &[Reading]) -> String {
        match self {
            Locator::Memory if readings.get(i).is_none_or(|r| r.line == 0) => {
                format!("reading {}: ", i + 1)
            }
            _ => String::new(),
        }
    }

    /// How to name another reading in a message: `line L` or `reading K`.
    fn name(&self, i: usize, readings: &[Reading]) -> String {
        match readings.get(i) {
            Some(r) if r.line > 0 => format!("line {}", r.line),
            _ => format!("reading {}", i + 1),
        }
    }

    /// The direction text of a reading as it was written.
    fn direction_text(&self, i: usize, readings: &[Reading]) -> String {
        let direction = readings.get(i).map(|r| r.direction).unwrap_or_default();
        match self {
            Locator::File { rows, .. } if rows.get(i).is_some_and(|r| r.direction_empty) => {
                format!("\"\" (empty, meaning {direction})")
            }
            _ => format!("{:?}", direction.as_str()),
        }
    }

    fn no_rows(&self) -> &'static str {
        match self {
            Locator::File { .. } => "no data rows after the header",
            Locator::Memory => "no readings",
        }
    }
}

fn invalid(file: &str, (line, column): (u64, u64), message: String) -> MeasurementError {
    MeasurementError::Invalid {
        file: file.to_string(),
        line,
        column,
        message,
    }
}

/// The offending text for a message: quoted and escaped, cut after 40 characters.
fn show(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}...", text.get(..cut).unwrap_or(text)),
        None => format!("{text:?}"),
    }
}

fn split_lines(text: &str) -> impl Iterator<Item = &str> {
    text.split('\n')
        .flat_map(|line| line.strip_suffix('\r').unwrap_or(line).split('\r'))
}

fn parse_bytes(
    bytes: &[u8],
    source: &str,
    faces: Option<usize>,
) -> Result<MeasurementSet, MeasurementError> {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let text = match std::str::from_utf8(bytes) {
        Ok(text) => text,
        Err(e) => {
            let valid = bytes
                .get(..e.valid_up_to())
                .and_then(|b| std::str::from_utf8(b).ok())
                .unwrap_or("");
            let index = LineIndex::new(valid);
            let message = match (e.error_len(), bytes.get(e.valid_up_to())) {
                (Some(_), Some(b)) => {
                    format!("not valid UTF-8 (byte 0x{b:02x}); the file must be UTF-8 text")
                }
                _ => "not valid UTF-8 (a character is cut off at the end of the file); \
                      the file must be UTF-8 text"
                    .to_string(),
            };
            return Err(invalid(source, index.location(valid.len()), message));
        }
    };
    parse_text(text, source, faces)
}

fn parse_text(
    text: &str,
    source: &str,
    faces: Option<usize>,
) -> Result<MeasurementSet, MeasurementError> {
    let index = LineIndex::new(text);
    let bytes = text.as_bytes();
    let err = |offset: usize, message: String| invalid(source, index.location(offset), message);

    // Comment and blank lines before the header.
    let mut header_line = None;
    let mut last_comment = None;
    for line in 0..index.starts.len() {
        let content = index.line_text(line);
        if content.starts_with('#') {
            last_comment = Some(line);
        } else if !content.trim().is_empty() {
            header_line = Some(line);
            break;
        }
    }
    let Some(header_line) = header_line else {
        return Err(match last_comment {
            None => invalid(
                source,
                (1, 1),
                "empty file: expected a header row naming the columns \
                 cycle, step, ac, face, reading"
                    .to_string(),
            ),
            Some(line) => invalid(
                source,
                (to_u64(line) + 2, 1),
                "no header row: the file has only comment lines; expected a header row \
                 naming the columns cycle, step, ac, face, reading"
                    .to_string(),
            ),
        });
    };
    let header_start = index.starts.get(header_line).copied().unwrap_or(0);
    let rest = bytes.get(header_start..).unwrap_or(b"");
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(rest);
    let record_start = |record: &csv::StringRecord| {
        header_start
            + record
                .position()
                .and_then(|p| usize::try_from(p.byte()).ok())
                .unwrap_or(0)
    };
    let csv_error = |e: csv::Error| {
        let offset = e
            .position()
            .and_then(|p| usize::try_from(p.byte()).ok())
            .unwrap_or(0);
        err(header_start + offset, format!("unreadable CSV: {e}"))
    };

    // The header.
    let mut record = csv::StringRecord::new();
    if !reader.read_record(&mut record).map_err(csv_error)? {
        return Err(err(header_start, "no header row".to_string()));
    }
    let header: Vec<String> = record.iter().map(str::to_string).collect();
    let span = Span::scan(bytes, record_start(&record), header.len());
    let header_start = span.start;
    let mut columns: [Option<usize>; NCOLS] = [None; NCOLS];
    let mut seen: HashMap<&str, usize> = HashMap::new();
    for (j, name) in header.iter().enumerate() {
        if let Some(&first) = seen.get(name.as_str()) {
            let (_, column) = index.location(span.field(first));
            return Err(err(
                span.field(j),
                format!(
                    "column {} appears twice in the header (first at column {column})",
                    show(name)
                ),
            ));
        }
        seen.insert(name, j);
        match Col::from_name(name) {
            Some(c) => columns[c as usize] = Some(j),
            None => {
                if let Some(c) = Col::near_miss(name) {
                    return Err(err(
                        span.field(j),
                        format!(
                            "column {} is not a known column name but looks like {:?}; \
                             names are exact (lower case, no spaces)",
                            show(name),
                            c.name()
                        ),
                    ));
                }
            }
        }
    }
    let missing: Vec<String> = Col::ALL
        .into_iter()
        .filter(|c| c.required() && columns[*c as usize].is_none())
        .map(|c| format!("{:?}", c.name()))
        .collect();
    if !missing.is_empty() {
        let names: Vec<String> = header.iter().map(|n| show(n)).collect();
        return Err(err(
            header_start,
            format!(
                "missing required column{} {}; the header has {}",
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", "),
                names.join(", ")
            ),
        ));
    }
    let header_fields = columns.map(|j| j.map(|j| span.field(j)));

    // The rows.
    let mut readings = Vec::new();
    let mut rows = Vec::new();
    while reader.read_record(&mut record).map_err(csv_error)? {
        let span = Span::scan(bytes, record_start(&record), record.len());
        if record.len() <= 1 && index.line_text(index.line_of(span.start)).trim().is_empty() {
            continue; // a blank line of spaces
        }
        if record.len() != header.len() {
            return Err(if record.len() > header.len() {
                err(
                    span.field(header.len()),
                    format!(
                        "row has {} but the header has {}: extra field {}",
                        count(record.len(), "field"),
                        header.len(),
                        show(record.get(header.len()).unwrap_or(""))
                    ),
                )
            } else {
                err(
                    span.end,
                    format!(
                        "row has {} but the header has {}: no value for column {}",
                        count(record.len(), "field"),
                        header.len(),
                        show(header.get(record.len()).map_or("", String::as_str))
                    ),
                )
            });
        }
        let (reading, row) = parse_row(&record, &columns, &span, index.location(span.start).0)
            .map_err(|(offset, message)| err(offset, message))?;
        readings.push(reading);
        rows.push(row);
    }
    if readings.is_empty() {
        return Err(err(
            header_start,
            "no data rows after the header".to_string(),
        ));
    }

    let locator = Locator::File {
        index: &index,
        header_start,
        header_fields: &header_fields,
        rows: &rows,
    };
    let n = validate(&readings, faces, &locator, source)?;
    Ok(MeasurementSet {
        faces: n,
        readings,
        source: source.to_string(),
    })
}

/// Parses one data row (with the right number of fields); an error is (byte offset,
/// message).
fn parse_row(
    record: &csv::StringRecord,
    columns: &[Option<usize>; NCOLS],
    span: &Span,
    line: u64,
) -> Result<(Reading, RowLoc), (usize, String)> {
    let mut row = RowLoc {
        start: span.start,
        fields: [None; NCOLS],
        direction_empty: false,
    };
    let mut order: Vec<(usize, Col)> = Col::ALL
        .into_iter()
        .filter_map(|c| columns[c as usize].map(|j| (j, c)))
        .collect();
    order.sort_unstable_by_key(|&(j, _)| j);
    let (mut cycle, mut step, mut ac, mut face, mut value) = (None, None, None, None, None);
    let mut reading = Reading {
        setup: 1,
        cycle: 0,
        step: 0,
        ac: 0,
        face: 0,
        reading_arcsec: 0.0,
        direction: Direction::Cw,
        time_seconds: None,
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line,
    };
    for (j, col) in order {
        let text = record.get(j).unwrap_or("");
        let offset = span.field(j);
        row.fields[col as usize] = Some(offset);
        let at = |message: String| (offset, message);
        let u32_max = u128::from(u32::MAX);
        let usize_max = u128::try_from(usize::MAX).unwrap_or(u128::MAX);
        match col {
            Col::Cycle => cycle = Some(parse_int(text, col, 1, u32_max).map_err(at)?),
            Col::Step => step = Some(parse_int(text, col, 0, usize_max).map_err(at)?),
            Col::Ac => ac = Some(parse_int(text, col, 1, u32_max).map_err(at)?),
            Col::Face => face = Some(parse_int(text, col, 1, usize_max).map_err(at)?),
            Col::Reading => value = Some(parse_float(text, col).map_err(at)?),
            Col::Setup => {
                if !text.is_empty() {
                    let setup = parse_int(text, col, 1, u32_max).map_err(at)?;
                    reading.setup = u32::try_from(setup).map_err(|_| at(too_large(text, col)))?;
                }
            }
            Col::Direction => match text {
                "" => row.direction_empty = true,
                "cw" => reading.direction = Direction::Cw,
                "ccw" => reading.direction = Direction::Ccw,
                _ => {
                    return Err(at(format!(
                        "column \"direction\": {} is not a direction; use \"cw\" or \"ccw\"",
                        show(text)
                    )));
                }
            },
            Col::Time | Col::ReadingY | Col::Temperature | Col::Encoder => {
                let x = if text.is_empty() {
                    None
                } else {
                    Some(parse_float(text, col).map_err(at)?)
                };
                match col {
                    Col::Time => reading.time_seconds = x,
                    Col::ReadingY => reading.reading_y_arcsec = x,
                    Col::Temperature => reading.temperature_celsius = x,
                    _ => reading.encoder_degrees = x,
                }
            }
        }
    }
    let (Some(cycle), Some(step), Some(ac), Some(face), Some(value)) =
        (cycle, step, ac, face, value)
    else {
        return Err((
            span.start,
            "internal error: a required column was not read".to_string(),
        ));
    };
    let internal = |col: Col| {
        (
            row.fields[col as usize].unwrap_or(span.start),
            format!("column {:?}: value out of range", col.name()),
        )
    };
    reading.cycle = u32::try_from(cycle).map_err(|_| internal(Col::Cycle))?;
    reading.step = usize::try_from(step).map_err(|_| internal(Col::Step))?;
    reading.ac = u32::try_from(ac).map_err(|_| internal(Col::Ac))?;
    reading.face = usize::try_from(face).map_err(|_| internal(Col::Face))?;
    reading.reading_arcsec = value;
    Ok((reading, row))
}

/// `1 field`, `2 fields`.
fn count(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

fn too_large(text: &str, col: Col) -> String {
    format!("column {:?}: {} is too large", col.name(), show(text))
}

/// Parses an integer field `min ..= max`.
fn parse_int(text: &str, col: Col, min: u128, max: u128) -> Result<u128, String> {
    let name = col.name();
    if text.is_empty() {
        return Err(format!(
            "column {name:?}: empty; an integer of at least {min} is required"
        ));
    }
    let digits = text.strip_prefix(['+', '-']).unwrap_or(text);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("column {name:?}: {} is not an integer", show(text)));
    }
    let negative = text.starts_with('-');
    match digits.parse::<u128>() {
        Ok(0) if negative => {
            if min > 0 {
                Err(format!(
                    "column {name:?}: {} is not allowed; {name} must be at least {min}",
                    show(text)
                ))
            } else {
                Ok(0)
            }
        }
        Ok(_) if negative => Err(format!(
            "column {name:?}: {} is not allowed; {name} must be at least {min}",
            show(text)
        )),
        Ok(x) if x < min => Err(format!(
            "column {name:?}: {} is not allowed; {name} must be at least {min}",
            show(text)
        )),
        Ok(x) if x <= max => Ok(x),
        _ => Err(format!(
            "column {name:?}: {} is too large; {name} must be at most {max}",
            show(text)
        )),
    }
}

/// Parses a finite float field.
fn parse_float(text: &str, col: Col) -> Result<f64, String> {
    let name = col.name();
    if text.is_empty() {
        return Err(format!("column {name:?}: empty; a number is required"));
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        Ok(_) => Err(format!(
            "column {name:?}: {} is not a finite number",
            show(text)
        )),
        Err(_) => Err(format!("column {name:?}: {} is not a number", show(text))),
    }
}

// ---------------------------------------------------------------------------------------
// The structural rules

/// (face − 1 − step) mod N, without overflow for any N ≥ 1.
fn face_offset(face: usize, step: usize, n: usize) -> usize {
    let n128 = n as u128;
    if n128 == 0 {
        return 0;
    }
    let step = (step as u128) % n128;
    // face ≥ 1 in a validated set; `face + N − 1 − step` cannot underflow as step < N.
    let d = (face as u128 + n128 - 1 - step) % n128;
    usize::try_from(d).unwrap_or(0)
}

/// The face that offset `d` puts in front of the autocollimator at `step`.
fn expected_face(step: usize, d: usize, n: usize) -> u128 {
    let n128 = n as u128;
    if n128 == 0 {
        return 0;
    }
    ((step as u128) % n128 + d as u128) % n128 + 1
}

/// The values of `lo ..= hi` not in `present`, as ranges, and how many there are.
fn missing_ranges(present: &BTreeSet<usize>, lo: usize, hi: usize) -> (Vec<(usize, usize)>, u128) {
    let mut ranges = Vec::new();
    let mut next = Some(lo);
    for &x in present.range(lo..=hi) {
        let Some(cur) = next else { break };
        if x > cur {
            ranges.push((cur, x - 1));
        }
        next = x.checked_add(1);
    }
    if let Some(cur) = next
        && cur <= hi
    {
        ranges.push((cur, hi));
    }
    let count = ranges.iter().map(|&(a, b)| (b - a) as u128 + 1).sum();
    (ranges, count)
}

fn format_ranges(ranges: &[(usize, usize)]) -> String {
    const MAX: usize = 20;
    let mut parts: Vec<String> = ranges
        .iter()
        .take(MAX)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}-{b}")
            }
        })
        .collect();
    if ranges.len() > MAX {
        parts.push("...".to_string());
    }
    parts.join(", ")
}

/// Checks readings against the structural rules; returns N.
fn validate(
    readings: &[Reading],
    faces: Option<usize>,
    loc: &Locator<'_>,
    source: &str,
) -> Result<usize, MeasurementError> {
    let err = |at: (u64, u64), message: String| invalid(source, at, message);
    if readings.is_empty() {
        return Err(err(loc.header(None), loc.no_rows().to_string()));
    }

    // Values (already checked, with their text, when read from a file).
    for (i, r) in readings.iter().enumerate() {
        let p = loc.prefix(i, readings);
        for (col, zero) in [
            (Col::Cycle, r.cycle == 0),
            (Col::Ac, r.ac == 0),
            (Col::Face, r.face == 0),
            (Col::Setup, r.setup == 0),
        ] {
            if zero {
                let name = col.name();
                return Err(err(
                    loc.row(i, readings, Some(col)),
                    format!("{p}column {name:?}: 0 is not allowed; {name} must be at least 1"),
                ));
            }
        }
        for (col, x) in [
            (Col::Reading, Some(r.reading_arcsec)),
            (Col::Time, r.time_seconds),
            (Col::ReadingY, r.reading_y_arcsec),
            (Col::Temperature, r.temperature_celsius),
            (Col::Encoder, r.encoder_degrees),
        ] {
            if let Some(x) = x
                && !x.is_finite()
            {
                return Err(err(
                    loc.row(i, readings, Some(col)),
                    format!("{p}column {:?}: {x} is not a finite number", col.name()),
                ));
            }
        }
    }

    // N.
    let (n, n_from) = match faces {
        Some(n) => {
            if n < 3 {
                return Err(err(
                    loc.header(Some(Col::Face)),
                    format!("--faces {n}: a polygon needs at least 3 faces"),
                ));
            }
            (n, "given by --faces")
        }
        None => {
            let mut largest = 0;
            let mut at = 0;
            for (i, r) in readings.iter().enumerate() {
                if r.face > largest {
                    largest = r.face;
                    at = i;
                }
            }
            if largest < 3 {
                return Err(err(
                    loc.row(at, readings, Some(Col::Face)),
                    format!(
                        "{}column \"face\": the largest face is {largest}, so N = {largest}; \
                         a polygon needs at least 3 faces",
                        loc.prefix(at, readings)
                    ),
                ));
            }
            (largest, "the largest face")
        }
    };

    // Row by row, in order.
    let mut first_read: HashMap<(u32, u32, usize, u32), usize> = HashMap::new();
    let mut cycle_direction: HashMap<(u32, u32), usize> = HashMap::new();
    let mut stream_offset: HashMap<(u32, u32), (usize, usize)> = HashMap::new();
    for (i, r) in readings.iter().enumerate() {
        let p = loc.prefix(i, readings);
        let mut range = Vec::new();
        if r.face > n {
            range.push((
                loc.row(i, readings, Some(Col::Face)),
                format!(
                    "{p}column \"face\": {} is outside 1 to {n} (N = {n}, {n_from})",
                    r.face
                ),
            ));
        }
        if r.step > n {
            range.push((
                loc.row(i, readings, Some(Col::Step)),
                format!(
                    "{p}column \"step\": {} is outside 0 to {n} (N = {n}, {n_from})",
                    r.step
                ),
            ));
        }
        if let Some((at, message)) = range.into_iter().min_by_key(|(at, _)| *at) {
            return Err(err(at, message));
        }

        match first_read.entry((r.setup, r.cycle, r.step, r.ac)) {
            Entry::Occupied(first) => {
                return Err(err(
                    loc.row(i, readings, None),
                    format!(
                        "{p}duplicate reading: setup {}, cycle {}, step {}, ac {} was already \
                         read at {}",
                        r.setup,
                        r.cycle,
                        r.step,
                        r.ac,
                        loc.name(*first.get(), readings)
                    ),
                ));
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
            }
        }

        match cycle_direction.entry((r.setup, r.cycle)) {
            Entry::Occupied(first) => {
                let j = *first.get();
                let direction = readings.get(j).map(|f| f.direction).unwrap_or_default();
                if direction != r.direction {
                    return Err(err(
                        loc.row(i, readings, Some(Col::Direction)),
                        format!(
                            "{p}column \"direction\": {} disagrees with {} set for setup {}, \
                             cycle {} at {}; a cycle has one direction",
                            loc.direction_text(i, readings),
                            loc.direction_text(j, readings),
                            r.setup,
                            r.cycle,
                            loc.name(j, readings)
                        ),
                    ));
                }
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
            }
        }

        let d = face_offset(r.face, r.step, n);
        match stream_offset.entry((r.setup, r.ac)) {
            Entry::Occupied(first) => {
                let (d0, j) = *first.get();
                if d != d0 {
                    return Err(err(
                        loc.row(i, readings, Some(Col::Face)),
                        format!(
                            "{p}column \"face\": face {} at step {} does not fit setup {}, \
                             ac {}: face {} was expected, as {} set the offset \
                             (face - 1 - step) mod {n} = {d0} (N = {n}, {n_from})",
                            r.face,
                            r.step,
                            r.setup,
                            r.ac,
                            expected_face(r.step, d0, n),
                            loc.name(j, readings)
                        ),
                    ));
                }
            }
            Entry::Vacant(slot) => {
                slot.insert((d, i));
            }
        }
    }

    // Every face and every step.
    let present: BTreeSet<usize> = readings.iter().map(|r| r.face).collect();
    let (missing, count) = missing_ranges(&present, 1, n);
    if count > 0 {
        let (what, verb) = if count == 1 {
            ("face", "is")
        } else {
            ("faces", "are")
        };
        return Err(err(
            loc.header(Some(Col::Face)),
            format!(
                "column \"face\": {what} {} {verb} never read; every face 1 to {n} must be \
                 read (N = {n}, {n_from})",
                format_ranges(&missing)
            ),
        ));
    }
    let present: BTreeSet<usize> = readings.iter().map(|r| r.step).collect();
    let (missing, count) = missing_ranges(&present, 0, n - 1);
    if count > 0 {
        let (what, verb) = if count == 1 {
            ("step", "is")
        } else {
            ("steps", "are")
        };
        return Err(err(
            loc.header(Some(Col::Step)),
            format!(
                "column \"step\": {what} {} {verb} never present; every step 0 to {} must be \
                 present (N = {n}, {n_from})",
                format_ranges(&missing),
                n - 1
            ),
        ));
    }
    Ok(n)
}
