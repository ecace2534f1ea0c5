//! The angle rules of a result file (docs/FORMAT.md §3.2), which hold across its rows:
//! angles only on encoder errors, 0 ≤ angle < 360, every encoder error with an angle or
//! none, no two at one position. The reader, the writer's checks ([`check_rows`]) and
//! `compare` apply them through [`AngleCheck`].
//!
//! [`check_rows`]: super::check_rows

use std::collections::BTreeMap;

use super::{ANGLE_TOLERANCE_DEG, Quantity, ResultRow, angle_distance_deg, angle_in_range};

/// What breaks the angle rules of a result file (docs/FORMAT.md §3.2) across its rows;
/// rows are named by their position in the file (0-based), the caller names them by line
/// or by row number.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum AngleProblem {
    /// The angle is not finite or not in 0 ≤ angle < 360.
    OutOfRange,
    /// An angle on a row that is not an encoder error.
    NotEncoder,
    /// Encoder row `without` has no angle while encoder row `with` has one; the problem is
    /// reported at `without` (the first row without an angle).
    Missing {
        /// The first encoder row without an angle.
        without: usize,
        /// An encoder row with one.
        with: usize,
    },
    /// The angle is (within [`ANGLE_TOLERANCE_DEG`]) that of the earlier encoder row
    /// `first`.
    Duplicate {
        /// The earlier row.
        first: usize,
    },
}

impl AngleProblem {
    /// The message for the problem found on admitting `row`, `rows` being the rows admitted
    /// before it (so `row`'s position is `rows.len()`) and `place` naming a row by its
    /// position ("line 7", "row 3").
    pub(crate) fn message(
        &self,
        row: &ResultRow,
        rows: &[ResultRow],
        place: impl Fn(usize) -> String,
    ) -> String {
        let describe = |i: usize| match rows.get(i) {
            Some(r) => format!("{} {}", r.quantity, r.index),
            None => format!("{} {}", row.quantity, row.index),
        };
        match self {
            AngleProblem::OutOfRange => format!(
                "angle_deg must be a finite number of degrees, 0 ≤ angle_deg < 360, got {}",
                row.angle_deg
                    .map_or("nothing".to_string(), |a| a.to_string())
            ),
            AngleProblem::NotEncoder => format!(
                "angle_deg is given for {} {}: only encoder_error rows carry a table angle \
                 (leave the field empty)",
                row.quantity, row.index
            ),
            AngleProblem::Missing { without, with } => format!(
                "{} has no angle_deg, but {} on {} has one: either every encoder_error row \
                 carries its table angle or none does",
                describe(*without),
                describe(*with),
                place(*with)
            ),
            AngleProblem::Duplicate { first } => format!(
                "{} {} at angle_deg {} is the position of {} on {} (angles within {:e}° \
                 around the circle are one position)",
                row.quantity,
                row.index,
                row.angle_deg.unwrap_or(f64::NAN),
                describe(*first),
                place(*first),
                ANGLE_TOLERANCE_DEG
            ),
        }
    }
}

/// The angle rules of a result file, checked row by row in file order: angles only on
/// encoder errors, 0 ≤ angle < 360, every encoder error with an angle or none, no two at
/// one position.
#[derive(Debug, Default)]
pub(crate) struct AngleCheck {
    /// The angles seen (non-negative, so their bits sort as the numbers) and their rows.
    seen: BTreeMap<u64, usize>,
    first_with: Option<usize>,
    first_without: Option<usize>,
}

impl AngleCheck {
    /// Admits row `position` (the rows before it admitted already).
    pub(crate) fn admit(&mut self, position: usize, row: &ResultRow) -> Result<(), AngleProblem> {
        if row.quantity != Quantity::EncoderError {
            return match row.angle_deg {
                Some(_) => Err(AngleProblem::NotEncoder),
                None => Ok(()),
            };
        }
        let Some(angle) = row.angle_deg else {
            if let Some(with) = self.first_with {
                return Err(AngleProblem::Missing {
                    without: position,
                    with,
                });
            }
            self.first_without.get_or_insert(position);
            return Ok(());
        };
        if !angle_in_range(angle) {
            return Err(AngleProblem::OutOfRange);
        }
        if let Some(without) = self.first_without {
            return Err(AngleProblem::Missing {
                without,
                with: position,
            });
        }
        self.first_with.get_or_insert(position);
        let angle = angle + 0.0; // −0 is 0
        if let Some(first) = self.near(angle) {
            return Err(AngleProblem::Duplicate { first });
        }
        self.seen.insert(angle.to_bits(), position);
        Ok(())
    }

    /// The earliest row seen whose angle is within the tolerance of `angle`.
    fn near(&self, angle: f64) -> Option<usize> {
        let tolerance = ANGLE_TOLERANCE_DEG;
        let mut windows = vec![(angle - tolerance, angle + tolerance)];
        if angle - tolerance < 0.0 {
            windows.push((angle - tolerance + 360.0, 360.0));
        }
        if angle + tolerance >= 360.0 {
            windows.push((0.0, angle + tolerance - 360.0));
        }
        windows
            .into_iter()
            .flat_map(|(low, high)| {
                // Widened by a hair, then judged by the distance itself.
                let low = (low - tolerance).max(0.0);
                let high = high + tolerance;
                self.seen.range(low.to_bits()..=high.to_bits())
            })
            .filter(|(bits, _)| angle_distance_deg(f64::from_bits(**bits), angle) <= tolerance)
            .map(|(_, &position)| position)
            .min()
    }
}
