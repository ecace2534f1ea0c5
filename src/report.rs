//! Outputs of `polycal solve`: the JSON object of FORMAT.md §5, the result CSV of §3,
//! and a table for people.
//!
//! JSON and CSV carry numbers at full precision (the shortest text that reads back to
//! the same double); only the table rounds.

use crate::results::ResultRow;
use crate::solve::{Method, SigmaSource, Solution};
use serde::Serialize;
use std::fmt::Write as _;

/// Output format of a reporting command (`--format`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Format {
    /// A table for people (the default).
    #[default]
    Table,
    /// JSON (one object per input file; JSON Lines for several).
    Json,
    /// CSV.
    Csv,
}

/// A setup error in the JSON report.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SetupErrorReport {
    /// Polygon mounting.
    pub setup: u32,
    /// Autocollimator.
    pub ac: u32,
    /// Estimate, arcsec.
    pub value: f64,
    /// Standard uncertainty, arcsec (null when unknown).
    pub u: Option<f64>,
}

/// The JSON object of `polycal solve` (FORMAT.md §5), arcsec throughout.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SolveReport {
    /// The input file, present when several files were solved.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// N.
    pub faces: usize,
    /// Number of readings.
    pub readings: usize,
    /// Residual degrees of freedom.
    pub dof: usize,
    /// √(RSS/dof); null when dof = 0.
    pub residual_rms: Option<f64>,
    /// β\[1..=N\].
    pub pitch_deviation: Vec<f64>,
    /// u(β), k = 1; null when σ is unknown.
    pub pitch_deviation_u: Option<Vec<f64>>,
    /// φ\[1..=N\].
    pub face_deviation: Vec<f64>,
    /// u(φ), k = 1 (an addition to FORMAT.md §5).
    pub face_deviation_u: Option<Vec<f64>>,
    /// α[0..N).
    pub encoder_error: Vec<f64>,
    /// u(α), k = 1.
    pub encoder_error_u: Option<Vec<f64>>,
    /// Setup errors per (setup, ac).
    pub setup_error: Vec<SetupErrorReport>,
    /// Effect terms in the fitted model (FORMAT.md §6); empty for the base model.
    pub effects: Vec<serde_json::Value>,
    /// `closed-form` or `lsq` (an addition).
    pub method: &'static str,
    /// σ of one reading used for the uncertainties, arcsec (an addition).
    pub sigma: Option<f64>,
    /// `residual` or `stated` (an addition).
    pub sigma_source: Option<&'static str>,
}

impl SolveReport {
    /// Builds the report of a solution.
    pub fn new(solution: &Solution, file: Option<String>) -> Self {
        let setup_u = solution.setup_error_u();
        Self {
            file,
            faces: solution.faces,
            readings: solution.readings,
            dof: solution.dof,
            residual_rms: solution.residual_rms(),
            pitch_deviation: solution.pitch_deviation.clone(),
            pitch_deviation_u: solution.pitch_deviation_u(),
            face_deviation: solution.face_deviation.clone(),
            face_deviation_u: solution.face_deviation_u(),
            encoder_error: solution.encoder_error.clone(),
            encoder_error_u: solution.encoder_error_u(),
            setup_error: solution
                .setup_error
                .iter()
                .enumerate()
                .map(|(k, s)| SetupErrorReport {
                    setup: s.setup,
                    ac: s.ac,
                    value: s.value,
                    u: setup_u.as_ref().map(|u| u[k]),
                })
                .collect(),
            effects: Vec::new(),
            method: solution.method.as_str(),
            sigma: solution.sigma.map(|(s, _)| s),
            sigma_source: solution.sigma.map(|(_, source)| match source {
                SigmaSource::Residual => "residual",
                SigmaSource::Stated => "stated",
            }),
        }
    }

    /// One-line JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|_| unreachable!("plain data serializes"))
    }
}

/// The result rows (FORMAT.md §3) of a solution: pitch deviations, face deviations,
/// encoder errors and setup errors (index = autocollimator; with several mountings the
/// index is `setup·1000 + ac`, an addition to the contract), with `u` where known.
pub fn result_rows(solution: &Solution) -> Vec<ResultRow> {
    let mut rows = Vec::with_capacity(3 * solution.faces + solution.setup_error.len());
    let mut push = |quantity: &str, index: u32, value: f64, u: Option<f64>| {
        rows.push(ResultRow {
            quantity: quantity.to_string(),
            index,
            value,
            u,
            expanded_u: None,
            k: None,
        });
    };
    let at = |v: &Option<Vec<f64>>, i: usize| v.as_ref().map(|v| v[i]);
    let pitch_u = solution.pitch_deviation_u();
    let face_u = solution.face_deviation_u();
    let encoder_u = solution.encoder_error_u();
    let setup_u = solution.setup_error_u();
    for (i, &value) in solution.pitch_deviation.iter().enumerate() {
        push("pitch_deviation", (i + 1) as u32, value, at(&pitch_u, i));
    }
    for (i, &value) in solution.face_deviation.iter().enumerate() {
        push("face_deviation", (i + 1) as u32, value, at(&face_u, i));
    }
    for (i, &value) in solution.encoder_error.iter().enumerate() {
        push("encoder_error", i as u32, value, at(&encoder_u, i));
    }
    let several_setups = solution.setup_error.iter().any(|s| s.setup != 1);
    for (i, s) in solution.setup_error.iter().enumerate() {
        let index = if several_setups {
            s.setup * 1000 + s.ac
        } else {
            s.ac
        };
        push("setup_error", index, s.value, at(&setup_u, i));
    }
    rows
}

/// Writes the result rows of several files as one CSV with a leading `file` column (an
/// addition to FORMAT.md §3 for batch runs).
pub fn write_results_with_file<W: std::io::Write>(
    writer: W,
    files: &[(String, Vec<ResultRow>)],
) -> std::io::Result<()> {
    use std::io::Write as _;
    let mut body = Vec::new();
    let mut out = std::io::BufWriter::new(writer);
    let mut header_written = false;
    for (file, rows) in files {
        body.clear();
        crate::results::write_results(&mut body, rows)?;
        let text = String::from_utf8_lossy(&body);
        let mut lines = text.lines();
        let header = lines.next().unwrap_or_default();
        if !header_written {
            writeln!(out, "file,{header}")?;
            header_written = true;
        }
        let quoted = csv_field(file);
        for line in lines {
            writeln!(out, "{quoted},{line}")?;
        }
    }
    out.flush()
}

/// A CSV field, quoted when it needs to be.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn fixed(value: Option<f64>, decimals: usize) -> String {
    match value {
        Some(v) => format!("{v:.decimals$}"),
        None => "—".to_string(),
    }
}

/// The table for people: per face β, u(β), φ, u(φ); per position the angle, α, u(α);
/// the setup errors; dof and residual RMS.
pub fn render_table(solution: &Solution, source: &str) -> String {
    let mut out = String::new();
    let n = solution.faces;
    let method = match solution.method {
        Method::ClosedForm => "closed form (paper eqs. (6)-(10))",
        _ => "least squares",
    };
    let _ = writeln!(out, "polycal solve: {source}");
    let _ = writeln!(
        out,
        "{n} faces, {} readings, {method}, dof {}, residual RMS {}",
        solution.readings,
        solution.dof,
        solution
            .residual_rms()
            .map_or("— (exactly determined)".to_string(), |r| format!(
                "{r:.4}″"
            ))
    );
    match solution.sigma {
        Some((s, SigmaSource::Residual)) => {
            let _ = writeln!(out, "uncertainties (k = 1) from the residual σ = {s:.4}″");
        }
        Some((s, SigmaSource::Stated)) => {
            let _ = writeln!(
                out,
                "uncertainties (k = 1) from the stated reading noise σ = {s:.4}″"
            );
        }
        None => {
            let _ = writeln!(
                out,
                "no uncertainties: the fit has no residual degrees of freedom; state the reading noise with --sigma"
            );
        }
    }
    let pitch_u = solution.pitch_deviation_u();
    let face_u = solution.face_deviation_u();
    let encoder_u = solution.encoder_error_u();
    let at = |v: &Option<Vec<f64>>, i: usize| v.as_ref().map(|v| v[i]);
    let _ = writeln!(out, "\nPolygon (arcsec)");
    let _ = writeln!(
        out,
        "{:>5} {:>11} {:>9} {:>8} {:>9} {:>8}",
        "face", "nominal/°", "β", "u(β)", "φ", "u(φ)"
    );
    for f in 0..n {
        let _ = writeln!(
            out,
            "{:>5} {:>11.4} {:>9.4} {:>8} {:>9.4} {:>8}",
            f + 1,
            f as f64 * 360.0 / n as f64,
            solution.pitch_deviation[f],
            fixed(at(&pitch_u, f), 4),
            solution.face_deviation[f],
            fixed(at(&face_u, f), 4),
        );
    }
    let _ = writeln!(out, "\nEncoder (arcsec)");
    let _ = writeln!(
        out,
        "{:>8} {:>11} {:>9} {:>8}",
        "position", "angle/°", "α", "u(α)"
    );
    for p in 0..n {
        let _ = writeln!(
            out,
            "{:>8} {:>11.4} {:>9.4} {:>8}",
            p,
            p as f64 * 360.0 / n as f64,
            solution.encoder_error[p],
            fixed(at(&encoder_u, p), 4),
        );
    }
    let setup_u = solution.setup_error_u();
    let _ = writeln!(out, "\nSetup errors (arcsec, gauge of FORMAT.md §1)");
    let _ = writeln!(out, "{:>5} {:>4} {:>9} {:>8}", "setup", "ac", "U", "u(U)");
    for (i, s) in solution.setup_error.iter().enumerate() {
        let _ = writeln!(
            out,
            "{:>5} {:>4} {:>9.4} {:>8}",
            s.setup,
            s.ac,
            s.value,
            fixed(at(&setup_u, i), 4)
        );
    }
    out
}
