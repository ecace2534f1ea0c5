//! Queries: commands whose reply only reports, and how they are retried (see
//! [`crate::lab`], *Retries and motion*).

use std::time::Duration;

use super::transport::Transport;
use super::{InstrumentError, ReplyError};

/// How queries are answered and retried.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct QueryOptions {
    /// Deadline for one complete reply line.
    pub reply_timeout: Duration,
    /// How many more times a query is sent after a lost, garbled or invalid reply (the
    /// input is cleared first). A motion is never retried.
    pub retries: u32,
}

impl QueryOptions {
    /// Options with a deadline for one reply line and a number of retries.
    pub fn new(reply_timeout: Duration, retries: u32) -> QueryOptions {
        QueryOptions {
            reply_timeout,
            retries,
        }
    }
}

impl Default for QueryOptions {
    /// A 1 s reply deadline and three retries.
    fn default() -> Self {
        QueryOptions::new(Duration::from_secs(1), 3)
    }
}

/// Sends `command` and reads its reply with `parse`, retrying as a query (module
/// [`crate::lab`]): after a timeout or a reply `parse` refuses, the input is
/// cleared and the command sent again, up to `options.retries` more times. Returns the
/// parsed value and the reply line. Port failures are not retried.
pub(crate) fn query<T: Transport + ?Sized, V>(
    transport: &mut T,
    options: &QueryOptions,
    command: &str,
    parse: impl Fn(&str) -> Result<V, ReplyError>,
) -> Result<(V, String), InstrumentError> {
    let attempts = options.retries.saturating_add(1);
    let mut last: Option<(String, ReplyError)> = None; // (reply, reason) of the last bad reply
    let mut timed_out = false;
    for attempt in 1..=attempts {
        if attempt > 1 {
            transport.clear_input()?;
        }
        transport.send(command)?;
        match transport.read_line(options.reply_timeout)? {
            None => timed_out = true,
            Some(line) => match parse(&line) {
                Ok(value) => return Ok((value, line)),
                Err(reason) => {
                    timed_out = false;
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
