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
pub(super) use super::store::{Key, key};
use super::{
    Identification, MANIFEST_FORMAT, Manifest, Mounting, MountingRecord, Outcome, Ports, RunError,
    RunSettings, rfc3339, unix_now,
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
/// `cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift`.
pub const COLUMNS: [Column; 11] = [
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
    Column::SHIFT,
];

/// The columns of a run started before the `shift` column ([`COLUMNS`] without it): a
/// run that has them is resumed with them, in its one mounting or in further unshifted
/// ones.
pub(super) fn columns_without_shift() -> Columns {
    Columns::new(&COLUMNS[..COLUMNS.len() - 1])
}

/// A run directory opened for measuring: its manifest, the readings on disk and the
/// measurement file open for appending.
#[derive(Debug)]
pub struct RunDir {
    pub(super) dir: PathBuf,
    pub(super) manifest: Manifest,
    pub(super) measurements: ReadingWriter<LineFile>,
    /// The mounting this session measures (the manifest's last).
    pub(super) mounting: Mounting,
    pub(super) done: BTreeSet<Key>,
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
        RunDir::open_mounting(dir, settings, ports, None, resume, budget)
    }

    /// As [`RunDir::open_with_budget`], in a given mounting of the polygon
    /// (docs/FORMAT.md §7.3, *Several mountings*); `None`: the first for a new run, the
    /// last one the manifest lists for a resumed run.
    ///
    /// A mounting after the first continues the run in `dir` (whether `resume` is set or
    /// not): it is the manifest's last mounting again (the same shift and face shift:
    /// its readings go on; with none on disk yet, it may be restated), or the next one
    /// when the last is complete, which then awaits the operator's remount
    /// ([`RunDir::awaits_remount`]). The first mounting starts a new run unless `resume`.
    ///
    /// # Errors
    ///
    /// As [`RunDir::open`]; a mounting out of range ([`RunError::Settings`]), for a run
    /// with none ([`RunError::NoRunForMounting`]), other than the run recorded
    /// ([`RunError::OtherMounting`]), already complete ([`RunError::MountingDone`]), out
    /// of order ([`RunError::MountingOrder`]), after one not complete
    /// ([`RunError::MountingIncomplete`]), or shifted in a run whose file has no `shift`
    /// column ([`RunError::NoShiftColumn`]).
    pub fn open_mounting(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        mounting: Option<Mounting>,
        resume: bool,
        budget: &WriteBudget,
    ) -> Result<RunDir, RunError> {
        let refused = |error| RunError::Settings {
            path: dir.to_path_buf(),
            error,
        };
        settings.validate().map_err(refused)?;
        if let Some(m) = &mounting {
            m.validate(settings).map_err(refused)?;
        }
        if fs::metadata(dir).is_ok_and(|m| !m.is_dir()) {
            return Err(RunError::NotADirectory {
                path: dir.to_path_buf(),
            });
        }
        if resume || mounting.is_some_and(|m| m.setup > 1) {
            RunDir::resume(dir, settings, ports, mounting, budget)
        } else {
            RunDir::create(dir, settings, ports, mounting.unwrap_or_default(), budget)
        }
    }

    /// A run directory of `manifest`, with the measurement file open after its header.
    pub(super) fn assemble(
        dir: &Path,
        manifest: Manifest,
        measurements: ReadingWriter<LineFile>,
        done: BTreeSet<Key>,
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
        let mounting = manifest
            .mountings
            .last()
            .map_or_else(Mounting::default, |m| m.mounting);
        RunDir {
            dir: dir.to_path_buf(),
            manifest,
            measurements,
            mounting,
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
        mounting: Mounting,
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
            mountings: vec![MountingRecord::new(mounting)],
            checked_cycles: Some(Vec::new()),
            repeat_noise: Vec::new(),
            profiles: None,
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

    /// The mounting this session measures.
    pub fn mounting(&self) -> Mounting {
        self.mounting
    }

    /// Whether the polygon is still to be remounted for this session's mounting, and the
    /// remount confirmed ([`RunDir::confirm_remount`]) before it is measured.
    pub fn awaits_remount(&self) -> bool {
        self.manifest
            .mountings
            .last()
            .is_some_and(MountingRecord::awaits_remount)
    }

    /// Records that the operator confirmed the remount, the table reporting `table_deg`.
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub fn confirm_remount(&mut self, table_deg: f64) -> Result<(), RunError> {
        if let Some(last) = self.manifest.mountings.last_mut() {
            last.confirmed = Some(rfc3339(unix_now()));
            last.table_deg = Some(table_deg);
        }
        self.write_manifest(false)
    }

    /// Withdraws the confirmation of this session's mounting's remount (its first stop
    /// showed the polygon not mounted as stated): the next session asks for it again.
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub(super) fn withdraw_remount(&mut self) -> Result<(), RunError> {
        match self.manifest.mountings.last_mut() {
            Some(last) if last.mounting.setup > 1 && last.confirmed.is_some() => {
                last.confirmed = None;
                last.table_deg = None;
                self.write_manifest(false)
            }
            _ => Ok(()),
        }
    }

    /// Records that the readings of this session's mounting do not fit those of the
    /// mountings before it (`warning`).
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub(super) fn record_misfit(&mut self, warning: &str) -> Result<(), RunError> {
        if let Some(last) = self.manifest.mountings.last_mut() {
            last.misfit = Some(warning.to_string());
        }
        self.write_manifest(false)
    }

    /// The latest cycle of this session's mounting whose readings are all on disk, when
    /// its check after the cycle was not done (the session before ended first).
    pub fn unchecked_cycle(&self) -> Option<u32> {
        super::store::unchecked_cycle(
            &self.manifest.settings,
            self.mounting.setup,
            &self.done,
            self.manifest.checked_cycles.as_deref(),
        )
    }

    /// Whether this session's mounting is complete: every reading on disk and the check
    /// after its last cycle done.
    pub fn is_complete(&self) -> bool {
        self.remaining().is_empty() && self.unchecked_cycle().is_none()
    }

    /// Records that the check after `cycle` of this session's mounting was done.
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub(super) fn record_checked(&mut self, cycle: u32) -> Result<(), RunError> {
        let key = (self.mounting.setup, cycle);
        if let Some(checked) = self.manifest.checked_cycles.as_mut()
            && !checked.contains(&key)
        {
            checked.push(key);
            return self.write_manifest(false);
        }
        Ok(())
    }

    /// Whether the run holds readings to look at again: measured again, suspect, or of a
    /// mounting that did not fit the mountings before it.
    pub fn has_doubts(&self) -> bool {
        !self.manifest.remeasured.is_empty()
            || !self.manifest.suspect.is_empty()
            || self.manifest.mountings.iter().any(|m| m.misfit.is_some())
    }

    /// The stops of this session's mounting still to visit, each with the
    /// autocollimators still to read there, in order.
    pub fn remaining(&self) -> Vec<(Stop, Vec<u32>)> {
        super::store::remaining(&self.manifest.settings, self.mounting.setup, &self.done)
    }

    /// The shift of mounting `setup`, degrees (0 for one the run does not have).
    fn shift_of(&self, setup: u32) -> f64 {
        self.manifest
            .mountings
            .iter()
            .find(|m| m.mounting.setup == setup)
            .map_or(0.0, |m| m.mounting.shift_deg)
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

    /// The profiles the run speaks with its instruments, as the manifest records them
    /// (`None` until a session recorded them, and for older runs).
    pub fn profiles(&self) -> Option<&super::RunProfiles> {
        self.manifest.profiles.as_ref()
    }

    /// Records the profiles this session speaks with its instruments; a run that
    /// recorded others refuses them (docs/FORMAT.md §7.5): a resumed run speaks the
    /// protocols it started with.
    ///
    /// # Errors
    ///
    /// [`RunError::OtherProfile`] for a profile of another name,
    /// [`RunError::ProfileChanged`] for one whose text changed since it was recorded,
    /// [`RunError::Io`] when the manifest cannot be written.
    pub fn record_profiles(&mut self, profiles: super::RunProfiles) -> Result<(), RunError> {
        let path = self.dir.join(MANIFEST);
        match &self.manifest.profiles {
            None => {
                self.manifest.profiles = Some(profiles);
                self.write_manifest(false)
            }
            Some(recorded) => {
                let pairs = [
                    ("autocollimators", &recorded.ac, &profiles.ac),
                    ("table", &recorded.table, &profiles.table),
                ];
                for (role, was, now) in pairs {
                    if was.name != now.name {
                        return Err(RunError::OtherProfile {
                            path,
                            role,
                            recorded: was.name.clone(),
                            given: now.name.clone(),
                        });
                    }
                    if was.sha256 != now.sha256 {
                        return Err(RunError::ProfileChanged {
                            path,
                            role,
                            name: was.name.clone(),
                            recorded: was.sha256.clone(),
                            now: now.sha256.clone(),
                        });
                    }
                }
                Ok(())
            }
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
                let (a, b) = (
                    before.ac(ac).map(String::as_str),
                    identification.ac(ac).map(String::as_str),
                );
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
        let shift_deg = self.shift_of(reading.setup);
        let written = self
            .measurements
            .write_with_shift(reading, shift_deg)
            .and_then(|()| self.measurements.get_ref().sync_data());
        if let Err(e) = written {
            // The write's error is the one to tell; a cut line left behind (the file
            // could not be cut back) is removed by a resumed run.
            let _ = self.measurements.get_mut().rollback();
            return Err(io_error(&path)(e));
        }
        self.measurements.get_mut().commit();
        self.done.insert(key(reading));
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
            // The row of `first`'s place: its cycle, step and autocollimator first, its
            // setup where the columns have it.
            let place = [
                first.cycle.to_string(),
                first.step.to_string(),
                first.ac.to_string(),
            ];
            let setup_field = self
                .measurements
                .columns()
                .as_slice()
                .iter()
                .position(|c| *c == Column::SETUP);
            let is_first = |line: &str| {
                let fields: Vec<&str> = line.split(',').collect();
                fields.len() == self.measurements.columns().as_slice().len()
                    && fields[..3] == place
                    && setup_field.is_none_or(|i| fields[i] == first.setup.to_string())
            };
            let mut found = false;
            let mut rewritten = String::with_capacity(text.len() + 64);
            for line in text.lines() {
                if !found && !line.starts_with('#') && is_first(line) {
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

    /// Records the noise each autocollimator's readings were judged by
    /// (`repeat_noise`), autocollimator 1 first.
    ///
    /// # Errors
    ///
    /// As [`RunDir::finish`].
    pub(super) fn record_noise(&mut self, noise: &[super::RepeatNoise]) -> Result<(), RunError> {
        let session = self.manifest.sessions.len().max(1);
        let stated = self.manifest.settings.reading_noise_arcsec;
        self.manifest.repeat_noise = noise
            .iter()
            .zip(1..)
            .map(|(n, ac)| super::NoiseRecord::of(ac, session, n, stated))
            .collect();
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
        self.measurements
            .columns()
            .row_with_shift(reading, self.shift_of(reading.setup))
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
            "cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift"
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
            "2,8,2,1,-0.12345678901234566,ccw,12.5,1,,360,0"
        );
        reading.reading_y_arcsec = Some(1e-7);
        reading.direction = Direction::Cw;
        assert_eq!(
            columns.row_with_shift(&reading, 22.5),
            "2,8,2,1,-0.12345678901234566,cw,12.5,1,0.0000001,360,22.5"
        );
    }
}
