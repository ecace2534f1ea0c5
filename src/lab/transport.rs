//! Line-oriented byte channels with one deadline per reply.
//!
//! A serial port's own timeout applies to each `read()`, not to a line: a device that
//! trickles one byte every 90 ms would never time out against a 100 ms port timeout. The
//! [`Transport`] trait therefore reads a whole reply line against one overall deadline.
//!
//! Lines are split at CR or LF (the ELCOMAT ends replies with CR, the SMC100 with CR LF);
//! empty lines are skipped, and a line longer than [`MAX_LINE_BYTES`] bytes is cut there
//! (it cannot be a valid reply, and the buffer must not grow without end). NUL bytes are
//! dropped as they arrive: a device that pads its replies with them (before a reply or
//! after its terminator) gives the same lines as one that does not. Bytes that are
//! not UTF-8 are replaced (`U+FFFD`): a garbled reply stays visible, never panics.
//!
//! There is one implementation, [`StreamTransport`], over any [`ByteStream`]: every
//! `Read + Write` (in-memory streams, sockets, the simulated devices) is one, and so is the
//! serial port ([`crate::lab::serial`]).

use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use super::InstrumentError;

/// Longest reply line kept, bytes; longer input is cut into lines of this length.
pub const MAX_LINE_BYTES: usize = 1024;

/// A line-oriented byte channel to one device.
pub trait Transport: Send {
    /// The port's name (a device path, or a label for in-memory channels).
    fn port(&self) -> &str;

    /// Writes `text` exactly as given (the caller includes the terminator) and flushes.
    fn send(&mut self, text: &str) -> Result<(), InstrumentError>;

    /// Reads one reply line, terminator removed, waiting at most `timeout` for all of it.
    /// `Ok(None)` when the deadline passed without a complete line.
    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError>;

    /// Discards everything received and not yet read (a stale or late reply).
    fn clear_input(&mut self) -> Result<(), InstrumentError>;

    /// Takes everything received and not yet read, without waiting for more, and returns
    /// it as lines (a last line without its terminator included): what a query discards
    /// before it is sent, and what follows a reply that should have come alone. Nothing
    /// pending gives an empty list.
    fn drain(&mut self) -> Result<Vec<String>, InstrumentError>;

    /// Waits at most `timeout` for input and takes what arrived, as [`Transport::drain`]
    /// does (a line not yet ended included): what follows a reply that should come
    /// alone, watched for as long as another reply takes on the line. Nothing within
    /// `timeout` gives an empty list, which is no timeout of a query (a logging
    /// transport records the lines taken as `discarded`, and nothing else).
    fn await_input(&mut self, timeout: Duration) -> Result<Vec<String>, InstrumentError> {
        let mut lines: Vec<String> = self.read_line(timeout)?.into_iter().collect();
        lines.extend(self.drain()?);
        Ok(lines)
    }

    /// Notes an event about a line already received, e.g. `discarded` for a late reply
    /// read while resynchronising. Only a logging transport records it.
    fn note(&mut self, _event: &str, _text: &str) {}
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn port(&self) -> &str {
        (**self).port()
    }
    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        (**self).send(text)
    }
    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        (**self).read_line(timeout)
    }
    fn clear_input(&mut self) -> Result<(), InstrumentError> {
        (**self).clear_input()
    }
    fn drain(&mut self) -> Result<Vec<String>, InstrumentError> {
        (**self).drain()
    }
    fn await_input(&mut self, timeout: Duration) -> Result<Vec<String>, InstrumentError> {
        (**self).await_input(timeout)
    }
    fn note(&mut self, event: &str, text: &str) {
        (**self).note(event, text)
    }
}

/// The bytes under a [`StreamTransport`]: what it needs of a port.
///
/// Every `Read + Write + Send` type is one: it cannot wait for input, so the transport
/// polls it every millisecond, and it discards input by reading what is there.
/// [`crate::lab::serial::SerialStream`] waits in the operating system and discards with
/// its own call.
pub trait ByteStream: Send {
    /// Writes all of `bytes` and flushes.
    ///
    /// # Errors
    ///
    /// Any error of the stream.
    fn send_bytes(&mut self, bytes: &[u8]) -> io::Result<()>;

    /// Reads what has arrived into `buf`, waiting at most `timeout` for it when the
    /// stream can wait. `Ok(0)` means the peer closed the channel; an error of kind
    /// `WouldBlock`, `TimedOut` or `Interrupted` means "no data yet".
    ///
    /// # Errors
    ///
    /// Any error of the stream.
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;

    /// Discards everything received and not yet read.
    ///
    /// # Errors
    ///
    /// Any error of the stream other than "no data".
    fn discard_input(&mut self) -> io::Result<()>;

    /// Why a write that failed as `TimedOut` stopped, in this port's own terms (how long
    /// it waits out a pause, and for what): the message's end after "sending …: ".
    fn write_stall(&self) -> String {
        "the device did not take it in time".to_string()
    }
}

impl<S: Read + Write + Send> ByteStream for S {
    fn send_bytes(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.write_all(bytes)?;
        self.flush()
    }

    fn receive(&mut self, buf: &mut [u8], _timeout: Duration) -> io::Result<usize> {
        self.read(buf)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        let mut chunk = [0u8; 256];
        // Whatever is already there; a stream that never runs dry is not ours to drain.
        for _ in 0..1024 {
            match self.read(&mut chunk) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e) if is_no_data(&e) => break,
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// Bytes received and not yet returned as lines.
#[derive(Debug, Default)]
struct LineBuffer {
    bytes: Vec<u8>,
}

impl LineBuffer {
    /// Appends bytes received, without their NUL bytes (pad bytes, never part of a reply).
    fn extend(&mut self, received: &[u8]) {
        self.bytes
            .extend(received.iter().copied().filter(|&b| b != 0));
    }

    /// Takes the next complete non-empty line, if there is one.
    fn take_line(&mut self) -> Option<String> {
        loop {
            let end = self.bytes.iter().position(|&b| b == b'\r' || b == b'\n');
            match end {
                Some(0) => {
                    self.bytes.remove(0);
                }
                Some(i) => {
                    let line = String::from_utf8_lossy(&self.bytes[..i]).into_owned();
                    self.bytes.drain(..=i);
                    return Some(line);
                }
                None if self.bytes.len() >= MAX_LINE_BYTES => {
                    let line = String::from_utf8_lossy(&self.bytes[..MAX_LINE_BYTES]).into_owned();
                    self.bytes.drain(..MAX_LINE_BYTES);
                    return Some(line);
                }
                None => return None,
            }
        }
    }

    /// Takes every complete line and then the unterminated rest, if any.
    fn take_all(&mut self) -> Vec<String> {
        let mut lines = Vec::new();
        while let Some(line) = self.take_line() {
            lines.push(line);
        }
        if !self.bytes.is_empty() {
            lines.push(String::from_utf8_lossy(&self.bytes).into_owned());
            self.bytes.clear();
        }
        lines
    }
}

/// How many reads [`Transport::drain`] makes at most: a device that never stops talking
/// must not hold the host.
const MAX_DRAIN_READS: usize = 64;

fn closed(port: &str, context: &str) -> InstrumentError {
    InstrumentError::Closed {
        port: port.to_string(),
        context: context.to_string(),
    }
}

/// Maps an I/O error of a port: a hang-up becomes [`InstrumentError::Closed`].
fn port_error(port: &str, context: &str, e: io::Error) -> InstrumentError {
    match e.kind() {
        io::ErrorKind::BrokenPipe
        | io::ErrorKind::ConnectionReset
        | io::ErrorKind::ConnectionAborted
        | io::ErrorKind::UnexpectedEof
        | io::ErrorKind::NotConnected => closed(port, context),
        _ if e.raw_os_error() == Some(libc::EIO) => closed(port, context),
        _ => InstrumentError::Io {
            port: port.to_string(),
            context: context.to_string(),
            source: e,
        },
    }
}

fn is_no_data(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut | io::ErrorKind::Interrupted
    )
}

/// A [`Transport`] over a [`ByteStream`]: any `Read + Write` (in-memory streams in tests,
/// sockets, …) or a serial port ([`crate::lab::serial::SerialTransport`]).
///
/// `Ok(0)` from the stream means the peer closed the channel; "no data yet" is retried
/// until the deadline, every millisecond for a stream that cannot wait by itself.
#[derive(Debug)]
pub struct StreamTransport<S> {
    name: String,
    stream: S,
    buffer: LineBuffer,
}

impl<S: ByteStream> StreamTransport<S> {
    /// A transport named `name` (used in messages and the traffic log) over `stream`.
    pub fn new(name: impl Into<String>, stream: S) -> Self {
        StreamTransport {
            name: name.into(),
            stream,
            buffer: LineBuffer::default(),
        }
    }

    /// The underlying stream.
    pub fn get_ref(&self) -> &S {
        &self.stream
    }

    /// The underlying stream, mutably.
    pub fn get_mut(&mut self) -> &mut S {
        &mut self.stream
    }
}

impl<S: ByteStream> Transport for StreamTransport<S> {
    fn port(&self) -> &str {
        &self.name
    }

    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        self.stream.send_bytes(text.as_bytes()).map_err(|e| {
            let context = if e.kind() == io::ErrorKind::TimedOut {
                format!("sending {text:?}: {}", self.stream.write_stall())
            } else {
                format!("sending {text:?}")
            };
            port_error(&self.name, &context, e)
        })
    }

    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        let deadline = Instant::now() + timeout;
        let mut chunk = [0u8; 256];
        loop {
            if let Some(line) = self.buffer.take_line() {
                return Ok(Some(line));
            }
            // The stream's wait bounds one read; the line's deadline bounds the whole.
            let remaining = deadline
                .saturating_duration_since(Instant::now())
                .max(Duration::from_millis(1));
            let got_data = match self.stream.receive(&mut chunk, remaining) {
                Ok(0) => return Err(closed(&self.name, "end of input while reading a reply")),
                Ok(n) => {
                    self.buffer.extend(&chunk[..n]);
                    true
                }
                Err(e) if is_no_data(&e) => false,
                Err(e) => return Err(port_error(&self.name, "reading a reply", e)),
            };
            let now = Instant::now();
            if now >= deadline {
                // A line completed by this very read still counts.
                return Ok(self.buffer.take_line());
            }
            if !got_data {
                std::thread::sleep((deadline - now).min(Duration::from_millis(1)));
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), InstrumentError> {
        self.buffer.bytes.clear();
        self.stream
            .discard_input()
            .map_err(|e| port_error(&self.name, "clearing the input", e))
    }

    fn drain(&mut self) -> Result<Vec<String>, InstrumentError> {
        let mut chunk = [0u8; 256];
        for _ in 0..MAX_DRAIN_READS {
            match self.stream.receive(&mut chunk, Duration::ZERO) {
                Ok(0) => return Err(closed(&self.name, "end of input while draining it")),
                Ok(n) => self.buffer.extend(&chunk[..n]),
                Err(e) if is_no_data(&e) => break,
                Err(e) => return Err(port_error(&self.name, "draining the input", e)),
            }
        }
        Ok(self.buffer.take_all())
    }
}
