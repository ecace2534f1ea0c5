//! Hardening (issue 13), errors and standard input: every usage and OS error is one
//! `error:` line, once for each bad file of several; standard input is read where `-` is
//! given, named `<stdin>`, and only once. Each class is tried with its own bad input,
//! through the binary as a user meets it.

use std::io::Write;
use std::path::Path;
use std::process::{Command, Output, Stdio};

use crate::hardening_support::{
    BUDGET, EXAMPLE, EXAMPLE_TRUTH, one_error_line, polycal, temp_dir, write,
};

fn polycal_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let mut stdin = child.stdin.take().expect("a pipe");
    // the process may refuse before reading all of it
    let _ = stdin.write_all(input);
    drop(stdin);
    child.wait_with_output().expect("the binary ends")
}

#[test]
fn usage_errors_are_one_line() {
    for args in [
        vec![],
        vec!["solve"],
        vec!["solve", "--bogus", EXAMPLE],
        vec!["frobnicate"],
        vec!["solve", EXAMPLE, "--format", "yaml"],
        vec!["budget", BUDGET, "--format", "csv"],
        vec!["compare", EXAMPLE],
        vec!["run"],
        vec!["simulate", "--faces", "x", "--cycles", "1"],
    ] {
        let message = one_error_line(&polycal(&args));
        assert!(message.ends_with("(see --help)"), "{args:?}: {message}");
    }
    assert_eq!(
        one_error_line(&polycal(&[])),
        "no command given; the commands are solve, diagnose, budget, compare, kc, history, selfcal, plan, report, \
         simulate, validate, run, sim-lab, completions, man (see --help)"
    );
}

#[test]
fn os_errors_are_named_once() {
    let missing = "no/such/file.csv";
    for args in [
        vec!["solve", missing],
        vec!["diagnose", missing],
        vec!["selfcal", missing],
        vec!["budget", missing],
        vec!["compare", missing, EXAMPLE],
        vec!["solve", EXAMPLE, "--budget", missing],
        vec!["diagnose", EXAMPLE, "--truth", missing],
        vec![
            "report",
            EXAMPLE,
            "--meta",
            missing,
            "--out",
            "/tmp/polycal-never.html",
        ],
    ] {
        let message = one_error_line(&polycal(&args));
        assert_eq!(
            message,
            format!("{missing}: No such file or directory (os error 2)"),
            "{args:?}"
        );
    }
    // a directory where a file is read
    assert_eq!(
        one_error_line(&polycal(&["solve", "examples"])),
        "examples: Is a directory (os error 21)"
    );
    // --plot on a file
    let dir = temp_dir("plot-file");
    let file = write(&dir, "not-a-dir", "");
    assert_eq!(
        one_error_line(&polycal(&["solve", EXAMPLE, "--plot", &file])),
        format!("--plot {file}: is a file, not a directory; the figures need a directory")
    );
}

#[test]
fn several_bad_files_give_one_error_line_each() {
    let out = polycal(&[
        "solve",
        "a/missing.csv",
        EXAMPLE,
        "b/missing.csv",
        "--format",
        "json",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(
        errors,
        [
            "error: a/missing.csv: No such file or directory (os error 2)",
            "error: b/missing.csv: No such file or directory (os error 2)",
        ],
        "{stderr}"
    );
    assert!(
        stderr.contains("\n2 of 3 files could not be solved\n"),
        "{stderr}"
    );
    // the good file is still solved, one JSON line
    assert_eq!(String::from_utf8_lossy(&out.stdout).lines().count(), 1);
    // with -q the summary goes, the errors stay
    let out = polycal(&["-q", "solve", "a/missing.csv", "b/missing.csv"]);
    assert_eq!(String::from_utf8_lossy(&out.stderr).lines().count(), 2);
}

#[test]
fn truth_from_standard_input_and_standard_input_only_once() {
    let from_file = polycal(&[
        "diagnose",
        EXAMPLE,
        "--truth",
        EXAMPLE_TRUTH,
        "--format",
        "json",
    ]);
    assert_eq!(from_file.status.code(), Some(0));
    let truth = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE_TRUTH)).unwrap();
    let from_stdin = polycal_stdin(
        &["diagnose", EXAMPLE, "--truth", "-", "--format", "json"],
        &truth,
    );
    assert_eq!(
        from_stdin.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&from_stdin.stderr)
    );
    let a: serde_json::Value = serde_json::from_slice(&from_file.stdout).unwrap();
    let b: serde_json::Value = serde_json::from_slice(&from_stdin.stdout).unwrap();
    assert!(a["error"].is_object());
    assert_eq!(a["error"], b["error"]);
    // bad JSON on standard input is named <stdin> with its line and column
    assert_eq!(
        one_error_line(&polycal_stdin(
            &["diagnose", EXAMPLE, "--truth", "-"],
            b"{\n  \"faces\": x"
        )),
        "<stdin>:2:12: not a valid truth file: expected value"
    );
    // two inputs cannot both be standard input
    let csv = std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(EXAMPLE)).unwrap();
    assert_eq!(
        one_error_line(&polycal_stdin(&["diagnose", "-", "--truth", "-"], &csv)),
        "standard input (`-`) is given for a measurement file and --truth: it can be read only \
         once; give the others as files"
    );
}
