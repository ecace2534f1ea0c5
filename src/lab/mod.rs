//! The lab: autocollimators (two or more) and a rotary table of any make, described by
//! profiles (the ELCOMAT 3000 and the SMC100 by default), on serial lines or TCP, and the
//! run procedure that drives them through a calibration and keeps every reading on disk
//! (docs/FORMAT.md §7). Built with the cargo feature `lab`.
//!
//! # What flows from the instruments to the run directory
//!
//! ```text
//!  serial line / TCP / pseudo-terminal / in-memory stream (serial, tcp, sim, scripted)
//!        │ bytes
//!  StreamTransport: one reply line per deadline           (transport)
//!        │ lines                ──► traffic.jsonl: every line sent and received (traffic)
//!  ProfileAutocollimator, ProfileTable: a profile's       (profile, driver, query)
//!    commands and replies, the runner's retries
//!        │ AcReading, table position
//!  run::measure: the stops of the plan, every autocollimator at each  (run)
//!        │ Reading                   ──► manifest.json: settings, instruments, outcome
//!  measurement::ReadingWriter ──► measurements.csv: one row per reading, synced before
//!                                 the table moves again
//! ```
//!
//! The modules, from the wire up:
//!
//! - [`transport`]: the [`Transport`](transport::Transport) trait, a line-oriented byte
//!   channel whose `read_line` has one overall deadline per reply (not per `read()`), and
//!   its one implementation [`StreamTransport`](transport::StreamTransport) over any byte
//!   stream;
//! - [`serial`]: the serial port as such a stream ([`serial::SerialTransport`]), and
//!   [`tcp`] a network port (`tcp://HOST:PORT`);
//! - [`scripted`]: an in-memory device for tests, a script of exchanges;
//! - [`traffic`]: [`LoggedTransport`](traffic::LoggedTransport), which records every line
//!   sent and received, with time and port, as JSON Lines (`traffic.jsonl`);
//! - [`profile`]: how an instrument talks — its line, commands and reply templates — read
//!   from TOML; five bundled from the makers' command sets;
//! - [`wire`]: the wire rules (a query's drain, its reply taken alone, resynchronisation,
//!   retries, a motion sent once and watched to its end) as machines that do no input or
//!   output — [`Exchange`], [`driver::AcWire`], [`driver::TableWire`] — for a lab that
//!   hands polycal a port of its own;
//! - [`driver`]: the drivers that speak any profile, behind the [`Autocollimator`] and
//!   [`RotaryTable`] traits: the [`wire`] machines carried out over a transport;
//!   [`check`]: each instrument once, before a run;
//! - [`sim`]: state machines speaking every profile, fed by the simulator's truth model,
//!   served on pseudo-terminals or TCP ports by `polycal sim-lab`;
//! - [`run`]: the run procedure: its settings and plan, the run directory and its
//!   manifest, resuming an interrupted run, and the measuring loop;
//! - `disk`: the run directory's files on a disk that can fill up: lines appended whole
//!   or cut back to the last whole line, and [`WriteBudget`], a byte budget that fails
//!   as a full disk does (for tests).
//!
//! # Retries and motion
//!
//! A *query* (a command whose reply only reports) is retried when its reply is lost,
//! garbled or reports an invalid measurement: the input is cleared and the command sent
//! again, at most [`QueryOptions::retries`] more times (three by default). A *motion*
//! (a profile's move and home, e.g. the SMC100's `1PA`, `1OR`) is never sent twice: after
//! a lost reply the driver asks the state and the position instead. A failing port, a device in a state that
//! forbids going on (disable, error bits) and a query that still fails after its retries
//! end in an [`InstrumentError`] naming the port, what was sent and what came back.
//!
//! # Example: the ELCOMAT driver over an in-memory transport
//!
//! ```
//! use polycal::lab::driver::ProfileAutocollimator;
//! use polycal::lab::scripted::ScriptedStream;
//! use polycal::lab::transport::StreamTransport;
//! use polycal::lab::{Autocollimator, QueryOptions};
//!
//! // What the device answers to each command (the ELCOMAT ends replies with CR).
//! let stream = ScriptedStream::new()
//!     .expect("s\n", "") // stop streaming: no reply
//!     .expect("d\n", "8 ELCOMAT 3000 S/N 4711\r")
//!     .expect("a\n", "4 003 12.345000 -1.234000\r");
//! let written = stream.written();
//! let transport = StreamTransport::new("mem:ac1", stream);
//! let mut ac = ProfileAutocollimator::elcomat3000(transport, QueryOptions::default());
//! ac.start()?;
//! assert_eq!(ac.identify()?, "ELCOMAT 3000 S/N 4711");
//! let reading = ac.measure()?;
//! assert_eq!(reading.x_arcsec, 12.345);
//! assert_eq!(reading.y_arcsec, Some(-1.234));
//! assert_eq!(written.bytes(), b"s\nd\na\n"); // the exact bytes sent
//! # Ok::<(), polycal::lab::InstrumentError>(())
//! ```

pub mod check;
mod disk;
pub mod driver;
mod error;
mod instruments;
mod per_instrument;
pub mod profile;
mod query;
pub mod run;
pub mod scripted;
pub mod serial;
pub mod sim;
mod stop;
pub mod tcp;
pub mod traffic;
pub mod transport;
pub mod wire;

pub use disk::WriteBudget;
pub use error::{InstrumentError, ReplyError};
pub use instruments::{AcReading, Autocollimator, RotaryTable};
pub use per_instrument::PerInstrument;
pub use query::{Exchange, QueryOptions, ReplyReader, Resync};
pub use run::{Action, Event, LogRecord, Outcome, Session, SessionError};
pub use stop::StopFlag;
