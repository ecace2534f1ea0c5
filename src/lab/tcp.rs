//! An instrument on the network: a TCP connection (`tcp://HOST:PORT`) as a
//! [`ByteStream`], e.g. an Aerotech controller's ASCII command interface or a PI
//! controller's Ethernet port.

use std::io::{self, Read, Write};
use std::net::{TcpStream, ToSocketAddrs};
use std::time::Duration;

use super::InstrumentError;
use super::transport::{ByteStream, StreamTransport, Transport};

/// How long a connection may take to open, and a write to go out.
pub const CONNECT_TIMEOUT: Duration = Duration::from_secs(5);

/// The address of a port named `tcp://HOST:PORT`, or `None` for any other name (a serial
/// device).
///
/// ```
/// use polycal::lab::tcp::tcp_address;
/// assert_eq!(tcp_address("tcp://192.168.1.20:8000"), Some("192.168.1.20:8000"));
/// assert_eq!(tcp_address("/dev/ttyUSB0"), None);
/// ```
pub fn tcp_address(port: &str) -> Option<&str> {
    port.strip_prefix("tcp://")
}

/// An open TCP connection: waits for input in the operating system, discards input by
/// reading what is there without waiting.
#[derive(Debug)]
pub struct TcpPort {
    stream: TcpStream,
}

impl ByteStream for TcpPort {
    fn send_bytes(&mut self, bytes: &[u8]) -> io::Result<()> {
        self.stream.write_all(bytes)?;
        self.stream.flush()
    }

    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.stream
            .set_read_timeout(Some(timeout.max(Duration::from_millis(1))))?;
        self.stream.read(buf)
    }

    fn discard_input(&mut self) -> io::Result<()> {
        self.stream.set_nonblocking(true)?;
        let mut chunk = [0u8; 512];
        let result = loop {
            match self.stream.read(&mut chunk) {
                Ok(0) => break Err(io::Error::from(io::ErrorKind::UnexpectedEof)),
                Ok(_) => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break Ok(()),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => break Err(e),
            }
        };
        self.stream.set_nonblocking(false)?;
        result
    }

    fn write_stall(&self) -> String {
        format!(
            "the instrument did not take it within {} s (its receive window stayed full, or the network stalled)",
            CONNECT_TIMEOUT.as_secs()
        )
    }
}

/// A [`Transport`] over a TCP connection.
pub type TcpTransport = StreamTransport<TcpPort>;

impl StreamTransport<TcpPort> {
    /// Connects to `tcp://HOST:PORT` (`name`, as given) and discards anything already
    /// received.
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] naming the port if the name is not `tcp://HOST:PORT` or
    /// the connection cannot be made within [`CONNECT_TIMEOUT`].
    pub fn connect(name: &str) -> Result<TcpTransport, InstrumentError> {
        let open_error = |message: String| InstrumentError::Open {
            port: name.to_string(),
            message,
        };
        let address = tcp_address(name)
            .ok_or_else(|| open_error("a network port is named tcp://HOST:PORT".into()))?;
        let addresses: Vec<_> = address
            .to_socket_addrs()
            .map_err(|e| open_error(format!("{address}: {e}")))?
            .collect();
        let mut last = None;
        for socket in addresses {
            match TcpStream::connect_timeout(&socket, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    let _ = stream.set_nodelay(true);
                    stream
                        .set_write_timeout(Some(CONNECT_TIMEOUT))
                        .map_err(|e| open_error(e.to_string()))?;
                    let mut transport = StreamTransport::new(name, TcpPort { stream });
                    transport.clear_input()?;
                    return Ok(transport);
                }
                Err(e) => last = Some(e),
            }
        }
        Err(open_error(last.map_or_else(
            || format!("{address} names no address"),
            |e| e.to_string(),
        )))
    }
}
