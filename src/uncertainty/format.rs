//! Number and table formatting for the human-readable tables (rounding is for tables only;
//! JSON and CSV carry full precision).

/// `x` with `digits` significant digits, in fixed notation between 10⁻⁴ and 10⁶.
pub(crate) fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        return format!("{:.*e}", digits.saturating_sub(1), x);
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

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
pub(crate) fn table<const N: usize>(
    header: &[String; N],
    rows: &[[String; N]],
    right: &[bool; N],
) -> String {
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
        s.trim_end().to_string()
    };
    let mut out = line(header);
    out.push('\n');
    let total: usize = width.iter().sum::<usize>() + 2 * (N - 1);
    out.push_str(&"-".repeat(total));
    out.push('\n');
    for row in rows {
        out.push_str(&line(row));
        out.push('\n');
    }
    out
}
