//! Instruments of other makes (docs/FORMAT.md §7, docs/instruments.md): every bundled
//! profile, over a pseudo-terminal and over TCP, with every fault of the simulated lab at
//! the first, a middle and the closing query of its device. Each run either completes
//! with every reading within 6σ of the lab's truth *at its own stop*, or stops with an
//! instrument error and resuming (the instruments switched off and on: the same truth,
//! no fault) completes it so. The bundled table profiles are also checked against
//! transcripts written by hand from the makers' command sets, apart from the profile
//! files.

#![cfg(unix)]

use std::time::Duration;

use crate::lab_support::expected_at;
use polycal::lab::driver::{ProfileAutocollimator, ProfileTable, TableOptions, TableState};
use polycal::lab::profile::{BUNDLED, Profile};
use polycal::lab::run::{self, Instruments, Outcome, Ports, RunDir, RunSettings};
use polycal::lab::scripted::ScriptedStream;
use polycal::lab::serial::SerialTransport;
use polycal::lab::sim::{DeviceId, Devices, FAULT_KINDS, Fault, FaultKind, Lab, LabConfig};
use polycal::lab::tcp::TcpTransport;
use polycal::lab::transport::{StreamTransport, Transport};
use polycal::lab::{QueryOptions, RotaryTable, StopFlag};
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, Truth};

/// The lab's noise σ, arcsec; the run is told the same.
const SIGMA: f64 = 0.05;
const FACES: usize = 4;

fn settings() -> RunSettings {
    RunSettings::new(FACES, 1)
        .with_closing(true)
        .with_reading_noise_arcsec(SIGMA)
}

/// A lab whose stops are far apart in what the autocollimators read.
fn config(faults: Vec<Fault>, ac: &Profile, table: &Profile) -> LabConfig {
    LabConfig::new(SimulationConfig {
        faces: FACES,
        noise_arcsec: SIGMA,
        pitch_spread_arcsec: 5.0,
        cycles: 1,
        closing: true,
        seed: 11,
        ..SimulationConfig::default()
    })
    .with_time_scale(0.0)
    .with_faults(faults)
    .with_ac_profile(ac.clone())
    .with_table_profile(table.clone())
}

/// The reply deadline: short, for a sweep of many sessions, yet long enough that a
/// machine busy with other tests (several sessions of this file run at once) does not
/// starve a device for four deadlines in a row.
fn query() -> QueryOptions {
    QueryOptions::new(Duration::from_millis(150), 3)
}

fn open(path: &str, profile: &Profile) -> Box<dyn Transport> {
    if path.starts_with("tcp://") {
        Box::new(TcpTransport::connect(path).unwrap())
    } else {
        Box::new(SerialTransport::open(path, &profile.line).unwrap())
    }
}

/// One session against a lab served over pseudo-terminals or TCP; the outcome.
fn session(
    dir: &std::path::Path,
    devices: Devices,
    tcp: bool,
    ac_profile: &Profile,
    table_profile: &Profile,
    resume: bool,
) -> Outcome {
    let lab = if tcp {
        Lab::start_tcp(devices).unwrap()
    } else {
        Lab::start(devices).unwrap()
    };
    let paths = lab.paths().clone();
    let mut run = RunDir::open(dir, &settings(), &paths, resume).unwrap();
    let stop = StopFlag::new();
    let ac = |path: &str| {
        ProfileAutocollimator::new(open(path, ac_profile), ac_profile, query())
            .unwrap()
            .with_drain(Duration::from_millis(5))
    };
    let mut acs: Vec<_> = paths.autocollimators.iter().map(|p| ac(p)).collect();
    let mut table = ProfileTable::new(
        open(&paths.table, table_profile),
        table_profile,
        TableOptions::new(query()).with_poll_interval(Duration::from_millis(2)),
    )
    .unwrap()
    .with_stop_flag(stop.clone());
    let outcome = run::measure(
        &mut run,
        Instruments::of(&mut acs, &mut table),
        &stop,
        None,
        &mut |_| {},
    )
    .unwrap();
    run.finish(&outcome).unwrap();
    drop((acs, table));
    lab.shutdown();
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
            "{what}: step {} ac {}: {} but {} at this stop",
            r.step,
            r.ac,
            r.reading_arcsec,
            want
        );
    }
}

/// The events at which a fault is armed: the first query, a middle one and the closing
/// stop's (measurements of an autocollimator, moves of the table).
fn positions(device: DeviceId) -> [u64; 3] {
    let stops = (FACES + 1) as u64;
    match device {
        DeviceId::Table => [0, stops / 2, stops - 1],
        _ => {
            let reads = u64::from(settings().reads_per_stop);
            [0, stops / 2 * reads, (stops - 1) * reads]
        }
    }
}

/// Runs every fault of the lab on `device` at its three places, for one pair of
/// profiles over one transport; returns the faults that stopped a session.
fn sweep(
    ac_profile: &Profile,
    table_profile: &Profile,
    tcp: bool,
    device: DeviceId,
) -> Vec<String> {
    let mut stopped = Vec::new();
    for kind in FAULT_KINDS {
        if !kind.applies_to(device) {
            continue;
        }
        for after in positions(device) {
            let mut fault = Fault::new(kind, device).with_after(after);
            if kind == FaultKind::Late {
                // Past the deadline of query(): the reply is stale when it comes.
                fault = fault.with_late(Duration::from_millis(400));
            }
            let what = format!(
                "{} / {} over {}: {fault}",
                ac_profile.name,
                table_profile.name,
                if tcp { "TCP" } else { "a pseudo-terminal" }
            );
            let dir = std::env::temp_dir().join(format!(
                "polycal-profiles-{}-{}-{}-{}-{}",
                std::process::id(),
                ac_profile.name,
                table_profile.name,
                tcp,
                fault.to_string().replace([':', '='], "-")
            ));
            let _ = std::fs::remove_dir_all(&dir);
            let devices = Devices::new(config(vec![fault], ac_profile, table_profile)).unwrap();
            let truth = devices.truth();
            let outcome = session(&dir, devices, tcp, ac_profile, table_profile, false);
            if outcome != Outcome::Completed {
                let Outcome::InstrumentError(message) = &outcome else {
                    panic!("{what}: {outcome:?}");
                };
                stopped.push(format!("{what}: {message}"));
                let again =
                    Devices::with_truth(config(vec![], ac_profile, table_profile), truth.clone())
                        .unwrap();
                assert_eq!(
                    session(&dir, again, tcp, ac_profile, table_profile, true),
                    Outcome::Completed,
                    "{what}: resumed"
                );
            }
            assert_every_reading_at_its_stop(&dir, &truth, &what);
            std::fs::remove_dir_all(&dir).unwrap();
        }
    }
    stopped
}

/// The faults that end a session by design: the device is gone or disabled.
fn stops_by_design(what: &str) -> bool {
    what.contains(": close:") || what.contains(": disable:")
}

/// The sweeps over a pseudo-terminal and over TCP, at once: each waits on its instruments
/// far more than it computes, so the two share the time.
fn table_sweep(name: &str) {
    let ac = Profile::load("elcomat3000").unwrap();
    let table = Profile::load(name).unwrap();
    let stopped_by_transport = std::thread::scope(|scope| {
        let sweeps: Vec<_> = [false, true]
            .map(|tcp| {
                let (ac, table) = (&ac, &table);
                scope.spawn(move || sweep(ac, table, tcp, DeviceId::Table))
            })
            .into_iter()
            .collect();
        sweeps
            .into_iter()
            .map(|s| s.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Vec<_>>()
    });
    for stopped in stopped_by_transport {
        let unexpected: Vec<&String> = stopped.iter().filter(|s| !stops_by_design(s)).collect();
        assert!(unexpected.is_empty(), "{unexpected:#?}");
        // close and disable at three places each: every one stopped, and was resumed.
        assert_eq!(stopped.len(), 6, "{stopped:#?}");
    }
}

#[test]
fn every_fault_on_the_smc100_profile_over_serial_and_tcp() {
    table_sweep("smc100");
}

#[test]
fn every_fault_on_the_pi_gcs2_profile_over_serial_and_tcp() {
    table_sweep("pi-gcs2");
}

#[test]
fn every_fault_on_the_aerotech_ascii_profile_over_serial_and_tcp() {
    table_sweep("aerotech-ascii");
}

#[test]
fn every_fault_on_the_esp301_profile_over_serial_and_tcp() {
    table_sweep("esp301");
}

/// The autocollimators' faults with the bundled `elcomat3000` profile, and with the same
/// protocol read from a profile file (served from the profile, not the hand-written
/// ELCOMAT simulation), on a table of another make.
#[test]
fn every_fault_on_the_autocollimator_profiles_over_serial_and_tcp() {
    let table = Profile::load("pi-gcs2").unwrap();
    let text = BUNDLED
        .iter()
        .find(|(n, _, _)| *n == "elcomat3000")
        .map(|(_, _, t)| t.replace("profile = \"elcomat3000\"", "profile = \"my-elcomat\""))
        .unwrap();
    let profiles = [
        Profile::load("elcomat3000").unwrap(),
        Profile::parse(&text, "my-elcomat.toml").unwrap(),
    ];
    // The four sweeps at once (see table_sweep).
    let stopped_by_sweep = std::thread::scope(|scope| {
        let sweeps: Vec<_> = profiles
            .iter()
            .flat_map(|ac| [false, true].map(|tcp| (ac, tcp)))
            .map(|(ac, tcp)| {
                let table = &table;
                scope.spawn(move || sweep(ac, table, tcp, DeviceId::Ac(1)))
            })
            .collect();
        sweeps
            .into_iter()
            .map(|s| s.join().unwrap_or_else(|e| std::panic::resume_unwind(e)))
            .collect::<Vec<_>>()
    });
    for stopped in stopped_by_sweep {
        let unexpected: Vec<&String> = stopped.iter().filter(|s| !stops_by_design(s)).collect();
        assert!(unexpected.is_empty(), "{unexpected:#?}");
        assert_eq!(stopped.len(), 3, "close at three places: {stopped:#?}");
    }
}

// ------------------------------------------------ transcripts from the command sets

fn fast() -> QueryOptions {
    QueryOptions::new(Duration::from_millis(30), 3)
}

fn table_over(name: &str, stream: ScriptedStream) -> ProfileTable<StreamTransport<ScriptedStream>> {
    ProfileTable::new(
        StreamTransport::new("mem:table", stream),
        &Profile::load(name).unwrap(),
        TableOptions::new(fast()).with_poll_interval(Duration::from_millis(1)),
    )
    .unwrap()
}

/// A move of each bundled table profile, as its maker's command set has it: the exact
/// bytes sent, in order, and the position read back.
#[test]
fn a_move_speaks_each_makers_command_set() {
    // PI GCS 2: MOV gives no reply, ERR? 0 means none, ONT? answers 1=<0|1>, POS? 1=<pos>.
    let pi = ScriptedStream::new()
        .expect("ONT? 1\n", "1=1\n")
        .expect("MOV 1 22.5\n", "")
        .expect("ERR?\n", "0\n")
        .expect("ONT? 1\n", "1=0\n")
        .expect("ONT? 1\n", "1=1\n")
        .expect("POS? 1\n", "1=22.50001\n");
    // Aerotech Ensemble ASCII: every command answered, `%` first; AXISSTATUS bits 0
    // Enabled, 1 Homed, 2 InPosition, 3 MoveActive (7 ready, 11 moving).
    let aerotech = ScriptedStream::new()
        .expect("AXISSTATUS(@0)\n", "%7\n")
        .expect("MOVEABS @0 22.5 F10\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("AXISSTATUS(@0)\n", "%11\n")
        .expect("AXISSTATUS(@0)\n", "%7\n")
        .expect("PFBKPROG(@0)\n", "%22.500010\n");
    // Newport ESP301: commands end with CR, replies with CR LF; 1MD? 1 done, 0 moving.
    // `0` after TE?'s `0` cannot be told from a stale copy of it: the controller is
    // brought back in step (VE?) and asked again.
    let esp = ScriptedStream::new()
        .expect("1MD?\r", "1\r\n")
        .expect("1PA22.5\r", "")
        .expect("TE?\r", "0\r\n")
        .expect("1MD?\r", "0\r\n")
        .expect("VE?\r", "ESP301 Version 3.0.1 6/1/99\r\n")
        .expect("1MD?\r", "0\r\n")
        .expect("1MD?\r", "1\r\n")
        .expect("1TP?\r", "22.50001\r\n");
    // Newport SMC100: 1PA gives no reply, 1TE @ none, 1TS state 33 ready, 28 moving.
    let smc = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA22.5\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000028\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1TP\r\n", "1TP22.50001\r\n");
    for (name, stream, sent) in [
        (
            "pi-gcs2",
            pi,
            "ONT? 1\nMOV 1 22.5\nERR?\nONT? 1\nONT? 1\nPOS? 1\n",
        ),
        (
            "aerotech-ascii",
            aerotech,
            "AXISSTATUS(@0)\nMOVEABS @0 22.5 F10\nAXISFAULT(@0)\nAXISSTATUS(@0)\nAXISSTATUS(@0)\nPFBKPROG(@0)\n",
        ),
        (
            "esp301",
            esp,
            "1MD?\r1PA22.5\rTE?\r1MD?\rVE?\r1MD?\r1MD?\r1TP?\r",
        ),
        (
            "smc100",
            smc,
            "1TS\r\n1PA22.5\r\n1TE\r\n1TS\r\n1TS\r\n1TP\r\n",
        ),
    ] {
        let written = stream.written();
        let mut table = table_over(name, stream);
        assert_eq!(table.move_to(22.5).unwrap(), 22.50001, "{name}");
        assert_eq!(written.text(), sent, "{name}");
    }
}

/// What each maker's controller says when it refuses a move or reports a fault comes out
/// as one error naming it; a motion is never sent twice.
#[test]
fn refusals_and_faults_of_each_make_are_named() {
    // PI: error 5, a move on an unreferenced axis.
    let pi = ScriptedStream::new()
        .expect("ONT? 1\n", "1=1\n")
        .expect("MOV 1 45\n", "")
        .expect("ERR?\n", "5\n");
    let e = table_over("pi-gcs2", pi)
        .move_to(45.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("error 5") && e.contains("unreferenced axis"),
        "{e}"
    );
    // Aerotech: `#` answers a move that faulted.
    let aerotech = ScriptedStream::new()
        .expect("AXISSTATUS(@0)\n", "%7\n")
        .expect("MOVEABS @0 45 F10\n", "#\n");
    let written = aerotech.written();
    let e = table_over("aerotech-ascii", aerotech)
        .move_to(45.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("refused") && e.contains("`#`"), "{e}");
    assert_eq!(written.text().matches("MOVEABS").count(), 1);
    // Aerotech prints AXISSTATUS as a signed register: -1675099646 is 0x9C280202, bit 0
    // (Enabled) clear: neither ready nor moving.
    let aerotech = ScriptedStream::new().expect("AXISSTATUS(@0)\n", "%-1675099646\n");
    let e = table_over("aerotech-ascii", aerotech)
        .state()
        .unwrap_err()
        .to_string();
    assert!(e.contains("neither ready nor moving"), "{e}");
    let aerotech = ScriptedStream::new().expect("AXISSTATUS(@0)\n", "%-2147483641\n"); // 0x80000007
    assert_eq!(
        table_over("aerotech-ascii", aerotech).state().unwrap(),
        TableState::Ready
    );
    // ESP301: error 113, axis 1 motor not enabled.
    let esp = ScriptedStream::new()
        .expect("1MD?\r", "1\r\n")
        .expect("1PA45\r", "")
        .expect("TE?\r", "113\r\n");
    let e = table_over("esp301", esp)
        .move_to(45.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("error 113") && e.contains("motor not enabled"),
        "{e}"
    );
}

/// Starting: the error latched before the session is read away first; PI switches the
/// servo on and references the axis only when `FRF?` says it is not; an Aerotech axis's
/// latched fault is acknowledged, and an axis at rest but not homed is homed; the ESP301,
/// which cannot tell, is homed on every start.
#[test]
fn starting_references_the_axis_as_each_make_allows() {
    let pi = ScriptedStream::new()
        .expect("ERR?\n", "0\n")
        .expect("SVO 1 1\n", "")
        .expect("ERR?\n", "0\n")
        .expect("ONT? 1\n", "1=1\n")
        .expect("FRF? 1\n", "1=1\n")
        .expect(
            "*IDN?\n",
            "(c)2015 Physik Instrumente (PI) GmbH & Co. KG, C-863.11, 0115500028, 01.00.00.00\n",
        )
        .expect("FRF? 1\n", "1=1\n");
    let written = pi.written();
    table_over("pi-gcs2", pi).start().unwrap();
    // FRF?'s `1=1` after ONT?'s `1=1`: asked again once the controller is in step.
    assert_eq!(
        written.text(),
        "ERR?\nSVO 1 1\nERR?\nONT? 1\nFRF? 1\n*IDN?\nFRF? 1\n"
    );
    // Aerotech: AXISSTATUS 2097157 (0x200005: Enabled, InPosition, bit 21; Homed clear)
    // is at rest but not homed, and is homed before anything moves; 0x80000007 after the
    // home search has Homed set.
    let aerotech = ScriptedStream::new()
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("FAULTACK @0\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("WAIT MODE NOWAIT\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("ENABLE @0\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("AXISSTATUS(@0)\n", "%2097157\n")
        .expect("HOME @0\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%0\n")
        .expect("AXISSTATUS(@0)\n", "%-2147483641\n");
    let written = aerotech.written();
    table_over("aerotech-ascii", aerotech).start().unwrap();
    assert_eq!(
        written.text().matches("HOME @0\n").count(),
        1,
        "{}",
        written.text()
    );
    let aerotech = ScriptedStream::new().expect("AXISSTATUS(@0)\n", "%2097157\n");
    assert_eq!(
        table_over("aerotech-ascii", aerotech).state().unwrap(),
        TableState::NotReferenced
    );
    let esp = ScriptedStream::new()
        .expect("TE?\r", "0\r\n")
        .expect("1MO\r", "")
        .expect("TE?\r", "0\r\n")
        .expect("1MD?\r", "1\r\n")
        .expect("1OR\r", "")
        .expect("TE?\r", "0\r\n")
        .expect("1MD?\r", "0\r\n")
        .expect("VE?\r", "ESP301 Version 3.0.1 6/1/99\r\n")
        .expect("1MD?\r", "0\r\n")
        .expect("1MD?\r", "1\r\n");
    let written = esp.written();
    table_over("esp301", esp).start().unwrap();
    assert_eq!(
        written.text(),
        "TE?\r1MO\rTE?\r1MD?\r1OR\rTE?\r1MD?\rVE?\r1MD?\r1MD?\r"
    );
}

/// A reply of the right form with a wrong value (a sign lost, X and Y exchanged, a digit
/// dropped) at the second stop of a run: refused by the agreement at its stop. The check
/// sees it: told a noise wide enough to let it through (100″), the same run stores it
/// off its stop.
#[test]
fn a_wrong_value_in_the_right_form_is_refused_at_its_stop() {
    use polycal::lab::sim::SimStream;
    for kind in [FaultKind::SignFlip, FaultKind::SwapXy, FaultKind::DropDigit] {
        let mut off = Vec::new();
        for stated in [SIGMA, 100.0] {
            // The first reading at step 1, where autocollimator 1 reads −5.21″.
            let fault = Fault::new(kind, DeviceId::Ac(1)).with_after(2);
            let ac = Profile::load("elcomat3000").unwrap();
            let table = Profile::load("smc100").unwrap();
            let devices = Devices::new(config(vec![fault], &ac, &table)).unwrap();
            let truth = devices.truth();
            let Devices {
                autocollimators,
                table: t,
                ..
            } = devices;
            let Ok([ac1, ac2]) = <[_; 2]>::try_from(autocollimators) else {
                panic!("two autocollimators")
            };
            let q = QueryOptions::new(Duration::from_millis(30), 3);
            let driver = |name: &str, e| {
                ProfileAutocollimator::elcomat3000(StreamTransport::new(name, SimStream::new(e)), q)
                    .with_drain(Duration::ZERO)
            };
            let (mut a1, mut a2) = (driver("mem:ac1", ac1), driver("mem:ac2", ac2));
            let mut tb = ProfileTable::smc100(
                StreamTransport::new("mem:table", SimStream::new(t)),
                TableOptions::new(q).with_poll_interval(Duration::from_millis(1)),
            );
            let dir = std::env::temp_dir().join(format!(
                "polycal-value-fault-{}-{}-{stated}",
                std::process::id(),
                kind.as_str()
            ));
            let _ = std::fs::remove_dir_all(&dir);
            let settings = RunSettings::new(FACES, 1)
                .with_closing(true)
                .with_reading_noise_arcsec(stated);
            let mut run =
                RunDir::open(&dir, &settings, &Ports::new(["a", "b"], "c"), false).unwrap();
            let outcome = run::measure(
                &mut run,
                Instruments::new(vec![&mut a1, &mut a2], &mut tb),
                &StopFlag::new(),
                None,
                &mut |_| {},
            )
            .unwrap();
            run.finish(&outcome).unwrap();
            assert_eq!(outcome, Outcome::Completed, "{kind:?}");
            let set = MeasurementSet::read_path(&dir.join(run::MEASUREMENTS), None).unwrap();
            off.push(
                set.readings
                    .iter()
                    .filter(|r| {
                        let want = expected_at(&truth, r.step, r.ac, r.encoder_degrees.unwrap());
                        (r.reading_arcsec - want).abs() > 6.0 * SIGMA
                    })
                    .count(),
            );
            std::fs::remove_dir_all(&dir).unwrap();
        }
        assert_eq!(off[0], 0, "{kind:?}: refused at its stop");
        assert_eq!(off[1], 1, "{kind:?}: the check sees it when let through");
    }
}
