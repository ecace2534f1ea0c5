//! A resumed run reads its last stop again before it stores anything (docs/FORMAT.md
//! §7.3, *Before the first reading of a session*), in process against the simulated lab:
//! autocollimators that identify alike, their ports swapped on resuming, are refused at
//! that stop; a value an autocollimator gave before the interruption, given again, is
//! refused as stale; and a clean resume completes with every reading where the lab's
//! truth puts it.

use crate::lab_support::*;
use polycal::lab::run::{self, Instruments, Outcome, RunDir, RunSettings};
use polycal::lab::sim::Devices;
use polycal::lab::{AcReading, Autocollimator, InstrumentError, StopFlag};
use polycal::measurement::{MeasurementSet, read_rows};
use polycal::simulate::Truth;

/// The lab's noise σ, arcsec; the run is told the same (agreement tolerance 0.141″).
const SIGMA: f64 = 0.02;

fn settings() -> RunSettings {
    RunSettings::new(8, 2)
        .with_closing(true)
        .with_reading_noise_arcsec(SIGMA)
}

/// An autocollimator that identifies as every other one does (one make, no serial
/// number in its reply), and gives `replay` before its own readings (a stale reply).
struct Alike<'a> {
    inner: &'a mut Ac,
    replay: Vec<AcReading>,
}

impl<'a> Alike<'a> {
    fn new(inner: &'a mut Ac) -> Alike<'a> {
        Alike {
            inner,
            replay: Vec::new(),
        }
    }
}

impl Autocollimator for Alike<'_> {
    fn port(&self) -> &str {
        self.inner.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.inner.start()
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        self.inner.identify()?;
        Ok("8 ELCOMAT 3000".into())
    }

    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        if !self.replay.is_empty() {
            return Ok(self.replay.remove(0));
        }
        self.inner.measure()
    }
}

/// One session with these autocollimators and the traffic log, stopped (as by Ctrl-C)
/// once `stop_after` readings of it are on disk.
fn session(
    dir: &std::path::Path,
    resume: bool,
    (ac1, ac2): (&mut dyn Autocollimator, &mut dyn Autocollimator),
    table: &mut Table,
    stop: &StopFlag,
    stop_after: Option<usize>,
) -> Outcome {
    let mut run = RunDir::open(dir, &settings(), &ports(), resume).unwrap();
    let log = run.traffic_log().unwrap();
    let mut taken = 0;
    let outcome = run::measure(
        &mut run,
        Instruments::new(vec![ac1, ac2], table),
        stop,
        Some(&log),
        &mut |p| {
            if p.cycle_check.is_none() {
                taken += 1;
                if Some(taken) == stop_after {
                    stop.request();
                }
            }
        },
    )
    .unwrap();
    run.finish(&outcome).unwrap();
    stop.shared()
        .store(false, std::sync::atomic::Ordering::SeqCst);
    outcome
}

/// A lab (8 faces, two cycles with the closing step), its drivers and their stop flag.
fn lab_drivers() -> ((Ac, Ac, Table, Truth), StopFlag) {
    let stop = StopFlag::new();
    let d = drivers(Devices::new(lab(8, SIGMA, Vec::new())).unwrap(), &stop);
    (d, stop)
}

fn stored(dir: &std::path::Path) -> Vec<polycal::measurement::Reading> {
    let text = std::fs::read_to_string(dir.join(run::MEASUREMENTS)).unwrap();
    read_rows(text.as_bytes(), "m").unwrap()
}

/// Every reading of the run, each within 6σ of its stored mean (σ/√2, two readings) of
/// what the lab's truth gives at its own stop and autocollimator.
fn assert_every_reading_at_its_place(dir: &std::path::Path, truth: &Truth) {
    let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
    assert_eq!(set.readings.len(), settings().reading_count());
    let sigma = SIGMA / 2f64.sqrt();
    for r in &set.readings {
        let expected = expected_at(truth, r.step, r.ac, r.encoder_degrees.unwrap());
        assert!(
            (r.reading_arcsec - expected).abs() < 6.0 * sigma,
            "{r:?}: the truth is {expected}"
        );
    }
}

/// The traffic log's records of `event`, their texts.
fn traffic(dir: &std::path::Path, event: &str) -> Vec<String> {
    std::fs::read_to_string(dir.join(run::TRAFFIC))
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|v| v["event"] == event)
        .map(|v| v["text"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn swapped_ports_on_resuming_are_refused_at_the_last_stop() {
    let dir = temp_dir("resume-swapped");
    let ((mut a, mut b, mut table, truth), stop) = lab_drivers();
    // Five stops measured (cycle 1, steps 0 … 4), then stopped.
    let outcome = session(
        &dir,
        false,
        (&mut Alike::new(&mut a), &mut Alike::new(&mut b)),
        &mut table,
        &stop,
        Some(10),
    );
    assert_eq!(outcome, Outcome::Interrupted);
    let before = stored(&dir);
    assert_eq!(before.len(), 10);

    // Resumed with the two autocollimators' ports swapped: they identify alike, so only
    // their readings at step 4 tell.
    let outcome = session(
        &dir,
        true,
        (&mut Alike::new(&mut b), &mut Alike::new(&mut a)),
        &mut table,
        &stop,
        None,
    );
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    assert!(
        message.starts_with("ac1 (mem:ac2) reads "),
        "names the autocollimator and its port: {message}"
    );
    assert!(
        message.contains("at cycle 1, step 4 where the run stored "),
        "{message}"
    );
    assert!(
        message.contains(
            "ac1 reads what ac2 stored, ac2 reads what ac1 stored: the autocollimators' ports look swapped"
        ),
        "{message}"
    );
    // The figures are the truth's: what each stored at step 4 against the other's
    // truth there.
    let stored_ac1 = before[8].reading_arcsec;
    assert!(
        message.contains(&format!("where the run stored {stored_ac1:.3}″")),
        "{message}"
    );
    let ac2_truth = expected_at(&truth, 4, 2, before[9].encoder_degrees.unwrap());
    assert!(
        (stored_ac1 - ac2_truth).abs() > 0.5,
        "the two faces read apart ({stored_ac1} vs {ac2_truth}): the test can tell"
    );
    assert_eq!(stored(&dir), before, "nothing new stored");
    let compared = traffic(&dir, "compared");
    assert_eq!(compared.len(), 1, "{compared:?}");
    assert!(
        compared[0].starts_with("cycle 1, step 4, read again on resuming: ac1 ")
            && compared[0].ends_with(": do not agree"),
        "{compared:?}"
    );

    // Connected as before: the last stop agrees, the run completes where the truth puts
    // every reading.
    let outcome = session(
        &dir,
        true,
        (&mut Alike::new(&mut a), &mut Alike::new(&mut b)),
        &mut table,
        &stop,
        None,
    );
    assert_eq!(outcome, Outcome::Completed);
    assert_every_reading_at_its_place(&dir, &truth);
    let compared = traffic(&dir, "compared");
    assert!(compared[1].ends_with(": agree"), "{compared:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_value_from_before_the_interruption_given_again_is_refused_as_stale() {
    let dir = temp_dir("resume-stale");
    let ((mut a, mut b, mut table, truth), stop) = lab_drivers();
    // Eleven readings: autocollimator 1 read at step 5, autocollimator 2 not yet (its
    // last reading is step 4's).
    let outcome = session(
        &dir,
        false,
        (&mut Alike::new(&mut a), &mut Alike::new(&mut b)),
        &mut table,
        &stop,
        Some(11),
    );
    assert_eq!(outcome, Outcome::Interrupted);
    let before = stored(&dir);
    assert_eq!(before.len(), 11);
    let last = &before[9];
    assert_eq!((last.step, last.ac), (4, 2));
    // Autocollimator 2 gives its last value before the interruption twice more at step 5
    // (a device that repeats its last reply).
    let stale = AcReading::new(3, last.reading_arcsec, last.reading_y_arcsec);
    let mut ac2 = Alike::new(&mut b);
    ac2.replay = vec![stale, stale];
    let outcome = session(
        &dir,
        true,
        (&mut Alike::new(&mut a), &mut ac2),
        &mut table,
        &stop,
        None,
    );
    assert_eq!(outcome, Outcome::Completed);
    let refused = traffic(&dir, "refused");
    let stale_text = format!("X {}", last.reading_arcsec);
    let as_stale: Vec<&String> = refused
        .iter()
        .filter(|t| t.contains("stale: the same value as its last one before this session"))
        .collect();
    assert_eq!(as_stale.len(), 2, "{refused:?}");
    assert!(
        as_stale.iter().all(|t| t.contains(&stale_text)),
        "{refused:?}"
    );
    let after = stored(&dir);
    assert_eq!(
        after[..11],
        before[..],
        "the readings before kept as they were"
    );
    assert!(
        after[11..]
            .iter()
            .all(|r| r.reading_arcsec != last.reading_arcsec),
        "the stale value stored nowhere"
    );
    assert_every_reading_at_its_place(&dir, &truth);
    let _ = std::fs::remove_dir_all(&dir);
}
