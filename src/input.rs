//! Where input comes from: a file or standard input, and a position in it.
//!
//! Every file reader of the crate (measurement files, result files, budget files, truth
//! files, run directories) names the place of a problem with one [`Location`] (file, line,
//! column), displayed as `file:line:column` like a compiler's message, and names standard
//! input [`STDIN_NAME`]. The path `-` means standard input wherever a path is read
//! (docs/FORMAT.md §8).

pub(crate) mod text;
use std::fmt;
use std::io::{self, Read};
use std::path::Path;

/// The name standard input has in messages and results: `<stdin>`.
pub const STDIN_NAME: &str = "<stdin>";

/// The path that means standard input: `-`.
pub const STDIN_PATH: &str = "-";

/// A position in an input: file name, 1-based line and 1-based character column.
///
/// A line or column of 0 means "not known" (for example a reading built in memory, or a
/// problem with the file as a whole); [`Location`]'s `Display` then leaves it out.
///
/// ```
/// use polycal::input::Location;
///
/// let at = Location::new("run.csv", 7, 9);
/// assert_eq!(at.to_string(), "run.csv:7:9");
/// assert_eq!((at.file(), at.line(), at.column()), ("run.csv", 7, 9));
/// assert_eq!(Location::new("run.csv", 7, 0).to_string(), "run.csv:7");
/// assert_eq!(Location::file_only("run.csv").to_string(), "run.csv");
/// ```
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct Location {
    file: String,
    line: u64,
    column: u64,
}

impl Location {
    /// A position: the file's name as shown to people, 1-based line and column.
    pub fn new(file: impl Into<String>, line: u64, column: u64) -> Self {
        Self {
            file: file.into(),
            line,
            column,
        }
    }

    /// The file as a whole (line and column unknown).
    pub fn file_only(file: impl Into<String>) -> Self {
        Self::new(file, 0, 0)
    }

    /// The file's name as shown to people (a path, or [`STDIN_NAME`]).
    pub fn file(&self) -> &str {
        &self.file
    }

    /// The 1-based line, 0 when unknown.
    pub fn line(&self) -> u64 {
        self.line
    }

    /// The 1-based character column, 0 when unknown.
    pub fn column(&self) -> u64 {
        self.column
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.file)?;
        if self.line > 0 {
            write!(f, ":{}", self.line)?;
            if self.column > 0 {
                write!(f, ":{}", self.column)?;
            }
        }
        Ok(())
    }
}

/// Whether a path means standard input (`-`).
pub fn is_stdin(path: &Path) -> bool {
    path == Path::new(STDIN_PATH)
}

/// The name of a path in messages: the path as displayed, or [`STDIN_NAME`] for `-`.
pub fn display_name(path: &Path) -> String {
    if is_stdin(path) {
        STDIN_NAME.to_string()
    } else {
        path.display().to_string()
    }
}

/// Opens a path for reading, or standard input for `-`; returns the reader and the name
/// to use in messages ([`display_name`]).
///
/// # Errors
///
/// The I/O error of opening the file.
pub fn open(path: &Path) -> io::Result<(Box<dyn Read>, String)> {
    let name = display_name(path);
    if is_stdin(path) {
        return Ok((Box::new(io::stdin().lock()), name));
    }
    let file = std::fs::File::open(path)?;
    Ok((Box::new(file), name))
}

/// Reads a whole path (or standard input for `-`) as bytes; returns them with the name
/// to use in messages.
///
/// # Errors
///
/// The I/O error of opening or reading, with the name.
pub fn read_bytes(path: &Path) -> Result<(Vec<u8>, String), (String, io::Error)> {
    let (mut reader, name) = open(path).map_err(|e| (display_name(path), e))?;
    let mut bytes = Vec::new();
    reader
        .read_to_end(&mut bytes)
        .map_err(|e| (name.clone(), e))?;
    Ok((bytes, name))
}
