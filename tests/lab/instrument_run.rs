//! The simulated instruments' state machines and the run procedure, in process over
//! in-memory streams (no pseudo-terminals): the physical model and its sign, readings
//! while moving, the controller's states, the faults through the drivers, a whole run
//! that solves to the truth, interruption and resume, and the run directory's refusals.

use std::path::Path;
use std::time::{Duration, Instant};

use crate::lab_support::*;
use polycal::lab::run::{self, Outcome, RunDir, RunError, RunSettings};
use polycal::lab::sim::{DeviceId, Devices, Endpoint, Fault, FaultKind, FaultProblem};
use polycal::lab::{Autocollimator, InstrumentError, RotaryTable, StopFlag};
use polycal::measurement::MeasurementSet;
use polycal::simulate::Truth;
use polycal::solve::{self, SolveOptions};

fn reply(endpoint: &mut Endpoint, command: &str) -> String {
    String::from_utf8(endpoint.input(command.as_bytes(), Instant::now())).unwrap()
}

#[test]
fn simulated_readings_follow_the_model_of_format_section_1() {
    let stop = StopFlag::new();
    let (mut ac1, mut ac2, mut table, truth) =
        drivers(Devices::new(lab(8, 0.0, vec![])).unwrap(), &stop);
    table.start().unwrap();
    ac1.start().unwrap();
    assert!(ac1.identify().unwrap().contains("ELCOMAT 3000"));
    assert!(table.identify().unwrap().contains("SMC100"));
    for step in 0..=8 {
        let reported = table.move_to(step as f64 * 45.0).unwrap();
        assert_eq!(reported, step as f64 * 45.0);
        for (ac, device) in [(1, &mut ac1), (2, &mut ac2)] {
            let x = device.measure().unwrap().x_arcsec;
            let want = expected(&truth, step, ac);
            assert!(
                (x - want).abs() < 1e-6,
                "step {step} ac {ac}: read {x}, model {want}"
            );
        }
    }
}

#[test]
fn the_sign_of_a_position_offset_and_readings_off_the_stops() {
    let mut devices = Devices::new(lab(8, 0.0, vec![])).unwrap();
    let truth = devices.truth();
    assert_eq!(reply(&mut devices.table, "1OR\r\n"), "");
    assert_eq!(reply(&mut devices.table, "1TS\r\n"), "1TS000032\r\n");
    // 45.001°: 3.6″ past stop 1; the reading grows by 3.6″ (α is true − indicated).
    assert_eq!(reply(&mut devices.table, "1PA45.001\r\n"), "");
    let line = reply(&mut devices.autocollimators[0], "a\n");
    let parts: Vec<&str> = line.split_whitespace().collect();
    assert_eq!(parts[..2], ["4", "003"]);
    let x: f64 = parts[2].parse().unwrap();
    assert!((x - (expected(&truth, 1, 1) + 3.6)).abs() < 1e-5, "{line}");
    // Half-way between two stops no face is in front of the autocollimator.
    reply(&mut devices.table, "1PA22.5\r\n");
    assert!(reply(&mut devices.autocollimators[1], "a\n").starts_with("4 000 "));
}

#[test]
fn a_reading_while_the_table_moves_is_not_valid() {
    let mut config = lab(8, 0.0, vec![]);
    config.time_scale = 1.0;
    config.speed_deg_per_s = 100.0;
    config.home_seconds = 0.0;
    let mut devices = Devices::new(config).unwrap();
    reply(&mut devices.table, "1OR\r\n");
    reply(&mut devices.table, "1PA90\r\n"); // 0.9 s of motion
    assert_eq!(reply(&mut devices.table, "1TS\r\n"), "1TS000028\r\n");
    let during = reply(&mut devices.autocollimators[0], "a\n");
    assert!(during.starts_with("4 000 "), "{during}");
    let tp = reply(&mut devices.table, "1TP\r\n");
    let pos: f64 = tp.trim().trim_start_matches("1TP").parse().unwrap();
    assert!(pos > 0.0 && pos < 90.0, "{tp}");
    reply(&mut devices.table, "1ST\r\n");
    assert_eq!(reply(&mut devices.table, "1TS\r\n"), "1TS000033\r\n");
}

#[test]
fn the_simulated_controller_states() {
    let mut d = Devices::new(lab(8, 0.0, vec![])).unwrap();
    let t = &mut d.table;
    assert_eq!(
        reply(t, "1TS\r\n"),
        "1TS00000A\r\n",
        "powers up not referenced"
    );
    reply(t, "1PA45\r\n");
    assert_eq!(reply(t, "1TE\r\n"), "1TEH\r\n", "no move before homing");
    assert_eq!(
        reply(t, "1TE\r\n"),
        "1TE@\r\n",
        "reading the error clears it"
    );
    reply(t, "1OR\r\n");
    assert_eq!(reply(t, "1TS\r\n"), "1TS000032\r\n");
    reply(t, "1PA45\r\n");
    assert_eq!(reply(t, "1TS\r\n"), "1TS000033\r\n");
    assert_eq!(reply(t, "1TP\r\n"), "1TP45\r\n");
    reply(t, "1PAx\r\n");
    assert_eq!(reply(t, "1TE\r\n"), "1TEC\r\n");
    reply(t, "1PA9999\r\n");
    assert_eq!(reply(t, "1TE\r\n"), "1TEG\r\n");
    reply(t, "1MM0\r\n");
    assert_eq!(reply(t, "1TS\r\n"), "1TS00003C\r\n");
    reply(t, "1PA90\r\n");
    assert_eq!(reply(t, "1TE\r\n"), "1TEJ\r\n");
    reply(t, "1MM1\r\n");
    assert_eq!(reply(t, "1TS\r\n"), "1TS000034\r\n");
    assert!(reply(t, "1VE\r\n").starts_with("1VE SMC100CC"));
    assert_eq!(reply(t, "2TS\r\n"), "", "another address is not ours");
    reply(t, "1XX\r\n");
    assert_eq!(reply(t, "1TE\r\n"), "1TEA\r\n");
}

#[test]
fn the_simulated_autocollimator_streams_until_stopped() {
    let mut d = Devices::new(lab(8, 0.0, vec![])).unwrap();
    assert!(reply(&mut d.autocollimators[0], "d\n").starts_with("8 ELCOMAT 3000"));
    assert_eq!(reply(&mut d.autocollimators[0], "A\n"), "");
    std::thread::sleep(Duration::from_millis(60));
    let streamed = String::from_utf8(d.autocollimators[0].tick(Instant::now())).unwrap();
    assert!(streamed.starts_with("3 "), "{streamed:?}");
    reply(&mut d.autocollimators[0], "s\n");
    std::thread::sleep(Duration::from_millis(60));
    assert!(d.autocollimators[0].tick(Instant::now()).is_empty());
    assert!(reply(&mut d.autocollimators[0], "r\n").starts_with("2 "));
    assert_eq!(
        reply(&mut d.autocollimators[0], "z\n"),
        "",
        "unknown commands get no reply"
    );
}

fn fault(spec: &str) -> Fault {
    spec.parse().unwrap()
}

#[test]
fn faults_through_the_drivers() {
    // Queries: retried, and the value is right.
    let stop = StopFlag::new();
    let faults = vec![
        fault("x-invalid:ac1:after=2"),
        fault("lost-reply:ac2:after=1"),
        fault("garbled:ac2:after=2"),
        fault("lost-reply:table:after=1"),
        fault("garbled:table:after=2"),
    ];
    let (mut ac1, mut ac2, mut table, truth) =
        drivers(Devices::new(lab(8, 0.0, faults)).unwrap(), &stop);
    table.start().unwrap();
    for step in 0..4 {
        table.move_to(step as f64 * 45.0).unwrap();
        let x1 = ac1.measure().unwrap().x_arcsec;
        let x2 = ac2.measure().unwrap().x_arcsec;
        assert!((x1 - expected(&truth, step, 1)).abs() < 1e-6);
        assert!((x2 - expected(&truth, step, 2)).abs() < 1e-6);
    }

    // The table stuck in a disable state.
    let (_, _, mut table, _) = drivers(
        Devices::new(lab(8, 0.0, vec![fault("disable:table:after=2")])).unwrap(),
        &stop,
    );
    table.start().unwrap();
    table.move_to(0.0).unwrap();
    table.move_to(45.0).unwrap();
    let e = table.move_to(90.0).unwrap_err().to_string();
    assert!(e.contains("3D"), "{e}");
    let e = table.move_to(90.0).unwrap_err().to_string();
    assert!(e.contains("3D"), "stays disabled: {e}");

    // The port closing.
    let (mut ac1, _, _, _) = drivers(
        Devices::new(lab(8, 0.0, vec![fault("close:ac1:after=1")])).unwrap(),
        &stop,
    );
    ac1.measure().unwrap();
    assert!(matches!(ac1.measure(), Err(InstrumentError::Closed { .. })));

    // Too many lost replies: the query gives up.
    let (mut ac1, _, _, _) = drivers(
        Devices::new(lab(8, 0.0, vec![fault("lost-reply:ac1:count=4")])).unwrap(),
        &stop,
    );
    assert!(matches!(
        ac1.measure(),
        Err(InstrumentError::Timeout { attempts: 4, .. })
    ));
    assert!(ac1.measure().is_ok(), "the fault is spent");
}

#[test]
fn fault_specs() {
    let f = fault("lost-reply:ac1:after=10");
    assert_eq!(
        (f.kind, f.device, f.after, f.count),
        (FaultKind::LostReply, DeviceId::Ac(1), 10, 1)
    );
    let f = fault("late:ac1:after=2:commands=4");
    assert_eq!(
        (f.kind, f.after, f.late_commands),
        (FaultKind::Late, 2, Some(4))
    );
    assert_eq!(f.to_string(), "late:ac1:after=2:count=1:commands=4");
    let f = fault("stall:table:after=3:fraction=0.25");
    assert_eq!(
        (f.kind, f.after, f.stall_fraction),
        (FaultKind::Stall, 3, 0.25)
    );
    assert_eq!(f.to_string(), "stall:table:after=3:count=1:fraction=0.25");
    for (bad, problem) in [
        ("lost-reply", FaultProblem::TooFewParts),
        ("melt:ac1", FaultProblem::UnknownKind("melt".into())),
        (
            "lost-reply:ac17",
            FaultProblem::UnknownDevice("ac17".into()),
        ),
        ("lost-reply:ac0", FaultProblem::UnknownDevice("ac0".into())),
        ("disable:ac1", FaultProblem::WrongDevice(FaultKind::Disable)),
        (
            "x-invalid:table",
            FaultProblem::WrongDevice(FaultKind::XInvalid),
        ),
        (
            "close:table:after",
            FaultProblem::NotAnOption("after".into()),
        ),
        (
            "close:table:after=x",
            FaultProblem::NotAWholeNumber("x".into()),
        ),
        ("garbled:ac2:count=0", FaultProblem::ZeroCount),
        ("stale:ac2:seconds=2", FaultProblem::SecondsNotLate),
        ("late:ac2:seconds=0", FaultProblem::BadSeconds("0".into())),
        ("stale:ac2:commands=2", FaultProblem::CommandsNotLate),
        ("late:ac1:commands=0", FaultProblem::BadCommands("0".into())),
        ("late:table:fraction=0.5", FaultProblem::FractionNotStall),
        (
            "stall:table:fraction=-1",
            FaultProblem::BadFraction("-1".into()),
        ),
        ("stall:ac1", FaultProblem::WrongDevice(FaultKind::Stall)),
        (
            "late:table:seconds=NaN",
            FaultProblem::BadSeconds("NaN".into()),
        ),
        (
            "garbled:ac2:when=3",
            FaultProblem::UnknownOption("when".into()),
        ),
    ] {
        let e = bad.parse::<Fault>().unwrap_err();
        assert_eq!((e.spec.as_str(), &e.problem), (bad, &problem));
    }
    // The message, as `sim-lab --fault` prints it.
    assert_eq!(
        "x-invalid:table".parse::<Fault>().unwrap_err().to_string(),
        "fault \"x-invalid:table\": x-invalid is a fault of an autocollimator \
         (expected KIND:DEVICE[:after=K][:count=M][:seconds=S|:commands=C][:fraction=F], e.g. \
         lost-reply:ac1:after=10, late:ac2:seconds=1.3, late:ac1:commands=4 or \
         stall:table:after=3:fraction=0.5)"
    );
    assert_eq!(
        FaultProblem::WrongDevice(FaultKind::Disable).to_string(),
        "disable is a fault of the table"
    );
}

fn settings(faces: usize, cycles: u32, bidirectional: bool) -> RunSettings {
    RunSettings::new(faces, cycles)
        .with_closing(true)
        .with_bidirectional(bidirectional)
}

/// Runs (or resumes) in process; `stop_after` readings of this session ask for a stop.
fn run_in_process(
    dir: &Path,
    s: &RunSettings,
    resume: bool,
    d: &mut (Ac, Ac, Table, Truth),
    stop: &StopFlag,
    stop_after: Option<usize>,
) -> Outcome {
    let mut run = RunDir::open(dir, s, &ports(), resume).unwrap();
    let log = run.traffic_log().unwrap();
    let mut taken = 0;
    let outcome = run::measure(&mut run, instruments(d), stop, Some(&log), &mut |_| {
        taken += 1;
        if Some(taken) == stop_after {
            stop.request();
        }
    })
    .unwrap();
    run.finish(&outcome).unwrap();
    outcome
}

fn assert_solves_to_truth(path: &Path, truth: &Truth, readings: usize) {
    let set = MeasurementSet::read_path(path, None).unwrap();
    assert_eq!(set.readings.len(), readings);
    let solution = solve::solve(&set, &SolveOptions::default()).unwrap();
    let sigma = truth.noise_arcsec.unwrap();
    for (name, est, tru) in [
        ("β", &solution.pitch_deviation, &truth.pitch_deviation),
        ("α", &solution.encoder_error, &truth.encoder_error),
    ] {
        for (k, (a, b)) in est.iter().zip(tru.iter()).enumerate() {
            assert!(
                (a - b).abs() < 5.0 * sigma,
                "{name}[{k}]: estimate {a}, truth {b}"
            );
        }
    }
}

#[test]
fn a_run_in_process_is_a_calibration() {
    for bidirectional in [false, true] {
        let dir = temp_dir(&format!("whole-{bidirectional}"));
        let stop = StopFlag::new();
        let mut d = drivers(Devices::new(lab(8, 0.05, vec![])).unwrap(), &stop);
        let s = settings(8, 2, bidirectional);
        assert_eq!(
            run_in_process(&dir, &s, false, &mut d, &stop, None),
            Outcome::Completed
        );
        assert_solves_to_truth(&dir.join(run::MEASUREMENTS), &d.3, 36);
        let text = std::fs::read_to_string(dir.join(run::MEASUREMENTS)).unwrap();
        assert!(text.contains(
            "\ncycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift\n"
        ));
        if bidirectional {
            assert!(text.contains(",ccw,"));
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}

#[test]
fn an_interrupted_run_resumes_without_losing_or_repeating_a_reading() {
    let dir = temp_dir("resume");
    let stop = StopFlag::new();
    let mut d = drivers(Devices::new(lab(8, 0.05, vec![])).unwrap(), &stop);
    let s = settings(8, 2, false);
    // Stop after 7 readings: in the middle of a stop (ac1 read, ac2 not).
    let outcome = run_in_process(&dir, &s, false, &mut d, &stop, Some(7));
    assert_eq!(outcome, Outcome::Interrupted);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap()).unwrap();
    assert_eq!(manifest["outcome"], "interrupted");
    assert_eq!(manifest["readings"], 7);

    let fresh = StopFlag::new();
    let mut d2 = (d.0, d.1, d.2.with_stop_flag(fresh.clone()), d.3);
    let outcome = run_in_process(&dir, &s, true, &mut d2, &fresh, None);
    assert_eq!(outcome, Outcome::Completed);
    assert_solves_to_truth(&dir.join(run::MEASUREMENTS), &d2.3, 36);
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join(run::MANIFEST)).unwrap()).unwrap();
    assert_eq!(manifest["outcome"], "completed");
    assert_eq!(manifest["sessions"].as_array().unwrap().len(), 2);
    assert_eq!(manifest["sessions"][1]["readings_before"], 7);
    let _ = std::fs::remove_dir_all(&dir);
}

fn refused(result: Result<RunDir, RunError>) -> String {
    match result {
        Err(e) if e.is_refusal() => e.to_string(),
        other => panic!("expected a refusal, got {other:?}"),
    }
}

#[test]
fn the_run_directory_refuses_what_would_lose_or_mix_data() {
    let dir = temp_dir("refusals");
    let s = settings(8, 2, false);
    assert!(refused(RunDir::open(&dir, &s, &ports(), true)).contains("no run to resume"));
    let first = RunDir::open(&dir, &s, &ports(), false).unwrap();
    let m = refused(RunDir::open(&dir, &s, &ports(), true));
    assert!(m.contains("another polycal run"), "{m}");
    drop(first);
    let m = refused(RunDir::open(&dir, &s, &ports(), false));
    assert!(m.contains("already holds a run"), "{m}");
    let other = settings(8, 3, false);
    let m = refused(RunDir::open(&dir, &other, &ports(), true));
    assert!(
        m.contains("cycles 2 vs 3") && m.contains("refusing to resume"),
        "{m}"
    );
    let mut bad = s.clone();
    bad.faces = 2;
    assert!(refused(RunDir::open(&dir, &bad, &ports(), true)).contains("at least 3"));

    // A reading out of order (a file changed by hand) is refused.
    let path = dir.join(run::MEASUREMENTS);
    let mut text = std::fs::read_to_string(&path).unwrap();
    text.push_str("1,0,1,1,0.5,cw,0.1,1,,0,0\n1,1,1,2,0.5,cw,0.2,1,,45,0\n");
    std::fs::write(&path, &text).unwrap();
    let m = refused(RunDir::open(&dir, &s, &ports(), true));
    assert!(
        m.contains(
            "measurements.csv:4: reading \"1,1,1,2\" (cw) is not the run's reading number 2"
        ),
        "{m}"
    );

    // A last line cut short is removed, with a warning, and the run goes on from there.
    let mut text = std::fs::read_to_string(&path).unwrap();
    text = text.replace(
        "1,1,1,2,0.5,cw,0.2,1,,45,0\n",
        "1,0,2,2,0.25,cw,0.2,1,,0,0\n1,1,1,2,0.",
    );
    std::fs::write(&path, &text).unwrap();
    let run = RunDir::open(&dir, &s, &ports(), true).unwrap();
    assert_eq!(run.readings_done(), 2);
    assert_eq!(run.warnings().len(), 1, "{:?}", run.warnings());
    assert_eq!(run.remaining()[0].0.step, 1);
    assert!(std::fs::read_to_string(&path).unwrap().ends_with(",0\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Writes `rows` after the run's first comment and header, and tries to resume.
fn resume_with(dir: &Path, rows: &str) -> Result<RunDir, RunError> {
    let path = dir.join(run::MEASUREMENTS);
    let text = std::fs::read_to_string(&path).unwrap();
    let head: String = text.lines().take(2).map(|l| format!("{l}\n")).collect();
    std::fs::write(&path, head + rows).unwrap();
    RunDir::open(dir, &settings(8, 1, false), &ports(), true)
}

#[test]
fn resume_reads_the_file_with_the_measurement_rules() {
    let dir = temp_dir("resume-rules");
    let s = settings(8, 1, false);
    drop(RunDir::open(&dir, &s, &ports(), false).unwrap());
    let ok = "1,0,1,1,0.5,cw,0.1,1,,0,0\n";

    // A row the measurement file's rules refuse, named by line and column.
    let m = refused(resume_with(
        &dir,
        &format!("{ok}1,0,2,x,0.5,cw,0.2,1,,0,0\n"),
    ));
    assert!(
        m.contains(
            "measurements.csv:4:7: column \"face\": \"x\" is not an integer; refusing to resume"
        ),
        "{m}"
    );
    // A value the run always writes, missing.
    let m = refused(resume_with(&dir, &format!("{ok}1,0,2,2,0.5,cw,,1,,0,0\n")));
    assert!(m.contains(":4: column \"time\" is empty"), "{m}");
    // More readings than the run has (18 for 8 faces, one cycle with closing).
    let all: String = s
        .plan()
        .iter()
        .flat_map(|stop| [(stop, 1u32), (stop, 2)])
        .chain(std::iter::once((&s.plan()[0], 1)))
        .map(|(stop, ac)| {
            let face = (stop.step + ac as usize - 1) % 8 + 1;
            format!(
                "{},{},{ac},{face},0.5,cw,0.1,1,,0,0\n",
                stop.cycle, stop.step
            )
        })
        .collect();
    let m = refused(resume_with(&dir, &all));
    assert!(m.contains(":21: more readings than the run has"), "{m}");
    // Without that last one the run is complete.
    let complete: String = all.lines().take(18).map(|l| format!("{l}\n")).collect();
    let run = resume_with(&dir, &complete).unwrap();
    assert_eq!((run.readings_done(), run.remaining().len()), (18, 0));
    drop(run);

    // Another header (another column order) is refused: rows appended to it would mix.
    let path = dir.join(run::MEASUREMENTS);
    std::fs::write(
        &path,
        "# a run\ncycle,step,ac,face,reading,direction,setup,time,reading_y,encoder\n",
    )
    .unwrap();
    let m = refused(RunDir::open(&dir, &s, &ports(), true));
    assert!(m.contains("measurements.csv:2: header"), "{m}");

    // The header itself cut short: the comment is kept, the header written again, and
    // the first reading appended after it.
    std::fs::write(&path, "# a run\ncycle,step,ac,fa").unwrap();
    let stop = StopFlag::new();
    let mut d = drivers(Devices::new(lab(8, 0.0, vec![])).unwrap(), &stop);
    let run = RunDir::open(&dir, &s, &ports(), true).unwrap();
    assert_eq!((run.warnings().len(), run.readings_done()), (1, 0));
    drop(run);
    let outcome = run_in_process(&dir, &s, true, &mut d, &stop, None);
    assert_eq!(outcome, Outcome::Completed);
    let text = std::fs::read_to_string(&path).unwrap();
    assert!(
        text.starts_with(
            "# a run\ncycle,step,ac,face,reading,direction,time,setup,reading_y,encoder,shift\n1,0,1,1,"
        ),
        "{text}"
    );
    let set = MeasurementSet::read_path(&path, None).unwrap();
    assert_eq!(set.readings.len(), 18);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_session_stopped_before_the_check_of_its_last_cycle_has_it_done_on_resume() {
    // A 2″ outlier at the last cycle's step 3 (autocollimator 2); the session is asked to
    // stop at the cycle's last reading, so the check that would measure it again ends
    // before it could (and is not recorded as done).
    let dir = temp_dir("unchecked-cycle");
    let s = settings(8, 2, false).with_reading_noise_arcsec(0.02);
    let mut config = lab(8, 0.02, vec![]);
    config
        .simulation
        .effects
        .push(polycal::effects::Effect::Outlier {
            cycle: 2,
            step: 3,
            ac: 2,
            setup: None,
            value: 2.0,
        });
    let stop = StopFlag::new();
    let mut d = drivers(Devices::new(config).unwrap(), &stop);
    // 36 readings and the check after cycle 1: the 37th report is the last reading.
    let outcome = run_in_process(&dir, &s, false, &mut d, &stop, Some(37));
    assert_eq!(outcome, Outcome::Interrupted);
    let run = RunDir::open(&dir, &s, &ports(), true).unwrap();
    assert!(run.remaining().is_empty(), "every reading on disk");
    assert_eq!(run.unchecked_cycle(), Some(2));
    assert!(!run.is_complete());
    assert!(run.manifest().remeasured.is_empty());
    drop(run);

    // Resumed: the check after cycle 2 is done first, and measures the outlier again.
    stop.shared()
        .store(false, std::sync::atomic::Ordering::SeqCst);
    let outcome = run_in_process(&dir, &s, true, &mut d, &stop, None);
    assert_eq!(outcome, Outcome::Completed);
    let run = RunDir::open(&dir, &s, &ports(), true).unwrap();
    assert!(run.is_complete());
    let remeasured = &run.manifest().remeasured;
    assert_eq!(remeasured.len(), 1, "{remeasured:?}");
    assert_eq!(
        (remeasured[0].cycle, remeasured[0].step, remeasured[0].ac),
        (2, 3, 2)
    );
    assert!((remeasured[0].first_arcsec - remeasured[0].reading_arcsec - 2.0).abs() < 0.2);
    assert_eq!(
        run.manifest().checked_cycles.as_deref(),
        Some(&[(1, 1), (1, 2)][..])
    );
    let _ = std::fs::remove_dir_all(&dir);
}
