//! No reading on the wrong stop (docs/FORMAT.md §7.3): every reply fault of the simulated
//! lab (late, duplicated, unsolicited, swapped, stale) on every device, at its first, a
//! middle and its last query. Each run either completes with every reading within 6σ of
//! the lab's truth *at its own stop* (checked reading by reading), or stops with an
//! instrument error, and resuming completes it so. Never a completed run with a reading
//! from another stop. In process, over in-memory streams.

use std::time::Duration;

use crate::lab_support::*;
use polycal::lab::StopFlag;
use polycal::lab::run::{self, Instruments, Outcome, RunDir, RunSettings};
use polycal::lab::sim::{DeviceId, Devices, Fault, FaultKind, LabConfig};
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, Truth};

/// The lab's noise σ, arcsec; the run is told the same.
const SIGMA: f64 = 0.05;

/// The faults of issue 33's table.
const KINDS: [FaultKind; 5] = [
    FaultKind::Late,
    FaultKind::Duplicated,
    FaultKind::Unsolicited,
    FaultKind::Swapped,
    FaultKind::Stale,
];

fn settings() -> RunSettings {
    RunSettings::new(8, 2)
        .with_closing(true)
        .with_reading_noise_arcsec(SIGMA)
}

/// A lab whose stops are far apart in what the autocollimators read (pitch spread 5″),
/// so that a reading from another stop cannot pass for this one's.
fn config(faults: Vec<Fault>) -> LabConfig {
    LabConfig::new(SimulationConfig {
        faces: 8,
        noise_arcsec: SIGMA,
        pitch_spread_arcsec: 5.0,
        cycles: 2,
        closing: true,
        seed: 7,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0)
    .with_faults(faults)
}

/// One session against `devices`; the outcome.
fn session(dir: &std::path::Path, devices: Devices, resume: bool) -> Outcome {
    let mut run = RunDir::open(dir, &settings(), &ports(), resume).unwrap();
    let stop = StopFlag::new();
    let (mut ac1, mut ac2, mut table, _) = drivers(devices, &stop);
    let outcome = run::measure(
        &mut run,
        Instruments::new(vec![&mut ac1, &mut ac2], &mut table),
        &stop,
        None,
        &mut |_| {},
    )
    .unwrap();
    run.finish(&outcome).unwrap();
    outcome
}

/// Every reading of the run directory at its own stop: within 6σ of the truth there.
fn assert_every_reading_at_its_stop(dir: &std::path::Path, truth: &Truth, what: &str) {
    let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
    assert_eq!(set.readings.len(), settings().reading_count(), "{what}");
    for r in &set.readings {
        let encoder = r.encoder_degrees.unwrap();
        let want = expected_at(truth, r.step, r.ac, encoder);
        assert!(
            (r.reading_arcsec - want).abs() <= 6.0 * SIGMA,
            "{what}: cycle {} step {} ac {}: {} but {} at this stop",
            r.cycle,
            r.step,
            r.ac,
            r.reading_arcsec,
            want
        );
    }
}

/// The check above can fail: a reading from the stop before or after would lie beyond
/// 6σ for every reading of this lab.
#[test]
fn the_stops_are_told_apart_by_the_check() {
    let truth = Devices::new(config(vec![])).unwrap().truth();
    for ac in [1, 2] {
        for step in 0..8 {
            let here = expected_at(&truth, step, ac, step as f64 * 45.0);
            for other in [step + 1, (step + 7) % 8] {
                let there = expected_at(&truth, other, ac, other as f64 * 45.0);
                assert!(
                    (here - there).abs() > 12.0 * SIGMA,
                    "ac {ac} steps {step} and {other}: {here} vs {there}"
                );
            }
        }
    }
}

/// The events at which a fault is armed: the first query, a middle one and the last
/// (measurements of an autocollimator: 36 in the run; moves of the table: 18).
fn positions(device: DeviceId) -> [u64; 3] {
    match device {
        DeviceId::Table => [0, 9, 17],
        _ => [0, 17, 35],
    }
}

#[test]
fn every_reply_fault_on_every_device_at_every_place_keeps_readings_at_their_stops() {
    let mut stopped = Vec::new();
    for kind in KINDS {
        for device in [DeviceId::Ac(1), DeviceId::Ac(2), DeviceId::Table] {
            for after in positions(device) {
                let mut fault = Fault::new(kind, device).with_after(after);
                if kind == FaultKind::Late {
                    // Later than the 20 ms deadline of the tests' queries.
                    fault = fault.with_late(Duration::from_millis(60));
                }
                let what = fault.to_string();
                let dir = temp_dir(&format!("wrong-stop-{}", what.replace([':', '='], "-")));
                let devices = Devices::new(config(vec![fault])).unwrap();
                let truth = devices.truth();
                let outcome = session(&dir, devices, false);
                if outcome != Outcome::Completed {
                    let Outcome::InstrumentError(message) = &outcome else {
                        panic!("{what}: {outcome:?}");
                    };
                    stopped.push(format!("{what}: {message}"));
                    // The instruments switched off and on: the same truth, no fault.
                    let again = Devices::with_truth(config(vec![]), truth.clone()).unwrap();
                    assert_eq!(session(&dir, again, true), Outcome::Completed, "{what}");
                }
                assert_every_reading_at_its_stop(&dir, &truth, &what);
                std::fs::remove_dir_all(&dir).unwrap();
            }
        }
    }
    // One fault each, with three retries: every run comes through without a stop.
    assert!(stopped.is_empty(), "{stopped:#?}");
}

#[test]
fn a_reply_arriving_after_its_deadline_is_discarded_not_read_as_the_next_answer() {
    // Five late replies in a row on autocollimator 1, from the middle of the run on,
    // each later than the deadline: none of them is stored, every reading is at its stop.
    let fault = Fault::new(FaultKind::Late, DeviceId::Ac(1))
        .with_after(10)
        .with_count(5)
        .with_late(Duration::from_millis(30));
    let dir = temp_dir("late-five");
    let devices = Devices::new(config(vec![fault])).unwrap();
    let truth = devices.truth();
    let outcome = session(&dir, devices, false);
    if outcome != Outcome::Completed {
        let again = Devices::with_truth(config(vec![]), truth.clone()).unwrap();
        assert_eq!(session(&dir, again, true), Outcome::Completed);
    }
    assert_every_reading_at_its_stop(&dir, &truth, "late x5");
    std::fs::remove_dir_all(&dir).unwrap();
}
