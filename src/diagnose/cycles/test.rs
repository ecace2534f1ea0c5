//! The test of one cycle against the others: an exact F test of the cycle × stop
//! interaction, autocollimator by autocollimator, with no model fitted.
//!
//! For each autocollimator of a mounting, the readings form a table: one row per cycle,
//! one column per stop (the closing stop its own column). Whatever the base model and the
//! effects it may lack, as long as they are the same at a stop in every cycle, the table
//! is additive: reading = a[stop] + b[cycle] + noise (the stop's α, φ and setup error in
//! a[stop]; a zero re-set per cycle, a direction offset, a linear drift of a clockwise run
//! in a[stop] + b[cycle]). A cycle logged wrongly breaks the additivity in its own row.
//! The statistic for cycle c is the Chow F of its row against the additive fit of the
//! other rows, summed over the autocollimators:
//!
//! F = [(RSS_all − RSS_rest) / (dof_all − dof_rest)] / [RSS_rest / dof_rest],
//!
//! exactly F-distributed under the additive model with Gaussian noise of one σ.

use statrs::distribution::{ContinuousCDF, FisherSnedecor};

use super::table::Table;

/// The F statistic (numerator sum of squares over its degrees of freedom against the
/// denominator's) and its upper-tail p: ∞ for a numerator against a zero denominator, 0
/// for neither.
pub(super) fn f_test(
    numerator: f64,
    dof_numerator: usize,
    denominator: f64,
    dof_denominator: usize,
) -> (f64, f64) {
    let top = numerator / dof_numerator as f64;
    let bottom = denominator / dof_denominator as f64;
    let f_statistic = if bottom > 0.0 {
        top / bottom
    } else if top > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    let p_value = FisherSnedecor::new(dof_numerator as f64, dof_denominator as f64)
        .map_or(1.0, |d| d.sf(f_statistic));
    (f_statistic, p_value)
}

/// A Chow F test of one cycle against the others.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Chow {
    /// The F statistic.
    pub f_statistic: f64,
    /// Numerator degrees of freedom (the cycle's readings less its zeros and the stops
    /// only it reads).
    pub dof_numerator: usize,
    /// Denominator degrees of freedom (the interaction of the other cycles).
    pub dof_denominator: usize,
    /// Upper-tail p-value.
    pub p_value: f64,
}

/// The additive fits of every table in `tables`: summed RSS and degrees of freedom.
pub(super) fn fits(tables: &[Table]) -> (f64, usize) {
    sum(tables.iter().map(Table::fit))
}

/// The additive fits of every table in `tables` without row `cycle`.
pub(super) fn fits_without(tables: &[Table], cycle: u32) -> (f64, usize) {
    sum(tables.iter().map(|t| t.fit_without(cycle)))
}

/// The sum of fits' RSS and degrees of freedom.
pub(super) fn sum(fits: impl Iterator<Item = (f64, usize)>) -> (f64, usize) {
    fits.fold((0.0, 0), |acc, (r, d)| (acc.0 + r, acc.1 + d))
}

/// The test of row `cycle` of every table in `tables` against their other rows; `None`
/// when the others leave fewer than `min_rest_dof` degrees of freedom or the cycle adds
/// none.
pub(super) fn chow(tables: &[Table], cycle: u32, min_rest_dof: usize) -> Option<Chow> {
    chow_of(fits(tables), fits_without(tables, cycle), min_rest_dof)
}

/// The test from the fits of the whole tables, `all`, and of the tables without the
/// cycle tested, `rest` ([`fits`], [`fits_without`]): a cycle's repairs share `rest`.
pub(super) fn chow_of(all: (f64, usize), rest: (f64, usize), min_rest_dof: usize) -> Option<Chow> {
    let ((rss_all, dof_all), (rss_rest, dof_rest)) = (all, rest);
    let dof_numerator = dof_all.checked_sub(dof_rest)?;
    if dof_numerator == 0 || dof_rest < min_rest_dof {
        return None;
    }
    let (f_statistic, p_value) = f_test(
        (rss_all - rss_rest).max(0.0),
        dof_numerator,
        rss_rest,
        dof_rest,
    );
    Some(Chow {
        f_statistic,
        dof_numerator,
        dof_denominator: dof_rest,
        p_value,
    })
}

#[cfg(test)]
mod tests {
    use super::super::table::{Entry, additive_rss};
    use super::*;

    #[test]
    fn an_additive_table_fits_exactly_and_counts_its_parameters() {
        // 3 rows × 4 columns of a[c] + b[r]: rss 0, dof 12 − 6 = 6
        let entries: Vec<Entry> = (1..=3u32)
            .flat_map(|r| (0..4usize).map(move |c| (r, c, c as f64 * 0.7 - r as f64 * 1.3)))
            .collect();
        let (rss, dof) = additive_rss(&entries);
        assert!(rss < 1e-20, "{rss}");
        assert_eq!(dof, 6);
    }

    #[test]
    fn one_interaction_cell_by_hand() {
        // 2 × 2 table with one cell off by d: the interaction contrast carries d²/4
        let d = 2.0;
        let entries: Vec<Entry> = vec![(1, 0, 0.0), (1, 1, 0.0), (2, 0, 0.0), (2, 1, d)];
        let (rss, dof) = additive_rss(&entries);
        assert!((rss - d * d / 4.0).abs() < 1e-12, "{rss}");
        assert_eq!(dof, 1);
    }

    #[test]
    fn a_row_off_at_one_column_is_found() {
        // 4 rows, 6 columns, small deterministic "noise"; row 3 off by 1 at column 2
        let entries: Vec<Entry> = (1..=4u32)
            .flat_map(|r| {
                (0..6usize).map(move |c| {
                    let noise = 0.01 * (((r as usize * 7 + c * 3) % 5) as f64 - 2.0);
                    let off = if r == 3 && c == 2 { 1.0 } else { 0.0 };
                    (r, c, c as f64 + r as f64 + noise + off)
                })
            })
            .collect();
        let test = chow(&[Table::of(entries.clone())], 3, 1).expect("a test");
        assert_eq!((test.dof_numerator, test.dof_denominator), (5, 10));
        assert!(test.p_value < 1e-6, "{test:?}");
        let other = chow(&[Table::of(entries)], 1, 1).expect("a test");
        assert!(other.f_statistic < test.f_statistic);
    }
}
