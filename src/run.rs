//! The run procedure of `polycal run` (FORMAT.md §7): step the table through full
//! cycles, read both autocollimators at every stop, and keep every reading on disk.
//!
//! # The run directory
//!
//! - `measurements.csv`: FORMAT.md §2, header
//!   `cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder` after `#`
//!   comment lines; one row per reading, appended and synced (`fsync` of its data)
//!   before the table moves again. `face` is p+1 for autocollimator 1 and p+2
//!   (wrapping) for autocollimator 2, `setup` 1, `time` seconds since the run started,
//!   `reading_y` empty when the Y axis was not valid, `encoder` the position the table
//!   reported (`1TP`), degrees.
//! - `manifest.json` ([`Manifest`]): the settings, the instruments' identification
//!   (ELCOMAT `d`, SMC100 `1VE`), the software version, start and end times, how the run
//!   ended (`outcome`: `running`, `completed`, `interrupted`, `instrument-error: …`,
//!   `file-error: …`) and one entry per session (the first run and each `--resume`).
//!   It is replaced atomically (written beside, synced, renamed).
//! - `traffic.jsonl`: every line sent and received ([`crate::instrument::traffic`]).
//!
//! # The order of the readings
//!
//! Cycles 1 … R; a clockwise cycle visits steps 0 … N−1, then N with the closing step; a
//! counter-clockwise one (cycles 2, 4, … with `bidirectional`, closing implied) visits
//! N … 0. At each stop autocollimator 1 is read, then 2. A resumed run continues from
//! the first reading (cycle, step, ac) of that order missing from `measurements.csv`:
//! the table is sent to that stop again and only the missing readings are taken. A file
//! whose readings are not exactly the first ones of that order is refused, as is a
//! manifest whose settings differ from the command, or instruments that identify
//! differently from those the run started with.
//!
//! # Example: a whole run against simulated instruments, in memory
//!
//! ```
//! use polycal::instrument::sim::{Devices, LabConfig, SimStream};
//! use polycal::instrument::{
//!     Elcomat3000, QueryOptions, Smc100, Smc100Options, StopFlag, StreamTransport,
//! };
//! use polycal::run::{self, Instruments, Outcome, Ports, RunDir, RunSettings};
//! use polycal::simulate::SimulationConfig;
//!
//! let lab = LabConfig {
//!     simulation: SimulationConfig { faces: 6, ..SimulationConfig::default() },
//!     time_scale: 0.0, // instantaneous motion
//!     ..LabConfig::default()
//! };
//! let Devices { ac1, ac2, table, .. } = Devices::new(lab)?;
//! let q = QueryOptions::default();
//! let mut ac1 = Elcomat3000::new(StreamTransport::new("sim:ac1", SimStream::new(ac1)), q);
//! let mut ac2 = Elcomat3000::new(StreamTransport::new("sim:ac2", SimStream::new(ac2)), q);
//! let mut table = Smc100::new(
//!     StreamTransport::new("sim:table", SimStream::new(table)),
//!     Smc100Options::default(),
//! );
//!
//! let settings = RunSettings {
//!     faces: 6,
//!     cycles: 2,
//!     closing: true,
//!     bidirectional: false,
//!     settle_seconds: 0.0,
//! };
//! let dir = std::env::temp_dir().join(format!("polycal-doc-run-{}", std::process::id()));
//! # let _ = std::fs::remove_dir_all(&dir);
//! let mut run = RunDir::open(&dir, &settings, &Ports::default(), false)?;
//! let instruments = Instruments { ac1: &mut ac1, ac2: &mut ac2, table: &mut table };
//! let outcome = run::measure(&mut run, instruments, &StopFlag::new(), None, &mut |_| {})?;
//! run.finish(&outcome)?;
//! assert_eq!(outcome, Outcome::Completed);
//!
//! let set = polycal::MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None)?;
//! assert_eq!(set.readings.len(), 2 * 7 * 2); // cycles · stops · autocollimators
//! # std::fs::remove_dir_all(&dir)?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::collections::BTreeSet;
use std::fmt;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};

use crate::instrument::{
    AcReading, Autocollimator, InstrumentError, RotaryTable, RunClock, StopFlag, TrafficLog,
};
use crate::measurement::Direction;

/// The measurement file's name in the run directory.
pub const MEASUREMENTS: &str = "measurements.csv";
/// The manifest's name in the run directory.
pub const MANIFEST: &str = "manifest.json";
/// The traffic log's name in the run directory.
pub const TRAFFIC: &str = "traffic.jsonl";
/// The header row of the measurement file.
pub const HEADER: &str = "cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder";
/// The manifest format tag.
pub const MANIFEST_FORMAT: &str = "polycal-run/1";

/// The settings that define a run; a resumed run must have the same.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunSettings {
    /// Number of polygon faces N (≥ 3).
    pub faces: usize,
    /// Number of cycles R (≥ 1).
    pub cycles: u32,
    /// Whether clockwise cycles end with the closing step N (implied by `bidirectional`).
    pub closing: bool,
    /// Whether every second cycle runs counter-clockwise.
    pub bidirectional: bool,
    /// Wait after the table arrived before reading, seconds.
    pub settle_seconds: f64,
}

pub use crate::measurement::{Stop, run_stops};

impl Stop {
    /// The commanded table position, degrees: step·360/N (360 for the closing step).
    pub fn degrees(&self, faces: usize) -> f64 {
        if self.step == faces {
            360.0
        } else {
            self.step as f64 * 360.0 / faces as f64
        }
    }
}

/// The face autocollimator `ac` (1 or 2) reads at `step`: p+1, or p+2 for
/// autocollimator 2, wrapping.
pub fn face_at(ac: u32, step: usize, faces: usize) -> usize {
    (step + ac as usize - 1) % faces + 1
}

impl RunSettings {
    /// Checks the settings; the text names the first bad one.
    pub fn validate(&self) -> Result<(), String> {
        if self.faces < 3 {
            return Err(format!(
                "--faces {}: a polygon has at least 3 faces",
                self.faces
            ));
        }
        if self.faces > 100_000 {
            return Err(format!("--faces {}: at most 100000", self.faces));
        }
        if self.cycles == 0 {
            return Err("--cycles 0: a run has at least one cycle".into());
        }
        if !(self.settle_seconds.is_finite() && (0.0..=3600.0).contains(&self.settle_seconds)) {
            return Err(format!(
                "--settle {}: must be a number of seconds from 0 to 3600",
                self.settle_seconds
            ));
        }
        Ok(())
    }

    /// Whether every cycle has the closing step.
    pub fn has_closing(&self) -> bool {
        self.closing || self.bidirectional
    }

    /// The stops in order ([`run_stops`]).
    pub fn plan(&self) -> Vec<Stop> {
        run_stops(self.faces, self.cycles, self.closing, self.bidirectional)
    }

    /// Number of readings of the whole run.
    pub fn reading_count(&self) -> usize {
        let stops = if self.has_closing() {
            self.faces + 1
        } else {
            self.faces
        };
        stops * self.cycles as usize * 2
    }

    /// The settings as command-line options, e.g. `--faces 8 --cycles 2 --closing --settle 0`.
    pub fn as_options(&self) -> String {
        let mut s = format!("--faces {} --cycles {}", self.faces, self.cycles);
        if self.closing {
            s.push_str(" --closing");
        }
        if self.bidirectional {
            s.push_str(" --bidirectional");
        }
        s.push_str(&format!(" --settle {}", self.settle_seconds));
        s
    }

    /// The settings that differ from `other`, as `name: this vs other`.
    pub fn differences(&self, other: &RunSettings) -> Vec<String> {
        let mut d = Vec::new();
        if self.faces != other.faces {
            d.push(format!("faces {} vs {}", self.faces, other.faces));
        }
        if self.cycles != other.cycles {
            d.push(format!("cycles {} vs {}", self.cycles, other.cycles));
        }
        if self.has_closing() != other.has_closing() {
            d.push(format!(
                "closing {} vs {}",
                self.has_closing(),
                other.has_closing()
            ));
        }
        if self.bidirectional != other.bidirectional {
            d.push(format!(
                "bidirectional {} vs {}",
                self.bidirectional, other.bidirectional
            ));
        }
        if self.settle_seconds != other.settle_seconds {
            d.push(format!(
                "settle {} s vs {} s",
                self.settle_seconds, other.settle_seconds
            ));
        }
        d
    }
}

/// The ports of the three instruments.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Ports {
    /// Autocollimator 1.
    pub ac1: String,
    /// Autocollimator 2.
    pub ac2: String,
    /// The rotary table.
    pub table: String,
}

/// The instruments' identification: ELCOMAT `d` replies and the SMC100 `1VE` reply.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Identification {
    /// Autocollimator 1.
    pub ac1: String,
    /// Autocollimator 2.
    pub ac2: String,
    /// The rotary table's controller.
    pub table: String,
}

/// One session of a run: the first start, or one `--resume`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Session {
    /// The software, e.g. `polycal 0.1.0`.
    pub software: String,
    /// Start, RFC 3339 UTC.
    pub started: String,
    /// End, RFC 3339 UTC; `null` while running (or if the process was killed).
    pub ended: Option<String>,
    /// How the session ended (see [`Outcome`]); `running` until then.
    pub outcome: String,
    /// Ports used.
    pub ports: Ports,
    /// Readings on disk when the session started.
    pub readings_before: usize,
    /// Readings on disk when it ended.
    pub readings_after: usize,
}

/// `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// The software of the latest session, e.g. `polycal 0.1.0`.
    pub software: String,
    /// The run's settings.
    pub settings: RunSettings,
    /// The instruments' identification (`null` until they answered).
    pub instruments: Option<Identification>,
    /// Ports of the latest session.
    pub ports: Ports,
    /// Start of the run, RFC 3339 UTC.
    pub started: String,
    /// Start of the run, seconds since the Unix epoch (the origin of `time`).
    pub started_unix: f64,
    /// End of the latest session, RFC 3339 UTC.
    pub ended: Option<String>,
    /// How the latest session ended: `running`, `completed`, `interrupted`,
    /// `instrument-error: …` or `file-error: …`.
    pub outcome: String,
    /// Readings on disk.
    pub readings: usize,
    /// Readings of the complete run.
    pub expected_readings: usize,
    /// Every session, oldest first.
    pub sessions: Vec<Session>,
}

/// How a measuring session ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Every reading of the run is on disk.
    Completed,
    /// Stopped on request (Ctrl-C).
    Interrupted,
    /// An instrument failed (the text says which and how).
    InstrumentError(String),
    /// A file of the run directory could not be written.
    FileError(String),
}

impl fmt::Display for Outcome {
    /// `completed`, `interrupted`, `instrument-error: …` or `file-error: …`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Outcome::Completed => f.write_str("completed"),
            Outcome::Interrupted => f.write_str("interrupted"),
            Outcome::InstrumentError(m) => write!(f, "instrument-error: {m}"),
            Outcome::FileError(m) => write!(f, "file-error: {m}"),
        }
    }
}

impl Outcome {
    /// The outcome of an instrument's failure; `role` names the instrument
    /// (`autocollimator 1`, `rotary table`).
    fn from_instrument(role: &str, e: InstrumentError) -> Outcome {
        if e.is_interrupted() {
            Outcome::Interrupted
        } else {
            Outcome::InstrumentError(format!("{role} at {e}"))
        }
    }
}

/// The instruments' names in messages.
const ROLES: [&str; 3] = ["autocollimator 1", "autocollimator 2", "rotary table"];

/// Why a run directory was refused or could not be used.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The directory or its files do not allow this command (the text says why).
    #[error("{}: {message}", path.display())]
    Refused {
        /// The file or directory.
        path: PathBuf,
        /// Why.
        message: String,
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
}

fn io_error(path: &Path) -> impl FnOnce(io::Error) -> RunError + '_ {
    move |source| RunError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// One reading as written to the measurement file.
#[derive(Debug, Clone, PartialEq)]
pub struct RunReading {
    /// Where it was taken.
    pub stop: Stop,
    /// Autocollimator 1 or 2.
    pub ac: u32,
    /// Face read.
    pub face: usize,
    /// X, arcsec.
    pub reading_arcsec: f64,
    /// Seconds since the run started.
    pub time_seconds: f64,
    /// Y, arcsec, if valid.
    pub reading_y_arcsec: Option<f64>,
    /// Position the table reported, degrees.
    pub encoder_degrees: f64,
}

impl RunReading {
    /// The CSV row (with its line feed), columns as [`HEADER`].
    pub fn to_row(&self) -> String {
        format!(
            "{},{},{},{},{},{},{},1,{},{}\n",
            self.stop.cycle,
            self.stop.step,
            self.ac,
            self.face,
            self.reading_arcsec,
            self.stop.direction,
            self.time_seconds,
            self.reading_y_arcsec
                .map(|y| y.to_string())
                .unwrap_or_default(),
            self.encoder_degrees
        )
    }
}

/// Seconds since the Unix epoch.
pub fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// An RFC 3339 UTC time stamp (`2026-11-03T14:05:09.123Z`) of seconds since the epoch.
///
/// ```
/// assert_eq!(polycal::run::rfc3339(0.0), "1970-01-01T00:00:00.000Z");
/// assert_eq!(polycal::run::rfc3339(1_700_000_000.25), "2023-11-14T22:13:20.250Z");
/// ```
pub fn rfc3339(unix_seconds: f64) -> String {
    let total_ms = (unix_seconds.max(0.0) * 1000.0).round() as i64;
    let (secs, ms) = (total_ms.div_euclid(1000), total_ms.rem_euclid(1000));
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Days to civil date (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{ms:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

fn software() -> String {
    format!("polycal {}", env!("CARGO_PKG_VERSION"))
}

/// A run directory opened for measuring: its manifest, the readings on disk and the
/// measurement file open for appending.
#[derive(Debug)]
pub struct RunDir {
    dir: PathBuf,
    manifest: Manifest,
    measurements: File,
    done: BTreeSet<(u32, usize, u32)>,
    clock: RunClock,
    session_open: bool,
    session_readings_before: usize,
    warnings: Vec<String>,
}

impl RunDir {
    /// Opens `dir` for a new run (`resume` false) or to continue one (`resume` true).
    ///
    /// A new run refuses a directory that already holds a run (a manifest or a
    /// measurement file) and creates the directory, the manifest (outcome `running`) and
    /// the measurement file's header. Either way the measurement file is locked for as
    /// long as the `RunDir` lives: a directory another run is using is refused. A resumed
    /// run refuses a directory without a manifest, a manifest whose settings differ from `settings`, and a measurement
    /// file that is not the first readings of the run in order; a last line cut short
    /// (no line feed) is removed, with a warning ([`RunDir::warnings`]).
    ///
    /// # Errors
    ///
    /// [`RunError::Refused`] or [`RunError::Io`], naming the file.
    pub fn open(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        resume: bool,
    ) -> Result<RunDir, RunError> {
        settings.validate().map_err(|message| RunError::Refused {
            path: dir.to_path_buf(),
            message,
        })?;
        if resume {
            RunDir::resume(dir, settings, ports)
        } else {
            RunDir::create(dir, settings, ports)
        }
    }

    fn create(dir: &Path, settings: &RunSettings, ports: &Ports) -> Result<RunDir, RunError> {
        for name in [MANIFEST, MEASUREMENTS] {
            let path = dir.join(name);
            if path.exists() {
                return Err(RunError::Refused {
                    path,
                    message: "this directory already holds a run; continue it with --resume, or choose another --out".into(),
                });
            }
        }
        fs::create_dir_all(dir).map_err(io_error(dir))?;
        let now = unix_now();
        let manifest = Manifest {
            format: MANIFEST_FORMAT.into(),
            software: software(),
            settings: settings.clone(),
            instruments: None,
            ports: ports.clone(),
            started: rfc3339(now),
            started_unix: now,
            ended: None,
            outcome: "running".into(),
            readings: 0,
            expected_readings: settings.reading_count(),
            sessions: Vec::new(),
        };
        let path = dir.join(MEASUREMENTS);
        let mut file = OpenOptions::new()
            .create_new(true)
            .append(true)
            .open(&path)
            .map_err(io_error(&path))?;
        lock_exclusive(&file, &path)?;
        let comment = format!(
            "# {} run: {}; started {}\n{HEADER}\n",
            software(),
            settings.as_options(),
            manifest.started
        );
        file.write_all(comment.as_bytes())
            .and_then(|()| file.sync_data())
            .map_err(io_error(&path))?;
        let mut run = RunDir {
            dir: dir.to_path_buf(),
            manifest,
            measurements: file,
            done: BTreeSet::new(),
            clock: RunClock::new(0.0),
            session_open: false,
            session_readings_before: 0,
            warnings: Vec::new(),
        };
        run.write_manifest()?;
        Ok(run)
    }

    fn resume(dir: &Path, settings: &RunSettings, ports: &Ports) -> Result<RunDir, RunError> {
        let manifest_path = dir.join(MANIFEST);
        let text = match fs::read_to_string(&manifest_path) {
            Ok(text) => text,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Err(RunError::Refused {
                    path: dir.to_path_buf(),
                    message: format!(
                        "no run to resume here (no {MANIFEST}); start one without --resume"
                    ),
                });
            }
            Err(e) => return Err(io_error(&manifest_path)(e)),
        };
        let mut manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| RunError::Refused {
                path: manifest_path.clone(),
                message: format!("not a run manifest: {e}"),
            })?;
        let differences = manifest.settings.differences(settings);
        if !differences.is_empty() {
            return Err(RunError::Refused {
                path: manifest_path,
                message: format!(
                    "the run was started with {}, this command says {} ({}); refusing to resume",
                    manifest.settings.as_options(),
                    settings.as_options(),
                    differences.join(", ")
                ),
            });
        }
        let path = dir.join(MEASUREMENTS);
        let mut file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .map_err(io_error(&path))?;
        lock_exclusive(&file, &path)?;
        let mut warnings = Vec::new();
        let done = read_existing(&path, settings, &mut warnings)?;
        let len = file.metadata().map_err(io_error(&path))?.len();
        if len == 0 {
            let comment = format!(
                "# {} run: {}; started {}\n{HEADER}\n",
                software(),
                settings.as_options(),
                manifest.started
            );
            file.write_all(comment.as_bytes())
                .and_then(|()| file.sync_data())
                .map_err(io_error(&path))?;
        }
        manifest.ports = ports.clone();
        manifest.readings = done.len();
        let offset = (unix_now() - manifest.started_unix).max(0.0);
        Ok(RunDir {
            dir: dir.to_path_buf(),
            session_readings_before: done.len(),
            manifest,
            measurements: file,
            done,
            clock: RunClock::new(offset),
            session_open: false,
            warnings,
        })
    }

    /// Warnings found while opening (a cut-short last line removed).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// The directory.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The manifest as it stands.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// The run's clock (seconds since the run started).
    pub fn clock(&self) -> RunClock {
        self.clock
    }

    /// Readings on disk.
    pub fn readings_done(&self) -> usize {
        self.done.len()
    }

    /// The stops still to visit, each with the autocollimators still to read there, in
    /// order.
    pub fn remaining(&self) -> Vec<(Stop, Vec<u32>)> {
        self.manifest
            .settings
            .plan()
            .into_iter()
            .filter_map(|stop| {
                let acs: Vec<u32> = (1..=2)
                    .filter(|&ac| !self.done.contains(&(stop.cycle, stop.step, ac)))
                    .collect();
                (!acs.is_empty()).then_some((stop, acs))
            })
            .collect()
    }

    /// Opens the traffic log (appending) on the run's clock.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] naming the file.
    pub fn traffic_log(&self) -> Result<TrafficLog, RunError> {
        let path = self.dir.join(TRAFFIC);
        TrafficLog::append_to(&path, self.clock).map_err(io_error(&path))
    }

    /// Records the instruments and starts this session in the manifest. On a resumed
    /// run, instruments that identify differently from those the run started with are
    /// refused.
    ///
    /// # Errors
    ///
    /// [`RunError::Refused`] for other instruments, [`RunError::Io`] when the manifest
    /// cannot be written.
    pub fn begin_session(&mut self, identification: Identification) -> Result<(), RunError> {
        if let Some(before) = &self.manifest.instruments {
            let mut differ = Vec::new();
            for (name, a, b) in [
                ("ac1", &before.ac1, &identification.ac1),
                ("ac2", &before.ac2, &identification.ac2),
                ("table", &before.table, &identification.table),
            ] {
                if a != b {
                    differ.push(format!("{name} was {a:?}, is now {b:?}"));
                }
            }
            if !differ.is_empty() {
                return Err(RunError::Refused {
                    path: self.dir.join(MANIFEST),
                    message: format!(
                        "other instruments than the run started with ({}); refusing to resume",
                        differ.join("; ")
                    ),
                });
            }
        }
        self.manifest.instruments = Some(identification);
        self.open_session();
        self.write_manifest()
    }

    fn open_session(&mut self) {
        if self.session_open {
            return;
        }
        self.session_open = true;
        self.manifest.software = software();
        self.manifest.outcome = "running".into();
        self.manifest.ended = None;
        self.manifest.sessions.push(Session {
            software: software(),
            started: rfc3339(unix_now()),
            ended: None,
            outcome: "running".into(),
            ports: self.manifest.ports.clone(),
            readings_before: self.session_readings_before,
            readings_after: self.session_readings_before,
        });
    }

    /// Appends one reading to the measurement file and syncs it to disk.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] naming the file.
    pub fn append(&mut self, reading: &RunReading) -> Result<(), RunError> {
        let path = self.dir.join(MEASUREMENTS);
        self.measurements
            .write_all(reading.to_row().as_bytes())
            .and_then(|()| self.measurements.sync_data())
            .map_err(io_error(&path))?;
        self.done
            .insert((reading.stop.cycle, reading.stop.step, reading.ac));
        Ok(())
    }

    /// Records how the session ended in the manifest.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] when the manifest cannot be written.
    pub fn finish(&mut self, outcome: &Outcome) -> Result<(), RunError> {
        self.open_session();
        let now = rfc3339(unix_now());
        let text = outcome.to_string();
        self.manifest.outcome = text.clone();
        self.manifest.ended = Some(now.clone());
        self.manifest.readings = self.done.len();
        if let Some(session) = self.manifest.sessions.last_mut() {
            session.ended = Some(now);
            session.outcome = text;
            session.readings_after = self.done.len();
        }
        self.write_manifest()
    }

    fn write_manifest(&mut self) -> Result<(), RunError> {
        self.manifest.readings = self.done.len();
        let path = self.dir.join(MANIFEST);
        let tmp = self.dir.join(format!("{MANIFEST}.tmp"));
        let text = serde_json::to_string_pretty(&self.manifest).map_err(|e| RunError::Io {
            path: path.clone(),
            source: io::Error::other(e),
        })? + "\n";
        let write = || -> io::Result<()> {
            let mut file = File::create(&tmp)?;
            file.write_all(text.as_bytes())?;
            file.sync_all()?;
            fs::rename(&tmp, &path)?;
            if let Ok(d) = File::open(&self.dir) {
                let _ = d.sync_all();
            }
            Ok(())
        };
        write().map_err(io_error(&path))
    }
}

/// Without flock, no lock (other systems).
#[cfg(not(unix))]
fn lock_exclusive(_file: &File, _path: &Path) -> Result<(), RunError> {
    Ok(())
}

/// Takes an exclusive lock on the open measurement file, so that two runs never write
/// one directory; the lock goes with the process, however it ends.
#[cfg(unix)]
fn lock_exclusive(file: &File, path: &Path) -> Result<(), RunError> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock on a descriptor that `file` keeps open.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(());
    }
    let e = io::Error::last_os_error();
    if e.kind() == io::ErrorKind::WouldBlock {
        return Err(RunError::Refused {
            path: path.to_path_buf(),
            message: "another polycal run is using this directory".into(),
        });
    }
    Err(io_error(path)(e))
}

/// Reads the readings already on disk; removes a cut-short last line.
fn read_existing(
    path: &Path,
    settings: &RunSettings,
    warnings: &mut Vec<String>,
) -> Result<BTreeSet<(u32, usize, u32)>, RunError> {
    let mut bytes = match fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(BTreeSet::new()),
        Err(e) => return Err(io_error(path)(e)),
    };
    if !bytes.is_empty() && bytes.last() != Some(&b'\n') {
        let keep = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let cut = String::from_utf8_lossy(&bytes[keep..]).into_owned();
        let file = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io_error(path))?;
        file.set_len(keep as u64)
            .and_then(|()| file.sync_all())
            .map_err(io_error(path))?;
        bytes.truncate(keep);
        warnings.push(format!(
            "{}: removed the last line, cut short when the run stopped: {cut:?}",
            path.display()
        ));
    }
    let text = String::from_utf8(bytes).map_err(|_| RunError::Refused {
        path: path.to_path_buf(),
        message: "not UTF-8 text".into(),
    })?;
    // The readings of the run in order: the file must hold exactly the first ones.
    let order: Vec<(Stop, u32)> = settings
        .plan()
        .into_iter()
        .flat_map(|stop| [(stop, 1), (stop, 2)])
        .collect();
    let mut done = BTreeSet::new();
    let mut header_seen = false;
    for (index, line) in text.lines().enumerate() {
        let line_no = index + 1;
        let refuse = |message: String| RunError::Refused {
            path: path.to_path_buf(),
            message: format!("line {line_no}: {message}; refusing to resume"),
        };
        if !header_seen {
            if line.starts_with('#') || line.trim().is_empty() {
                continue;
            }
            if line != HEADER {
                return Err(refuse(format!(
                    "header {line:?} is not the run's header {HEADER:?}"
                )));
            }
            header_seen = true;
            continue;
        }
        if line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() != 10 {
            return Err(refuse(format!("{} fields, expected 10", fields.len())));
        }
        let k = done.len();
        let Some(&(stop, ac)) = order.get(k) else {
            return Err(refuse("more readings than the run has".into()));
        };
        let expected = format!(
            "{},{},{},{}",
            stop.cycle,
            stop.step,
            ac,
            face_at(ac, stop.step, settings.faces)
        );
        let got = fields[..4].join(",");
        if got != expected || fields[5] != stop.direction.as_str() {
            return Err(refuse(format!(
                "reading {got:?} ({}) is not the run's reading number {} ({expected:?}, {})",
                fields[5],
                k + 1,
                stop.direction
            )));
        }
        for (name, i) in [("reading", 4), ("time", 6), ("encoder", 9)] {
            if !fields[i].parse::<f64>().is_ok_and(f64::is_finite) {
                return Err(refuse(format!(
                    "{name} {:?} is not a finite number",
                    fields[i]
                )));
            }
        }
        done.insert((stop.cycle, stop.step, ac));
    }
    Ok(done)
}

/// The three instruments of a run.
pub struct Instruments<'a> {
    /// Autocollimator 1.
    pub ac1: &'a mut dyn Autocollimator,
    /// Autocollimator 2.
    pub ac2: &'a mut dyn Autocollimator,
    /// The rotary table.
    pub table: &'a mut dyn RotaryTable,
}

impl fmt::Debug for Instruments<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Instruments")
            .field("ac1", &self.ac1.port())
            .field("ac2", &self.ac2.port())
            .field("table", &self.table.port())
            .finish()
    }
}

/// Where a run is, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Readings on disk.
    pub done: usize,
    /// Readings of the whole run.
    pub total: usize,
    /// Current cycle, and the number of cycles.
    pub cycle: (u32, u32),
    /// Current stop within the cycle (1-based), and stops per cycle.
    pub stop: (usize, usize),
    /// Current step (0 … N).
    pub step: usize,
    /// Estimated seconds until the run is complete, once a reading was taken.
    pub seconds_left: Option<f64>,
}

/// Starts and identifies the instruments, then measures every remaining reading of
/// `run`, syncing each to disk (and the traffic log, if given) before the table moves
/// again. Returns how the session ended; on anything but completion the table is sent a
/// stop. The manifest is not finished here: call [`RunDir::finish`].
///
/// # Errors
///
/// [`RunError::Refused`] when a resumed run meets other instruments than it started
/// with (nothing was measured then), [`RunError::Io`] when the manifest cannot be
/// written at the start.
pub fn measure(
    run: &mut RunDir,
    instruments: Instruments<'_>,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Outcome, RunError> {
    let Instruments { ac1, ac2, table } = instruments;
    let identification = match identify(ac1, ac2, table) {
        Ok(id) => id,
        Err((role, e)) => {
            let _ = table.stop();
            return Ok(Outcome::from_instrument(role, e));
        }
    };
    run.begin_session(identification)?;
    let outcome = measure_stops(run, ac1, ac2, table, stop_flag, traffic, progress);
    if outcome != Outcome::Completed {
        let _ = table.stop();
    }
    if let Some(log) = traffic
        && let Err(e) = log.sync()
        && outcome == Outcome::Completed
    {
        return Ok(Outcome::FileError(format!(
            "{}: {e}",
            run.dir.join(TRAFFIC).display()
        )));
    }
    Ok(outcome)
}

fn identify(
    ac1: &mut dyn Autocollimator,
    ac2: &mut dyn Autocollimator,
    table: &mut dyn RotaryTable,
) -> Result<Identification, (&'static str, InstrumentError)> {
    let role = |i: usize| move |e| (ROLES[i], e);
    ac1.start().map_err(role(0))?;
    let id1 = ac1.identify().map_err(role(0))?;
    ac2.start().map_err(role(1))?;
    let id2 = ac2.identify().map_err(role(1))?;
    table.start().map_err(role(2))?;
    let id_table = table.identify().map_err(role(2))?;
    Ok(Identification {
        ac1: id1,
        ac2: id2,
        table: id_table,
    })
}

fn measure_stops(
    run: &mut RunDir,
    ac1: &mut dyn Autocollimator,
    ac2: &mut dyn Autocollimator,
    table: &mut dyn RotaryTable,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    progress: &mut dyn FnMut(&Progress),
) -> Outcome {
    let settings = run.manifest.settings.clone();
    let total = settings.reading_count();
    let stops_per_cycle = if settings.has_closing() {
        settings.faces + 1
    } else {
        settings.faces
    };
    let session_start = Instant::now();
    let before = run.readings_done();
    let settle = std::time::Duration::try_from_secs_f64(settings.settle_seconds)
        .unwrap_or(std::time::Duration::ZERO);
    for (stop, acs) in run.remaining() {
        if stop_flag.is_set() {
            return Outcome::Interrupted;
        }
        // Everything on disk before the table moves.
        if let Some(log) = traffic
            && let Err(e) = log.sync()
        {
            return Outcome::FileError(format!("{}: {e}", run.dir.join(TRAFFIC).display()));
        }
        let encoder = match table.move_to(stop.degrees(settings.faces)) {
            Ok(p) => p,
            Err(e) => return Outcome::from_instrument(ROLES[2], e),
        };
        if stop_flag.sleep(settle) {
            return Outcome::Interrupted;
        }
        for ac in acs {
            if stop_flag.is_set() {
                return Outcome::Interrupted;
            }
            let device: &mut dyn Autocollimator = if ac == 1 { &mut *ac1 } else { &mut *ac2 };
            let AcReading {
                x_arcsec, y_arcsec, ..
            } = match device.measure() {
                Ok(r) => r,
                Err(e) => return Outcome::from_instrument(ROLES[ac as usize - 1], e),
            };
            let reading = RunReading {
                stop,
                ac,
                face: face_at(ac, stop.step, settings.faces),
                reading_arcsec: x_arcsec,
                time_seconds: run.clock.now(),
                reading_y_arcsec: y_arcsec,
                encoder_degrees: encoder,
            };
            if let Err(e) = run.append(&reading) {
                // The reading was taken: say it, so that it is not lost with the file.
                return Outcome::FileError(format!(
                    "{e} (the reading not written: {})",
                    reading.to_row().trim_end()
                ));
            }
            let done = run.readings_done();
            let this_session = done - before;
            let elapsed = session_start.elapsed().as_secs_f64();
            let position = match stop.direction {
                Direction::Cw => stop.step + 1,
                Direction::Ccw => stops_per_cycle - stop.step,
            };
            progress(&Progress {
                done,
                total,
                cycle: (stop.cycle, settings.cycles),
                stop: (position, stops_per_cycle),
                step: stop.step,
                seconds_left: (this_session > 0)
                    .then(|| elapsed / this_session as f64 * (total - done) as f64),
            });
        }
    }
    Outcome::Completed
}
