//! The serial port (a real one, a USB adapter or a pseudo-terminal) as a [`ByteStream`],
//! and its line settings.

use std::io::{self, Read, Write};
use std::time::Duration;

use super::InstrumentError;
use super::transport::{ByteStream, StreamTransport};

/// Flow control of a serial line.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum FlowControl {
    /// None.
    None,
    /// XON/XOFF (software).
    Software,
}

/// Serial line settings; the data format is always 8 data bits, no parity, 1 stop bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub struct SerialSettings {
    /// Baud rate.
    pub baud_rate: u32,
    /// Flow control.
    pub flow_control: FlowControl,
}

impl SerialSettings {
    /// The ELCOMAT 3000: 19200 baud, 8N1, no flow control.
    pub const ELCOMAT: SerialSettings = SerialSettings::new(19_200, FlowControl::None);
    /// The SMC100: 57600 baud, 8N1, XON/XOFF.
    pub const SMC100: SerialSettings = SerialSettings::new(57_600, FlowControl::Software);

    /// Settings of a line: baud rate and flow control (8N1).
    pub const fn new(baud_rate: u32, flow_control: FlowControl) -> SerialSettings {
        SerialSettings {
            baud_rate,
            flow_control,
        }
    }
}

/// An open serial port: waits for input in the operating system (the port's timeout set
/// to what is left of the reply's deadline before each read) and discards input with the
/// driver's own call.
pub struct SerialStream {
    port: Box<dyn serialport::SerialPort>,
}

impl std::fmt::Debug for SerialStream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SerialStream").finish_non_exhaustive()
    }
}

/// How long a write waits out a flow-control pause (the device holding XOFF, or a full
/// output buffer) before it fails, seconds: a device may pause the host for a moment
/// (the SMC100 while it is busy); one that holds it longer than this is not answering.
pub const WRITE_PAUSE_LIMIT_SECONDS: u64 = 10;

impl ByteStream for SerialStream {
    /// Writes with the port's timeout set to [`WRITE_PAUSE_LIMIT_SECONDS`] (the reads set
    /// their own before each read, down to none while draining): a write stopped by XOFF
    /// waits for XON that long, then fails as `TimedOut`.
    fn send_bytes(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.port
            .set_timeout(Duration::from_secs(WRITE_PAUSE_LIMIT_SECONDS))?;
        self.port.write_all(bytes)?;
        self.port.flush()
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.port.set_timeout(timeout)?;
        self.port.read(buf)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        Ok(self.port.clear(serialport::ClearBuffer::Input)?)
    }
}

/// A [`crate::lab::transport::Transport`] over a serial port, opened exclusively.
pub type SerialTransport = StreamTransport<SerialStream>;

impl StreamTransport<SerialStream> {
    /// Opens `path` with `settings` (8N1) and discards anything already received.
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] naming the path if it cannot be opened or configured.
    pub fn open(path: &str, settings: SerialSettings) -> Result<SerialTransport, InstrumentError> {
        use super::transport::Transport;
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
            .map_err(|e| InstrumentError::Open {
                port: path.to_string(),
                message: e.to_string(),
            })?;
        let mut transport = StreamTransport::new(path, SerialStream { port });
        transport.clear_input()?;
        Ok(transport)
    }
}
