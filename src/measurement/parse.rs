//! Reading the measurement CSV: its columns as a description for the crate's one table
//! reader ([`crate::input::table`]), each typed row made a [`Reading`], and the one rule
//! across rows checked while reading (a mounting has one shift).

use super::*;

use super::validate::*;
use crate::input::limits::{self, Limit};
use crate::input::table::{Column, Locator, Numbered, Range, Reader, TableError, Value};
use std::collections::btree_map::Entry;

/// The columns this module knows, in the order of docs/FORMAT.md §2 (and of
/// [`COLUMNS`], which describes them).
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

const U32_MAX: u128 = u32::MAX as u128;
const USIZE_MAX: u128 = usize::MAX as u128;

/// The words of the `direction` column, in the order of [`Direction::from_word`].
pub(crate) const DIRECTION_WORDS: &[&str] = &["cw", "ccw"];

/// The measurement file's columns (docs/FORMAT.md §2), indexed by [`Col`].
pub(crate) const COLUMNS: [Column; NCOLS] = [
    Column::integer("cycle", 1, U32_MAX),
    Column::integer("step", 0, USIZE_MAX),
    Column::integer("ac", 1, U32_MAX),
    Column::integer("face", 1, USIZE_MAX),
    Column::number("reading", Range::Limit(limits::READING_ARCSEC, "a reading")),
    Column::word("direction", DIRECTION_WORDS, "a direction").or(Value::Word(0)),
    Column::number("time", Range::Limit(limits::TIME_SECONDS, "a time")).optional(),
    Column::integer("setup", 1, U32_MAX).or(Value::Integer(1)),
    Column::number(
        "reading_y",
        Range::Limit(limits::READING_ARCSEC, "a reading"),
    )
    .optional(),
    Column::number(
        "temperature",
        Range::Limit(limits::TEMPERATURE_CELSIUS, "a temperature"),
    )
    .optional(),
    Column::number(
        "encoder",
        Range::Limit(limits::ENCODER_DEGREES, "an encoder position"),
    )
    .optional(),
    Column::number(
        "shift",
        Range::Within {
            contains: valid_shift,
            broken: SHIFT_RANGE,
        },
    )
    .or(Value::Number(0.0)),
];

impl Col {
    /// The column's index in [`COLUMNS`].
    pub(super) fn at(self) -> usize {
        self as usize
    }

    /// The range of a numeric column and what its values are (docs/FORMAT.md §2.2);
    /// `None` for the integer columns, `direction`, and `shift` (which has its own rule).
    pub(super) fn limit(self) -> Option<(Limit, &'static str)> {
        COLUMNS.get(self.at()).and_then(Column::limit)
    }

    pub(super) fn name(self) -> &'static str {
        COLUMNS.get(self.at()).map_or("", |c| c.name)
    }
}

impl Direction {
    /// The direction of a word of [`DIRECTION_WORDS`] by its index.
    pub(crate) fn from_word(i: usize) -> Direction {
        if i == 1 {
            Direction::Ccw
        } else {
            Direction::Cw
        }
    }
}

impl Numbered for Reading {
    fn line(&self) -> u64 {
        self.line
    }
}

/// A direction of record `i` as it was written: `"" (empty, meaning cw)` for an empty
/// field read from a file, the quoted word otherwise. Shared by the measurement and the
/// self-calibration file (column `c` is `direction` in either description).
pub(crate) fn direction_text(
    loc: &Locator<'_>,
    i: usize,
    c: usize,
    direction: Direction,
) -> String {
    match loc.field_text(i, c) {
        Some(text) if text.is_empty() => format!("\"\" (empty, meaning {direction})"),
        _ => format!("{:?}", direction.as_str()),
    }
}

pub(super) fn invalid(file: &str, (line, column): (u64, u64), message: String) -> MeasurementError {
    MeasurementError::Invalid {
        location: Location::new(file, line, column),
        message,
    }
}

impl From<TableError> for MeasurementError {
    fn from(e: TableError) -> Self {
        if let Some(found) = e.found() {
            return MeasurementError::WrongKind {
                location: e.location,
                message: e.message,
                found,
            };
        }
        MeasurementError::Invalid {
            location: e.location,
            message: e.message,
        }
    }
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
    let no_readings = || MeasurementSet {
        faces: 0,
        readings: Vec::new(),
        source: source.to_string(),
        setup_shift_deg: BTreeMap::new(),
    };
    let partial = matches!(rules, Rules::Rows);
    let mut table = match Reader::open(bytes, source, &COLUMNS) {
        Err(e) if partial && e.is_empty_table() => return Ok(no_readings()),
        read => read?,
    };
    let has_shift = table.has(Col::Shift.at());

    // The rows, and the shift of each setup: (shift, line and text of its first row).
    let mut readings = Vec::new();
    let mut shifts: BTreeMap<u32, (f64, u64, String)> = BTreeMap::new();
    loop {
        let row = match table.next_row() {
            Ok(Some(row)) => row,
            Ok(None) => break,
            Err(e) if partial && e.is_empty_table() => return Ok(no_readings()),
            Err(e) => return Err(e.into()),
        };
        let reading = Reading {
            setup: row.integer(Col::Setup.at())?,
            cycle: row.integer(Col::Cycle.at())?,
            step: row.integer(Col::Step.at())?,
            ac: row.integer(Col::Ac.at())?,
            face: row.integer(Col::Face.at())?,
            reading_arcsec: row.number(Col::Reading.at())?,
            direction: Direction::from_word(row.word(Col::Direction.at())?),
            time_seconds: row.optional_number(Col::Time.at()),
            reading_y_arcsec: row.optional_number(Col::ReadingY.at()),
            temperature_celsius: row.optional_number(Col::Temperature.at()),
            encoder_degrees: row.optional_number(Col::Encoder.at()),
            line: row.line(),
        };
        if has_shift {
            let shift = row.number(Col::Shift.at())?;
            let text = || row.text(Col::Shift.at()).to_string();
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
                        return Err(row
                            .error(
                                Col::Shift.at(),
                                format!(
                                    "column \"shift\": {} disagrees with {} set for setup {} \
                                     at line {first_line}; a mounting has one shift",
                                    written(text()),
                                    written(first_text.clone()),
                                    reading.setup
                                ),
                            )
                            .into());
                    }
                }
            }
        }
        readings.push(reading);
    }

    let positions = table.finish();
    let n = match rules {
        Rules::Set(faces) => validate(&readings, faces, &Locator::File(&positions), source)?,
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

pub(super) use crate::input::table::show;

#[cfg(test)]
mod required_columns {
    #[test]
    fn the_description_requires_the_columns_its_kind_is_recognised_by() {
        let kind = crate::input::kind::FileKind::Measurement;
        crate::input::table::assert_requires(&super::COLUMNS, kind);
    }
}
