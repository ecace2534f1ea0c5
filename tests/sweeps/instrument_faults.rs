//! Injected faults end in a correct retry (queries) or a clean stop with the data kept
//! (everything else); a motion is never re-sent (checked in the traffic log). Every test
//! runs `polycal run` against its own `polycal sim-lab` over pseudo-terminals.

#![cfg(unix)]

use crate::instrument_support::*;
use polycal::lab::run::RunSettings;
use serde_json::Value;

const DESIGN: [&str; 9] = [
    "--faces",
    "8",
    "--cycles",
    "2",
    "--closing",
    "--settle",
    "0",
    "--timeout",
    "0.3",
];

fn settings() -> RunSettings {
    RunSettings::new(8, 2).with_closing(true)
}

/// Runs against a lab with `fault`; returns the run directory, the lab and the output.
fn run_with_fault(name: &str, fault: &str) -> (std::path::PathBuf, SimLab, std::process::Output) {
    let dir = scratch(name);
    let lab = SimLab::start(&dir, &["--fault", fault]);
    let out = dir.join("run");
    let mut args = lab.run_args(&out, &DESIGN);
    args.push("-q".into());
    let result = polycal(&args);
    (out, lab, result)
}

/// The events of one device in a session.
fn of<'a>(session: &'a [Value], device: &str) -> Vec<&'a Value> {
    session.iter().filter(|r| r["device"] == device).collect()
}

/// The commands that bring a device back in step (docs/FORMAT.md §7.3).
const RESYNC: [&str; 2] = ["d\n", "1VE\r\n"];

/// Asserts that the first event of `device` matching `bad` is followed by the same query
/// again — after a timeout, once the device was brought back in step with its
/// identification command — and by nothing else.
fn assert_retried(session: &[Value], device: &str, bad: impl Fn(&Value) -> bool) {
    let events = of(session, device);
    let i = events
        .iter()
        .position(|r| bad(r))
        .unwrap_or_else(|| panic!("no faulty reply of {device} in the traffic log"));
    let query = events[..i]
        .iter()
        .rev()
        .find(|r| r["event"] == "sent")
        .map(|r| r["text"].clone())
        .unwrap();
    let resent = events[i + 1..]
        .iter()
        .position(|r| r["event"] == "sent" && !RESYNC.contains(&r["text"].as_str().unwrap()))
        .unwrap()
        + i
        + 1;
    for r in &events[i + 1..resent] {
        let resync = r["event"] == "sent" && RESYNC.contains(&r["text"].as_str().unwrap());
        let its_reply = r["event"] == "received"
            && ["8 ", "1VE"]
                .iter()
                .any(|p| r["text"].as_str().unwrap().starts_with(p));
        assert!(resync || its_reply || r["event"] == "discarded", "{r:?}");
    }
    if events[i]["event"] == "timeout" {
        assert!(
            resent > i + 1,
            "a timeout is followed by a resynchronisation"
        );
    }
    assert_eq!(events[resent]["text"], query, "the same query again");
    assert!(!query.as_str().unwrap().starts_with("1PA"), "never a move");
}

fn assert_completed_with_retry(
    name: &str,
    fault: &str,
    device: &str,
    bad: impl Fn(&Value) -> bool,
) {
    let (out, lab, result) = run_with_fault(name, fault);
    assert!(result.status.success(), "{fault}: {}", stderr(&result));
    assert_complete(&out, &settings());
    assert_solves_to_truth(&out, &lab.truth);
    let sessions = sessions(&out);
    assert_moves_follow_plan(&sessions[0], &settings(), 0);
    assert_eq!(moves(&sessions[0]).len(), 18, "{fault}: one move per stop");
    assert_retried(&sessions[0], device, bad);
    assert_eq!(manifest(&out)["outcome"], "completed");
}

#[test]
fn a_lost_autocollimator_reply_is_asked_again() {
    assert_completed_with_retry("lost-ac1", "lost-reply:ac1:after=10", "ac1", |r| {
        r["event"] == "timeout"
    });
}

#[test]
fn a_lost_table_reply_is_asked_again_not_the_move() {
    assert_completed_with_retry("lost-table", "lost-reply:table:after=4", "table", |r| {
        r["event"] == "timeout"
    });
}

#[test]
fn a_garbled_autocollimator_reply_is_asked_again() {
    assert_completed_with_retry("garbled-ac2", "garbled:ac2:after=6", "ac2", |r| {
        r["event"] == "received" && r["text"].as_str().unwrap().contains('?')
    });
}

#[test]
fn a_garbled_table_reply_is_asked_again() {
    assert_completed_with_retry("garbled-table", "garbled:table:after=2", "table", |r| {
        r["event"] == "received" && r["text"].as_str().unwrap().contains('?')
    });
}

#[test]
fn an_x_invalid_reading_is_taken_again() {
    assert_completed_with_retry("xinv-ac1", "x-invalid:ac1:after=14", "ac1", |r| {
        r["event"] == "received" && r["text"].as_str().unwrap().starts_with("4 002 ")
    });
}

/// The checks of a clean stop: status 2 and one `error:` line, the readings so far kept
/// in order, the manifest saying why, the table sent a stop, no move sent twice.
fn assert_clean_stop(
    out: &std::path::Path,
    result: &std::process::Output,
    says: &str,
    kept: usize,
) {
    let text = assert_error(result, says);
    assert!(text.contains("--resume"), "{text}");
    let rows = rows(out);
    assert_eq!(rows.len(), kept, "{text}");
    assert_eq!(rows, plan_readings(&settings())[..kept]);
    let m = manifest(out);
    let outcome = m["outcome"].as_str().unwrap();
    assert!(outcome.starts_with("instrument-error: "), "{outcome}");
    assert!(outcome.contains(says), "{outcome}");
    assert_eq!(m["readings"], kept);
    assert!(m["ended"].is_string());
    let sessions = sessions(out);
    assert_moves_follow_plan(&sessions[0], &settings(), 0);
    let last_sent = sessions[0]
        .iter()
        .rev()
        .find(|r| r["event"] == "sent" && r["device"] == "table")
        .unwrap();
    assert_eq!(last_sent["text"], "1ST\r\n", "the table is stopped");
}

#[test]
fn a_table_stuck_in_disable_stops_the_run_cleanly() {
    // Six moves — the pre-position before step 0 (approached clockwise) and five stops —
    // then the move to the sixth stop stops midway in DISABLE from MOVING.
    let (out, _lab, result) = run_with_fault("disable", "disable:table:after=6");
    // Five stops measured.
    assert_clean_stop(&out, &result, "3D", 10);
    let m = moves(&sessions(&out)[0]);
    assert_eq!(m.len(), 6, "the failed move was sent once: {m:?}");
}

#[test]
fn a_port_closing_mid_run_stops_it_cleanly() {
    let (out, _lab, result) = run_with_fault("close", "close:ac2:after=14");
    // The closed port is seen either when the next command is flushed (the serial
    // driver's "flush failed") or when its reply is awaited ("the port was closed"),
    // depending on which comes first under load; both are the same clean stop.
    let says = if stderr(&result).contains("flush failed") {
        "flush failed"
    } else {
        "closed"
    };
    assert_clean_stop(&out, &result, says, 15);
}

#[test]
fn persistent_x_invalid_stops_the_run_cleanly() {
    let (out, _lab, result) = run_with_fault("xinv-stop", "x-invalid:ac2:after=4:count=4");
    assert_clean_stop(&out, &result, "X axis not valid", 5);
}

#[test]
fn a_silent_autocollimator_stops_the_run_and_resume_completes_it() {
    let (out, lab, result) = run_with_fault("silent", "lost-reply:ac1:after=6:count=4");
    assert_clean_stop(&out, &result, "no reply to \"a\\n\"", 6);
    // The fault is spent: resuming carries on from the first missing reading.
    let mut args = lab.run_args(&out, &DESIGN);
    args.extend(["--resume".to_string(), "-q".into()]);
    let resumed = polycal(&args);
    assert!(resumed.status.success(), "{}", stderr(&resumed));
    assert_complete(&out, &settings());
    assert_solves_to_truth(&out, &lab.truth);
    let sessions = sessions(&out);
    assert_eq!(sessions.len(), 2);
    // The last stop measured (step 2) read again first, then the stops from step 3 on.
    assert_resumed_moves_follow_plan(&sessions[1], &settings(), 6);
    let m = manifest(&out);
    assert_eq!(m["outcome"], "completed");
    assert_eq!(m["sessions"][0]["readings_after"], 6);
    assert!(
        m["sessions"][0]["outcome"]
            .as_str()
            .unwrap()
            .starts_with("instrument-error: ")
    );
}

#[test]
fn replies_padded_with_nul_bytes_give_the_right_readings() {
    // Every reply of every device padded with NUL bytes, before it and after its
    // terminator: the run completes, one move per stop, and solves to the lab's truth.
    let dir = scratch("nul-padding");
    let lab = SimLab::start(
        &dir,
        &[
            "--fault",
            "nul-padding:ac1",
            "--fault",
            "nul-padding:ac2",
            "--fault",
            "nul-padding:table",
        ],
    );
    let out = dir.join("run");
    let mut args = lab.run_args(&out, &DESIGN);
    args.push("-q".into());
    let result = polycal(&args);
    assert!(result.status.success(), "{}", stderr(&result));
    assert_complete(&out, &settings());
    assert_solves_to_truth(&out, &lab.truth);
    let sessions = sessions(&out);
    assert_moves_follow_plan(&sessions[0], &settings(), 0);
    assert_eq!(moves(&sessions[0]).len(), 18, "one move per stop");
    assert_eq!(manifest(&out)["outcome"], "completed");
    // No reply was refused, timed out or discarded: the padding is invisible.
    for r in &sessions[0] {
        assert!(
            !["timeout", "discarded", "refused", "error"].contains(&r["event"].as_str().unwrap()),
            "{r:?}"
        );
        assert!(!r["text"].as_str().unwrap().contains('\0'), "{r:?}");
    }
}

/// The longest gap between two consecutive table records of a session, seconds.
fn longest_table_gap(session: &[Value]) -> f64 {
    let t: Vec<f64> = of(session, "table")
        .iter()
        .map(|r| r["t"].as_f64().unwrap())
        .collect();
    t.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max)
}

#[test]
fn a_table_holding_xoff_for_two_seconds_pauses_the_run() {
    // After its third move the table holds the host's output with XOFF for 2 s (the
    // SMC100's line has XON/XOFF): the next command waits for XON, and the run goes on.
    let (out, lab, result) = run_with_fault("xoff-2s", "xoff:table:after=3:seconds=2");
    assert!(result.status.success(), "{}", stderr(&result));
    assert_complete(&out, &settings());
    assert_solves_to_truth(&out, &lab.truth);
    let sessions = sessions(&out);
    assert_moves_follow_plan(&sessions[0], &settings(), 0);
    assert_eq!(moves(&sessions[0]).len(), 18, "one move per stop");
    assert_eq!(manifest(&out)["outcome"], "completed");
    // The pause happened (the lab's 2 s, less the run's own time to its next command).
    let gap = longest_table_gap(&sessions[0]);
    assert!((1.5..5.0).contains(&gap), "longest gap {gap} s");
    assert!(
        !sessions[0]
            .iter()
            .any(|r| r["event"] == "timeout" || r["event"] == "error"),
        "nothing timed out"
    );
}

#[test]
fn a_table_holding_xoff_past_the_limit_stops_the_run_naming_its_port() {
    // 12 s of XOFF is more than the 10 s a write waits: one error naming the table's port.
    let (out, lab, result) = run_with_fault("xoff-12s", "xoff:table:after=3:seconds=12");
    let text = assert_error(&result, &lab.table);
    assert!(text.contains("within 10 s"), "{text}");
    assert!(text.contains("XOFF"), "{text}");
    let m = manifest(&out);
    assert!(
        m["outcome"]
            .as_str()
            .unwrap()
            .starts_with("instrument-error: "),
        "{m:#}"
    );
}
