//! The simulated lab on pseudo-terminals: what `polycal sim-lab` serves.

use std::io::{Read, Write};
use std::os::unix::io::AsRawFd;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use serialport::{SerialPort, TTYPort};

use super::{Devices, Endpoint, RemountError, World, lock};
use crate::lab::{InstrumentError, PerInstrument};
use crate::simulate::Truth;

/// The device paths a client opens, one per simulated instrument: autocollimators
/// 1 … K and the table (in JSON `ac1`, `ac2`, `table`, `ac3`, …).
pub type LabPaths = PerInstrument<String>;

/// Each device with its label (`ac1`, `ac2`, …, `table`), the table last.
fn labelled(autocollimators: Vec<Endpoint>, table: Endpoint) -> Vec<(String, Endpoint)> {
    let mut endpoints: Vec<(String, Endpoint)> = (1..)
        .zip(autocollimators)
        .map(|(number, e)| (format!("ac{number}"), e))
        .collect();
    endpoints.push(("table".to_string(), table));
    endpoints
}

/// The paths of [`labelled`]'s devices, in its order.
fn paths_of(mut names: Vec<String>) -> LabPaths {
    let table = names.pop().unwrap_or_default();
    PerInstrument::new(names, table)
}

/// Three simulated instruments served on pseudo-terminals, each by its own thread.
///
/// The lab keeps both ends of every pseudo-terminal open, so that clients may come and
/// go (a killed run, a resumed one) without the devices noticing. It lifts the
/// terminal's exclusive mode (`TIOCNXCL`) every 100 ms, so that a client killed before
/// it could lift it does not lock the next one out; two clients at once are still kept
/// apart by the lock serialport takes on the port.
pub struct Lab {
    paths: LabPaths,
    world: Arc<std::sync::Mutex<World>>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for Lab {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Lab")
            .field("paths", &self.paths)
            .finish_non_exhaustive()
    }
}

impl Lab {
    /// Opens one pseudo-terminal per device and starts serving `devices` on them.
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] when a pseudo-terminal cannot be created.
    pub fn start(devices: Devices) -> Result<Lab, InstrumentError> {
        let stop = Arc::new(AtomicBool::new(false));
        let Devices {
            world,
            autocollimators,
            table,
        } = devices;
        let mut threads = Vec::new();
        let mut names = Vec::new();
        let endpoints = labelled(autocollimators, table);
        for (label, endpoint) in endpoints {
            let (master, slave) = TTYPort::pair().map_err(|e| InstrumentError::Open {
                port: format!("pseudo-terminal for {label}"),
                message: e.to_string(),
            })?;
            let name = slave.name().ok_or_else(|| InstrumentError::Open {
                port: format!("pseudo-terminal for {label}"),
                message: "it has no device path".into(),
            })?;
            names.push(name);
            let stop = Arc::clone(&stop);
            let handle = std::thread::Builder::new()
                .name(format!("sim-{label}"))
                .spawn(move || serve(master, slave, endpoint, &stop))
                .map_err(|e| InstrumentError::Open {
                    port: format!("pseudo-terminal for {label}"),
                    message: format!("cannot start its thread: {e}"),
                })?;
            threads.push(handle);
        }
        Ok(Lab {
            paths: paths_of(names),
            world,
            stop,
            threads,
        })
    }

    /// Starts serving `devices` on TCP ports of 127.0.0.1 instead, one per device: the
    /// paths are `tcp://127.0.0.1:PORT`. A device serves one connection at a time and
    /// takes the next when it closes; a `close` fault closes the connection and stops
    /// listening (the port is gone).
    ///
    /// # Errors
    ///
    /// [`InstrumentError::Open`] when a port cannot be bound.
    pub fn start_tcp(devices: Devices) -> Result<Lab, InstrumentError> {
        let stop = Arc::new(AtomicBool::new(false));
        let Devices {
            world,
            autocollimators,
            table,
        } = devices;
        let mut threads = Vec::new();
        let mut names = Vec::new();
        let endpoints = labelled(autocollimators, table);
        for (label, endpoint) in endpoints {
            let open_error = |message: String| InstrumentError::Open {
                port: format!("TCP port for {label}"),
                message,
            };
            let listener = std::net::TcpListener::bind("127.0.0.1:0")
                .map_err(|e| open_error(e.to_string()))?;
            let address = listener
                .local_addr()
                .map_err(|e| open_error(e.to_string()))?;
            listener
                .set_nonblocking(true)
                .map_err(|e| open_error(e.to_string()))?;
            names.push(format!("tcp://{address}"));
            let stop = Arc::clone(&stop);
            let handle = std::thread::Builder::new()
                .name(format!("sim-{label}"))
                .spawn(move || serve_tcp(listener, endpoint, &stop))
                .map_err(|e| open_error(format!("cannot start its thread: {e}")))?;
            threads.push(handle);
        }
        Ok(Lab {
            paths: paths_of(names),
            world,
            stop,
            threads,
        })
    }

    /// The device paths.
    pub fn paths(&self) -> &LabPaths {
        &self.paths
    }

    /// A copy of the truth the readings are drawn from.
    pub fn truth(&self) -> Truth {
        lock(&self.world).truth().clone()
    }

    /// The operator remounts the polygon for the simulation's next setup
    /// ([`World::remount`]).
    ///
    /// # Errors
    ///
    /// [`RemountError::LastMounting`]: the last setup is mounted already.
    pub fn remount(&self) -> Result<u32, RemountError> {
        lock(&self.world).remount()
    }

    /// Stops serving and closes the pseudo-terminals.
    pub fn shutdown(mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for handle in self.threads.drain(..) {
            let _ = handle.join();
        }
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

fn release_exclusive(slave: &TTYPort) {
    #[cfg(target_os = "linux")]
    // SAFETY: TIOCNXCL takes no argument and only clears a flag of the terminal; the
    // descriptor is open for as long as `slave` lives.
    unsafe {
        libc::ioctl(slave.as_raw_fd(), libc::TIOCNXCL);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = slave.as_raw_fd();
}

/// XOFF (DC3): the receiver asks the sender to pause.
const XOFF: u8 = 0x13;
/// XON (DC1): the sender may go on.
const XON: u8 = 0x11;

fn serve(mut master: TTYPort, slave: TTYPort, mut endpoint: Endpoint, stop: &AtomicBool) {
    let _ = master.set_timeout(Duration::from_millis(10));
    let mut buf = [0u8; 512];
    let mut last_release = Instant::now();
    // When an `xoff` fault's pause ends (XON due).
    let mut xon_at: Option<Instant> = None;
    while !stop.load(Ordering::SeqCst) {
        let mut out = Vec::new();
        let mut pause = None;
        match master.read(&mut buf) {
            Ok(n) if n > 0 => {
                out = endpoint.input(&buf[..n], Instant::now());
                if xon_at.is_none() {
                    pause = endpoint.flow_pause();
                }
            }
            Ok(_) => std::thread::sleep(Duration::from_millis(10)),
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => std::thread::sleep(Duration::from_millis(10)),
        }
        if endpoint.is_closed() {
            break; // drops both ends: the port disappears under the client
        }
        out.extend(endpoint.tick(Instant::now()));
        if !out.is_empty() {
            // A client that does not read must not stall the device: give up on a full buffer.
            let _ = master.write_all(&out);
        }
        if let Some(pause) = pause {
            // After the reply: the host's next command waits until XON.
            let _ = master.write_all(&[XOFF]);
            xon_at = Some(Instant::now() + pause);
        }
        if xon_at.is_some_and(|at| Instant::now() >= at) {
            let _ = master.write_all(&[XON]);
            xon_at = None;
        }
        if last_release.elapsed() >= Duration::from_millis(100) {
            release_exclusive(&slave);
            last_release = Instant::now();
        }
    }
    drop(slave);
    drop(master);
}

fn serve_tcp(listener: std::net::TcpListener, mut endpoint: Endpoint, stop: &AtomicBool) {
    let mut buf = [0u8; 512];
    while !stop.load(Ordering::SeqCst) {
        let mut client = match listener.accept() {
            Ok((client, _)) => client,
            Err(_) => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        if client.set_nonblocking(false).is_err()
            || client
                .set_read_timeout(Some(Duration::from_millis(10)))
                .is_err()
        {
            continue;
        }
        let _ = client.set_nodelay(true);
        while !stop.load(Ordering::SeqCst) {
            let mut out = Vec::new();
            match client.read(&mut buf) {
                Ok(0) => break, // the client went away: take the next one
                Ok(n) => out = endpoint.input(&buf[..n], Instant::now()),
                Err(e)
                    if matches!(
                        e.kind(),
                        std::io::ErrorKind::WouldBlock | std::io::ErrorKind::TimedOut
                    ) => {}
                Err(_) => break,
            }
            if endpoint.is_closed() {
                return; // drops the connection and the listener: the port is gone
            }
            out.extend(endpoint.tick(Instant::now()));
            if !out.is_empty() && client.write_all(&out).is_err() {
                break;
            }
        }
    }
}
