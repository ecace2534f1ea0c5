//! Ending a run at once from another thread (a second Ctrl-C, docs/FORMAT.md §7.3): the
//! run directory shares what it has on disk with an [`AbortHandle`], which records
//! `interrupted` in the manifest and closes the directory, so that nothing more is
//! written before the process ends.

use std::path::PathBuf;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError, TryLockError};
use std::time::{Duration, Instant};

use super::{MANIFEST, Manifest, Outcome, RunError};
use crate::lab::WriteBudget;

/// What a run directory has on disk, shared with its [`AbortHandle`]. The run directory
/// holds the lock while it appends a reading or replaces the manifest.
#[derive(Debug)]
pub(super) struct OnDisk {
    /// The manifest as last written (or read, on a resumed run).
    pub(super) manifest: Manifest,
    /// Whether that manifest holds this session.
    pub(super) session_in_manifest: bool,
    /// Readings on disk when this session started.
    pub(super) readings_before: usize,
    /// Readings on disk.
    pub(super) readings: usize,
    /// Whether this session's end is in the manifest.
    pub(super) ended: bool,
    /// Whether an abort closed the directory: nothing more is written.
    pub(super) closed: bool,
}

/// The shared state of a run directory.
pub(super) type Shared = Arc<Mutex<OnDisk>>;

/// Locks the shared state; a panic elsewhere does not make it unusable.
pub(super) fn lock(shared: &Shared) -> MutexGuard<'_, OnDisk> {
    shared.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Ends the writing of a run directory from another thread, for a process that must end
/// at once (a second Ctrl-C): see [`AbortHandle::abort`]. Obtained from
/// [`RunDir::abort_handle`](super::RunDir::abort_handle); cloning shares it.
#[derive(Debug, Clone)]
pub struct AbortHandle {
    pub(super) dir: PathBuf,
    pub(super) budget: WriteBudget,
    pub(super) shared: Shared,
}

impl AbortHandle {
    /// Waits up to `wait` for a write under way (a reading being appended and synced,
    /// the manifest being replaced) to finish; then records in the manifest that this
    /// session ended `interrupted` with the readings on disk (unless the session's end
    /// is recorded already), and closes the run directory: the [`RunDir`](super::RunDir)
    /// writes nothing more (its writes fail with [`RunError::Closed`]). The measurement
    /// file ends on a whole line, and a resumed run continues from it. Returns the
    /// readings on disk.
    ///
    /// # Errors
    ///
    /// [`RunError::Busy`] when a write is still under way after `wait` (nothing was
    /// changed); [`RunError::Io`] when the manifest cannot be written (the directory is
    /// closed all the same).
    pub fn abort(&self, wait: Duration) -> Result<usize, RunError> {
        let deadline = Instant::now() + wait;
        let mut on_disk = loop {
            match self.shared.try_lock() {
                Ok(guard) => break guard,
                Err(TryLockError::Poisoned(e)) => break e.into_inner(),
                Err(TryLockError::WouldBlock) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(5));
                }
                Err(TryLockError::WouldBlock) => {
                    return Err(RunError::Busy {
                        path: self.dir.join(MANIFEST),
                    });
                }
            }
        };
        let readings = on_disk.readings;
        if on_disk.closed || on_disk.ended {
            on_disk.closed = true;
            return Ok(readings);
        }
        on_disk.closed = true;
        let mut manifest = on_disk.manifest.clone();
        if !on_disk.session_in_manifest {
            manifest.open_session(on_disk.readings_before);
        }
        manifest.end_session(&Outcome::Interrupted.to_string(), readings);
        manifest.write_to(&self.dir, &self.budget)?;
        on_disk.manifest = manifest;
        on_disk.ended = true;
        Ok(readings)
    }
}
