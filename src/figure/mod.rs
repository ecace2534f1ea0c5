//! Figures of a calibration, as SVG documents: what a metrologist reads before the
//! numbers (the paper's Figs. 4–7 and the diagnosis and budget pictures).
//!
//! Every figure is built from a command's report object, the same data its JSON output
//! carries (docs/FORMAT.md §10), so that a figure never shows a number the JSON does not.
//! A [`Figure`] holds one standalone SVG document that can be written to a file
//! ([`write_figures`], `--plot DIR`) or inlined as is in an HTML page (`polycal report`).

use std::path::{Path, PathBuf};

mod budget;
mod chart;
mod compare;
mod diagnose;
mod history;
mod kc;
mod kc_doe;
mod plan;
mod selfcal;
mod solve;
pub(crate) mod svg;

use crate::compare::Comparison;
use crate::output::SolveReport;
use crate::output::diagnose::DiagnoseReport;
use crate::output::plan::PlanReport;
use crate::output::selfcal::SelfcalReport;
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

    /// A figure of a name, a title and an SVG document.
    pub fn new(name: impl Into<String>, title: impl Into<String>, svg: String) -> Self {
        Self {
            name: name.into(),
            title: title.into(),
            svg,
        }
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
    /// A figure that cannot be written where it would go.
    #[error(transparent)]
    Output(#[from] crate::output_file::OutputError),
    /// The path given for the figures' directory is a file (or another non-directory).
    #[error("{path}: is a file, not a directory; the figures need a directory")]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
}

/// The figures of `polycal solve`: pitch deviations β with U bars, face deviations φ,
/// encoder errors α against angle with U bars, and with a budget its contributions.
///
/// U is the report's own (`pitch_deviation_U`, … with `k` per point) when it carries a
/// budget; otherwise k·u with k Student's t at p = 95 % for the fit's degrees of freedom
/// (1.96 for a stated σ). Each figure says which. Without σ the points have no bars.
pub fn solve_figures(report: &SolveReport) -> Vec<Figure> {
    solve::figures(report)
}

/// The figures of `polycal selfcal`: the graduation error e against angle with U bars,
/// the heads' errors.
pub fn selfcal_figures(report: &SelfcalReport) -> Vec<Figure> {
    selfcal::figures(report)
}

/// The figures of `polycal compare` (the paper's Figs. 4–7): both results with their U
/// bars, and the difference with the ±√(U_a² + U_b²) band and En of every point.
///
/// The results are named `a` and `b` ([`compare_figures_labelled`] names them).
pub fn compare_figures(comparison: &Comparison) -> Vec<Figure> {
    compare::figures(comparison, "a", "b")
}

/// [`compare_figures`] with the two results named (e.g. by their files) in the legends.
pub fn compare_figures_labelled(
    comparison: &Comparison,
    label_a: &str,
    label_b: &str,
) -> Vec<Figure> {
    compare::figures(comparison, label_a, label_b)
}

/// The figures of `polycal diagnose`: residuals against time per autocollimator, before
/// and after, with each effect found drawn where it acts.
///
/// They are drawn from the report's `residuals` ([`DiagnoseReport::with_residuals`]):
/// none without them.
pub fn diagnose_figures(report: &DiagnoseReport) -> Vec<Figure> {
    diagnose::figures(report)
}

/// The figures of an instrument budget: each component's share of the variance (its
/// index, per cent), largest first.
///
/// For each of the pitch deviations, face deviations and encoder errors, the quantity
/// with the largest U, its components' indices 100·u_i²/u_c² with the fit's type A as
/// one of them.
pub fn budget_figures(uncertainty: &CalibrationUncertainty) -> Vec<Figure> {
    budget::figures(uncertainty)
}

/// The figures of `polycal kc`: every laboratory's degree of equivalence d_i with its
/// U(d_i) bar per face (those left out of the reference drawn with open squares and
/// labelled so), the reference value per face with U = 2·u_ref beside every laboratory's
/// value, the pairwise matrix, the KCDB graphs (one small graph per face, position or angle block, the
/// laboratories along the x axis; at most 24, and with more those of the largest
/// |d_i|/U(d_i)), and with the pilot's repeats each repeat's d_r with U(d_r).
pub fn kc_figures(kc: &crate::kc::KeyComparison) -> Vec<Figure> {
    let mut figures = kc::figures(kc);
    figures.extend(kc_doe::figures(kc));
    figures
}

/// The KCDB graphs of a key comparison alone (`kc-kcdb`, the last of [`kc_figures`]): what
/// its Digital Calibration Certificate carries as an SVG file.
pub fn kcdb_figure(kc: &crate::kc::KeyComparison) -> Option<Figure> {
    kc_doe::figures(kc).into_iter().next()
}

/// The figures of `polycal history`: one document of control charts, one small chart
/// per position (three to a row): every calibration's value with its U bar against its
/// date, the chosen model's line with its band ±U up to the prediction's date, and the
/// prediction with its U (docs/FORMAT.md §13.2).
pub fn history_figures(history: &crate::history::History) -> Vec<Figure> {
    history::figures(history)
}

/// The figures of `polycal plan`: the predicted u(α) against the table angle and u(β)
/// against the face's angle, one series per design (designs that cannot calibrate are
/// left out, and the figure says how many).
pub fn plan_figures(reports: &[PlanReport]) -> Vec<Figure> {
    plan::figures(reports)
}

/// The figures a command may write, known before it computes, so that `--plot DIR` can
/// be checked before any work (docs/FORMAT.md §10.1).
///
/// Most names are fixed: a command's figures take some of [`FigureSet::file_names`]
/// (the budget's only with a budget; a set of names a given run may not all use). The
/// residual figures of a diagnosis, `diagnose-residuals-ac<j>.svg`, one per
/// autocollimator, are known only once the file is read: [`check_figures`] checks
/// every file already in the directory under such a name, and the figures are checked
/// again as they are written.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FigureSet {
    /// `polycal solve` ([`solve_figures`]); with a budget, its figures too.
    Solve {
        /// `--budget` is given.
        budget: bool,
    },
    /// `polycal diagnose` ([`diagnose_figures`], and [`selfcal_figures`] for a
    /// self-calibration file); with a budget, its figures too.
    Diagnose {
        /// `--budget` is given.
        budget: bool,
    },
    /// `polycal selfcal` ([`selfcal_figures`]).
    Selfcal,
    /// `polycal compare` ([`compare_figures`]): two figures per family.
    Compare,
    /// `polycal plan` ([`plan_figures`]).
    Plan,
    /// `polycal kc` ([`kc_figures`]); with the pilot's repeats, their figure too.
    Kc {
        /// `--pilot` is given.
        pilot: bool,
    },
    /// `polycal history` ([`history_figures`]).
    History,
}

/// The stem of the residual figures of a diagnosis, before the autocollimator's number.
const RESIDUALS_STEM: &str = "diagnose-residuals-ac";

impl FigureSet {
    /// The fixed file names (`{name}.svg`) the command's figures may take.
    pub fn file_names(self) -> Vec<String> {
        let budget = |with: bool| {
            let families: &[&str] = if with {
                &["pitch-deviation", "face-deviation", "encoder-error"]
            } else {
                &[]
            };
            families
                .iter()
                .map(|f| format!("budget-{f}.svg"))
                .collect::<Vec<_>>()
        };
        let selfcal = ["selfcal-encoder-error.svg", "selfcal-head-error.svg"].map(String::from);
        match self {
            FigureSet::Solve { budget: with } => {
                let mut names: Vec<String> = [
                    "pitch-deviation.svg",
                    "face-deviation.svg",
                    "encoder-error.svg",
                ]
                .map(String::from)
                .to_vec();
                names.extend(budget(with));
                names
            }
            FigureSet::Diagnose { budget: with } => {
                let mut names = selfcal.to_vec();
                names.extend(budget(with));
                names
            }
            FigureSet::Selfcal => selfcal.to_vec(),
            FigureSet::Compare => crate::results::Quantity::ALL
                .iter()
                .flat_map(|q| {
                    let slug = compare::family_slug(*q);
                    [
                        format!("compare-{slug}.svg"),
                        format!("compare-{slug}-difference.svg"),
                    ]
                })
                .collect(),
            FigureSet::Plan => ["plan-encoder-error-u.svg", "plan-pitch-deviation-u.svg"]
                .map(String::from)
                .to_vec(),
            FigureSet::Kc { pilot } => kc::NAMES
                .iter()
                .chain([&kc_doe::NAME])
                .chain(pilot.then_some(&kc::PILOT))
                .map(|n| format!("{n}.svg"))
                .collect(),
            FigureSet::History => vec![format!("{}.svg", history::NAME)],
        }
    }

    /// Whether a file named `file_name` may be one of the command's figures: one of
    /// [`FigureSet::file_names`], or for `diagnose` `diagnose-residuals-ac<j>.svg`.
    pub fn may_take(self, file_name: &str) -> bool {
        if matches!(self, FigureSet::Diagnose { .. })
            && let Some(number) = file_name
                .strip_prefix(RESIDUALS_STEM)
                .and_then(|rest| rest.strip_suffix(".svg"))
            && !number.is_empty()
            && number.bytes().all(|b| b.is_ascii_digit())
        {
            return true;
        }
        self.file_names().iter().any(|n| n == file_name)
    }
}

/// Checks, before any work, that the figures of `set` can be written into `dir`
/// (docs/FORMAT.md §10.1): `dir` a directory, or missing with a directory as its
/// nearest existing ancestor; a directory the process can write into (tried by
/// [`crate::output_file::check_writable_directory`]); and none of the figures' names
/// one of `inputs` or not a regular file ([`crate::output_file::Outputs::check`]):
/// every fixed name of [`FigureSet::file_names`], and every file already in `dir` that
/// [`FigureSet::may_take`]. Writes nothing and leaves nothing.
///
/// # Errors
///
/// [`FigureError::NotADirectory`] naming `dir` (or the ancestor that is a file);
/// [`FigureError::Output`] for a directory that cannot be written into, or a figure
/// that would replace an input or something other than a regular file;
/// [`FigureError::Write`] when `dir` cannot be examined.
pub fn check_figures(dir: &Path, set: FigureSet, inputs: &[&Path]) -> Result<(), FigureError> {
    let metadata = match std::fs::metadata(dir) {
        Ok(metadata) => metadata,
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::NotFound | std::io::ErrorKind::NotADirectory
            ) =>
        {
            // created when the figures are written: where it would be created must be
            // a directory the process can write into
            let ancestor = nearest_existing(dir);
            if !ancestor.is_dir() {
                return Err(FigureError::NotADirectory { path: ancestor });
            }
            return crate::output_file::check_writable_directory(&ancestor).map_err(|e| {
                crate::output_file::OutputError::Io {
                    path: dir.to_path_buf(),
                    source: e.into_io(),
                }
                .into()
            });
        }
        Err(source) => {
            return Err(FigureError::Write {
                path: dir.to_path_buf(),
                source,
            });
        }
    };
    if !metadata.is_dir() {
        return Err(FigureError::NotADirectory {
            path: dir.to_path_buf(),
        });
    }
    crate::output_file::check_writable_directory(dir)?;
    let mut names = set.file_names();
    let entries = std::fs::read_dir(dir).map_err(|source| FigureError::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    for entry in entries.flatten() {
        if let Some(name) = entry.file_name().to_str()
            && set.may_take(name)
            && !names.iter().any(|n| n == name)
        {
            names.push(name.to_string());
        }
    }
    let paths: Vec<PathBuf> = names.iter().map(|n| dir.join(n)).collect();
    let outputs = crate::output_file::Outputs::new(inputs.iter().copied())?;
    outputs.check(paths.iter().map(PathBuf::as_path))?;
    Ok(())
}

/// `path` itself if it exists, else its nearest ancestor that does (`.` for a relative
/// path none of whose ancestors exists).
fn nearest_existing(path: &Path) -> PathBuf {
    let mut at = path;
    loop {
        if std::fs::symlink_metadata(at).is_ok() {
            return at.to_path_buf();
        }
        match at.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => at = parent,
            _ => return PathBuf::from("."),
        }
    }
}

/// Writes every figure into `dir` (created if missing) as `{name}.svg`, all or none
/// ([`crate::output_file::Outputs`]: none of them one of `inputs`, each written whole and
/// renamed into place once every figure is written); returns the paths written. A name
/// with a directory, `encoder_error/kc-reference`, goes into that subdirectory of `dir`,
/// created if missing.
///
/// # Errors
///
/// [`FigureError::NotADirectory`] when `dir` is an existing file; [`FigureError::Write`]
/// naming the directory that could not be created; [`FigureError::Output`] for a figure
/// that cannot be written where it would go (an input, not a regular file, a failed
/// write).
pub fn write_figures(
    dir: &Path,
    figures: &[Figure],
    inputs: &[&Path],
) -> Result<Vec<PathBuf>, FigureError> {
    if dir.exists() && !dir.is_dir() {
        return Err(FigureError::NotADirectory {
            path: dir.to_path_buf(),
        });
    }
    std::fs::create_dir_all(dir).map_err(|source| FigureError::Write {
        path: dir.to_path_buf(),
        source,
    })?;
    let mut outputs = crate::output_file::Outputs::new(inputs.iter().copied())?;
    for figure in figures {
        let path = dir.join(figure.file_name());
        if let Some(parent) = path.parent().filter(|p| *p != dir) {
            std::fs::create_dir_all(parent).map_err(|source| FigureError::Write {
                path: parent.to_path_buf(),
                source,
            })?;
        }
        outputs.write(&path, figure.svg.as_bytes())?;
    }
    Ok(outputs.commit()?)
}
