//! The measurement file's columns (docs/FORMAT.md §2): their description for the crate's
//! one table reader ([`crate::input::table`]), the index of each, and what the reader
//! ([`super::parse`]), the rules across rows ([`super::validate`]) and the writer share
//! about them — the words of `direction`, the range of `shift`, how a direction read is
//! quoted in a message. A leaf: it uses neither the reader nor the rules.

use super::{Direction, Reading};
use crate::input::limits::{self, Limit};
use crate::input::table::{Column, Locator, Numbered, Range, Value};

/// What a shift out of range breaks, after the value in a message.
pub(super) const SHIFT_RANGE: &str = "is outside 0 to 360 degrees; a shift is the table's angle at step 0 of its mounting, \
     0 <= shift < 360";

/// Whether a (finite) shift is in range, 0 ≤ shift < 360 degrees (-0 counts as 0).
pub(super) fn valid_shift(shift: f64) -> bool {
    (0.0..360.0).contains(&shift)
}

/// The columns the measurement file knows, in the order of docs/FORMAT.md §2 (and of
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
    /// setup, kept by the set, not by the reading
    /// ([`MeasurementSet::setup_shift_deg`](super::MeasurementSet::setup_shift_deg)).
    Shift,
}

/// How many columns the measurement file knows.
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

    /// The column's name in the header.
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

#[cfg(test)]
mod required_columns {
    #[test]
    fn the_description_requires_the_columns_its_kind_is_recognised_by() {
        let kind = crate::input::kind::FileKind::Measurement;
        crate::input::table::assert_requires(&super::COLUMNS, kind);
    }
}
