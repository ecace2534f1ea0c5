//! Reading the measurement CSV: the file's columns ([`super::columns`]) read by the
//! crate's one table reader ([`crate::input::table`]), each typed row made a [`Reading`],
//! and the one rule across rows checked while reading (a mounting has one shift); the
//! rules across rows are then [`super::validate`]'s.

use std::collections::BTreeMap;
use std::collections::btree_map::Entry;

use super::columns::{COLUMNS, Col};
use super::validate::validate;
use super::{Direction, MeasurementSet, Reading};
use crate::input::FileError;
use crate::input::table::{Locator, Reader, show};

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

/// Reads the bytes of a measurement file by `rules`; `source` names it in messages.
pub(super) fn parse_bytes(
    bytes: &[u8],
    source: &str,
    rules: Rules,
) -> Result<MeasurementSet, FileError> {
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
