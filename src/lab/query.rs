//! Queries: commands whose reply only reports, how a reply is tied to the query that
//! asked for it, and how a query is retried (see [`crate::lab`], *Retries and motion*,
//! and docs/FORMAT.md §7.3, *No reading on the wrong stop*) — as [`Exchange`], a machine
//! of the wire rules that does no input or output ([`crate::lab::wire`]).

use std::time::Duration;

use super::profile::Template;
use super::wire::{Wire, WireAction, WireError, WireEvent, check};
use super::{InstrumentError, ReplyError};

/// How queries are answered and retried.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct QueryOptions {
    /// Deadline for one complete reply line.
    pub reply_timeout: Duration,
    /// How many more times a query is sent after a lost, garbled, doubtful or invalid
    /// reply. A motion is never retried.
    pub retries: u32,
    /// How long a reply is watched for a line after it before it is taken as coming
    /// alone: on a serial line the next line is still on the wire when a reply was read
    /// (an ELCOMAT reply takes 13.5 ms at 19200 baud), so a look at what is pending
    /// alone cannot see it. [`QueryOptions::new`] gives zero (only what is pending);
    /// `run` sets [`LineSettings::alone_wait`](super::profile::LineSettings::alone_wait)
    /// for each line.
    pub alone_wait: Duration,
}

impl QueryOptions {
    /// Options with a deadline for one reply line and a number of retries.
    pub fn new(reply_timeout: Duration, retries: u32) -> QueryOptions {
        QueryOptions {
            reply_timeout,
            retries,
            alone_wait: Duration::ZERO,
        }
    }

    /// Sets how long a reply is watched for a line after it ([`QueryOptions::alone_wait`]).
    pub fn with_alone_wait(mut self, alone_wait: Duration) -> QueryOptions {
        self.alone_wait = alone_wait;
        self
    }
}

impl Default for QueryOptions {
    /// A 1 s reply deadline and three retries.
    fn default() -> Self {
        QueryOptions::new(Duration::from_secs(1), 3)
    }
}

/// A command whose reply cannot be mistaken for any other (an identification), sent to
/// bring a device's replies back in step with the host after a reply was late or
/// doubtful: every line that comes before its reply is discarded.
#[derive(Debug, Clone, PartialEq)]
pub struct Resync {
    /// The command, terminator included.
    pub command: String,
    /// The form of its reply.
    pub reply: Template,
}

/// How many lines a resynchronisation reads at most before it gives up.
const MAX_RESYNC_LINES: usize = 32;

/// Where a resynchronisation is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum ResyncStep {
    /// What is pending is taken (and discarded).
    Drain,
    /// The command is sent.
    Send,
    /// Lines are read until its reply; this many read so far.
    Read(usize),
    /// Its reply came: what came with it is older than any query still to come.
    DrainAfter,
    /// Over: whether its reply came.
    Over(bool),
}

/// Brings a device back in step: sends the resynchronisation command and reads until its
/// reply, noting every line before it as discarded (a late or extra reply to an earlier
/// query). A device answers in order, so nothing sent before it can arrive after its
/// reply. Gives whether its reply came.
#[derive(Debug)]
pub(crate) struct Resynchronising {
    with: Resync,
    reply_timeout: Duration,
    step: ResyncStep,
    /// A line to note as discarded before the next action.
    discarded: Option<String>,
    /// The port failed.
    failed: Option<InstrumentError>,
}

impl Resynchronising {
    pub(crate) fn new(with: Resync, reply_timeout: Duration) -> Resynchronising {
        Resynchronising {
            with,
            reply_timeout,
            step: ResyncStep::Drain,
            discarded: None,
            failed: None,
        }
    }

    fn asked(&self) -> Option<WireAction> {
        match self.step {
            ResyncStep::Drain | ResyncStep::DrainAfter => Some(WireAction::Drain),
            ResyncStep::Send => Some(WireAction::Send(self.with.command.clone())),
            ResyncStep::Read(_) => Some(WireAction::ReadLine(self.reply_timeout)),
            ResyncStep::Over(_) => None,
        }
    }
}

impl Wire for Resynchronising {
    type Output = bool;

    fn poll(&mut self) -> WireAction {
        if let Some(text) = self.discarded.take() {
            return note("discarded", text);
        }
        self.asked().unwrap_or(WireAction::Done)
    }

    fn tell(&mut self, now_seconds: f64, event: WireEvent) -> Result<(), WireError> {
        check(self.asked().as_ref(), now_seconds, &event)?;
        if let WireEvent::Failed(e) = event {
            self.failed = Some(e);
            self.step = ResyncStep::Over(false);
            return Ok(());
        }
        self.step = match (self.step, event) {
            (ResyncStep::Drain, _) => ResyncStep::Send,
            (ResyncStep::Send, _) => ResyncStep::Read(0),
            (ResyncStep::Read(_), WireEvent::Line(None)) => ResyncStep::Over(false),
            (ResyncStep::Read(_), WireEvent::Line(Some(line)))
                if self.with.reply.matches(&line).is_some() =>
            {
                ResyncStep::DrainAfter
            }
            (ResyncStep::Read(n), WireEvent::Line(Some(line))) => {
                self.discarded = Some(line);
                if n + 1 >= MAX_RESYNC_LINES {
                    ResyncStep::Over(false)
                } else {
                    ResyncStep::Read(n + 1)
                }
            }
            (ResyncStep::DrainAfter, _) => ResyncStep::Over(true),
            (step, _) => step,
        };
        Ok(())
    }

    fn outcome(&mut self) -> Option<Result<bool, InstrumentError>> {
        match self.step {
            ResyncStep::Over(came) => Some(match self.failed.take() {
                Some(e) => Err(e),
                None => Ok(came),
            }),
            _ => None,
        }
    }
}

/// A note for the traffic log.
pub(crate) fn note(event: &str, text: String) -> WireAction {
    WireAction::Note {
        event: event.to_string(),
        text,
    }
}

/// How a reply is read: the value it gives, or why it is refused.
pub type ReplyReader<V> = Box<dyn Fn(&str) -> Result<V, ReplyError> + Send + Sync>;

/// Where an exchange is.
enum ExchangeStep<V> {
    /// The next attempt is to begin (or the attempts are spent).
    Next,
    /// The device is being brought back in step before an attempt.
    Resync(Box<Resynchronising>),
    /// What is pending is drained before the command.
    Drain,
    /// The command is sent.
    Send,
    /// Its reply is read.
    Read,
    /// A reply was read; what follows it is taken: first what is pending, then (when
    /// nothing was) what arrives within the alone wait.
    After {
        value: V,
        line: String,
        awaited: bool,
    },
    /// Over.
    Over(Option<Result<(V, String), InstrumentError>>),
}

/// One query as the wire rules ask it: a machine ([`Wire`]) that gives the value read
/// from the reply and the reply line.
///
/// A reply is taken only when it is tied to this query beyond doubt:
///
/// - whatever is pending before the command is sent is drained (and logged as
///   discarded): it answers an earlier command;
/// - a reply that the reader accepts but that is followed by more input — pending, or
///   arriving within [`QueryOptions::alone_wait`], the time another reply line takes on
///   the wire — is not taken ([`ReplyError::NotAlone`]): a late reply to an earlier query
///   read as this one's answer has this one's own reply right behind it;
/// - after a reply that did not come in time or was not taken for that reason, the
///   device is resynchronised with the [`Resync`] command (when there is one) before the
///   command is sent again, so that a late reply is discarded when it arrives instead of
///   being read as the answer to the retry.
///
/// A reply the reader refuses is retried after the drain alone. At most
/// [`QueryOptions::retries`] more attempts are made; port failures are not retried.
///
/// ```
/// use std::time::Duration;
/// use polycal::lab::Exchange;
/// use polycal::lab::wire::{Wire, WireAction, WireEvent};
/// use polycal::lab::QueryOptions;
///
/// // A position query whose reply is a number, asked over a port of one's own.
/// let mut q = Exchange::new(
///     "lab:table",
///     "POS?\n",
///     QueryOptions::default(),
///     None,
///     Box::new(|reply: &str| {
///         reply.trim().parse::<f64>().map_err(|_| polycal::lab::ReplyError::NotTheForm {
///             form: "a number".into(),
///         })
///     }),
/// );
/// assert_eq!(q.poll(), WireAction::Drain);
/// q.tell(0.0, WireEvent::Drained(vec!["stale".into()]))?;
/// assert_eq!(q.poll(), WireAction::Send("POS?\n".into()));
/// q.tell(0.0, WireEvent::Sent)?;
/// assert_eq!(q.poll(), WireAction::ReadLine(Duration::from_secs(1)));
/// q.tell(0.01, WireEvent::Line(Some("45.0".into())))?;
/// assert_eq!(q.poll(), WireAction::Drain); // anything right behind the reply?
/// q.tell(0.01, WireEvent::Drained(vec![]))?;
/// assert_eq!(q.poll(), WireAction::Done);
/// let (deg, line) = q.outcome().unwrap()?;
/// assert_eq!((deg, line.as_str()), (45.0, "45.0"));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Exchange<V> {
    port: String,
    command: String,
    options: QueryOptions,
    resync: Option<Resync>,
    read: ReplyReader<V>,
    /// The attempt under way (1-based); 0 before the first.
    attempt: u32,
    /// (reply, reason) of the last reply not taken.
    last: Option<(String, ReplyError)>,
    timed_out: bool,
    out_of_step: bool,
    step: ExchangeStep<V>,
}

impl<V> std::fmt::Debug for Exchange<V> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Exchange")
            .field("port", &self.port)
            .field("command", &self.command)
            .field("attempt", &self.attempt)
            .finish_non_exhaustive()
    }
}

impl<V> Exchange<V> {
    /// The query `command` (terminator included) on `port` (named in errors), its reply
    /// read by `read`, resynchronised with `resync` when given.
    pub fn new(
        port: impl Into<String>,
        command: impl Into<String>,
        options: QueryOptions,
        resync: Option<Resync>,
        read: ReplyReader<V>,
    ) -> Exchange<V> {
        Exchange {
            port: port.into(),
            command: command.into(),
            options,
            resync,
            read,
            attempt: 0,
            last: None,
            timed_out: false,
            out_of_step: false,
            step: ExchangeStep::Next,
        }
    }

    /// The command, as sent.
    pub fn command(&self) -> &str {
        &self.command
    }

    fn attempts(&self) -> u32 {
        self.options.retries.saturating_add(1)
    }

    /// The step after the last attempt ended: the next attempt, or the error.
    fn next(&mut self) -> ExchangeStep<V> {
        if self.attempt >= self.attempts() {
            return ExchangeStep::Over(Some(Err(self.failure())));
        }
        self.attempt += 1;
        match &self.resync {
            Some(with) if self.attempt > 1 && self.out_of_step => ExchangeStep::Resync(Box::new(
                Resynchronising::new(with.clone(), self.options.reply_timeout),
            )),
            _ => ExchangeStep::Drain,
        }
    }

    /// The error once every attempt failed: the last bad reply, or a time-out.
    fn failure(&mut self) -> InstrumentError {
        let attempts = self.attempts();
        match self.last.take() {
            Some((received, reason)) if !self.timed_out => InstrumentError::BadReply {
                port: self.port.clone(),
                sent: self.command.clone(),
                received,
                reason: Box::new(reason),
                attempts,
            },
            _ => InstrumentError::Timeout {
                port: self.port.clone(),
                sent: self.command.clone(),
                timeout: self.options.reply_timeout,
                attempts,
            },
        }
    }

    /// The action the step asks, `None` when it asks none of its own.
    fn asked(&self) -> Option<WireAction> {
        match &self.step {
            ExchangeStep::Drain => Some(WireAction::Drain),
            ExchangeStep::Send => Some(WireAction::Send(self.command.clone())),
            ExchangeStep::Read => Some(WireAction::ReadLine(self.options.reply_timeout)),
            ExchangeStep::After { awaited: false, .. } => Some(WireAction::Drain),
            ExchangeStep::After { awaited: true, .. } => {
                Some(WireAction::AwaitInput(self.options.alone_wait))
            }
            ExchangeStep::Next | ExchangeStep::Resync(_) | ExchangeStep::Over(_) => None,
        }
    }
}

impl<V> Wire for Exchange<V> {
    type Output = (V, String);

    fn poll(&mut self) -> WireAction {
        loop {
            match &mut self.step {
                ExchangeStep::Next => self.step = self.next(),
                ExchangeStep::Resync(r) => match r.poll() {
                    WireAction::Done => {
                        self.step = match r.outcome() {
                            Some(Ok(true)) => ExchangeStep::Drain,
                            // The device did not come back in step: this attempt is
                            // spent on it.
                            Some(Ok(false)) | None => {
                                self.timed_out = true;
                                ExchangeStep::Next
                            }
                            Some(Err(e)) => ExchangeStep::Over(Some(Err(e))),
                        }
                    }
                    action => return action,
                },
                ExchangeStep::Over(_) => return WireAction::Done,
                _ => return self.asked().unwrap_or(WireAction::Done),
            }
        }
    }

    fn tell(&mut self, now_seconds: f64, event: WireEvent) -> Result<(), WireError> {
        if let ExchangeStep::Resync(r) = &mut self.step {
            return r.tell(now_seconds, event);
        }
        check(self.asked().as_ref(), now_seconds, &event)?;
        let step = std::mem::replace(&mut self.step, ExchangeStep::Next);
        self.step = match (step, event) {
            (_, WireEvent::Failed(e)) => ExchangeStep::Over(Some(Err(e))),
            (ExchangeStep::Drain, _) => ExchangeStep::Send,
            (ExchangeStep::Send, _) => ExchangeStep::Read,
            (ExchangeStep::Read, WireEvent::Line(None)) => {
                self.timed_out = true;
                self.out_of_step = true;
                ExchangeStep::Next
            }
            (ExchangeStep::Read, WireEvent::Line(Some(line))) => match (self.read)(&line) {
                Ok(value) => ExchangeStep::After {
                    value,
                    line,
                    awaited: false,
                },
                Err(reason) => {
                    self.timed_out = false;
                    self.out_of_step = false;
                    self.last = Some((line, reason));
                    ExchangeStep::Next
                }
            },
            (
                ExchangeStep::After {
                    value,
                    line,
                    awaited,
                },
                WireEvent::Drained(extra) | WireEvent::Input(extra),
            ) => {
                if extra.is_empty() && !awaited && !self.options.alone_wait.is_zero() {
                    ExchangeStep::After {
                        value,
                        line,
                        awaited: true,
                    }
                } else if extra.is_empty() {
                    ExchangeStep::Over(Some(Ok((value, line))))
                } else {
                    self.timed_out = false;
                    self.out_of_step = true;
                    self.last = Some((
                        line,
                        ReplyError::NotAlone {
                            extra: extra.join(" | "),
                        },
                    ));
                    ExchangeStep::Next
                }
            }
            (step, _) => step,
        };
        Ok(())
    }

    fn outcome(&mut self) -> Option<Result<(V, String), InstrumentError>> {
        match &mut self.step {
            ExchangeStep::Over(outcome) => outcome.take(),
            _ => None,
        }
    }
}
