//! The traffic log: every line sent and received, with time and port (`traffic.jsonl`).
//!
//! One JSON object per line:
//!
//! ```text
//! {"t":1.503221,"device":"table","port":"/dev/pts/7","event":"sent","text":"1PA45\r\n"}
//! {"t":1.504010,"device":"table","port":"/dev/pts/7","event":"received","text":"1TS000028"}
//! ```
//!
//! - `t`: seconds since the run started (the clock of the measurement file's `time`);
//! - `device`: `ac1`, `ac2` or `table`; `port`: the port's name;
//! - `event`: `sent` (`text` is exactly what was written, terminator included),
//!   `received` (one reply line, terminator removed), `timeout` (no complete reply before
//!   the deadline), `clear` (pending input discarded before a retry), `error` (the port
//!   failed; `text` says how), or `session` (a run or a resumed run started; `text`
//!   says which).
//!
//! Each record is written with one `write` call straight to the file, so that a killed
//! process leaves every record it made; [`TrafficLog::sync`] puts them on disk. A record
//! that cannot be written (a full disk) is cut back out of the file, so that the log ends
//! on a whole line, and nothing more is recorded: [`TrafficLog::check`] and
//! [`TrafficLog::sync`] give the error, and the run stops (docs/FORMAT.md §7.3).

use std::io::{self, Write};
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::InstrumentError;
use super::disk::{LineFile, WriteBudget};
use super::transport::Transport;

/// The run's clock: seconds since the run started, monotonic within one process.
#[derive(Debug, Clone, Copy)]
pub struct RunClock {
    origin: Instant,
    offset_seconds: f64,
}

impl RunClock {
    /// A clock that reads `offset_seconds` now (0 for a new run; the time since the first
    /// start for a resumed one).
    pub fn new(offset_seconds: f64) -> RunClock {
        RunClock {
            origin: Instant::now(),
            offset_seconds,
        }
    }

    /// Seconds since the run started.
    pub fn now(&self) -> f64 {
        self.offset_seconds + self.origin.elapsed().as_secs_f64()
    }
}

/// Where the records go.
enum Sink {
    /// Any writer (e.g. memory).
    Writer(Box<dyn Write + Send>),
    /// A file, line by line.
    File(LineFile),
}

struct LogInner {
    sink: Sink,
    error: Option<io::Error>,
}

/// A shared, cloneable traffic log (JSON Lines, see the [module documentation](self)).
///
/// Write errors do not disturb the instruments: the first one is kept (and nothing more
/// is written) and returned by [`TrafficLog::check`] and [`TrafficLog::sync`], which the
/// run calls after every exchange and before every move.
#[derive(Clone)]
pub struct TrafficLog {
    inner: Arc<Mutex<LogInner>>,
    clock: RunClock,
}

impl std::fmt::Debug for TrafficLog {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TrafficLog")
            .field("clock", &self.clock)
            .finish_non_exhaustive()
    }
}

impl TrafficLog {
    /// A log writing to `writer` (e.g. a `Vec<u8>` behind a lock in tests).
    pub fn new(writer: impl Write + Send + 'static, clock: RunClock) -> TrafficLog {
        TrafficLog {
            inner: Arc::new(Mutex::new(LogInner {
                sink: Sink::Writer(Box::new(writer)),
                error: None,
            })),
            clock,
        }
    }

    /// A log appending to the file at `path` (created if missing), which must end on a
    /// whole line.
    ///
    /// # Errors
    ///
    /// Any error creating or opening the file.
    pub fn append_to(path: &Path, clock: RunClock) -> io::Result<TrafficLog> {
        TrafficLog::append_to_with_budget(path, clock, &WriteBudget::unlimited())
    }

    /// As [`TrafficLog::append_to`], writing through `budget` (a full disk, simulated).
    ///
    /// # Errors
    ///
    /// Any error creating or opening the file.
    pub fn append_to_with_budget(
        path: &Path,
        clock: RunClock,
        budget: &WriteBudget,
    ) -> io::Result<TrafficLog> {
        let file = LineFile::open(path, false, budget)?;
        Ok(TrafficLog {
            inner: Arc::new(Mutex::new(LogInner {
                sink: Sink::File(file),
                error: None,
            })),
            clock,
        })
    }

    /// The log's clock.
    pub fn clock(&self) -> RunClock {
        self.clock
    }

    /// Records one event (see the [module documentation](self) for the fields).
    pub fn record(&self, device: &str, port: &str, event: &str, text: &str) {
        let quote = |s: &str| serde_json::Value::from(s).to_string();
        let line = format!(
            "{{\"t\":{},\"device\":{},\"port\":{},\"event\":{},\"text\":{}}}\n",
            serde_json::Value::from(self.clock.now()),
            quote(device),
            quote(port),
            quote(event),
            quote(text)
        );
        if let Ok(mut inner) = self.inner.lock() {
            if inner.error.is_some() {
                return;
            }
            let written = match &mut inner.sink {
                Sink::Writer(w) => w.write_all(line.as_bytes()).and_then(|()| w.flush()),
                Sink::File(file) => file.append_line(line.as_bytes()),
            };
            if let Err(e) = written {
                inner.error = Some(e);
            }
        }
    }

    /// The first write error, if any (without putting anything on disk).
    ///
    /// # Errors
    ///
    /// The first write error.
    pub fn check(&self) -> io::Result<()> {
        let inner = self
            .inner
            .lock()
            .map_err(|_| io::Error::other("the traffic log's lock is poisoned"))?;
        match &inner.error {
            // An `io::Error` cannot be cloned: the same kind and text.
            Some(e) => Err(match e.raw_os_error() {
                Some(code) => io::Error::from_raw_os_error(code),
                None => io::Error::new(e.kind(), e.to_string()),
            }),
            None => Ok(()),
        }
    }

    /// Returns the first write error, if any, else puts the file on disk (`fsync` of its
    /// data) when the log is a file.
    ///
    /// # Errors
    ///
    /// The first write error, or the error of the sync.
    pub fn sync(&self) -> io::Result<()> {
        self.check()?;
        let inner = self
            .inner
            .lock()
            .map_err(|_| io::Error::other("the traffic log's lock is poisoned"))?;
        match &inner.sink {
            Sink::File(file) => file.sync_data(),
            Sink::Writer(_) => Ok(()),
        }
    }
}

/// A [`Transport`] that records everything passing through it in a [`TrafficLog`].
///
/// A line is recorded as `sent` just before it is written, so that the log never misses
/// a command that may have reached the device.
#[derive(Debug)]
pub struct LoggedTransport<T> {
    inner: T,
    device: String,
    log: TrafficLog,
}

impl<T: Transport> LoggedTransport<T> {
    /// Wraps `inner`; `device` (`ac1`, `ac2`, `table`) names it in the log.
    pub fn new(inner: T, device: impl Into<String>, log: TrafficLog) -> Self {
        LoggedTransport {
            inner,
            device: device.into(),
            log,
        }
    }

    /// The wrapped transport.
    pub fn into_inner(self) -> T {
        self.inner
    }

    fn error(&self, e: &InstrumentError) {
        self.log
            .record(&self.device, self.inner.port(), "error", &e.to_string());
    }
}

impl<T: Transport> Transport for LoggedTransport<T> {
    fn port(&self) -> &str {
        self.inner.port()
    }

    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        self.log
            .record(&self.device, self.inner.port(), "sent", text);
        self.inner.send(text).inspect_err(|e| self.error(e))
    }

    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        match self.inner.read_line(timeout) {
            Ok(Some(line)) => {
                self.log
                    .record(&self.device, self.inner.port(), "received", &line);
                Ok(Some(line))
            }
            Ok(None) => {
                let text = format!("no complete reply within {} ms", timeout.as_millis());
                self.log
                    .record(&self.device, self.inner.port(), "timeout", &text);
                Ok(None)
            }
            Err(e) => {
                self.error(&e);
                Err(e)
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), InstrumentError> {
        self.log
            .record(&self.device, self.inner.port(), "clear", "");
        self.inner.clear_input().inspect_err(|e| self.error(e))
    }

    fn drain(&mut self) -> Result<Vec<String>, InstrumentError> {
        let lines = self.inner.drain().inspect_err(|e| self.error(e))?;
        for line in &lines {
            self.log
                .record(&self.device, self.inner.port(), "discarded", line);
        }
        Ok(lines)
    }

    fn await_input(&mut self, timeout: Duration) -> Result<Vec<String>, InstrumentError> {
        let lines = self
            .inner
            .await_input(timeout)
            .inspect_err(|e| self.error(e))?;
        for line in &lines {
            self.log
                .record(&self.device, self.inner.port(), "discarded", line);
        }
        Ok(lines)
    }

    fn note(&mut self, event: &str, text: &str) {
        self.log
            .record(&self.device, self.inner.port(), event, text);
    }
}
