//! The design rows of a fit's readings, sparse, in one buffer: what every form of a
//! fit's geometry ([`super::core`], [`super::structured`]) reads its readings through.

/// The design rows of a fit's readings, sparse, in one buffer (no allocation per
/// reading): row i is its (index in ψ or g, coefficient) pairs.
#[derive(Debug, Clone, Default)]
pub(super) struct Rows {
    /// Every row's pairs, row after row.
    entries: Vec<(usize, f64)>,
    /// Where row i begins in `entries` (`starts[i]`) and ends (`starts[i + 1]`).
    starts: Vec<usize>,
}

impl Rows {
    /// No rows yet, room for `rows` of about `per_row` pairs.
    pub(super) fn with_capacity(rows: usize, per_row: usize) -> Self {
        let mut starts = Vec::with_capacity(rows + 1);
        starts.push(0);
        Rows {
            entries: Vec::with_capacity(rows.saturating_mul(per_row)),
            starts,
        }
    }

    /// A pair of the row being built (the last one [`Rows::end_row`] has not closed).
    pub(super) fn push(&mut self, index: usize, value: f64) {
        self.entries.push((index, value));
    }

    /// Closes the row being built.
    pub(super) fn end_row(&mut self) {
        self.starts.push(self.entries.len());
    }

    /// The number of rows.
    pub(super) fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }
}

impl std::ops::Index<usize> for Rows {
    type Output = [(usize, f64)];

    fn index(&self, i: usize) -> &[(usize, f64)] {
        &self.entries[self.starts[i]..self.starts[i + 1]]
    }
}
