//! A test that needs a program the machine lacks says so where `cargo test` shows it
//! (issue 48, item 7): without `xmllint` the DCC schema validation, and without Chromium
//! or poppler's `pdftotext` the printed-report test, would otherwise pass silently.
//!
//! libtest captures what a passing test prints with `print!`/`eprint!`, and shows it only
//! when the test fails or with `--nocapture`; it does not capture writes to the process's
//! standard error through [`std::io::stderr`]. So the line written here reaches whatever
//! `cargo test`'s standard error is — the terminal, or the CI log — between the
//! `test … ok` lines, once per test binary (the tier) and program, with or without
//! `--nocapture`.
//! It is not opened on the terminal behind the caller's back (`/dev/tty`): redirected
//! output keeps it. The README's "Tests" paragraph says to look for `SKIPPED:` lines.
//!
//! Where CI must not skip, a variable (`POLYCAL_REQUIRE_XMLLINT`,
//! `POLYCAL_REQUIRE_BROWSER`, set by `.ci/run`) turns the absence into a failure.
#![allow(dead_code)]

use std::collections::BTreeSet;
use std::io::Write;
use std::sync::Mutex;

/// Programs already reported as missing by this test binary.
static REPORTED: Mutex<BTreeSet<String>> = Mutex::new(BTreeSet::new());

/// The program could not run: fails when `require` (an environment variable) is set,
/// otherwise writes one `SKIPPED:` line on standard error (once per binary and program)
/// naming the binary's tier (`tests/commands`), what is not checked, the program, how to
/// install it and the variable that makes its absence a failure.
pub fn missing(program: &str, what: &str, install: &str, require: &str, error: &str) {
    assert!(
        std::env::var_os(require).is_none(),
        "{require} is set and {program} cannot run: {error}"
    );
    let first = REPORTED
        .lock()
        .map(|mut seen| seen.insert(program.to_string()))
        .unwrap_or(true);
    if first {
        let line = format!(
            "SKIPPED: tests/{}: {what}, because {program} is not installed ({install}); \
             {require}=1 makes this a failure\n",
            env!("CARGO_CRATE_NAME")
        );
        // one write of the whole line, so that parallel tests do not interleave within it
        let _ = std::io::stderr().write_all(line.as_bytes());
    }
}
