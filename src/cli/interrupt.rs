//! Ctrl-C and SIGTERM during `polycal run` (docs/FORMAT.md §7.3): the first asks the run
//! to stop the table and finish its files; a second ends the process at once (status
//! 130) with one `error:` line, after recording `interrupted` in the manifest when that
//! can be done within a second (the library's [`AbortHandle`]).

use std::path::PathBuf;
use std::sync::{Arc, Mutex, OnceLock, PoisonError, TryLockError};
use std::time::Duration;

use anyhow::{Context, Result};
use polycal::lab::StopFlag;
use polycal::lab::run::AbortHandle;

use super::output::Output;

/// The exit status of a process ended at once by a second interrupt.
pub const EXIT_AT_ONCE: i32 = 130;

/// How long a second interrupt waits for a write under way before it ends the process
/// without updating the manifest.
const WAIT_FOR_WRITE: Duration = Duration::from_secs(1);

/// Held by whichever ends the process and prints its last line: the run itself, or a
/// second interrupt. The other one then prints nothing.
static ENDING: Mutex<()> = Mutex::new(());

/// What a second interrupt needs to end the run at once.
#[derive(Debug)]
pub struct Interrupts {
    stop: StopFlag,
    at_once: Arc<AtOnce>,
}

#[derive(Debug)]
struct AtOnce {
    /// The run directory's handle, once it is open.
    handle: OnceLock<AbortHandle>,
    /// The progress bar, to clear before the line.
    bar: OnceLock<indicatif::ProgressBar>,
    /// The measurement file and the readings of the whole run, for the message.
    file: PathBuf,
    total: OnceLock<usize>,
}

impl Interrupts {
    /// Installs the handlers of SIGINT and SIGTERM for a run whose measurement file is
    /// `file`.
    pub fn install(out: &Output, file: PathBuf) -> Result<Interrupts> {
        let interrupts = Interrupts {
            stop: StopFlag::new(),
            at_once: Arc::new(AtOnce {
                handle: OnceLock::new(),
                bar: OnceLock::new(),
                file,
                total: OnceLock::new(),
            }),
        };
        interrupts
            .register(*out)
            .context("cannot install the Ctrl-C handler")?;
        Ok(interrupts)
    }

    /// The flag the first interrupt sets.
    pub fn stop_flag(&self) -> &StopFlag {
        &self.stop
    }

    /// The run directory is open, of `total` readings in its mountings so far: a second
    /// interrupt records `interrupted` through `handle`.
    pub fn run_dir_opened(&self, handle: AbortHandle, total: usize) {
        let _ = self.at_once.total.set(total);
        let _ = self.at_once.handle.set(handle);
    }

    /// The progress bar, cleared by a second interrupt before its line.
    pub fn show_progress(&self, bar: &indicatif::ProgressBar) {
        let _ = self.at_once.bar.set(bar.clone());
    }

    /// The run is ending by itself and will print its last line: a second interrupt
    /// from now on prints nothing (the process ends anyway). Waits if a second interrupt
    /// is ending the process already.
    pub fn ending(&self) {
        let guard = ENDING.lock().unwrap_or_else(PoisonError::into_inner);
        // Kept until the process ends.
        std::mem::forget(guard);
    }

    /// The first interrupt sets the stop flag at once; every interrupt is also counted by
    /// a thread that ends the process at the second.
    #[cfg(unix)]
    fn register(&self, out: Output) -> std::io::Result<()> {
        use std::io::Read;
        use std::os::unix::net::UnixStream;

        let (mut read, write) = UnixStream::pair()?;
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register(signal, self.stop.shared())?;
            signal_hook::low_level::pipe::register(signal, write.try_clone()?)?;
        }
        let at_once = Arc::clone(&self.at_once);
        std::thread::Builder::new()
            .name("interrupts".into())
            .spawn(move || {
                let mut byte = [0u8; 1];
                let mut count = 0;
                loop {
                    match read.read(&mut byte) {
                        Ok(0) => return,
                        Ok(_) => count += 1,
                        Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                        Err(_) => return,
                    }
                    if count >= 2 {
                        at_once.end(&out);
                        return;
                    }
                }
            })?;
        Ok(())
    }

    /// Without a way to count signals in a thread, a second interrupt ends the process
    /// with status 130 and no line.
    #[cfg(not(unix))]
    fn register(&self, _out: Output) -> std::io::Result<()> {
        for signal in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
            signal_hook::flag::register_conditional_shutdown(
                signal,
                EXIT_AT_ONCE,
                self.stop.shared(),
            )?;
            signal_hook::flag::register(signal, self.stop.shared())?;
        }
        Ok(())
    }
}

impl AtOnce {
    /// Ends the process at once: records `interrupted` if it can, prints one `error:`
    /// line and exits with status 130, unless the run is ending by itself.
    #[cfg_attr(not(unix), allow(dead_code))]
    fn end(&self, out: &Output) {
        match ENDING.try_lock() {
            Ok(guard) => std::mem::forget(guard),
            Err(TryLockError::Poisoned(guard)) => std::mem::forget(guard.into_inner()),
            // The run prints its own last line and ends.
            Err(TryLockError::WouldBlock) => return,
        }
        if let Some(bar) = self.bar.get() {
            bar.finish_and_clear();
        }
        let stopped = "run stopped at once by a second interrupt (the table may not have stopped)";
        let resume = "continue with the same command and --resume";
        let file = self.file.display();
        let message = match self.handle.get().map(|h| h.abort(WAIT_FOR_WRITE)) {
            None => "run stopped at once by a second interrupt, before it began measuring".into(),
            Some(Ok(readings)) => format!(
                "{stopped}; {readings} of {} readings are in {file}; {resume}",
                self.total.get().copied().unwrap_or(0)
            ),
            Some(Err(e)) => format!(
                "{stopped}; the manifest was not updated ({e}); the readings taken are in {file}; {resume}"
            ),
        };
        out.error_message(message);
        signal_hook::low_level::exit(EXIT_AT_ONCE);
    }
}
