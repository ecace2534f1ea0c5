//! One autocollimator's table of a mounting (rows cycles, columns stops) and its additive
//! fit value = a[stop] + b[cycle], the whole table's, without one row, or with one row
//! replaced: what the cycle test ([`super::test`]) compares.
//!
//! A complete table (every cycle reads every stop once, the usual case) keeps its row
//! and column sums, so that the fit without a row or with a row replaced costs one pass
//! over that row: the analysis of variance of a two-way table without replication,
//! RSS = Σx² − Σ_r R_r²/C − Σ_c C_c²/R + (Σx)²/(RC) (the values first centred on their
//! column's mean so that nothing large cancels), and a row x_c read at the stops S added
//! to a complete table of R rows raises the RSS by R/(R+1) · Σ_{c∈S} (d_c − d̄)², with
//! d_c = x_c − the column's mean and d̄ their mean over S, on |S| − 1 more degrees of
//! freedom (the column means are the rows' least-squares columns, each of variance
//! σ²/R, and the new row's own zero takes out d̄). Any other table is refitted by
//! alternating means ([`additive_rss`]).

use super::test::additive_rss;

/// One value of a table: row (cycle), column (stop), value.
pub(super) type Entry = (u32, usize, f64);

/// A table and what its fits need.
#[derive(Debug, Clone)]
pub(super) enum Table {
    /// Every row reads every column once.
    Complete(Complete),
    /// Any other table, refitted entry by entry.
    General(Vec<Entry>),
}

/// A complete table: its values centred on their column's mean, row by row, with the
/// sums of its rows and columns.
#[derive(Debug, Clone)]
pub(super) struct Complete {
    /// The rows' cycles, ascending.
    rows: Vec<u32>,
    /// The columns' stops, ascending.
    columns: Vec<usize>,
    /// The column means taken off the values.
    centre: Vec<f64>,
    /// The centred values, row after row (`rows.len() × columns.len()`).
    values: Vec<f64>,
    row_sum: Vec<f64>,
    column_sum: Vec<f64>,
    sum_of_squares: f64,
}

impl Table {
    /// The table of `entries`.
    pub(super) fn of(entries: Vec<Entry>) -> Table {
        match Complete::of(&entries) {
            Some(complete) => Table::Complete(complete),
            None => Table::General(entries),
        }
    }

    /// The additive fit of the whole table: RSS and degrees of freedom.
    pub(super) fn fit(&self) -> (f64, usize) {
        match self {
            Table::Complete(c) => c.fit(None),
            Table::General(entries) => additive_rss(entries),
        }
    }

    /// The additive fit of the table without row `cycle`.
    pub(super) fn fit_without(&self, cycle: u32) -> (f64, usize) {
        match self {
            Table::Complete(c) if c.rows.contains(&cycle) => c.fit(Some((cycle, None))),
            Table::Complete(_) => self.fit(),
            Table::General(entries) => {
                let rest: Vec<Entry> = entries.iter().copied().filter(|e| e.0 != cycle).collect();
                additive_rss(&rest)
            }
        }
    }

    /// The additive fit of the table with row `cycle` replaced by `row` (stop, value).
    pub(super) fn fit_replaced(&self, cycle: u32, row: &[(usize, f64)]) -> (f64, usize) {
        if let Table::Complete(c) = self
            && let Some(fit) = c.fit_with_row(cycle, row)
        {
            return fit;
        }
        let replaced: Vec<Entry> = self
            .entries()
            .into_iter()
            .filter(|e| e.0 != cycle)
            .chain(row.iter().map(|&(step, v)| (cycle, step, v)))
            .collect();
        additive_rss(&replaced)
    }

    /// The table's entries.
    fn entries(&self) -> Vec<Entry> {
        match self {
            Table::General(entries) => entries.clone(),
            Table::Complete(c) => c
                .rows
                .iter()
                .enumerate()
                .flat_map(|(i, &row)| {
                    c.columns.iter().enumerate().map(move |(j, &column)| {
                        (row, column, c.values[i * c.columns.len() + j] + c.centre[j])
                    })
                })
                .collect(),
        }
    }
}

impl Complete {
    /// The table of `entries` when every row reads every column exactly once.
    fn of(entries: &[Entry]) -> Option<Complete> {
        // rows and columns found by direct index (cycles and stops are small integers)
        let row_count = entries.iter().map(|e| e.0 as usize).max()? + 1;
        let column_count = entries.iter().map(|e| e.1).max()? + 1;
        let mut row_index = vec![usize::MAX; row_count];
        let mut column_index = vec![usize::MAX; column_count];
        for e in entries {
            row_index[e.0 as usize] = 0;
            column_index[e.1] = 0;
        }
        let rows: Vec<u32> = (0..row_count)
            .filter(|&r| row_index[r] == 0)
            .map(|r| r as u32)
            .collect();
        let columns: Vec<usize> = (0..column_count)
            .filter(|&j| column_index[j] == 0)
            .collect();
        for (i, &r) in rows.iter().enumerate() {
            row_index[r as usize] = i;
        }
        for (j, &column) in columns.iter().enumerate() {
            column_index[column] = j;
        }
        let (r, c) = (rows.len(), columns.len());
        if entries.len() != r * c {
            return None;
        }
        let mut values = vec![f64::NAN; r * c];
        for &(row, column, v) in entries {
            let cell = &mut values[row_index[row as usize] * c + column_index[column]];
            if !cell.is_nan() || v.is_nan() {
                // a cell read twice (another then not at all)
                return None;
            }
            *cell = v;
        }
        let mut centre = vec![0.0; c];
        for row in values.chunks(c) {
            centre.iter_mut().zip(row).for_each(|(m, v)| *m += v);
        }
        centre.iter_mut().for_each(|m| *m /= r as f64);
        for row in values.chunks_mut(c) {
            row.iter_mut().zip(&centre).for_each(|(v, m)| *v -= m);
        }
        let row_sum = values.chunks(c).map(|row| row.iter().sum()).collect();
        let mut column_sum = vec![0.0; c];
        for row in values.chunks(c) {
            column_sum.iter_mut().zip(row).for_each(|(s, v)| *s += v);
        }
        let sum_of_squares = values.iter().map(|v| v * v).sum();
        Some(Complete {
            rows,
            columns,
            centre,
            values,
            row_sum,
            column_sum,
            sum_of_squares,
        })
    }

    /// The fit with row `cycle` (one of the table's) replaced by `row` (stop, value), read
    /// at some of the table's stops, each once (module documentation); `None` for any
    /// other row.
    fn fit_with_row(&self, cycle: u32, row: &[(usize, f64)]) -> Option<(f64, usize)> {
        let i = self.rows.binary_search(&cycle).ok()?;
        let c = self.columns.len();
        let rest_rows = (self.rows.len() - 1) as f64;
        let (rss_rest, dof_rest) = self.fit(Some((cycle, None)));
        if row.is_empty() || rest_rows == 0.0 {
            return (row.is_empty()).then_some((rss_rest, dof_rest));
        }
        let old = &self.values[i * c..(i + 1) * c];
        let mut seen = vec![false; c];
        let mut d = Vec::with_capacity(row.len());
        for &(step, v) in row {
            let j = self.columns.binary_search(&step).ok()?;
            if std::mem::replace(&mut seen[j], true) || !v.is_finite() {
                return None;
            }
            let rest_mean = (self.column_sum[j] - old[j]) / rest_rows;
            d.push(v - self.centre[j] - rest_mean);
        }
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let added: f64 = d.iter().map(|x| (x - mean).powi(2)).sum();
        Some((
            rss_rest + rest_rows / (rest_rows + 1.0) * added,
            dof_rest + d.len() - 1,
        ))
    }

    /// The fit of the table, or with row `change.0` left out (`None`) or replaced by the
    /// centred values given.
    fn fit(&self, change: Option<(u32, Option<&[f64]>)>) -> (f64, usize) {
        let c = self.columns.len();
        let mut sum_of_squares = self.sum_of_squares;
        let mut column_sum = self.column_sum.clone();
        let mut row_squares: f64 = self.row_sum.iter().map(|s| s * s).sum();
        let mut rows = self.rows.len();
        if let Some((cycle, replacement)) = change
            && let Ok(i) = self.rows.binary_search(&cycle)
        {
            let old = &self.values[i * c..(i + 1) * c];
            sum_of_squares -= old.iter().map(|v| v * v).sum::<f64>();
            column_sum.iter_mut().zip(old).for_each(|(s, v)| *s -= v);
            row_squares -= self.row_sum[i] * self.row_sum[i];
            rows -= 1;
            if let Some(new) = replacement {
                sum_of_squares += new.iter().map(|v| v * v).sum::<f64>();
                column_sum.iter_mut().zip(new).for_each(|(s, v)| *s += v);
                let new_sum: f64 = new.iter().sum();
                row_squares += new_sum * new_sum;
                rows += 1;
            }
        }
        if rows == 0 || c == 0 {
            return (0.0, 0);
        }
        let total: f64 = column_sum.iter().sum();
        let column_squares: f64 = column_sum.iter().map(|s| s * s).sum();
        let n = (rows * c) as f64;
        let rss = sum_of_squares - row_squares / c as f64 - column_squares / rows as f64
            + total * total / n;
        (rss.max(0.0), rows * c - (rows + c - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 5 × 7 table with row and column effects, an interaction and an offset of
    /// 1 000″ (for cancellation).
    fn table() -> Vec<Entry> {
        (1..=5u32)
            .flat_map(|r| {
                (0..7usize).map(move |c| {
                    let wobble = (((r as usize) * 31 + c * 17) % 13) as f64 * 0.01;
                    (r, c, 1000.0 + 3.0 * c as f64 - 0.5 * r as f64 + wobble)
                })
            })
            .collect()
    }

    #[test]
    fn the_sums_give_the_refitted_rss_without_and_with_a_row_replaced() {
        let entries = table();
        let t = Table::of(entries.clone());
        assert!(matches!(t, Table::Complete(_)));
        let close = |a: (f64, usize), b: (f64, usize)| {
            assert_eq!(a.1, b.1);
            assert!((a.0 - b.0).abs() < 1e-9 * (1.0 + b.0), "{a:?} {b:?}");
        };
        close(t.fit(), additive_rss(&entries));
        let rest: Vec<Entry> = entries.iter().copied().filter(|e| e.0 != 3).collect();
        close(t.fit_without(3), additive_rss(&rest));
        let row: Vec<(usize, f64)> = (0..7)
            .map(|c| (c, 1000.0 + ((c * 5) % 7) as f64 * 0.3))
            .collect();
        let replaced: Vec<Entry> = rest
            .iter()
            .copied()
            .chain(row.iter().map(|&(c, v)| (3, c, v)))
            .collect();
        close(t.fit_replaced(3, &row), additive_rss(&replaced));
        // a replacement that misses a column goes the general way
        let short = &row[1..];
        let replaced: Vec<Entry> = rest
            .iter()
            .copied()
            .chain(short.iter().map(|&(c, v)| (3, c, v)))
            .collect();
        close(t.fit_replaced(3, short), additive_rss(&replaced));
        // and both agree with a dense least-squares solve of the 11 parameters made
        // outside the crate (Python, normal equations): RSS 132.52112273809433
        assert!((additive_rss(&replaced).0 - 132.52112273809433).abs() < 1e-8);
    }

    #[test]
    fn an_incomplete_table_is_refitted_entry_by_entry() {
        let mut entries = table();
        entries.remove(4);
        let t = Table::of(entries.clone());
        assert!(matches!(t, Table::General(_)));
        let rest: Vec<Entry> = entries.iter().copied().filter(|e| e.0 != 2).collect();
        assert_eq!(t.fit_without(2), additive_rss(&rest));
        // a cell read twice with another missing is not complete
        entries.push(entries[0]);
        assert!(matches!(Table::of(entries), Table::General(_)));
    }
}
