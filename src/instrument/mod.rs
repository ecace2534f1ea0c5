//! Instruments: the serial-line transport, the ELCOMAT 3000 autocollimator and SMC100
//! rotary-table drivers, a traffic log, and simulated instruments (FORMAT.md §7).
//!
//! The layers, from the wire up:
//!
//! - [`transport`]: the [`Transport`] trait, a line-oriented byte channel whose
//!   [`Transport::read_line`] has one overall deadline per reply (not per `read()`), with
//!   implementations over a serial port ([`SerialTransport`]) and over any `Read + Write`
//!   ([`StreamTransport`], e.g. the in-memory [`ScriptedStream`] of the driver tests);
//! - [`traffic`]: [`LoggedTransport`], which records every line sent and received, with
//!   time and port, as JSON Lines (`traffic.jsonl`);
//! - [`elcomat`] and [`smc100`]: the drivers, behind the [`Autocollimator`] and
//!   [`RotaryTable`] traits;
//! - [`sim`]: state machines speaking both protocols, fed by the simulator's truth model,
//!   served on pseudo-terminals by `polycal sim-lab`.
//!
//! # Retries and motion
//!
//! A *query* (a command whose reply only reports) is retried when its reply is lost,
//! garbled or reports an invalid measurement: the input is cleared and the command sent
//! again, at most [`QueryOptions::retries`] more times (three by default). A *motion*
//! (`1PA`, `1OR`) is never sent twice: after a lost reply the driver asks the state
//! (`1TS`) and the position (`1TP`) instead. A failing port, a device in a state that
//! forbids going on (disable, error bits) and a query that still fails after its retries
//! end in an [`InstrumentError`] naming the port, what was sent and what came back.
//!
//! # Example: the ELCOMAT driver over an in-memory transport
//!
//! ```
//! use polycal::instrument::{Autocollimator, Elcomat3000, QueryOptions, ScriptedStream, StreamTransport};
//!
//! // What the device answers to each command (the ELCOMAT ends replies with CR).
//! let stream = ScriptedStream::new()
//!     .expect("s\n", "") // stop streaming: no reply
//!     .expect("d\n", "8 ELCOMAT 3000 S/N 4711\r")
//!     .expect("a\n", "4 003 12.345000 -1.234000\r");
//! let written = stream.written();
//! let transport = StreamTransport::new("mem:ac1", stream);
//! let mut ac = Elcomat3000::new(transport, QueryOptions::default());
//! ac.start()?;
//! assert_eq!(ac.identify()?, "ELCOMAT 3000 S/N 4711");
//! let reading = ac.measure()?;
//! assert_eq!(reading.x_arcsec, 12.345);
//! assert_eq!(reading.y_arcsec, Some(-1.234));
//! assert_eq!(written.bytes(), b"s\nd\na\n"); // the exact bytes sent
//! # Ok::<(), polycal::instrument::InstrumentError>(())
//! ```

pub mod elcomat;
pub mod sim;
pub mod smc100;
pub mod traffic;
pub mod transport;

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

pub use elcomat::Elcomat3000;
pub use smc100::{ControllerState, Smc100, Smc100Options, TableStatus};
pub use traffic::{LoggedTransport, RunClock, TrafficLog};
pub use transport::{
    ScriptedStream, SerialSettings, SerialTransport, StreamTransport, Transport, WrittenBytes,
};

/// Why an instrument operation failed. Every variant names the port; those about a
/// command say what was sent (terminator included) and what came back.
#[derive(Debug, thiserror::Error)]
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
        reason: String,
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

/// How queries are answered and retried.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QueryOptions {
    /// Deadline for one complete reply line.
    pub reply_timeout: Duration,
    /// How many more times a query is sent after a lost, garbled or invalid reply (the
    /// input is cleared first). A motion is never retried.
    pub retries: u32,
}

impl Default for QueryOptions {
    /// A 1 s reply deadline and three retries.
    fn default() -> Self {
        QueryOptions {
            reply_timeout: Duration::from_secs(1),
            retries: 3,
        }
    }
}

/// A shared flag asking a long operation (a move, a settle time) to stop: set by the
/// Ctrl-C handler, polled by the drivers and the run.
#[derive(Debug, Clone, Default)]
pub struct StopFlag(Arc<AtomicBool>);

impl StopFlag {
    /// A flag that is not set.
    pub fn new() -> StopFlag {
        StopFlag::default()
    }

    /// The shared boolean, e.g. for `signal_hook::flag::register`.
    pub fn shared(&self) -> Arc<AtomicBool> {
        Arc::clone(&self.0)
    }

    /// Asks for a stop.
    pub fn request(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// Whether a stop was asked for.
    pub fn is_set(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }

    /// Sleeps for `duration`, waking early when a stop is asked for; returns whether it was.
    pub fn sleep(&self, duration: Duration) -> bool {
        let end = std::time::Instant::now() + duration;
        loop {
            if self.is_set() {
                return true;
            }
            let now = std::time::Instant::now();
            if now >= end {
                return false;
            }
            std::thread::sleep((end - now).min(Duration::from_millis(20)));
        }
    }
}

/// One autocollimator measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AcReading {
    /// The device's three-digit status, e.g. 3 for `003`.
    pub status: u16,
    /// Measuring axis (X), arcsec; always valid in a returned reading.
    pub x_arcsec: f64,
    /// Second axis (Y), arcsec, when the status says it is valid.
    pub y_arcsec: Option<f64>,
}

/// An autocollimator that gives one absolute two-axis measurement on request.
pub trait Autocollimator {
    /// The port it is connected to (for messages).
    fn port(&self) -> &str;
    /// Puts the device into a known state (stops any stream, clears pending input).
    fn start(&mut self) -> Result<(), InstrumentError>;
    /// The device's identification.
    fn identify(&mut self) -> Result<String, InstrumentError>;
    /// One absolute measurement whose X axis is valid (retried as a query).
    fn measure(&mut self) -> Result<AcReading, InstrumentError>;
}

/// A rotary table that moves to absolute positions in degrees.
pub trait RotaryTable {
    /// The port it is connected to (for messages).
    fn port(&self) -> &str;
    /// Makes the table ready to move: clears pending input, checks the state, homes it
    /// when it is not referenced, and waits until it is ready.
    fn start(&mut self) -> Result<(), InstrumentError>;
    /// The controller's identification.
    fn identify(&mut self) -> Result<String, InstrumentError>;
    /// Moves to `degrees` (the motion command is sent exactly once), waits until the
    /// table is ready, and returns the position it reports.
    fn move_to(&mut self, degrees: f64) -> Result<f64, InstrumentError>;
    /// The position the table reports, degrees.
    fn position(&mut self) -> Result<f64, InstrumentError>;
    /// Stops any motion at once.
    fn stop(&mut self) -> Result<(), InstrumentError>;
}
