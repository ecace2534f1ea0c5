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

    /// The time `bytes` bytes take on the line: 10 bits each (start, 8 data, stop).
    ///
    /// ```
    /// use polycal::lab::serial::SerialSettings;
    /// // An ELCOMAT reply, `4 003 12.345000 -1.234000` and CR: 26 bytes, 13.5 ms.
    /// let t = SerialSettings::ELCOMAT.line_time(26);
    /// assert!((t.as_secs_f64() - 0.0135417).abs() < 1e-6);
    /// ```
    pub fn line_time(&self, bytes: usize) -> std::time::Duration {
        std::time::Duration::from_secs_f64(bytes as f64 * 10.0 / f64::from(self.baud_rate.max(1)))
    }

    /// How long a reply is watched for a line after it on this line
    /// ([`crate::lab::QueryOptions::alone_wait`]): twice the time of a reply of
    /// [`REPLY_BYTES`] on the line, plus [`ALONE_MARGIN`] for the adapter's and the
    /// operating system's latency — 47.3 ms for an ELCOMAT at 19200 baud, 26.4 ms for
    /// the SMC100 at 57600.
    ///
    /// ```
    /// use polycal::lab::serial::SerialSettings;
    /// let ms = |d: std::time::Duration| (d.as_secs_f64() * 1e4).round() / 10.0;
    /// assert_eq!(ms(SerialSettings::ELCOMAT.alone_wait()), 47.3);
    /// assert_eq!(ms(SerialSettings::SMC100.alone_wait()), 26.4);
    /// ```
    pub fn alone_wait(&self) -> std::time::Duration {
        self.line_time(2 * REPLY_BYTES) + ALONE_MARGIN
    }
}

/// The bytes of a long reply line of the instruments `run` drives (an ELCOMAT
/// measurement, `4 003 -123.456789 -12.345678` and CR: 30).
pub const REPLY_BYTES: usize = 30;

/// What [`SerialSettings::alone_wait`] adds to the time of the replies on the line: a
/// USB-serial adapter may hold what it received for its latency timer (16 ms, an
/// FTDI's default) before it hands it on.
pub const ALONE_MARGIN: std::time::Duration = std::time::Duration::from_millis(16);

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

impl ByteStream for SerialStream {
    fn send_bytes(&mut self, bytes: &[u8]) -> io::Result<()> {
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
