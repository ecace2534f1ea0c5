//! The `polycal` binary's help: `completions SHELL` for every shell, the man pages, and the
//! examples of every command's `--help` run as written.

use std::path::Path;
use std::process::Command;

use crate::cli_support::{polycal, temp_dir};

/// `completions SHELL` for every shell and `man` (polycal(1) and a command's page).
#[test]
fn completions_and_man_page() {
    for shell in ["bash", "zsh", "fish", "powershell", "elvish"] {
        let out = polycal(&["completions", shell]);
        assert!(out.status.success(), "{shell}");
        let script = String::from_utf8(out.stdout).unwrap();
        for word in ["polycal", "solve", "monte-carlo", "completions"] {
            assert!(script.contains(word), "{shell}: no {word}");
        }
        assert_eq!(script.contains("sim-lab"), cfg!(feature = "lab"), "{shell}");
    }
    let out = polycal(&["completions", "tcsh"]);
    assert_eq!(out.status.code(), Some(2));

    let out = polycal(&["man"]);
    assert!(out.status.success());
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(page.contains(".TH polycal 1"), "{page}");
    for word in ["solve", "diagnose", "completions", "\\-\\-color"] {
        assert!(page.contains(word), "no {word} in the man page");
    }
    let out = polycal(&["man", "solve"]);
    assert!(out.status.success());
    let page = String::from_utf8(out.stdout).unwrap();
    assert!(page.contains(".TH polycal-solve 1"), "{page}");
    assert!(page.contains("\\-\\-monte\\-carlo"), "{page}");
    assert_eq!(polycal(&["man", "nothing"]).status.code(), Some(2));
}

/// The examples in every command's `--help` run as written (from a directory holding
/// the bundled `examples/`), in order, so later ones can read what earlier ones wrote.
#[cfg(unix)]
#[test]
fn help_examples_run() {
    let dir = temp_dir("help-examples");
    let link = dir.join("examples");
    // A link left by an earlier run whose process id this one reuses may point nowhere.
    let _ = std::fs::remove_file(&link);
    std::os::unix::fs::symlink(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples"),
        &link,
    )
    .unwrap();
    let bin_dir = Path::new(env!("CARGO_BIN_EXE_polycal")).parent().unwrap();
    let path = format!(
        "{}:{}",
        bin_dir.display(),
        std::env::var("PATH").unwrap_or_default()
    );
    for command in [
        "solve", "diagnose", "budget", "compare", "simulate", "validate", "kc",
    ] {
        let help = String::from_utf8(polycal(&[command, "--help"]).stdout).unwrap();
        let examples = help
            .split("Examples:\n")
            .nth(1)
            .unwrap_or_else(|| panic!("{command} --help has no examples"));
        let lines: Vec<&str> = examples
            .lines()
            .map(str::trim)
            .filter(|l| l.starts_with("polycal "))
            .collect();
        assert!(lines.len() >= 2, "{command}: {lines:?}");
        for line in lines {
            let out = Command::new("sh")
                .args(["-c", line])
                .current_dir(&dir)
                .env("PATH", &path)
                .output()
                .unwrap();
            assert!(
                matches!(out.status.code(), Some(0 | 1)),
                "{line}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
    }
}
