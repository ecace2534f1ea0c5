//! Writing the measurement CSV (docs/FORMAT.md §2): a whole set at once
//! ([`MeasurementSet::write_to`]), or one reading at a time as it is taken
//! ([`ReadingWriter`]), each with the columns it chooses ([`Columns`]).
//!
//! Floats are written with Rust's `{}` formatting, the shortest text that reads back to
//! the same `f64`; an optional value that is not recorded is an empty field; lines end
//! with `\n`.

use std::fmt::Write as _;
use std::io::{self, BufWriter, Write};
use std::path::Path;

use super::columns::Col;
use super::{MeasurementSet, Reading};
use crate::input::FileError;

/// A column of the measurement file (docs/FORMAT.md §2).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Column(Col);

impl Column {
    /// `cycle`: the repeat number.
    pub const CYCLE: Column = Column(Col::Cycle);
    /// `step`: the table stop.
    pub const STEP: Column = Column(Col::Step);
    /// `ac`: the autocollimator.
    pub const AC: Column = Column(Col::Ac);
    /// `face`: the polygon face read.
    pub const FACE: Column = Column(Col::Face);
    /// `reading`: the measuring axis (X), arcsec.
    pub const READING: Column = Column(Col::Reading);
    /// `direction`: `cw` or `ccw`.
    pub const DIRECTION: Column = Column(Col::Direction);
    /// `time`: seconds since the run started.
    pub const TIME: Column = Column(Col::Time);
    /// `setup`: the polygon's mounting.
    pub const SETUP: Column = Column(Col::Setup);
    /// `reading_y`: the second axis, arcsec.
    pub const READING_Y: Column = Column(Col::ReadingY);
    /// `temperature`: °C.
    pub const TEMPERATURE: Column = Column(Col::Temperature);
    /// `encoder`: the position the table reported, degrees.
    pub const ENCODER: Column = Column(Col::Encoder);
    /// `shift`: the table's angle at step 0 of the mounting, degrees. A [`Reading`] does
    /// not carry it (the set does, per setup): [`Columns::row`] writes 0,
    /// [`Columns::row_with_shift`] the shift given.
    pub const SHIFT: Column = Column(Col::Shift);

    /// The column's name in the header, e.g. `reading_y`.
    pub fn name(self) -> &'static str {
        self.0.name()
    }

    /// Appends the field of `reading` in this column (empty for a value not recorded), with
    /// `shift_deg` the shift of its mounting.
    fn write_field(self, reading: &Reading, shift_deg: f64, out: &mut String) {
        let optional = |value: Option<f64>| value.map(|x| x.to_string()).unwrap_or_default();
        let field = match self.0 {
            Col::Cycle => reading.cycle.to_string(),
            Col::Step => reading.step.to_string(),
            Col::Ac => reading.ac.to_string(),
            Col::Face => reading.face.to_string(),
            Col::Reading => reading.reading_arcsec.to_string(),
            Col::Direction => reading.direction.to_string(),
            Col::Setup => reading.setup.to_string(),
            Col::Time => optional(reading.time_seconds),
            Col::ReadingY => optional(reading.reading_y_arcsec),
            Col::Temperature => optional(reading.temperature_celsius),
            Col::Encoder => optional(reading.encoder_degrees),
            Col::Shift => shift_deg.to_string(),
        };
        out.push_str(&field);
    }
}

/// The columns of a measurement file, in order: its header and the row of each reading.
///
/// ```
/// use polycal::measurement::{Column, Columns, Direction, Reading};
///
/// let columns = Columns::new([Column::CYCLE, Column::STEP, Column::AC, Column::FACE,
///                             Column::READING, Column::READING_Y]);
/// assert_eq!(columns.header(), "cycle,step,ac,face,reading,reading_y");
/// let reading = Reading {
///     setup: 1, cycle: 2, step: 3, ac: 1, face: 4, reading_arcsec: -0.25,
///     direction: Direction::Cw, time_seconds: None, reading_y_arcsec: None,
///     temperature_celsius: None, encoder_degrees: None, line: 0,
/// };
/// assert_eq!(columns.row(&reading), "2,3,1,4,-0.25,");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Columns(Vec<Column>);

impl Columns {
    /// These columns, in this order. A file that is to be read back needs the required
    /// columns (`cycle`, `step`, `ac`, `face`, `reading`), each once.
    pub fn new(columns: impl Into<Vec<Column>>) -> Columns {
        Columns(columns.into())
    }

    /// The columns, in order.
    pub fn as_slice(&self) -> &[Column] {
        &self.0
    }

    /// The header row, without its line feed.
    pub fn header(&self) -> String {
        let names: Vec<&str> = self.0.iter().map(|c| c.name()).collect();
        names.join(",")
    }

    /// The row of `reading`, without its line feed (a `shift` column gets 0).
    pub fn row(&self, reading: &Reading) -> String {
        self.row_with_shift(reading, 0.0)
    }

    /// The row of `reading` of a mounting shifted by `shift_deg` degrees (the `shift`
    /// column), without its line feed.
    pub fn row_with_shift(&self, reading: &Reading, shift_deg: f64) -> String {
        let mut out = String::new();
        for (i, column) in self.0.iter().enumerate() {
            if i > 0 {
                out.push(',');
            }
            column.write_field(reading, shift_deg, &mut out);
        }
        out
    }
}

/// Writes a measurement file one reading at a time: the comments and the header once,
/// then one row per reading, each with a single `write_all` so that an unbuffered file
/// holds every row written whole or, if the process dies within it, the start of the
/// last one.
///
/// ```
/// use polycal::measurement::{Column, Columns, Direction, Reading, ReadingWriter};
///
/// let columns = Columns::new([Column::CYCLE, Column::STEP, Column::AC, Column::FACE,
///                             Column::READING]);
/// let mut w = ReadingWriter::start(Vec::new(), columns, &["a run".to_string()])?;
/// let mut reading = Reading {
///     setup: 1, cycle: 1, step: 0, ac: 1, face: 1, reading_arcsec: 0.5,
///     direction: Direction::Cw, time_seconds: None, reading_y_arcsec: None,
///     temperature_celsius: None, encoder_degrees: None, line: 0,
/// };
/// w.write(&reading)?;
/// reading.ac = 2;
/// reading.face = 2;
/// w.write(&reading)?;
/// assert_eq!(
///     String::from_utf8(w.into_inner()).unwrap(),
///     "# a run\ncycle,step,ac,face,reading\n1,0,1,1,0.5\n1,0,2,2,0.5\n"
/// );
/// # Ok::<(), std::io::Error>(())
/// ```
#[derive(Debug)]
pub struct ReadingWriter<W> {
    writer: W,
    columns: Columns,
}

impl<W: Write> ReadingWriter<W> {
    /// Starts a new file on `writer`: `comments` as leading `# ` lines (a comment holding
    /// line breaks becomes several lines, an empty line a lone `#`), then the header,
    /// with one `write_all`.
    ///
    /// # Errors
    ///
    /// Any error of `writer`.
    pub fn start(
        mut writer: W,
        columns: Columns,
        comments: &[String],
    ) -> io::Result<ReadingWriter<W>> {
        let mut text = String::new();
        for comment in comments {
            for line in split_lines(comment) {
                if line.is_empty() {
                    text.push_str("#\n");
                } else {
                    // Writing to a String cannot fail.
                    let _ = writeln!(text, "# {line}");
                }
            }
        }
        text.push_str(&columns.header());
        text.push('\n');
        writer.write_all(text.as_bytes())?;
        Ok(ReadingWriter { writer, columns })
    }

    /// Continues a file whose header (of these columns) is already written: rows are
    /// appended to `writer`.
    pub fn resume(writer: W, columns: Columns) -> ReadingWriter<W> {
        ReadingWriter { writer, columns }
    }

    /// Writes the row of `reading`, line feed included, with one `write_all` (a `shift`
    /// column gets 0).
    ///
    /// # Errors
    ///
    /// Any error of `writer`.
    pub fn write(&mut self, reading: &Reading) -> io::Result<()> {
        self.write_with_shift(reading, 0.0)
    }

    /// Writes the row of `reading` of a mounting shifted by `shift_deg` degrees (the
    /// `shift` column), line feed included, with one `write_all`.
    ///
    /// # Errors
    ///
    /// Any error of `writer`.
    pub fn write_with_shift(&mut self, reading: &Reading, shift_deg: f64) -> io::Result<()> {
        let mut row = self.columns.row_with_shift(reading, shift_deg);
        row.push('\n');
        self.writer.write_all(row.as_bytes())
    }

    /// The columns.
    pub fn columns(&self) -> &Columns {
        &self.columns
    }

    /// The writer.
    pub fn get_ref(&self) -> &W {
        &self.writer
    }

    /// The writer, mutably.
    pub fn get_mut(&mut self) -> &mut W {
        &mut self.writer
    }

    /// The writer, given back.
    pub fn into_inner(self) -> W {
        self.writer
    }
}

impl MeasurementSet {
    /// The columns [`MeasurementSet::write_to`] writes: `cycle,step,ac,face,reading,
    /// direction,setup`, followed by `time`, `reading_y`, `temperature` and `encoder`,
    /// each only if some reading has that value, and `shift` when some mounting's shift
    /// is not 0.
    pub fn columns(&self) -> Columns {
        let mut columns = vec![
            Column::CYCLE,
            Column::STEP,
            Column::AC,
            Column::FACE,
            Column::READING,
            Column::DIRECTION,
            Column::SETUP,
        ];
        let any =
            |value: fn(&Reading) -> Option<f64>| self.readings.iter().any(|r| value(r).is_some());
        for (present, column) in [
            (any(|r| r.time_seconds), Column::TIME),
            (any(|r| r.reading_y_arcsec), Column::READING_Y),
            (any(|r| r.temperature_celsius), Column::TEMPERATURE),
            (any(|r| r.encoder_degrees), Column::ENCODER),
        ] {
            if present {
                columns.push(column);
            }
        }
        if self.has_shifts() {
            columns.push(Column::SHIFT);
        }
        Columns::new(columns)
    }

    /// Writes the measurement CSV (docs/FORMAT.md §2); `comments` become leading `# ` lines.
    ///
    /// The columns are [`MeasurementSet::columns`]; a reading without a value of an
    /// optional column gets an empty field. Floats are written with Rust's `{}`
    /// formatting, the shortest text that reads back to the same `f64`, so reading the
    /// output back gives an equal set (apart from [`Reading::line`] and `source`; the
    /// shifts of the mountings included). A
    /// comment holding line breaks becomes several comment lines. Rows keep the set's
    /// order; lines end with `\n`. Non-finite values (possible only in a set not built by
    /// this module) are written as Rust prints them and would be refused on reading.
    ///
    /// # Errors
    ///
    /// Any error of `writer`.
    pub fn write_to<W: Write>(&self, writer: W, comments: &[String]) -> io::Result<()> {
        let mut w = ReadingWriter::start(BufWriter::new(writer), self.columns(), comments)?;
        for reading in &self.readings {
            w.write_with_shift(reading, self.shift_deg(reading.setup))?;
        }
        w.into_inner().flush()
    }

    /// Writes the measurement CSV to a file, as [`MeasurementSet::write_to`] does, whole
    /// or not at all ([`crate::output_file`]: a new file renamed over the old one).
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] naming the path if the file cannot be created or written.
    pub fn write_path(&self, path: &Path, comments: &[String]) -> Result<(), FileError> {
        let io_error = |source| FileError::Io {
            file: path.display().to_string(),
            source,
        };
        crate::output_file::write_file_with(path, |w| self.write_to(w, comments))
            .map_err(|e| io_error(e.into_io()))
    }
}

/// The lines of a comment: split at `\n`, `\r\n` and a lone `\r`.
fn split_lines(text: &str) -> impl Iterator<Item = &str> {
    text.split('\n')
        .flat_map(|line| line.strip_suffix('\r').unwrap_or(line).split('\r'))
}
