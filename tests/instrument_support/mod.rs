//! Helpers of the end-to-end instrument tests: a `polycal sim-lab` process serving
//! pseudo-terminals, `polycal run` against it, and checks of the run directory.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Lines, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Output, Stdio};
use std::time::{Duration, Instant};

use polycal::lab::run::RunSettings;
use polycal::measurement::MeasurementSet;
use serde_json::Value;

pub const BIN: &str = env!("CARGO_BIN_EXE_polycal");

/// A fresh scratch directory for one test.
pub fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-inst-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A running `polycal sim-lab`; killed when dropped.
pub struct SimLab {
    child: Child,
    stdin: ChildStdin,
    stdout: Lines<BufReader<ChildStdout>>,
    /// Every autocollimator's path, 1 … K.
    pub acs: Vec<String>,
    pub table: String,
    pub truth: PathBuf,
}

impl SimLab {
    /// Starts `polycal sim-lab --faces 8 --truth-out DIR/truth.json EXTRA…` (with
    /// `--time-scale 0` unless EXTRA sets it) and reads its three device paths.
    pub fn start(dir: &Path, extra: &[&str]) -> SimLab {
        let truth = dir.join("truth.json");
        let mut args = vec![
            "sim-lab".to_string(),
            "--faces".into(),
            "8".into(),
            "--truth-out".into(),
            truth.display().to_string(),
        ];
        if !extra.contains(&"--time-scale") {
            args.extend(["--time-scale".to_string(), "0".into()]);
        }
        args.extend(extra.iter().map(|s| s.to_string()));
        let mut child = Command::new(BIN)
            .args(&args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("sim-lab starts");
        let stdin = child.stdin.take().unwrap();
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        // `ac1 PATH`, `ac2 PATH`, … then `table PATH`.
        let mut acs = Vec::new();
        let table = loop {
            let line = lines.next().expect("a device line").unwrap();
            let (label, path) = line.split_once(' ').expect("NAME PATH");
            if label == "table" {
                break path.to_string();
            }
            assert_eq!(label, format!("ac{}", acs.len() + 1));
            acs.push(path.to_string());
        };
        SimLab {
            child,
            stdin,
            stdout: lines,
            acs,
            table,
            truth,
        }
    }

    /// The operator remounts the polygon for the lab's next setup: `remount` on the
    /// lab's standard input, and its `remounted N` line awaited.
    pub fn remount(&mut self) -> u32 {
        writeln!(self.stdin, "remount").unwrap();
        self.stdin.flush().unwrap();
        let line = self.stdout.next().expect("a line").unwrap();
        line.strip_prefix("remounted ")
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("not a remount: {line}"))
    }

    /// The `polycal run` arguments for this lab, writing to `out` (`--ac1`, `--ac2` for
    /// two autocollimators, one `--ac` each for more).
    pub fn run_args(&self, out: &Path, design: &[&str]) -> Vec<String> {
        let mut args = vec!["run".to_string()];
        if self.acs.len() == 2 {
            args.extend([
                "--ac1".into(),
                self.acs[0].clone(),
                "--ac2".into(),
                self.acs[1].clone(),
            ]);
        } else {
            for path in &self.acs {
                args.extend(["--ac".to_string(), path.clone()]);
            }
        }
        args.extend([
            "--table".into(),
            self.table.clone(),
            "--out".into(),
            out.display().to_string(),
        ]);
        args.extend(design.iter().map(|s| s.to_string()));
        args
    }
}

impl Drop for SimLab {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs the binary to completion.
pub fn polycal<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Output {
    Command::new(BIN)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .expect("the binary runs")
}

/// Runs the binary to completion with `input` on its standard input (the answer to a
/// prompt).
pub fn polycal_with_input<S: AsRef<std::ffi::OsStr>>(args: &[S], input: &str) -> Output {
    let mut child = Command::new(BIN)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("the binary runs");
    let mut stdin = child.stdin.take().unwrap();
    // The run may end before it reads (a refusal): a closed pipe is not the test's error.
    let _ = stdin.write_all(input.as_bytes());
    drop(stdin);
    child.wait_with_output().expect("the binary ends")
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Asserts a clean failure: status 2 and exactly one line, starting `error:`.
pub fn assert_error(out: &Output, says: &str) -> String {
    let text = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{text}");
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 1, "one error line: {text}");
    assert!(lines[0].starts_with("error: "), "{text}");
    assert!(lines[0].contains(says), "expected {says:?} in {text}");
    text
}

/// The header of a run's measurement file (docs/FORMAT.md §7), as the run has always written it.
pub const RUN_HEADER: &str =
    "cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift";

/// The (cycle, step, ac) of every data row of a run's measurement file.
pub fn rows(dir: &Path) -> Vec<(u32, usize, u32)> {
    let text = std::fs::read_to_string(dir.join("measurements.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    assert_eq!(lines.next(), Some(RUN_HEADER));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 11, "{l}");
            (
                f[0].parse().unwrap(),
                f[1].parse().unwrap(),
                f[2].parse().unwrap(),
            )
        })
        .collect()
}

/// The readings of the whole run, in order.
pub fn plan_readings(settings: &RunSettings) -> Vec<(u32, usize, u32)> {
    settings
        .plan()
        .into_iter()
        .flat_map(|s| (1..=settings.ac_faces.len() as u32).map(move |ac| (s.cycle, s.step, ac)))
        .collect()
}

pub fn manifest(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("manifest.json")).unwrap()).unwrap()
}

/// The traffic log's records, split into sessions.
pub fn sessions(dir: &Path) -> Vec<Vec<Value>> {
    let text = std::fs::read_to_string(dir.join("traffic.jsonl")).unwrap();
    let mut out: Vec<Vec<Value>> = Vec::new();
    for line in text.lines() {
        let v: Value = serde_json::from_str(line).expect("every traffic line is JSON");
        for key in ["t", "device", "port", "event", "text"] {
            assert!(v.get(key).is_some(), "{key} in {line}");
        }
        if v["event"] == "session" {
            out.push(Vec::new());
        }
        out.last_mut().expect("a session record first").push(v);
    }
    out
}

/// The positions of every `1PA` command sent in a session, degrees, pre-positions
/// included.
pub fn all_moves(session: &[Value]) -> Vec<f64> {
    session
        .iter()
        .filter(|r| r["event"] == "sent" && r["device"] == "table")
        .filter_map(|r| r["text"].as_str()?.strip_prefix("1PA"))
        .map(|a| a.trim().parse().unwrap())
        .collect()
}

/// Whether a traffic record is a `1PA` command sent to the table.
fn is_move(r: &Value) -> bool {
    r["event"] == "sent"
        && r["device"] == "table"
        && r["text"].as_str().is_some_and(|t| t.starts_with("1PA"))
}

/// The positions of the `1PA` commands sent in a session onto stops, degrees: without
/// the pre-positions from which a stop is approached in its cycle's direction (a move
/// followed by another move before any autocollimator is asked anything).
pub fn moves(session: &[Value]) -> Vec<f64> {
    let mut out = Vec::new();
    for (i, r) in session.iter().enumerate() {
        if !is_move(r) {
            continue;
        }
        let rest = &session[i + 1..];
        let next_move = rest.iter().position(is_move).unwrap_or(rest.len());
        let read_before = rest[..next_move]
            .iter()
            .any(|e| e["device"].as_str().is_some_and(|d| d.starts_with("ac")));
        if read_before || next_move == rest.len() {
            let text = r["text"].as_str().unwrap();
            out.push(text["1PA".len()..].trim().parse().unwrap());
        }
    }
    out
}

/// Asserts that a session sent exactly one move per stop, in the run's order, from stop
/// `first` on: a move is never sent twice.
pub fn assert_moves_follow_plan(session: &[Value], settings: &RunSettings, first: usize) {
    assert_follow_plan(&moves(session), settings, first);
}

/// Asserts that the moves `sent` are the run's stops in order from stop `first` on.
fn assert_follow_plan(sent: &[f64], settings: &RunSettings, first: usize) {
    let plan: Vec<f64> = settings
        .plan()
        .iter()
        .map(|s| s.degrees(settings.faces))
        .collect();
    assert!(
        first + sent.len() <= plan.len(),
        "more moves than stops: {sent:?}"
    );
    for (i, (a, b)) in sent.iter().zip(&plan[first..]).enumerate() {
        assert!(
            (a - b).abs() < 1e-6,
            "move {i}: sent {a}, the plan says {b}"
        );
    }
}

/// Asserts that a resumed session, begun with `done` readings on disk, first went back
/// to the last stop with a stored reading (read again there and compared, docs/FORMAT.md
/// §7.3, nothing stored), then sent one move per stop in the run's order from the first
/// stop with a missing reading on.
pub fn assert_resumed_moves_follow_plan(session: &[Value], settings: &RunSettings, done: usize) {
    let k = settings.ac_faces.len();
    let plan: Vec<f64> = settings
        .plan()
        .iter()
        .map(|s| s.degrees(settings.faces))
        .collect();
    let sent = moves(session);
    let last_stored = plan[(done - 1) / k];
    assert!(
        sent.first().is_some_and(|a| (a - last_stored).abs() < 1e-6),
        "the last stop with a stored reading, {last_stored}°, first: {sent:?}"
    );
    assert_follow_plan(&sent[1..], settings, done / k);
    assert_eq!(sent.len() - 1, plan.len() - done / k, "{sent:?}");
}

/// Every reading of the run is in the file exactly once, in order.
pub fn assert_complete(dir: &Path, settings: &RunSettings) {
    assert_eq!(rows(dir), plan_readings(settings));
}

/// `polycal solve --format json` of the run agrees with the lab's truth within the
/// uncertainties the fit states (5 u, and 5 σ of the noise at most).
pub fn assert_solves_to_truth(dir: &Path, truth: &Path) {
    let file = dir.join("measurements.csv");
    MeasurementSet::read_path(&file, None).expect("the run's file reads back");
    let out = polycal(&[
        "solve".to_string(),
        file.display().to_string(),
        "--format".into(),
        "json".into(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let truth: Value = serde_json::from_str(&std::fs::read_to_string(truth).unwrap()).unwrap();
    let sigma = truth["noise_arcsec"].as_f64().unwrap();
    let numbers = |v: &Value| -> Vec<f64> {
        v.as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    for key in ["pitch_deviation", "encoder_error"] {
        let est = numbers(&json[key]);
        let u = numbers(&json[format!("{key}_u")]);
        let tru = numbers(&truth[key]);
        assert_eq!(est.len(), tru.len());
        for k in 0..est.len() {
            let err = (est[k] - tru[k]).abs();
            assert!(
                err < 5.0 * u[k] && err < 5.0 * sigma,
                "{key}[{k}]: estimate {}, truth {}, u {}",
                est[k],
                tru[k],
                u[k]
            );
        }
    }
}

/// Waits until the run's file has at least `n` data rows.
pub fn wait_for_rows(dir: &Path, n: usize, limit: Duration) {
    let start = Instant::now();
    loop {
        let count = std::fs::read_to_string(dir.join("measurements.csv"))
            .map(|t| {
                t.lines()
                    .filter(|l| !l.starts_with('#'))
                    .count()
                    .saturating_sub(1)
            })
            .unwrap_or(0);
        if count >= n {
            return;
        }
        assert!(start.elapsed() < limit, "only {count} rows after {limit:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
}
