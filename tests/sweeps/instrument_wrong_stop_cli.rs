//! Issue 33's table, tried as a new user would: `polycal run` against `polycal sim-lab`
//! on pseudo-terminals, 8 faces, 2 cycles with the closing step, `--timeout 1`, one reply
//! fault on autocollimator 1 in the middle of the run. Each run completes with every
//! reading within 6σ of the lab's truth at its own stop (reading by reading), and the
//! traffic log shows what was discarded or refused.

#![cfg(unix)]

use crate::instrument_support::*;
use crate::lab_support::expected_at;
use polycal::measurement::MeasurementSet;
use polycal::simulate::Truth;
use serde_json::Value;

const SIGMA: f64 = 0.05;

/// Runs against a lab with `fault` (pitch spread 5″: every stop reads far from the
/// next); returns the run directory, the truth and the output.
fn run_with_fault(name: &str, fault: &str) -> (std::path::PathBuf, Truth, Vec<Value>) {
    let dir = scratch(name);
    let lab = SimLab::start(
        &dir,
        &[
            "--fault",
            fault,
            "--noise",
            "0.05",
            "--pitch-spread",
            "5",
            "--seed",
            "7",
            "--cycles",
            "2",
            "--closing",
        ],
    );
    let out = dir.join("run");
    let args = lab.run_args(
        &out,
        &[
            "--faces",
            "8",
            "--cycles",
            "2",
            "--closing",
            "--settle",
            "0",
            "--timeout",
            "1",
            "--reading-noise",
            "0.05",
            "-q",
        ],
    );
    let result = polycal(&args);
    assert!(result.status.success(), "{fault}: {}", stderr(&result));
    let truth = Truth::read_path(&lab.truth).unwrap();
    let log = sessions(&out).concat();
    (out, truth, log)
}

/// Every reading within 6σ of what the lab's autocollimator reads at its own stop.
fn assert_at_their_stops(out: &std::path::Path, truth: &Truth, fault: &str) {
    let set = MeasurementSet::read_path(&out.join("measurements.csv"), None).unwrap();
    assert_eq!(set.readings.len(), 36);
    for r in &set.readings {
        let want = expected_at(truth, r.step, r.ac, r.encoder_degrees.unwrap());
        assert!(
            (r.reading_arcsec - want).abs() <= 6.0 * SIGMA,
            "{fault}: cycle {} step {} ac {}: {} but {want} at this stop",
            r.cycle,
            r.step,
            r.ac,
            r.reading_arcsec
        );
    }
}

fn events<'a>(log: &'a [Value], event: &str) -> Vec<&'a Value> {
    log.iter()
        .filter(|r| r["event"] == event && r["device"] == "ac1")
        .collect()
}

#[test]
fn a_reply_1_3_s_late_is_discarded_when_it_arrives() {
    let fault = "late:ac1:after=17:seconds=1.3";
    let (out, truth, log) = run_with_fault("late", fault);
    assert_at_their_stops(&out, &truth, fault);
    // The late reply came while the device was brought back in step, and was discarded.
    let discarded = events(&log, "discarded");
    assert_eq!(discarded.len(), 1, "{discarded:?}");
    assert!(discarded[0]["text"].as_str().unwrap().starts_with("4 003 "));
}

#[test]
fn a_reply_sent_twice_is_drained() {
    let fault = "duplicated:ac1:after=17";
    let (out, truth, log) = run_with_fault("duplicated", fault);
    assert_at_their_stops(&out, &truth, fault);
    assert_eq!(events(&log, "discarded").len(), 1);
}

#[test]
fn an_unsolicited_line_is_not_stored() {
    let fault = "unsolicited:ac1:after=17";
    let (out, truth, log) = run_with_fault("unsolicited", fault);
    assert_at_their_stops(&out, &truth, fault);
    // Either it came with the reply (neither taken, asked again) or alone (outvoted).
    assert!(!events(&log, "discarded").is_empty() || !events(&log, "refused").is_empty());
}

#[test]
fn two_swapped_replies_are_not_stored_at_the_wrong_stop() {
    let fault = "swapped:ac1:after=17";
    let (out, truth, _) = run_with_fault("swapped", fault);
    assert_at_their_stops(&out, &truth, fault);
}

#[test]
fn a_stale_reply_is_refused() {
    // The first reading at cycle 2, step 1 (the 21st): the stale reply repeats the last
    // one at step 0, which is refused as such.
    let fault = "stale:ac1:after=20";
    let (out, truth, log) = run_with_fault("stale", fault);
    assert_at_their_stops(&out, &truth, fault);
    let refused = events(&log, "refused");
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(refused[0]["text"].as_str().unwrap().contains("stale"));
}
