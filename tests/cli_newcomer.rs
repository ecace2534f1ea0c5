//! What a newcomer meets first (issue 48): refusals that say what the file is and what to
//! do, a warning for a cycle with fewer steps than the others, standard output closed by
//! its reader ending quietly, and the sim-lab banner's lines.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

fn polycal_stdin(args: &[&str], input: &[u8]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    child.stdin.take().unwrap().write_all(input).unwrap();
    child.wait_with_output().unwrap()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-newcomer-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn path_str(path: &Path) -> &str {
    path.to_str().unwrap()
}

/// Spawns polycal with standard output a pipe, reads one line of it, closes the pipe and
/// waits: (the line, standard error, the exit status).
fn read_one_line_then_close(args: &[&str]) -> (String, String, Option<i32>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let mut first = String::new();
    {
        let mut reader = BufReader::new(child.stdout.take().unwrap());
        reader.read_line(&mut first).unwrap();
        // the reader dropped here: the pipe's read end is closed
    }
    let out = child.wait_with_output().unwrap();
    (first, stderr(&out), out.status.code())
}

/// `simulate --faces 720` writes 8 640 readings (about 300 kB, far more than a pipe's
/// 64 kB buffer), so its writes after the reader is gone really fail with a broken pipe.
#[test]
fn standard_output_closed_by_its_reader_ends_quietly() {
    let (first, err, status) = read_one_line_then_close(&["simulate", "--faces", "720"]);
    assert!(first.starts_with("# polycal"), "{first}");
    assert_eq!(err, "", "nothing on standard error");
    assert_eq!(status, Some(141));

    // The same for a solve whose CSV is far larger than the pipe's buffer.
    let dir = temp_dir("pipe");
    let big = dir.join("big.csv");
    let made = polycal(&["simulate", "--faces", "720", "--out", path_str(&big)]);
    assert!(made.status.success(), "{}", stderr(&made));
    let (first, err, status) =
        read_one_line_then_close(&["solve", path_str(&big), "--format", "csv"]);
    assert_eq!(first, "quantity,index,value,U,u,k,angle_deg\n");
    assert_eq!(err, "", "nothing on standard error");
    assert_eq!(status, Some(141));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Standard output that is read to its end is no different: status 0, the whole table.
#[test]
fn standard_output_read_to_the_end_is_whole() {
    let out = polycal(&["simulate", "--faces", "720"]);
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let text = String::from_utf8(out.stdout).unwrap();
    // a comment line, the header, 720 steps × 2 autocollimators × 6 cycles
    assert_eq!(text.lines().count(), 2 + 720 * 2 * 6);
}

/// The sim-lab banner is lines, not one line with a literal `\n` in it.
#[test]
fn the_sim_lab_banner_is_lines() {
    // Standard input closed at once: the lab prints its paths and banner, then ends.
    let out = polycal_stdin(&["sim-lab", "--faces", "8"], b"");
    assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(!err.contains("\\n"), "{err}");
    let lines: Vec<&str> = err.lines().collect();
    assert_eq!(
        lines.first(),
        Some(&"polycal sim-lab: serving; try"),
        "{err}"
    );
    assert!(
        lines
            .get(1)
            .is_some_and(|l| l.starts_with("  polycal run --ac1 ")),
        "{err}"
    );
    assert!(
        lines.iter().any(|l| l.starts_with("stop with Ctrl-C")),
        "{err}"
    );
}

/// A negative count is a value out of range, not an unknown option `-5`.
#[test]
fn a_negative_count_is_out_of_range() {
    for (args, option) in [
        (&["simulate", "--faces", "-5"][..], "--faces -5"),
        (&["simulate", "--faces=-5"][..], "--faces -5"),
        (&["simulate", "--cycles", "-1"][..], "--cycles -1"),
        (
            &[
                "solve",
                "examples/data/polygon24-2ac-6cycles.csv",
                "--faces",
                "-24",
            ][..],
            "--faces -24",
        ),
    ] {
        let out = polycal(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = stderr(&out);
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(
            err.starts_with(&format!("error: {option}: out of range")),
            "{err}"
        );
        assert!(!err.contains("unexpected argument"), "{err}");
    }
    // A parser with a message of its own keeps it.
    let out = polycal(&["solve", "-", "--sigma", "-1"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        stderr(&out).contains("must be a positive, finite number"),
        "{}",
        stderr(&out)
    );
}
