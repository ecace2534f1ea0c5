//! Interrupted runs over pseudo-terminals: the running binary killed (SIGKILL) in mid
//! cycle, then `--resume`; and Ctrl-C (SIGINT), which stops the table, finishes the files
//! and records how the run ended. In both, the final file has every reading exactly
//! once and still solves to the truth.

#![cfg(unix)]

use std::process::{Command, Stdio};
use std::time::Duration;

use crate::instrument_support::*;
use polycal::lab::run::RunSettings;

fn settings(cycles: u32, closing: bool, settle: f64) -> RunSettings {
    RunSettings::new(8, cycles)
        .with_closing(closing)
        .with_settle_seconds(settle)
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
    let mut child = spawn_run(&lab.run_args(&out, &design));
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
    assert_resumed_moves_follow_plan(&traffic[1], &s, before.len());
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
    let child = spawn_run(&lab.run_args(&out, &design));
    wait_for_rows(&out, 2, Duration::from_secs(20));
    std::thread::sleep(Duration::from_millis(60)); // on the way to 45°
    interrupt(&child);
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
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    assert_complete(&out, &s);
    assert_solves_to_truth(&out, &lab.truth);
    assert_eq!(manifest(&out)["outcome"], "completed");
    assert_resumed_moves_follow_plan(&sessions(&out)[1], &s, kept.len());
}

#[test]
fn a_second_ctrl_c_ends_at_once_records_interrupted_and_resume_completes() {
    let dir = scratch("ctrl-c-twice");
    // Autocollimator 1's fifth reply (its first at stop 2; two readings a stop) and the
    // three resynchronisations after it are lost: with --timeout 2 its driver waits 8 s
    // without looking at the stop flag, so the first Ctrl-C cannot end the run quickly.
    let lab = SimLab::start(&dir, &["--fault", "lost-reply:ac1:after=4:count=4"]);
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
        "--timeout",
        "2",
    ];
    let child = spawn_run(&lab.run_args(&out, &design));
    wait_for_rows(&out, 4, Duration::from_secs(20));
    // The ninth `a` (autocollimator 1 at stop 2) is sent: its driver waits for the reply.
    let start = std::time::Instant::now();
    while std::fs::read_to_string(out.join("traffic.jsonl"))
        .unwrap()
        .matches(r#""event":"sent","text":"a\n""#)
        .count()
        < 9
    {
        assert!(start.elapsed() < Duration::from_secs(20));
        std::thread::sleep(Duration::from_millis(5));
    }
    std::thread::sleep(Duration::from_millis(50));
    interrupt(&child);
    std::thread::sleep(Duration::from_millis(200));
    let second = std::time::Instant::now();
    interrupt(&child);
    let output = child.wait_with_output().unwrap();
    // "at once": well before the 8 s the driver would still wait for the lost replies
    // (the bound is loose, so that a loaded machine does not fail it)
    assert!(second.elapsed() < Duration::from_secs(5), "at once");
    let text = stderr(&output);
    assert_eq!(output.status.code(), Some(130), "{text}");
    assert_eq!(
        text,
        format!(
            "error: run stopped at once by a second interrupt (the table may not have stopped); \
             4 of 18 readings are in {}; continue with the same command and --resume\n",
            out.join("measurements.csv").display()
        )
    );

    let m = manifest(&out);
    assert_eq!(m["outcome"], "interrupted");
    assert!(m["ended"].is_string());
    assert_eq!(m["readings"], 4);
    assert_eq!(m["sessions"][0]["outcome"], "interrupted");
    assert_eq!(m["sessions"][0]["readings_after"], 4);
    assert!(!out.join("manifest.json.tmp").exists());
    let text = std::fs::read_to_string(out.join("measurements.csv")).unwrap();
    assert!(text.ends_with('\n'));
    assert_eq!(rows(&out), plan_readings(&s)[..4]);
    sessions(&out); // every record is JSON

    let mut args = lab.run_args(&out, &design);
    args.truncate(args.len() - 2);
    args.extend(["--timeout", "0.3", "--resume", "-q"].map(String::from));
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    assert_complete(&out, &s);
    assert_solves_to_truth(&out, &lab.truth);
    let m = manifest(&out);
    assert_eq!(m["outcome"], "completed");
    assert_eq!(m["sessions"][1]["readings_before"], 4);
}

/// A tmpfs of a given size mounted on a directory, unmounted when dropped.
struct Tmpfs(std::path::PathBuf);

impl Tmpfs {
    /// Mounts `size` (e.g. `32k`) on `dir`, or `None` when that is not possible here
    /// (not root, no tmpfs).
    fn mount(dir: &std::path::Path, size: &str) -> Option<Tmpfs> {
        // SAFETY: geteuid has no preconditions.
        if unsafe { libc::geteuid() } != 0 {
            return None;
        }
        std::fs::create_dir_all(dir).ok()?;
        let mounted = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir)
            .stderr(Stdio::null())
            .status()
            .ok()?
            .success();
        mounted.then(|| Tmpfs(dir.to_path_buf()))
    }

    fn resize(&self, size: &str) {
        let status = Command::new("mount")
            .args(["-o", &format!("remount,size={size}")])
            .arg(&self.0)
            .status()
            .unwrap();
        assert!(status.success());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn a_real_full_disk_stops_the_run_and_resume_completes_with_space() {
    let dir = scratch("tmpfs");
    let Some(disk) = Tmpfs::mount(&dir.join("disk"), "4k") else {
        eprintln!("skipped: cannot mount a tmpfs here (needs root on Linux)");
        return;
    };
    let lab = SimLab::start(&dir, &["--cycles", "3", "--closing"]);
    let out = disk.0.join("run");
    let s = settings(3, true, 0.0);
    let design = [
        "--faces",
        "8",
        "--cycles",
        "3",
        "--closing",
        "--settle",
        "0",
        "-q",
    ];
    // One page: the measurement file's header fits, the manifest does not. The run
    // does not start and removes what it created; the same command starts it later.
    let no_start = polycal(&lab.run_args(&out, &design));
    let text = assert_error(&no_start, "No space left on device");
    assert!(
        text.contains("manifest.json") && text.ends_with("its files were removed\n"),
        "{text}"
    );
    assert!(!out.exists(), "nothing left: {text}");

    disk.resize("32k");
    let full = polycal(&lab.run_args(&out, &design));
    let text = assert_error(&full, "No space left on device");
    assert!(
        text.contains("continue with the same command and --resume"),
        "{text}"
    );

    // Whole lines, the run's first readings in order, every record JSON.
    let bytes = std::fs::read(out.join("measurements.csv")).unwrap();
    assert_eq!(bytes.last(), Some(&b'\n'));
    let kept = rows(&out);
    assert!(kept.len() < 54, "the disk filled up: {text}");
    assert_eq!(kept, plan_readings(&s)[..kept.len()]);
    let log = std::fs::read_to_string(out.join("traffic.jsonl")).unwrap();
    assert!(log.ends_with('\n'));
    sessions(&out);
    assert!(!out.join("manifest.json.tmp").exists());
    let outcome = manifest(&out)["outcome"].as_str().unwrap().to_string();
    if text.contains("the manifest could not record it") {
        assert_eq!(outcome, "running", "{text}");
    } else {
        assert!(outcome.starts_with("file-error: ") && outcome.contains("No space left on device"));
    }

    // Resumed while the disk is still full: it stops again, consistently.
    let mut args = lab.run_args(&out, &design);
    args.push("--resume".into());
    let again = polycal(&args);
    assert_error(&again, "No space left on device");
    let kept = rows(&out);
    assert_eq!(kept, plan_readings(&s)[..kept.len()]);
    assert!(
        std::fs::read_to_string(out.join("traffic.jsonl"))
            .unwrap()
            .ends_with('\n')
    );
    sessions(&out);

    disk.resize("1m");
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    assert_complete(&out, &s);
    assert_solves_to_truth(&out, &lab.truth);
    assert_eq!(manifest(&out)["outcome"], "completed");
    let traffic = sessions(&out);
    assert_resumed_moves_follow_plan(traffic.last().unwrap(), &s, kept.len());
}

/// `polycal run` with `args` as a child process: standard output and error piped, no
/// standard input.
fn spawn_run(args: &[String]) -> std::process::Child {
    Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("polycal runs")
}

/// Ctrl-C to a child process.
fn interrupt(child: &std::process::Child) {
    // SAFETY: sending a signal to our own child process.
    let sent = unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGINT) };
    assert_eq!(sent, 0);
}
