//! Which row of the other result is the same quantity: by `(quantity, index)`, or the
//! encoder errors by table angle (docs/FORMAT.md §5.4, "Matching encoder errors").

use std::collections::HashMap;

use super::EncoderMatching;
use crate::results::{ANGLE_TOLERANCE_DEG, Quantity, ResultRow, angle_distance_deg};

/// The rows of one result, ready to be matched to the rows of the other: by
/// `(quantity, index)`, or the encoder errors by angle. Rows are named by their position
/// in the result.
pub(super) struct Matcher<'r> {
    rows: &'r [ResultRow],
    by_key: HashMap<(Quantity, u32), usize>,
    /// The encoder errors' angles and positions, sorted by angle (when matching by angle).
    by_angle: Vec<(f64, usize)>,
    by: EncoderMatching,
}

impl<'r> Matcher<'r> {
    pub(super) fn new(rows: &'r [ResultRow], by: EncoderMatching) -> Matcher<'r> {
        let by_angle_here = |row: &ResultRow| {
            by == EncoderMatching::Angle && row.quantity == Quantity::EncoderError
        };
        let by_key = rows
            .iter()
            .enumerate()
            .filter(|(_, row)| !by_angle_here(row))
            .map(|(i, row)| ((row.quantity, row.index), i))
            .collect();
        let mut by_angle: Vec<(f64, usize)> = rows
            .iter()
            .enumerate()
            .filter(|(_, row)| by_angle_here(row))
            .filter_map(|(i, row)| row.angle_deg.map(|angle| (angle, i)))
            .collect();
        by_angle.sort_by(|x, y| x.0.total_cmp(&y.0));
        Matcher {
            rows,
            by_key,
            by_angle,
            by,
        }
    }

    /// Whether `row` (of the other result) is matched by angle.
    pub(super) fn by_angle(&self, row: &ResultRow) -> bool {
        self.by == EncoderMatching::Angle && row.quantity == Quantity::EncoderError
    }

    /// The positions of the rows matching `row` of the other result: at most one by key;
    /// by angle, every encoder error within the tolerance around the circle, nearest
    /// first.
    pub(super) fn matches(&self, row: &ResultRow) -> Vec<usize> {
        if !self.by_angle(row) {
            return self
                .by_key
                .get(&(row.quantity, row.index))
                .copied()
                .into_iter()
                .collect();
        }
        let Some(angle) = row.angle_deg else {
            return Vec::new();
        };
        let tolerance = ANGLE_TOLERANCE_DEG;
        let mut windows = vec![(angle - tolerance, angle + tolerance)];
        if angle - tolerance < 0.0 {
            windows.push((angle - tolerance + 360.0, f64::INFINITY));
        }
        if angle + tolerance >= 360.0 {
            windows.push((f64::NEG_INFINITY, angle + tolerance - 360.0));
        }
        let mut found: Vec<(f64, usize)> = Vec::new();
        for (low, high) in windows {
            // Widened by a hair, then judged by the distance itself.
            let (low, high) = (low - tolerance, high + tolerance);
            let from = self.by_angle.partition_point(|(a, _)| *a < low);
            for &(a, other) in self.by_angle[from..].iter().take_while(|(a, _)| *a <= high) {
                let distance = angle_distance_deg(a, angle);
                if distance <= tolerance && !found.iter().any(|&(_, i)| i == other) {
                    found.push((distance, other));
                }
            }
        }
        found.sort_by(|x, y| x.0.total_cmp(&y.0));
        found.into_iter().map(|(_, i)| i).collect()
    }

    /// The row at position `i`.
    pub(super) fn row(&self, i: usize) -> &'r ResultRow {
        &self.rows[i]
    }
}
