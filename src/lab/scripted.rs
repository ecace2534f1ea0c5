//! An in-memory device for tests and examples: a script of exchanges, each the exact
//! bytes expected from the host and the bytes replied to them. Put it under a
//! [`crate::lab::transport::StreamTransport`] to drive a driver without hardware.

use std::collections::VecDeque;
use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex};

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
