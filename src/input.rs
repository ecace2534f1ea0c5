//! Where input comes from: a file or standard input, and a position in it.
//!
//! Every file reader of the crate (measurement files, result files, budget files, truth
//! files, run directories) names the place of a problem with one [`Location`] (file, line,
//! column), displayed as `file:line:column` like a compiler's message, and names standard
//! input [`STDIN_NAME`]. The path `-` means standard input wherever a path is read
//! (docs/FORMAT.md §8).
//!
//! The crate's CSV tables (the measurement file, the self-calibration file, the result
//! file) are read by one table reader (the crate's `input::table`): each file kind
//! describes its columns, and the rules of the text, the header and the rows, with their
//! messages, are the reader's. A table file is refused, or fails to be read or written,
//! with one error, [`FileError`], whatever its kind.

mod error;
pub mod kind;
pub mod limits;
pub(crate) mod table;
pub(crate) mod text;

pub use error::FileError;

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

/// The name of a path in messages, tables and reports: the path as displayed (bytes
/// that are not UTF-8 as U+FFFD), its control characters shown escaped (`\u{1b}`,
/// `\n`: a file name cannot recolour a terminal or forge a line; docs/FORMAT.md §8), or
/// [`STDIN_NAME`] for `-`.
///
/// ```
/// use polycal::input::display_name;
/// use std::path::Path;
/// assert_eq!(display_name(Path::new("run 1.csv")), "run 1.csv");
/// assert_eq!(display_name(Path::new("a\u{1b}[31mb.csv")), "a\\u{1b}[31mb.csv");
/// assert_eq!(display_name(Path::new("-")), "<stdin>");
/// ```
pub fn display_name(path: &Path) -> String {
    if is_stdin(path) {
        return STDIN_NAME.to_string();
    }
    shown_path(path)
}

/// A path as given, for the `file` of results, tables and reports (`-` stays `-`): as
/// displayed, its control characters shown escaped as [`display_name`] shows them.
pub fn shown_path(path: &Path) -> String {
    escaped(&path.display().to_string()).into_owned()
}

/// A file as a document handed to a customer names it (the report, the DCC, figures):
/// its file name alone, never the directories of the machine that wrote it (the SHA-256
/// beside it identifies the file); escaped as [`display_name`] escapes, [`STDIN_NAME`]
/// for standard input. Works on a name already shown (`display_name`'s text) as well.
///
/// ```
/// use polycal::input::document_name;
/// assert_eq!(document_name("/home/lab/runs/p24.csv"), "p24.csv");
/// assert_eq!(document_name("data/p24.csv"), "p24.csv");
/// assert_eq!(document_name("p24.csv"), "p24.csv");
/// assert_eq!(document_name("-"), "<stdin>");
/// assert_eq!(document_name("<stdin>"), "<stdin>");
/// ```
pub fn document_name(path: &str) -> String {
    let path = Path::new(path);
    if is_stdin(path) {
        return STDIN_NAME.to_string();
    }
    match path.file_name() {
        Some(name) => escaped(&name.to_string_lossy()).into_owned(),
        None => display_name(path),
    }
}

/// A text with its control characters and bidirectional formatting characters shown
/// escaped (`\n`, `\u{1b}`, `\u{202e}`, …): a file or laboratory name with an escape
/// sequence or a line feed cannot recolour a terminal or forge a line of its own, nor one
/// with a right-to-left override display as another name (docs/FORMAT.md §8, §12). The
/// one place names and messages are escaped ([`is_shown_escaped`] tells which characters).
///
/// ```
/// use polycal::input::escaped;
/// assert_eq!(escaped("plain ünïcode"), "plain ünïcode");
/// assert_eq!(escaped("a\u{1b}[31m\n"), "a\\u{1b}[31m\\n");
/// assert_eq!(escaped("PTB\u{202e}LPN"), "PTB\\u{202e}LPN");
/// ```
pub fn escaped(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains(is_shown_escaped) {
        return std::borrow::Cow::Borrowed(text);
    }
    std::borrow::Cow::Owned(
        text.chars()
            .map(|c| {
                if is_shown_escaped(c) {
                    c.escape_default().to_string()
                } else {
                    c.to_string()
                }
            })
            .collect(),
    )
}

/// Whether [`escaped`] shows `c` escaped: a control character, or a bidirectional
/// formatting character ([`is_bidi_control`]).
pub fn is_shown_escaped(c: char) -> bool {
    c.is_control() || is_bidi_control(c)
}

/// Whether `c` is a bidirectional formatting character — the marks U+200E, U+200F,
/// U+061C, the embeddings and overrides U+202A–U+202E, the isolates U+2066–U+2069 — which
/// reorders the text around it on screen, so that a name can display as another.
pub fn is_bidi_control(c: char) -> bool {
    matches!(
        c,
        '\u{061C}' | '\u{200E}' | '\u{200F}' | '\u{202A}'..='\u{202E}' | '\u{2066}'..='\u{2069}'
    )
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

/// The most bytes polycal reads from one input file or stream: 256 MiB. A measurement
/// file of a million readings takes about 50 MiB; an input beyond the limit is refused
/// (a regular file before it is read, a stream once the limit is passed), never read
/// until memory runs out.
pub const MAX_INPUT_BYTES: u64 = 256 << 20;

/// The error of an input larger than [`MAX_INPUT_BYTES`] (kind `FileTooLarge`).
fn too_large(bytes: u64, at_least: bool) -> io::Error {
    let size = if at_least {
        format!("at least {bytes} bytes")
    } else {
        format!("{bytes} bytes")
    };
    io::Error::new(
        io::ErrorKind::FileTooLarge,
        format!("{size}, more than polycal reads from one input ({MAX_INPUT_BYTES} bytes at most)"),
    )
}

/// Reads a reader to its end, refusing it once it passes [`MAX_INPUT_BYTES`].
///
/// # Errors
///
/// The reader's I/O error, or one of kind `FileTooLarge` naming the size and the limit.
pub fn read_limited(reader: impl Read) -> io::Result<Vec<u8>> {
    let mut bytes = Vec::new();
    reader.take(MAX_INPUT_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_INPUT_BYTES {
        return Err(too_large(bytes.len() as u64, true));
    }
    Ok(bytes)
}

/// Reads a whole path (or standard input for `-`) as bytes; returns them with the name
/// to use in messages. A regular file larger than [`MAX_INPUT_BYTES`] is refused before
/// it is read; a stream (standard input, a pipe, a device) is read to the limit and no
/// further.
///
/// # Errors
///
/// The I/O error of opening or reading, or one of kind `FileTooLarge`, with the name.
pub fn read_bytes(path: &Path) -> Result<(Vec<u8>, String), (String, io::Error)> {
    let (reader, name) = open(path).map_err(|e| (display_name(path), e))?;
    if !is_stdin(path)
        && let Ok(meta) = std::fs::metadata(path)
        && meta.is_file()
        && meta.len() > MAX_INPUT_BYTES
    {
        return Err((name, too_large(meta.len(), false)));
    }
    let bytes = read_limited(reader).map_err(|e| (name.clone(), e))?;
    Ok((bytes, name))
}
