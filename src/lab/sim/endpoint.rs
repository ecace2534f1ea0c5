//! A simulated device behind its reply faults and input line buffer ([`Endpoint`]), and
//! an in-memory stream to it ([`SimStream`]).

use std::collections::VecDeque;
use std::fmt;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

use super::{Fault, FaultKind, fault::NUL_PADDING};

/// A simulated device: answers command lines.
pub trait SimDevice: Send {
    /// The reply to one command line (terminator removed), terminator included; `None`
    /// when the protocol gives none.
    fn handle(&mut self, command: &str, now: Instant) -> Option<String>;
    /// Output the device sends by itself (a continuous stream), if due.
    fn tick(&mut self, now: Instant) -> Option<String>;
    /// Events so far (measurements, or move commands), which arm faults.
    fn events(&self) -> u64;
    /// A line in the form of a reply that nothing asked for (an `unsolicited` fault),
    /// terminator included.
    fn unsolicited(&mut self, now: Instant) -> String;
}

#[derive(Debug, Clone, Copy)]
struct Armed {
    fault: Fault,
    left: u64,
}

/// A device with its reply faults and its input line buffer: the part shared by the
/// pseudo-terminal lab and the in-memory [`SimStream`].
pub struct Endpoint {
    device: Box<dyn SimDevice>,
    faults: Vec<Armed>,
    input: Vec<u8>,
    closed: bool,
    /// Replies on their way, each with the instant it is due, in the order sent.
    outgoing: VecDeque<(Instant, Vec<u8>)>,
    /// A reply held back by a `swapped` fault, sent after the next one.
    held: Option<String>,
    /// The last reply sent (for a `stale` fault).
    last_reply: Option<String>,
    /// Replies of a `late` fault with `commands=C`: the commands still to come before
    /// each is sent.
    held_late: Vec<(u32, Vec<u8>)>,
    /// The time one byte takes on the line (zero: a reply arrives whole at once).
    byte_time: Duration,
}

impl fmt::Debug for Endpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Endpoint")
            .field("faults", &self.faults)
            .field("closed", &self.closed)
            .finish_non_exhaustive()
    }
}

impl Endpoint {
    /// A device with the faults that act on its replies (every kind but `x-invalid` and
    /// `disable`, which are the device's own).
    pub fn new(device: Box<dyn SimDevice>, faults: &[Fault]) -> Endpoint {
        Endpoint {
            device,
            faults: faults
                .iter()
                .filter(|f| f.kind.acts_on_replies())
                .map(|&fault| Armed {
                    fault,
                    left: fault.count,
                })
                .collect(),
            input: Vec::new(),
            closed: false,
            outgoing: VecDeque::new(),
            held: None,
            last_reply: None,
            held_late: Vec::new(),
            byte_time: Duration::ZERO,
        }
    }

    /// Puts the replies on a line of `baud_rate` baud (10 bits a byte): each reply line
    /// arrives once its last byte would have, after the line before it — a reply read
    /// while the next is still on the wire, as on a real serial line.
    pub fn with_baud_rate(mut self, baud_rate: u32) -> Endpoint {
        self.byte_time = Duration::from_secs_f64(10.0 / f64::from(baud_rate.max(1)));
        self
    }

    /// Queues `bytes` to start on the line at `start` (or once the line before it is
    /// through), line by line, each due when its last byte has arrived.
    fn queue(&mut self, start: Instant, bytes: Vec<u8>) {
        let mut at = self
            .outgoing
            .back()
            .map_or(start, |&(last, _)| last.max(start));
        let mut line = Vec::new();
        let mut bytes = bytes.into_iter().peekable();
        while let Some(b) = bytes.next() {
            line.push(b);
            let ends = b == b'\n' || (b == b'\r' && bytes.peek() != Some(&b'\n'));
            if ends || bytes.peek().is_none() {
                at += self.byte_time * line.len() as u32;
                self.outgoing.push_back((at, std::mem::take(&mut line)));
            }
        }
    }

    /// Whether a `close` fault closed the device.
    pub fn is_closed(&self) -> bool {
        self.closed
    }

    /// Feeds bytes from the host; returns the bytes due to be sent back now.
    pub fn input(&mut self, bytes: &[u8], now: Instant) -> Vec<u8> {
        if self.closed {
            return Vec::new();
        }
        self.input.extend_from_slice(bytes);
        while let Some(i) = self.input.iter().position(|&b| b == b'\r' || b == b'\n') {
            let line: Vec<u8> = self.input.drain(..=i).collect();
            let command = String::from_utf8_lossy(&line[..i]).trim().to_string();
            if command.is_empty() {
                continue;
            }
            // Replies held by a `late` fault with `commands=C` come just inside the
            // window of the C-th command after them, ahead of its reply.
            let mut released = Vec::new();
            for (left, bytes) in &mut self.held_late {
                *left = left.saturating_sub(1);
                if *left == 0 {
                    released.push(std::mem::take(bytes));
                }
            }
            self.held_late.retain(|(left, _)| *left > 0);
            for bytes in released {
                self.queue(now, bytes);
            }
            let events = self.device.events();
            if self
                .faults
                .iter()
                .any(|a| a.fault.kind == FaultKind::Close && events >= a.fault.after)
            {
                self.closed = true;
                self.outgoing.clear();
                return Vec::new();
            }
            let Some(reply) = self.device.handle(&command, now) else {
                continue;
            };
            self.send_reply(reply, events, now);
        }
        if self.input.len() > 4096 {
            self.input.clear();
        }
        self.due(now)
    }

    /// Puts one reply on its way, as the armed faults make it.
    fn send_reply(&mut self, reply: String, events: u64, now: Instant) {
        let mut text = reply;
        let mut delay = Duration::ZERO;
        let mut before = String::new();
        let mut copies = 1;
        let mut hold = false;
        let mut held_for: Option<u32> = None;
        let mut pad = false;
        for armed in &mut self.faults {
            if armed.fault.kind == FaultKind::Xoff {
                continue; // the serving loop's (`flow_pause`)
            }
            if armed.fault.kind == FaultKind::NulPadding {
                // Every reply once armed: `count` does not run out.
                pad |= events >= armed.fault.after;
                continue;
            }
            if armed.left == 0 || events < armed.fault.after {
                continue;
            }
            armed.left -= 1;
            match armed.fault.kind {
                FaultKind::LostReply => return,
                FaultKind::Garbled => text = garble(&text),
                FaultKind::Late => match armed.fault.late_commands {
                    Some(c) => held_for = Some(c),
                    None => delay = delay.max(armed.fault.late),
                },
                FaultKind::Duplicated => copies = 2,
                FaultKind::Unsolicited => before = self.device.unsolicited(now),
                FaultKind::Swapped => hold = true,
                FaultKind::Stale => {
                    if let Some(previous) = &self.last_reply {
                        text = previous.clone();
                    }
                }
                _ => armed.left += 1, // not a fault of the replies
            }
        }
        self.last_reply = Some(text.clone());
        if hold && self.held.is_none() {
            self.held = Some(text);
            return;
        }
        let mut bytes = before.into_bytes();
        for _ in 0..copies {
            if pad {
                bytes.extend_from_slice(NUL_PADDING);
            }
            bytes.extend_from_slice(text.as_bytes());
            if pad {
                bytes.extend_from_slice(NUL_PADDING);
            }
        }
        if let Some(held) = self.held.take() {
            bytes.extend(held.into_bytes());
        }
        if let Some(commands) = held_for {
            self.held_late.push((commands, bytes));
            return;
        }
        // A device answers in order: nothing overtakes a late reply.
        self.queue(now + delay, bytes);
    }

    /// The replies due at `now`, in order.
    fn due(&mut self, now: Instant) -> Vec<u8> {
        let mut out = Vec::new();
        while let Some((due, _)) = self.outgoing.front() {
            if *due > now {
                break;
            }
            if let Some((_, bytes)) = self.outgoing.pop_front() {
                out.extend(bytes);
            }
        }
        out
    }

    /// How long the device now holds the host's output with XOFF, once per reply an
    /// `xoff` fault hits (armed after its `after` events, for `count` pauses); the
    /// pseudo-terminal lab sends XOFF, then XON when the pause is over.
    pub fn flow_pause(&mut self) -> Option<Duration> {
        let events = self.device.events();
        let armed = self
            .faults
            .iter_mut()
            .find(|a| a.fault.kind == FaultKind::Xoff && a.left > 0 && events >= a.fault.after)?;
        armed.left -= 1;
        Some(armed.fault.late)
    }

    /// Output due now: replies on their way, and what the device sends by itself.
    pub fn tick(&mut self, now: Instant) -> Vec<u8> {
        if self.closed {
            return Vec::new();
        }
        let mut out = self.due(now);
        if let Some(line) = self.device.tick(now) {
            out.extend(line.into_bytes());
        }
        out
    }
}

/// Every third character (from the first) replaced by `?`, terminators kept.
fn garble(reply: &str) -> String {
    let body = reply.trim_end_matches(['\r', '\n']);
    let end = &reply[body.len()..];
    let garbled: String = body
        .chars()
        .enumerate()
        .map(|(i, c)| if i % 3 == 0 { '?' } else { c })
        .collect();
    garbled + end
}

/// An in-memory `Read + Write` connected to a simulated device, for driving the drivers
/// (through a [`crate::lab::transport::StreamTransport`]) without pseudo-terminals.
///
/// Writing feeds the device; reading returns its replies, `WouldBlock` when there are
/// none yet, and end of input once a `close` fault closed it.
#[derive(Debug)]
pub struct SimStream {
    endpoint: Endpoint,
    output: Vec<u8>,
}

impl SimStream {
    /// A stream to `endpoint`.
    pub fn new(endpoint: Endpoint) -> SimStream {
        SimStream {
            endpoint,
            output: Vec::new(),
        }
    }
}

impl Read for SimStream {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        if self.output.is_empty() {
            let tick = self.endpoint.tick(Instant::now());
            self.output.extend(tick);
        }
        if self.output.is_empty() {
            if self.endpoint.is_closed() {
                return Ok(0);
            }
            return Err(io::Error::new(io::ErrorKind::WouldBlock, "no reply yet"));
        }
        let n = buf.len().min(self.output.len());
        buf[..n].copy_from_slice(&self.output[..n]);
        self.output.drain(..n);
        Ok(n)
    }
}

impl Write for SimStream {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.endpoint.is_closed() {
            return Err(io::Error::new(io::ErrorKind::BrokenPipe, "device closed"));
        }
        let reply = self.endpoint.input(buf, Instant::now());
        self.output.extend(reply);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}
