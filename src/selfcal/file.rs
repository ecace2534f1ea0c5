//! The self-calibration CSV (docs/FORMAT.md §9.2): reading, validation, writing.
//!
//! A [`SelfcalSet`] is read with [`SelfcalSet::read_path`] (the path `-` is standard
//! input) or [`SelfcalSet::read_from`] for any reader, built from readings in memory (by
//! the simulator, say) with [`SelfcalSet::from_readings`], and written with
//! [`SelfcalSet::write_to`] (or [`SelfcalSet::write_with_comments`],
//! [`SelfcalSet::write_path`]).
//!
//! The rules are stated in the [`selfcal` module's documentation](crate::selfcal); this
//! module holds the public functions (a refusal is a [`FileError`]), `columns` the file's
//! columns, `parse` the reader, `validate` the rules beyond one field and `write` the
//! writer.

use std::io::Read;
use std::path::Path;

use super::{HeadReading, SelfcalSet};
use crate::input::FileError;

mod columns;
mod parse;
mod validate;
mod write;

/// The name readings checked by [`SelfcalSet::from_readings`] have in messages.
const MEMORY_NAME: &str = "<readings>";

/// The name [`SelfcalSet::write_to`] gives its writer in an I/O error.
const OUTPUT_NAME: &str = "<output>";

impl SelfcalSet {
    /// Whether a file's text is that of a self-calibration file: its header (its first
    /// line that is not a `#` comment) has the `head` and `head_angle` columns
    /// (docs/FORMAT.md §9.2). How `report` and `diagnose` tell it from a measurement file.
    ///
    /// ```
    /// use polycal::selfcal::SelfcalSet;
    /// assert!(SelfcalSet::is_selfcal_file(b"# SelfA\ncycle,step,head,head_angle,reading\n"));
    /// assert!(!SelfcalSet::is_selfcal_file(b"cycle,step,ac,face,reading\n"));
    /// ```
    pub fn is_selfcal_file(bytes: &[u8]) -> bool {
        let text = String::from_utf8_lossy(bytes);
        text.lines()
            .map(|l| l.trim_start_matches('\u{feff}'))
            .find(|l| !l.starts_with('#'))
            .is_some_and(|header| {
                let columns: Vec<&str> = header.split(',').map(str::trim).collect();
                columns.contains(&"head") && columns.contains(&"head_angle")
            })
    }

    /// Reads a self-calibration CSV from a path; the path `-` reads standard input (named
    /// `<stdin>` in messages).
    ///
    /// `positions` is the `--positions P` option: P is the largest `step` + 1 unless
    /// given. The path as displayed (or `<stdin>`) names the file in messages. See
    /// [`SelfcalSet::read_from`] and the [module documentation](crate::selfcal) for the rules.
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] if the file cannot be opened or read,
    /// [`FileError::Invalid`] if it breaks a rule of docs/FORMAT.md §9.2.
    pub fn read_path(path: impl AsRef<Path>, positions: Option<usize>) -> Result<Self, FileError> {
        let path = path.as_ref();
        let (bytes, name) = crate::input::read_bytes(path)
            .map_err(|(file, source)| FileError::Io { file, source })?;
        parse::parse_bytes(&bytes, &name, positions)
    }

    /// Reads a self-calibration CSV from any reader; `source` names it in messages.
    ///
    /// The whole input is read, then checked against docs/FORMAT.md §9.2 (see the
    /// [module documentation](crate::selfcal)); the first problem found is returned as one
    /// [`FileError::Invalid`]. `positions` is the `--positions P` option: P is the
    /// largest `step` + 1 unless given. Each [`HeadReading::line`] is the line its row
    /// starts on.
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] if reading fails, [`FileError::Invalid`] if the input
    /// breaks a rule.
    ///
    /// # Example
    ///
    /// ```
    /// use polycal::input::FileError;
    /// use polycal::selfcal::SelfcalSet;
    ///
    /// let csv = b"# two heads half a turn apart, three positions\n\
    ///             cycle,step,head,head_angle,reading\n\
    ///             1,0,1,0,0.5\n\
    ///             1,0,2,180,-0.25\n\
    ///             1,1,1,0,0.125\n\
    ///             1,1,2,180,0\n\
    ///             1,2,1,0,-0.5\n\
    ///             1,2,2,180,0.75\n";
    /// let set = SelfcalSet::read_from(&csv[..], "example.csv", None)?;
    /// assert_eq!(set.positions, 3);
    /// assert_eq!(set.readings.len(), 6);
    /// assert_eq!(set.readings[1].head_angle_deg, 180.0);
    /// assert_eq!(set.readings[1].reading_arcsec, -0.25);
    /// assert_eq!(set.readings[1].line, 4);
    /// assert_eq!(set.heads().len(), 2);
    ///
    /// // A refused file names the file, line and column.
    /// let bad = b"cycle,step,head,head_angle,reading\n1,0,1,0,0.5\n1,0,2,x,0.5\n";
    /// let err = SelfcalSet::read_from(&bad[..], "bad.csv", None).unwrap_err();
    /// assert_eq!(err.to_string(), r#"bad.csv:3:7: column "head_angle": "x" is not a number"#);
    /// # Ok::<(), FileError>(())
    /// ```
    pub fn read_from<R: Read>(
        reader: R,
        source: &str,
        positions: Option<usize>,
    ) -> Result<Self, FileError> {
        let bytes = crate::input::read_limited(reader).map_err(|e| FileError::Io {
            file: source.to_string(),
            source: e,
        })?;
        parse::parse_bytes(&bytes, source, positions)
    }

    /// Checks readings built in memory (e.g. by the simulator) by the rules of the file;
    /// P is the largest step + 1 unless given.
    ///
    /// The checks are those of [`SelfcalSet::read_from`] that apply to values: cycle and
    /// head at least 1, finite numbers, a head angle in [0, 360), P at least 3, steps
    /// below P, no duplicate reading, one direction per cycle, head 1 at angle 0, one
    /// angle per head, distinct angles of different heads, at least 2 heads, head 1
    /// present and every step read by every head in every cycle. An error names the file
    /// `<readings>`, the reading's [`HeadReading::line`] (0 when not from a file) and
    /// column 0; when the line is 0 the message starts with `reading K:` (1-based position
    /// in `readings`).
    ///
    /// # Errors
    ///
    /// [`FileError::Invalid`] for the first rule broken.
    pub fn from_readings(
        readings: Vec<HeadReading>,
        positions: Option<usize>,
    ) -> Result<Self, FileError> {
        let positions = validate::validate(
            &readings,
            positions,
            &crate::input::table::Locator::Memory,
            MEMORY_NAME,
        )?;
        Ok(Self {
            positions,
            readings,
        })
    }

    /// Checks a set built field by field (its fields are public) by the file's rules,
    /// with its own P: what [`SelfcalSet::from_readings`] checks. [`crate::selfcal::solve`]
    /// calls it first, so that no set reaches the solver unchecked.
    ///
    /// # Errors
    ///
    /// [`FileError::Invalid`] for the first rule broken.
    pub fn check(&self) -> Result<(), FileError> {
        validate::validate(
            &self.readings,
            Some(self.positions),
            &crate::input::table::Locator::Memory,
            MEMORY_NAME,
        )
        .map(|_| ())
    }

    /// Writes the self-calibration CSV (docs/FORMAT.md §9.2), without comments.
    ///
    /// The header is `cycle,step,head,head_angle,reading`, followed by `direction` if some
    /// reading is counter-clockwise and `time` if some reading has a time (a reading
    /// without one gets an empty field). Numbers are written with Rust's `{}` formatting,
    /// the shortest text that reads back to the same `f64`, so reading the output back
    /// gives an equal set (apart from [`HeadReading::line`]). Rows keep the set's order;
    /// lines end with `\n`. Values that break the rules (possible only in a set not built
    /// by this module) are written as they are and would be refused on reading.
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] (naming the file `<output>`) for any error of `w`.
    pub fn write_to<W: std::io::Write>(&self, w: W) -> Result<(), FileError> {
        self.write_with_comments(w, &[])
    }

    /// Writes the self-calibration CSV as [`SelfcalSet::write_to`] does, with `comments`
    /// as leading `# ` lines before the header (a comment holding line breaks becomes
    /// several lines, an empty comment a lone `#`).
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] (naming the file `<output>`) for any error of `w`.
    pub fn write_with_comments<W: std::io::Write>(
        &self,
        w: W,
        comments: &[String],
    ) -> Result<(), FileError> {
        write::write(self, w, comments).map_err(|source| FileError::Io {
            file: OUTPUT_NAME.to_string(),
            source,
        })
    }

    /// Writes the self-calibration CSV to a file, as [`SelfcalSet::write_with_comments`]
    /// does, whole or not at all ([`crate::output_file`]: a new file renamed over the old
    /// one).
    ///
    /// # Errors
    ///
    /// [`FileError::Io`] naming the path if the file cannot be created or written.
    pub fn write_path(&self, path: impl AsRef<Path>, comments: &[String]) -> Result<(), FileError> {
        let path = path.as_ref();
        let io_error = |source| FileError::Io {
            file: path.display().to_string(),
            source,
        };
        crate::output_file::write_file_with(path, |w| write::write(self, w, comments))
            .map_err(|e| io_error(e.into_io()))
    }
}
