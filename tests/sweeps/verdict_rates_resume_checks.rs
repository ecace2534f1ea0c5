//! How often the checks before a session's first reading (docs/FORMAT.md §7.3, *Before
//! the first reading of a session*) refuse, on simulated runs in process: a clean resume
//! and a correct remount are never refused (false alarms), swapped ports on resuming and
//! a forgotten remount nearly always are (power). Each run is a lab of its own seed, 8
//! faces, two cycles with the closing step, the lab's noise σ = 0.02″ stated to the run.

use crate::lab_support::*;
use polycal::lab::StopFlag;
use polycal::lab::run::{
    self, Attendant, Instruments, Mounting, Outcome, Progress, Remount, RunDir, RunSettings,
};
use polycal::lab::sim::{Devices, LabConfig, World};
use polycal::lab::{AcReading, Autocollimator, InstrumentError, WriteBudget};
use polycal::simulate::SimulationConfig;
use std::sync::{Arc, Mutex};

const SIGMA: f64 = 0.02;
/// Simulated runs per case.
const RUNS: u64 = 60;

fn settings() -> RunSettings {
    RunSettings::new(8, 2)
        .with_closing(true)
        .with_reading_noise_arcsec(SIGMA)
}

/// A lab of `seed`: two mountings, both with the table at 0° at step 0, the second
/// turned 3 faces.
fn config(seed: u64) -> LabConfig {
    LabConfig::new(SimulationConfig {
        faces: 8,
        noise_arcsec: SIGMA,
        cycles: 2,
        closing: true,
        setups: 2,
        setup_shift_faces: 3,
        seed,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0)
}

/// An autocollimator that identifies as every other one does.
struct Alike<'a>(&'a mut Ac);

impl Autocollimator for Alike<'_> {
    fn port(&self) -> &str {
        self.0.port()
    }
    fn start(&mut self) -> Result<(), InstrumentError> {
        self.0.start()
    }
    fn identify(&mut self) -> Result<String, InstrumentError> {
        self.0.identify()?;
        Ok("8 ELCOMAT 3000".into())
    }
    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        self.0.measure()
    }
}

/// The person at the table: remounts the polygon when asked, or forgets to.
struct Person {
    world: Arc<Mutex<World>>,
    remounts: bool,
}

impl Attendant for Person {
    fn progress(&mut self, _progress: &Progress) {}

    fn remount(&mut self, _remount: &Remount) -> bool {
        if self.remounts {
            self.world.lock().unwrap().remount().unwrap();
        }
        true
    }
}

/// Resumed after 10 readings (cycle 1, steps 0 … 4), the ports swapped or not: whether
/// the resumed session was refused, and (not refused) whether it completed.
fn resumed(seed: u64, swapped: bool) -> (bool, bool) {
    let dir = temp_dir(&format!("rates-resume-{seed}-{swapped}"));
    let stop = StopFlag::new();
    let devices = Devices::new(config(seed)).unwrap();
    let (mut a, mut b, mut table, _) = drivers(devices, &stop);
    let mut session = |first: &mut Ac, second: &mut Ac, resume: bool, stop_after: Option<usize>| {
        let mut run = RunDir::open(&dir, &settings(), &ports(), resume).unwrap();
        let mut taken = 0;
        let outcome = run::measure(
            &mut run,
            Instruments::new(vec![&mut Alike(first), &mut Alike(second)], &mut table),
            &stop,
            None,
            &mut |p| {
                taken += usize::from(p.cycle_check.is_none());
                if Some(taken) == stop_after {
                    stop.request();
                }
            },
        )
        .unwrap();
        run.finish(&outcome).unwrap();
        stop.shared()
            .store(false, std::sync::atomic::Ordering::SeqCst);
        outcome
    };
    assert_eq!(
        session(&mut a, &mut b, false, Some(10)),
        Outcome::Interrupted
    );
    let outcome = if swapped {
        session(&mut b, &mut a, true, None)
    } else {
        session(&mut a, &mut b, true, None)
    };
    let _ = std::fs::remove_dir_all(&dir);
    (
        matches!(&outcome, Outcome::InstrumentError(m) if m.contains("before the interruption")),
        outcome == Outcome::Completed,
    )
}

/// Mounting 1, then mounting 2 (the lab's: turned 3 faces) stated turned `face_shift`
/// faces, with the polygon remounted or not: whether mounting 2 was refused at its first
/// stop (as not remounted, or as turned otherwise than stated).
fn second_mounting(seed: u64, remounts: bool, face_shift: usize) -> bool {
    let dir = temp_dir(&format!("rates-mounting-{seed}-{remounts}-{face_shift}"));
    let stop = StopFlag::new();
    let devices = Devices::new(config(seed)).unwrap();
    let mut person = Person {
        world: Arc::clone(&devices.world),
        remounts,
    };
    let mut d = drivers(devices, &stop);
    let budget = WriteBudget::unlimited();
    for mounting in [
        Mounting::new(1),
        Mounting::new(2).with_face_shift(face_shift),
    ] {
        let mut run =
            RunDir::open_mounting(&dir, &settings(), &ports(), Some(mounting), false, &budget)
                .unwrap();
        let outcome =
            run::measure_attended(&mut run, instruments(&mut d), &stop, None, &mut person).unwrap();
        run.finish(&outcome).unwrap();
        if mounting.setup == 2 {
            let _ = std::fs::remove_dir_all(&dir);
            return matches!(&outcome, Outcome::InstrumentError(m)
                if m.contains("not remounted") || m.contains("as stated: their Y readings"));
        }
        assert_eq!(outcome, Outcome::Completed);
    }
    unreachable!()
}

#[test]
fn a_clean_resume_is_never_refused_and_swapped_ports_nearly_always_are() {
    let clean: Vec<(bool, bool)> = (1..=RUNS).map(|seed| resumed(seed, false)).collect();
    let false_alarms = clean.iter().filter(|r| r.0).count();
    assert_eq!(false_alarms, 0, "clean resumes refused");
    assert!(clean.iter().all(|r| r.1), "every clean resume completes");
    // Swapped: refused unless the two faces at step 4 read within 5·√2·σ = 0.141″ of
    // each other on both axes: in X their difference is a pitch deviation and two setup
    // errors (spread 0.5″ each: X alone let about one run in five through, 13 of 60),
    // in Y two pyramidal errors (spread 2″). 59 of 60 refused.
    let refused = (1..=RUNS).filter(|&seed| resumed(seed, true).0).count();
    eprintln!("swapped ports refused in {refused} of {RUNS} runs");
    assert!(refused * 10 >= RUNS as usize * 9, "{refused} of {RUNS}");
}

#[test]
fn a_correct_remount_is_never_refused_and_a_forgotten_one_nearly_always_is() {
    let false_alarms = (1..=RUNS)
        .filter(|&seed| second_mounting(seed, true, 3))
        .count();
    assert_eq!(false_alarms, 0, "correct remounts refused");
    // Forgotten: faces 1, 2 in front of the autocollimators, not 4, 5: their Y (spread
    // 2″) tells them apart unless two faces' pyramidal errors lie within 0.141″.
    let refused = (1..=RUNS)
        .filter(|&seed| second_mounting(seed, false, 3))
        .count();
    eprintln!("forgotten remounts refused in {refused} of {RUNS} runs");
    assert!(refused * 10 >= RUNS as usize * 9, "{refused} of {RUNS}");
}

#[test]
fn a_misstated_face_shift_nearly_always_is_refused() {
    // Remounted turned 3 faces, stated 2: faces 3, 4 expected, 4, 5 seen. 60 of 60 refused.
    let refused = (1..=RUNS)
        .filter(|&seed| second_mounting(seed, true, 2))
        .count();
    eprintln!("misstated face shifts refused in {refused} of {RUNS} runs");
    assert!(refused * 10 >= RUNS as usize * 9, "{refused} of {RUNS}");
}
