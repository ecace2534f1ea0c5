//! Where the header and the rows of a table read are, so that a file kind's own rules
//! (checked after the rows are read) name the line and column of a field the way the
//! reader does; and the same rules' places for rows built in memory.
//!
//! A row keeps only where its record starts (one offset): the field positions and the
//! text of a field are found again from there, following the CSV rules, only for a
//! message.

use super::show;
use crate::input::text::{LineIndex, Span};

/// The positions of a table's header and rows in its text.
pub(crate) struct Positions<'t> {
    pub(super) index: LineIndex<'t>,
    pub(super) bytes: &'t [u8],
    /// Whether fields are trimmed ([`Dialect::trimmed`](super::Dialect)): a field's place
    /// is then where its text starts, after the spaces.
    pub(super) trimmed: bool,
    /// Byte offset where the header's first field starts.
    pub(super) header_start: usize,
    /// Byte offset of each described column's name in the header.
    pub(super) header_fields: Vec<Option<usize>>,
    /// The header field of each described column.
    pub(super) field_of: Vec<Option<usize>>,
    /// The number of fields of the header (and of every row).
    pub(super) fields: usize,
    /// Where the CSV reader found each row (blank lines before it included).
    pub(super) rows: Vec<usize>,
}

impl Positions<'_> {
    /// The 1-based (line, column) of a byte offset.
    fn location(&self, offset: usize) -> (u64, u64) {
        self.index.location(offset)
    }

    /// Where field `j` of a record starts: as the CSV rules place it, or, in a trimmed
    /// dialect, after the spaces that precede its text (never past the record's line).
    pub(super) fn field_start(&self, span: &Span, j: usize) -> usize {
        let start = span.field(j);
        if !self.trimmed {
            return start;
        }
        // the text of `bytes` (a field starts after a comma or a line break: a character
        // boundary)
        let spaces: usize = (self.index.text.get(start..).unwrap_or(""))
            .chars()
            .take_while(|&c| c.is_whitespace() && c != '\r' && c != '\n')
            .map(char::len_utf8)
            .sum();
        start + spaces
    }

    /// The (line, column) of the header's name of column `c`, or of the header's start.
    pub(crate) fn header(&self, c: Option<usize>) -> (u64, u64) {
        let offset = c
            .and_then(|c| self.header_fields.get(c).copied().flatten())
            .unwrap_or(self.header_start);
        self.location(offset)
    }

    /// The (line, column) of row `i`'s field of column `c`, or of the row's start; `None`
    /// when no row `i` was read.
    pub(crate) fn row(&self, i: usize, c: Option<usize>) -> Option<(u64, u64)> {
        let &position = self.rows.get(i)?;
        let span = Span::scan(self.bytes, position, self.fields);
        let offset = match c.and_then(|c| self.field_of.get(c).copied().flatten()) {
            Some(j) => self.field_start(&span, j),
            None => span.start,
        };
        Some(self.location(offset))
    }

    /// Row `i`'s field of column `c` as written (after CSV unquoting); `None` when the
    /// header does not name the column or no row `i` was read.
    pub(crate) fn field_text(&self, i: usize, c: usize) -> Option<String> {
        let j = self.field_of.get(c).copied().flatten()?;
        let &position = self.rows.get(i)?;
        let mut csv = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(if self.trimmed {
                csv::Trim::All
            } else {
                csv::Trim::None
            })
            .from_reader(self.bytes.get(position..)?);
        let mut record = csv::StringRecord::new();
        match csv.read_record(&mut record) {
            Ok(true) => record.get(j).map(str::to_string),
            _ => None,
        }
    }
}

/// A record a file kind validates: it knows the line of the file it came from.
pub(crate) trait Numbered {
    /// The 1-based line of the file the record came from; 0 when not from a file.
    fn line(&self) -> u64;
}

/// Finds where a record or a header column is, for the messages of a file kind's rules:
/// in a file read by the [`Reader`](super::Reader), or among records built in memory
/// (line from the record, column 0).
pub(crate) enum Locator<'a> {
    /// Records read from a file: positions in its text.
    File(&'a Positions<'a>),
    /// Records built in memory.
    Memory,
}

impl Locator<'_> {
    /// The (line, column) of record `i`'s field of column `c`.
    pub(crate) fn row(&self, i: usize, records: &[impl Numbered], c: usize) -> (u64, u64) {
        self.place(i, records, Some(c))
    }

    /// The (line, column) where record `i` starts.
    pub(crate) fn row_start(&self, i: usize, records: &[impl Numbered]) -> (u64, u64) {
        self.place(i, records, None)
    }

    fn place(&self, i: usize, records: &[impl Numbered], c: Option<usize>) -> (u64, u64) {
        let line = records.get(i).map_or(0, Numbered::line);
        match self {
            Locator::File(positions) => positions.row(i, c).unwrap_or((line, 1)),
            Locator::Memory => (line, 0),
        }
    }

    /// The (line, column) of column `c`'s name in the header ((0, 0) in memory).
    pub(crate) fn header(&self, c: usize) -> (u64, u64) {
        match self {
            Locator::File(positions) => positions.header(Some(c)),
            Locator::Memory => (0, 0),
        }
    }

    /// The (line, column) where the header starts ((0, 0) in memory).
    pub(crate) fn header_start(&self) -> (u64, u64) {
        match self {
            Locator::File(positions) => positions.header(None),
            Locator::Memory => (0, 0),
        }
    }

    /// `reading K: ` for a record built in memory without a line, else nothing.
    pub(crate) fn prefix(&self, i: usize, records: &[impl Numbered]) -> String {
        match self {
            Locator::Memory if records.get(i).is_none_or(|r| r.line() == 0) => {
                format!("reading {}: ", i + 1)
            }
            _ => String::new(),
        }
    }

    /// How to name another record in a message: `line L` or `reading K`.
    pub(crate) fn name(&self, i: usize, records: &[impl Numbered]) -> String {
        match records.get(i) {
            Some(r) if r.line() > 0 => format!("line {}", r.line()),
            _ => format!("reading {}", i + 1),
        }
    }

    /// Record `i`'s field of column `c` as written, when read from a file whose header
    /// names the column.
    pub(crate) fn field_text(&self, i: usize, c: usize) -> Option<String> {
        match self {
            Locator::File(positions) => positions.field_text(i, c),
            Locator::Memory => None,
        }
    }

    /// Record `i`'s field of column `c` as written, quoted for a message
    /// ([`show`](super::show)), when read from a file whose header names the column.
    pub(crate) fn shown(&self, i: usize, c: usize) -> Option<String> {
        self.field_text(i, c).map(|text| show(&text))
    }

    /// What an empty table is called: no data rows in a file, no readings in memory.
    pub(crate) fn no_rows(&self) -> &'static str {
        match self {
            Locator::File(_) => "no data rows after the header",
            Locator::Memory => "no readings",
        }
    }
}
