//! What the tests of written files share: the binary run in a scratch directory of
//! copied examples, the refusal every such test expects, and the directory's contents
//! read back.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The binary run with `args` in `dir`.
pub fn polycal_in(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("the binary runs")
}

/// A fresh scratch directory `polycal-{prefix}-{pid}-{name}` holding copies of the
/// repository's files `copies` (from, to).
pub fn scratch_with(prefix: &str, name: &str, copies: &[(&str, &str)]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-{prefix}-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("scratch directory");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (from, to) in copies {
        std::fs::copy(root.join(from), dir.join(to)).expect("copy");
    }
    dir
}

/// Status 2 and one `error:` line; returns it.
pub fn refused(out: &Output) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "stderr:\n{stderr}");
    assert_eq!(stderr.lines().count(), 1, "one line:\n{stderr}");
    assert!(stderr.starts_with("error: "), "{stderr}");
    stderr
}

/// The names in `dir`, sorted.
pub fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The bytes of the file `path`.
pub fn bytes(path: &Path) -> Vec<u8> {
    std::fs::read(path).expect("read")
}
