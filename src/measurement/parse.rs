//! Parsing the measurement CSV: columns, exact line and column positions, fields.

use super::*;

use super::validate::*;
use crate::input::limits::{self, Limit};
use std::collections::HashMap;
use std::collections::btree_map::Entry;

/// The columns this module knows, in the order of docs/FORMAT.md §2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Col {
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
    /// The mounting's table angle at step 0, degrees (docs/FORMAT.md §2, §9.1): one per
    /// setup, kept by the set ([`MeasurementSet::setup_shift_deg`]), not by the reading.
    Shift,
}

pub(super) const NCOLS: usize = 12;

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
        Col::Shift,
    ];

    /// The range of a numeric column and what its values are (docs/FORMAT.md §2.2);
    /// `None` for the integer columns, `direction`, and `shift` (which has its own rule).
    pub(super) fn limit(self) -> Option<(Limit, &'static str)> {
        match self {
            Col::Reading => Some((limits::READING_ARCSEC, "a reading")),
            Col::ReadingY => Some((limits::READING_ARCSEC, "a reading")),
            Col::Time => Some((limits::TIME_SECONDS, "a time")),
            Col::Temperature => Some((limits::TEMPERATURE_CELSIUS, "a temperature")),
            Col::Encoder => Some((limits::ENCODER_DEGREES, "an encoder position")),
            _ => None,
        }
    }

    pub(super) fn name(self) -> &'static str {
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
            Col::Shift => "shift",
        }
    }

    pub(super) fn required(self) -> bool {
        matches!(
            self,
            Col::Cycle | Col::Step | Col::Ac | Col::Face | Col::Reading
        )
    }

    pub(super) fn from_name(name: &str) -> Option<Col> {
        Col::ALL.into_iter().find(|c| c.name() == name)
    }

    /// A known column that `name` resembles (differs only by case, surrounding spaces,
    /// or `-`/space for `_`), when `name` is not itself a known column.
    pub(super) fn near_miss(name: &str) -> Option<Col> {
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

pub(super) use crate::input::text::{LineIndex, Span, to_u64};

// ---------------------------------------------------------------------------------------
// Reading the file

/// Where the fields of one parsed row are, for messages.
pub(super) struct RowLoc {
    start: usize,
    fields: [Option<usize>; NCOLS],
    direction_empty: bool,
}

/// Finds where a reading or a header column is, for messages.
pub(super) enum Locator<'a> {
    File {
        index: &'a LineIndex<'a>,
        header_start: usize,
        header_fields: &'a [Option<usize>; NCOLS],
        rows: &'a [RowLoc],
    },
    Memory,
}

impl Locator<'_> {
    pub(super) fn row(&self, i: usize, readings: &[Reading], col: Option<Col>) -> (u64, u64) {
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

    pub(super) fn header(&self, col: Option<Col>) -> (u64, u64) {
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
    pub(super) fn prefix(&self, i: usize, readings: &[Reading]) -> String {
        match self {
            Locator::Memory if readings.get(i).is_none_or(|r| r.line == 0) => {
                format!("reading {}: ", i + 1)
            }
            _ => String::new(),
        }
    }

    /// How to name another reading in a message: `line L` or `reading K`.
    pub(super) fn name(&self, i: usize, readings: &[Reading]) -> String {
        match readings.get(i) {
            Some(r) if r.line > 0 => format!("line {}", r.line),
            _ => format!("reading {}", i + 1),
        }
    }

    /// The direction text of a reading as it was written.
    pub(super) fn direction_text(&self, i: usize, readings: &[Reading]) -> String {
        let direction = readings.get(i).map(|r| r.direction).unwrap_or_default();
        match self {
            Locator::File { rows, .. } if rows.get(i).is_some_and(|r| r.direction_empty) => {
                format!("\"\" (empty, meaning {direction})")
            }
            _ => format!("{:?}", direction.as_str()),
        }
    }

    pub(super) fn no_rows(&self) -> &'static str {
        match self {
            Locator::File { .. } => "no data rows after the header",
            Locator::Memory => "no readings",
        }
    }
}

pub(super) fn invalid(file: &str, (line, column): (u64, u64), message: String) -> MeasurementError {
    MeasurementError::Invalid {
        location: Location::new(file, line, column),
        message,
    }
}

/// The offending text for a message: quoted and escaped, cut after 40 characters.
pub(super) fn show(text: &str) -> String {
    const MAX: usize = 40;
    match text.char_indices().nth(MAX) {
        Some((cut, _)) => format!("{:?}...", text.get(..cut).unwrap_or(text)),
        None => format!("{text:?}"),
    }
}

pub(super) fn split_lines(text: &str) -> impl Iterator<Item = &str> {
    text.split('\n')
        .flat_map(|line| line.strip_suffix('\r').unwrap_or(line).split('\r'))
}

/// Which rules a reading of the file applies.
#[derive(Debug, Clone, Copy)]
pub(super) enum Rules {
    /// All of docs/FORMAT.md §2, with N given (`faces`) or the largest face.
    Set(Option<usize>),
    /// Those of the header and of each row only, for a file still being written: a file
    /// without a header or without rows gives no readings, and the rules about the whole
    /// set are not checked (the `faces` of the result is 0).
    Rows,
}

pub(super) fn parse_bytes(
    bytes: &[u8],
    source: &str,
    rules: Rules,
) -> Result<MeasurementSet, MeasurementError> {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let text = match crate::input::text::utf8(bytes) {
        Ok(text) => text,
        Err((location, message)) => return Err(invalid(source, location, message)),
    };
    parse_text(text, source, rules)
}

pub(super) fn parse_text(
    text: &str,
    source: &str,
    rules: Rules,
) -> Result<MeasurementSet, MeasurementError> {
    let no_readings = || MeasurementSet {
        faces: 0,
        readings: Vec::new(),
        source: source.to_string(),
        setup_shift_deg: BTreeMap::new(),
    };
    let index = LineIndex::new(text);
    let bytes = text.as_bytes();
    let err = |offset: usize, message: String| invalid(source, index.location(offset), message);
    if let Some(offset) = crate::input::text::too_many_fields(text) {
        return Err(err(offset, crate::input::text::too_many_fields_message()));
    }

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
        if let Rules::Rows = rules {
            return Ok(no_readings());
        }
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

    // The rows, and the shift of each setup: (shift, line and text of its first row).
    let mut readings = Vec::new();
    let mut rows = Vec::new();
    let mut shifts: BTreeMap<u32, (f64, u64, String)> = BTreeMap::new();
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
        let (reading, row, shift) =
            parse_row(&record, &columns, &span, index.location(span.start).0)
                .map_err(|(offset, message)| err(offset, message))?;
        if let Some(j) = columns[Col::Shift as usize] {
            let text = || record.get(j).unwrap_or("").to_string();
            match shifts.entry(reading.setup) {
                Entry::Vacant(slot) => {
                    slot.insert((shift, reading.line, text()));
                }
                Entry::Occupied(first) => {
                    let (first_shift, first_line, first_text) = first.get();
                    if shift != *first_shift {
                        let written = |text: String| {
                            if text.is_empty() {
                                "\"\" (empty, meaning 0)".to_string()
                            } else {
                                show(&text)
                            }
                        };
                        return Err(err(
                            span.field(j),
                            format!(
                                "column \"shift\": {} disagrees with {} set for setup {} at \
                                 line {first_line}; a mounting has one shift",
                                written(text()),
                                written(first_text.clone()),
                                reading.setup
                            ),
                        ));
                    }
                }
            }
        }
        readings.push(reading);
        rows.push(row);
    }
    if readings.is_empty() {
        if let Rules::Rows = rules {
            return Ok(no_readings());
        }
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
    let n = match rules {
        Rules::Set(faces) => validate(&readings, faces, &locator, source)?,
        Rules::Rows => 0,
    };
    Ok(MeasurementSet {
        faces: n,
        readings,
        source: source.to_string(),
        setup_shift_deg: shifts
            .into_iter()
            .filter(|(_, (shift, _, _))| *shift != 0.0)
            .map(|(setup, (shift, _, _))| (setup, shift))
            .collect(),
    })
}

/// Parses one data row (with the right number of fields), with its mounting's shift in
/// degrees (0 when the column is absent or the field empty); an error is (byte offset,
/// message).
pub(super) fn parse_row(
    record: &csv::StringRecord,
    columns: &[Option<usize>; NCOLS],
    span: &Span,
    line: u64,
) -> Result<(Reading, RowLoc, f64), (usize, String)> {
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
    let mut shift = 0.0;
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
            Col::Shift => {
                if !text.is_empty() {
                    shift = parse_float(text, col).map_err(at)?;
                    if !valid_shift(shift) {
                        return Err(at(format!(
                            "column \"shift\": {} {SHIFT_RANGE}",
                            show(text)
                        )));
                    }
                }
            }
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
    Ok((reading, row, shift))
}

/// `1 field`, `2 fields`.
pub(super) fn count(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

pub(super) fn too_large(text: &str, col: Col) -> String {
    format!("column {:?}: {} is too large", col.name(), show(text))
}

/// Parses an integer field `min ..= max`.
pub(super) fn parse_int(text: &str, col: Col, min: u128, max: u128) -> Result<u128, String> {
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

/// Parses a finite float field within the column's limits ([`Col::limit`]).
pub(super) fn parse_float(text: &str, col: Col) -> Result<f64, String> {
    let name = col.name();
    if text.is_empty() {
        return Err(format!("column {name:?}: empty; a number is required"));
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => match col.limit() {
            Some((limit, what)) => limit
                .check_shown(x, &show(text), what)
                .map_err(|rule| format!("column {name:?}: {rule}")),
            None => Ok(x),
        },
        Ok(_) => Err(format!(
            "column {name:?}: {} is not a finite number",
            show(text)
        )),
        Err(_) => Err(format!("column {name:?}: {} is not a number", show(text))),
    }
}

// ---------------------------------------------------------------------------------------
// The structural rules
