//! What a report is made of ([`ReportInputs`]) and why one cannot be made
//! ([`ReportError`]).

use std::path::PathBuf;

use crate::compare::CompareError;
use crate::input::FileError;
use crate::input::Location;
use crate::measurement::Sigma;
use crate::selfcal::SelfcalSolveError;
use crate::simulate::SimulateError;
use crate::solve::SolveError;
use crate::uncertainty::BudgetError;
use crate::uncertainty::calibration::CalibrationError;

/// What a report is made of: the measurement (or self-calibration) file and the optional
/// budget, diagnosis, truth, reference result, metadata file and run directory.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct ReportInputs {
    /// The measurement file (docs/FORMAT.md §2) or self-calibration file (§9.2).
    pub measurement: PathBuf,
    /// The number of faces (positions of a self-calibration), when not the file's largest.
    pub faces: Option<usize>,
    /// σ of one reading, arcsec, for the uncertainties of an exactly determined fit
    /// (dof = 0, the paper's bare design); with dof > 0 the residuals' σ is used.
    pub sigma: Option<Sigma>,
    /// An instrument budget (docs/FORMAT.md §5.1, `acts_on` per component).
    pub budget: Option<PathBuf>,
    /// Whether to diagnose the measurement (polygon files).
    pub diagnose: bool,
    /// A truth file, for the diagnosis's error before and after (simulated data).
    pub truth: Option<PathBuf>,
    /// A reference result (docs/FORMAT.md §3) to compare with.
    pub reference: Option<PathBuf>,
    /// A metadata file (TOML, docs/FORMAT.md §10).
    pub meta: Option<PathBuf>,
    /// A run directory (`polycal run`'s, with `manifest.json`).
    pub run_dir: Option<PathBuf>,
    /// The report's date and time, RFC 3339 UTC; `None`: now.
    pub generated_utc: Option<String>,
    /// The command line that made the report, shown in its provenance.
    pub command_line: Option<String>,
    /// Cross-talk stated from the autocollimators' calibrations (docs/FORMAT.md §6): the
    /// readings are corrected for it, its U enters the budget, and the diagnosis tries no
    /// cross-talk term for those autocollimators.
    pub stated_cross_talk: Vec<crate::measurement::cross_talk::StatedCrossTalk>,
    /// The JSON of `polycal kc --format json` to report (docs/FORMAT.md §12), and the
    /// laboratory the report is for, when one is named.
    pub key_comparison: Option<(PathBuf, Option<String>)>,
    /// The standard's earlier calibrations (docs/FORMAT.md §13.2): with them the report
    /// has the section "History of the standard", this calibration the newest, dated by
    /// the metadata's `date_of_measurement`.
    pub history: Vec<crate::history::DatedPath>,
}

impl ReportInputs {
    /// A report of one measurement file, nothing else.
    pub fn new(measurement: impl Into<PathBuf>) -> Self {
        Self {
            measurement: measurement.into(),
            faces: None,
            sigma: None,
            budget: None,
            diagnose: false,
            truth: None,
            reference: None,
            meta: None,
            run_dir: None,
            generated_utc: None,
            command_line: None,
            stated_cross_talk: Vec::new(),
            key_comparison: None,
            history: Vec::new(),
        }
    }
    /// With the number of faces (or positions).
    pub fn with_faces(mut self, faces: Option<usize>) -> Self {
        self.faces = faces;
        self
    }
    /// With σ of one reading (for an exactly determined fit).
    pub fn with_sigma(mut self, sigma: Option<Sigma>) -> Self {
        self.sigma = sigma;
        self
    }
    /// With an instrument budget.
    pub fn with_budget(mut self, budget: impl Into<PathBuf>) -> Self {
        self.budget = Some(budget.into());
        self
    }
    /// With cross-talk stated from the autocollimators' calibrations.
    pub fn with_stated_cross_talk(
        mut self,
        stated: Vec<crate::measurement::cross_talk::StatedCrossTalk>,
    ) -> Self {
        self.stated_cross_talk = stated;
        self
    }
    /// With a diagnosis (or without).
    pub fn with_diagnose(mut self, diagnose: bool) -> Self {
        self.diagnose = diagnose;
        self
    }
    /// With a truth file for the diagnosis.
    pub fn with_truth(mut self, truth: impl Into<PathBuf>) -> Self {
        self.truth = Some(truth.into());
        self
    }
    /// With a reference result to compare with.
    pub fn with_reference(mut self, reference: impl Into<PathBuf>) -> Self {
        self.reference = Some(reference.into());
        self
    }
    /// With a metadata file.
    pub fn with_meta(mut self, meta: impl Into<PathBuf>) -> Self {
        self.meta = Some(meta.into());
        self
    }
    /// With a run directory.
    pub fn with_run_dir(mut self, run_dir: impl Into<PathBuf>) -> Self {
        self.run_dir = Some(run_dir.into());
        self
    }
    /// With a key comparison's JSON (`polycal kc --format json`) and the laboratory the
    /// report is for (`None`: every laboratory's degrees of equivalence).
    pub fn with_key_comparison(mut self, kc_json: impl Into<PathBuf>, lab: Option<String>) -> Self {
        self.key_comparison = Some((kc_json.into(), lab));
        self
    }
    /// With the standard's earlier calibrations, each a result file or DCC with its day
    /// (at least 2, each before the metadata's `date_of_measurement`): the section
    /// "History of the standard" (docs/FORMAT.md §10.2, §13.2).
    pub fn with_history(mut self, earlier: Vec<crate::history::DatedPath>) -> Self {
        self.history = earlier;
        self
    }
    /// With the report's date and time (RFC 3339 UTC), instead of now.
    pub fn with_generated_utc(mut self, generated_utc: impl Into<String>) -> Self {
        self.generated_utc = Some(generated_utc.into());
        self
    }
    /// With the command line shown in the provenance.
    pub fn with_command_line(mut self, command_line: impl Into<String>) -> Self {
        self.command_line = Some(command_line.into());
        self
    }
}

/// Why a report cannot be made.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ReportError {
    /// A file could not be read.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A metadata file or run manifest that is not valid.
    #[error("{location}: {message}")]
    Meta {
        /// Where.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// A table file: the measurement file, the self-calibration file or the reference
    /// result file.
    #[error(transparent)]
    File(#[from] FileError),
    /// A stated cross-talk cannot be corrected for.
    #[error(transparent)]
    CrossTalk(#[from] crate::measurement::cross_talk::CrossTalkError),
    /// The budget file.
    #[error(transparent)]
    Budget(#[from] BudgetError),
    /// The truth file.
    #[error(transparent)]
    Truth(#[from] SimulateError),
    /// The measurement cannot be solved.
    #[error("{file}: cannot solve: {source}")]
    Solve {
        /// The measurement file.
        file: String,
        /// Why.
        source: SolveError,
    },
    /// The self-calibration cannot be solved.
    #[error("{file}: cannot solve: {source}")]
    SelfcalSolve {
        /// The self-calibration file.
        file: String,
        /// Why.
        source: SelfcalSolveError,
    },
    /// The budget cannot be evaluated for this measurement.
    #[error("{file}: cannot evaluate the uncertainty: {source}")]
    Uncertainty {
        /// The measurement file.
        file: String,
        /// Why.
        source: CalibrationError,
    },
    /// The comparison cannot be made.
    #[error("cannot compare with {reference}: {source}")]
    Compare {
        /// The reference file.
        reference: String,
        /// Why.
        source: CompareError,
    },
    /// A comparison needs the expanded uncertainty U of this result, which only an
    /// instrument budget gives a polygon calibration.
    #[error(
        "cannot compare with {reference}: En needs the expanded uncertainty U of every result, and a polygon calibration has U only with an instrument budget"
    )]
    NoExpandedUncertainty {
        /// The reference file.
        reference: String,
    },
    /// An evaluation the report does not make for this kind of file.
    #[error("{file}: {what} is not supported for {kind}")]
    NotSupported {
        /// The measurement file.
        file: String,
        /// What was asked.
        what: &'static str,
        /// What the file is.
        kind: &'static str,
    },
    /// The key comparison file is not the JSON of `polycal kc --format json`.
    #[error("{location}: {message}")]
    KeyComparison {
        /// The file, with serde's line and column where it has them.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// The key comparison's lists do not have the shape the documents rely on.
    #[error("{file}: {problem}")]
    KeyComparisonShape {
        /// The key comparison file.
        file: String,
        /// What is wrong.
        problem: crate::kc::KeyComparisonShapeError,
    },
    /// A calibration of the standard's history cannot be read.
    #[error(transparent)]
    HistoryFile {
        /// Why.
        source: crate::history::DatedReadError,
    },
    /// The standard's history cannot be evaluated.
    #[error("the standard's history: {source}")]
    History {
        /// Why.
        #[from]
        source: crate::history::HistoryError,
    },
    /// A history without the day of this calibration.
    #[error(
        "{file}: a standard's history needs the day of this calibration, the metadata's \
         date_of_measurement (the metadata file, a `# date_of_measurement:` comment of the \
         measurement file, or the run manifest): the report's own date is not the day it was \
         measured"
    )]
    HistoryNoDate {
        /// The measurement file.
        file: String,
    },
    /// A history needs this calibration's U.
    #[error(
        "{file}: a standard's history needs the u and U of this calibration's pitch \
         deviations, and a polygon calibration has U only with an instrument budget"
    )]
    HistoryNoExpandedUncertainty {
        /// The measurement file.
        file: String,
    },
    /// A calibration of the history that is not earlier than this one.
    #[error(
        "{file}: dated {date}, not before this calibration's {today} (the metadata's \
         date_of_measurement): the history takes earlier calibrations, this one is the newest"
    )]
    HistoryNotEarlier {
        /// The file, as given.
        file: String,
        /// Its day.
        date: String,
        /// This calibration's day.
        today: String,
    },
    /// The laboratory named for the key comparison is not one of its laboratories.
    #[error("{file}: laboratory {lab:?} is not in this key comparison; its laboratories: {labs}")]
    KeyComparisonLab {
        /// The key comparison file.
        file: String,
        /// The name given.
        lab: String,
        /// The comparison's laboratories, comma-separated.
        labs: String,
    },
}
