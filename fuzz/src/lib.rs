//! What the cargo-fuzz targets share: the contract every reader keeps (a refusal names
//! the file) and a scratch file for the readers that take a path.
//!
//! A target panics when the contract is broken, so that libFuzzer keeps the input as a
//! crash, just as for a panic of the library itself.

use std::fmt::Display;
use std::path::PathBuf;

/// The name every reader is given for the fuzzed input.
pub const SOURCE: &str = "fuzzed-input";

/// Panics unless `error`'s message names `source`.
pub fn assert_names<E: Display>(error: &E, source: &str) {
    let message = error.to_string();
    assert!(
        message.contains(source),
        "the error does not name the file {source:?}: {message}"
    );
}

/// `Some(value)` for an accepted input; `None` for a refusal, which must name `source`
/// and, when `data` is not UTF-8, the line and column (`SOURCE:LINE:COLUMN`, a line no
/// later than that of the first invalid byte: docs/FORMAT.md §2.1, §3.2, §4, §5.3, §9.2.1).
pub fn accepted<T, E: Display>(result: Result<T, E>, source: &str, data: &[u8]) -> Option<T> {
    match result {
        Ok(value) => Some(value),
        Err(error) => {
            assert_names(&error, source);
            if let Err(e) = std::str::from_utf8(data) {
                let before = &data[..e.valid_up_to()];
                let lines = before.iter().filter(|&&b| b == b'\n' || b == b'\r').count() + 1;
                let message = error.to_string();
                assert!(
                    has_position(&message, source, lines as u64),
                    "a refusal of bytes that are not UTF-8 has no line and column: {message}"
                );
            }
            None
        }
    }
}

/// Whether `message` has `SOURCE:LINE:COLUMN` with 1 ≤ LINE ≤ `max_line`.
fn has_position(message: &str, source: &str, max_line: u64) -> bool {
    message.match_indices(source).any(|(i, _)| {
        let mut parts = message[i + source.len()..].splitn(4, ':');
        let (Some(""), Some(line), Some(column)) = (parts.next(), parts.next(), parts.next())
        else {
            return false;
        };
        let column_ok = !column.is_empty() && column.bytes().all(|b| b.is_ascii_digit());
        column_ok
            && line
                .parse::<u64>()
                .is_ok_and(|l| (1..=max_line).contains(&l))
    })
}

/// Writes `data` to this process's scratch file `name` (for readers that take a path)
/// and returns its path.
pub fn scratch_file(name: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let path = dir.join(name);
    std::fs::write(&path, data).expect("scratch file");
    path
}
