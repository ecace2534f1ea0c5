//! The wire rules without the wire: how a query is tied to its reply, how a device is
//! brought back in step, how a motion is sent once and watched to its end — as machines
//! that decide and do no input or output (docs/FORMAT.md §7.7).
//!
//! A machine ([`Wire`]) asks for [`WireAction`]s, the operations of a line-oriented port
//! (take what is pending, send a line, read a line within a deadline, wait), and is told
//! [`WireEvent`]s, what the port did. Whoever owns the port carries the actions out:
//! polycal's drivers ([`crate::lab::driver`]) with [`drive`] over a
//! [`Transport`], lab software over a port of its own (a LabVIEW VISA session, a
//! pyserial port, an EPICS IOC's asyn port). The rules are the same for both: the
//! drivers *are* [`drive`] over these machines.
//!
//! The machines: [`Exchange`](crate::lab::Exchange), one query (its drain, its
//! reply taken only alone, its resynchronisation and retries);
//! [`AcWire`](crate::lab::driver::AcWire), an autocollimator's operations; and
//! [`TableWire`](crate::lab::driver::TableWire), a table's (the start with its home search,
//! a move sent once and watched until it is done, the position checked).

use std::time::{Duration, Instant};

use super::transport::Transport;
use super::{InstrumentError, StopFlag};

/// What a wire machine asks of the port ([`Wire::poll`]). Each is answered by one
/// [`WireEvent`] (or [`WireEvent::Failed`] when the port failed), except
/// [`WireAction::Note`] (answered by nothing) and [`WireAction::Done`].
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum WireAction {
    /// Take everything received and not yet read, without waiting, and record each line
    /// taken as `discarded` (it answers an earlier command): [`WireEvent::Drained`].
    Drain,
    /// Throw away everything received and not yet read, the port's own buffer included:
    /// [`WireEvent::Cleared`].
    ClearInput,
    /// Write this text exactly as given (terminator included) and flush:
    /// [`WireEvent::Sent`].
    Send(String),
    /// Read one line (terminator removed, empty lines skipped), waiting at most this long
    /// for all of it: [`WireEvent::Line`], `None` when the deadline passed.
    ReadLine(Duration),
    /// Wait at most this long for input and take what arrived (a line not yet ended
    /// included), recording each line taken as `discarded`: [`WireEvent::Input`], an
    /// empty list when nothing came.
    AwaitInput(Duration),
    /// Wait this long (a poll interval, the time start commands take to be answered):
    /// [`WireEvent::Waited`].
    Wait(Duration),
    /// Record `event` about `text` in the traffic log (`discarded`, `doubtful`,
    /// `latched`, `no acknowledgement`); answered by nothing.
    Note {
        /// The traffic log's event.
        event: String,
        /// The line it is about.
        text: String,
    },
    /// The operation is over: its outcome is [`Wire::outcome`].
    Done,
}

/// What the port did, told to a wire machine ([`Wire::tell`]).
#[derive(Debug)]
#[non_exhaustive]
pub enum WireEvent {
    /// The lines [`WireAction::Drain`] took (an empty list when nothing was pending).
    Drained(Vec<String>),
    /// [`WireAction::ClearInput`] is done.
    Cleared,
    /// [`WireAction::Send`] is done.
    Sent,
    /// The line [`WireAction::ReadLine`] read, or `None` at its deadline.
    Line(Option<String>),
    /// The lines [`WireAction::AwaitInput`] took.
    Input(Vec<String>),
    /// [`WireAction::Wait`] is over.
    Waited,
    /// The port failed doing the action asked (closed, an input/output error): the
    /// operation ends with this error.
    Failed(InstrumentError),
}

/// A told event that does not answer the action asked.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
#[error("the wire rules asked for {asked}, and were told {told}")]
pub struct WireError {
    /// The action that waits for its answer (`nothing` when none does).
    pub asked: String,
    /// The event told.
    pub told: String,
}

impl WireError {
    /// The error for `told` when `asked` (an action, or `None` for nothing) waits.
    pub(crate) fn new(asked: Option<&WireAction>, told: &WireEvent) -> WireError {
        WireError {
            asked: asked.map_or_else(|| "nothing".to_string(), |a| format!("{a:?}")),
            told: format!("{told:?}"),
        }
    }
}

/// Checks that `event`, told at `now_seconds`, answers `asked`.
pub(crate) fn check(
    asked: Option<&WireAction>,
    now_seconds: f64,
    event: &WireEvent,
) -> Result<(), WireError> {
    if !asked.is_some_and(|action| answers(action, event)) {
        return Err(WireError::new(asked, event));
    }
    if !now_seconds.is_finite() {
        let mut e = WireError::new(asked, event);
        e.told = format!(
            "{} at {now_seconds} s, a time that is not a finite number",
            e.told
        );
        return Err(e);
    }
    Ok(())
}

/// Whether `event` answers `action`.
fn answers(action: &WireAction, event: &WireEvent) -> bool {
    matches!(
        (action, event),
        (WireAction::Drain, WireEvent::Drained(_))
            | (WireAction::ClearInput, WireEvent::Cleared)
            | (WireAction::Send(_), WireEvent::Sent)
            | (WireAction::ReadLine(_), WireEvent::Line(_))
            | (WireAction::AwaitInput(_), WireEvent::Input(_))
            | (WireAction::Wait(_), WireEvent::Waited)
    ) || matches!(event, WireEvent::Failed(_))
        && !matches!(action, WireAction::Note { .. } | WireAction::Done)
}

/// A machine of the wire rules: one operation on one device, asked for actions and told
/// what the port did, until it is done.
pub trait Wire {
    /// What the operation gives when it succeeds.
    type Output;

    /// The next action. Until its event is told, the same action again; [`WireAction::Note`]
    /// is given once and needs no answer; [`WireAction::Done`] from the end on.
    fn poll(&mut self) -> WireAction;

    /// Tells what the port did for the action asked, at `now_seconds` on the driver's
    /// clock (seconds from any origin, never going back): what a motion's time-out is
    /// counted on.
    ///
    /// # Errors
    ///
    /// [`WireError`] when the event does not answer the action asked, or `now_seconds`
    /// is not a finite number (the machine is unchanged).
    fn tell(&mut self, now_seconds: f64, event: WireEvent) -> Result<(), WireError>;

    /// The operation's outcome once [`Wire::poll`] gave [`WireAction::Done`] (taken: a
    /// second call gives `None`); `None` before.
    fn outcome(&mut self) -> Option<Result<Self::Output, InstrumentError>>;

    /// A stop was requested (Ctrl-C): a table that may be moving is stopped and the
    /// operation ends as [`InstrumentError::Interrupted`]; an operation that moves
    /// nothing may end as it would have.
    fn interrupt(&mut self) {}
}

/// Carries out `wire`'s actions on `transport` until it is done, and gives its outcome:
/// how polycal's own drivers speak every rule. `stop`, when set, interrupts the machine
/// ([`Wire::interrupt`]) and cuts its waits short.
///
/// # Errors
///
/// The operation's [`InstrumentError`].
pub fn drive<W: Wire + ?Sized, T: Transport + ?Sized>(
    wire: &mut W,
    transport: &mut T,
    stop: Option<&StopFlag>,
) -> Result<W::Output, InstrumentError> {
    let mut interrupted = false;
    let start = Instant::now();
    loop {
        if !interrupted && stop.is_some_and(StopFlag::is_set) {
            interrupted = true;
            wire.interrupt();
        }
        let result = match wire.poll() {
            WireAction::Drain => transport.drain().map(WireEvent::Drained),
            WireAction::ClearInput => transport.clear_input().map(|()| WireEvent::Cleared),
            WireAction::Send(text) => transport.send(&text).map(|()| WireEvent::Sent),
            WireAction::ReadLine(timeout) => transport.read_line(timeout).map(WireEvent::Line),
            WireAction::AwaitInput(timeout) => transport.await_input(timeout).map(WireEvent::Input),
            WireAction::Wait(duration) => {
                match stop {
                    Some(stop) => {
                        stop.sleep(duration);
                    }
                    None => sleep_until(Instant::now() + duration),
                }
                Ok(WireEvent::Waited)
            }
            WireAction::Note { event, text } => {
                transport.note(&event, &text);
                continue;
            }
            WireAction::Done => {
                return wire.outcome().unwrap_or_else(|| {
                    Err(InstrumentError::Reported {
                        port: transport.port().to_string(),
                        message: "the wire rules ended without an outcome".to_string(),
                    })
                });
            }
        };
        let event = result.unwrap_or_else(WireEvent::Failed);
        if let Err(e) = wire.tell(start.elapsed().as_secs_f64(), event) {
            // The actions above answer themselves: a machine that refuses its own answer
            // is a bug of polycal's, reported rather than looped on.
            return Err(InstrumentError::Reported {
                port: transport.port().to_string(),
                message: e.to_string(),
            });
        }
    }
}

fn sleep_until(deadline: Instant) {
    let left = deadline.saturating_duration_since(Instant::now());
    if !left.is_zero() {
        std::thread::sleep(left);
    }
}
