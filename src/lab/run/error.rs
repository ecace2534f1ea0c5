//! Why a run directory was refused or could not be used.

use std::io;
use std::path::PathBuf;

use super::{MANIFEST, RunSettings, SettingsError};
use crate::input::FileError;
use crate::input::Location;
use crate::measurement::Direction;

/// Why a run directory was refused or could not be used. Every variant names the file or
/// directory; those about a line of the measurement file give its [`Location`].
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum RunError {
    /// The settings are out of range.
    #[error("{}: {error}", path.display())]
    Settings {
        /// The run directory.
        path: PathBuf,
        /// Which setting, and why.
        error: SettingsError,
    },
    /// A run directory that is a file.
    #[error("{}: is a file, not a directory", path.display())]
    NotADirectory {
        /// The path.
        path: PathBuf,
    },
    /// A new run in a directory that already holds one.
    #[error("{}: this directory already holds a run", path.display())]
    AlreadyHoldsRun {
        /// Its manifest or measurement file.
        path: PathBuf,
    },
    /// A run to resume in a directory without a manifest.
    #[error("{}: no run to resume here (no {MANIFEST})", path.display())]
    NoRunToResume {
        /// The directory.
        path: PathBuf,
    },
    /// A manifest that cannot be read as one.
    #[error("{}: not a run manifest: {message}", path.display())]
    NotAManifest {
        /// The manifest.
        path: PathBuf,
        /// What the JSON reader said.
        message: String,
    },
    /// A run to resume with other settings than it was started with.
    #[error(
        "{}: the run was started with {started}, these settings are {requested} ({}); refusing to resume",
        path.display(),
        started.differences(requested).join(", ")
    )]
    OtherSettings {
        /// The manifest.
        path: PathBuf,
        /// The settings the run was started with.
        started: Box<RunSettings>,
        /// The settings given now.
        requested: Box<RunSettings>,
    },
    /// A run to resume with other instruments than it was started with.
    #[error(
        "{}: other instruments than the run started with ({}); refusing to resume",
        path.display(),
        differences.join("; ")
    )]
    OtherInstruments {
        /// The manifest.
        path: PathBuf,
        /// Each instrument that differs, e.g. `ac1 was "…", is now "…"`.
        differences: Vec<String>,
    },
    /// A resumed run given another profile than it recorded.
    #[error(
        "{}: the run speaks with its {role} through the profile {recorded:?}, not {given:?}: \
         resume it with the profile it started with",
        path.display()
    )]
    OtherProfile {
        /// The manifest.
        path: PathBuf,
        /// `autocollimators` or `table`.
        role: &'static str,
        /// The profile the run recorded.
        recorded: String,
        /// The profile given now.
        given: String,
    },
    /// A resumed run whose profile's text changed since the run recorded it.
    #[error(
        "{}: the {role} profile {name:?} changed since the run started (its text had \
         SHA-256 {recorded}, it has {now} now): resume with the profile's text as it was, \
         or start a new run",
        path.display()
    )]
    ProfileChanged {
        /// The manifest.
        path: PathBuf,
        /// `autocollimators` or `table`.
        role: &'static str,
        /// The profile's name as given.
        name: String,
        /// The SHA-256 the run recorded.
        recorded: String,
        /// The SHA-256 of its text now.
        now: String,
    },
    /// Another run holds the directory's lock.
    #[error("{}: another polycal run is using this directory", path.display())]
    Locked {
        /// The measurement file (its lock).
        path: PathBuf,
    },
    /// A measurement file whose header is not the run's.
    #[error("{at}: header {found:?} is not the run's header {expected:?}; refusing to resume")]
    Header {
        /// Where the header is.
        at: Location,
        /// The header found.
        found: String,
        /// The run's header.
        expected: String,
    },
    /// A measurement file that cannot be read (a row that breaks docs/FORMAT.md §2).
    #[error("{error}; refusing to resume")]
    Unreadable {
        /// What is wrong, and where.
        error: FileError,
    },
    /// A reading that is not the run's next one in order.
    #[error(
        "{at}: reading {found:?} ({found_direction}) is not the run's reading number {number} ({expected:?}, {expected_direction}); refusing to resume"
    )]
    OutOfOrder {
        /// Where the reading is.
        at: Location,
        /// Its `cycle,step,ac,face`.
        found: String,
        /// Its direction.
        found_direction: Direction,
        /// Its number in the run's order (1-based).
        number: usize,
        /// The `cycle,step,ac,face` of the run's reading of that number.
        expected: String,
        /// Its direction.
        expected_direction: Direction,
    },
    /// A value the run always writes is missing.
    #[error("{at}: column {column:?} is empty; the run writes a number there; refusing to resume")]
    Missing {
        /// Where the field is.
        at: Location,
        /// The column, `time` or `encoder`.
        column: &'static str,
    },
    /// More readings than the run has.
    #[error("{at}: more readings than the run has; refusing to resume")]
    TooManyReadings {
        /// Where the first reading too many is.
        at: Location,
    },
    /// A later mounting for a directory that holds no run.
    #[error(
        "{}: no run here (no {MANIFEST}): mounting {setup} continues a run whose first mounting was measured in this directory",
        path.display()
    )]
    NoRunForMounting {
        /// The directory.
        path: PathBuf,
        /// The mounting asked for.
        setup: u32,
    },
    /// A mounting stated otherwise than the run recorded it, with readings of it on disk.
    #[error(
        "{}: the run measures {recorded}, this command says {requested}; refusing to mix two mountings in one setup",
        path.display()
    )]
    OtherMounting {
        /// The manifest.
        path: PathBuf,
        /// The mounting as recorded.
        recorded: super::Mounting,
        /// The mounting as given now.
        requested: super::Mounting,
    },
    /// A mounting the run has left behind.
    #[error(
        "{}: mounting {setup} is complete and the run has gone on to mounting {last}; the polygon cannot be mounted as before again",
        path.display()
    )]
    MountingDone {
        /// The manifest.
        path: PathBuf,
        /// The mounting asked for.
        setup: u32,
        /// The run's last mounting.
        last: u32,
    },
    /// A mounting that is not the next one.
    #[error(
        "{}: the run's last mounting is {last}; the next one is {}, not {requested}",
        path.display(),
        last + 1
    )]
    MountingOrder {
        /// The manifest.
        path: PathBuf,
        /// The mounting asked for.
        requested: u32,
        /// The run's last mounting.
        last: u32,
    },
    /// A next mounting while the last one is not complete.
    #[error(
        "{}: mounting {setup} has {done} of its {expected} readings; complete it (resume it) before the polygon is remounted",
        path.display()
    )]
    MountingIncomplete {
        /// The manifest.
        path: PathBuf,
        /// The incomplete mounting.
        setup: u32,
        /// Its readings on disk.
        done: usize,
        /// Its readings when complete.
        expected: usize,
    },
    /// A shifted mounting in a run whose measurement file has no `shift` column (started
    /// by an older polycal).
    #[error(
        "{}: {mounting} needs the measurement file's shift column, which this run's file (started by an older polycal) lacks; measure it in a new run directory",
        path.display()
    )]
    NoShiftColumn {
        /// The manifest.
        path: PathBuf,
        /// The mounting asked for.
        mounting: super::Mounting,
    },
    /// A file could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// A new run could not create or write its files (e.g. a full disk): nothing was
    /// measured, and the files it had created were removed again, so that the same run
    /// can start once the cause is gone.
    #[error("{}: {source}; the run could not start (nothing was measured){}", path.display(), left_behind(left))]
    NotStarted {
        /// The file that could not be created or written.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: io::Error,
        /// Files it created that could not be removed (empty when all were).
        left: Vec<PathBuf>,
    },
    /// A write of the run directory still under way when it was to be aborted.
    #[error("{}: a write was still under way", path.display())]
    Busy {
        /// The manifest.
        path: PathBuf,
    },
    /// A write after the run directory was closed by an abort.
    #[error("{}: not written: the run was stopped at once", path.display())]
    Closed {
        /// The file.
        path: PathBuf,
    },
}

/// How [`RunError::NotStarted`] ends: what it left behind, if anything.
fn left_behind(left: &[PathBuf]) -> String {
    if left.is_empty() {
        "; its files were removed".into()
    } else {
        let names: Vec<String> = left.iter().map(|p| p.display().to_string()).collect();
        format!("; remove {} before starting it again", names.join(", "))
    }
}

impl RunError {
    /// Whether the directory or its files were refused (everything but a failure to
    /// read or write): nothing was changed that could lose data.
    pub fn is_refusal(&self) -> bool {
        !matches!(
            self,
            RunError::Io { .. }
                | RunError::NotStarted { .. }
                | RunError::Busy { .. }
                | RunError::Closed { .. }
        )
    }
}

/// The error of an I/O failure on `path`.
pub(super) fn io_error(path: &std::path::Path) -> impl FnOnce(io::Error) -> RunError + '_ {
    move |source| RunError::Io {
        path: path.to_path_buf(),
        source,
    }
}
