//! The one error of the crate's table files: why a measurement file, a self-calibration
//! file or a result file (or a set of readings checked by a file's rules) was refused,
//! or could not be read or written.

use crate::input::Location;
use crate::input::kind::FileKind;
use crate::input::table::TableError;

/// Why a table file — a measurement file (docs/FORMAT.md §2), a result file (§3) or a
/// self-calibration file (§9.2) — or a set of readings checked by its rules was refused,
/// or could not be read or written.
///
/// Every reader built on the crate's one table reader returns it:
/// [`MeasurementSet::read_path`](crate::measurement::MeasurementSet::read_path),
/// [`SelfcalSet::read_path`](crate::selfcal::SelfcalSet::read_path),
/// [`read_result_file`](crate::results::read_result_file) and their kin.
///
/// ```
/// use polycal::input::FileError;
/// use polycal::measurement::MeasurementSet;
///
/// let bad = b"cycle,step,ac,face,reading\n1,0,1,one,0.5\n";
/// let err = MeasurementSet::read_from(&bad[..], "bad.csv", None).unwrap_err();
/// assert!(matches!(err, FileError::Invalid { .. }));
/// assert_eq!(err.location().map(|at| (at.line(), at.column())), Some((2, 7)));
/// assert_eq!(err.to_string(), r#"bad.csv:2:7: column "face": "one" is not an integer"#);
///
/// let budget = b"p = 0.95\n[[component]]\n";
/// let err = MeasurementSet::read_from(&budget[..], "budget.toml", None).unwrap_err();
/// assert_eq!(err.found_kind(), Some(polycal::input::kind::FileKind::Budget));
/// ```
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FileError {
    /// A file that breaks the rules: names the file, 1-based line and 1-based character
    /// column.
    ///
    /// Displayed as `file:line:column: message`, e.g.
    /// `run.csv:7:9: column "face": "x" is not an integer`. For readings built in memory
    /// the line is the reading's own (its `line` field: 0 when not from a file) and the
    /// column 0; a 0 is left out of the display.
    #[error("{location}: {message}")]
    Invalid {
        /// Where: the file (the `source` name given; `<stdin>` for standard input), line
        /// and column.
        location: Location,
        /// What is wrong, naming the column and quoting the offending text.
        message: String,
    },
    /// A file of another kind than the one expected: a budget or a result file given as
    /// a measurement file, a measurement file given as a result file, … (docs/FORMAT.md
    /// §8). Displayed as `file:line:column: this is a budget (TOML, …), not a measurement
    /// file …`.
    #[error("{location}: {message}")]
    WrongKind {
        /// Where: the file and the line that tells its kind.
        location: Location,
        /// What the file is, and what was expected.
        message: String,
        /// What the file is.
        found: FileKind,
    },
    /// The file could not be opened, read or written. Displayed as `file: error`.
    #[error("{file}: {source}")]
    Io {
        /// The file (the `source` name given; `<stdin>` for standard input).
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl FileError {
    /// A refusal ([`FileError::Invalid`]) of `file` at a 1-based `(line, column)`, either
    /// 0 when not known.
    pub(crate) fn invalid(file: &str, (line, column): (u64, u64), message: String) -> Self {
        FileError::Invalid {
            location: Location::new(file, line, column),
            message,
        }
    }

    /// Where the problem is, for a refused file ([`FileError::Invalid`],
    /// [`FileError::WrongKind`]); `None` for an I/O error.
    pub fn location(&self) -> Option<&Location> {
        match self {
            FileError::Invalid { location, .. } | FileError::WrongKind { location, .. } => {
                Some(location)
            }
            FileError::Io { .. } => None,
        }
    }

    /// What the file is, when it is of another kind than the one expected
    /// ([`FileError::WrongKind`]).
    pub fn found_kind(&self) -> Option<FileKind> {
        match self {
            FileError::WrongKind { found, .. } => Some(*found),
            _ => None,
        }
    }
}

impl From<TableError> for FileError {
    /// The table reader's refusal: [`FileError::WrongKind`] when the text is a file of
    /// another kind, [`FileError::Invalid`] otherwise.
    fn from(e: TableError) -> Self {
        if let Some(found) = e.found() {
            return FileError::WrongKind {
                location: e.location,
                message: e.message,
                found,
            };
        }
        FileError::Invalid {
            location: e.location,
            message: e.message,
        }
    }
}
