//! The self-calibration file's columns (docs/FORMAT.md §9.2): their description for the
//! crate's one table reader ([`crate::input::table`]), the index of each, and what the
//! reader ([`super::parse`]) and the rules across rows ([`super::validate`]) share about
//! them — the range of a head angle and its message. A leaf: it uses neither the reader
//! nor the rules.

use crate::input::limits::{self, Limit};
use crate::input::table::{Column, Numbered, Range, Value};
use crate::measurement::DIRECTION_WORDS;
use crate::selfcal::HeadReading;

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

/// How many columns the self-calibration file knows.
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

    /// The column's name in the header.
    pub(super) fn name(self) -> &'static str {
        COLUMNS.get(self.at()).map_or("", |c| c.name)
    }
}

impl Numbered for HeadReading {
    fn line(&self) -> u64 {
        self.line
    }
}

/// The message for a head angle outside [0, 360); `text` is already quoted or a value.
pub(super) fn angle_outside(text: &str) -> String {
    format!("column \"head_angle\": {text} {ANGLE_RANGE}")
}

#[cfg(test)]
mod required_columns {
    #[test]
    fn the_description_requires_the_columns_its_kind_is_recognised_by() {
        let kind = crate::input::kind::FileKind::SelfCalibration;
        crate::input::table::assert_requires(&super::COLUMNS, kind);
    }
}
