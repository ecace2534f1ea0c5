//! How much memory a solve may plan to use, and the one way sizes are written.
//!
//! A solver estimates what its engine will allocate before it allocates anything and
//! refuses a design that does not fit ([`super::SolveError::TooLarge`]), so that a design
//! too big for the machine ends in a clear error, never in an abort.

/// The memory the machine has available now, in bytes (Linux: `MemAvailable` of
/// `/proc/meminfo`); `None` where it cannot be read, and then no limit is applied.
pub fn available_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    text.lines()
        .find_map(|line| line.strip_prefix("MemAvailable:"))
        .and_then(|rest| rest.trim().strip_suffix("kB"))
        .and_then(|kb| kb.trim().parse::<u64>().ok())
        .map(|kb| kb.saturating_mul(1024))
}

/// A size in bytes as people read it: `512 B`, `3.2 MiB`, `137.4 GiB`.
///
/// ```
/// use polycal::solve::memory::human_bytes;
/// assert_eq!(human_bytes(512), "512 B");
/// assert_eq!(human_bytes(3 * 1024 * 1024 + 1024 * 200), "3.2 MiB");
/// ```
pub fn human_bytes(bytes: u128) -> String {
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    if bytes < 1024 {
        return format!("{bytes} B");
    }
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < UNITS.len() {
        value /= 1024.0;
        unit += 1;
    }
    format!("{value:.1} {}", UNITS[unit])
}

/// Below this, a plan is not checked against the machine's memory (reading it costs more
/// than a small solve).
const UNCHECKED_BELOW_BYTES: u128 = 64 << 20;

/// The limit a plan of `needed_bytes` is held to and where it comes from: the caller's,
/// else the machine's available memory (for plans of 64 MiB or more), else none.
pub(crate) fn limit_for(needed_bytes: u128, stated: Option<u64>) -> Option<(u64, &'static str)> {
    match stated {
        Some(bytes) => Some((bytes, "is the limit set")),
        None if needed_bytes < UNCHECKED_BELOW_BYTES => None,
        None => available_bytes().map(|bytes| (bytes, "are available on this machine")),
    }
}
