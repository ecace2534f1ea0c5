//! Number and table formatting for the human-readable tables (rounding is for tables only;
//! JSON and CSV carry full precision), and the table of an evaluated budget.

use std::fmt;

use super::budget::{BudgetResult, ComponentResult, DofPolicy};
use crate::input::limits::sig;

/// Degrees of freedom: `∞` for `None`, an integer as is, otherwise one decimal.
pub(crate) fn dof(nu: Option<f64>) -> String {
    match nu {
        None => "∞".to_string(),
        Some(nu) if nu.fract() == 0.0 && nu.abs() < 1e15 => format!("{nu}"),
        Some(nu) => format!("{nu:.1}"),
    }
}

/// A probability as a percentage without trailing zeros: 0.95 → `95`, 0.9545 → `95.45`.
pub(crate) fn percent(p: f64) -> String {
    format!("{}", (p * 100.0 * 1e9).round() / 1e9)
}

/// A plain-text table: a header, a rule, then the rows; columns separated by two spaces,
/// right-aligned where `right` says so.
pub(crate) fn write_table<const N: usize>(
    out: &mut (impl fmt::Write + ?Sized),
    header: &[String; N],
    rows: &[[String; N]],
    right: &[bool; N],
) -> fmt::Result {
    let mut width = [0usize; N];
    for row in std::iter::once(header).chain(rows.iter()) {
        for (w, cell) in width.iter_mut().zip(row.iter()) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |row: &[String; N]| {
        let mut s = String::new();
        for (i, cell) in row.iter().enumerate() {
            if i > 0 {
                s.push_str("  ");
            }
            let pad = width[i] - cell.chars().count();
            if right[i] {
                s.push_str(&" ".repeat(pad));
                s.push_str(cell);
            } else {
                s.push_str(cell);
                if i + 1 < N {
                    s.push_str(&" ".repeat(pad));
                }
            }
        }
        s.truncate(s.trim_end().len());
        s
    };
    writeln!(out, "{}", line(header))?;
    let total: usize = width.iter().sum::<usize>() + 2 * (N - 1);
    writeln!(out, "{}", "-".repeat(total))?;
    for row in rows {
        writeln!(out, "{}", line(row))?;
    }
    Ok(())
}

/// [`write_table`] into a new string.
pub(crate) fn table<const N: usize>(
    header: &[String; N],
    rows: &[[String; N]],
    right: &[bool; N],
) -> String {
    struct Table<'a, const N: usize>(&'a [String; N], &'a [[String; N]], &'a [bool; N]);
    impl<const N: usize> fmt::Display for Table<'_, N> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write_table(f, self.0, self.1, self.2)
        }
    }
    Table(header, rows, right).to_string()
}

/// Renders an evaluated budget as a table in the style of GUM Workbench: quantity, type,
/// distribution, `u(xᵢ)`, `cᵢ`, `uᵢ(y)`, `νᵢ`, index; then `u_c`, `ν_eff`, `k` and `U`.
/// Numbers are rounded for reading (4 significant digits; `ν` to 0.1; `k` to 0.001);
/// JSON carries them at full precision. Components of nested budgets are indented.
///
/// ```
/// use polycal::uncertainty::budget::{Budget, Component, DofPolicy};
/// use polycal::uncertainty::distribution::Distribution;
///
/// let budget = Budget::new(vec![Component::type_b("x", Distribution::Normal { u: 0.1 }, None)]);
/// let mut table = String::new();
/// polycal::uncertainty::render_table(&mut table, &budget.evaluate(0.95, DofPolicy::Fractional)?)?;
/// assert!(table.contains("u_c   = 0.1000"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// The error of `out`.
pub fn render_table(out: &mut (impl fmt::Write + ?Sized), result: &BudgetResult) -> fmt::Result {
    fn walk(rows: &mut Vec<[String; 8]>, lines: &[ComponentResult], depth: usize) {
        for l in lines {
            rows.push([
                format!("{}{}", "  ".repeat(depth), l.name),
                l.evaluation.to_string(),
                l.distribution.clone(),
                sig(l.u, 4),
                sig(l.sensitivity, 4),
                sig(l.contribution, 4),
                dof(l.dof),
                format!("{:.1} %", l.index_percent),
            ]);
            walk(rows, &l.components, depth + 1);
        }
    }
    let mut rows: Vec<[String; 8]> = Vec::new();
    walk(&mut rows, &result.components, 0);
    let header = [
        "Quantity".to_string(),
        "Type".into(),
        "Distribution".into(),
        "u(x_i)".into(),
        "c_i".into(),
        "u_i(y)".into(),
        "ν_i".into(),
        "Index".into(),
    ];
    write_table(
        out,
        &header,
        &rows,
        &[false, false, false, true, true, true, true, true],
    )?;
    let k_note = match result.dof_policy {
        DofPolicy::K2 => "k = 2 by policy".to_string(),
        _ => format!(
            "t at p = {} % for ν = {}",
            percent(result.p),
            dof(result.dof_for_k())
        ),
    };
    writeln!(out)?;
    writeln!(
        out,
        "Combined standard uncertainty   u_c   = {}",
        sig(result.combined_u, 4)
    )?;
    writeln!(
        out,
        "Effective degrees of freedom    ν_eff = {}",
        dof(result.dof_eff)
    )?;
    writeln!(
        out,
        "Coverage factor                 k     = {:.3} ({k_note})",
        result.k
    )?;
    writeln!(
        out,
        "Expanded uncertainty            U     = {} (p = {} %)",
        sig(result.expanded_u, 3),
        percent(result.p)
    )
}

/// An evaluated budget's table ([`render_table`]) as a value to format, e.g.
/// `write!(io_out, "{}", budget_table(&result))`.
pub fn budget_table(result: &BudgetResult) -> impl fmt::Display + '_ {
    struct BudgetTable<'a>(&'a BudgetResult);
    impl fmt::Display for BudgetTable<'_> {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            render_table(f, self.0)
        }
    }
    BudgetTable(result)
}
