//! Reading the result CSV (docs/FORMAT.md §3.2): its columns as a description for the
//! crate's one table reader ([`crate::input::table`]), in the dialect other programs
//! write it (fields trimmed, unknown columns passed over), each typed row made a
//! [`ResultRow`] and the rules across rows (one row per quantity and index, the angle
//! rules) checked row by row in file order, in one pass.

use std::collections::HashMap;
use std::collections::hash_map::Entry;

use super::angle::{AngleCheck, AngleProblem};
use super::{Quantity, ResultFile, ResultRow, RowColumns, angle_in_range};
use crate::input::FileError;
use crate::input::limits;
use crate::input::table::{Column, Dialect, Range, Reader, Row, TableError};

/// The columns of the result file, in the order of docs/FORMAT.md §3 (and of
/// [`COLUMNS`], which describes them).
#[derive(Debug, Clone, Copy)]
enum Col {
    Quantity,
    Index,
    Value,
    ExpandedU,
    U,
    K,
    AngleDeg,
    Dof,
    NominalDeg,
}

impl Col {
    /// The column's index in [`COLUMNS`].
    fn at(self) -> usize {
        self as usize
    }

    fn name(self) -> &'static str {
        COLUMNS.get(self.at()).map_or("", |c| c.name)
    }
}

/// The words of the `quantity` column: the families in the order of [`Quantity::ALL`].
const QUANTITY_WORDS: &[&str] = &[
    "pitch_deviation",
    "face_deviation",
    "encoder_error",
    "setup_error",
    "angle_block",
];

/// What an `angle_deg` outside [0, 360) breaks, after the value in a message.
const ANGLE_RANGE: &str = "is outside 0 ≤ angle_deg < 360 degrees; write 0, not 360, for \
                           the position that closes the circle";

/// What a `dof` that is not positive breaks, after the value in a message.
const DOF_RANGE: &str = "is not positive: the degrees of freedom of u are more than 0 (leave \
                         the field empty for infinitely many)";

/// What a `nominal_deg` outside (0, 360) breaks, after the value in a message.
const NOMINAL_RANGE: &str = "is outside 0 < nominal_deg < 360 degrees: an angle block's \
                             nominal angle";

/// Whether a number is an angle block's nominal angle, degrees: 0 < angle < 360.
fn nominal_in_range(nominal_deg: f64) -> bool {
    nominal_deg > 0.0 && nominal_deg < 360.0
}

/// Whether a number is a stated number of degrees of freedom: positive.
fn dof_in_range(dof: f64) -> bool {
    dof > 0.0
}

/// The result file's columns (docs/FORMAT.md §3), indexed by [`Col`].
pub(crate) const COLUMNS: [Column; 9] = [
    Column::word("quantity", QUANTITY_WORDS, "a quantity"),
    Column::integer("index", 0, u32::MAX as u128),
    Column::number(
        "value",
        Range::Limit(limits::RESULT_ARCSEC, "a result's value"),
    ),
    Column::number("U", Range::Limit(limits::RESULT_ARCSEC, "a result's U")).optional(),
    Column::number("u", Range::Limit(limits::RESULT_ARCSEC, "a result's u")).optional(),
    Column::number("k", Range::Limit(limits::COVERAGE_FACTOR, "a result's k")).optional(),
    Column::number(
        "angle_deg",
        Range::Within {
            contains: angle_in_range,
            broken: ANGLE_RANGE,
        },
    )
    .optional(),
    Column::number(
        "dof",
        Range::Within {
            contains: dof_in_range,
            broken: DOF_RANGE,
        },
    )
    .optional(),
    Column::number(
        "nominal_deg",
        Range::Within {
            contains: nominal_in_range,
            broken: NOMINAL_RANGE,
        },
    )
    .optional(),
];

/// How result files are written: by polycal and by other programs and people, so the
/// spaces around fields are trimmed and columns not named in docs/FORMAT.md §3 (such as
/// `file`) are passed over whatever their names (docs/FORMAT.md §3.2).
const DIALECT: Dialect = Dialect {
    trimmed: true,
    unknown_names_checked: false,
};

/// Reads the bytes of a result file and checks every rule; `source` names it in messages.
pub(super) fn parse_bytes(bytes: &[u8], source: &str) -> Result<ResultFile, FileError> {
    let mut table = Reader::open_with(bytes, source, &COLUMNS, DIALECT)?;
    let mut file = ResultFile {
        source: source.to_string(),
        rows: Vec::new(),
        lines: Vec::new(),
        columns: Vec::new(),
    };
    // The line of the first row of each (quantity, index).
    let mut first: HashMap<(Quantity, u32), u64> = HashMap::new();
    let mut angles = AngleCheck::default();
    loop {
        let row = match table.next_row() {
            Ok(Some(row)) => row,
            Ok(None) => break,
            // a header and no rows: a result of nothing
            Err(e) if e.is_empty_table() => break,
            Err(e) => return Err(e.into()),
        };
        let result = result_row(&row)?;
        match first.entry((result.quantity, result.index)) {
            Entry::Occupied(line) => {
                return Err(row
                    .error(
                        Col::Quantity.at(),
                        format!(
                            "{} {} appears twice (first on line {})",
                            result.quantity,
                            result.index,
                            line.get()
                        ),
                    )
                    .into());
            }
            Entry::Vacant(slot) => {
                slot.insert(row.line());
            }
        }
        if let Err(problem) = angles.admit(file.rows.len(), &result) {
            let lines = &file.lines;
            let place = |i: usize| format!("line {}", lines.get(i).copied().unwrap_or(row.line()));
            let message = problem.message(&result, &file.rows, place);
            // At the angle_deg field of the row the problem is reported at (the first row
            // without an angle for a missing one; the column exists whenever an angle does).
            let angle = Col::AngleDeg.at();
            return Err(match problem {
                AngleProblem::Missing { without, .. } if without < file.rows.len() => {
                    row.error_on_row(without, angle, message)
                }
                _ => row.error(angle, message),
            }
            .into());
        }
        let columns = row.columns();
        let column = |col: Col| columns.get(col.at()).copied().flatten();
        file.columns.push(RowColumns {
            quantity: column(Col::Quantity).unwrap_or(1),
            index: column(Col::Index).unwrap_or(1),
            value: column(Col::Value).unwrap_or(1),
            expanded_u: column(Col::ExpandedU),
            u: column(Col::U),
            k: column(Col::K),
            nominal_deg: column(Col::NominalDeg),
        });
        file.lines.push(row.line());
        file.rows.push(result);
    }
    Ok(file)
}

/// The result of a row whose fields the reader read: the rules of one row beyond its
/// fields (an index of 0 only for an encoder error, no negative uncertainty).
fn result_row(row: &Row<'_>) -> Result<ResultRow, TableError> {
    let word = row.word(Col::Quantity.at())?;
    let Some(&quantity) = Quantity::ALL.get(word) else {
        let message = "internal error: a quantity word has no family".to_string();
        return Err(row.error(Col::Quantity.at(), message));
    };
    let index: u32 = row.integer(Col::Index.at())?;
    if index == 0 && quantity != Quantity::EncoderError {
        let what = match quantity {
            Quantity::SetupError => "autocollimator numbers start at 1",
            Quantity::AngleBlock => "angle blocks are numbered 1, 2, …",
            _ => "faces are numbered 1 … N",
        };
        return Err(row.error(
            Col::Index.at(),
            format!("column \"index\": 0 is not allowed for {quantity}: {what}"),
        ));
    }
    let uncertainty = |col: Col| match row.optional_number(col.at()) {
        Some(x) if x < 0.0 => Err(row.error(
            col.at(),
            format!(
                "column {:?}: {} is negative; an uncertainty is at least 0",
                col.name(),
                crate::input::table::show(row.text(col.at()))
            ),
        )),
        x => Ok(x),
    };
    let nominal_deg = row.optional_number(Col::NominalDeg.at());
    if nominal_deg.is_some() && quantity != Quantity::AngleBlock {
        return Err(row.error(
            Col::NominalDeg.at(),
            format!(
                "column \"nominal_deg\": an angle block's nominal angle on a {quantity} row \
                 (only angle_block rows have one)"
            ),
        ));
    }
    Ok(ResultRow {
        quantity,
        index,
        value: row.number(Col::Value.at())?,
        expanded_u: uncertainty(Col::ExpandedU)?,
        u: uncertainty(Col::U)?,
        k: row.optional_number(Col::K.at()),
        angle_deg: row.optional_number(Col::AngleDeg.at()).map(|a| a + 0.0), // −0 is 0
        dof: row.optional_number(Col::Dof.at()),
        nominal_deg,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_quantity_words_are_the_families_in_order() {
        let names: Vec<&str> = Quantity::ALL.iter().map(|q| q.name()).collect();
        assert_eq!(QUANTITY_WORDS, names.as_slice());
    }
}

#[cfg(test)]
mod required_columns {
    #[test]
    fn the_description_requires_the_columns_its_kind_is_recognised_by() {
        let kind = crate::input::kind::FileKind::Result;
        crate::input::table::assert_requires(&super::COLUMNS, kind);
    }
}
