//! An observer of a long computation's progress ([`Progress`]): the Monte Carlo engine,
//! the solvers, a diagnosis and a plan tell it how far they are; a command draws a bar
//! from it. On the ground floor, beside the input, so that every computation can reach it
//! without importing another's module.

/// An observer of the progress of a run, told after every block of trials of a
/// Monte Carlo run ([`BLOCK_SIZE`](crate::uncertainty::monte_carlo::BLOCK_SIZE)), after
/// every round of a diagnosis's search, after every design a plan scores (so that a
/// command can draw a progress bar; the library draws nothing).
///
/// Calls come from rayon's threads but never at the same time, and `done` grows from call
/// to call. Any `Fn(u64, Option<u64>) + Sync` closure is a `Progress`:
///
/// ```
/// use std::sync::atomic::{AtomicU64, Ordering};
/// use polycal::uncertainty::monte_carlo::{EngineOptions, Progress, Trials};
///
/// let last = AtomicU64::new(0);
/// let report = |done: u64, _total: Option<u64>| last.store(done, Ordering::Relaxed);
/// let options = EngineOptions::new(Trials::Fixed(20_000)).with_progress(&report);
/// # let _ = options;
/// ```
pub trait Progress: Sync {
    /// `done` trials have run so far; `total` is the number the run will make if known:
    /// `M` for a fixed number of trials (raised if trials are re-run to widen a bracket),
    /// `None` for the adaptive procedure, which stops when the results are stable.
    fn update(&self, done: u64, total: Option<u64>);
}

impl<F: Fn(u64, Option<u64>) + Sync> Progress for F {
    fn update(&self, done: u64, total: Option<u64>) {
        self(done, total);
    }
}
