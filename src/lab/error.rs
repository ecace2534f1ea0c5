//! Why an instrument operation failed, and why a reply line was refused.

use std::time::Duration;

/// Why an instrument operation failed. Every variant names the port; those about a
/// command say what was sent (terminator included) and what came back.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum InstrumentError {
    /// The port could not be opened or configured.
    #[error("{port}: cannot open the port: {message}")]
    Open {
        /// The port (device path).
        port: String,
        /// Why, as the operating system said.
        message: String,
    },
    /// No complete reply line arrived before the deadline, on every attempt.
    #[error("{port}: no reply to {sent:?} within {} ms ({attempts} attempt{})", timeout.as_millis(), if *attempts == 1 { "" } else { "s" })]
    Timeout {
        /// The port.
        port: String,
        /// The command, as sent.
        sent: String,
        /// The deadline of one reply.
        timeout: Duration,
        /// How many times the command was sent.
        attempts: u32,
    },
    /// A reply that is not what the protocol allows for the command (garbled, wrong
    /// type, a measurement whose X axis is not valid), on every attempt.
    #[error("{port}: reply {received:?} to {sent:?}: {reason} ({attempts} attempt{})", if *attempts == 1 { "" } else { "s" })]
    BadReply {
        /// The port.
        port: String,
        /// The command, as sent.
        sent: String,
        /// The last reply line received (terminator removed).
        received: String,
        /// What is wrong with it.
        reason: Box<ReplyError>,
        /// How many times the command was sent.
        attempts: u32,
    },
    /// The device reports a state that forbids going on (disable state, error bits, a
    /// refused command, a move that did not arrive).
    #[error("{port}: {message} (after {sent:?}, reply {received:?})")]
    Device {
        /// The port.
        port: String,
        /// The command whose reply showed the state.
        sent: String,
        /// The reply line.
        received: String,
        /// What the state means, and what to do.
        message: String,
    },
    /// The port was closed under us (device unplugged, simulator gone).
    #[error("{port}: the port was closed ({context})")]
    Closed {
        /// The port.
        port: String,
        /// While doing what.
        context: String,
    },
    /// Another input/output error of the port.
    #[error("{port}: {context}: {source}")]
    Io {
        /// The port.
        port: String,
        /// While doing what.
        context: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A failure that lab software reported for an instrument it drives itself (a driver
    /// of the run's session other than `polycal run`'s own: docs/FORMAT.md §7.6), in its
    /// own words.
    #[error("{port}: {message} (reported by its driver)")]
    Reported {
        /// The port (or the name the driver gives the instrument).
        port: String,
        /// What failed, as the driver said.
        message: String,
    },
    /// The operation was abandoned because a stop was requested (Ctrl-C).
    #[error("{port}: stopped on request")]
    Interrupted {
        /// The port of the operation that was abandoned.
        port: String,
    },
}

impl InstrumentError {
    /// Whether a stop request, not a failure, ended the operation.
    pub fn is_interrupted(&self) -> bool {
        matches!(self, InstrumentError::Interrupted { .. })
    }
}

/// Why a reply line is not what the protocol allows for the command that was sent: the
/// reason of [`InstrumentError::BadReply`], as the drivers of [`crate::lab::driver`] read
/// a reply against its profile.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ReplyError {
    /// A value that is not a finite number.
    #[error("{name} {text:?} is not a finite number")]
    NotFinite {
        /// Which value: `X`, `Y` or `position`.
        name: &'static str,
        /// The text received.
        text: String,
    },
    /// A measurement whose measuring axis (X) is not valid.
    #[error("X axis not valid (status {status}: no reflected light, or out of range)")]
    XNotValid {
        /// The status as received.
        status: String,
    },
    /// A reply that does not have the form its profile gives.
    #[error("not of the form `{form}`")]
    NotTheForm {
        /// The reply's template, as in the profile.
        form: String,
    },
    /// A reply that says the device refused the command (a profile's `refusal`).
    #[error("the device refused the command (a reply of the form `{form}`)")]
    Refused {
        /// The refusal's template, as in the profile.
        form: String,
    },
    /// A reply followed at once by more input: which line answers the query cannot be
    /// told, so neither is taken.
    #[error("followed at once by {extra:?}: which line answers the query cannot be told")]
    NotAlone {
        /// The line(s) that followed, joined by ` | `.
        extra: String,
    },
}
