//! The run's rules as a session that decides and does no input or output of its own
//! (docs/FORMAT.md §7, *The run's rules without the run's instruments*): it asks for
//! [`Action`]s — move the table, read an autocollimator, wait, ask for a remount, keep a
//! record — and is told [`Event`]s. Every rule of `polycal run` lives here: the approach
//! from the cycle's direction, readings until they agree and stale replies refused
//! (`repeat.rs`), the checks before the first reading (`verify.rs`), the remount, the
//! check after every cycle with its re-measurements (`live.rs`). `polycal run` drives a
//! session with its own ports and profiles ([`measure`](super::measure)); lab software
//! that owns its instruments drives the same session.
//!
//! The stages of a session are in `session/`: the visit of one stop
//! (`session/visit.rs`), the check after a cycle (`session/cycle.rs`) and the remount
//! (`session/remount.rs`).

use std::collections::VecDeque;
use std::fmt;

use super::live::{Cell, CycleCheck};
use super::mounting::{Mounting, Remount};
use super::repeat::DeviceMemory;
use super::store::{MemoryStore, Record, RunSoFar, Store};
use super::{RunSettings, verify};
use crate::lab::driver::POSITION_TOLERANCE_DEG;
use crate::lab::{AcReading, InstrumentError};
use crate::measurement::{Direction, Stop};

mod cycle;
mod remount;
mod visit;

use cycle::CycleChecking;
use remount::RemountStep;
use visit::{Purpose, Visit};

/// How a measuring session ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Every reading of the run is kept.
    Completed,
    /// Stopped on request (Ctrl-C).
    Interrupted,
    /// An instrument failed, or its readings were refused (the text says which and how).
    InstrumentError(String),
    /// A file of the run (or the caller's store) could not be written.
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
    pub fn from_instrument(role: &str, e: &InstrumentError) -> Outcome {
        if e.is_interrupted() {
            Outcome::Interrupted
        } else {
            Outcome::InstrumentError(format!("{role} at {e}"))
        }
    }
}

/// The table's name in messages.
pub(super) const TABLE: &str = "rotary table";

/// Autocollimator `ac`'s name in messages, `autocollimator 3`.
pub(super) fn role(ac: u32) -> String {
    format!("autocollimator {ac}")
}

/// Where a run is, for a progress display.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Progress {
    /// Readings kept.
    pub done: usize,
    /// The mounting measured (1 for a run of one).
    pub setup: u32,
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
    /// Readings taken in this session and not stored: refused (stale, not agreeing
    /// with the others at their stop) or beyond the agreeing ones.
    pub refused: usize,
    /// At the end of a cycle: what the check of the run so far found (docs/FORMAT.md
    /// §7.3, *Checked while it runs*), after any reading it measured again.
    pub cycle_check: Option<CycleCheck>,
}

/// A line for the run's traffic log (`traffic.jsonl`, docs/FORMAT.md §7.3): what the
/// rules decided, beside the lines the instruments sent and received.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct LogRecord {
    /// The instrument (`ac1`), or empty for the run.
    pub device: String,
    /// Its port, or empty.
    pub port: String,
    /// `refused`, `compared`, `remeasured` or `remounted`.
    pub event: String,
    /// What happened.
    pub text: String,
}

/// What a session asks its driver to do next ([`Session::poll`]).
///
/// The actions marked *answered* wait for their [`Event`] ([`Session::tell`]): until it
/// comes, [`Session::poll`] gives the same action again. The others are done when given.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Action {
    /// Answered by [`Event::Moved`]: move the table to `to_deg`, degrees, and say where it
    /// reports itself once there. Never send a move twice: after a lost reply, ask the
    /// controller's state and position instead.
    Move {
        /// The target, degrees (the closing step is 360°).
        to_deg: f64,
    },
    /// Answered by [`Event::Position`]: ask the table where it is.
    Position,
    /// Answered by [`Event::Read`]: one reading of autocollimator `ac` (1 … K), a reply to
    /// a query sent after pending input was drained.
    Read {
        /// The autocollimator, 1 … K.
        ac: u32,
    },
    /// Answered by [`Event::Waited`]: wait until the run's clock reads `until_seconds`
    /// (the table settling).
    Wait {
        /// Seconds since the run started.
        until_seconds: f64,
    },
    /// Answered by [`Event::Remounted`]: the polygon is to be remounted for
    /// `remount.mounting`, the table standing at the mounting's step 0.
    Remount(Remount),
    /// Answered by [`Event::Kept`] or [`Event::NotKept`]: keep this record ([`Store::keep`]).
    Keep(Record),
    /// Write this line to the traffic log (or wherever the driver logs).
    Log(LogRecord),
    /// Show where the run is.
    Progress(Progress),
    /// Stop the table (a session that does not complete ends so).
    Halt,
    /// The session is over; [`Session::poll`] gives this from now on.
    Finished(Outcome),
}

impl Action {
    /// Whether the session waits for an [`Event`] answering this action.
    pub fn is_answered(&self) -> bool {
        matches!(
            self,
            Action::Move { .. }
                | Action::Position
                | Action::Read { .. }
                | Action::Wait { .. }
                | Action::Remount(_)
                | Action::Keep(_)
        )
    }
}

/// What happened, told to a session ([`Session::tell`]).
#[derive(Debug)]
#[non_exhaustive]
pub enum Event {
    /// The table reached the target of [`Action::Move`], reporting this position,
    /// degrees.
    Moved {
        /// The position the table reports, degrees.
        at_deg: f64,
    },
    /// The table reports this position ([`Action::Position`]), degrees.
    Position {
        /// Degrees.
        deg: f64,
    },
    /// The autocollimator's reply to [`Action::Read`].
    Read(AcReading),
    /// The wait is over ([`Action::Wait`]).
    Waited,
    /// The operator's answer to [`Action::Remount`]: `true` once the polygon is mounted,
    /// `false` to end the session without measuring.
    Remounted {
        /// Whether to measure the new mounting.
        confirmed: bool,
    },
    /// The record of [`Action::Keep`] is kept.
    Kept,
    /// The record of [`Action::Keep`] could not be kept: why.
    NotKept(String),
    /// The instrument asked failed ([`Action::Move`], [`Action::Position`],
    /// [`Action::Read`]).
    Failed(InstrumentError),
}

/// A told event that does not answer the action asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
#[error("the session asked for {asked}, and was told {told}")]
pub struct SessionError {
    /// The action that waits for its answer (`nothing` when none does).
    pub asked: String,
    /// The event told.
    pub told: String,
}

/// Where the rules are.
#[derive(Debug, Clone)]
enum Step {
    /// Nothing done yet.
    Begin,
    /// The remount of a new mounting.
    Remount(RemountStep),
    /// A stop being visited.
    Visit(Box<Visit>),
    /// The check after a cycle.
    Check(Box<CycleChecking>),
    /// Records to keep, one at a time, then actions to give and where to go on.
    Keeping {
        records: VecDeque<Record>,
        notes: Vec<Action>,
        then: Box<Step>,
    },
    /// The next piece of work.
    NextWork,
    /// To end with this outcome.
    End(Outcome),
    /// Over.
    Over(Outcome),
}

/// One piece of a session's work, in order.
#[derive(Debug, Clone)]
enum Work {
    /// Visit the stop and read these autocollimators.
    Stop(Stop, Vec<u32>),
    /// The check after this cycle.
    Check(u32),
}

/// What a session asked and waits to be told.
#[derive(Debug, Clone)]
struct Asked {
    action: Action,
}

/// The rules of one session of a run: from a run as a store keeps it ([`RunSoFar`]) to
/// every reading of the mounting kept, asking its driver for each thing to do.
///
/// ```
/// use polycal::lab::run::{MemoryStore, RunSettings, RunSoFar};
/// use polycal::lab::{Action, AcReading, Event, Outcome, Session};
///
/// // A 4-face polygon, one cycle; instruments whose readings change with the table.
/// let settings = RunSettings::new(4, 1);
/// let mut session = Session::new(RunSoFar::new(settings), 0.0);
/// let mut kept = MemoryStore::new(session.settings().clone());
/// let (mut t, mut table_deg) = (0.0, 0.0);
/// let outcome = loop {
///     t += 0.5;
///     let event = match session.poll() {
///         Action::Move { to_deg } => {
///             table_deg = to_deg;
///             Event::Moved { at_deg: to_deg }
///         }
///         Action::Read { ac } => {
///             Event::Read(AcReading::new(3, table_deg / 100.0 + f64::from(ac), Some(0.0)))
///         }
///         Action::Wait { .. } => Event::Waited,
///         Action::Keep(record) => match polycal::lab::run::Store::keep(&mut kept, &record) {
///             Ok(()) => Event::Kept,
///             Err(e) => Event::NotKept(e.to_string()),
///         },
///         Action::Finished(outcome) => break outcome,
///         _ => continue, // logs, progress, a halt
///     };
///     session.tell(t, event)?;
/// };
/// assert_eq!(outcome, Outcome::Completed);
/// assert_eq!(kept.run.readings.len(), 4 * 2); // stops · autocollimators
/// assert_eq!(kept.run.readings[2].reading_arcsec, 0.9 + 1.0); // step 1 at 90°, ac 1
/// # Ok::<(), polycal::lab::SessionError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Session {
    /// The run as kept, updated with every record kept.
    kept: MemoryStore,
    settings: RunSettings,
    mounting: Mounting,
    memory: Vec<DeviceMemory>,
    work: VecDeque<Work>,
    readings_before: usize,
    started_seconds: f64,
    now_seconds: f64,
    /// Where the table was last sent, when known.
    commanded: Option<f64>,
    refused: usize,
    handled: Vec<Cell>,
    notes: VecDeque<Action>,
    asked: Option<Asked>,
    step: Step,
}

impl Session {
    /// A session of the run `so_far` (what its store holds: [`Store::so_far`]),
    /// starting at `now_seconds` on the run's clock (seconds since the run started).
    pub fn new(so_far: RunSoFar, now_seconds: f64) -> Session {
        let settings = so_far.settings.clone();
        let mounting = so_far.mounting();
        let memory = verify::carried_memory(&so_far);
        let mut work = VecDeque::new();
        if let Some(cycle) = so_far.unchecked_cycle() {
            // The session before ended before the check after this cycle: done now,
            // while the polygon is still mounted so.
            work.push_back(Work::Check(cycle));
        }
        let remaining = so_far.remaining();
        for (index, (stop, to_read)) in remaining.iter().enumerate() {
            work.push_back(Work::Stop(*stop, to_read.clone()));
            let cycle_ends = remaining
                .get(index + 1)
                .is_none_or(|(next, _)| next.cycle != stop.cycle);
            if cycle_ends {
                work.push_back(Work::Check(stop.cycle));
            }
        }
        let readings_before = so_far.readings.len();
        let mut kept = MemoryStore::new(settings.clone());
        kept.run = so_far;
        Session {
            kept,
            settings,
            mounting,
            memory,
            work,
            readings_before,
            started_seconds: now_seconds,
            now_seconds,
            commanded: None,
            refused: 0,
            handled: Vec::new(),
            notes: VecDeque::new(),
            asked: None,
            step: Step::Begin,
        }
    }

    /// The run's settings.
    pub fn settings(&self) -> &RunSettings {
        &self.settings
    }

    /// The mounting this session measures.
    pub fn mounting(&self) -> Mounting {
        self.mounting
    }

    /// The run as kept so far, with every record this session kept.
    pub fn so_far(&self) -> &RunSoFar {
        &self.kept.run
    }

    /// How the session ended, once it has.
    pub fn outcome(&self) -> Option<&Outcome> {
        match &self.step {
            Step::Over(outcome) => Some(outcome),
            _ => None,
        }
    }

    /// Readings taken in this session and not kept.
    pub fn refused(&self) -> usize {
        self.refused
    }

    /// The next thing to do. An answered action ([`Action::is_answered`]) is given again
    /// until its event is told; [`Action::Finished`] once the session is over.
    pub fn poll(&mut self) -> Action {
        loop {
            if let Some(note) = self.notes.pop_front() {
                return note;
            }
            if let Some(asked) = &self.asked {
                return asked.action.clone();
            }
            if let Step::Over(outcome) = &self.step {
                return Action::Finished(outcome.clone());
            }
            self.advance();
        }
    }

    /// Tells the session what happened to the action it asked, at `now_seconds` on the
    /// run's clock.
    ///
    /// # Errors
    ///
    /// [`SessionError`] when the event does not answer the action asked, or when it or
    /// `now_seconds` carries a number that is not finite (a NaN position, an infinite
    /// reading): the session is unchanged.
    pub fn tell(&mut self, now_seconds: f64, event: Event) -> Result<(), SessionError> {
        let Some(asked) = self.asked.take() else {
            return Err(unexpected("nothing", &event));
        };
        let answers = matches!(
            (&asked.action, &event),
            (Action::Move { .. }, Event::Moved { .. } | Event::Failed(_))
                | (Action::Position, Event::Position { .. } | Event::Failed(_))
                | (Action::Read { .. }, Event::Read(_) | Event::Failed(_))
                | (Action::Wait { .. }, Event::Waited)
                | (Action::Remount(_), Event::Remounted { .. })
                | (Action::Keep(_), Event::Kept | Event::NotKept(_))
        );
        if !answers {
            let asked_text = action_name(&asked.action);
            self.asked = Some(asked);
            return Err(unexpected(&asked_text, &event));
        }
        // A number that is not one is never taken: a NaN position would be stored as the
        // stop's encoder angle, a NaN time would stop every wait from ending.
        if let Some(what) = not_finite(now_seconds, &event) {
            let asked_text = action_name(&asked.action);
            self.asked = Some(asked);
            return Err(SessionError {
                asked: asked_text,
                told: format!("{event:?} at {now_seconds} s, whose {what} is not a finite number"),
            });
        }
        self.now_seconds = now_seconds;
        // A table that reports itself off the commanded angle has not stopped where the
        // readings would be stored: polycal's own drivers refuse such a move, and so does
        // the session for a driver of the lab's own.
        let event = match (&asked.action, event) {
            (Action::Move { to_deg }, Event::Moved { at_deg })
                if (at_deg - to_deg).abs() > POSITION_TOLERANCE_DEG =>
            {
                Event::Failed(InstrumentError::Reported {
                    port: self.kept.run.table_name.clone(),
                    message: format!(
                        "the table stopped at {at_deg}°, not at the commanded {to_deg}° (beyond {POSITION_TOLERANCE_DEG}°)"
                    ),
                })
            }
            (_, event) => event,
        };
        if let Action::Keep(record) = &asked.action {
            match event {
                Event::NotKept(why) => self.step = self.end(Outcome::FileError(why)),
                _ => self.kept_record(record),
            }
            return Ok(());
        }
        let step = std::mem::replace(&mut self.step, Step::NextWork);
        self.step = match step {
            Step::Remount(r) => self.remount_told(r, event),
            Step::Visit(v) => self.visit_told(*v, event),
            other => other,
        };
        Ok(())
    }

    /// Ends the session as interrupted (Ctrl-C): the table is to be stopped.
    pub fn interrupt(&mut self) {
        if !matches!(self.step, Step::Over(_)) {
            self.step = self.end(Outcome::Interrupted);
        }
    }

    /// Ends the session because a file of the driver's could not be written (its traffic
    /// log): `message` says which and why.
    pub fn file_failed(&mut self, message: impl Into<String>) {
        if !matches!(self.step, Step::Over(_)) {
            self.step = self.end(Outcome::FileError(message.into()));
        }
    }

    /// The step that ends the session with `outcome`: nothing asked any more, and the
    /// table halted unless it completed.
    fn end(&mut self, outcome: Outcome) -> Step {
        self.asked = None;
        if outcome != Outcome::Completed {
            self.notes.push_back(Action::Halt);
        }
        Step::Over(outcome)
    }

    /// Asks for `action` (answered) and stays at `step`.
    fn ask(&mut self, action: Action, step: Step) -> Step {
        self.asked = Some(Asked { action });
        step
    }

    /// Gives a note (an action not answered).
    fn note(&mut self, action: Action) {
        self.notes.push_back(action);
    }

    /// A line for the traffic log from the run.
    fn log(&mut self, event: &str, text: String) {
        self.note(Action::Log(LogRecord {
            device: String::new(),
            port: String::new(),
            event: event.to_string(),
            text,
        }));
    }

    /// Works out the next action from where the rules are.
    fn advance(&mut self) {
        let step = std::mem::replace(&mut self.step, Step::NextWork);
        self.step = match step {
            Step::Begin => self.begin(),
            Step::Remount(r) => self.remount_next(r),
            Step::Visit(v) => self.visit_next(*v),
            Step::Check(c) => self.check_next(*c),
            Step::Keeping {
                mut records,
                notes,
                then,
            } => match records.pop_front() {
                Some(record) => {
                    let action = Action::Keep(record);
                    self.ask(
                        action,
                        Step::Keeping {
                            records,
                            notes,
                            then,
                        },
                    )
                }
                None => {
                    self.notes.extend(notes);
                    *then
                }
            },
            Step::NextWork => self.next_work(),
            Step::End(outcome) => self.end(outcome),
            over @ Step::Over(_) => over,
        };
    }

    /// A record kept: the session's copy follows it, and a reading's progress is shown.
    fn kept_record(&mut self, record: &Record) {
        // The session's copy in memory cannot fail where the store did not.
        let _ = self.kept.keep(record);
        if let Record::Reading(r) = record {
            let stop = Stop {
                cycle: r.cycle,
                step: r.step,
                direction: r.direction,
            };
            let progress = self.progress(stop, None);
            self.note(Action::Progress(progress));
        }
    }

    /// The first step: the remount of a new mounting, or the checks before the first
    /// reading, then the work.
    fn begin(&mut self) -> Step {
        let so_far = &self.kept.run;
        let remaining = so_far.remaining();
        if so_far.awaits_remount() {
            return match remaining.first() {
                Some(&(stop, _)) => self.remount_next(RemountStep::Start { stop }),
                None => Step::NextWork,
            };
        }
        if remaining.is_empty() && so_far.unchecked_cycle().is_none() {
            return Step::NextWork;
        }
        if let Some(stop) = verify::last_stop(so_far) {
            return self.start_visit(Visit::new(
                Purpose::LastStop,
                stop,
                self.settings.acs().collect(),
            ));
        }
        if self.mounting.setup > 1
            && let Some(&(stop, _)) = remaining.first()
        {
            return self.start_visit(Visit::new(
                Purpose::NewMounting { remounted_at: None },
                stop,
                self.settings.acs().collect(),
            ));
        }
        Step::NextWork
    }

    /// The next piece of work, or the session completed.
    fn next_work(&mut self) -> Step {
        match self.work.pop_front() {
            Some(Work::Stop(stop, acs)) => {
                self.start_visit(Visit::new(Purpose::Measure, stop, acs))
            }
            Some(Work::Check(cycle)) => self.check_next(CycleChecking::new(cycle)),
            None => self.end(Outcome::Completed),
        }
    }

    /// Where the run is, at `stop`.
    fn progress(&self, stop: Stop, cycle_check: Option<CycleCheck>) -> Progress {
        let stops_per_cycle = self.settings.stops_per_cycle();
        let done = self.kept.run.readings.len();
        let total = self.kept.run.expected_readings();
        let this_session = done.saturating_sub(self.readings_before);
        let elapsed = self.now_seconds - self.started_seconds;
        let position = match stop.direction {
            Direction::Cw => stop.step + 1,
            Direction::Ccw => stops_per_cycle.saturating_sub(stop.step),
        };
        Progress {
            done,
            setup: self.mounting.setup,
            total,
            cycle: (stop.cycle, self.settings.cycles),
            stop: (position, stops_per_cycle),
            step: stop.step,
            seconds_left: (this_session > 0)
                .then(|| elapsed / this_session as f64 * total.saturating_sub(done) as f64),
            refused: self.refused,
            cycle_check,
        }
    }
}

/// The name of an action in a [`SessionError`].
fn action_name(action: &Action) -> String {
    match action {
        Action::Move { to_deg } => format!("a move to {to_deg}°"),
        Action::Position => "the table's position".to_string(),
        Action::Read { ac } => format!("a reading of autocollimator {ac}"),
        Action::Wait { until_seconds } => format!("a wait until {until_seconds} s"),
        Action::Remount(r) => format!("the remount of {}", r.mounting),
        Action::Keep(_) => "a record kept".to_string(),
        other => format!("{other:?}"),
    }
}

/// What of an event (or its time) is not a finite number, if anything is.
fn not_finite(now_seconds: f64, event: &Event) -> Option<&'static str> {
    if !now_seconds.is_finite() {
        return Some("time");
    }
    match event {
        Event::Moved { at_deg } if !at_deg.is_finite() => Some("position"),
        Event::Position { deg } if !deg.is_finite() => Some("position"),
        Event::Read(r) if !r.x_arcsec.is_finite() => Some("X reading"),
        Event::Read(r) if r.y_arcsec.is_some_and(|y| !y.is_finite()) => Some("Y reading"),
        _ => None,
    }
}

fn unexpected(asked: &str, told: &Event) -> SessionError {
    SessionError {
        asked: asked.to_string(),
        told: format!("{told:?}"),
    }
}
