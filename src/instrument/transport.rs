//! Line-oriented byte channels with one deadline per reply.
//!
//! A serial port's own timeout applies to each `read()`, not to a line: a device that
//! trickles one byte every 90 ms would never time out against a 100 ms port timeout. The
//! [`Transport`] trait therefore reads a whole reply line against one overall deadline.
//!
//! Lines are split at CR or LF (the ELCOMAT ends replies with CR, the SMC100 with CR LF);
//! empty lines are skipped, and a line longer than [`MAX_LINE`] bytes is cut there (it
//! cannot be a valid reply, and the buffer must not grow without end). Bytes that are not
//! UTF-8 are replaced (`U+FFFD`): a garbled reply stays visible, never panics.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::InstrumentError;

/// Longest reply line kept, bytes; longer input is cut into lines of this length.
pub const MAX_LINE: usize = 1024;

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
}

/// Bytes received and not yet returned as lines.
#[derive(Debug, Default)]
struct LineBuffer {
    bytes: Vec<u8>,
}

impl LineBuffer {
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
                None if self.bytes.len() >= MAX_LINE => {
                    let line = String::from_utf8_lossy(&self.bytes[..MAX_LINE]).into_owned();
                    self.bytes.drain(..MAX_LINE);
                    return Some(line);
                }
                None => return None,
            }
        }
    }
}

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

/// A [`Transport`] over any `Read + Write` (in-memory streams in tests, sockets, …).
///
/// `read()` returning `Ok(0)` means the peer closed the channel; an error of kind
/// `WouldBlock`, `TimedOut` or `Interrupted` means "no data yet" and is retried every
/// millisecond until the deadline.
#[derive(Debug)]
pub struct StreamTransport<S> {
    name: String,
    stream: S,
    buffer: LineBuffer,
}

impl<S: Read + Write + Send> StreamTransport<S> {
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

impl<S: Read + Write + Send> Transport for StreamTransport<S> {
    fn port(&self) -> &str {
        &self.name
    }

    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        let context = format!("sending {text:?}");
        self.stream
            .write_all(text.as_bytes())
            .and_then(|()| self.stream.flush())
            .map_err(|e| port_error(&self.name, &context, e))
    }

    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        let deadline = Instant::now() + timeout;
        let mut chunk = [0u8; 256];
        loop {
            if let Some(line) = self.buffer.take_line() {
                return Ok(Some(line));
            }
            let got_data = match self.stream.read(&mut chunk) {
                Ok(0) => return Err(closed(&self.name, "end of input while reading a reply")),
                Ok(n) => {
                    self.buffer.bytes.extend_from_slice(&chunk[..n]);
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
        let mut chunk = [0u8; 256];
        // Whatever is already there; a stream that never runs dry is not ours to drain.
        for _ in 0..1024 {
            match self.stream.read(&mut chunk) {
                Ok(0) => break,
                Ok(_) => {}
                Err(e) if is_no_data(&e) => break,
                Err(e) => return Err(port_error(&self.name, "clearing the input", e)),
            }
        }
        Ok(())
    }
}

/// Flow control of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlowControl {
    /// None.
    None,
    /// XON/XOFF (software).
    Software,
}

/// Serial line settings; the data format is always 8 data bits, no parity, 1 stop bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SerialSettings {
    /// Baud rate.
    pub baud_rate: u32,
    /// Flow control.
    pub flow_control: FlowControl,
}

impl SerialSettings {
    /// The ELCOMAT 3000: 19200 baud, 8N1, no flow control.
    pub const ELCOMAT: SerialSettings = SerialSettings {
        baud_rate: 19_200,
        flow_control: FlowControl::None,
    };
    /// The SMC100: 57600 baud, 8N1, XON/XOFF.
    pub const SMC100: SerialSettings = SerialSettings {
        baud_rate: 57_600,
        flow_control: FlowControl::Software,
    };
}

/// A [`Transport`] over a serial port (a real one, a USB adapter or a pseudo-terminal),
/// opened exclusively.
pub struct SerialTransport {
    name: String,
    port: Box<dyn serialport::SerialPort>,
    buffer: LineBuffer,
}

impl std::fmt::Debug for SerialTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialTransport")
            .field("name", &self.name)
            .finish_non_exhaustive()
    }
}

impl SerialTransport {
    /// Opens `path` with `settings` (8N1) and discards anything already received.
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] naming the path if it cannot be opened or configured.
    pub fn open(path: &str, settings: SerialSettings) -> Result<SerialTransport, InstrumentError> {
        let open_error = |message: String| InstrumentError::Open {
            port: path.to_string(),
            message,
        };
        let port = serialport::new(path, settings.baud_rate)
            .data_bits(serialport::DataBits::Eight)
            .parity(serialport::Parity::None)
            .stop_bits(serialport::StopBits::One)
            .flow_control(match settings.flow_control {
                FlowControl::None => serialport::FlowControl::None,
                FlowControl::Software => serialport::FlowControl::Software,
            })
            .timeout(Duration::from_millis(100))
            .open()
            .map_err(|e| open_error(e.to_string()))?;
        let mut transport = SerialTransport {
            name: path.to_string(),
            port,
            buffer: LineBuffer::default(),
        };
        transport.clear_input()?;
        Ok(transport)
    }
}

impl Transport for SerialTransport {
    fn port(&self) -> &str {
        &self.name
    }

    fn send(&mut self, text: &str) -> Result<(), InstrumentError> {
        let context = format!("sending {text:?}");
        self.port
            .write_all(text.as_bytes())
            .and_then(|()| self.port.flush())
            .map_err(|e| port_error(&self.name, &context, e))
    }

    fn read_line(&mut self, timeout: Duration) -> Result<Option<String>, InstrumentError> {
        let deadline = Instant::now() + timeout;
        let mut chunk = [0u8; 256];
        loop {
            if let Some(line) = self.buffer.take_line() {
                return Ok(Some(line));
            }
            let now = Instant::now();
            if now >= deadline {
                return Ok(None);
            }
            // The port's timeout bounds one read(); the line's deadline bounds the whole.
            let remaining = (deadline - now).max(Duration::from_millis(1));
            self.port
                .set_timeout(remaining)
                .map_err(|e| port_error(&self.name, "setting the timeout", e.into()))?;
            match self.port.read(&mut chunk) {
                Ok(0) => return Err(closed(&self.name, "end of input while reading a reply")),
                Ok(n) => self.buffer.bytes.extend_from_slice(&chunk[..n]),
                Err(e) if is_no_data(&e) => {}
                Err(e) => return Err(port_error(&self.name, "reading a reply", e)),
            }
        }
    }

    fn clear_input(&mut self) -> Result<(), InstrumentError> {
        self.buffer.bytes.clear();
        self.port
            .clear(serialport::ClearBuffer::Input)
            .map_err(|e| port_error(&self.name, "clearing the input", e.into()))
    }
}

/// A handle on everything written to a [`ScriptedStream`], readable after the stream was
/// moved into a transport.
#[derive(Debug, Clone, Default)]
pub struct WrittenBytes(Arc<Mutex<Vec<u8>>>);

impl WrittenBytes {
    /// Every byte written so far.
    pub fn bytes(&self) -> Vec<u8> {
        self.0.lock().map(|b| b.clone()).unwrap_or_default()
    }

    /// Every byte written so far, as text (invalid UTF-8 replaced).
    pub fn text(&self) -> String {
        String::from_utf8_lossy(&self.bytes()).into_owned()
    }
}

#[derive(Debug)]
struct Exchange {
    sent: Vec<u8>,
    reply: Vec<u8>,
}

/// An in-memory device for tests: a script of exchanges, each the exact bytes expected
/// from the host and the bytes replied to them.
///
/// Reading returns the replies of the exchanges completed so far; with nothing to read it
/// fails with `WouldBlock` (no data yet), or returns end of input once the script is
/// done when [`ScriptedStream::close_when_done`] was asked. Writing bytes that differ
/// from the next expected exchange fails with `InvalidData`, naming both.
#[derive(Debug, Default)]
pub struct ScriptedStream {
    script: VecDeque<Exchange>,
    pending: Vec<u8>,
    readable: VecDeque<u8>,
    written: WrittenBytes,
    close_when_done: bool,
}

impl ScriptedStream {
    /// An empty script.
    pub fn new() -> ScriptedStream {
        ScriptedStream::default()
    }

    /// Adds an exchange: when the host has written exactly `sent`, the device replies
    /// `reply` (may be empty: no reply, or a lost one).
    pub fn expect(mut self, sent: &str, reply: &str) -> ScriptedStream {
        self.script.push_back(Exchange {
            sent: sent.as_bytes().to_vec(),
            reply: reply.as_bytes().to_vec(),
        });
        self
    }

    /// Bytes readable before anything is sent (e.g. a stream the device is already in).
    pub fn initially(mut self, bytes: &str) -> ScriptedStream {
        self.readable.extend(bytes.as_bytes());
        self
    }

    /// Reports end of input (the port closed) once the script is done and read.
    pub fn close_when_done(mut self) -> ScriptedStream {
        self.close_when_done = true;
        self
    }

    /// A handle on the bytes written.
    pub fn written(&self) -> WrittenBytes {
        self.written.clone()
    }

    /// How many exchanges of the script have not happened yet.
    pub fn remaining(&self) -> usize {
        self.script.len()
    }
}

impl Read for ScriptedStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.readable.is_empty() {
            if self.close_when_done && self.script.is_empty() {
                return Ok(0);
            }
            return Err(io::Error::new(io::ErrorKind::WouldBlock, "no data yet"));
        }
        let n = buf.len().min(self.readable.len());
        for (slot, byte) in buf.iter_mut().zip(self.readable.drain(..n)) {
            *slot = byte;
        }
        Ok(n)
    }
}

impl Write for ScriptedStream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if let Ok(mut w) = self.written.0.lock() {
            w.extend_from_slice(buf);
        }
        self.pending.extend_from_slice(buf);
        loop {
            let Some(next) = self.script.front() else {
                if self.pending.is_empty() {
                    return Ok(buf.len());
                }
                let unexpected = String::from_utf8_lossy(&self.pending).into_owned();
                self.pending.clear();
                return Err(io::Error::new(
                    io::ErrorKind::InvalidData,
                    format!("script: unexpected {unexpected:?} after the end of the script"),
                ));
            };
            let n = next.sent.len().min(self.pending.len());
            if self.pending[..n] != next.sent[..n] {
                let message = format!(
                    "script: got {:?}, expected {:?}",
                    String::from_utf8_lossy(&self.pending),
                    String::from_utf8_lossy(&next.sent)
                );
                self.pending.clear();
                return Err(io::Error::new(io::ErrorKind::InvalidData, message));
            }
            if n < next.sent.len() {
                return Ok(buf.len());
            }
            self.pending.drain(..n);
            if let Some(done) = self.script.pop_front() {
                self.readable.extend(done.reply);
            }
        }
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// Sends `command` and reads its reply with `parse`, retrying as a query (module
/// [`crate::instrument`]): after a timeout or a reply `parse` refuses, the input is
/// cleared and the command sent again, up to `options.retries` more times. Returns the
/// parsed value and the reply line. Port failures are not retried.
pub(crate) fn query<T: Transport + ?Sized, V>(
    transport: &mut T,
    options: &super::QueryOptions,
    command: &str,
    parse: impl Fn(&str) -> Result<V, String>,
) -> Result<(V, String), InstrumentError> {
    let attempts = options.retries.saturating_add(1);
    let mut last: Option<(String, String)> = None; // (reply, reason) of the last bad reply
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
            reason,
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
