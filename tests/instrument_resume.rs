//! Interrupted runs over pseudo-terminals: the running binary killed (SIGKILL) in mid
//! cycle, then `--resume`; and Ctrl-C (SIGINT), which stops the table, finishes the files
//! and records how the run ended. In both, the final file has every reading exactly
//! once and still solves to the truth.

#![cfg(unix)]

mod instrument_support;

use std::process::{Command, Stdio};
use std::time::Duration;

use instrument_support::*;
use polycal::lab::run::RunSettings;

fn settings(cycles: u32, closing: bool, settle: f64) -> RunSettings {
    RunSettings::new(8, cycles)
        .with_closing(closing)
        .with_settle_seconds(settle)
}

/// The first stop of the plan with a missing reading, given the rows on disk (two
/// readings per stop, in order).
fn first_missing_stop(dir: &std::path::Path) -> usize {
    rows(dir).len() / 2
}

#[test]
fn killed_in_mid_cycle_then_resumed_loses_and_repeats_nothing() {
    let dir = scratch("kill");
    let lab = SimLab::start(&dir, &["--cycles", "3", "--closing"]);
    let out = dir.join("run");
    let s = settings(3, true, 0.04);
    let design = [
        "--faces",
        "8",
        "--cycles",
        "3",
        "--closing",
        "--settle",
        "0.04",
        "-q",
    ];
    let mut child = Command::new(BIN)
        .args(lab.run_args(&out, &design))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // Cycle 1 has 18 readings: wait until cycle 2 is under way.
    wait_for_rows(&out, 23, Duration::from_secs(20));
    child.kill().unwrap(); // SIGKILL: no chance to tidy up
    child.wait().unwrap();

    let before = rows(&out);
    assert!(before.len() < 54, "killed before the end");
    assert_eq!(
        before,
        plan_readings(&s)[..before.len()],
        "what is there is in order"
    );
    assert_eq!(
        manifest(&out)["outcome"],
        "running",
        "the killed run could not say more"
    );

    let mut args = lab.run_args(&out, &design);
    args.push("--resume".into());
    let first = first_missing_stop(&out);
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));

    assert_complete(&out, &s);
    assert_solves_to_truth(&out, &lab.truth);
    let m = manifest(&out);
    assert_eq!(m["outcome"], "completed");
    assert_eq!(m["readings"], 54);
    let sessions_in_manifest = m["sessions"].as_array().unwrap();
    assert_eq!(sessions_in_manifest.len(), 2);
    assert_eq!(sessions_in_manifest[0]["outcome"], "running");
    assert_eq!(sessions_in_manifest[1]["readings_before"], before.len());

    let traffic = sessions(&out);
    assert_eq!(traffic.len(), 2);
    assert_moves_follow_plan(&traffic[0], &s, 0);
    assert_moves_follow_plan(&traffic[1], &s, first);
    // Time goes on from the run's start across the sessions.
    let text = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    let times: Vec<f64> = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').nth(6).unwrap().parse().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
}

#[test]
fn ctrl_c_stops_the_table_keeps_the_data_and_resume_completes() {
    let dir = scratch("ctrl-c");
    // 45° takes 0.25 s: the table is moving most of the time.
    let lab = SimLab::start(
        &dir,
        &["--time-scale", "1", "--speed", "180", "--home-seconds", "0"],
    );
    let out = dir.join("run");
    let s = settings(1, true, 0.0);
    let design = [
        "--faces",
        "8",
        "--cycles",
        "1",
        "--closing",
        "--settle",
        "0",
    ];
    let child = Command::new(BIN)
        .args(lab.run_args(&out, &design))
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_rows(&out, 2, Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(60)); // on the way to 45°
    // SAFETY: sending a signal to our own child process.
    let sent = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    assert_eq!(sent, 0);
    let output = child.wait_with_output().unwrap();
    let text = assert_error(&output, "interrupted");
    assert!(text.contains("--resume"), "{text}");

    let m = manifest(&out);
    assert_eq!(m["outcome"], "interrupted");
    assert!(m["ended"].is_string());
    let kept = rows(&out);
    assert!(!kept.is_empty() && kept.len() < 18);
    assert_eq!(kept, plan_readings(&s)[..kept.len()]);
    let traffic = sessions(&out);
    let table_sent: Vec<&str> = traffic[0]
        .iter()
        .filter(|r| r["event"] == "sent" && r["device"] == "table")
        .map(|r| r["text"].as_str().unwrap())
        .collect();
    assert_eq!(table_sent.last(), Some(&"1ST\r\n"), "the table was stopped");
    assert_moves_follow_plan(&traffic[0], &s, 0);

    let mut args = lab.run_args(&out, &design);
    args.extend(["--resume".to_string(), "-q".into()]);
    let first = first_missing_stop(&out);
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    assert_complete(&out, &s);
    assert_solves_to_truth(&out, &lab.truth);
    assert_eq!(manifest(&out)["outcome"], "completed");
    assert_moves_follow_plan(&sessions(&out)[1], &s, first);
}
