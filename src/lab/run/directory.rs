//! The run directory: its files, its lock, its manifest as it is updated through a
//! session, and the measurement file each reading is appended and synced to.

use std::collections::BTreeSet;
use std::fs::{self, File};
use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use super::abort::{self, AbortHandle, OnDisk, Shared};
use super::error::io_error;
use super::manifest::software;
use super::{
    Identification, MANIFEST_FORMAT, Manifest, Outcome, Ports, RunError, RunSettings, rfc3339,
    unix_now,
};
use crate::lab::WriteBudget;
use crate::lab::disk::LineFile;
use crate::lab::traffic::{RunClock, TrafficLog};
use crate::measurement::{Column, Columns, Reading, ReadingWriter, Stop};

/// The measurement file's name in the run directory.
pub const MEASUREMENTS: &str = "measurements.csv";
/// The manifest's name in the run directory.
pub const MANIFEST: &str = "manifest.json";
/// The traffic log's name in the run directory.
pub const TRAFFIC: &str = "traffic.jsonl";
/// The run directory's record of the first values of readings measured again.
pub const REMEASURED: &str = "remeasured.csv";

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
    pub(super) measurements: ReadingWriter<LineFile>,
    pub(super) done: BTreeSet<(u32, usize, u32)>,
    pub(super) clock: RunClock,
    pub(super) session_open: bool,
    pub(super) session_readings_before: usize,
    pub(super) warnings: Vec<String>,
    pub(super) budget: WriteBudget,
    /// What is on disk, shared with the [`AbortHandle`]s.
    pub(super) shared: Shared,
}

impl RunDir {
    /// Opens `dir` for a new run (`resume` false) or to continue one (`resume` true).
    ///
    /// A path that is a file, not a directory, is refused. A new run refuses a directory
    /// that already holds a run (a manifest or a measurement file) and creates the
    /// directory, the measurement file's header and the manifest (outcome `running`); if
    /// that fails (a full disk), the files it created are removed again
    /// ([`RunError::NotStarted`]), so that the same run can start once the cause is gone.
    /// Either way the measurement file is locked for as long as the `RunDir` lives: a
    /// directory another run is using is refused. A resumed run refuses a directory
    /// without a manifest, a manifest whose settings differ from `settings`, and a
    /// measurement file that is not the first readings of the run in order; a last line
    /// cut short (no line feed) in the measurement file or the traffic log is removed,
    /// with a warning ([`RunDir::warnings`]).
    ///
    /// # Errors
    ///
    /// A refusal ([`RunError::is_refusal`]), [`RunError::NotStarted`] or
    /// [`RunError::Io`], naming the file.
    pub fn open(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        resume: bool,
    ) -> Result<RunDir, RunError> {
        RunDir::open_with_budget(dir, settings, ports, resume, &WriteBudget::unlimited())
    }

    /// As [`RunDir::open`], with every file of the run directory (the measurement file,
    /// the manifest and the traffic log of [`RunDir::traffic_log`]) written through
    /// `budget`: a full disk, simulated.
    ///
    /// # Errors
    ///
    /// As [`RunDir::open`].
    pub fn open_with_budget(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        resume: bool,
        budget: &WriteBudget,
    ) -> Result<RunDir, RunError> {
        settings.validate().map_err(|error| RunError::Settings {
            path: dir.to_path_buf(),
            error,
        })?;
        if fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
            return Err(RunError::NotADirectory {
                path: dir.to_path_buf(),
            });
        }
        if resume {
            RunDir::resume(dir, settings, ports, budget)
        } else {
            RunDir::create(dir, settings, ports, budget)
        }
    }

    /// A run directory of `manifest`, with the measurement file open after its header.
    pub(super) fn assemble(
        dir: &Path,
        manifest: Manifest,
        measurements: ReadingWriter<LineFile>,
        done: BTreeSet<(u32, usize, u32)>,
        clock: RunClock,
        warnings: Vec<String>,
        budget: &WriteBudget,
    ) -> RunDir {
        let shared = Arc::new(Mutex::new(OnDisk {
            manifest: manifest.clone(),
            session_in_manifest: false,
            readings_before: done.len(),
            readings: done.len(),
            ended: false,
            closed: false,
        }));
        RunDir {
            dir: dir.to_path_buf(),
            manifest,
            measurements,
            session_readings_before: done.len(),
            done,
            clock,
            session_open: false,
            warnings,
            budget: budget.clone(),
            shared,
        }
    }

    fn create(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        budget: &WriteBudget,
    ) -> Result<RunDir, RunError> {
        for name in [MANIFEST, MEASUREMENTS] {
            let path = dir.join(name);
            if path.exists() {
                return Err(RunError::AlreadyHoldsRun { path });
            }
        }
        let made_dir = !dir.exists();
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
            remeasured: Vec::new(),
            suspect: Vec::new(),
        };
        let path = dir.join(MEASUREMENTS);
        let file = LineFile::open(&path, true, budget)
            .map_err(|e| not_started(dir, made_dir, None, io_error(&path)(e)))?;
        let started = (|| {
            lock_exclusive(file.file(), &path)?;
            let measurements = start_file(file, &[first_comment(&manifest)])?;
            let mut run = RunDir::assemble(
                dir,
                manifest,
                measurements,
                BTreeSet::new(),
                RunClock::new(0.0),
                Vec::new(),
                budget,
            );
            run.write_manifest(false)?;
            Ok(run)
        })();
        started.map_err(|e| not_started(dir, made_dir, Some(&path), e))
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
                let acs: Vec<u32> = self
                    .manifest
                    .settings
                    .acs()
                    .filter(|&ac| !self.done.contains(&(stop.cycle, stop.step, ac)))
                    .collect();
                (!acs.is_empty()).then_some((stop, acs))
            })
            .collect()
    }

    /// Opens the traffic log (appending) on the run's clock, written through the run
    /// directory's budget.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] naming the file.
    pub fn traffic_log(&self) -> Result<TrafficLog, RunError> {
        let path = self.dir.join(TRAFFIC);
        TrafficLog::append_to_with_budget(&path, self.clock, &self.budget).map_err(io_error(&path))
    }

    /// A handle that ends this run directory's writing from another thread, recording
    /// `interrupted` in the manifest: for a process that must end at once (a second
    /// Ctrl-C).
    pub fn abort_handle(&self) -> AbortHandle {
        AbortHandle {
            dir: self.dir.clone(),
            budget: self.budget.clone(),
            shared: Arc::clone(&self.shared),
        }
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
            for ac in self.manifest.settings.acs() {
                let (a, b) = (before.ac(ac), identification.ac(ac));
                if a != b {
                    differences.push(format!(
                        "ac{ac} was {:?}, is now {:?}",
                        a.unwrap_or(""),
                        b.unwrap_or("")
                    ));
                }
            }
            if before.table != identification.table {
                differences.push(format!(
                    "table was {:?}, is now {:?}",
                    before.table, identification.table
                ));
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
        self.write_manifest(false)
    }

    fn open_session(&mut self) {
        if !self.session_open {
            self.session_open = true;
            self.manifest.open_session(self.session_readings_before);
        }
    }

    /// Appends one reading to the measurement file and syncs it to disk. When that
    /// fails, the file is cut back to its last whole line: the reading is not on disk.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] naming the file; [`RunError::Closed`] after an
    /// [`AbortHandle::abort`].
    pub fn append(&mut self, reading: &Reading) -> Result<(), RunError> {
        let path = self.dir.join(MEASUREMENTS);
        let mut on_disk = abort::lock(&self.shared);
        if on_disk.closed {
            return Err(RunError::Closed { path });
        }
        let written = self
            .measurements
            .write(reading)
            .and_then(|()| self.measurements.get_ref().sync_data());
        if let Err(e) = written {
            // The write's error is the one to tell; a cut line left behind (the file
            // could not be cut back) is removed by a resumed run.
            let _ = self.measurements.get_mut().rollback();
            return Err(io_error(&path)(e));
        }
        self.measurements.get_mut().commit();
        self.done.insert((reading.cycle, reading.step, reading.ac));
        on_disk.readings = self.done.len();
        Ok(())
    }

    /// Replaces the reading `first` in the measurement file by `again`, the same
    /// reading (cycle, step, autocollimator) measured again at its stop, and records it
    /// in the manifest as `record`:
    ///
    /// 1. `first`'s row is appended to `remeasured.csv` (with the measurement file's
    ///    header when the file is new) and synced: it is never lost;
    /// 2. the measurement file is written anew beside (`measurements.csv.tmp`, locked,
    ///    synced) with `again`'s row in `first`'s place and renamed over the old one, so
    ///    that it holds either the one or the other, whole;
    /// 3. the manifest lists `record` under `remeasured`.
    ///
    /// # Errors
    ///
    /// [`RunError::Io`] naming the file that could not be written (the measurement file
    /// is then the one before); [`RunError::Closed`] after an [`AbortHandle::abort`].
    pub(super) fn replace_reading(
        &mut self,
        first: &Reading,
        again: &Reading,
        record: super::Remeasured,
    ) -> Result<(), RunError> {
        let path = self.dir.join(MEASUREMENTS);
        let record_path = self.dir.join(REMEASURED);
        {
            let on_disk = abort::lock(&self.shared);
            if on_disk.closed {
                return Err(RunError::Closed { path });
            }
            let mut kept = LineFile::open(&record_path, false, &self.budget)
                .map_err(io_error(&record_path))?;
            let mut lines = String::new();
            if kept.file().metadata().map(|m| m.len()).unwrap_or(0) == 0 {
                lines.push_str(&self.measurements.columns().header());
                lines.push('\n');
            }
            lines.push_str(&self.row(first));
            lines.push('\n');
            kept.append_line(lines.as_bytes())
                .and_then(|()| kept.sync_data())
                .map_err(io_error(&record_path))?;

            let text = fs::read_to_string(&path).map_err(io_error(&path))?;
            let key = format!("{},{},{},", first.cycle, first.step, first.ac);
            let mut found = false;
            let mut rewritten = String::with_capacity(text.len() + 64);
            for line in text.lines() {
                if !found && line.starts_with(&key) {
                    found = true;
                    rewritten.push_str(&self.row(again));
                } else {
                    rewritten.push_str(line);
                }
                rewritten.push('\n');
            }
            if !found {
                return Err(io_error(&path)(io::Error::other(format!(
                    "no row of cycle {}, step {}, autocollimator {} to replace",
                    first.cycle, first.step, first.ac
                ))));
            }
            let tmp = self.dir.join(format!("{MEASUREMENTS}.tmp"));
            let _ = fs::remove_file(&tmp);
            let mut file = LineFile::open(&tmp, true, &self.budget).map_err(io_error(&path))?;
            lock_exclusive(file.file(), &path)?;
            let written = file
                .append_line(rewritten.as_bytes())
                .and_then(|()| file.file().sync_all())
                .and_then(|()| fs::rename(&tmp, &path));
            if let Err(e) = written {
                drop(file);
                let _ = fs::remove_file(&tmp);
                return Err(io_error(&path)(e));
            }
            if let Ok(d) = File::open(&self.dir) {
                let _ = d.sync_all();
            }
            file.renamed(path.clone());
            let columns = self.measurements.columns().clone();
            // The old file's lock goes with its handle; the new one is locked already.
            self.measurements = ReadingWriter::resume(file, columns);
        }
        self.manifest.remeasured.push(record);
        self.write_manifest(false)
    }

    /// Lists `suspect` in the manifest.
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub(super) fn record_suspect(&mut self, suspect: super::Suspect) -> Result<(), RunError> {
        self.manifest.suspect.push(suspect);
        self.write_manifest(false)
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
    /// [`RunError::Io`] when the manifest cannot be written (the manifest on disk is
    /// the one before); [`RunError::Closed`] after an [`AbortHandle::abort`].
    pub fn finish(&mut self, outcome: &Outcome) -> Result<(), RunError> {
        self.open_session();
        self.manifest
            .end_session(&outcome.to_string(), self.done.len());
        self.write_manifest(true)
    }

    /// Replaces the manifest atomically (written beside, synced, renamed); `ends`: it
    /// records the end of this session.
    pub(super) fn write_manifest(&mut self, ends: bool) -> Result<(), RunError> {
        self.manifest.readings = self.done.len();
        let mut on_disk = abort::lock(&self.shared);
        if on_disk.closed {
            return Err(RunError::Closed {
                path: self.dir.join(MANIFEST),
            });
        }
        self.manifest.write_to(&self.dir, &self.budget)?;
        on_disk.manifest = self.manifest.clone();
        on_disk.session_in_manifest = self.session_open;
        on_disk.ended = ends;
        Ok(())
    }
}

/// A new run in `dir` that could not start (`error`): removes the measurement file it
/// created (`created`) and the directory if it made it (`made_dir`) and nothing else is
/// in it. An I/O failure becomes [`RunError::NotStarted`], naming what could not be
/// removed.
fn not_started(dir: &Path, made_dir: bool, created: Option<&Path>, error: RunError) -> RunError {
    let mut left = Vec::new();
    if let Some(path) = created
        && let Err(e) = fs::remove_file(path)
        && e.kind() != io::ErrorKind::NotFound
    {
        left.push(path.to_path_buf());
    }
    if made_dir && left.is_empty() {
        // Only an empty directory is removed: anything else in it is not this run's.
        let _ = fs::remove_dir(dir);
    }
    match error {
        RunError::Io { path, source } => RunError::NotStarted { path, source, left },
        other => other,
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

/// Writes `comments` and the header to the measurement file `file`, which holds no
/// header yet, syncs them, and returns the writer for the readings. When that fails, the
/// file is cut back to what it held.
pub(super) fn start_file(
    mut file: LineFile,
    comments: &[String],
) -> Result<ReadingWriter<LineFile>, RunError> {
    let columns = Columns::new(COLUMNS);
    let started = ReadingWriter::start(&mut file, columns.clone(), comments)
        .map(drop)
        .and_then(|()| file.sync_data());
    if let Err(e) = started {
        let _ = file.rollback();
        return Err(io_error(file.path())(e));
    }
    file.commit();
    Ok(ReadingWriter::resume(file, columns))
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
