//! The result file (FORMAT.md §3). Placeholder until the uncertainty branch lands.

/// One row of the result file.
#[derive(Debug, Clone, PartialEq)]
pub struct ResultRow {
    /// `pitch_deviation`, `face_deviation`, `encoder_error` or `setup_error`.
    pub quantity: String,
    /// Face, step or autocollimator.
    pub index: u32,
    /// Estimate, arcsec.
    pub value: f64,
    /// Standard uncertainty, arcsec.
    pub u: Option<f64>,
    /// Expanded uncertainty (column `U`), arcsec.
    pub expanded_u: Option<f64>,
    /// Coverage factor.
    pub k: Option<f64>,
}

fn opt(v: Option<f64>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

/// Writes result rows as the result CSV.
pub fn write_results<W: std::io::Write>(mut w: W, rows: &[ResultRow]) -> std::io::Result<()> {
    writeln!(w, "quantity,index,value,U,u,k")?;
    for r in rows {
        writeln!(
            w,
            "{},{},{},{},{},{}",
            r.quantity,
            r.index,
            r.value,
            opt(r.expanded_u),
            opt(r.u),
            opt(r.k)
        )?;
    }
    Ok(())
}
