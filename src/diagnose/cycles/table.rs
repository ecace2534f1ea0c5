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

/// The distinct keys (cycles or stops) of a table's rows or columns, ascending, and each
/// key's place among them: by direct index when the keys are small, as they are in a
/// run's files, else by search (a file may number its cycles up to 2³²; a vector as long
/// as the largest would not fit in memory).
pub(super) struct Keys {
    /// The distinct keys, ascending.
    pub sorted: Vec<usize>,
    /// Each key's place, indexed by the key, when the keys are small.
    direct: Option<Vec<usize>>,
}

impl Keys {
    /// The keys of `keys`.
    pub(super) fn of(keys: impl Iterator<Item = usize> + Clone) -> Keys {
        let count = keys.clone().count();
        let largest = keys.clone().max().unwrap_or(0);
        if largest <= 4 * count + 64 {
            let mut place = vec![usize::MAX; largest + 1];
            keys.for_each(|k| place[k] = 0);
            let sorted: Vec<usize> = (0..=largest).filter(|&k| place[k] == 0).collect();
            for (i, &k) in sorted.iter().enumerate() {
                place[k] = i;
            }
            Keys {
                sorted,
                direct: Some(place),
            }
        } else {
            let mut sorted: Vec<usize> = keys.collect();
            sorted.sort_unstable();
            sorted.dedup();
            Keys {
                sorted,
                direct: None,
            }
        }
    }

    /// The place of `key`, one of the keys.
    pub(super) fn place(&self, key: usize) -> usize {
        match &self.direct {
            Some(place) => place[key],
            None => self.sorted.binary_search(&key).unwrap_or(usize::MAX),
        }
    }

    /// The number of distinct keys.
    pub(super) fn len(&self) -> usize {
        self.sorted.len()
    }
}

impl Complete {
    /// The table of `entries` when every row reads every column exactly once.
    fn of(entries: &[Entry]) -> Option<Complete> {
        let row_keys = Keys::of(entries.iter().map(|e| e.0 as usize));
        let column_keys = Keys::of(entries.iter().map(|e| e.1));
        let rows: Vec<u32> = row_keys.sorted.iter().map(|&r| r as u32).collect();
        let columns = column_keys.sorted.clone();
        let (r, c) = (rows.len(), columns.len());
        if entries.len() != r * c {
            return None;
        }
        let mut values = vec![f64::NAN; r * c];
        for &(row, column, v) in entries {
            let cell = &mut values[row_keys.place(row as usize) * c + column_keys.place(column)];
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

/// The residual sum of squares and degrees of freedom of the additive fit
/// value = a[column] + b[row] of `entries`, by alternating means until the RSS stops
/// falling (a complete table has its closed form in [`Table`]).
pub(super) fn additive_rss(entries: &[Entry]) -> (f64, usize) {
    if entries.is_empty() {
        return (0.0, 0);
    }
    let row_keys = Keys::of(entries.iter().map(|e| e.0 as usize));
    let column_keys = Keys::of(entries.iter().map(|e| e.1));
    // each entry's row and column by place
    let cells: Vec<(usize, usize, f64)> = entries
        .iter()
        .map(|e| (row_keys.place(e.0 as usize), column_keys.place(e.1), e.2))
        .collect();
    let mut in_row = vec![0usize; row_keys.len()];
    let mut in_column = vec![0usize; column_keys.len()];
    for e in &cells {
        in_row[e.0] += 1;
        in_column[e.1] += 1;
    }
    let mut a = vec![0.0; column_keys.len()];
    let mut b = vec![0.0; row_keys.len()];
    let mut previous = f64::INFINITY;
    let mut rss = 0.0;
    for _ in 0..500 {
        a.iter_mut().for_each(|x| *x = 0.0);
        for e in &cells {
            a[e.1] += e.2 - b[e.0];
        }
        for (x, &n) in a.iter_mut().zip(&in_column) {
            *x /= n.max(1) as f64;
        }
        b.iter_mut().for_each(|x| *x = 0.0);
        for e in &cells {
            b[e.0] += e.2 - a[e.1];
        }
        for (x, &n) in b.iter_mut().zip(&in_row) {
            *x /= n.max(1) as f64;
        }
        rss = cells
            .iter()
            .map(|e| (e.2 - a[e.1] - b[e.0]).powi(2))
            .sum::<f64>();
        // (the first pass has nothing to compare with: ∞ − rss ≤ ∞ would stop it there)
        if previous.is_finite() && previous - rss <= 1e-12 * previous.max(f64::MIN_POSITIVE) {
            break;
        }
        previous = rss;
    }
    let rows = in_row.iter().filter(|&&n| n > 0).count();
    let columns = in_column.iter().filter(|&&n| n > 0).count();
    (rss, entries.len().saturating_sub(rows + columns - 1))
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
    fn cycles_numbered_up_to_two_to_the_32_fit_as_small_ones() {
        // a file may number a cycle 4 000 000 000: the fit is that of the same table
        // numbered 1 … 5 (a vector indexed by the cycle would need 32 GB and abort)
        let small = table();
        let large: Vec<Entry> = small
            .iter()
            .map(|&(r, c, v)| (if r == 5 { 4_000_000_000 } else { r }, c, v))
            .collect();
        let (t_small, t_large) = (Table::of(small.clone()), Table::of(large.clone()));
        assert_eq!(t_large.fit(), t_small.fit());
        assert_eq!(t_large.fit_without(4_000_000_000), t_small.fit_without(5));
        // and the alternating means of an incomplete one
        let (mut small, mut large) = (small, large);
        small.remove(3);
        large.remove(3);
        let (a, b) = (additive_rss(&small), additive_rss(&large));
        assert_eq!(a.1, b.1);
        assert!((a.0 - b.0).abs() < 1e-9, "{a:?} {b:?}");
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
