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

    /// Waits with `poll(2)`, to the millisecond: a socket's read timeout (`SO_RCVTIMEO`)
    /// counts in the kernel's ticks, so a wait of 1 ms for input that does not come took
    /// 4–12 ms, and every query over TCP, whose reply is followed by such a wait, took
    /// that much longer than over a serial line.
    #[cfg(unix)]
    fn receive(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        use std::os::unix::io::AsRawFd;
        // whole milliseconds, rounded up (at least one), as the read timeout had it
        let ms = i32::try_from(timeout.as_micros().div_ceil(1000))
            .unwrap_or(i32::MAX)
            .max(1);
        let mut wanted = libc::pollfd {
            fd: self.stream.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        // SAFETY: one `pollfd`, alive for the call, on a descriptor open while `self` is.
        let ready = unsafe { libc::poll(&mut wanted, 1, ms) };
        match ready {
            // EINTR comes back as `Interrupted`: "no data yet"
            r if r < 0 => Err(io::Error::last_os_error()),
            0 => Err(io::Error::from(io::ErrorKind::TimedOut)),
            // input, the peer's end or an error: the read returns at once
            _ => self.stream.read(buf),
        }
    }

    #[cfg(not(unix))]
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
