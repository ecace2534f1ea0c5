//! A full disk during a run, in process: the run directory's files written through a
//! byte budget ([`WriteBudget`]) that fails as a full disk does once spent. Whichever
//! write fails first — while the run starts, in the measurement file, in the traffic log
//! or in the manifest — the run stops there with its files consistent: the measurement
//! file and the traffic log end on whole lines, every traffic record is JSON, the
//! measurement file reads back with the crate's reader and holds the run's first readings
//! in order, each the value the simulated lab's truth gives (noise 0), and no reading
//! that was reported on disk is missing. With space again, a resumed run completes with
//! exactly the run's readings, none lost or repeated.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use crate::lab_support::*;
use polycal::lab::driver::ProfileAutocollimator;
use polycal::lab::driver::{ProfileTable, TableOptions};
use polycal::lab::run::{self, Instruments, Outcome, RunDir, RunError, RunSettings};
use polycal::lab::sim::{Devices, SimStream};
use polycal::lab::traffic::{LoggedTransport, TrafficLog};
use polycal::lab::transport::StreamTransport;
use polycal::lab::{StopFlag, WriteBudget};
use polycal::measurement::{Reading, read_rows};
use polycal::simulate::Truth;
use serde_json::Value;

/// 8 faces, 2 cycles with the closing step: 36 readings.
fn settings() -> RunSettings {
    RunSettings::new(8, 2).with_closing(true)
}

const READINGS: usize = 36;

/// A noiseless lab (every reading is the truth's value); each session gets a new one
/// with the same truth, as after switching the instruments off and on.
fn noiseless() -> Devices {
    Devices::new(lab(8, 0.0, vec![])).unwrap()
}

/// The lab's truth.
fn truth() -> &'static Truth {
    static TRUTH: OnceLock<Truth> = OnceLock::new();
    TRUTH.get_or_init(|| noiseless().truth())
}

type Logged = LoggedTransport<StreamTransport<SimStream>>;

/// The drivers of a new noiseless lab, every line they exchange recorded in `log`.
fn logged_drivers(
    log: &TrafficLog,
) -> (
    ProfileAutocollimator<Logged>,
    ProfileAutocollimator<Logged>,
    ProfileTable<Logged>,
) {
    let Devices {
        autocollimators,
        table,
        ..
    } = noiseless();
    let Ok([ac1, ac2]) = <[_; 2]>::try_from(autocollimators) else {
        panic!("two autocollimators")
    };
    let port = |name: &str, device: &str, stream| {
        LoggedTransport::new(StreamTransport::new(name, stream), device, log.clone())
    };
    let ac = |name: &str, device: &str, stream| {
        ProfileAutocollimator::elcomat3000(port(name, device, stream), query())
            .with_drain(Duration::ZERO)
    };
    (
        ac("mem:ac1", "ac1", SimStream::new(ac1)),
        ac("mem:ac2", "ac2", SimStream::new(ac2)),
        ProfileTable::smc100(
            port("mem:table", "table", SimStream::new(table)),
            TableOptions::new(query()).with_poll_interval(Duration::from_millis(1)),
        ),
    )
}

/// How one session went.
#[derive(Debug)]
struct Session {
    outcome: Outcome,
    /// Whether the manifest recorded the outcome.
    finished: Result<(), RunError>,
    /// Readings on disk as last reported by the progress display.
    reported: usize,
    warnings: Vec<String>,
}

/// One session as `polycal run` has it, in process, with the files written through
/// `budget`: open, the session record in the traffic log, measure, finish; a complete run
/// is only finished.
fn session(dir: &Path, resume: bool, budget: &WriteBudget) -> Result<Session, RunError> {
    let mut run = RunDir::open_with_budget(dir, &settings(), &ports(), resume, budget)?;
    let warnings = run.warnings().to_vec();
    let mut reported = run.readings_done();
    let outcome = if run.remaining().is_empty() {
        Outcome::Completed
    } else {
        let log = run.traffic_log()?;
        log.record("", "", "session", if resume { "resume" } else { "run" });
        let (mut ac1, mut ac2, mut table) = logged_drivers(&log);
        run::measure(
            &mut run,
            Instruments::new(vec![&mut ac1, &mut ac2], &mut table),
            &StopFlag::new(),
            Some(&log),
            &mut |p| reported = p.done,
        )?
    };
    let finished = run.finish(&outcome);
    Ok(Session {
        outcome,
        finished,
        reported,
        warnings,
    })
}

/// The text of a file-error outcome.
fn file_error(outcome: &Outcome) -> &str {
    match outcome {
        Outcome::FileError(message) => message,
        other => panic!("expected a file error, got {other:?}"),
    }
}

/// The run directory is consistent: the measurement file ends on a whole line, reads
/// back with the crate's reader and holds the run's first readings in order, each the
/// truth's value at the stop the table reported; every traffic record is a whole line
/// of JSON; the manifest is JSON and nothing is left beside it. Returns the readings.
fn assert_consistent(dir: &Path) -> Vec<Reading> {
    let bytes = std::fs::read(dir.join(run::MEASUREMENTS)).unwrap();
    assert_eq!(
        bytes.last(),
        Some(&b'\n'),
        "the measurement file ends on a whole line"
    );
    let readings = read_rows(bytes.as_slice(), "measurements.csv").unwrap();
    let plan: Vec<(u32, usize, u32)> = settings()
        .plan()
        .into_iter()
        .flat_map(|s| [(s.cycle, s.step, 1), (s.cycle, s.step, 2)])
        .collect();
    let found: Vec<(u32, usize, u32)> = readings.iter().map(|r| (r.cycle, r.step, r.ac)).collect();
    assert_eq!(
        found,
        plan[..found.len()],
        "the run's first readings, in order"
    );
    for r in &readings {
        let want = expected(truth(), r.step, r.ac);
        assert!(
            (r.reading_arcsec - want).abs() < 1e-6,
            "{r:?}: the truth says {want}"
        );
        assert_eq!(r.encoder_degrees, Some(r.step as f64 * 45.0));
        assert!(r.time_seconds.is_some());
    }
    for line in traffic(dir) {
        for key in ["t", "device", "port", "event", "text"] {
            assert!(line.get(key).is_some(), "{key} in {line}");
        }
    }
    let text = std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap();
    serde_json::from_str::<Value>(&text).expect("the manifest is JSON");
    assert!(
        !dir.join("manifest.json.tmp").exists(),
        "nothing left beside the manifest"
    );
    readings
}

/// Every record of the traffic log (the log ends on a whole line, each line is JSON).
fn traffic(dir: &Path) -> Vec<Value> {
    let text = std::fs::read_to_string(dir.join(run::TRAFFIC)).unwrap_or_default();
    assert!(
        text.is_empty() || text.ends_with('\n'),
        "the log ends on a whole line"
    );
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l:?}")))
        .collect()
}

fn manifest(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap()).unwrap()
}

/// The commands sent to the table.
fn table_commands(dir: &Path) -> Vec<String> {
    traffic(dir)
        .iter()
        .filter(|r| r["event"] == "sent" && r["device"] == "table")
        .map(|r| r["text"].as_str().unwrap().to_string())
        .collect()
}

/// With space again, the run resumes and completes with exactly the run's readings;
/// the manifest records the two sessions. `before`: readings on disk before.
fn resume_completes(dir: &Path, before: usize) {
    let s = session(dir, true, &WriteBudget::unlimited()).unwrap();
    assert_eq!(s.outcome, Outcome::Completed);
    s.finished.unwrap();
    assert_eq!(
        assert_consistent(dir).len(),
        READINGS,
        "none lost or repeated"
    );
    let m = manifest(dir);
    assert_eq!(
        (m["outcome"].as_str(), m["readings"].as_u64()),
        (Some("completed"), Some(36))
    );
    let last = m["sessions"].as_array().unwrap().last().unwrap().clone();
    assert_eq!(last["readings_before"], before);
    assert_eq!(last["readings_after"], READINGS);
}

/// The bytes each file takes in a whole run without a limit: the measurement file and
/// the manifest when the run has started, and the manifest's writes: when the session
/// starts, after each cycle's check (the cycles checked), when it ends.
struct Sizes {
    header: u64,
    manifest_start: u64,
    manifest_session: u64,
    manifest_checks: u64,
    manifest_end: u64,
}

fn sizes() -> &'static Sizes {
    static SIZES: OnceLock<Sizes> = OnceLock::new();
    SIZES.get_or_init(measure_sizes)
}

fn measure_sizes() -> Sizes {
    let dir = temp_dir("disk-sizes");
    let large = 1 << 40;
    let measurements = WriteBudget::for_file(run::MEASUREMENTS, large);
    let manifest = WriteBudget::for_file(run::MANIFEST, large);
    let used = |b: &WriteBudget, name| large - b.left_bytes(name).unwrap();
    let mut run =
        RunDir::open_with_budget(&dir, &settings(), &ports(), false, &measurements).unwrap();
    let header = used(&measurements, run::MEASUREMENTS);
    drop(run);
    std::fs::remove_dir_all(&dir).unwrap();
    run = RunDir::open_with_budget(&dir, &settings(), &ports(), false, &manifest).unwrap();
    let manifest_start = used(&manifest, run::MANIFEST);
    let (mut ac1, mut ac2, mut table, _) = drivers(noiseless(), &StopFlag::new());
    // The session's first write is done when the first reading is reported.
    let mut at_first_reading = None;
    let outcome = run::measure(
        &mut run,
        Instruments::new(vec![&mut ac1, &mut ac2], &mut table),
        &StopFlag::new(),
        None,
        &mut |_| {
            at_first_reading.get_or_insert_with(|| used(&manifest, run::MANIFEST));
        },
    )
    .unwrap();
    let manifest_session = at_first_reading.unwrap() - manifest_start;
    let manifest_checks = used(&manifest, run::MANIFEST) - manifest_start - manifest_session;
    run.finish(&outcome).unwrap();
    let manifest_end =
        used(&manifest, run::MANIFEST) - manifest_start - manifest_session - manifest_checks;
    assert_eq!(
        std::fs::metadata(dir.join(run::MANIFEST)).unwrap().len(),
        manifest_end
    );
    std::fs::remove_dir_all(&dir).unwrap();
    Sizes {
        header,
        manifest_start,
        manifest_session,
        manifest_checks,
        manifest_end,
    }
}

#[test]
fn a_start_that_fails_for_lack_of_space_leaves_nothing_and_starts_again() {
    let z = sizes();
    let k_values = [
        (0, run::MEASUREMENTS),
        (z.header / 2, run::MEASUREMENTS),
        (z.header, run::MANIFEST),
        (z.header + z.manifest_start / 2, run::MANIFEST),
    ];
    for (k, failing) in k_values {
        for existing in [false, true] {
            let dir = temp_dir(&format!("disk-start-{k}-{existing}"));
            if existing {
                std::fs::create_dir_all(&dir).unwrap();
            }
            let e = RunDir::open_with_budget(
                &dir,
                &settings(),
                &ports(),
                false,
                &WriteBudget::shared(k),
            )
            .unwrap_err();
            let message = e.to_string();
            assert!(
                matches!(e, RunError::NotStarted { .. }) && !e.is_refusal(),
                "{e:?}"
            );
            assert!(
                message.contains(failing)
                    && message.contains("No space left on device")
                    && message.ends_with(
                        "the run could not start (nothing was measured); its files were removed"
                    ),
                "K = {k}: {message}"
            );
            // Nothing of the run is left: the directory it made is gone, one that was
            // there is empty again.
            if existing {
                assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "K = {k}");
            } else {
                assert!(!dir.exists(), "K = {k}");
            }
            // A fresh run with space starts there and completes.
            let s = session(&dir, false, &WriteBudget::unlimited()).unwrap();
            assert_eq!(s.outcome, Outcome::Completed);
            assert_eq!(assert_consistent(&dir).len(), READINGS);
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }
}

#[test]
fn the_measurement_file_filling_up_stops_the_run_at_that_reading() {
    let z = sizes();
    let dir = temp_dir("disk-measurements");
    let budget = z.header + 500; // some rows
    let s = session(
        &dir,
        false,
        &WriteBudget::for_file(run::MEASUREMENTS, budget),
    )
    .unwrap();
    let message = file_error(&s.outcome).to_string();
    assert!(
        message.contains("measurements.csv: No space left on device"),
        "{message}"
    );
    s.finished.unwrap();

    let kept = assert_consistent(&dir);
    let n = kept.len();
    assert!(n > 0 && n < READINGS, "{n} readings");
    assert_eq!(s.reported, n, "every reading reported on disk is there");
    // The reading not written is named: the run's next one, which did not fit.
    let row = message
        .split("(the reading not written: ")
        .nth(1)
        .unwrap()
        .trim_end_matches(')');
    let next = read_rows(
        format!("cycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift\n{row}\n")
            .as_bytes(),
        "row",
    )
    .unwrap();
    assert_eq!(
        (next[0].cycle, next[0].step, next[0].ac),
        (1, n / 2, n as u32 % 2 + 1)
    );
    let size = std::fs::metadata(dir.join(run::MEASUREMENTS))
        .unwrap()
        .len();
    assert!(
        size <= budget && size + row.len() as u64 + 1 > budget,
        "{size} of {budget}"
    );

    let m = manifest(&dir);
    assert_eq!(m["outcome"], format!("file-error: {message}"));
    assert_eq!(
        (
            m["readings"].as_u64(),
            m["sessions"][0]["readings_after"].as_u64()
        ),
        (Some(n as u64), Some(n as u64))
    );
    assert_eq!(
        table_commands(&dir).last().map(String::as_str),
        Some("1ST\r\n"),
        "the table stopped"
    );
    resume_completes(&dir, n);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_traffic_log_filling_up_stops_the_run_at_once() {
    // While the session record is written, while the instruments are identified, in
    // the middle of the run.
    for k in [0u64, 150, 6000] {
        let dir = temp_dir(&format!("disk-traffic-{k}"));
        let s = session(&dir, false, &WriteBudget::for_file(run::TRAFFIC, k)).unwrap();
        let message = file_error(&s.outcome).to_string();
        assert!(
            message.contains("traffic.jsonl: No space left on device"),
            "K = {k}: {message}"
        );
        s.finished.unwrap();

        let kept = assert_consistent(&dir);
        let n = kept.len();
        assert_eq!(s.reported, n, "every reading reported on disk is there");
        assert!(std::fs::metadata(dir.join(run::TRAFFIC)).unwrap().len() <= k);
        // Every reading on disk has its two replies (two readings that agree) in the
        // log, and no reading was taken on after the log failed (the log may hold the
        // first reply of the reading it failed at).
        let replies = traffic(&dir)
            .iter()
            .filter(|r| r["event"] == "received" && r["text"].as_str().unwrap().starts_with("4 "))
            .count();
        assert!(
            (2 * n..=2 * n + 1).contains(&replies),
            "K = {k}: {replies} replies for {n} readings"
        );
        if k == 6000 {
            assert!(n > 0 && n < READINGS, "{n}");
        } else {
            assert_eq!(n, 0, "K = {k}: stopped before the first move");
        }
        let m = manifest(&dir);
        assert_eq!(m["outcome"], format!("file-error: {message}"));
        assert_eq!(m["readings"], n);

        if k == 6000 {
            // A record cut short (a process killed within it) is removed on resuming.
            let mut log = std::fs::OpenOptions::new()
                .append(true)
                .open(dir.join(run::TRAFFIC))
                .unwrap();
            std::io::Write::write_all(&mut log, b"{\"t\":1.5,\"device\":\"ta").unwrap();
            let s = session(&dir, true, &WriteBudget::unlimited()).unwrap();
            assert_eq!(s.outcome, Outcome::Completed);
            assert_eq!(s.warnings.len(), 1, "{:?}", s.warnings);
            assert!(
                s.warnings[0].contains("traffic.jsonl: removed the last line"),
                "{:?}",
                s.warnings
            );
            assert_eq!(assert_consistent(&dir).len(), READINGS);
            let sessions = traffic(&dir)
                .iter()
                .filter(|r| r["event"] == "session")
                .count();
            assert_eq!(sessions, 2);
        } else {
            resume_completes(&dir, n);
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn the_manifest_not_written_stops_the_run_and_resume_records_it() {
    let z = sizes();
    // When the session starts: nothing is measured, the table is stopped.
    let dir = temp_dir("disk-manifest-session");
    let budget = WriteBudget::for_file(run::MANIFEST, z.manifest_start + z.manifest_session / 2);
    let s = session(&dir, false, &budget).unwrap();
    assert!(
        file_error(&s.outcome).contains("manifest.json: No space left on device"),
        "{s:?}"
    );
    let e = s.finished.unwrap_err();
    assert!(
        matches!(&e, RunError::Io { path, .. } if path.ends_with(run::MANIFEST)),
        "{e:?}"
    );
    assert!(assert_consistent(&dir).is_empty());
    let m = manifest(&dir);
    assert_eq!(m["outcome"], "running", "the manifest of the start is kept");
    assert_eq!(m["sessions"].as_array().map(Vec::len), Some(0));
    assert_eq!(
        table_commands(&dir).last().map(String::as_str),
        Some("1ST\r\n")
    );
    resume_completes(&dir, 0);
    std::fs::remove_dir_all(&dir).unwrap();

    // When the session ends: every reading is on disk, the manifest says the session
    // runs; resuming records that the run is complete.
    let dir = temp_dir("disk-manifest-end");
    let k = z.manifest_start + z.manifest_session + z.manifest_checks + z.manifest_end / 2;
    let s = session(&dir, false, &WriteBudget::for_file(run::MANIFEST, k)).unwrap();
    assert_eq!(s.outcome, Outcome::Completed);
    assert!(s.finished.is_err());
    assert_eq!(assert_consistent(&dir).len(), READINGS);
    assert_eq!(manifest(&dir)["outcome"], "running");
    resume_completes(&dir, READINGS);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_full_disk_shared_by_every_file_stops_the_run_consistently() {
    let z = sizes();
    let start = z.header + z.manifest_start;
    for extra in [200u64, 3000, 9000] {
        let dir = temp_dir(&format!("disk-shared-{extra}"));
        let s = session(&dir, false, &WriteBudget::shared(start + extra)).unwrap();
        let message = file_error(&s.outcome).to_string();
        assert!(message.contains("No space left on device"), "{message}");
        let n = assert_consistent(&dir).len();
        assert_eq!(s.reported, n);
        let m = manifest(&dir);
        // The manifest records why when it can be written, else it still says running.
        match &s.finished {
            Ok(()) => assert_eq!(m["outcome"], format!("file-error: {message}")),
            Err(_) => assert_eq!(m["outcome"], "running"),
        }
        resume_completes(&dir, n);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn a_run_directory_that_is_a_file_is_refused() {
    let dir = temp_dir("disk-a-file");
    std::fs::create_dir_all(&dir).unwrap();
    let file: PathBuf = dir.join("results.csv");
    std::fs::write(&file, "kept\n").unwrap();
    for resume in [false, true] {
        let e = RunDir::open(&file, &settings(), &ports(), resume).unwrap_err();
        assert!(e.is_refusal());
        assert_eq!(
            e.to_string(),
            format!("{}: is a file, not a directory", file.display())
        );
    }
    assert_eq!(std::fs::read_to_string(&file).unwrap(), "kept\n");
    std::fs::remove_dir_all(&dir).unwrap();
}
