//! The serial port (a real one, a USB adapter or a pseudo-terminal) as a [`ByteStream`],
//! opened with a profile's line settings ([`LineSettings`]).

use std::io::{self, Read, Write};
use std::time::Duration;

use super::InstrumentError;
use super::profile::{FlowControl, LineSettings, Parity};
use super::transport::{ByteStream, StreamTransport};

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

    fn write_stall(&self) -> String {
        format!(
            "the device did not take it within {WRITE_PAUSE_LIMIT_SECONDS} s (flow control held, XOFF, or the line stalled)"
        )
    }
}

/// A [`crate::lab::transport::Transport`] over a serial port, opened exclusively.
pub type SerialTransport = StreamTransport<SerialStream>;

impl StreamTransport<SerialStream> {
    /// Opens `path` with a profile's line settings and discards anything already
    /// received.
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] naming the path if it cannot be opened or configured.
    pub fn open(path: &str, line: &LineSettings) -> Result<SerialTransport, InstrumentError> {
        use super::transport::Transport;
        let port = serialport::new(path, line.baud)
            .data_bits(match line.data_bits {
                5 => serialport::DataBits::Five,
                6 => serialport::DataBits::Six,
                7 => serialport::DataBits::Seven,
                _ => serialport::DataBits::Eight,
            })
            .parity(match line.parity {
                Parity::None => serialport::Parity::None,
                Parity::Even => serialport::Parity::Even,
                Parity::Odd => serialport::Parity::Odd,
            })
            .stop_bits(if line.stop_bits == 2 {
                serialport::StopBits::Two
            } else {
                serialport::StopBits::One
            })
            .flow_control(match line.flow_control {
                FlowControl::None => serialport::FlowControl::None,
                FlowControl::Software => serialport::FlowControl::Software,
                FlowControl::Hardware => serialport::FlowControl::Hardware,
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
