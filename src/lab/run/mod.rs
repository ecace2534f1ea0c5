//! The run procedure of `polycal run` (docs/FORMAT.md §7): step the table through full
//! cycles, read every autocollimator at every stop, and keep every reading on disk.
//!
//! One concept a file: the settings and the plan (`settings.rs`: [`RunSettings`]), the
//! manifest (`manifest.rs`: [`Manifest`]), the run directory and its lock
//! (`directory.rs`: [`RunDir`]), continuing an interrupted run (`resume.rs`), the
//! measuring loop (`measure.rs`: [`measure`]), the checks before a session's first
//! reading (`verify.rs`: a resumed mounting's last stop read again, a new mounting's
//! first stop against the mountings before), ending a run at once from another thread
//! (`abort.rs`: [`AbortHandle`]) and the refusals (`error.rs`: [`RunError`]).
//!
//! # A full disk
//!
//! Every file of the run directory is written so that a failed write leaves it
//! consistent: a reading or a traffic record that does not fit is cut back off its file
//! (both end on whole lines), the manifest is replaced whole or not at all, and the first
//! failed write ends the session with [`Outcome::FileError`]. A new run that cannot
//! write its files removes what it created ([`RunError::NotStarted`]). Tests fill the
//! disk through a [`WriteBudget`](crate::lab::WriteBudget)
//! ([`RunDir::open_with_budget`]).
//!
//! # The run directory
//!
//! - `measurements.csv`: docs/FORMAT.md §2, the columns [`COLUMNS`]
//!   (`cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder`) after `#`
//!   comment lines, written by the measurement module's
//!   [`ReadingWriter`](crate::measurement::ReadingWriter); one row per reading, appended
//!   and synced (`fsync` of its data) before the table moves again. `face` is p+1 for
//!   autocollimator 1 and p+2 (wrapping) for autocollimator 2, `setup` 1, `time` seconds
//!   since the run started, `reading_y` empty when the Y axis was not valid, `encoder`
//!   the position the table reported (`1TP`), degrees.
//! - `manifest.json` ([`Manifest`]): the settings, the instruments' identification
//!   (ELCOMAT `d`, SMC100 `1VE`), the software version, start and end times, how the run
//!   ended (`outcome`: `running`, `completed`, `interrupted`, `instrument-error: …`,
//!   `file-error: …`) and one entry per session (the first run and each resumption).
//!   It is replaced atomically (written beside, synced, renamed).
//! - `traffic.jsonl`: every line sent and received ([`crate::lab::traffic`]), appended
//!   whole or not at all.
//!
//! # The order of the readings
//!
//! Cycles 1 … R; a clockwise cycle visits steps 0 … N−1, then N with the closing step; a
//! counter-clockwise one (cycles 2, 4, … with `bidirectional`, closing implied) visits
//! N … 0. At each stop autocollimators 1 … K are read in order. A resumed run continues from
//! the first reading (cycle, step, ac) of that order missing from `measurements.csv`:
//! the table is sent to that stop again and only the missing readings are taken. A file
//! whose readings are not exactly the first ones of that order is refused, as is a
//! manifest whose settings differ from the ones given, or instruments that identify
//! differently from those the run started with. Before the first new reading the last
//! stop with a stored reading is visited and read again (not stored): readings that do not
//! agree with the stored ones end the session (`verify.rs`).
//!
//! # Example: a whole run against simulated instruments, in memory
//!
//! ```
//! use polycal::lab::driver::ProfileAutocollimator;
//! use polycal::lab::run::{self, Instruments, Outcome, Ports, RunDir, RunSettings};
//! use polycal::lab::sim::{Devices, LabConfig, SimStream};
//! use polycal::lab::driver::{ProfileTable, TableOptions};
//! use polycal::lab::transport::StreamTransport;
//! use polycal::lab::{QueryOptions, StopFlag};
//! use polycal::simulate::SimulationConfig;
//!
//! let simulation = SimulationConfig { faces: 6, ..SimulationConfig::default() };
//! let lab = LabConfig::new(simulation).with_time_scale(0.0); // instantaneous motion
//! let Devices { autocollimators, table, .. } = Devices::new(lab)?;
//! let q = QueryOptions::default();
//! let mut acs: Vec<_> = autocollimators
//!     .into_iter()
//!     .map(|device| ProfileAutocollimator::elcomat3000(StreamTransport::new("sim:ac", SimStream::new(device)), q))
//!     .collect();
//! let mut table = ProfileTable::smc100(
//!     StreamTransport::new("sim:table", SimStream::new(table)),
//!     TableOptions::default(),
//! );
//!
//! let settings = RunSettings::new(6, 2).with_closing(true);
//! let dir = std::env::temp_dir().join(format!("polycal-doc-run-{}", std::process::id()));
//! # let _ = std::fs::remove_dir_all(&dir);
//! let mut run = RunDir::open(&dir, &settings, &Ports::default(), false)?;
//! let instruments = Instruments::of(&mut acs, &mut table);
//! let outcome = run::measure(&mut run, instruments, &StopFlag::new(), None, &mut |_| {})?;
//! run.finish(&outcome)?;
//! assert_eq!(outcome, Outcome::Completed);
//!
//! let set = polycal::MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None)?;
//! assert_eq!(set.readings.len(), 2 * 7 * 2); // cycles · stops · autocollimators
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod abort;
mod dir_store;
mod directory;
mod error;
mod live;
mod manifest;
mod measure;
mod mounting;
mod noise;
mod plan_file;
mod repeat;
mod resume;
mod session;
mod settings;
mod store;
mod verify;

pub use abort::AbortHandle;
pub use directory::{COLUMNS, MANIFEST, MEASUREMENTS, REMEASURED, RunDir, TRAFFIC};
pub use error::RunError;
pub use live::{
    Cell, CycleCheck, MAX_REMEASURED_PER_CYCLE, MIN_DOF, OFFSET_SIGMAS, OUTLIER_SIGMAS, Remeasured,
    Suspect, ToMeasureAgain, to_measure_again, to_measure_again_judged,
};
pub use manifest::{
    Identification, MANIFEST_FORMAT, Manifest, Ports, ProfileRecord, RunProfiles, SessionRecord,
    recorded_profiles, rfc3339, unix_now,
};
pub use measure::{
    APPROACH_OVERSHOOT_DEG, Attendant, Instruments, approach_overshoot_deg, measure,
    measure_attended,
};
pub use mounting::{
    MAX_MOUNTINGS, Mounting, MountingRecord, REMOUNT_TOLERANCE_DEG, Remount, lost_harmonics,
    unevaluable,
};
pub use noise::{NOISE_FLOOR_ARCSEC, NoiseRecord, RepeatNoise};
pub use plan_file::{PlanFileError, PlannedRun, run_from_plan};
pub use repeat::{EXTRA_READS, LastValue};
pub use session::{Action, Event, LogRecord, Outcome, Progress, Session, SessionError};
pub use settings::{
    AGREEMENT_SIGMAS, DEFAULT_READING_NOISE_ARCSEC, DEFAULT_READS_PER_STOP, MAX_AUTOCOLLIMATORS,
    MAX_READS_PER_STOP, RunSettings, SettingsError,
};
pub use store::{MemoryStore, Record, RunSoFar, Store, StoreError};
