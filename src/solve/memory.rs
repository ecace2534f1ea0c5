//! How much memory a solve may plan to use, and the one way sizes are written.
//!
//! A solver estimates what its engine will allocate before it allocates anything and
//! refuses a design that does not fit ([`super::SolveError::TooLarge`]), so that a design
//! too big for the machine ends in a clear error, never in an abort.

/// The memory this process may still take, in bytes: the tightest of [`room`]'s limits;
/// `None` where none can be read, and then no limit is applied.
pub fn available_bytes() -> Option<u64> {
    room().map(|(bytes, _)| bytes)
}

/// The memory this process may still take and what sets it, the tightest of (Linux):
/// the machine's available memory (`MemAvailable` of `/proc/meminfo`), what is left
/// under the process's address-space and data limits (`ulimit -v`, `RLIMIT_AS` and
/// `RLIMIT_DATA` of `/proc/self/limits`, less `VmSize` and `VmData` of
/// `/proc/self/status`), and what is left under its control group's memory limit
/// (cgroup v2 `memory.max` less `memory.current`, v1 `memory.limit_in_bytes` less
/// `memory.usage_in_bytes`). The text completes "… bytes {text}". `None` where none can
/// be read.
pub fn room() -> Option<(u64, &'static str)> {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let limits = std::fs::read_to_string("/proc/self/limits").unwrap_or_default();
    let meminfo = std::fs::read_to_string("/proc/meminfo").unwrap_or_default();
    let mut candidates: Vec<(u64, &'static str)> = Vec::new();
    if let Some(bytes) = kilobytes(&meminfo, "MemAvailable:") {
        candidates.push((bytes, "are available on this machine"));
    }
    for (limit, used, text) in [
        (
            "Max address space",
            "VmSize:",
            "are left under this process's address-space limit (ulimit -v)",
        ),
        (
            "Max data size",
            "VmData:",
            "are left under this process's data-size limit (ulimit -d)",
        ),
    ] {
        if let (Some(limit), Some(used)) = (soft_limit(&limits, limit), kilobytes(&status, used)) {
            candidates.push((limit.saturating_sub(used), text));
        }
    }
    if let Some(left) = cgroup_room() {
        candidates.push((
            left,
            "are left under this process's control-group memory limit",
        ));
    }
    candidates.into_iter().min_by_key(|(bytes, _)| *bytes)
}

/// `KEY:   1234 kB` of a `/proc` file, in bytes.
fn kilobytes(text: &str, key: &str) -> Option<u64> {
    text.lines()
        .find_map(|line| line.strip_prefix(key))
        .and_then(|rest| rest.trim().strip_suffix("kB"))
        .and_then(|kb| kb.trim().parse::<u64>().ok())
        .map(|kb| kb.saturating_mul(1024))
}

/// The soft limit of `name` in `/proc/self/limits`, bytes; `None` when unlimited.
fn soft_limit(text: &str, name: &str) -> Option<u64> {
    let rest = text.lines().find_map(|line| line.strip_prefix(name))?;
    rest.split_whitespace().next()?.parse::<u64>().ok()
}

/// What is left under the control group's memory limit, bytes; `None` without one.
fn cgroup_room() -> Option<u64> {
    let groups = std::fs::read_to_string("/proc/self/cgroup").ok()?;
    let read = |path: &str| -> Option<u64> {
        std::fs::read_to_string(path)
            .ok()?
            .trim()
            .parse::<u64>()
            .ok()
    };
    let mut rooms = Vec::new();
    for line in groups.lines() {
        let mut fields = line.splitn(3, ':');
        let (_, controllers, path) = (fields.next()?, fields.next()?, fields.next()?);
        let path = path.trim_end_matches('/');
        if controllers.is_empty() {
            // cgroup v2: the group's own files, else those of the namespace's root
            for base in [
                format!("/sys/fs/cgroup{path}"),
                "/sys/fs/cgroup".to_string(),
            ] {
                if let (Some(max), Some(current)) = (
                    read(&format!("{base}/memory.max")),
                    read(&format!("{base}/memory.current")),
                ) {
                    rooms.push(max.saturating_sub(current));
                    break;
                }
            }
        } else if controllers.split(',').any(|c| c == "memory") {
            for base in [
                format!("/sys/fs/cgroup/memory{path}"),
                "/sys/fs/cgroup/memory".to_string(),
            ] {
                if let (Some(max), Some(current)) = (
                    read(&format!("{base}/memory.limit_in_bytes")),
                    read(&format!("{base}/memory.usage_in_bytes")),
                ) {
                    // v1 writes "no limit" as a number near 2^63
                    if max < 1 << 62 {
                        rooms.push(max.saturating_sub(current));
                    }
                    break;
                }
            }
        }
    }
    rooms.into_iter().min()
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
        None => room(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn proc_files_are_read_as_the_kernel_writes_them() {
        let limits = "Limit                     Soft Limit           Hard Limit           Units     \n\
                      Max data size             unlimited            unlimited            bytes     \n\
                      Max address space         1572864000           unlimited            bytes     \n";
        assert_eq!(soft_limit(limits, "Max address space"), Some(1_572_864_000));
        assert_eq!(soft_limit(limits, "Max data size"), None);
        let status = "Name:\tpolycal\nVmSize:\t   3896 kB\nVmData:\t    428 kB\n";
        assert_eq!(kilobytes(status, "VmSize:"), Some(3896 * 1024));
        assert_eq!(kilobytes(status, "VmData:"), Some(428 * 1024));
        assert_eq!(kilobytes(status, "VmRSS:"), None);
    }
}
