//! A run in several mountings of the polygon (docs/FORMAT.md §7.3, *Several mountings*),
//! in process against the simulated lab: the second mounting measured after the
//! operator's remount, reading by reading where the lab's truth puts it; the remount's
//! checks (confirmed, the table not moved, a face in front of every autocollimator); and
//! the refusals that keep the mountings of one run directory in order.

use std::sync::{Arc, Mutex};

use polycal::MeasurementSet;
use polycal::lab::StopFlag;
use polycal::lab::WriteBudget;
use polycal::lab::run::{
    self, Attendant, Mounting, Outcome, Progress, Remount, RunDir, RunError, RunSettings,
};
use polycal::lab::sim::{Devices, LabConfig, RemountError, World};
use polycal::simulate::{SimulationConfig, Truth};
use polycal::solve::SolveOptions;
use polycal::solve::sub_pitch::solve_shifted;

use crate::lab_support::*;

const NOISE: f64 = 0.02;

/// A lab of 8 faces, two cycles with the closing step, two mountings: the second with
/// the table at `shift` at step 0 (22.5°: between the stops) and the polygon turned 3
/// faces.
fn two_mountings(shift: f64) -> LabConfig {
    LabConfig::new(SimulationConfig {
        faces: 8,
        noise_arcsec: NOISE,
        cycles: 2,
        closing: true,
        setups: 2,
        setup_shift_faces: 3,
        table_shift_deg: vec![0.0, shift],
        seed: 11,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0)
}

fn settings() -> RunSettings {
    RunSettings::new(8, 2)
        .with_closing(true)
        .with_reading_noise_arcsec(NOISE)
}

fn second() -> Mounting {
    Mounting::new(2).with_shift_deg(22.5).with_face_shift(3)
}

/// What the person at the table does when asked to remount.
#[derive(Clone, Copy, PartialEq)]
enum Operator {
    /// Remounts the polygon and confirms.
    Remounts,
    /// Confirms without remounting.
    Forgets,
    /// Remounts, and turns the table by hand by this many degrees.
    Turns(f64),
    /// Does not confirm.
    Declines,
}

struct Person {
    world: Arc<Mutex<World>>,
    does: Operator,
    asked: Vec<Remount>,
    /// The warnings of the checks after each cycle: (setup, cycle, warning).
    warned: Vec<(u32, u32, String)>,
}

impl Attendant for Person {
    fn progress(&mut self, progress: &Progress) {
        if let Some(check) = &progress.cycle_check {
            for w in &check.warnings {
                self.warned.push((check.setup, check.cycle, w.clone()));
            }
        }
    }

    fn remount(&mut self, remount: &Remount) -> bool {
        self.asked.push(remount.clone());
        let mut world = self.world.lock().unwrap();
        match self.does {
            Operator::Remounts => {
                world.remount().unwrap();
            }
            Operator::Forgets => {}
            Operator::Turns(degrees) => {
                world.remount().unwrap();
                world.turn_table_by_hand(degrees);
            }
            Operator::Declines => return false,
        }
        true
    }
}

/// One session in `mounting` (None: the manifest's), the person doing `does`.
fn session(
    dir: &std::path::Path,
    mounting: Option<Mounting>,
    resume: bool,
    d: &mut (Ac, Ac, Table, Truth),
    person: &mut Person,
) -> Result<Outcome, RunError> {
    let mut run = open(dir, mounting, resume)?;
    let outcome = run::measure_attended(&mut run, instruments(d), &StopFlag::new(), None, person)?;
    run.finish(&outcome)?;
    Ok(outcome)
}

/// A lab, its drivers and the person at its table.
fn lab_and_person(does: Operator) -> ((Ac, Ac, Table, Truth), Person, StopFlag) {
    lab_and_person_at(does, 22.5)
}

/// As [`lab_and_person`], the second mounting at `shift`.
fn lab_and_person_at(does: Operator, shift: f64) -> ((Ac, Ac, Table, Truth), Person, StopFlag) {
    let devices = Devices::new(two_mountings(shift)).unwrap();
    let world = Arc::clone(&devices.world);
    let stop = StopFlag::new();
    let d = drivers(devices, &stop);
    (
        d,
        Person {
            world,
            does,
            asked: Vec::new(),
            warned: Vec::new(),
        },
        stop,
    )
}

/// Every reading lies where the truth puts it: the face its mounting turns in front of
/// the autocollimator, α at the table's angle (the shift + step·45°), the mounting's
/// setup error, the table's offset from its stop, within 6σ of a stored mean.
fn assert_every_reading_at_its_place(set: &MeasurementSet, truth: &Truth, shift: f64) {
    let shifts = [0.0, shift];
    let face_shifts = [0, 3];
    let sigma = NOISE / 2f64.sqrt();
    for r in &set.readings {
        let s = r.setup as usize - 1;
        let face = (r.ac as usize - 1 + face_shifts[s] + r.step) % 8 + 1;
        assert_eq!(r.face, face, "{r:?}");
        let angle = shifts[s] + (r.step % 8) as f64 * 45.0;
        let commanded = shifts[s] + r.step as f64 * 45.0;
        let expected = truth.encoder_error_at_deg(angle).unwrap()
            + truth.face_deviation_at(face)
            + truth.setup_error_of(r.setup, r.ac).unwrap()
            + (r.encoder_degrees.unwrap() - commanded) * 3600.0;
        assert!(
            (r.reading_arcsec - expected).abs() < 6.0 * sigma,
            "{r:?}: expected {expected}"
        );
    }
}

/// The lab mounts the polygon as its next setup, and refuses a remount past its last
/// with a typed error that says how many mountings it simulates.
#[test]
fn the_lab_refuses_a_remount_past_its_last_mounting() {
    let devices = Devices::new(two_mountings(22.5)).unwrap();
    assert_eq!(devices.remount(), Ok(2));
    let refused = devices.remount().unwrap_err();
    assert_eq!(
        refused,
        RemountError::LastMounting {
            setups: 2,
            mounting: 2
        }
    );
    assert_eq!(
        refused.to_string(),
        "the lab simulates 2 mounting(s), and mounting 2 is on the table"
    );
}

#[test]
fn a_run_in_two_mountings_is_measured_where_the_truth_puts_it() {
    let dir = temp_dir("mountings");
    let (mut d, mut person, _stop) = lab_and_person(Operator::Remounts);
    let truth = d.3.clone();
    assert_eq!(
        session(&dir, None, false, &mut d, &mut person).unwrap(),
        Outcome::Completed
    );
    assert!(
        person.asked.is_empty(),
        "the first mounting is not asked for"
    );
    assert_eq!(
        session(&dir, Some(second()), false, &mut d, &mut person).unwrap(),
        Outcome::Completed
    );
    // Asked once, with the table at the mounting's step 0 and the faces to face.
    assert_eq!(person.asked.len(), 1);
    assert_eq!(person.asked[0].mounting, second());
    assert!((person.asked[0].table_deg - 22.5).abs() < 1e-9);
    assert_eq!(person.asked[0].faces, [(1, 4), (2, 5)]);

    let path = dir.join(run::MEASUREMENTS);
    let set = MeasurementSet::read_path(&path, None).unwrap();
    assert_eq!(set.readings.len(), 2 * 36);
    assert_eq!(set.shift_deg(2), 22.5);
    assert_every_reading_at_its_place(&set, &truth, 22.5);
    // Solved as `solve` solves it: β and both cosets' α against the truth.
    let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
    assert_eq!(solved.encoder_angle_deg.len(), 16);
    let u = solved.encoder_error_u.clone().unwrap();
    for (k, (a, angle)) in solved
        .encoder_error
        .iter()
        .zip(&solved.encoder_angle_deg)
        .enumerate()
    {
        let t = truth.encoder_error_at_deg(*angle).unwrap();
        assert!(
            (a - t).abs() < 5.0 * u[k].max(NOISE),
            "α at {angle}°: {a} vs {t}"
        );
    }
    for (k, (b, t)) in solved
        .solution
        .pitch_deviation
        .iter()
        .zip(&truth.pitch_deviation)
        .enumerate()
    {
        assert!((b - t).abs() < 5.0 * NOISE, "β[{k}]: {b} vs {t}");
    }
    assert!(person.warned.is_empty(), "{:?}", person.warned);
    let text = std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap();
    let m: serde_json::Value = serde_json::from_str(&text).unwrap();
    assert_eq!(m["expected_readings"], 72);
    assert_eq!(m["mountings"][1]["shift_deg"], 22.5);
    assert_eq!(m["mountings"][1]["face_shift"], 3);
    assert!(m["mountings"][1]["confirmed"].is_string());
    assert_eq!(m["mountings"][0]["confirmed"], serde_json::Value::Null);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Mounting 1 complete in `name`'s directory, the lab still mounted so.
fn first_done(
    name: &str,
    does: Operator,
    shift: f64,
) -> (std::path::PathBuf, (Ac, Ac, Table, Truth), Person) {
    let dir = temp_dir(name);
    let (mut d, mut person, _stop) = lab_and_person_at(does, shift);
    assert_eq!(
        session(&dir, None, false, &mut d, &mut person).unwrap(),
        Outcome::Completed
    );
    (dir, d, person)
}

fn readings_of(dir: &std::path::Path, setup: u32) -> usize {
    let text = std::fs::read_to_string(dir.join(run::MEASUREMENTS)).unwrap();
    polycal::measurement::read_rows(text.as_bytes(), "m")
        .unwrap()
        .iter()
        .filter(|r| r.setup == setup)
        .count()
}

#[test]
fn a_remount_not_confirmed_or_not_done_measures_nothing_and_is_asked_again() {
    // Declined: nothing measured, the mounting awaits its remount still.
    let (dir, mut d, mut person) = first_done("declined", Operator::Declines, 22.5);
    let outcome = session(&dir, Some(second()), false, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Interrupted);
    assert_eq!(readings_of(&dir, 2), 0);

    // Confirmed, but the polygon was not remounted: no face in front of autocollimator
    // 1 (the stops lie 22.5° off the faces); nothing measured, not recorded as confirmed.
    person.does = Operator::Forgets;
    let outcome = session(&dir, None, true, &mut d, &mut person).unwrap();
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    assert!(
        message.starts_with("autocollimator 1 sees no face after the remount of mounting 2"),
        "{message}"
    );
    assert!(
        message.contains("face 4 facing it, the table at 22.5°"),
        "{message}"
    );
    assert_eq!(readings_of(&dir, 2), 0);

    // Remounted, but the table turned by hand meanwhile: refused before any reading.
    person.does = Operator::Turns(0.01);
    let outcome = session(&dir, None, true, &mut d, &mut person).unwrap();
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    assert!(message.contains("reports 22.51°, not 22.5°"), "{message}");
    assert!(message.contains("the table was moved"), "{message}");
    assert_eq!(readings_of(&dir, 2), 0);

    // Asked a fourth time; the polygon stays mounted (the lab's second mounting), the
    // table back where it belongs.
    person.does = Operator::Forgets;
    let outcome = session(&dir, None, true, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Completed);
    assert_eq!(person.asked.len(), 4);
    assert_eq!(readings_of(&dir, 2), 36);
    let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
    assert_every_reading_at_its_place(&set, &d.3, 22.5);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The manifest's record of mounting 2.
fn second_record(dir: &std::path::Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap();
    let m: serde_json::Value = serde_json::from_str(&text).unwrap();
    m["mountings"][1].clone()
}

#[test]
fn a_misstated_face_shift_is_refused_at_the_first_stop_of_the_mounting() {
    // The run is told the polygon is turned 2 faces; the person turns it 3 (the lab's).
    let (dir, mut d, mut person) = first_done("told-otherwise", Operator::Remounts, 22.5);
    let truth = d.3.clone();
    let told = Mounting::new(2).with_shift_deg(22.5).with_face_shift(2);
    let outcome = session(&dir, Some(told), false, &mut d, &mut person).unwrap();
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    // At step 0 autocollimators 1, 2 face faces 4, 5 (turned 3), not 3, 4 (turned 2);
    // the Y readings they compare are the lab's pyramidal errors of those faces.
    assert!(
        message.starts_with(
            "at the first stop of mounting 2 (shift 22.5°, turned 2 faces), cycle 1, step 0, \
             the autocollimators see faces 4, 5 (the polygon turned 3 face(s)), not faces 3, 4 \
             as stated"
        ),
        "{message}"
    );
    assert!(
        message.contains("state the mounting as it is (--setup 2 --shift 22.5 --face-shift 3)"),
        "{message}"
    );
    assert_eq!(readings_of(&dir, 2), 0, "nothing of the mounting stored");
    assert_eq!(second_record(&dir)["confirmed"], serde_json::Value::Null);
    assert!(person.warned.is_empty(), "{:?}", person.warned);

    // Stated as mounted (nothing of it measured yet: restated), it is asked for again
    // and measured where the truth puts it. (The lab is in its second mounting already.)
    person.does = Operator::Forgets;
    let outcome = session(&dir, Some(second()), false, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Completed);
    assert_eq!(person.asked.len(), 2);
    let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
    assert_eq!(set.readings.len(), 72);
    assert_every_reading_at_its_place(&set, &truth, 22.5);
    assert!(person.warned.is_empty(), "{:?}", person.warned);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_forgotten_remount_is_refused_at_the_first_stop_of_the_mounting() {
    // Both mountings with the table at 0° at step 0; the second turns the polygon 3
    // faces. The person confirms without remounting: every autocollimator sees a face,
    // the faces of mounting 1.
    let (dir, mut d, mut person) = first_done("forgotten", Operator::Forgets, 0.0);
    let truth = d.3.clone();
    let turned = Mounting::new(2).with_face_shift(3);
    let outcome = session(&dir, Some(turned), false, &mut d, &mut person).unwrap();
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    assert!(
        message.starts_with(
            "at the first stop of mounting 2 (shift 0°, turned 3 faces), cycle 1, step 0, the \
             table at 0°, the autocollimators read what they read at this table angle in \
             mounting 1"
        ),
        "{message}"
    );
    assert!(
        message.contains(
            "and Y as faces 1, 2 (not faces 4, 5 as stated): the polygon was not remounted"
        ),
        "{message}"
    );
    assert_eq!(readings_of(&dir, 2), 0, "nothing of the mounting stored");
    assert_eq!(second_record(&dir)["confirmed"], serde_json::Value::Null);

    // Remounted when asked again: measured where the truth puts it.
    person.does = Operator::Remounts;
    let outcome = session(&dir, None, true, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Completed);
    assert_eq!(person.asked.len(), 2);
    assert!(second_record(&dir)["confirmed"].is_string());
    let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
    assert_eq!(set.readings.len(), 72);
    assert_every_reading_at_its_place(&set, &truth, 0.0);
    assert!(person.warned.is_empty(), "{:?}", person.warned);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_polygon_mounted_otherwise_without_y_readings_is_a_warning_after_its_first_cycle() {
    // Mounting 1's Y readings left out of the file (an autocollimator without a valid Y
    // axis): the first stop cannot tell the faces apart, the check after the cycle can.
    let (dir, mut d, mut person) = first_done("told-otherwise-no-y", Operator::Remounts, 22.5);
    let path = dir.join(run::MEASUREMENTS);
    let text = std::fs::read_to_string(&path).unwrap();
    let mut rows = 0;
    let without_y: String = text
        .lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            if !l.starts_with('#') && f.len() == 11 && f[0] != "cycle" {
                f[8] = "";
                rows += 1;
            }
            format!("{}\n", f.join(","))
        })
        .collect();
    assert_eq!(rows, 36);
    std::fs::write(&path, without_y).unwrap();
    let told = Mounting::new(2).with_shift_deg(22.5).with_face_shift(2);
    let outcome = session(&dir, Some(told), false, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Completed);
    let first = person.warned.first().expect("a warning");
    assert_eq!((first.0, first.1), (2, 1), "{:?}", person.warned);
    assert!(
        first
            .2
            .starts_with("the readings of mounting 2 do not fit those of the mountings before it"),
        "{}",
        first.2
    );
    // The run keeps it: the mounting's record, and its doubts.
    let run = open(&dir, None, true).unwrap();
    assert!(run.has_doubts());
    let misfit = run.manifest().mountings[1].misfit.clone().unwrap();
    assert!(misfit.contains("do not fit"), "{misfit}");
    let _ = std::fs::remove_dir_all(&dir);
}

fn refused(result: Result<RunDir, RunError>) -> String {
    match result {
        Ok(_) => panic!("not refused"),
        Err(e) => {
            assert!(e.is_refusal(), "{e}");
            e.to_string()
        }
    }
}

fn open(
    dir: &std::path::Path,
    mounting: Option<Mounting>,
    resume: bool,
) -> Result<RunDir, RunError> {
    RunDir::open_mounting(
        dir,
        &settings(),
        &ports(),
        mounting,
        resume,
        &WriteBudget::unlimited(),
    )
}

#[test]
fn the_mountings_of_a_run_directory_stay_in_order() {
    // No run yet: a second mounting has nothing to continue.
    let empty = temp_dir("mountings-empty");
    let m = refused(open(&empty, Some(second()), false));
    assert!(m.contains("no run here"), "{m}");
    assert!(!empty.join(run::MANIFEST).exists());

    // Mounting 1 interrupted: the next one must wait for it.
    let dir = temp_dir("mountings-order");
    let (mut d, _person, stop) = lab_and_person(Operator::Remounts);
    {
        let mut run = open(&dir, None, false).unwrap();
        let mut taken = 0;
        let outcome = run::measure(&mut run, instruments(&mut d), &stop, None, &mut |_| {
            taken += 1;
            if taken == 10 {
                stop.request();
            }
        })
        .unwrap();
        assert_eq!(outcome, Outcome::Interrupted);
        run.finish(&outcome).unwrap();
    }
    let m = refused(open(&dir, Some(second()), false));
    assert!(
        m.ends_with("mounting 1 has 10 of its 36 readings; complete it (resume it) before the polygon is remounted"),
        "{m}"
    );
    let m = refused(open(&dir, Some(Mounting::new(3)), true));
    assert!(m.contains("the next one is 2, not 3"), "{m}");
    // Mounting 1 restated otherwise than it was started.
    let m = refused(open(
        &dir,
        Some(Mounting::new(1).with_shift_deg(10.0)),
        true,
    ));
    assert!(
        m.contains(
            "the run measures mounting 1 (shift 0°), this command says mounting 1 (shift 10°)"
        ),
        "{m}"
    );
    let m = refused(open(&dir, Some(Mounting::new(2).with_face_shift(8)), true));
    assert!(m.contains("face-shift 8"), "{m}");

    // Completed; mounting 2 started, stated otherwise before anything of it was
    // measured (accepted), then mounting 1 is left behind. (The stop asked for above is
    // withdrawn: the table's driver shares the flag.)
    stop.shared()
        .store(false, std::sync::atomic::Ordering::SeqCst);
    {
        let mut run = open(&dir, None, true).unwrap();
        assert_eq!(run.mounting(), Mounting::new(1));
        let outcome =
            run::measure(&mut run, instruments(&mut d), &stop, None, &mut |_| {}).unwrap();
        assert_eq!(outcome, Outcome::Completed);
        run.finish(&outcome).unwrap();
    }
    let run = open(&dir, Some(Mounting::new(2).with_shift_deg(45.0)), false).unwrap();
    assert!(run.awaits_remount());
    assert_eq!(run.manifest().expected_readings, 72);
    drop(run);
    let run = open(&dir, Some(second()), false).unwrap();
    assert_eq!(run.mounting(), second());
    assert_eq!(run.remaining().len(), 18);
    drop(run);
    let m = refused(open(&dir, Some(Mounting::new(1)), true));
    assert!(
        m.contains("mounting 1 is complete and the run has gone on to mounting 2"),
        "{m}"
    );
    // Without a mounting, a resumed run is in its last one.
    let run = open(&dir, None, true).unwrap();
    assert_eq!(run.mounting(), second());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_started_before_the_shift_column_goes_on_without_one() {
    // A complete mounting 1 as an older polycal wrote it: no `shift` column, no
    // `mountings` in the manifest.
    let (dir, mut d, mut person) = first_done("old-run", Operator::Remounts, 0.0);
    let path = dir.join(run::MEASUREMENTS);
    let text = std::fs::read_to_string(&path).unwrap();
    let old: String = text
        .lines()
        .map(
            |l| match l.strip_suffix(",shift").or_else(|| l.strip_suffix(",0")) {
                Some(kept) if !l.starts_with('#') => format!("{kept}\n"),
                _ => format!("{l}\n"),
            },
        )
        .collect();
    assert!(old.contains("\ncycle,step,ac,face,reading,direction,time,setup,reading_y,encoder\n"));
    std::fs::write(&path, &old).unwrap();
    let manifest = dir.join(run::MANIFEST);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    m.as_object_mut().unwrap().remove("mountings");
    std::fs::write(&manifest, serde_json::to_string(&m).unwrap()).unwrap();

    // A shifted mounting needs the column.
    let m = refused(open(&dir, Some(second()), false));
    assert!(
        m.contains("lacks; measure it in a new run directory"),
        "{m}"
    );
    // An unshifted one goes on in the file's own columns.
    let whole = Mounting::new(2).with_face_shift(3);
    let outcome = session(&dir, Some(whole), false, &mut d, &mut person).unwrap();
    assert_eq!(outcome, Outcome::Completed);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(text.starts_with(&old), "the old rows and header are kept");
    let set = MeasurementSet::read_path(&path, None).unwrap();
    assert_eq!(set.readings.len(), 72);
    assert_every_reading_at_its_place(&set, &d.3, 0.0);
    let _ = std::fs::remove_dir_all(&dir);
}
