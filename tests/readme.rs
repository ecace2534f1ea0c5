//! The README's shell blocks, run as written (issue 8: "every command the README shows
//! must run as written"): every ```sh block, in order, in one scratch directory that sees
//! the repository's `examples/`, with `cargo run --release --` and `target/release/polycal`
//! standing for the built binary. `cargo build`/`cargo test` lines are left out (this test
//! is run by them), and so are blocks preceded by a `<!-- tests/readme.rs skips … -->`
//! line (the two-terminal instructions, whose device paths differ on every machine; the
//! same run is shown as one script, which is run).

#![cfg(unix)]

use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

/// The ```sh blocks of the README that are to be run, each as its lines.
fn runnable_blocks(readme: &str) -> Vec<(usize, Vec<String>)> {
    let mut blocks = Vec::new();
    let mut lines = readme.lines().enumerate().peekable();
    let mut skip_next = false;
    while let Some((number, line)) = lines.next() {
        if line.starts_with("<!-- tests/readme.rs skips") {
            skip_next = true;
            continue;
        }
        if line.trim_end() != "```sh" {
            continue;
        }
        let mut body = Vec::new();
        for (_, inner) in lines.by_ref() {
            if inner.starts_with("```") {
                break;
            }
            body.push(inner.to_string());
        }
        if std::mem::take(&mut skip_next) {
            continue;
        }
        blocks.push((number + 1, body));
    }
    blocks
}

/// A block as a bash script for the built binary.
fn script(body: &[String]) -> String {
    let mut out = String::from("set -euo pipefail\n");
    for line in body {
        let trimmed = line.trim_start();
        if trimmed.starts_with("cargo ") && !trimmed.starts_with("cargo run --release --") {
            continue; // building and testing: what runs this test
        }
        out.push_str(
            &line
                .replace("cargo run --release --", "\"$POLYCAL\"")
                .replace("target/release/polycal", "\"$POLYCAL\""),
        );
        out.push('\n');
    }
    out
}

#[test]
fn the_readme_shell_blocks_run_as_written() {
    let readme = std::fs::read_to_string("README.md").expect("README.md");
    let blocks = runnable_blocks(&readme);
    assert!(
        blocks.len() >= 5,
        "expected the README's set-up, diagnose, uncertainty, command and lab blocks, found {}",
        blocks.len()
    );
    let scratch = std::env::temp_dir().join(format!("polycal-readme-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch).unwrap();
    let examples: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples");
    std::os::unix::fs::symlink(&examples, scratch.join("examples")).unwrap();
    for (line, body) in &blocks {
        let text = script(body);
        let output = Command::new("bash")
            .arg("-c")
            .arg(&text)
            .current_dir(&scratch)
            .env("POLYCAL", BIN)
            .env_remove("NO_COLOR")
            .output()
            .expect("bash runs");
        assert!(
            output.status.success(),
            "README.md block at line {line} failed ({}):\n{text}\nstdout:\n{}\nstderr:\n{}",
            output.status,
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let _ = std::fs::remove_dir_all(&scratch);
}

#[test]
fn the_skip_marker_and_the_cargo_lines_are_honoured() {
    let readme = "<!-- tests/readme.rs skips this -->\n```sh\nfalse\n```\n\n```sh\ncargo test\ncargo run --release -- solve x.csv\n```\n";
    let blocks = runnable_blocks(readme);
    assert_eq!(blocks.len(), 1);
    assert_eq!(
        script(&blocks[0].1),
        "set -euo pipefail\n\"$POLYCAL\" solve x.csv\n"
    );
}
