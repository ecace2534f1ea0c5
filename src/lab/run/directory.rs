//! The run directory: its files, its lock, its manifest as it is updated through a
//! session, and the measurement file each reading is appended and synced to.

use std::collections::BTreeSet;
use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::error::io_error;
use super::manifest::software;
use super::{
    Identification, MANIFEST_FORMAT, Manifest, Outcome, Ports, RunError, RunSettings, Session,
    rfc3339, unix_now,
};
use crate::lab::traffic::{RunClock, TrafficLog};
use crate::measurement::{Column, Columns, Reading, ReadingWriter, Stop};

/// The measurement file's name in the run directory.
pub const MEASUREMENTS: &str = "measurements.csv";
/// The manifest's name in the run directory.
pub const MANIFEST: &str = "manifest.json";
/// The traffic log's name in the run directory.
pub const TRAFFIC: &str = "traffic.jsonl";

/// The columns of the run's measurement file, in order:
/// `cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder`.
pub const COLUMNS: [Column; 10] = [
    Column::CYCLE,
    Column::STEP,
    Column::AC,
    Column::FACE,
    Column::READING,
    Column::DIRECTION,
    Column::TIME,
    Column::SETUP,
    Column::READING_Y,
    Column::ENCODER,
];

/// A run directory opened for measuring: its manifest, the readings on disk and the
/// measurement file open for appending.
#[derive(Debug)]
pub struct RunDir {
    pub(super) dir: PathBuf,
    pub(super) manifest: Manifest,
    pub(super) measurements: ReadingWriter<File>,
    pub(super) done: BTreeSet<(u32, usize, u32)>,
    pub(super) clock: RunClock,
    pub(super) session_open: bool,
    pub(super) session_readings_before: usize,
    pub(super) warnings: Vec<String>,
}

impl RunDir {
    /// Opens `dir` for a new run (`resume` false) or to continue one (`resume` true).
    ///
    /// A new run refuses a directory that already holds a run (a manifest or a
    /// measurement file) and creates the directory, the manifest (outcome `running`) and
    /// the measurement file's header. Either way the measurement file is locked for as
    /// long as the `RunDir` lives: a directory another run is using is refused. A resumed
    /// run refuses a directory without a manifest, a manifest whose settings differ from
    /// `settings`, and a measurement file that is not the first readings of the run in
    /// order; a last line cut short (no line feed) is removed, with a warning
    /// ([`RunDir::warnings`]).
    ///
    /// # Errors
    ///
    /// A refusal ([`RunError::is_refusal`]) or [`RunError::Io`], naming the file.
    pub fn open(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        resume: bool,
    ) -> Result<RunDir, RunError> {
        settings.validate().map_err(|error| RunError::Settings {
            path: dir.to_path_buf(),
            error,
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
                return Err(RunError::AlreadyHoldsRun { path });
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
        let file = OpenOptions::new()
            .create_new(true)
            .append(true)
            .open(&path)
            .map_err(io_error(&path))?;
        lock_exclusive(&file, &path)?;
        let measurements = start_file(file, &path, &[first_comment(&manifest)])?;
        let mut run = RunDir {
            dir: dir.to_path_buf(),
            manifest,
            measurements,
            done: BTreeSet::new(),
            clock: RunClock::new(0.0),
            session_open: false,
            session_readings_before: 0,
            warnings: Vec::new(),
        };
        run.write_manifest()?;
        Ok(run)
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
    /// [`RunError::OtherInstruments`] for other instruments, [`RunError::Io`] when the
    /// manifest cannot be written.
    pub fn begin_session(&mut self, identification: Identification) -> Result<(), RunError> {
        if let Some(before) = &self.manifest.instruments {
            let mut differences = Vec::new();
            for (name, a, b) in [
                ("ac1", &before.ac1, &identification.ac1),
                ("ac2", &before.ac2, &identification.ac2),
                ("table", &before.table, &identification.table),
            ] {
                if a != b {
                    differences.push(format!("{name} was {a:?}, is now {b:?}"));
                }
            }
            if !differences.is_empty() {
                return Err(RunError::OtherInstruments {
                    path: self.dir.join(MANIFEST),
                    differences,
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
    pub fn append(&mut self, reading: &Reading) -> Result<(), RunError> {
        let path = self.dir.join(MEASUREMENTS);
        self.measurements
            .write(reading)
            .and_then(|()| self.measurements.get_ref().sync_data())
            .map_err(io_error(&path))?;
        self.done.insert((reading.cycle, reading.step, reading.ac));
        Ok(())
    }

    /// The row `reading` has (or would have) in the measurement file, without its line
    /// feed.
    pub fn row(&self, reading: &Reading) -> String {
        self.measurements.columns().row(reading)
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

    /// Replaces the manifest atomically: written beside, synced, renamed.
    pub(super) fn write_manifest(&mut self) -> Result<(), RunError> {
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

/// The first comment of the measurement file: the software, the settings as options and
/// the start of the run.
pub(super) fn first_comment(manifest: &Manifest) -> String {
    format!(
        "{} run: {}; started {}",
        software(),
        manifest.settings.as_options(),
        manifest.started
    )
}

/// Writes `comments` and the header to the measurement file `file` (at `path`), which
/// holds no header yet, syncs them, and returns the writer for the readings.
pub(super) fn start_file(
    file: File,
    path: &Path,
    comments: &[String],
) -> Result<ReadingWriter<File>, RunError> {
    ReadingWriter::start(file, Columns::new(COLUMNS), comments)
        .and_then(|w| w.get_ref().sync_data().map(|()| w))
        .map_err(io_error(path))
}

/// Without flock, no lock (other systems).
#[cfg(not(unix))]
pub(super) fn lock_exclusive(_file: &File, _path: &Path) -> Result<(), RunError> {
    Ok(())
}

/// Takes an exclusive lock on the open measurement file, so that two runs never write
/// one directory; the lock goes with the process, however it ends.
#[cfg(unix)]
pub(super) fn lock_exclusive(file: &File, path: &Path) -> Result<(), RunError> {
    use std::os::unix::io::AsRawFd;
    // SAFETY: flock on a descriptor that `file` keeps open.
    let rc = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    if rc == 0 {
        return Ok(());
    }
    let e = io::Error::last_os_error();
    if e.kind() == io::ErrorKind::WouldBlock {
        return Err(RunError::Locked {
            path: path.to_path_buf(),
        });
    }
    Err(io_error(path)(e))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::Direction;

    /// The measurement file's header and rows, byte for byte as the run wrote them before
    /// it used the measurement module's writer.
    #[test]
    fn the_run_writes_its_columns_in_its_order() {
        let columns = Columns::new(COLUMNS);
        assert_eq!(
            columns.header(),
            "cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder"
        );
        let mut reading = Reading {
            setup: 1,
            cycle: 2,
            step: 8,
            ac: 2,
            face: 1,
            reading_arcsec: -0.123_456_789_012_345_67,
            direction: Direction::Ccw,
            time_seconds: Some(12.5),
            reading_y_arcsec: None,
            temperature_celsius: None,
            encoder_degrees: Some(360.0),
            line: 0,
        };
        assert_eq!(
            columns.row(&reading),
            "2,8,2,1,-0.12345678901234566,ccw,12.5,1,,360"
        );
        reading.reading_y_arcsec = Some(1e-7);
        reading.direction = Direction::Cw;
        assert_eq!(
            columns.row(&reading),
            "2,8,2,1,-0.12345678901234566,cw,12.5,1,0.0000001,360"
        );
    }
}
