//! An autocollimator as its profile describes it.

use std::collections::VecDeque;
use std::time::Duration;

use super::read_reply;
use crate::lab::profile::{AcProfile, LineSettings, Profile, ProfileError};
use crate::lab::query::{Exchange, Resync};
use crate::lab::transport::Transport;
use crate::lab::wire::{Wire, WireAction, WireError, WireEvent, check, drive};
use crate::lab::{AcReading, Autocollimator, InstrumentError, QueryOptions};

/// An operation of an autocollimator ([`AcWire::begin`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum AcOp {
    /// The profile's start commands (e.g. stop a stream), each without a reply; then, after
    /// a wait for lines still on their way, the input cleared.
    Start,
    /// Ask the identification.
    Identify,
    /// One measurement: the profile's measure query, resynchronised with the
    /// identification after a late or doubtful reply.
    Measure,
}

/// What an operation of an autocollimator gave.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum AcOutcome {
    /// [`AcOp::Start`] is done.
    Started,
    /// The identification's text ([`AcOp::Identify`]).
    Identified(String),
    /// The reading ([`AcOp::Measure`]).
    Reading(AcReading),
}

/// The operation under way.
#[derive(Debug)]
enum AcRunning {
    /// The start's actions, in order, and the one asked.
    Start(VecDeque<WireAction>, Option<WireAction>),
    Identify(Exchange<String>),
    Measure(Exchange<AcReading>),
    Over(Option<Result<AcOutcome, InstrumentError>>),
}

/// An autocollimator's operations as a machine of the wire rules
/// ([`crate::lab::wire`]): [`AcWire::begin`] an operation ([`AcOp`]), carry out its
/// actions, take its [`AcOutcome`]. [`ProfileAutocollimator`] is this machine driven over
/// a [`Transport`].
///
/// ```
/// use polycal::lab::driver::{AcOp, AcOutcome, AcWire};
/// use polycal::lab::profile::Profile;
/// use polycal::lab::wire::{Wire, WireAction, WireEvent};
/// use polycal::lab::QueryOptions;
///
/// let profile = Profile::load("elcomat3000")?;
/// let mut ac = AcWire::new("COM3", &profile, QueryOptions::default())?;
/// ac.begin(AcOp::Measure);
/// assert_eq!(ac.poll(), WireAction::Drain); // what is pending answers an earlier query
/// ac.tell(0.0, WireEvent::Drained(vec!["4 003 99.000000 0.000000".into()]))?;
/// assert_eq!(ac.poll(), WireAction::Send("a\n".into()));
/// ac.tell(0.0, WireEvent::Sent)?;
/// assert!(matches!(ac.poll(), WireAction::ReadLine(_)));
/// ac.tell(0.02, WireEvent::Line(Some("4 003 12.345000 -1.234000".into())))?;
/// assert_eq!(ac.poll(), WireAction::Drain); // the reply must come alone
/// ac.tell(0.02, WireEvent::Drained(vec![]))?;
/// assert_eq!(ac.poll(), WireAction::Done);
/// let Some(Ok(AcOutcome::Reading(r))) = ac.outcome() else { panic!() };
/// assert_eq!((r.x_arcsec, r.y_arcsec), (12.345, Some(-1.234)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct AcWire {
    port: String,
    line: LineSettings,
    ac: AcProfile,
    options: QueryOptions,
    drain: Duration,
    running: AcRunning,
}

impl AcWire {
    /// The machine of an autocollimator on `port` (named in errors) speaking `profile`;
    /// its start waits 50 ms for lines still on their way ([`AcWire::with_drain`]).
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for a table's profile.
    pub fn new(
        port: impl Into<String>,
        profile: &Profile,
        options: QueryOptions,
    ) -> Result<AcWire, ProfileError> {
        Ok(AcWire::of(
            port.into(),
            profile.line.clone(),
            profile.autocollimator()?.clone(),
            options,
        ))
    }

    fn of(port: String, line: LineSettings, ac: AcProfile, options: QueryOptions) -> AcWire {
        AcWire {
            port,
            line,
            ac,
            options,
            drain: Duration::from_millis(50),
            running: AcRunning::Over(None),
        }
    }

    /// Sets the wait between the start commands and clearing the input on start.
    pub fn with_drain(mut self, drain: Duration) -> AcWire {
        self.drain = drain;
        self
    }

    fn wire(&self, command: &str) -> String {
        format!("{command}{}", self.line.command_end)
    }

    /// Begins `op`, dropping whatever operation was under way.
    pub fn begin(&mut self, op: AcOp) {
        self.running = match op {
            AcOp::Start => {
                let mut actions: VecDeque<WireAction> = (self.ac.start.iter())
                    .map(|c| WireAction::Send(self.wire(c)))
                    .collect();
                if !self.ac.start.is_empty() && !self.drain.is_zero() {
                    actions.push_back(WireAction::Wait(self.drain));
                }
                actions.push_back(WireAction::ClearInput);
                AcRunning::Start(actions, None)
            }
            AcOp::Identify => {
                let (line, template) = (self.line.clone(), self.ac.identify.reply.clone());
                AcRunning::Identify(Exchange::new(
                    self.port.clone(),
                    self.wire(&self.ac.identify.send),
                    self.options,
                    None,
                    Box::new(move |reply| {
                        read_reply(&line, &template, reply)
                            .map(|c| c.get("text").unwrap_or(reply.trim()).trim().to_string())
                    }),
                ))
            }
            AcOp::Measure => {
                let resync = Resync {
                    command: self.wire(&self.ac.identify.send),
                    reply: self.ac.identify.reply.clone(),
                };
                let (line, ac) = (self.line.clone(), self.ac.clone());
                AcRunning::Measure(Exchange::new(
                    self.port.clone(),
                    self.wire(&self.ac.measure.send),
                    self.options,
                    Some(resync),
                    Box::new(move |reply| {
                        // A refusal of the line's is named as such; the rest is the
                        // profile's.
                        read_reply(&line, &ac.measure.reply, reply)?;
                        ac.reading(reply)
                    }),
                ))
            }
        };
    }
}

impl Wire for AcWire {
    type Output = AcOutcome;

    fn poll(&mut self) -> WireAction {
        let over = match &mut self.running {
            AcRunning::Start(actions, asked) => match asked {
                Some(action) => return action.clone(),
                None => match actions.pop_front() {
                    Some(action) => {
                        *asked = Some(action.clone());
                        return action;
                    }
                    None => Ok(AcOutcome::Started),
                },
            },
            AcRunning::Identify(ex) => match ex.poll() {
                WireAction::Done => match ex.outcome() {
                    Some(r) => r.map(|(text, _)| AcOutcome::Identified(text)),
                    None => return WireAction::Done,
                },
                action => return action,
            },
            AcRunning::Measure(ex) => match ex.poll() {
                WireAction::Done => match ex.outcome() {
                    Some(r) => r.map(|(reading, _)| AcOutcome::Reading(reading)),
                    None => return WireAction::Done,
                },
                action => return action,
            },
            AcRunning::Over(_) => return WireAction::Done,
        };
        self.running = AcRunning::Over(Some(over));
        WireAction::Done
    }

    fn tell(&mut self, now_seconds: f64, event: WireEvent) -> Result<(), WireError> {
        match &mut self.running {
            AcRunning::Identify(ex) => ex.tell(now_seconds, event),
            AcRunning::Measure(ex) => ex.tell(now_seconds, event),
            AcRunning::Start(_, asked) => {
                check(asked.as_ref(), now_seconds, &event)?;
                *asked = None;
                if let WireEvent::Failed(e) = event {
                    self.running = AcRunning::Over(Some(Err(e)));
                }
                Ok(())
            }
            AcRunning::Over(_) => check(None, now_seconds, &event),
        }
    }

    fn outcome(&mut self) -> Option<Result<AcOutcome, InstrumentError>> {
        match &mut self.running {
            AcRunning::Over(outcome) => outcome.take(),
            _ => None,
        }
    }
}

/// An autocollimator driven through its profile's commands (module
/// [`crate::lab::driver`]).
///
/// ```
/// use std::sync::Arc;
/// use polycal::lab::driver::ProfileAutocollimator;
/// use polycal::lab::profile::Profile;
/// use polycal::lab::scripted::ScriptedStream;
/// use polycal::lab::transport::StreamTransport;
/// use polycal::lab::{Autocollimator, QueryOptions};
///
/// let stream = ScriptedStream::new()
///     .expect("s\n", "")
///     .expect("a\n", "4 003 12.345000 -1.234000\r");
/// let profile = Profile::load("elcomat3000")?;
/// let transport = StreamTransport::new("mem:ac1", stream);
/// let mut ac = ProfileAutocollimator::new(transport, &profile, QueryOptions::default())?;
/// ac.start()?;
/// let reading = ac.measure()?;
/// assert_eq!((reading.x_arcsec, reading.y_arcsec), (12.345, Some(-1.234)));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct ProfileAutocollimator<T> {
    transport: T,
    name: String,
    wire: AcWire,
}

impl<T: Transport> ProfileAutocollimator<T> {
    /// A driver over `transport` speaking `profile`. On [`Autocollimator::start`] it
    /// waits 50 ms after the profile's start commands for lines still on their way
    /// before it clears the input ([`ProfileAutocollimator::with_drain`] changes that).
    ///
    /// # Errors
    ///
    /// [`ProfileError::WrongInstrument`] for a table's profile.
    pub fn new(
        transport: T,
        profile: &Profile,
        options: QueryOptions,
    ) -> Result<Self, ProfileError> {
        let wire = AcWire::new(transport.port(), profile, options)?;
        Ok(ProfileAutocollimator {
            transport,
            name: profile.name.clone(),
            wire,
        })
    }

    /// An ELCOMAT 3000 (the bundled profile `elcomat3000`).
    pub fn elcomat3000(transport: T, options: QueryOptions) -> Self {
        let profile = crate::lab::profile::bundled("elcomat3000");
        let ac = match profile.kind {
            crate::lab::profile::ProfileKind::Autocollimator(ac) => *ac,
            crate::lab::profile::ProfileKind::Table(_) => {
                unreachable!("the bundled elcomat3000 describes an autocollimator")
            }
        };
        let port = transport.port().to_string();
        ProfileAutocollimator {
            transport,
            name: profile.name.clone(),
            wire: AcWire::of(port, profile.line.clone(), ac, options),
        }
    }

    /// Sets the wait between the start commands and clearing the input on start.
    pub fn with_drain(mut self, drain: Duration) -> Self {
        self.wire = self.wire.with_drain(drain);
        self
    }

    /// The profile's name.
    pub fn profile_name(&self) -> &str {
        &self.name
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }

    /// `op` carried out over the transport.
    fn run(&mut self, op: AcOp) -> Result<AcOutcome, InstrumentError> {
        self.wire.begin(op);
        drive(&mut self.wire, &mut self.transport, None)
    }

    /// An outcome that is not its operation's: a bug of polycal's, reported.
    fn unexpected(&self, outcome: AcOutcome) -> InstrumentError {
        InstrumentError::Reported {
            port: self.transport.port().to_string(),
            message: format!("the autocollimator's wire rules gave {outcome:?}"),
        }
    }
}

impl<T: Transport> Autocollimator for ProfileAutocollimator<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.run(AcOp::Start).map(|_| ())
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        match self.run(AcOp::Identify)? {
            AcOutcome::Identified(text) => Ok(text),
            other => Err(self.unexpected(other)),
        }
    }

    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        match self.run(AcOp::Measure)? {
            AcOutcome::Reading(reading) => Ok(reading),
            other => Err(self.unexpected(other)),
        }
    }
}
