//! Outputs of `polycal solve` for programs: the JSON object of docs/FORMAT.md §5 and the
//! result rows of its CSV (§3). The table for people is in [`super::solve_table`].
//!
//! JSON and CSV carry numbers at full precision (the shortest text that reads back to
//! the same double); only the table rounds.

use crate::results::{Quantity, ResultRow};
use crate::solve::sub_pitch::SubPitchSolution;
use crate::solve::{SigmaSource, Solution};
use crate::uncertainty::calibration::{CalibrationMonteCarlo, CalibrationUncertainty};
use serde::Serialize;

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
    /// Expanded uncertainty with `--budget` (an addition), arcsec.
    #[serde(rename = "U", skip_serializing_if = "Option::is_none")]
    pub expanded_u: Option<f64>,
    /// Coverage factor with `--budget` (an addition).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub k: Option<f64>,
}

/// The JSON object of `polycal solve` (docs/FORMAT.md §5), arcsec throughout.
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
    /// u(φ), k = 1 (an addition to docs/FORMAT.md §5).
    pub face_deviation_u: Option<Vec<f64>>,
    /// α[0..N).
    pub encoder_error: Vec<f64>,
    /// u(α), k = 1.
    pub encoder_error_u: Option<Vec<f64>>,
    /// Sub-pitch mountings only (docs/FORMAT.md §9.1): the table angle of each
    /// `encoder_error`, degrees, ascending.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder_angle_deg: Option<Vec<f64>>,
    /// Setup errors per (setup, ac).
    pub setup_error: Vec<SetupErrorReport>,
    /// Effect terms in the fitted model (docs/FORMAT.md §6); empty for the base model.
    pub effects: Vec<serde_json::Value>,
    /// `closed-form` or `lsq` (an addition).
    pub method: &'static str,
    /// `closed-form`, `circulant` or `dense`: the engine that computed it (an addition).
    pub engine: &'static str,
    /// σ of one reading used for the uncertainties, arcsec (an addition).
    pub sigma: Option<f64>,
    /// `residual` or `stated` (an addition).
    pub sigma_source: Option<&'static str>,
    /// Sub-pitch mountings only: what a reader must know about the result (each coset's
    /// encoder errors are determined up to a constant, docs/FORMAT.md §9.1).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub notes: Option<Vec<String>>,
    /// What the user should check in the data, one sentence each (the `warning:` lines of
    /// the command): a cycle with fewer steps than a whole cycle. Absent when there is
    /// none (an addition).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub warnings: Vec<String>,
    /// The cycles with fewer steps than a whole cycle (docs/FORMAT.md §5.1), for a
    /// program; absent when there is none (an addition).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub incomplete_cycles: Vec<crate::measurement::IncompleteCycle>,
    /// Coverage probability of the expanded uncertainties (with `--budget`; an addition,
    /// like every field below).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub p: Option<f64>,
    /// U(β) = k·u_c(β): the fit's type A combined with the budget, per face.
    #[serde(rename = "pitch_deviation_U", skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_expanded_u: Option<Vec<f64>>,
    /// k of each U(β) (t at p for its own ν_eff).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_k: Option<Vec<Option<f64>>>,
    /// U(φ); 0 for the reference face φ\[N\].
    #[serde(rename = "face_deviation_U", skip_serializing_if = "Option::is_none")]
    pub face_deviation_expanded_u: Option<Vec<f64>>,
    /// k of each U(φ); null for φ\[N\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub face_deviation_k: Option<Vec<Option<f64>>>,
    /// U(α).
    #[serde(rename = "encoder_error_U", skip_serializing_if = "Option::is_none")]
    pub encoder_error_expanded_u: Option<Vec<f64>>,
    /// k of each U(α).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub encoder_error_k: Option<Vec<Option<f64>>>,
    /// The whole evaluation: type A, combined u, ν_eff, k, U per quantity, and every
    /// budget component's contribution to every quantity.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<CalibrationUncertainty>,
    /// Monte Carlo (`--monte-carlo`): per quantity mean, u, coverage interval, and the
    /// validation of the GUM result.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub monte_carlo: Option<CalibrationMonteCarlo>,
    /// The fit's covariance of the pitch deviations σ²Q, N rows of N, arcsec² (on
    /// request, [`SolveReport::with_pitch_deviation_covariance`]; `null` when σ is
    /// unknown; an addition).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pitch_deviation_covariance: Option<Option<Vec<Vec<f64>>>>,
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
            encoder_angle_deg: None,
            setup_error: solution
                .setup_error
                .iter()
                .enumerate()
                .map(|(k, s)| SetupErrorReport {
                    setup: s.setup,
                    ac: s.ac,
                    value: s.value,
                    u: setup_u.as_ref().map(|u| u[k]),
                    expanded_u: None,
                    k: None,
                })
                .collect(),
            effects: Vec::new(),
            method: solution.method.as_str(),
            engine: solution.engine.as_str(),
            sigma: solution.sigma.map(|(s, _)| s),
            sigma_source: solution.sigma.map(|(_, source)| match source {
                SigmaSource::Residual => "residual",
                SigmaSource::Stated => "stated",
            }),
            notes: None,
            warnings: solution
                .incomplete_cycles
                .iter()
                .map(ToString::to_string)
                .collect(),
            incomplete_cycles: solution.incomplete_cycles.clone(),
            p: None,
            pitch_deviation_expanded_u: None,
            pitch_deviation_k: None,
            face_deviation_expanded_u: None,
            face_deviation_k: None,
            encoder_error_expanded_u: None,
            encoder_error_k: None,
            uncertainty: None,
            monte_carlo: None,
            pitch_deviation_covariance: None,
        }
    }

    /// Adds the fit's covariance of the pitch deviations, σ²Q of β (N rows of N,
    /// arcsec²; `null` when σ is unknown), for a key comparison's closed vector.
    pub fn with_pitch_deviation_covariance(mut self, solution: &Solution) -> Self {
        self.pitch_deviation_covariance = Some(
            solution
                .family_covariance(crate::results::Quantity::PitchDeviation)
                .map(|(n, flat)| flat.chunks(n.max(1)).map(<[f64]>::to_vec).collect()),
        );
        self
    }

    /// The report of a set with shifted mountings
    /// ([`solve_shifted`](crate::solve::sub_pitch::solve_shifted)): for sub-pitch mountings
    /// `encoder_error` and `encoder_error_u` cover every table angle of every coset, in
    /// the order of `encoder_angle_deg`, and `notes` says what fixes each coset's
    /// constant; for whole-face shifts the report of the solution, as [`SolveReport::new`].
    pub fn sub_pitch(solved: &SubPitchSolution, file: Option<String>) -> Self {
        let mut report = Self::new(&solved.solution, file);
        if solved.is_sub_pitch() {
            report.encoder_error = solved.encoder_error.clone();
            report.encoder_error_u = solved.encoder_error_u.clone();
            report.encoder_angle_deg = Some(solved.encoder_angle_deg.clone());
            report.notes = Some(solved.notes.clone());
        }
        report
    }

    /// Adds the expanded uncertainties of `--budget`.
    pub fn with_uncertainty(mut self, uncertainty: &CalibrationUncertainty) -> Self {
        self.p = Some(uncertainty.p);
        self.pitch_deviation_expanded_u = Some(uncertainty.pitch_deviation.expanded_u.clone());
        self.pitch_deviation_k = Some(uncertainty.pitch_deviation.k.clone());
        self.face_deviation_expanded_u = Some(uncertainty.face_deviation.expanded_u.clone());
        self.face_deviation_k = Some(uncertainty.face_deviation.k.clone());
        self.encoder_error_expanded_u = Some(uncertainty.encoder_error.expanded_u.clone());
        self.encoder_error_k = Some(uncertainty.encoder_error.k.clone());
        for (i, s) in self.setup_error.iter_mut().enumerate() {
            s.expanded_u = Some(uncertainty.setup_error.expanded_u[i]);
            s.k = uncertainty.setup_error.k[i];
        }
        self.uncertainty = Some(uncertainty.clone());
        self
    }

    /// Adds the Monte Carlo results of `--monte-carlo`.
    pub fn with_monte_carlo(mut self, monte_carlo: CalibrationMonteCarlo) -> Self {
        self.monte_carlo = Some(monte_carlo);
        self
    }

    /// One line of JSON, with the software version ([`crate::output::to_json`]).
    ///
    /// # Errors
    ///
    /// serde_json's error (not expected for this plain data).
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        crate::output::to_json(self)
    }
}

/// The result rows (docs/FORMAT.md §3) of a solution: pitch deviations, face deviations,
/// encoder errors and setup errors (index = autocollimator; with several mountings the
/// index is `setup·1000 + ac`, an addition to the contract), with `u` where known. Every
/// encoder error carries its table angle: step p of N at p·360°/N ([`crate::measurement::step_angle_deg`]).
pub fn result_rows(solution: &Solution) -> Vec<ResultRow> {
    result_rows_with(solution, None)
}

/// The result rows with the expanded uncertainties of `--budget` when given: then `u`
/// is the combined standard uncertainty u_c, `U` = k·u_c and `k` fill every row, and
/// the reference face φ\[N\] (0 by definition, U = 0, for which En is undefined) is left
/// out, so that the file goes straight into `polycal compare`.
pub fn result_rows_with(
    solution: &Solution,
    uncertainty: Option<&CalibrationUncertainty>,
) -> Vec<ResultRow> {
    let mut rows = Vec::with_capacity(3 * solution.faces + solution.setup_error.len());
    let at = |v: &Option<Vec<f64>>, i: usize| v.as_ref().map(|v| v[i]);
    let fit_u = [
        solution.pitch_deviation_u(),
        solution.face_deviation_u(),
        solution.encoder_error_u(),
        solution.setup_error_u(),
    ];
    let several_setups = solution.setup_error.iter().any(|s| s.setup != 1);
    let families: [(Quantity, Vec<(u32, f64)>); 4] = [
        (
            Quantity::PitchDeviation,
            (1..)
                .zip(solution.pitch_deviation.iter().copied())
                .collect(),
        ),
        (
            Quantity::FaceDeviation,
            (1..).zip(solution.face_deviation.iter().copied()).collect(),
        ),
        (
            Quantity::EncoderError,
            (0..).zip(solution.encoder_error.iter().copied()).collect(),
        ),
        (
            Quantity::SetupError,
            solution
                .setup_error
                .iter()
                .map(|s| {
                    let index = if several_setups {
                        s.setup * 1000 + s.ac
                    } else {
                        s.ac
                    };
                    (index, s.value)
                })
                .collect(),
        ),
    ];
    let positions = solution.encoder_error.len();
    for (f, (quantity, values)) in families.into_iter().enumerate() {
        for (i, (index, value)) in values.into_iter().enumerate() {
            let angle_deg = (quantity == Quantity::EncoderError)
                .then(|| crate::measurement::step_angle_deg(index, positions));
            let row = match uncertainty {
                None => ResultRow {
                    quantity,
                    index,
                    value,
                    u: at(&fit_u[f], i),
                    expanded_u: None,
                    k: None,
                    angle_deg,
                    dof: None,
                    nominal_deg: None,
                },
                Some(unc) => {
                    let family = unc.families()[f].1;
                    let Some(k) = family.k[i] else {
                        continue; // φ[N]: no uncertainty
                    };
                    ResultRow {
                        quantity,
                        index,
                        value,
                        u: Some(family.u[i]),
                        expanded_u: Some(family.expanded_u[i]),
                        k: Some(k),
                        angle_deg,
                        dof: None,
                        nominal_deg: None,
                    }
                }
            };
            rows.push(row);
        }
    }
    rows
}

/// The result rows (docs/FORMAT.md §3) of a set with shifted mountings
/// ([`solve_shifted`](crate::solve::sub_pitch::solve_shifted)): as [`result_rows`],
/// except that for sub-pitch mountings the `encoder_error` rows cover every table angle
/// of every coset, index 0 … C·N − 1 in the order of
/// [`SubPitchSolution::encoder_angle_deg`].
pub fn sub_pitch_result_rows(solved: &SubPitchSolution) -> Vec<ResultRow> {
    let rows = result_rows(&solved.solution);
    if !solved.is_sub_pitch() {
        return rows;
    }
    let encoder: Vec<ResultRow> = (0..)
        .zip(&solved.encoder_error)
        .enumerate()
        .map(|(i, (index, &value))| {
            let row = ResultRow::new(Quantity::EncoderError, index, value)
                .with_angle_deg(solved.encoder_angle_deg[i]);
            match &solved.encoder_error_u {
                Some(u) => row.with_u(u[i]),
                None => row,
            }
        })
        .collect();
    let first = rows
        .iter()
        .position(|r| r.quantity == Quantity::EncoderError)
        .unwrap_or(rows.len());
    let mut out: Vec<ResultRow> = rows.iter().take(first).cloned().chain(encoder).collect();
    out.extend(
        rows.into_iter()
            .skip(first)
            .filter(|r| r.quantity != Quantity::EncoderError),
    );
    out
}

/// Writes the result rows of several files as one CSV with a leading `file` column (an
/// addition to docs/FORMAT.md §3 for batch runs).
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

/// A text cell of a CSV polycal writes (docs/FORMAT.md §3.1): a cell that begins with
/// `=`, `+`, `-`, `@`, a tab or a carriage return — what a spreadsheet runs as a formula —
/// gets a leading `'`, which spreadsheets show as text; then the cell is quoted when it
/// needs to be. Number cells are never text cells.
fn csv_field(text: &str) -> String {
    let text = if text.starts_with(['=', '+', '-', '@', '\t', '\r']) {
        format!("'{text}")
    } else {
        text.to_string()
    };
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text
    }
}

#[cfg(test)]
mod csv_field_tests {
    #[test]
    fn a_formula_leading_cell_is_neutralised_and_quoted_when_needed() {
        assert_eq!(super::csv_field("run 1.csv"), "run 1.csv");
        assert_eq!(super::csv_field("=HYPERLINK(1).csv"), "'=HYPERLINK(1).csv");
        assert_eq!(super::csv_field("+1.csv"), "'+1.csv");
        assert_eq!(super::csv_field("-2.csv"), "'-2.csv");
        assert_eq!(super::csv_field("@sum.csv"), "'@sum.csv");
        assert_eq!(super::csv_field("=a,b.csv"), "\"'=a,b.csv\"");
        assert_eq!(super::csv_field("a\"b.csv"), "\"a\"\"b.csv\"");
    }
}
