//! The one reader of the crate's CSV tables (docs/FORMAT.md §2.2): the measurement file,
//! the self-calibration file and the result file are *descriptions* ([`Column`]s: names,
//! required or optional, what a field holds, which limit applies, the default of an empty
//! field; and a [`Dialect`]), read by the same [`Reader`] with the same rules and the same
//! messages.
//!
//! The rules: UTF-8 text (a leading byte-order mark allowed), at most
//! [`MAX_FIELDS_PER_LINE`](crate::input::text::MAX_FIELDS_PER_LINE) fields a line, `#`
//! comment lines and blank lines before the header, one header row naming every required
//! column once (columns in any order; unknown names ignored, a near miss of a known name
//! such as `Face` or `head-angle` refused; no name twice), blank lines between rows
//! skipped, every row with as many fields as the header, every field read by its column's
//! [`Kind`]. The first problem is one [`TableError`] naming the file, line and character
//! column where the offending field starts.
//!
//! A [`Dialect`] relaxes two of these rules for a file kind that other programs write (the
//! result file, docs/FORMAT.md §3.2): the spaces around every field trimmed (the column
//! of a field is then where its text starts), and names the description does not know
//! passed over whatever they are (no near misses, repeated freely).
//!
//! The reader gives back typed rows ([`Row`]) one at a time, so that a file kind's rules
//! across rows are checked in file order, and when it is done the [`Positions`] of the
//! header and rows, through which the kind's own validation ([`Locator`]) names the line
//! and column of a reading.

mod column;
mod locate;
#[cfg(test)]
mod tests;

pub(crate) use column::{Column, Range, Value, count, show};
pub(crate) use locate::{Locator, Numbered, Positions};

use crate::input::Location;
use crate::input::kind::{self, FileKind};
use crate::input::text::{self, LineIndex, Span, to_u64};
use std::collections::HashMap;

/// A table that breaks a rule of the reader: where (file, line, column) and what.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{location}: {message}")]
#[non_exhaustive]
pub(crate) struct TableError {
    /// Where: the file, 1-based line and character column.
    pub(crate) location: Location,
    /// What is wrong, naming the column and quoting the offending text.
    pub(crate) message: String,
    /// Whether the table has no rows: no header row (only comments or blank lines), or
    /// a header and no data rows. A file still being written may be read so.
    empty: bool,
    /// The kind of file the text is when it is not the table described (a budget given
    /// as a measurement file): the header lacks a required column and
    /// [`kind::recognize`] tells what it is instead.
    found: Option<FileKind>,
}

impl TableError {
    /// Whether the refusal is that of a table without rows: no header row, or no data
    /// rows after it (a file still being written may be read so, as no rows).
    pub(crate) fn is_empty_table(&self) -> bool {
        self.empty
    }

    /// The kind of file the text is instead of the table described, when the refusal is
    /// that (a budget or a result file given as a measurement file).
    pub(crate) fn found(&self) -> Option<FileKind> {
        self.found
    }
}

/// How a file kind's text is written, beyond its columns: the rules a [`Reader`] may
/// relax for it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Dialect {
    /// Whether the spaces around every field (the header's names included) are trimmed,
    /// and a comment line before the header may begin with spaces.
    pub(crate) trimmed: bool,
    /// Whether the header's names the description does not know are checked: a near
    /// miss of a known name (`Face`, `head-angle`) refused, and no name twice. Otherwise
    /// only the described names must be once, the others being passed over.
    pub(crate) unknown_names_checked: bool,
}

impl Dialect {
    /// The measurement and self-calibration files' (docs/FORMAT.md §2.1): fields as
    /// written, every name checked.
    pub(crate) const STRICT: Dialect = Dialect {
        trimmed: false,
        unknown_names_checked: true,
    };
}

/// Reads a table of a described kind, one row at a time.
pub(crate) struct Reader<'t> {
    columns: &'t [Column],
    dialect: Dialect,
    source: &'t str,
    csv: csv::Reader<&'t [u8]>,
    /// Byte offset of the header's line, where the CSV reader starts.
    base: usize,
    record: csv::StringRecord,
    /// The header's names as written.
    header: Vec<String>,
    /// The described columns in the order of the header: (field index, column index).
    order: Vec<(usize, usize)>,
    /// The value of each described column in the current row.
    values: Vec<Option<Value>>,
    /// Where the current row's first field starts.
    row_start: usize,
    positions: Positions<'t>,
}

/// One row of a table, its fields read by their columns' kinds.
pub(crate) struct Row<'r> {
    reader: &'r Reader<'r>,
    line: u64,
}

impl<'t> Reader<'t> {
    /// Reads the bytes of a table up to and including its header (a leading byte-order
    /// mark skipped); `source` names the file in messages, `columns` describe it.
    ///
    /// # Errors
    ///
    /// The first rule of the text or the header broken ([`TableError::is_empty_table`]
    /// for a file without a header row).
    pub(crate) fn open(
        bytes: &'t [u8],
        source: &'t str,
        columns: &'t [Column],
    ) -> Result<Self, TableError> {
        Self::open_with(bytes, source, columns, Dialect::STRICT)
    }

    /// [`Reader::open`] of a table written in a [`Dialect`] of its own.
    ///
    /// # Errors
    ///
    /// As [`Reader::open`].
    pub(crate) fn open_with(
        bytes: &'t [u8],
        source: &'t str,
        columns: &'t [Column],
        dialect: Dialect,
    ) -> Result<Self, TableError> {
        let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
        let text = text::utf8(bytes).map_err(|((line, column), message)| TableError {
            location: Location::new(source, line, column),
            message,
            empty: false,
            found: None,
        })?;
        let index = LineIndex::new(text);
        let at = |offset: usize, message: String| refusal(source, index.location(offset), message);
        if let Some(offset) = text::too_many_fields(text) {
            return Err(at(offset, text::too_many_fields_message()));
        }

        // Comment and blank lines before the header.
        let mut header_line = None;
        let mut last_comment = None;
        for line in 0..index.starts.len() {
            let content = index.line_text(line);
            let content = if dialect.trimmed {
                content.trim_start()
            } else {
                content
            };
            if content.starts_with('#') {
                last_comment = Some(line);
            } else if !content.trim().is_empty() {
                header_line = Some(line);
                break;
            }
        }
        let Some(header_line) = header_line else {
            let required: Vec<&str> = columns
                .iter()
                .filter(|c| c.required)
                .map(|c| c.name)
                .collect();
            let required = required.join(", ");
            let (location, message) = match last_comment {
                None => (
                    (1, 1),
                    format!("empty file: expected a header row naming the columns {required}"),
                ),
                Some(line) => (
                    (to_u64(line) + 2, 1),
                    format!(
                        "no header row: the file has only comment lines; expected a header \
                         row naming the columns {required}"
                    ),
                ),
            };
            return Err(TableError {
                empty: true,
                ..refusal(source, location, message)
            });
        };
        let base = index.starts.get(header_line).copied().unwrap_or(0);
        let csv = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(if dialect.trimmed {
                csv::Trim::All
            } else {
                csv::Trim::None
            })
            .from_reader(bytes.get(base..).unwrap_or(b""));
        let positions = Positions {
            index,
            bytes,
            trimmed: dialect.trimmed,
            header_start: base,
            header_fields: vec![None; columns.len()],
            field_of: vec![None; columns.len()],
            fields: 0,
            rows: Vec::new(),
        };
        let mut reader = Reader {
            columns,
            dialect,
            source,
            csv,
            base,
            record: csv::StringRecord::new(),
            header: Vec::new(),
            order: Vec::new(),
            values: vec![None; columns.len()],
            row_start: base,
            positions,
        };
        reader.header()?;
        Ok(reader)
    }

    /// A refusal at a byte offset of the text.
    fn at(&self, offset: usize, message: String) -> TableError {
        refusal(self.source, self.positions.index.location(offset), message)
    }

    /// Where the CSV reader's current record starts (blank lines before it included).
    fn record_position(&self) -> usize {
        self.base
            + self
                .record
                .position()
                .and_then(|p| usize::try_from(p.byte()).ok())
                .unwrap_or(0)
    }

    /// Reads the next record; `false` at the end of the text.
    fn next_record(&mut self) -> Result<bool, TableError> {
        match self.csv.read_record(&mut self.record) {
            Ok(more) => Ok(more),
            Err(e) => {
                let offset = e
                    .position()
                    .and_then(|p| usize::try_from(p.byte()).ok())
                    .unwrap_or(0);
                Err(self.at(self.base + offset, format!("unreadable CSV: {e}")))
            }
        }
    }

    /// Reads the header: every described column it names, where.
    fn header(&mut self) -> Result<(), TableError> {
        if !self.next_record()? {
            return Err(self.at(self.base, "no header row".to_string()));
        }
        let names: Vec<String> = self.record.iter().map(str::to_string).collect();
        let span = Span::scan(self.positions.bytes, self.record_position(), names.len());
        let starts: Vec<usize> = (0..names.len())
            .map(|j| self.positions.field_start(&span, j))
            .collect();
        let field = |j: usize| starts.get(j).copied().unwrap_or(span.start);
        let column_at = |j: usize| self.positions.index.location(field(j)).1;
        let checked = self.dialect.unknown_names_checked;
        let mut seen: HashMap<&str, usize> = HashMap::new();
        for (j, name) in names.iter().enumerate() {
            let known = self.columns.iter().position(|c| c.name == name);
            if !checked && known.is_none() {
                continue;
            }
            if let Some(&first) = seen.get(name.as_str()) {
                return Err(self.at(
                    field(j),
                    format!(
                        "column {} appears twice in the header (first at column {})",
                        show(name),
                        column_at(first)
                    ),
                ));
            }
            seen.insert(name, j);
            match known {
                Some(c) => {
                    self.order.push((j, c));
                    let start = field(j);
                    if let Some(slot) = self.positions.field_of.get_mut(c) {
                        *slot = Some(j);
                    }
                    if let Some(slot) = self.positions.header_fields.get_mut(c) {
                        *slot = Some(start);
                    }
                }
                None => {
                    if let Some(c) = self.near_miss(name) {
                        return Err(self.at(
                            field(j),
                            format!(
                                "column {} is not a known column name but looks like {:?}; \
                                 names are exact (lower case, no spaces)",
                                show(name),
                                c.name
                            ),
                        ));
                    }
                }
            }
        }
        let missing: Vec<String> = self
            .columns
            .iter()
            .zip(&self.positions.field_of)
            .filter(|(c, j)| c.required && j.is_none())
            .map(|(c, _)| format!("{:?}", c.name))
            .collect();
        if !missing.is_empty() {
            return Err(self.missing_columns(&names, &missing, span.start));
        }
        self.positions.header_start = span.start;
        self.positions.fields = names.len();
        self.header = names;
        // The values of the columns the header does not name: their defaults.
        for (c, column) in self.columns.iter().enumerate() {
            if self.positions.field_of.get(c).is_some_and(Option::is_none)
                && let Some(slot) = self.values.get_mut(c)
            {
                *slot = column.default;
            }
        }
        Ok(())
    }

    /// The refusal of a header without every required column (`missing`), at `start`:
    /// a table separated by semicolons or tabs (and with decimal commas) named so, a file
    /// of another kind named as what it is (docs/FORMAT.md §8), else the missing columns
    /// and the header as found.
    fn missing_columns(&self, names: &[String], missing: &[String], start: usize) -> TableError {
        let index = &self.positions.index;
        let line = index.line_of(start);
        let header = index.line_text(line);
        let next = (line + 1..index.starts.len())
            .map(|l| index.line_text(l))
            .find(|l| !l.trim().is_empty());
        let required: Vec<&str> = self
            .columns
            .iter()
            .filter(|c| c.required)
            .map(|c| c.name)
            .collect();
        if let Some(message) = kind::separator_problem(header, next, &required) {
            return self.at(start, message);
        }
        let text = std::str::from_utf8(self.positions.bytes).unwrap_or("");
        let expected = kind_of_description(self.columns);
        if let Some(found) = kind::recognize(text).filter(|&k| Some(k) != expected) {
            let expected = expected.map_or_else(
                || format!("a table with the columns {}", required.join(", ")),
                |k| k.name().to_string(),
            );
            return TableError {
                found: Some(found),
                ..self.at(start, kind::other_kind_message(found, &expected, text))
            };
        }
        let shown: Vec<String> = names.iter().map(|n| show(n)).collect();
        self.at(
            start,
            format!(
                "missing required column{} {}; the header has {}",
                if missing.len() > 1 { "s" } else { "" },
                missing.join(", "),
                shown.join(", ")
            ),
        )
    }

    /// A described column that `name` resembles (differs only by case, surrounding spaces
    /// or a byte-order mark, or `-`/space for `_`), when `name` is not itself one.
    fn near_miss(&self, name: &str) -> Option<&'t Column> {
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
        self.columns.iter().find(|c| c.name == normal)
    }

    /// The next row, its fields read; `None` after the last.
    ///
    /// # Errors
    ///
    /// The first field of the row that breaks its column's rule, a row whose number of
    /// fields is not the header's, or a header without data rows
    /// ([`TableError::is_empty_table`]).
    pub(crate) fn next_row(&mut self) -> Result<Option<Row<'_>>, TableError> {
        let bytes = self.positions.bytes;
        let fields = self.positions.fields;
        let position = loop {
            if !self.next_record()? {
                if self.positions.rows.is_empty() {
                    return Err(TableError {
                        empty: true,
                        ..self.at(
                            self.positions.header_start,
                            "no data rows after the header".to_string(),
                        )
                    });
                }
                return Ok(None);
            }
            let position = self.record_position();
            let start = text::record_begin(bytes, position);
            let index = &self.positions.index;
            if self.record.len() <= 1 && index.line_text(index.line_of(start)).trim().is_empty() {
                continue; // a blank line of spaces
            }
            self.row_start = start;
            break position;
        };
        let found = self.record.len();
        if found != fields {
            let span = Span::scan(bytes, position, found);
            return Err(if found > fields {
                // extra fields of digits alone, and no decimal point in the row: the
                // fractions of numbers written `1,5`
                let decimal_commas = self
                    .record
                    .iter()
                    .skip(fields)
                    .all(|f| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()))
                    && !self.record.iter().any(|f| f.contains('.'));
                self.at(
                    span.field(fields),
                    format!(
                        "row has {} but the header has {fields}: extra field {}{}",
                        count(found, "field"),
                        show(self.record.get(fields).unwrap_or("")),
                        if decimal_commas {
                            "; if its numbers are written with decimal commas (1,5), write \
                             them with points (1.5): a comma separates fields"
                        } else {
                            ""
                        }
                    ),
                )
            } else {
                self.at(
                    span.end,
                    format!(
                        "row has {} but the header has {fields}: no value for column {}",
                        count(found, "field"),
                        show(self.header.get(found).map_or("", String::as_str))
                    ),
                )
            });
        }
        for &(j, c) in &self.order {
            let text = self.record.get(j).unwrap_or("");
            let read = match self.columns.get(c) {
                Some(column) => column.value(text),
                None => Ok(None),
            };
            match read {
                Ok(value) => {
                    if let Some(slot) = self.values.get_mut(c) {
                        *slot = value;
                    }
                }
                Err(refusal) => {
                    let span = Span::scan(bytes, position, found);
                    return Err(self.at(self.positions.field_start(&span, j), refusal.to_string()));
                }
            }
        }
        self.positions.rows.push(position);
        let line = to_u64(self.positions.index.line_of(self.row_start)) + 1;
        Ok(Some(Row { reader: self, line }))
    }

    /// Whether the header names column `c` of the description.
    pub(crate) fn has(&self, c: usize) -> bool {
        self.positions.field_of.get(c).is_some_and(Option::is_some)
    }

    /// The positions of the header and of the rows read, for the file kind's validation.
    pub(crate) fn finish(self) -> Positions<'t> {
        self.positions
    }
}

impl Row<'_> {
    /// The 1-based line the row starts on.
    pub(crate) fn line(&self) -> u64 {
        self.line
    }

    /// The value of column `c` (the default, or `None` when not recorded).
    pub(crate) fn value(&self, c: usize) -> Option<Value> {
        self.reader.values.get(c).copied().flatten()
    }

    /// The field of column `c` as written (after CSV unquoting); empty when the header
    /// does not name the column.
    pub(crate) fn text(&self, c: usize) -> &str {
        self.reader
            .positions
            .field_of
            .get(c)
            .copied()
            .flatten()
            .and_then(|j| self.reader.record.get(j))
            .unwrap_or("")
    }

    /// A refusal at the field of column `c` (at the row's start when the header does
    /// not name it).
    pub(crate) fn error(&self, c: usize, message: String) -> TableError {
        self.reader.at(self.offset(c), message)
    }

    /// Where the field of column `c` starts (the row's start when the header does not
    /// name it).
    fn offset(&self, c: usize) -> usize {
        let positions = &self.reader.positions;
        match positions.field_of.get(c).copied().flatten() {
            Some(j) => {
                let span = Span::scan(
                    positions.bytes,
                    self.reader.record_position(),
                    positions.fields,
                );
                positions.field_start(&span, j)
            }
            None => self.reader.row_start,
        }
    }

    /// The 1-based character column where the field of each described column starts
    /// (in the description's order); `None` for a column the header does not name.
    pub(crate) fn columns(&self) -> Vec<Option<u64>> {
        let positions = &self.reader.positions;
        let span = Span::scan(
            positions.bytes,
            self.reader.record_position(),
            positions.fields,
        );
        positions
            .field_of
            .iter()
            .map(|j| {
                j.map(|j| {
                    let (_, column) = positions.index.location(positions.field_start(&span, j));
                    column
                })
            })
            .collect()
    }

    /// A refusal at the field of column `c` of the earlier row `i` (0-based among the rows
    /// read; this row is the last of them), for a rule across rows that names the earlier
    /// one; at this row's field when no row `i` was read.
    pub(crate) fn error_on_row(&self, i: usize, c: usize, message: String) -> TableError {
        match self.reader.positions.row(i, Some(c)) {
            Some(at) => refusal(self.reader.source, at, message),
            None => self.error(c, message),
        }
    }

    /// The integer of column `c`, as `T`.
    ///
    /// # Errors
    ///
    /// A column without a value (an optional one without a default), or a value that
    /// `T` cannot hold: the description does not fit the caller's type.
    pub(crate) fn integer<T: TryFrom<u128>>(&self, c: usize) -> Result<T, TableError> {
        match self.value(c) {
            Some(Value::Integer(x)) => T::try_from(x).map_err(|_| self.out_of_range(c)),
            _ => Err(self.not_read()),
        }
    }

    /// The number of column `c`.
    ///
    /// # Errors
    ///
    /// A column without a number (the description does not fit the caller).
    pub(crate) fn number(&self, c: usize) -> Result<f64, TableError> {
        self.optional_number(c).ok_or_else(|| self.not_read())
    }

    /// The number of an optional column `c`, `None` when not recorded.
    pub(crate) fn optional_number(&self, c: usize) -> Option<f64> {
        match self.value(c) {
            Some(Value::Number(x)) => Some(x),
            _ => None,
        }
    }

    /// The index of column `c`'s word.
    ///
    /// # Errors
    ///
    /// A column without a word (the description does not fit the caller).
    pub(crate) fn word(&self, c: usize) -> Result<usize, TableError> {
        match self.value(c) {
            Some(Value::Word(i)) => Ok(i),
            _ => Err(self.not_read()),
        }
    }

    fn not_read(&self) -> TableError {
        self.reader.at(
            self.reader.row_start,
            "internal error: a required column was not read".to_string(),
        )
    }

    fn out_of_range(&self, c: usize) -> TableError {
        let name = self.reader.columns.get(c).map_or("", |c| c.name);
        self.error(c, format!("column {name:?}: value out of range"))
    }
}

/// A refusal at a (line, column).
fn refusal(source: &str, (line, column): (u64, u64), message: String) -> TableError {
    TableError {
        location: Location::new(source, line, column),
        message,
        empty: false,
        found: None,
    }
}

/// The kind whose required columns `columns` describe (the kind a table reader expects).
pub(crate) fn kind_of_description(columns: &[Column]) -> Option<FileKind> {
    let names: Vec<&str> = columns
        .iter()
        .filter(|c| c.required)
        .map(|c| c.name)
        .collect();
    kind::csv_kind(&names)
}

/// Asserts that `columns` require exactly the columns `kind` is recognised by (each file
/// kind's unit test: its description and [`FileKind::required_columns`] agree).
#[cfg(test)]
pub(crate) fn assert_requires(columns: &[Column], kind: FileKind) {
    let mut required: Vec<&str> = columns
        .iter()
        .filter(|c| c.required)
        .map(|c| c.name)
        .collect();
    let mut recognised = kind.required_columns().to_vec();
    required.sort_unstable();
    recognised.sort_unstable();
    assert_eq!(required, recognised, "{kind:?}");
}
