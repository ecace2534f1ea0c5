//! Parsing the self-calibration CSV: columns, exact line and column positions, fields.
//!
//! The same reading rules and positions as the measurement file's reader
//! (`crate::measurement`), for the columns of docs/FORMAT.md §9.2.

use std::collections::HashMap;

use super::SelfcalError;
use super::validate::{Locator, RowLoc, validate};
use crate::input::Location;
use crate::input::limits::{self, Limit};
use crate::measurement::Direction;
use crate::selfcal::{HeadReading, SelfcalSet};

/// The columns of the self-calibration file, in the order of docs/FORMAT.md §9.2.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Col {
    Cycle,
    Step,
    Head,
    HeadAngle,
    Reading,
    Direction,
    Time,
}

pub(super) const NCOLS: usize = 7;

impl Col {
    pub(super) const ALL: [Col; NCOLS] = [
        Col::Cycle,
        Col::Step,
        Col::Head,
        Col::HeadAngle,
        Col::Reading,
        Col::Direction,
        Col::Time,
    ];

    /// The range of a numeric column and what its values are (docs/FORMAT.md §2.2);
    /// `None` for the integer columns, `direction`, and `head_angle` (0 ≤ angle < 360).
    pub(super) fn limit(self) -> Option<(Limit, &'static str)> {
        match self {
            Col::Reading => Some((limits::READING_ARCSEC, "a reading")),
            Col::Time => Some((limits::TIME_SECONDS, "a time")),
            _ => None,
        }
    }

    pub(super) fn name(self) -> &'static str {
        match self {
            Col::Cycle => "cycle",
            Col::Step => "step",
            Col::Head => "head",
            Col::HeadAngle => "head_angle",
            Col::Reading => "reading",
            Col::Direction => "direction",
            Col::Time => "time",
        }
    }

    fn required(self) -> bool {
        !matches!(self, Col::Direction | Col::Time)
    }

    fn from_name(name: &str) -> Option<Col> {
        Col::ALL.into_iter().find(|c| c.name() == name)
    }

    /// A known column that `name` resembles (differs only by case, surrounding spaces or a
    /// byte-order mark, or `-`/space for `_`), when `name` is not itself a known column.
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

/// The required columns, for messages: `cycle, step, head, head_angle, reading`.
const REQUIRED: &str = "cycle, step, head, head_angle, reading";

// ---------------------------------------------------------------------------------------
// Positions in the text

pub(super) use crate::input::text::{LineIndex, Span, to_u64};

// ---------------------------------------------------------------------------------------
// Messages

pub(super) fn invalid(file: &str, (line, column): (u64, u64), message: String) -> SelfcalError {
    SelfcalError::Invalid {
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

/// The message for a head angle outside [0, 360); `text` is already quoted or a value.
pub(super) fn angle_outside(text: &str) -> String {
    format!(
        "column \"head_angle\": {text} is outside 0 to 360 degrees; a head angle must be at \
         least 0 and less than 360"
    )
}

/// `1 field`, `2 fields`.
fn count(n: usize, what: &str) -> String {
    if n == 1 {
        format!("1 {what}")
    } else {
        format!("{n} {what}s")
    }
}

// ---------------------------------------------------------------------------------------
// Reading the file

/// Reads the bytes of a self-calibration file and checks every rule.
pub(super) fn parse_bytes(
    bytes: &[u8],
    source: &str,
    positions: Option<usize>,
) -> Result<SelfcalSet, SelfcalError> {
    let bytes = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(bytes);
    let text = match crate::input::text::utf8(bytes) {
        Ok(text) => text,
        Err((location, message)) => return Err(invalid(source, location, message)),
    };
    parse_text(text, source, positions)
}

fn parse_text(
    text: &str,
    source: &str,
    positions: Option<usize>,
) -> Result<SelfcalSet, SelfcalError> {
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
        return Err(match last_comment {
            None => invalid(
                source,
                (1, 1),
                format!("empty file: expected a header row naming the columns {REQUIRED}"),
            ),
            Some(line) => invalid(
                source,
                (to_u64(line) + 2, 1),
                format!(
                    "no header row: the file has only comment lines; expected a header row \
                     naming the columns {REQUIRED}"
                ),
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
    let positions = validate(&readings, positions, &locator, source)?;
    Ok(SelfcalSet {
        positions,
        readings,
    })
}

/// Parses one data row (with the right number of fields); an error is (byte offset,
/// message).
fn parse_row(
    record: &csv::StringRecord,
    columns: &[Option<usize>; NCOLS],
    span: &Span,
    line: u64,
) -> Result<(HeadReading, RowLoc), (usize, String)> {
    let mut row = RowLoc {
        start: span.start,
        fields: [None; NCOLS],
        direction_empty: false,
        head_angle_text: String::new(),
    };
    let mut order: Vec<(usize, Col)> = Col::ALL
        .into_iter()
        .filter_map(|c| columns[c as usize].map(|j| (j, c)))
        .collect();
    order.sort_unstable_by_key(|&(j, _)| j);
    let (mut cycle, mut step, mut head, mut angle, mut value) = (None, None, None, None, None);
    let mut direction = Direction::Cw;
    let mut time = None;
    for (j, col) in order {
        let text = record.get(j).unwrap_or("");
        let offset = span.field(j);
        row.fields[col as usize] = Some(offset);
        let at = |message: String| (offset, message);
        match col {
            Col::Cycle => cycle = Some(parse_u32(text, col).map_err(at)?),
            Col::Step => {
                let max = u128::try_from(usize::MAX).unwrap_or(u128::MAX);
                let x = parse_int(text, col, 0, max).map_err(at)?;
                step = Some(usize::try_from(x).map_err(|_| at(too_large(text, col, max)))?);
            }
            Col::Head => head = Some(parse_u32(text, col).map_err(at)?),
            Col::HeadAngle => {
                let x = parse_float(text, col).map_err(at)?;
                if !(0.0..360.0).contains(&x) {
                    return Err(at(angle_outside(&show(text))));
                }
                row.head_angle_text = text.to_string();
                angle = Some(x);
            }
            Col::Reading => value = Some(parse_float(text, col).map_err(at)?),
            Col::Direction => match text {
                "" => row.direction_empty = true,
                "cw" => direction = Direction::Cw,
                "ccw" => direction = Direction::Ccw,
                _ => {
                    return Err(at(format!(
                        "column \"direction\": {} is not a direction; use \"cw\" or \"ccw\"",
                        show(text)
                    )));
                }
            },
            Col::Time => {
                if !text.is_empty() {
                    time = Some(parse_float(text, col).map_err(at)?);
                }
            }
        }
    }
    let (Some(cycle), Some(step), Some(head), Some(head_angle_deg), Some(reading_arcsec)) =
        (cycle, step, head, angle, value)
    else {
        return Err((
            span.start,
            "internal error: a required column was not read".to_string(),
        ));
    };
    let reading = HeadReading {
        cycle,
        step,
        head,
        head_angle_deg,
        reading_arcsec,
        direction,
        time_seconds: time,
        line,
    };
    Ok((reading, row))
}

fn too_large(text: &str, col: Col, max: u128) -> String {
    let name = col.name();
    format!(
        "column {name:?}: {} is too large; {name} must be at most {max}",
        show(text)
    )
}

/// Parses an integer field `1 ..= u32::MAX`.
fn parse_u32(text: &str, col: Col) -> Result<u32, String> {
    let max = u128::from(u32::MAX);
    let x = parse_int(text, col, 1, max)?;
    u32::try_from(x).map_err(|_| too_large(text, col, max))
}

/// Parses an integer field `min ..= max`: decimal digits with an optional sign (`-0` is
/// 0), nothing else.
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
    let below = || {
        format!(
            "column {name:?}: {} is not allowed; {name} must be at least {min}",
            show(text)
        )
    };
    let negative = text.starts_with('-');
    match digits.parse::<u128>() {
        Ok(0) if negative && min == 0 => Ok(0),
        Ok(_) if negative => Err(below()),
        Ok(x) if x < min => Err(below()),
        Ok(x) if x <= max => Ok(x),
        _ => Err(too_large(text, col, max)),
    }
}

/// Parses a finite float field within the column's limits ([`Col::limit`]).
fn parse_float(text: &str, col: Col) -> Result<f64, String> {
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
