//! Reading the self-calibration CSV: its columns (docs/FORMAT.md §9.2) as a description
//! for the crate's one table reader ([`crate::input::table`]), the measurement file's
//! reading rules and messages, each typed row made a [`HeadReading`].

use super::SelfcalError;
use super::validate::validate;
use crate::input::Location;
use crate::input::limits::{self, Limit};
use crate::input::table::{Column, Locator, Numbered, Range, Reader, TableError, Value};
use crate::measurement::{DIRECTION_WORDS, Direction};
use crate::selfcal::{HeadReading, SelfcalSet};

/// The columns of the self-calibration file, in the order of docs/FORMAT.md §9.2 (and
/// of [`COLUMNS`], which describes them).
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

const NCOLS: usize = 7;

const U32_MAX: u128 = u32::MAX as u128;
const USIZE_MAX: u128 = usize::MAX as u128;

/// What a head angle outside [0, 360) breaks, after the value in a message.
const ANGLE_RANGE: &str =
    "is outside 0 to 360 degrees; a head angle must be at least 0 and less than 360";

/// Whether a (finite) head angle is in [0, 360).
fn valid_angle(angle: f64) -> bool {
    (0.0..360.0).contains(&angle)
}

/// The self-calibration file's columns (docs/FORMAT.md §9.2), indexed by [`Col`].
pub(crate) const COLUMNS: [Column; NCOLS] = [
    Column::integer("cycle", 1, U32_MAX),
    Column::integer("step", 0, USIZE_MAX),
    Column::integer("head", 1, U32_MAX),
    Column::number(
        "head_angle",
        Range::Within {
            contains: valid_angle,
            broken: ANGLE_RANGE,
        },
    ),
    Column::number("reading", Range::Limit(limits::READING_ARCSEC, "a reading")),
    Column::word("direction", DIRECTION_WORDS, "a direction").or(Value::Word(0)),
    Column::number("time", Range::Limit(limits::TIME_SECONDS, "a time")).optional(),
];

impl Col {
    /// The column's index in [`COLUMNS`].
    pub(super) fn at(self) -> usize {
        self as usize
    }

    /// The range of a numeric column and what its values are (docs/FORMAT.md §2.2);
    /// `None` for the integer columns, `direction`, and `head_angle` (0 ≤ angle < 360).
    pub(super) fn limit(self) -> Option<(Limit, &'static str)> {
        COLUMNS.get(self.at()).and_then(Column::limit)
    }

    pub(super) fn name(self) -> &'static str {
        COLUMNS.get(self.at()).map_or("", |c| c.name)
    }
}

impl Numbered for HeadReading {
    fn line(&self) -> u64 {
        self.line
    }
}

// ---------------------------------------------------------------------------------------
// Messages

pub(super) fn invalid(file: &str, (line, column): (u64, u64), message: String) -> SelfcalError {
    SelfcalError::Invalid {
        location: Location::new(file, line, column),
        message,
    }
}

impl From<TableError> for SelfcalError {
    fn from(e: TableError) -> Self {
        if let Some(found) = e.found() {
            return SelfcalError::WrongKind {
                location: e.location,
                message: e.message,
                found,
            };
        }
        SelfcalError::Invalid {
            location: e.location,
            message: e.message,
        }
    }
}

/// The message for a head angle outside [0, 360); `text` is already quoted or a value.
pub(super) fn angle_outside(text: &str) -> String {
    format!("column \"head_angle\": {text} {ANGLE_RANGE}")
}

// ---------------------------------------------------------------------------------------
// Reading the file

/// Reads the bytes of a self-calibration file and checks every rule.
pub(super) fn parse_bytes(
    bytes: &[u8],
    source: &str,
    positions: Option<usize>,
) -> Result<SelfcalSet, SelfcalError> {
    let mut table = Reader::open(bytes, source, &COLUMNS)?;
    let mut readings = Vec::new();
    while let Some(row) = table.next_row()? {
        readings.push(HeadReading {
            cycle: row.integer(Col::Cycle.at())?,
            step: row.integer(Col::Step.at())?,
            head: row.integer(Col::Head.at())?,
            head_angle_deg: row.number(Col::HeadAngle.at())?,
            reading_arcsec: row.number(Col::Reading.at())?,
            direction: Direction::from_word(row.word(Col::Direction.at())?),
            time_seconds: row.optional_number(Col::Time.at()),
            line: row.line(),
        });
    }
    let table = table.finish();
    let positions = validate(&readings, positions, &Locator::File(&table), source)?;
    Ok(SelfcalSet {
        positions,
        readings,
    })
}

#[cfg(test)]
mod required_columns {
    #[test]
    fn the_description_requires_the_columns_its_kind_is_recognised_by() {
        let kind = crate::input::kind::FileKind::SelfCalibration;
        crate::input::table::assert_requires(&super::COLUMNS, kind);
    }
}
