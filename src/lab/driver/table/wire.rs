//! A table's operations as a machine of the wire rules ([`crate::lab::wire`]): what
//! [`ProfileTable`](super::ProfileTable) does, without a port.

mod answers;
mod steps;

use std::collections::VecDeque;
use std::time::Duration;

use super::{LATCHED_ERRORS_READ, TableOptions, TableState};
use crate::lab::InstrumentError;
use crate::lab::driver::read_reply;
use crate::lab::profile::{
    Captures, Command, LineSettings, Profile, ProfileError, Query, TableProfile,
};
use crate::lab::query::{Exchange, Resync, Resynchronising};
use crate::lab::wire::WireAction;

/// An operation of a table ([`TableWire::begin`]).
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub enum TableOp {
    /// Make the axis ready to move: pending input thrown away, the errors latched before
    /// the session read away, the `[[enable]]` commands each sent once and checked, and a
    /// home search when the axis is not referenced (or the profile cannot tell).
    Start,
    /// Ask the identification.
    Identify,
    /// Ask the state.
    State,
    /// Move to this angle, degrees: the state (must be ready), the move sent **once**,
    /// the error (must be none), the state every poll interval until ready, the position
    /// (must be within tolerance of the target).
    MoveTo(f64),
    /// Ask the position, degrees.
    Position,
    /// Stop at once.
    Stop,
}

/// What an operation of a table gave.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum TableOutcome {
    /// The axis is ready to move ([`TableOp::Start`]).
    Started,
    /// The identification's text ([`TableOp::Identify`]).
    Identified(String),
    /// The state ([`TableOp::State`]).
    State(TableState),
    /// Where the table is, degrees ([`TableOp::MoveTo`], [`TableOp::Position`]).
    At(f64),
    /// The stop command was sent ([`TableOp::Stop`]).
    Stopped,
}

/// Why a query is asked: what its reply decides.
#[derive(Debug, Clone)]
enum Purpose {
    /// The identification's text ends the operation.
    Identify,
    /// The state, for this use.
    State(StateUse),
    /// The error after `motion`: none, or the operation ends refused.
    Error { motion: String },
    /// The errors latched before the session: read until none, the same twice, or
    /// `left` more times.
    Latched {
        left: usize,
        previous: Option<String>,
    },
    /// Whether the axis is referenced: at the start (noted), or after the home search
    /// (must be).
    Referenced { after_home: bool },
    /// The position ends the operation: within tolerance of the target when there is one.
    Position { target: Option<f64> },
}

/// What a state reply is asked for.
#[derive(Debug, Clone)]
enum StateUse {
    /// It ends the operation.
    Report,
    /// It must be ready before the move to this target.
    BeforeMove(f64),
    /// It is noted at the start.
    AtStart,
    /// A motion is watched until it is done, by this time on the driver's clock.
    Ready { motion: String, deadline: f64 },
}

/// A step of an operation, in order.
#[derive(Debug, Clone)]
enum Step {
    ClearInput,
    Ask(Box<Query>, Purpose),
    /// A command that changes something sent exactly once; its acknowledgement read when
    /// it has one, and never a reason to send it again.
    SendOnce(Box<Command>, String),
    /// The home search sent once, its acknowledgement awaited as long as a motion may take.
    SendHome,
    /// The error after this motion checked, when the profile has an error query.
    CheckAccepted(String),
    /// The state polled until ready after this motion.
    WaitReady(String),
    Wait(Duration),
    /// What the start does once the state (and whether referenced) is known.
    StartDecide,
    Finish(TableOutcome),
}

/// A query and the doubtful-reply rule: a reply word for word the last one, which
/// answered another query, is asked again after a resynchronisation.
#[derive(Debug)]
enum Asking {
    First(Exchange<Captures>, Box<Query>),
    Doubtful(Resynchronising, Box<Query>),
    Second(Exchange<Captures>),
}

/// The step under way.
#[derive(Debug)]
enum Running {
    Ask(Box<Asking>, Purpose),
    /// A command sent once: drain, send, read the acknowledgement.
    Send {
        command: Box<Command>,
        text: String,
        phase: SendPhase,
    },
    /// The home search's acknowledgement awaited until `deadline` (None until sent).
    Home {
        phase: SendPhase,
        deadline: f64,
    },
    ClearInput,
    Wait(Duration),
    /// The stop command sent; then the operation ends with this error when there is one
    /// (whether the stop could be sent or not), or goes on.
    Stop(Option<Box<InstrumentError>>),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum SendPhase {
    Drain,
    Send,
    Ack,
}

/// A table's operations as a machine of the wire rules: [`TableWire::begin`] an
/// operation ([`TableOp`]), carry out its actions ([`Wire::poll`](crate::lab::wire::Wire::poll), [`Wire::tell`](crate::lab::wire::Wire::tell)), take
/// its [`TableOutcome`]. One operation at a time; between two, the machine remembers the
/// last query and its reply (the doubtful-reply rule). [`ProfileTable`](super::ProfileTable)
/// is this machine driven over a [`Transport`](crate::lab::transport::Transport).
///
/// ```
/// use polycal::lab::driver::{TableOp, TableOptions, TableOutcome, TableWire};
/// use polycal::lab::profile::Profile;
/// use polycal::lab::wire::{Wire, WireAction, WireEvent};
///
/// let profile = Profile::load("pi-gcs2")?;
/// let mut table = TableWire::new("lab:table", &profile, TableOptions::default())?;
/// table.begin(TableOp::MoveTo(45.0));
/// // A port of one's own, and a controller that answers at once:
/// let mut sent = Vec::new();
/// let (mut now, mut reply) = (0.0, None::<&str>);
/// loop {
///     now += 0.01;
///     let event = match table.poll() {
///         WireAction::Drain | WireAction::AwaitInput(_) => WireEvent::Drained(vec![]),
///         WireAction::Send(text) => {
///             reply = match text.as_str() {
///                 "ONT? 1\n" => Some("1=1"),
///                 "ERR?\n" => Some("0"),
///                 "POS? 1\n" => Some("1=45.0000"),
///                 _ => None, // MOV 1 45 has no reply
///             };
///             sent.push(text);
///             WireEvent::Sent
///         }
///         WireAction::ReadLine(_) => WireEvent::Line(reply.take().map(String::from)),
///         WireAction::Done => break,
///         _ => continue,
///     };
///     table.tell(now, event)?;
/// }
/// assert_eq!(table.outcome().unwrap()?, TableOutcome::At(45.0));
/// assert_eq!(sent, ["ONT? 1\n", "MOV 1 45\n", "ERR?\n", "ONT? 1\n", "POS? 1\n"]);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct TableWire {
    port: String,
    line: LineSettings,
    table: TableProfile,
    options: TableOptions,
    /// The last query sent and the reply taken for it.
    last: Option<(String, String)>,
    /// The time last told, seconds.
    now_seconds: f64,
    steps: VecDeque<Step>,
    running: Option<Running>,
    interrupted: bool,
    /// The start's state and whether the axis is referenced.
    start_state: Option<TableState>,
    start_referenced: Option<bool>,
    notes: VecDeque<WireAction>,
    /// The action of a step (not a query's) that waits for its event.
    asked: Option<WireAction>,
    outcome: Option<Result<TableOutcome, InstrumentError>>,
}

impl TableWire {
    /// The machine of a table on `port` (named in errors) speaking `profile`.
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for an autocollimator's profile.
    pub fn new(
        port: impl Into<String>,
        profile: &Profile,
        options: TableOptions,
    ) -> Result<TableWire, ProfileError> {
        Ok(TableWire::of(
            port.into(),
            profile.line.clone(),
            profile.table()?.clone(),
            options,
        ))
    }

    pub(super) fn of(
        port: String,
        line: LineSettings,
        table: TableProfile,
        options: TableOptions,
    ) -> TableWire {
        TableWire {
            port,
            line,
            table,
            options,
            last: None,
            now_seconds: 0.0,
            steps: VecDeque::new(),
            running: None,
            interrupted: false,
            start_state: None,
            start_referenced: None,
            notes: VecDeque::new(),
            asked: None,
            outcome: None,
        }
    }

    /// The port named in errors.
    pub fn port(&self) -> &str {
        &self.port
    }

    /// Begins `op`, dropping whatever operation was under way (its outcome is lost).
    pub fn begin(&mut self, op: TableOp) {
        self.steps.clear();
        self.running = None;
        self.notes.clear();
        self.asked = None;
        self.outcome = None;
        self.interrupted = false;
        self.start_state = None;
        self.start_referenced = None;
        let t = &self.table;
        let steps: Vec<Step> = match op {
            TableOp::Identify => vec![Step::Ask(Box::new(t.identify.clone()), Purpose::Identify)],
            TableOp::State => vec![Step::Ask(
                Box::new(t.state.query.clone()),
                Purpose::State(StateUse::Report),
            )],
            TableOp::Position => vec![Step::Ask(
                Box::new(t.position.clone()),
                Purpose::Position { target: None },
            )],
            TableOp::MoveTo(deg) => vec![Step::Ask(
                Box::new(t.state.query.clone()),
                Purpose::State(StateUse::BeforeMove(deg)),
            )],
            TableOp::Stop => {
                self.running = Some(Running::Stop(None));
                vec![Step::Finish(TableOutcome::Stopped)]
            }
            TableOp::Start => self.start_steps(),
        };
        self.steps.extend(steps);
    }

    /// [`TableOp::Start`] up to the state.
    fn start_steps(&self) -> Vec<Step> {
        let t = &self.table;
        let mut steps = vec![Step::ClearInput];
        if let Some(error) = &t.error {
            steps.push(Step::Ask(
                Box::new(error.query.clone()),
                Purpose::Latched {
                    left: LATCHED_ERRORS_READ,
                    previous: None,
                },
            ));
        }
        for enable in &t.enable {
            steps.push(Step::SendOnce(
                Box::new(enable.clone()),
                enable.send.clone(),
            ));
            steps.push(Step::CheckAccepted(enable.send.clone()));
        }
        steps.push(Step::Ask(
            Box::new(t.state.query.clone()),
            Purpose::State(StateUse::AtStart),
        ));
        if let Some((q, _)) = &t.referenced {
            steps.push(Step::Ask(
                Box::new(q.clone()),
                Purpose::Referenced { after_home: false },
            ));
        }
        steps.push(Step::StartDecide);
        steps
    }

    pub(super) fn table(&self) -> &TableProfile {
        &self.table
    }

    pub(super) fn wire(&self, command: &str) -> String {
        format!("{command}{}", self.line.command_end)
    }

    pub(super) fn device_error(
        &self,
        sent: &str,
        received: &str,
        message: String,
    ) -> InstrumentError {
        InstrumentError::Device {
            port: self.port.clone(),
            sent: self.wire(sent),
            received: received.to_string(),
            message,
        }
    }

    fn interrupted_error(&self) -> InstrumentError {
        InstrumentError::Interrupted {
            port: self.port.clone(),
        }
    }

    /// Ends the operation.
    fn end(&mut self, outcome: Result<TableOutcome, InstrumentError>) {
        self.steps.clear();
        self.running = None;
        self.outcome = Some(outcome);
    }

    /// Stops the table, then ends with `error`.
    fn stop_then(&mut self, error: InstrumentError) {
        self.steps.clear();
        self.running = Some(Running::Stop(Some(Box::new(error))));
    }

    /// The identification, which brings the device back in step.
    fn resync(&self) -> Resync {
        Resync {
            command: self.wire(&self.table.identify.send),
            reply: self.table.identify.reply.clone(),
        }
    }

    /// An exchange of `q` with the identification as its resynchronisation (but the
    /// identification's own).
    fn exchange(&self, q: &Query) -> Exchange<Captures> {
        let resync = (q.send != self.table.identify.send).then(|| self.resync());
        let (line, template) = (self.line.clone(), q.reply.clone());
        Exchange::new(
            self.port.clone(),
            self.wire(&q.send),
            self.options.query,
            resync,
            Box::new(move |reply| read_reply(&line, &template, reply)),
        )
    }

    /// Starts the next step; `false` when there is none.
    fn start_next(&mut self) -> bool {
        let Some(step) = self.steps.pop_front() else {
            return false;
        };
        self.running = match step {
            Step::ClearInput => Some(Running::ClearInput),
            Step::Wait(d) => Some(Running::Wait(d)),
            Step::Ask(q, purpose) => {
                if self.interrupted {
                    match &purpose {
                        // nothing sent yet: nothing to stop
                        Purpose::State(StateUse::BeforeMove(_)) => {
                            self.end(Err(self.interrupted_error()));
                            return true;
                        }
                        Purpose::State(StateUse::Ready { .. }) => {
                            self.stop_then(self.interrupted_error());
                            return true;
                        }
                        _ => {}
                    }
                }
                let first = Asking::First(self.exchange(&q), q);
                Some(Running::Ask(Box::new(first), purpose))
            }
            Step::SendOnce(command, text) => Some(Running::Send {
                command,
                text,
                phase: SendPhase::Drain,
            }),
            Step::SendHome => {
                if self.table.home.ack.is_none() {
                    let home = self.table.home.clone();
                    self.steps
                        .push_front(Step::SendOnce(Box::new(home.clone()), home.send));
                    return true;
                }
                Some(Running::Home {
                    phase: SendPhase::Drain,
                    deadline: f64::INFINITY,
                })
            }
            Step::CheckAccepted(motion) => {
                if let Some(error) = &self.table.error {
                    let q = error.query.clone();
                    self.steps
                        .push_front(Step::Ask(Box::new(q), Purpose::Error { motion }));
                }
                return true;
            }
            Step::WaitReady(motion) => {
                let deadline = self.now_seconds + self.options.motion_timeout.as_secs_f64();
                let q = self.table.state.query.clone();
                self.steps.push_front(Step::Ask(
                    Box::new(q),
                    Purpose::State(StateUse::Ready { motion, deadline }),
                ));
                return true;
            }
            Step::StartDecide => {
                self.start_decide();
                return true;
            }
            Step::Finish(outcome) => {
                self.end(Ok(outcome));
                return true;
            }
        };
        true
    }

    /// After the start's state: a motion under way waited for, and the home search when
    /// the axis is not referenced or the profile cannot tell (the encoder's zero must be
    /// the same in every session of a run).
    fn start_decide(&mut self) {
        let state = self.start_state.unwrap_or(TableState::NotReferenced);
        let can_tell = self.table.referenced.is_some() || self.table.state.not_referenced.is_some();
        let referenced = self
            .start_referenced
            .unwrap_or(state != TableState::NotReferenced);
        let mut steps = Vec::new();
        if state == TableState::Moving {
            steps.push(Step::WaitReady("(motion in progress at start)".to_string()));
        }
        if !referenced || !can_tell {
            let home = self.table.home.send.clone();
            steps.push(Step::SendHome);
            steps.push(Step::CheckAccepted(home.clone()));
            steps.push(Step::WaitReady(home));
            if let Some((q, _)) = &self.table.referenced {
                steps.push(Step::Ask(
                    Box::new(q.clone()),
                    Purpose::Referenced { after_home: true },
                ));
            }
        }
        steps.push(Step::Finish(TableOutcome::Started));
        for step in steps.into_iter().rev() {
            self.steps.push_front(step);
        }
    }
}
