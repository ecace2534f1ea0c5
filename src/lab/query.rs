//! Queries: commands whose reply only reports, how a reply is tied to the query that
//! asked for it, and how a query is retried (see [`crate::lab`], *Retries and motion*,
//! and docs/FORMAT.md §7.3, *No reading on the wrong stop*).

use std::time::Duration;

use super::transport::Transport;
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

/// What follows a reply: what is pending, and — when nothing is — whatever arrives
/// within `options.alone_wait` (a line, or part of one).
fn after_reply<T: Transport + ?Sized>(
    transport: &mut T,
    options: &QueryOptions,
) -> Result<Vec<String>, InstrumentError> {
    let extra = transport.drain()?;
    if extra.is_empty() && !options.alone_wait.is_zero() {
        return transport.await_input(options.alone_wait);
    }
    Ok(extra)
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
#[derive(Clone, Copy)]
pub(crate) struct Resync<'a> {
    /// The command, terminator included.
    pub(crate) command: &'a str,
    /// Whether a line is the command's reply.
    pub(crate) is_reply: &'a dyn Fn(&str) -> bool,
}

/// How many lines a resynchronisation reads at most before it gives up.
const MAX_RESYNC_LINES: usize = 32;

/// Brings the device back in step: sends `resync.command` and reads until its reply,
/// noting every line before it as discarded (a late or extra reply to an earlier
/// query). A device answers in order, so nothing sent before the resynchronisation can
/// arrive after its reply. `Ok(false)` when its reply did not come.
pub(crate) fn resync<T: Transport + ?Sized>(
    transport: &mut T,
    options: &QueryOptions,
    resync: &Resync<'_>,
) -> Result<bool, InstrumentError> {
    transport.drain()?;
    transport.send(resync.command)?;
    for _ in 0..MAX_RESYNC_LINES {
        match transport.read_line(options.reply_timeout)? {
            None => return Ok(false),
            Some(line) if (resync.is_reply)(&line) => {
                // Whatever came with it is older than any query still to come.
                transport.drain()?;
                return Ok(true);
            }
            Some(line) => transport.note("discarded", &line),
        }
    }
    Ok(false)
}

/// Sends `command` and reads its reply with `parse`, retrying as a query (module
/// [`crate::lab`]). Returns the parsed value and the reply line. Port failures are not
/// retried.
///
/// A reply is taken only when it is tied to this query beyond doubt:
///
/// - whatever is pending before the command is sent is drained (and logged as
///   discarded): it answers an earlier command;
/// - a reply that `parse` accepts but that is followed by more input — pending, or
///   arriving within `options.alone_wait`, the time another reply line takes on the
///   wire — is not taken ([`ReplyError::NotAlone`]): a late reply to an earlier query
///   read as this one's answer has this one's own reply right behind it;
/// - after a reply that did not come in time or was not taken for that reason, the
///   device is resynchronised with `resync` (when the driver has one) before the command
///   is sent again, so that a late reply is discarded when it arrives instead of being
///   read as the answer to the retry.
///
/// A reply `parse` refuses is retried after the drain alone. At most
/// `options.retries` more attempts are made.
pub(crate) fn query<T: Transport + ?Sized, V>(
    transport: &mut T,
    options: &QueryOptions,
    resync_with: Option<&Resync<'_>>,
    command: &str,
    parse: impl Fn(&str) -> Result<V, ReplyError>,
) -> Result<(V, String), InstrumentError> {
    let attempts = options.retries.saturating_add(1);
    let mut last: Option<(String, ReplyError)> = None; // (reply, reason) of the last bad reply
    let mut timed_out = false;
    let mut out_of_step = false;
    for attempt in 1..=attempts {
        if attempt > 1
            && out_of_step
            && let Some(with) = resync_with
            && !resync(transport, options, with)?
        {
            // The device did not come back in step: this attempt is spent on it.
            timed_out = true;
            continue;
        }
        transport.drain()?;
        transport.send(command)?;
        match transport.read_line(options.reply_timeout)? {
            None => {
                timed_out = true;
                out_of_step = true;
            }
            Some(line) => match parse(&line) {
                Ok(value) => {
                    let extra = after_reply(transport, options)?;
                    if extra.is_empty() {
                        return Ok((value, line));
                    }
                    timed_out = false;
                    out_of_step = true;
                    last = Some((
                        line,
                        ReplyError::NotAlone {
                            extra: extra.join(" | "),
                        },
                    ));
                }
                Err(reason) => {
                    timed_out = false;
                    out_of_step = false;
                    last = Some((line, reason));
                }
            },
        }
    }
    let port = transport.port().to_string();
    match last {
        Some((received, reason)) if !timed_out => Err(InstrumentError::BadReply {
            port,
            sent: command.to_string(),
            received,
            reason: Box::new(reason),
            attempts,
        }),
        _ => Err(InstrumentError::Timeout {
            port,
            sent: command.to_string(),
            timeout: options.reply_timeout,
            attempts,
        }),
    }
}
