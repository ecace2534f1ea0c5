//! `polycal validate`: the software validated for its use (ISO/IEC 17025 7.11.2) against
//! reference data sets whose results were computed without polycal (docs/FORMAT.md §13.1).
//!
//! A *case* is a directory: its input files, `case.toml` (the evaluation it runs, the
//! command a user would type for it, the tolerance and its reason) and `reference.json`
//! (the reference values, named as the command's JSON names them). The bundled cases are
//! `examples/validation/`, carried by the binary; their references are written by
//! `scripts/validation/reference.py`, which implements the model in exact arithmetic and
//! imports nothing of polycal. Each case runs through the library function its command
//! calls, its JSON is compared number by number with the reference, and the largest
//! deviation is judged against the tolerance.
//!
//! ```
//! let record = polycal::validation::validate(&polycal::validation::bundled())?;
//! assert!(record.failed == 0 && record.passed > 0);
//! # Ok::<(), polycal::validation::ValidationError>(())
//! ```

mod build;
mod case;
mod deviation;
mod evaluate;
mod html;
mod table;

use std::path::Path;

use serde::Serialize;

pub use build::{BuildInfo, Platform};
pub use case::{CaseFile, CaseSource, Tolerance};
pub use html::write_html;
pub use table::write_table;

use crate::input::Location;

/// A bundled file: its name and bytes.
type BundledFile = (&'static str, &'static [u8]);

/// The bundled cases, `(case, [(file, bytes)])`, written by the build script.
const BUNDLED: &[(&str, &[BundledFile])] =
    include!(concat!(env!("OUT_DIR"), "/validation_cases.rs"));

/// The command that rewrites the bundled references, stated in the record.
pub const REFERENCE_COMMAND: &str = "python3 scripts/validation/reference.py";

/// The cases bundled with this build (`examples/validation/`), in name order.
pub fn bundled() -> Vec<CaseSource> {
    BUNDLED
        .iter()
        .map(|(name, files)| CaseSource {
            name: (*name).to_string(),
            origin: format!("bundled: examples/validation/{name}"),
            files: files
                .iter()
                .map(|(file, bytes)| CaseFile {
                    name: (*file).to_string(),
                    bytes: bytes.to_vec(),
                })
                .collect(),
        })
        .collect()
}

/// The cases of a directory: every sub-directory holding a `case.toml`, in name order.
///
/// # Errors
///
/// [`ValidationError::Io`] when the directory or a file cannot be read,
/// [`ValidationError::NoCases`] when no sub-directory holds a `case.toml`.
pub fn read_cases(dir: &Path) -> Result<Vec<CaseSource>, ValidationError> {
    let io = |path: &Path, e: std::io::Error| ValidationError::Io {
        location: Location::file_only(path.display().to_string()),
        message: e.to_string(),
    };
    let mut dirs: Vec<_> = std::fs::read_dir(dir)
        .map_err(|e| io(dir, e))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.join("case.toml").is_file())
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        return Err(ValidationError::NoCases {
            location: Location::file_only(dir.display().to_string()),
        });
    }
    let mut cases = Vec::new();
    for case_dir in dirs {
        let mut paths: Vec<_> = std::fs::read_dir(&case_dir)
            .map_err(|e| io(&case_dir, e))?
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.is_file())
            .collect();
        paths.sort();
        let mut files = Vec::new();
        for path in paths {
            let (bytes, _) = crate::input::read_bytes(&path).map_err(|(_, e)| io(&path, e))?;
            let name = path.file_name().map(|n| n.to_string_lossy().to_string());
            files.push(CaseFile {
                name: name.unwrap_or_default(),
                bytes,
            });
        }
        let name = case_dir
            .file_name()
            .map(|n| n.to_string_lossy().to_string());
        cases.push(CaseSource {
            name: name.unwrap_or_default(),
            origin: case_dir.display().to_string(),
            files,
        });
    }
    Ok(cases)
}

/// The validation record (docs/FORMAT.md §13.1): what was run, on what, and each case's
/// verdict.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct ValidationRecord {
    /// The software's version.
    pub version: &'static str,
    /// How this binary was built.
    pub build: BuildInfo,
    /// The machine it ran on.
    pub platform: Platform,
    /// When it ran (RFC 3339, UTC).
    pub date: String,
    /// The command that rewrites the bundled references.
    pub reference_command: &'static str,
    /// Every case, in name order.
    pub cases: Vec<CaseResult>,
    /// Cases that passed.
    pub passed: usize,
    /// Cases that failed.
    pub failed: usize,
}

/// One case's outcome.
#[derive(Debug, Clone, Serialize)]
#[non_exhaustive]
pub struct CaseResult {
    /// The case's name (its directory).
    pub name: String,
    /// Where the case was read: `bundled: examples/validation/NAME` or a directory.
    pub origin: String,
    /// What the case checks.
    pub description: String,
    /// The evaluation run (`solve`, `budget`, `monte-carlo`, `selfcal`, `diagnose`,
    /// `compare`, `kc`).
    pub evaluation: String,
    /// The command a user types to run the same evaluation in the case's directory.
    pub command: String,
    /// How the reference was computed.
    pub reference_method: String,
    /// The reference file's generator and the day of its version, as the file states.
    pub reference_generator: String,
    /// The largest deviation, in the tolerance's measure; `null` when a value could not be
    /// compared (`problem` says why).
    pub deviation: Option<f64>,
    /// Where the largest deviation is (a JSON path, e.g. `pitch_deviation[3]`).
    pub worst: Option<String>,
    /// Numbers compared.
    pub compared: usize,
    /// The tolerance, in the measure `tolerance_kind` names.
    pub tolerance: f64,
    /// How a deviation is measured (docs/FORMAT.md §13.1).
    pub tolerance_kind: Tolerance,
    /// Why the tolerance is what it is.
    pub tolerance_reason: String,
    /// Whether the case passed.
    pub pass: bool,
    /// Why the case could not be judged number by number (a missing field, an evaluation
    /// refused), else `null`.
    pub problem: Option<String>,
    /// Every file of the case with its SHA-256.
    pub files: Vec<FileDigest>,
}

/// A file and its SHA-256.
#[derive(Debug, Clone, Serialize)]
pub struct FileDigest {
    /// The file's name within its case.
    pub name: String,
    /// Its SHA-256, lower-case hexadecimal.
    pub sha256: String,
}

/// A case that cannot be run as written (status 2: the validation itself is not valid).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ValidationError {
    /// A case's file is missing or not what it should be.
    #[error("{location}: {message}")]
    Case {
        /// Where.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A file or directory cannot be read.
    #[error("{location}: {message}")]
    Io {
        /// Which.
        location: Location,
        /// The system's reason.
        message: String,
    },
    /// A directory without a case.
    #[error("{location}: no case (a sub-directory with a case.toml)")]
    NoCases {
        /// The directory.
        location: Location,
    },
}

/// Runs every case and writes the record, dated now (UTC).
///
/// # Errors
///
/// [`ValidationError`] for no case at all, or a case that cannot be read (its `case.toml`
/// or `reference.json` malformed, a file it names missing). A case whose evaluation fails or differs is not an
/// error: it fails, with its `problem` or deviation.
pub fn validate(cases: &[CaseSource]) -> Result<ValidationRecord, ValidationError> {
    validate_dated(cases, crate::clock::rfc3339(crate::clock::unix_now()))
}

/// [`validate`] with the record's date given (RFC 3339), e.g. from `SOURCE_DATE_EPOCH`.
///
/// # Errors
///
/// As [`validate`].
pub fn validate_dated(
    cases: &[CaseSource],
    date: String,
) -> Result<ValidationRecord, ValidationError> {
    // no case is no validation, never a pass (a build without examples/validation/)
    if cases.is_empty() {
        return Err(ValidationError::NoCases {
            location: Location::file_only("the cases given"),
        });
    }
    let parsed = cases
        .iter()
        .map(case::Case::parse)
        .collect::<Result<Vec<_>, _>>()?;
    let results: Vec<CaseResult> = parsed.iter().map(run_case).collect();
    let passed = results.iter().filter(|r| r.pass).count();
    Ok(ValidationRecord {
        version: crate::SOFTWARE_VERSION,
        build: BuildInfo::of_this_build(),
        platform: Platform::of_this_machine(),
        date,
        reference_command: REFERENCE_COMMAND,
        failed: results.len() - passed,
        passed,
        cases: results,
    })
}

/// One case run and judged.
fn run_case(case: &case::Case) -> CaseResult {
    let outcome = evaluate::evaluate(case)
        .and_then(|actual| deviation::compare(&case.reference, &actual, case.spec.tolerance_kind));
    let (deviation, worst, compared, problem) = match outcome {
        Ok(found) => (found.deviation, found.worst, found.compared, None),
        Err(problem) => (None, None, 0, Some(problem)),
    };
    let pass =
        problem.is_none() && deviation.is_some_and(|d| d.is_finite() && d <= case.spec.tolerance);
    CaseResult {
        name: case.source.name.clone(),
        origin: case.source.origin.clone(),
        description: case.spec.description.clone(),
        evaluation: case.spec.evaluation.name().to_string(),
        command: case.spec.command.clone(),
        reference_method: case.spec.reference_method.clone(),
        reference_generator: case.generator.clone(),
        deviation: deviation.filter(|d| d.is_finite()),
        worst,
        compared,
        tolerance: case.spec.tolerance,
        tolerance_kind: case.spec.tolerance_kind,
        tolerance_reason: case.spec.tolerance_reason.clone(),
        pass,
        problem,
        files: case
            .source
            .files
            .iter()
            .map(|f| FileDigest {
                name: f.name.clone(),
                sha256: crate::certificate::sha256_hex(&f.bytes),
            })
            .collect(),
    }
}
