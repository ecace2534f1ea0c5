//! Reading the self-calibration CSV: the file's columns ([`super::columns`]) read by the
//! crate's one table reader ([`crate::input::table`]) with the measurement file's reading
//! rules and messages, each typed row made a [`HeadReading`]; the rules across rows are
//! then [`super::validate`]'s.

use super::columns::{COLUMNS, Col};
use super::validate::validate;
use crate::input::FileError;
use crate::input::table::{Locator, Reader};
use crate::measurement::Direction;
use crate::selfcal::{HeadReading, SelfcalSet};

/// Reads the bytes of a self-calibration file and checks every rule.
pub(super) fn parse_bytes(
    bytes: &[u8],
    source: &str,
    positions: Option<usize>,
) -> Result<SelfcalSet, FileError> {
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
