//! Positions in a text read as CSV: the start of every line, and where a record's fields
//! start (following the CSV quoting rules from the position the CSV reader reports), so
//! that every reader of the crate's CSV files (measurement, self-calibration) names the
//! line and column of an offending field the same way.

/// Start offsets of the lines of a text; a line ends at `\n`, `\r\n` or a lone `\r`
/// (as for the CSV reader).
pub(crate) struct LineIndex<'a> {
    pub(crate) text: &'a str,
    pub(crate) starts: Vec<usize>,
}

impl<'a> LineIndex<'a> {
    pub(crate) fn new(text: &'a str) -> Self {
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
    pub(crate) fn line_of(&self, offset: usize) -> usize {
        self.starts
            .partition_point(|&s| s <= offset)
            .saturating_sub(1)
    }

    /// 1-based (line, character column) of a byte offset.
    pub(crate) fn location(&self, offset: usize) -> (u64, u64) {
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
    pub(crate) fn line_text(&self, line: usize) -> &'a str {
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

/// The most fields a line of the crate's CSV files may hold (docs/FORMAT.md §2.2): far
/// more than any file's columns, few enough that a line of separators alone is refused
/// before the CSV reader holds its fields (tens of bytes each).
pub(crate) const MAX_FIELDS_PER_LINE: usize = 1024;

/// The byte offset of the separator that gives a line more than
/// [`MAX_FIELDS_PER_LINE`] fields, if one does (every comma counted, quoted ones too;
/// comment lines, which begin with `#`, are not CSV and are passed over). One pass, no
/// allocation: run before the CSV reader.
pub(crate) fn too_many_fields(text: &str) -> Option<usize> {
    let mut commas = 0usize;
    let mut comment = false;
    let mut line_start = true;
    for (i, &b) in text.as_bytes().iter().enumerate() {
        if line_start {
            comment = b == b'#';
            line_start = false;
        }
        match b {
            b'\n' | b'\r' => {
                commas = 0;
                line_start = true;
            }
            b',' if !comment => {
                commas += 1;
                if commas >= MAX_FIELDS_PER_LINE {
                    return Some(i);
                }
            }
            _ => {}
        }
    }
    None
}

/// The message of [`too_many_fields`].
pub(crate) fn too_many_fields_message() -> String {
    format!(
        "a line of more than {MAX_FIELDS_PER_LINE} fields; polycal's CSV files have a few \
         columns (docs/FORMAT.md §2.2)"
    )
}

pub(crate) fn to_u64(x: usize) -> u64 {
    u64::try_from(x).unwrap_or(u64::MAX)
}

/// Where a record's first field starts, from the position the CSV reader reports for it:
/// after the line breaks of blank lines before it and a byte-order mark (as [`Span::scan`]
/// finds it, without scanning the fields).
pub(crate) fn record_begin(bytes: &[u8], from: usize) -> usize {
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
    pos
}

/// Where a record's fields start in the text, found by following the CSV quoting rules
/// from the position the CSV reader reports (which may lie before skipped blank lines).
pub(crate) struct Span {
    /// Byte offset where the record's first field starts.
    pub(crate) start: usize,
    /// Byte offsets where each field starts.
    pub(crate) fields: Vec<usize>,
    /// Byte offset just after the record's last field.
    pub(crate) end: usize,
}

impl Span {
    pub(crate) fn scan(bytes: &[u8], from: usize, fields: usize) -> Span {
        let mut pos = record_begin(bytes, from);
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

    pub(crate) fn field(&self, i: usize) -> usize {
        self.fields.get(i).copied().unwrap_or(self.start)
    }
}

/// The bytes of a text file as `str`, or where and why they are not UTF-8: the 1-based
/// (line, character column) of the first invalid byte and the message every reader of the
/// crate gives for it.
pub(crate) fn utf8(bytes: &[u8]) -> Result<&str, ((u64, u64), String)> {
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(text),
        Err(e) => {
            let valid = bytes
                .get(..e.valid_up_to())
                .and_then(|b| std::str::from_utf8(b).ok())
                .unwrap_or("");
            let message = match (e.error_len(), bytes.get(e.valid_up_to())) {
                (Some(_), Some(b)) => {
                    format!("not valid UTF-8 (byte 0x{b:02x}); the file must be UTF-8 text")
                }
                _ => "not valid UTF-8 (a character is cut off at the end of the file); \
                      the file must be UTF-8 text"
                    .to_string(),
            };
            Err((LineIndex::new(valid).location(valid.len()), message))
        }
    }
}
