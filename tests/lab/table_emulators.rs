//! Every make homed (issue 54): each bundled table profile drives a controller written
//! by hand from its maker's manual (`tests/lab/emulator_support/`), from each of the
//! controller's power-on states, over a pseudo-terminal and over TCP. The driver starts
//! the axis and moves it once: either a home search came before every motion command
//! that needed one and the move landed, physically, where it was commanded, or the
//! start was refused with an error naming the cause and nothing moved.

#![cfg(unix)]

use std::time::Duration;

use crate::emulator_support::{
    self, HOME_MARK_DEG, Log, Record, aerotech, esp301, pi_gcs2, smc100,
};
use polycal::lab::driver::{ProfileTable, TableOptions};
use polycal::lab::profile::Profile;
use polycal::lab::scripted::ScriptedStream;
use polycal::lab::serial::SerialTransport;
use polycal::lab::sim::SimDevice;
use polycal::lab::tcp::TcpTransport;
use polycal::lab::traffic::{LoggedTransport, RunClock, TrafficLog};
use polycal::lab::transport::{StreamTransport, Transport};
use polycal::lab::{QueryOptions, RotaryTable};

/// Where the first move goes, degrees.
pub(crate) const TARGET: f64 = 22.5;

/// What a session from one power-on state must end with.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Expect {
    /// Started and moved to [`TARGET`]; with `home`, a home search first.
    Lands { home: bool },
    /// The start refused with an error containing every one of these; nothing moved.
    Refused(&'static [&'static str]),
}

/// Short deadlines: the emulators answer at once, but a machine busy with other tests
/// must not starve one for three deadlines in a row.
pub(crate) fn options() -> TableOptions {
    TableOptions::new(QueryOptions::new(Duration::from_millis(100), 2))
        .with_poll_interval(Duration::from_millis(5))
        .with_motion_timeout(Duration::from_secs(5))
}

fn open(path: &str, profile: &Profile) -> Box<dyn Transport> {
    if path.starts_with("tcp://") {
        Box::new(TcpTransport::connect(path).unwrap())
    } else {
        Box::new(SerialTransport::open(path, &profile.line).unwrap())
    }
}

/// One session: the driver of `profile` starts the table and moves it to [`TARGET`];
/// what it returned and what the controller recorded.
fn session(
    profile: &Profile,
    device: Box<dyn SimDevice>,
    log: &Log,
    tcp: bool,
) -> (Result<f64, String>, Record) {
    let (lab, path) = emulator_support::serve(device, tcp);
    let mut table = ProfileTable::new(open(&path, profile), profile, options()).unwrap();
    let outcome = table
        .start()
        .and_then(|()| table.move_to(TARGET))
        .map_err(|e| e.to_string());
    drop(table);
    lab.shutdown();
    (outcome, log.record())
}

/// Checks one session's outcome against what its state expects.
pub(crate) fn check(what: &str, expect: Expect, outcome: &Result<f64, String>, record: &Record) {
    assert!(
        record.unknown.is_empty(),
        "{what}: commands the controller does not know: {:?}\n{:#?}",
        record.unknown,
        record.received
    );
    assert!(
        record.motions.iter().all(|m| m.referenced),
        "{what}: a motion command before the axis was referenced: {:#?}\n{:#?}",
        record.motions,
        record.received
    );
    match expect {
        Expect::Lands { home } => {
            let reported = outcome
                .as_ref()
                .unwrap_or_else(|e| panic!("{what}: {e}\n{:#?}", record.received));
            assert!(
                (reported - TARGET).abs() < 1e-3,
                "{what}: reported {reported}"
            );
            if home {
                assert!(
                    record.motions.first().is_some_and(|m| m.homes_before >= 1),
                    "{what}: no home search ended before the first motion command\n{:#?}",
                    record.received
                );
            }
            let landed = record.landings.first().copied();
            assert!(
                landed.is_some_and(|at| (at - (TARGET + HOME_MARK_DEG)).abs() < 1e-6),
                "{what}: the table landed at {landed:?}° physically, not at {TARGET}°\n{:#?}",
                record.received
            );
        }
        Expect::Refused(words) => {
            let message = match outcome {
                Err(message) => message,
                Ok(at) => panic!("{what}: moved to {at}°\n{:#?}", record.received),
            };
            for word in words {
                assert!(
                    message.contains(word),
                    "{what}: {word:?} not in {message:?}\n{:#?}",
                    record.received
                );
            }
            assert!(
                record.motions.is_empty() && record.landings.is_empty(),
                "{what}: a motion command was sent: {:#?}",
                record.motions
            );
        }
    }
}

/// Every state of one make over both transports, all sessions at once (each waits on its
/// controller far more than it computes).
fn every_state<S: Copy + std::fmt::Debug + Send + Sync>(
    profile: &str,
    states: &[(S, Expect)],
    device: fn(S, Log) -> Box<dyn SimDevice>,
) {
    let profile = Profile::load(profile).unwrap();
    std::thread::scope(|scope| {
        let sessions: Vec<_> = states
            .iter()
            .flat_map(|&(state, expect)| [false, true].map(|tcp| (state, expect, tcp)))
            .map(|(state, expect, tcp)| {
                let profile = &profile;
                scope.spawn(move || {
                    let what = format!(
                        "{} from {state:?} over {}",
                        profile.name,
                        if tcp { "TCP" } else { "a pseudo-terminal" }
                    );
                    let log = Log::default();
                    let (outcome, record) = session(profile, device(state, log.clone()), &log, tcp);
                    check(&what, expect, &outcome, &record);
                })
            })
            .collect();
        for s in sessions {
            s.join().unwrap_or_else(|e| std::panic::resume_unwind(e));
        }
    });
}

/// An Ensemble moves an axis that is not homed, from wherever it came up: the driver
/// must home it (and wait out `HOME`, which answers only when done), acknowledge a latched
/// fault first, and refuse an emergency stop that is still pressed.
#[test]
fn an_aerotech_axis_is_homed_before_its_first_move() {
    use aerotech::PowerOn::*;
    every_state(
        "aerotech-ascii",
        &[
            (Disabled, Expect::Lands { home: true }),
            (EnabledNotHomed, Expect::Lands { home: true }),
            (FaultLatched, Expect::Lands { home: true }),
            (
                EmergencyStop,
                Expect::Refused(&["error 2048 (EmergencyStop)"]),
            ),
            (Homed, Expect::Lands { home: false }),
        ],
        |state, log| Box::new(aerotech::Ensemble::new(state, log)),
    );
}

/// A C-863 refuses `MOV` with its servo off or its axis unreferenced (error 5): the driver
/// must switch the servo on, reference the axis, read away a motion error of an earlier
/// session, and refuse a stage whose motion error comes back.
#[test]
fn a_pi_axis_is_referenced_before_its_first_move() {
    use pi_gcs2::PowerOn::*;
    every_state(
        "pi-gcs2",
        &[
            (ServoOff, Expect::Lands { home: true }),
            (ServoOnNotReferenced, Expect::Lands { home: true }),
            (MotionErrorLatched, Expect::Lands { home: false }),
            (Jammed, Expect::Refused(&["error -1024", "motion error"])),
            (Referenced, Expect::Lands { home: false }),
        ],
        |state, log| Box::new(pi_gcs2::C863::new(state, log)),
    );
}

/// An ESP301 moves an axis that has not searched home, and cannot say whether it has:
/// the driver must switch the motor on and home it on every start, read away an error
/// queued by an earlier session, and refuse an amplifier fault that stays.
#[test]
fn an_esp301_axis_is_homed_before_its_first_move() {
    use esp301::PowerOn::*;
    every_state(
        "esp301",
        &[
            (MotorOff, Expect::Lands { home: true }),
            (MotorOnNotHomed, Expect::Lands { home: true }),
            (FollowingErrorLatched, Expect::Lands { home: true }),
            (
                AmplifierFault,
                Expect::Refused(&["error 102", "amplifier fault"]),
            ),
            (Homed, Expect::Lands { home: true }),
        ],
        |state, log| Box::new(esp301::Esp301::new(state, log)),
    );
}

/// An SMC100 refuses `PA` until referenced: the driver must home it when NOT REFERENCED,
/// and refuse DISABLE and a following error with what they are.
#[test]
fn an_smc100_axis_is_homed_before_its_first_move() {
    use smc100::PowerOn::*;
    every_state(
        "smc100",
        &[
            (NotReferenced, Expect::Lands { home: true }),
            // DISABLE is left to the operator, as the profile's message says: `1MM1`
            // is refused in NOT REFERENCED, so it cannot be sent on every start.
            (Disabled, Expect::Refused(&["DISABLE from READY", "1MM1"])),
            (
                FollowingError,
                Expect::Refused(&["fault", "following error"]),
            ),
            (Ready, Expect::Lands { home: false }),
        ],
        |state, log| Box::new(smc100::Smc100::new(state, log)),
    );
}

// ------------------------------------------- what the emulators asked of the driver

/// A writer into memory that a test reads afterwards.
#[derive(Clone, Default)]
struct Shared(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl std::io::Write for Shared {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn scripted(name: &str, stream: ScriptedStream, traffic: &Shared) -> ProfileTable<Logged> {
    let log = TrafficLog::new(traffic.clone(), RunClock::new(0.0));
    ProfileTable::new(
        LoggedTransport::new(StreamTransport::new("mem:table", stream), "table", log),
        &Profile::load(name).unwrap(),
        options(),
    )
    .unwrap()
}

type Logged = LoggedTransport<StreamTransport<ScriptedStream>>;

/// Byte for byte: an error latched before the session is read away before the first
/// command and noted `latched` in the traffic log (a PI's −1024 no longer passes for a
/// refusal of `SVO 1 1`); an Aerotech fault is acknowledged before the axis is enabled,
/// and one that stays refuses the start named by its bits.
#[test]
fn a_latched_error_is_read_away_and_a_fault_that_stays_is_named() {
    let pi = ScriptedStream::new()
        .expect("ERR?\n", "-1024\n")
        .expect("ERR?\n", "0\n")
        .expect("SVO 1 1\n", "")
        .expect("ERR?\n", "0\n")
        .expect("ONT? 1\n", "1=1\n")
        .expect("FRF? 1\n", "1=1\n")
        .expect(
            "*IDN?\n",
            "(c)2017 Physik Instrumente (PI) GmbH & Co. KG, C-863.11, 0117030512, 01.02.01.12\n",
        )
        .expect("FRF? 1\n", "1=1\n");
    let written = pi.written();
    let traffic = Shared::default();
    scripted("pi-gcs2", pi, &traffic).start().unwrap();
    assert_eq!(
        written.text(),
        "ERR?\nERR?\nSVO 1 1\nERR?\nONT? 1\nFRF? 1\n*IDN?\nFRF? 1\n"
    );
    let log = String::from_utf8(traffic.0.lock().unwrap().clone()).unwrap();
    assert!(
        log.lines()
            .any(|l| l.contains(r#""event":"latched","text":"-1024""#)),
        "{log}"
    );
    // AXISFAULT is a register: read twice alike, then FAULTACK; EmergencyStop and
    // OverCurrent stay.
    let aerotech = ScriptedStream::new()
        .expect("AXISFAULT(@0)\n", "%2050\n")
        .expect("AXISFAULT(@0)\n", "%2050\n")
        .expect("FAULTACK @0\n", "%\n")
        .expect("AXISFAULT(@0)\n", "%2050\n");
    let written = aerotech.written();
    let e = scripted("aerotech-ascii", aerotech, &Shared::default())
        .start()
        .unwrap_err()
        .to_string();
    assert!(e.contains("error 2050 (OverCurrent, EmergencyStop)"), "{e}");
    assert_eq!(
        written.text(),
        "AXISFAULT(@0)\nAXISFAULT(@0)\nFAULTACK @0\nAXISFAULT(@0)\n"
    );
}
