//! Progress of the long jobs on standard error, and Ctrl-C during them (issue 34): a bar
//! on a terminal only, none with `-q`, and the process ended within a second of the
//! signal. The terminal is util-linux `script`'s pseudo-terminal; Ctrl-C is the SIGINT
//! `timeout -s INT` sends.

use std::path::PathBuf;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_polycal");

/// A fresh directory of this test process.
fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-progress-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    dir
}

/// `polycal simulate ARGS` written to `dir`, then written again as `name` without the
/// readings `left_out` picks (the comment and header lines kept): a run whose missing
/// readings make its fits slow.
fn simulated_without(
    dir: &std::path::Path,
    args: &[&str],
    name: &str,
    mut left_out: impl FnMut(&str) -> bool,
) -> PathBuf {
    let full = dir.join("full.csv");
    let out = Command::new(BIN)
        .arg("simulate")
        .args(args)
        .arg("--out")
        .arg(&full)
        .output()
        .expect("the binary runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(&full).expect("the simulated run");
    let mut kept = String::new();
    for line in text.lines() {
        let header = line.starts_with('#') || line.starts_with("cycle");
        if header || !left_out(line) {
            kept.push_str(line);
            kept.push('\n');
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, kept).expect("the input is written");
    path
}

/// A diagnosis that takes seconds: 1440 faces, 4 cycles with closing readings, a drift
/// and a zero jump, and one stop in six left out (every cell that loses a reading is
/// irregular, so every fit is the dense reference's, about a second each; about 6 s in
/// all on two cores).
fn long_diagnosis_input(dir: &std::path::Path) -> PathBuf {
    let args = [
        "--faces",
        "1440",
        "--cycles",
        "4",
        "--closing",
        "--drift",
        "2:1.5",
        "--offset-step",
        "1:3:0.4",
    ];
    simulated_without(dir, &args, "irregular.csv", |line| {
        let mut fields = line.split(',');
        let (cycle, step) = (fields.next(), fields.next());
        match (
            cycle.and_then(|c| c.parse::<usize>().ok()),
            step.and_then(|s| s.parse::<usize>().ok()),
        ) {
            (Some(cycle), Some(step)) => (step * 7 + cycle) % 6 == 0,
            _ => false,
        }
    })
}

/// `polycal ARGS` sent SIGINT after `seconds`, on a pseudo-terminal: what the terminal
/// showed, the status (`timeout`'s 124 when the signal came before the end) and how long
/// it ran.
fn interrupted_on_a_terminal(args: &str, seconds: u32) -> (String, Option<i32>, Duration) {
    let started = Instant::now();
    let out = Command::new("script")
        .args([
            "-qec",
            &format!("timeout -s INT {seconds} {BIN} {args}"),
            "/dev/null",
        ])
        .stdin(Stdio::null())
        .output()
        .expect("script (util-linux) runs");
    let elapsed = started.elapsed();
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        out.status.code(),
        elapsed,
    )
}

/// `polycal ARGS` sent SIGINT after `seconds`, standard error a pipe.
fn interrupted_in_a_pipe(args: &[&str], seconds: u32) -> Output {
    Command::new("timeout")
        .args(["-s", "INT", &seconds.to_string(), BIN])
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("timeout (coreutils) runs")
}

/// When Ctrl-C comes on the terminal. Alone on two cores the first bar is drawn after
/// 1.6 s (the diagnosis) and 2.2–2.7 s (the sub-pitch solve), which run 34 s and 15 s in
/// all: 6 s leaves room for the other tests of the tier running beside this one.
const CTRL_C_AFTER_SECONDS: u32 = 6;

/// `polycal COMMAND FILE` on a pseudo-terminal shows `bar` (checked by `shows`) and is
/// still running when Ctrl-C comes after [`CTRL_C_AFTER_SECONDS`], then ends within a
/// second; with `-q` it shows nothing of it, and into a pipe its standard error stays
/// empty.
fn bar_shown_only_on_a_terminal_and_ctrl_c_ends_it(
    command: &str,
    input: &std::path::Path,
    bar: &str,
    shows: impl Fn(&str),
) {
    let file = input.display();
    let (shown, status, elapsed) =
        interrupted_on_a_terminal(&format!("{command} {file}"), CTRL_C_AFTER_SECONDS);
    assert_eq!(status, Some(124), "ended before Ctrl-C:\n{shown}");
    shows(&shown);
    assert!(
        elapsed < Duration::from_secs(u64::from(CTRL_C_AFTER_SECONDS) + 1),
        "ended {elapsed:?} after its start, {CTRL_C_AFTER_SECONDS} s of it before Ctrl-C"
    );
    // -q: no bar
    let (shown, status, _) = interrupted_on_a_terminal(&format!("-q {command} {file}"), 2);
    assert_eq!(status, Some(124), "ended before Ctrl-C:\n{shown}");
    assert!(!shown.contains(bar), "a bar with -q:\n{shown}");
    // standard error not a terminal: nothing on it
    let out = interrupted_in_a_pipe(&[command, &input.to_string_lossy()], 2);
    assert_eq!(out.status.code(), Some(124));
    assert!(
        out.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_long_diagnosis_shows_its_rounds_and_ends_within_a_second_of_ctrl_c() {
    let dir = temp_dir("diagnose");
    let input = long_diagnosis_input(&dir);
    // the rounds of the forward selection, a spinner (their number is the data's: no
    // estimate of the time left)
    bar_shown_only_on_a_terminal_and_ctrl_c_ends_it("diagnose", &input, "Diagnosing", |shown| {
        assert!(
            shown.contains("Diagnosing ") && shown.contains(" rounds · "),
            "no progress:\n{shown}"
        );
        assert!(
            !shown.contains(" left"),
            "an estimate without a total:\n{shown}"
        );
    });
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sub-pitch solve that takes seconds: 720 faces, three autocollimators, four mountings
/// 0.1° apart (four cosets), one reading in ten left out at random, so that the coset engine cannot
/// take it and the dense reference fits the cosets' differences as effect columns (a
/// reduced system of about 2900 unknowns).
fn long_sub_pitch_input(dir: &std::path::Path) -> PathBuf {
    let args = [
        "--faces",
        "720",
        "--ac-faces",
        "1,2,3",
        "--setups",
        "4",
        "--shift-deg",
        "0,0.1,0.2,0.3",
    ];
    // one in ten at random (a regular pattern the coset engine would take)
    let mut data = 0_u64;
    simulated_without(dir, &args, "sub-pitch.csv", |_| {
        data += 1;
        (data.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40).is_multiple_of(10)
    })
}

#[test]
fn a_long_sub_pitch_solve_shows_the_time_left_and_ends_within_a_second_of_ctrl_c() {
    let dir = temp_dir("solve");
    let input = long_sub_pitch_input(&dir);
    // a bar with a total and the time left
    bar_shown_only_on_a_terminal_and_ctrl_c_ends_it("solve", &input, "Solving", |shown| {
        assert!(shown.contains("Solving ["), "no progress bar:\n{shown}");
        assert!(
            shown.contains(" steps · ") && shown.contains(" left"),
            "no estimate of the time left:\n{shown}"
        );
    });
    let _ = std::fs::remove_dir_all(&dir);
}
