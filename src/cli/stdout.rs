//! Standard output as every command writes its results: closed by its reader (`polycal
//! solve big.csv | head -1`) is not an error (docs/FORMAT.md §8).
//!
//! A write to standard output that fails with a broken pipe gives an error that carries
//! [`Closed`]; `main` ends such a run quietly with [`EXIT_CLOSED`]. Only standard output
//! is so marked: a broken pipe on an instrument's port or on an output file stays an
//! `error:` line with status 2.

use std::io::{self, Write};

/// Exit status when standard output was closed by its reader: 128 + SIGPIPE (13), the
/// status a shell shows for `cat` ended by the signal. Not 0: the command did not finish.
pub const EXIT_CLOSED: u8 = 141;

/// The mark of a write to standard output that found its reader gone.
#[derive(Debug)]
pub struct Closed;

impl std::fmt::Display for Closed {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("standard output was closed by its reader")
    }
}

impl std::error::Error for Closed {}

/// Standard output, its broken pipe marked [`Closed`].
pub fn stdout() -> Stdout {
    Stdout(io::stdout())
}

/// Standard output (see [`stdout`]).
pub struct Stdout(io::Stdout);

/// Standard output locked (see [`stdout`]).
pub struct StdoutLock(io::StdoutLock<'static>);

impl Stdout {
    /// Locks standard output for a run of writes.
    pub fn lock(&self) -> StdoutLock {
        StdoutLock(self.0.lock())
    }
}

/// A broken pipe marked as standard output's; any other error as it is.
fn marked(error: io::Error) -> io::Error {
    if error.kind() == io::ErrorKind::BrokenPipe {
        io::Error::new(io::ErrorKind::BrokenPipe, Closed)
    } else {
        error
    }
}

impl Write for Stdout {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(buf).map_err(marked)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush().map_err(marked)
    }
}

impl Write for StdoutLock {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.write(buf).map_err(marked)
    }

    fn flush(&mut self) -> io::Result<()> {
        self.0.flush().map_err(marked)
    }
}

/// Whether `error` is standard output closed by its reader (somewhere in its chain).
pub fn is_closed(error: &anyhow::Error) -> bool {
    error.chain().any(|cause| {
        cause.is::<Closed>()
            || cause
                .downcast_ref::<io::Error>()
                .and_then(io::Error::get_ref)
                .is_some_and(|inner| inner.is::<Closed>())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_marked_broken_pipe_is_closed() {
        let marked_pipe = anyhow::Error::from(marked(io::Error::from(io::ErrorKind::BrokenPipe)));
        assert!(is_closed(&marked_pipe));
        assert!(is_closed(&marked_pipe.context("writing the table")));
        // A port's broken pipe is not standard output's.
        let port = anyhow::Error::from(io::Error::from(io::ErrorKind::BrokenPipe));
        assert!(!is_closed(&port));
        let other = anyhow::Error::from(marked(io::Error::from(io::ErrorKind::WriteZero)));
        assert!(!is_closed(&other));
    }
}
