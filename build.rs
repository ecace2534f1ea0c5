//! Build script: the facts `polycal validate` states about its own build (docs/FORMAT.md
//! §13.1), and the bundled validation cases (`examples/validation/`) as a list of
//! `include_bytes!`, so that an installed binary carries them.
//!
//! Nothing here may fail a build: without git (a build from a tarball or crates.io) the
//! commit is `unknown`, and a missing `examples/validation/` bundles no case.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

fn main() {
    let manifest = PathBuf::from(std::env::var_os("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out_dir = PathBuf::from(std::env::var_os("OUT_DIR").unwrap_or_default());
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=POLYCAL_BUILD_COMMIT");
    println!("cargo:rustc-env=POLYCAL_BUILD_COMMIT={}", commit(&manifest));
    println!("cargo:rustc-env=POLYCAL_BUILD_RUSTC={}", rustc_version());
    let target = std::env::var("TARGET").unwrap_or_else(|_| "unknown".into());
    println!("cargo:rustc-env=POLYCAL_BUILD_TARGET={target}");
    let profile = std::env::var("PROFILE").unwrap_or_else(|_| "unknown".into());
    println!("cargo:rustc-env=POLYCAL_BUILD_PROFILE={profile}");
    let mut features: Vec<String> = std::env::vars()
        .filter_map(|(k, _)| {
            k.strip_prefix("CARGO_FEATURE_")
                .map(|f| f.to_lowercase().replace('_', "-"))
        })
        .collect();
    features.sort();
    println!(
        "cargo:rustc-env=POLYCAL_BUILD_FEATURES={}",
        features.join(",")
    );
    let cases = bundled_cases(&manifest.join("examples").join("validation"));
    // Without an OUT_DIR there is nowhere to write: cargo always sets one.
    let _ = std::fs::write(out_dir.join("validation_cases.rs"), cases);
}

/// The commit the build was made from: `POLYCAL_BUILD_COMMIT` when set, else git's HEAD
/// when a release build was made, else `unknown`. Changes not committed are not detected.
///
/// Only a release build (the binary a laboratory validates and uses) asks git: a commit
/// recorded in the library makes every commit rebuild it, which the debug and test builds
/// of development and CI need not pay.
fn commit(manifest: &Path) -> String {
    if let Ok(commit) = std::env::var("POLYCAL_BUILD_COMMIT") {
        return commit;
    }
    if std::env::var("PROFILE").as_deref() != Ok("release") {
        return "not recorded (a debug build: release builds record the commit)".into();
    }
    let git = |args: &[&str]| {
        Command::new("git")
            .args(args)
            .current_dir(manifest)
            .output()
            .ok()
            .filter(|o| o.status.success())
            .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
    };
    let Some(head) = git(&["rev-parse", "HEAD"]).filter(|h| !h.is_empty()) else {
        return "unknown".into();
    };
    // rebuild when HEAD moves (a commit, a checkout)
    for file in ["HEAD"] {
        if let Some(path) = git(&["rev-parse", "--git-path", file]) {
            println!("cargo:rerun-if-changed={}", manifest.join(path).display());
        }
    }
    if let Some(reference) = git(&["symbolic-ref", "-q", "HEAD"])
        && let Some(path) = git(&["rev-parse", "--git-path", &reference])
    {
        println!("cargo:rerun-if-changed={}", manifest.join(path).display());
    }
    head
}

/// `rustc --version` of the compiler cargo uses.
fn rustc_version() -> String {
    let rustc = std::env::var_os("RUSTC").unwrap_or_else(|| "rustc".into());
    Command::new(rustc)
        .arg("--version")
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
        .unwrap_or_else(|| "unknown".into())
}

/// Rust source of `&[(case, &[(file, bytes)])]`: every sub-directory of `dir` that holds
/// a `case.toml`, its files in name order.
fn bundled_cases(dir: &Path) -> String {
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut text = String::from("&[\n");
    let mut cases: Vec<PathBuf> = std::fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join("case.toml").is_file())
        .collect();
    cases.sort();
    for case in cases {
        println!("cargo:rerun-if-changed={}", case.display());
        let name = case
            .file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .to_string();
        let _ = writeln!(text, "    ({name:?}, &[");
        let mut files: Vec<PathBuf> = std::fs::read_dir(&case)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_file())
            .collect();
        files.sort();
        for file in files {
            println!("cargo:rerun-if-changed={}", file.display());
            let fname = file
                .file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .to_string();
            let _ = writeln!(
                text,
                "        ({fname:?}, include_bytes!({:?}).as_slice()),",
                file.display().to_string()
            );
        }
        text.push_str("    ]),\n");
    }
    text.push_str("]\n");
    text
}
