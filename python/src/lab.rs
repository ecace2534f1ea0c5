//! `polycal.Session`: the run's session (`polycal::lab::Session`, docs/FORMAT.md §7.6)
//! with the run directory as its store, for a Python driver that owns its instruments.
//! The rules are the library's; this file only carries the actions the run directory
//! does (keep a record, log a line) out with the library's own code, as `polycal run`'s
//! driver does (`src/lab/run/measure.rs`), and hands the others to Python as
//! [`PyAction`]s. Every time told to the session is the run clock's.

use std::collections::BTreeMap;
use std::path::PathBuf;

use polycal::lab::run::{Identification, Ports, RunDir, RunSettings, Store};
use polycal::lab::traffic::TrafficLog;
use polycal::lab::{AcReading, Action, Event, InstrumentError, Outcome, Session};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::refusal;

/// What the session asks the driver to do next (`Session.poll()`): `kind` says what, and
/// the fields of that kind are set (the others are `None`).
#[pyclass(name = "Action", module = "polycal", frozen)]
#[derive(Debug, Clone, Default)]
pub struct PyAction {
    /// `move`, `position`, `read`, `wait`, `remount`, `progress`, `halt` or `finished`.
    #[pyo3(get)]
    kind: String,
    /// `move`: the target, degrees (the closing step is 360°).
    #[pyo3(get)]
    to_deg: Option<f64>,
    /// `read`: the autocollimator, 1 … K.
    #[pyo3(get)]
    ac: Option<u32>,
    /// `wait`: until the run clock (`Session.now()`) reads this, seconds.
    #[pyo3(get)]
    until_seconds: Option<f64>,
    /// `remount`: the mounting, as `mounting 2 (shift 22.5°, turned 3 faces)`.
    #[pyo3(get)]
    mounting: Option<String>,
    /// `remount`: the mounting's number (the `setup` column).
    #[pyo3(get)]
    setup: Option<u32>,
    /// `remount`: the position the table reports, degrees (the mounting's step 0).
    #[pyo3(get)]
    table_deg: Option<f64>,
    /// `remount`: the face each autocollimator is to face, (autocollimator, face) pairs.
    #[pyo3(get)]
    faces: Option<Vec<(u32, usize)>>,
    /// `progress`: readings kept, and of the whole run.
    #[pyo3(get)]
    done: Option<usize>,
    #[pyo3(get)]
    total: Option<usize>,
    /// `progress`: the cycle and the number of cycles.
    #[pyo3(get)]
    cycle: Option<(u32, u32)>,
    /// `progress`: the stop within the cycle (1-based) and the stops per cycle.
    #[pyo3(get)]
    stop: Option<(usize, usize)>,
    /// `progress`: the step (0 … N).
    #[pyo3(get)]
    step: Option<usize>,
    /// `progress`: estimated seconds until the run is complete (once a reading was taken).
    #[pyo3(get)]
    seconds_left: Option<f64>,
    /// `progress`: replies refused in this session.
    #[pyo3(get)]
    refused: Option<usize>,
    /// `progress`: at the end of a cycle, what its check found, as JSON text.
    cycle_check: Option<String>,
    /// `finished`: how the session ended, as the manifest writes it: `completed`,
    /// `interrupted`, `instrument-error: …` or `file-error: …`.
    #[pyo3(get)]
    outcome: Option<String>,
}

#[pymethods]
impl PyAction {
    /// `progress`: at the end of a cycle, what its check of the run so far found (a dict:
    /// `setup`, `cycle`, `closure_arcsec`, `residual_rms_arcsec`, `sigma_arcsec`,
    /// `remeasured`, `suspect`, `warnings`, …); `None` after a reading.
    #[getter]
    fn cycle_check(&self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        match &self.cycle_check {
            Some(text) => Ok(Some(
                py.import("json")?.call_method1("loads", (text,))?.unbind(),
            )),
            None => Ok(None),
        }
    }

    fn __repr__(&self) -> String {
        let mut fields = vec![format!("kind={:?}", self.kind)];
        let mut show = |name: &str, value: Option<String>| {
            if let Some(v) = value {
                fields.push(format!("{name}={v}"));
            }
        };
        show("to_deg", self.to_deg.map(|v| v.to_string()));
        show("ac", self.ac.map(|v| v.to_string()));
        show("until_seconds", self.until_seconds.map(|v| v.to_string()));
        show("mounting", self.mounting.as_ref().map(|v| format!("{v:?}")));
        show("table_deg", self.table_deg.map(|v| v.to_string()));
        show("faces", self.faces.as_ref().map(|v| format!("{v:?}")));
        show("done", self.done.map(|v| v.to_string()));
        show("total", self.total.map(|v| v.to_string()));
        show("cycle", self.cycle.map(|v| format!("{v:?}")));
        show("stop", self.stop.map(|v| format!("{v:?}")));
        show("outcome", self.outcome.as_ref().map(|v| format!("{v:?}")));
        format!("Action({})", fields.join(", "))
    }
}

impl PyAction {
    fn of(kind: &str) -> PyAction {
        PyAction {
            kind: kind.to_string(),
            ..PyAction::default()
        }
    }

    /// The Python form of an action the driver carries out (not `Keep` or `Log`).
    fn from_action(action: &Action) -> PyResult<PyAction> {
        Ok(match action {
            Action::Move { to_deg } => PyAction {
                to_deg: Some(*to_deg),
                ..PyAction::of("move")
            },
            Action::Position => PyAction::of("position"),
            Action::Read { ac } => PyAction {
                ac: Some(*ac),
                ..PyAction::of("read")
            },
            Action::Wait { until_seconds } => PyAction {
                until_seconds: Some(*until_seconds),
                ..PyAction::of("wait")
            },
            Action::Remount(r) => PyAction {
                mounting: Some(r.mounting.to_string()),
                setup: Some(r.mounting.setup),
                table_deg: Some(r.table_deg),
                faces: Some(r.faces.clone()),
                ..PyAction::of("remount")
            },
            Action::Progress(p) => PyAction {
                done: Some(p.done),
                total: Some(p.total),
                cycle: Some(p.cycle),
                stop: Some(p.stop),
                step: Some(p.step),
                seconds_left: p.seconds_left,
                refused: Some(p.refused),
                cycle_check: p.cycle_check.as_ref().map(crate::to_json).transpose()?,
                ..PyAction::of("progress")
            },
            Action::Halt => PyAction::of("halt"),
            Action::Finished(outcome) => finished(outcome),
            // Kept and logged inside; a kind this version does not know ends nothing.
            other => PyAction::of(&format!("{other:?}")),
        })
    }
}

fn finished(outcome: &Outcome) -> PyAction {
    PyAction {
        outcome: Some(outcome.to_string()),
        ..PyAction::of("finished")
    }
}

/// The session of a run kept in a run directory, driven from Python.
#[pyclass(name = "Session", module = "polycal")]
pub struct PySession {
    /// The run directory, until `finish()` releases it.
    run: Option<RunDir>,
    /// Its traffic log.
    log: Option<TrafficLog>,
    /// The instruments' ports (or names) in messages and the traffic log.
    names: Ports,
    /// The session, once begun.
    session: Option<Session>,
    /// An end before the session could be built (the manifest or the log failed).
    ended: Option<Outcome>,
    /// The outcome `finish()` recorded.
    recorded: Option<String>,
    /// The port of the instrument the action last given asks (for `failed`).
    asked_port: String,
    /// The readings on disk when `finish()` closed the run directory.
    readings_at_finish: usize,
}

/// The settings of a run, as `polycal run` takes them.
#[allow(clippy::too_many_arguments)]
fn settings(
    faces: usize,
    cycles: u32,
    closing: bool,
    bidirectional: bool,
    ac_faces: Option<Vec<usize>>,
    reads_per_stop: Option<u32>,
    reading_noise_arcsec: Option<f64>,
    settle_seconds: f64,
) -> RunSettings {
    let mut s = RunSettings::new(faces, cycles)
        .with_closing(closing)
        .with_bidirectional(bidirectional)
        .with_settle_seconds(settle_seconds);
    if let Some(ac_faces) = ac_faces {
        s = s.with_ac_faces(ac_faces);
    }
    if let Some(reads) = reads_per_stop {
        s = s.with_reads_per_stop(reads);
    }
    if let Some(noise) = reading_noise_arcsec {
        s = s.with_reading_noise_arcsec(noise);
    }
    s
}

/// The ports of a dict `{"ac1": …, "ac2": …, "table": …}`, read as the manifest's
/// `ports` object is; none given, none recorded.
fn ports(given: Option<BTreeMap<String, String>>, k: usize) -> PyResult<Ports> {
    let Some(given) = given else {
        return Ok(Ports::default());
    };
    let json = serde_json::to_value(&given).map_err(refusal)?;
    let ports: Ports =
        serde_json::from_value(json).map_err(|e| PyValueError::new_err(format!("ports: {e}")))?;
    if ports.autocollimators.len() != k {
        return Err(PyValueError::new_err(format!(
            "ports: {} autocollimator port(s) given (ac1 … acK) for the {k} autocollimators of the run",
            ports.autocollimators.len()
        )));
    }
    Ok(ports)
}

impl PySession {
    fn run(&mut self) -> PyResult<&mut RunDir> {
        self.run
            .as_mut()
            .ok_or_else(|| refusal("the session is finished: its run directory is closed"))
    }

    fn clock_now(&self) -> f64 {
        self.run.as_ref().map_or(0.0, |r| r.clock().now())
    }

    /// Tells `event` to the session, at the run clock's time.
    fn tell(&mut self, event: Event) -> PyResult<()> {
        let now = self.clock_now();
        let session = self
            .session
            .as_mut()
            .ok_or_else(|| refusal("the session has not begun: call begin() first"))?;
        session.tell(now, event).map_err(refusal)
    }
}

#[pymethods]
impl PySession {
    /// Opens the run directory `dir` for a new run (`resume=False`: the directory must
    /// hold none) or to continue one (`resume=True`: the same settings), with the same
    /// files as `polycal run` (measurements.csv, manifest.json, traffic.jsonl), and its
    /// traffic log. `ports` maps `ac1` … `acK` and `table` to the instruments' ports (or
    /// names), recorded in the manifest and named in messages. Refusals raise
    /// `PolycalError` with the library's message.
    #[new]
    #[pyo3(signature = (dir, *, faces, cycles, closing=false, bidirectional=false, ac_faces=None, reads_per_stop=None, reading_noise_arcsec=None, settle_seconds=0.0, resume=false, ports=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        dir: PathBuf,
        faces: usize,
        cycles: u32,
        closing: bool,
        bidirectional: bool,
        ac_faces: Option<Vec<usize>>,
        reads_per_stop: Option<u32>,
        reading_noise_arcsec: Option<f64>,
        settle_seconds: f64,
        resume: bool,
        ports: Option<BTreeMap<String, String>>,
    ) -> PyResult<PySession> {
        let settings = settings(
            faces,
            cycles,
            closing,
            bidirectional,
            ac_faces,
            reads_per_stop,
            reading_noise_arcsec,
            settle_seconds,
        );
        let k = settings.autocollimators();
        let ports = self::ports(ports, k)?;
        let run = RunDir::open(&dir, &settings, &ports, resume).map_err(refusal)?;
        // The names in messages and the log: the ports, else `ac1` … and `table`.
        let names = if ports.autocollimators.is_empty() {
            Ports::new((1..=k).map(|ac| format!("ac{ac}")), "table")
        } else {
            ports
        };
        let log = run.traffic_log().map_err(refusal)?;
        log.record(
            "",
            "",
            "session",
            &format!(
                "polycal {} Session (Python){} {} {}",
                polycal::output::SOFTWARE_VERSION,
                if resume { " --resume" } else { "" },
                settings.as_options(),
                run.mounting().as_options()
            ),
        );
        Ok(PySession {
            run: Some(run),
            log: Some(log),
            names,
            session: None,
            ended: None,
            recorded: None,
            asked_port: String::new(),
            readings_at_finish: 0,
        })
    }

    /// The run directory.
    #[getter]
    fn dir(&self) -> Option<PathBuf> {
        self.run.as_ref().map(|r| r.dir().to_path_buf())
    }

    /// Warnings found when the directory was opened (a line cut short removed).
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.run
            .as_ref()
            .map_or_else(Vec::new, |r| r.warnings().to_vec())
    }

    /// Readings in the measurement file (when the session was finished, once it is).
    #[getter]
    fn readings_done(&self) -> usize {
        self.run
            .as_ref()
            .map_or(self.readings_at_finish, RunDir::readings_done)
    }

    /// Replies taken in this session and not kept (stale, or not agreeing at their stop).
    #[getter]
    fn refused(&self) -> usize {
        self.session.as_ref().map_or(0, Session::refused)
    }

    /// The run clock: seconds since the run started (the `time` of a reading).
    fn now(&self) -> f64 {
        self.clock_now()
    }

    /// Records the instruments' identifications in the manifest (autocollimator 1 first,
    /// then the table) and begins the session from the run as the directory holds it. A
    /// resumed run refuses other instruments than it started with (`PolycalError`,
    /// nothing measured).
    fn begin(
        &mut self,
        ac_identifications: Vec<String>,
        table_identification: String,
    ) -> PyResult<()> {
        if self.session.is_some() {
            return Err(refusal("the session has begun already"));
        }
        if let Some(outcome) = &self.ended {
            return Err(refusal(format!("the session has ended: {outcome}")));
        }
        let names: Vec<String> = self.names.autocollimators.clone();
        let table_name = self.names.table.clone();
        let log = self.log.clone();
        let run = self.run()?;
        let k = run.manifest().settings.autocollimators();
        if ac_identifications.len() != k {
            return Err(PyValueError::new_err(format!(
                "ac_identifications: {} given for the {k} autocollimators of the run",
                ac_identifications.len()
            )));
        }
        let identification = Identification::new(ac_identifications, table_identification);
        if let Err(e) = run.begin_session(identification) {
            if e.is_refusal() {
                return Err(refusal(e));
            }
            self.ended = Some(Outcome::FileError(e.to_string()));
            return Ok(());
        }
        if let Some(failed) = log.as_ref().and_then(|l| run.traffic_failure(l, false)) {
            self.ended = Some(Outcome::FileError(failed));
            return Ok(());
        }
        match run.so_far() {
            Ok(mut so_far) => {
                // Messages and the log name the ports given now.
                so_far.ac_names = names;
                so_far.table_name = table_name;
                let now = run.clock().now();
                self.session = Some(Session::new(so_far, now));
            }
            Err(e) => self.ended = Some(Outcome::FileError(e.to_string())),
        }
        Ok(())
    }

    /// The next action for the driver to carry out: `move` (answer with `moved`),
    /// `position` (`position`), `read` (`read`), `wait` (`waited`), `remount`
    /// (`remounted`), or, not answered, `progress`, `halt` (stop the table) and
    /// `finished` (from then on, every time). An answered action is given again until
    /// it is answered. The records are kept in the run directory and the log lines go to
    /// its traffic log here; the traffic log is put on disk before every `move`.
    fn poll(&mut self) -> PyResult<PyAction> {
        if let Some(outcome) = &self.ended {
            return Ok(finished(outcome));
        }
        let log = self.log.clone();
        let Some(run) = self.run.as_mut() else {
            return Err(refusal(
                "the session is finished: its run directory is closed",
            ));
        };
        let session = self
            .session
            .as_mut()
            .ok_or_else(|| refusal("the session has not begun: call begin() first"))?;
        let action = loop {
            let action = session.poll();
            match &action {
                Action::Keep(record) => {
                    let event = match run.keep_logged(record, log.as_ref()) {
                        Ok(()) => Event::Kept,
                        Err(e) => Event::NotKept(e.to_string()),
                    };
                    session.tell(run.clock().now(), event).map_err(refusal)?;
                }
                Action::Log(line) => {
                    if let Some(log) = &log {
                        log.record(&line.device, &line.port, &line.event, &line.text);
                    }
                }
                Action::Move { .. } => {
                    // Everything on disk before the table moves.
                    match log.as_ref().and_then(|l| run.traffic_failure(l, true)) {
                        Some(failed) => session.file_failed(failed),
                        None => break action,
                    }
                }
                _ => break action,
            }
        };
        self.asked_port = match &action {
            Action::Read { ac } => self.names.ac(*ac).cloned().unwrap_or_default(),
            _ => self.names.table.clone(),
        };
        PyAction::from_action(&action)
    }

    /// The table reached the target of `move`, reporting `at_deg`, degrees. (The lines
    /// of the move are to be in the traffic log already: a log that failed ends the
    /// session with `file-error`.)
    fn moved(&mut self, at_deg: f64) -> PyResult<()> {
        let failed = match (&self.run, &self.log) {
            (Some(run), Some(log)) => run.traffic_failure(log, false),
            _ => None,
        };
        if let Some(failed) = failed {
            if let Some(session) = self.session.as_mut() {
                session.file_failed(failed);
            }
            return Ok(());
        }
        self.tell(Event::Moved { at_deg })
    }

    /// The table reports `deg`, degrees (the answer to `position`).
    fn position(&mut self, deg: f64) -> PyResult<()> {
        self.tell(Event::Position { deg })
    }

    /// The autocollimator's reply to `read`: its status (e.g. 3 for `003`), X and Y
    /// (`None` when Y is not valid), arcsec.
    #[pyo3(signature = (status, x_arcsec, y_arcsec=None))]
    fn read(&mut self, status: u16, x_arcsec: f64, y_arcsec: Option<f64>) -> PyResult<()> {
        if !x_arcsec.is_finite() || y_arcsec.is_some_and(|y| !y.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "read: X {x_arcsec} and Y {y_arcsec:?} must be finite numbers of arcseconds"
            )));
        }
        self.tell(Event::Read(AcReading::new(status, x_arcsec, y_arcsec)))
    }

    /// The wait of `wait` is over.
    fn waited(&mut self) -> PyResult<()> {
        self.tell(Event::Waited)
    }

    /// The operator's answer to `remount`: `True` once the polygon is mounted, `False`
    /// to end the session without measuring (`interrupted`).
    fn remounted(&mut self, confirmed: bool) -> PyResult<()> {
        self.tell(Event::Remounted { confirmed })
    }

    /// The instrument asked (`move`, `position` or `read`) failed: `message` says how.
    /// The session ends with `instrument-error: …` naming it and its port.
    fn failed(&mut self, message: String) -> PyResult<()> {
        if self.session.is_none() && self.ended.is_none() {
            // Before the session began (an instrument that could not be started).
            self.ended = Some(Outcome::InstrumentError(message));
            return Ok(());
        }
        let port = self.asked_port.clone();
        self.tell(Event::Failed(InstrumentError::Reported { port, message }))
    }

    /// Writes a line of the driver's own to the run's traffic log (traffic.jsonl):
    /// `device` `ac1` … `acK` or `table`, its `port`, `event` `sent` (the text exactly as
    /// written, terminator included), `received` (one reply line, terminator removed),
    /// `timeout`, `discarded`, `clear` or `error`, and the `text`.
    fn traffic(&self, device: &str, port: &str, event: &str, text: &str) -> PyResult<()> {
        let log = self
            .log
            .as_ref()
            .ok_or_else(|| refusal("the session is finished: its traffic log is closed"))?;
        log.record(device, port, event, text);
        Ok(())
    }

    /// Ends the session as `interrupted` (the next `poll` gives `halt`, then `finished`).
    fn interrupt(&mut self) {
        match self.session.as_mut() {
            Some(session) => session.interrupt(),
            None => {
                self.ended.get_or_insert(Outcome::Interrupted);
            }
        }
    }

    /// Records how the session ended in the manifest, puts the traffic log on disk,
    /// closes the run directory and returns the outcome: `completed`, `interrupted`,
    /// `instrument-error: …` or `file-error: …`. A session not over is ended as
    /// `interrupt()` ends it (stopping the table is then the driver's).
    fn finish(&mut self) -> PyResult<String> {
        if let Some(recorded) = &self.recorded {
            return Ok(recorded.clone());
        }
        let mut outcome = match (&self.ended, self.session.as_mut()) {
            (Some(outcome), _) => outcome.clone(),
            (None, Some(session)) => {
                session.interrupt();
                session.outcome().cloned().unwrap_or(Outcome::Interrupted)
            }
            (None, None) => Outcome::Interrupted,
        };
        let log = self.log.take();
        let run = self.run()?;
        if let Some(log) = &log
            && let Some(failed) = run.traffic_failure(log, true)
            && outcome == Outcome::Completed
        {
            outcome = Outcome::FileError(failed);
        }
        run.finish(&outcome).map_err(refusal)?;
        self.readings_at_finish = run.readings_done();
        self.run = None;
        let text = outcome.to_string();
        self.recorded = Some(text.clone());
        Ok(text)
    }
}
