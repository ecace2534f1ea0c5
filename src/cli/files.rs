//! The files a command writes (docs/FORMAT.md §8.1), through the library's
//! [`polycal::output_file::Outputs`], each refusal naming the option that named the file.

use std::path::{Path, PathBuf};

use anyhow::{Result, anyhow};
use polycal::output_file::{OutputError, Outputs};

/// The outputs of one command and the options that named them.
pub struct CommandOutputs {
    outputs: Outputs,
}

/// `error: --out m.csv: is the input m.csv (the same file); …`.
fn flagged(flag: &str, e: OutputError) -> anyhow::Error {
    anyhow!("{flag} {e}")
}

impl CommandOutputs {
    /// The outputs of a command that reads `inputs` (`-` and absent files passed over).
    pub fn new<'p>(inputs: impl IntoIterator<Item = &'p Path>) -> Result<CommandOutputs> {
        Ok(CommandOutputs {
            outputs: Outputs::new(inputs).map_err(|e| anyhow!("{e}"))?,
        })
    }

    /// Refuses, before any work, an output that is an input, two outputs that are one
    /// file, and an output that is not a regular file; writes nothing.
    pub fn check<'p>(&self, outputs: impl IntoIterator<Item = (&'p str, &'p Path)>) -> Result<()> {
        let outputs: Vec<(&str, &Path)> = outputs.into_iter().collect();
        for n in 0..outputs.len() {
            self.outputs
                .check(outputs[..=n].iter().map(|(_, p)| *p))
                .map_err(|e| flagged(outputs[n].0, e))?;
        }
        Ok(())
    }

    /// Writes the output `path` named by `flag` (renamed into place by
    /// [`CommandOutputs::commit`]).
    pub fn write(&mut self, flag: &str, path: &Path, bytes: &[u8]) -> Result<()> {
        self.outputs
            .write(path, bytes)
            .map_err(|e| flagged(flag, e))
    }

    /// Writes the output `path` named by `flag` through `write`.
    pub fn write_with(
        &mut self,
        flag: &str,
        path: &Path,
        write: impl FnOnce(&mut dyn std::io::Write) -> std::io::Result<()>,
    ) -> Result<()> {
        self.outputs
            .write_with(path, write)
            .map_err(|e| flagged(flag, e))
    }

    /// Puts every output written into place (all of them, or none when one failed
    /// before).
    pub fn commit(self) -> Result<Vec<PathBuf>> {
        self.outputs.commit().map_err(|e| anyhow!("{e}"))
    }
}

/// Called before the final `error:` line: when Ctrl-C or SIGTERM is being handled (its
/// temporary files removed), the command's error is its consequence — an output whose
/// temporary file went, or that could no longer be made — and the handler is ending the
/// process as the signal would. Waits for it, so that the status is the signal's, not
/// 2 (at most a second, then status 130).
pub fn wait_if_interrupted() {
    if polycal::output_file::interrupted() {
        std::thread::sleep(std::time::Duration::from_secs(1));
        std::process::exit(130);
    }
}

/// On Ctrl-C or SIGTERM, removes the temporary files of the outputs not yet in place
/// ([`polycal::output_file::remove_temporaries`]) and ends the process as the signal
/// would have (docs/FORMAT.md §8.1): an interrupted command leaves its old files and no
/// half-written one. For every command but `run` and `sim-lab`, which handle the signals
/// themselves.
pub fn clean_up_on_interrupt() {
    use signal_hook::consts::{SIGINT, SIGTERM};
    let Ok(mut signals) = signal_hook::iterator::Signals::new([SIGINT, SIGTERM]) else {
        // without the handler the signal ends the process as before; only a temporary
        // file may then be left
        return;
    };
    let spawned = std::thread::Builder::new()
        .name("interrupt".into())
        .spawn(move || {
            if let Some(signal) = signals.forever().next() {
                polycal::output_file::remove_temporaries();
                let _ = signal_hook::low_level::emulate_default_handler(signal);
                std::process::exit(128 + signal);
            }
        });
    drop(spawned);
}
