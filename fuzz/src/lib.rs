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

/// `Some(value)` for an accepted input; `None` for a refusal, which must name `source`.
pub fn accepted<T, E: Display>(result: Result<T, E>, source: &str) -> Option<T> {
    match result {
        Ok(value) => Some(value),
        Err(error) => {
            assert_names(&error, source);
            None
        }
    }
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
