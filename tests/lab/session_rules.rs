//! The run's rules through the session alone (`polycal::lab::Session`, docs/FORMAT.md
//! §7.6): scripted events, no port, no clock, no disk — each rule decided as `polycal
//! run` decides it (the same session drives `polycal run`; tests/lab/instrument_*.rs and
//! tests/sweeps/instrument_*.rs run it through the instruments).
//!
//! The instruments are a few lines of physics written here (paper eq. (2): encoder error
//! + face angle deviation + setup error), not polycal's simulator.

use polycal::lab::run::{MemoryStore, Mounting, Record, RunSettings, RunSoFar, Store};
use polycal::lab::{AcReading, Action, Event, LogRecord, Outcome, Session};

const FACES: usize = 8;

/// A polygon on a table, two autocollimators at faces 1 and 2.
#[derive(Clone)]
struct Physics {
    table_deg: f64,
    /// How many faces the polygon is turned on the table from its first mounting.
    turned: usize,
    /// The two autocollimators' cables swapped at the driver.
    swapped: bool,
    /// Added to autocollimator 1's X, arcsec.
    offset_ac1: f64,
    state: u64,
}

impl Physics {
    fn new() -> Physics {
        Physics {
            table_deg: 0.0,
            turned: 0,
            swapped: false,
            offset_ac1: 0.0,
            state: 0x2545_f491_4f6c_dd1d,
        }
    }

    /// ±0.005″ of noise.
    fn noise(&mut self) -> f64 {
        self.state ^= self.state << 13;
        self.state ^= self.state >> 7;
        self.state ^= self.state << 17;
        ((self.state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.01
    }

    /// What autocollimator `ac` sees: the step's encoder error, the face's angle
    /// deviation and pyramidal error (Y), its setup error.
    fn reply(&mut self, ac: u32) -> AcReading {
        let ac = if self.swapped { 3 - ac } else { ac };
        let step = (self.table_deg * FACES as f64 / 360.0).round() as usize % FACES;
        let face = (step + ac as usize - 1 + self.turned) % FACES + 1;
        let encoder = 0.6 * (2.0 * std::f64::consts::PI * step as f64 / FACES as f64).sin();
        let face_deviation = [0.0, 0.4, -0.3, 0.9, 0.2, -0.5, 0.7, 0.0][face - 1];
        let setup = [0.8, -1.1][ac as usize - 1];
        let offset = if ac == 1 { self.offset_ac1 } else { 0.0 };
        let x = encoder + face_deviation + setup + offset + self.noise();
        let y = [3.0, -2.0, 5.0, 1.0, -4.0, 2.5, -1.5, 0.5][face - 1] + self.noise();
        AcReading::new(3, x, Some(y))
    }
}

/// How a scripted session went.
struct Ran {
    outcome: Outcome,
    logged: Vec<LogRecord>,
    halted: bool,
}

/// Drives `session` to its end: the physics answers, `tamper` may change a reply (the
/// autocollimator, the table angle, the reply), `remount` is the operator (may change
/// the physics; returns the confirmation), `stop_after` interrupts after that many
/// readings kept.
fn drive(
    session: &mut Session,
    store: &mut MemoryStore,
    physics: &mut Physics,
    tamper: &mut dyn FnMut(u32, f64, AcReading) -> AcReading,
    remount: &mut dyn FnMut(&mut Physics) -> bool,
    stop_after: Option<usize>,
) -> Ran {
    let mut t = 0.0;
    let mut logged = Vec::new();
    let mut halted = false;
    let mut kept = 0;
    loop {
        t += 0.1;
        let event = match session.poll() {
            Action::Move { to_deg } => {
                physics.table_deg = to_deg;
                Event::Moved { at_deg: to_deg }
            }
            Action::Position => Event::Position {
                deg: physics.table_deg,
            },
            Action::Read { ac } => {
                let reply = physics.reply(ac);
                Event::Read(tamper(ac, physics.table_deg, reply))
            }
            Action::Wait { .. } => Event::Waited,
            Action::Remount(_) => Event::Remounted {
                confirmed: remount(physics),
            },
            Action::Keep(record) => {
                if matches!(record, Record::Reading(_)) {
                    kept += 1;
                }
                store.keep(&record).unwrap();
                Event::Kept
            }
            Action::Log(line) => {
                logged.push(line);
                continue;
            }
            Action::Halt => {
                halted = true;
                continue;
            }
            Action::Finished(outcome) => {
                return Ran {
                    outcome,
                    logged,
                    halted,
                };
            }
            _ => continue,
        };
        session.tell(t, event).unwrap();
        if stop_after == Some(kept) {
            session.interrupt();
        }
    }
}

fn untouched(_: u32, _: f64, reply: AcReading) -> AcReading {
    reply
}

fn settings(cycles: u32) -> RunSettings {
    RunSettings::new(FACES, cycles).with_reading_noise_arcsec(0.02)
}

/// A whole run of `cycles` cycles, kept in memory.
fn whole_run(cycles: u32) -> MemoryStore {
    let mut store = MemoryStore::new(settings(cycles));
    let mut session = Session::new(store.so_far().unwrap(), 0.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut Physics::new(),
        &mut untouched,
        &mut |_| true,
        None,
    );
    assert_eq!(ran.outcome, Outcome::Completed);
    assert!(!ran.halted, "a completed session does not halt the table");
    store
}

/// One cycle of a fresh run, its replies through `tamper`: how it went, what was kept and
/// the session.
fn one_cycle(
    tamper: &mut dyn FnMut(u32, f64, AcReading) -> AcReading,
) -> (Ran, MemoryStore, Session) {
    let mut store = MemoryStore::new(settings(1));
    let mut session = Session::new(store.so_far().unwrap(), 0.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut Physics::new(),
        tamper,
        &mut |_| true,
        None,
    );
    (ran, store, session)
}

#[test]
fn a_clean_run_keeps_every_reading_in_the_runs_order() {
    let store = whole_run(2);
    let places: Vec<(u32, usize, u32)> = store
        .run
        .readings
        .iter()
        .map(|r| (r.cycle, r.step, r.ac))
        .collect();
    let mut expected = Vec::new();
    for cycle in 1..=2 {
        for step in 0..FACES {
            expected.extend([(cycle, step, 1), (cycle, step, 2)]);
        }
    }
    assert_eq!(places, expected);
    // Every reading with the table where it was measured and the face it saw.
    for r in &store.run.readings {
        assert_eq!(r.encoder_degrees, Some(r.step as f64 * 45.0));
        assert_eq!(r.face, (r.step + r.ac as usize - 1) % FACES + 1);
    }
    assert!(store.remeasured.is_empty() && store.suspect.is_empty());
}

#[test]
fn every_stop_is_approached_from_the_cycles_direction() {
    let mut store = MemoryStore::new(settings(1));
    let mut session = Session::new(store.so_far().unwrap(), 0.0);
    let mut physics = Physics::new();
    let mut moves = Vec::new();
    loop {
        let event = match session.poll() {
            Action::Move { to_deg } => {
                moves.push(to_deg);
                physics.table_deg = to_deg;
                Event::Moved { at_deg: to_deg }
            }
            Action::Read { ac } => Event::Read(physics.reply(ac)),
            Action::Keep(record) => {
                store.keep(&record).unwrap();
                Event::Kept
            }
            Action::Finished(outcome) => {
                assert_eq!(outcome, Outcome::Completed);
                break;
            }
            _ => continue,
        };
        session.tell(0.0, event).unwrap();
    }
    // A pre-position 0.5° short of the first stop, then each stop from below.
    assert_eq!(moves[..3], [-0.5, 0.0, 45.0]);
    assert!(moves.windows(2).all(|w| w[1] > w[0]), "{moves:?}");
}

#[test]
fn a_stale_reply_is_refused_and_the_reading_taken_from_the_replies_after_it() {
    // Autocollimator 1's first reply at step 3 is its last reply at step 2, again.
    let mut last_at_2: Option<AcReading> = None;
    let mut at_3 = 0;
    let mut tamper = |ac: u32, deg: f64, reply: AcReading| {
        if ac != 1 {
            return reply;
        }
        if deg == 90.0 {
            last_at_2 = Some(reply);
        }
        if deg == 135.0 {
            at_3 += 1;
            if at_3 == 1 {
                return last_at_2.unwrap();
            }
        }
        reply
    };
    let (ran, store, session) = one_cycle(&mut tamper);
    assert_eq!(ran.outcome, Outcome::Completed);
    let refused: Vec<&LogRecord> = ran.logged.iter().filter(|l| l.event == "refused").collect();
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(refused[0].text.contains("stale: the same X, Y and status"));
    assert_eq!(refused[0].device, "ac1");
    let kept = store
        .run
        .readings
        .iter()
        .find(|r| (r.step, r.ac) == (3, 1))
        .unwrap();
    // Encoder 0.6·sin(135°) + face 4's 0.9 + setup 0.8, within the noise.
    let truth = 0.6 * (135f64).to_radians().sin() + 0.9 + 0.8;
    assert!((kept.reading_arcsec - truth).abs() < 0.01, "{kept:?}");
    assert_eq!(session.refused(), 1);
}

#[test]
fn a_late_reply_from_another_query_is_outvoted_and_logged() {
    // Autocollimator 2's first reply at step 5 is autocollimator 1's (a reply late on a
    // shared line): the right form, the wrong value.
    let mut first = true;
    let mut tamper = |ac: u32, deg: f64, reply: AcReading| {
        if ac == 2 && deg == 225.0 && first {
            first = false;
            let mut p = Physics::new();
            p.table_deg = deg;
            return p.reply(1);
        }
        reply
    };
    let (ran, store, _) = one_cycle(&mut tamper);
    assert_eq!(ran.outcome, Outcome::Completed);
    let refused: Vec<&LogRecord> = ran.logged.iter().filter(|l| l.event == "refused").collect();
    assert_eq!(refused.len(), 1, "{refused:?}");
    assert!(
        refused[0]
            .text
            .contains("does not agree with the readings after it"),
        "{}",
        refused[0].text
    );
    let kept = store
        .run
        .readings
        .iter()
        .find(|r| (r.step, r.ac) == (5, 2))
        .unwrap();
    let truth = 0.6 * (225f64).to_radians().sin() + 0.7 - 1.1;
    assert!((kept.reading_arcsec - truth).abs() < 0.01, "{kept:?}");
}

#[test]
fn a_sign_flip_at_the_first_query_is_measured_again_once_the_noise_is_known() {
    // Autocollimator 1 reads about 0.03″ at step 0; its very first reply comes with X's
    // sign flipped: within the stated tolerance (5·√2·0.02″) of the next reply, so the
    // stop's mean, about 0″, is stored — some 15σ of the true noise (±0.005″ uniform)
    // off. The check after a later cycle, once the repeats measured the noise, finds it
    // and measures the stop again.
    let mut store = MemoryStore::new(settings(3));
    let mut session = Session::new(store.so_far().unwrap(), 0.0);
    let mut physics = Physics::new();
    physics.offset_ac1 = -0.77;
    let mut first = true;
    let mut tamper = |ac: u32, _: f64, reply: AcReading| {
        if ac == 1 && std::mem::take(&mut first) {
            return AcReading::new(reply.status, -reply.x_arcsec, reply.y_arcsec);
        }
        reply
    };
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut tamper,
        &mut |_| true,
        None,
    );
    assert_eq!(ran.outcome, Outcome::Completed);
    let again: Vec<_> = store
        .remeasured
        .iter()
        .map(|r| (r.cycle, r.step, r.ac))
        .collect();
    assert_eq!(again, [(1, 0, 1)], "{:?}", store.remeasured);
    // What was stored first: the mean of the flipped reply and the next, about 0″.
    assert!(
        store.remeasured[0].first_arcsec.abs() < 0.01,
        "{:?}",
        store.remeasured
    );
    let kept = store
        .run
        .readings
        .iter()
        .find(|r| (r.cycle, r.step, r.ac) == (1, 0, 1))
        .unwrap();
    assert!((kept.reading_arcsec - 0.03).abs() < 0.006, "{kept:?}");
    assert!(store.suspect.is_empty());
}

#[test]
fn readings_that_never_agree_end_the_session_and_keep_nothing_of_that_stop() {
    let mut n = 0.0;
    let mut tamper = |ac: u32, deg: f64, reply: AcReading| {
        if ac == 1 && deg == 180.0 {
            n += 1.0;
            return AcReading::new(3, reply.x_arcsec + n, reply.y_arcsec);
        }
        reply
    };
    let (ran, store, _) = one_cycle(&mut tamper);
    let Outcome::InstrumentError(message) = ran.outcome else {
        panic!("{:?}", ran.outcome)
    };
    assert!(
        message.starts_with("autocollimator 1 (ac1) at cycle 1, step 4: no 2 consecutive"),
        "{message}"
    );
    assert!(ran.halted, "the table is stopped");
    assert_eq!(
        store.run.readings.len(),
        8,
        "steps 0 … 3, both autocollimators"
    );
}

#[test]
fn resuming_with_the_ports_swapped_is_refused_at_the_last_stop() {
    let mut store = MemoryStore::new(settings(1));
    let mut session = Session::new(store.so_far().unwrap(), 0.0);
    let mut physics = Physics::new();
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut untouched,
        &mut |_| true,
        Some(8),
    );
    assert_eq!(ran.outcome, Outcome::Interrupted);
    assert!(ran.halted);
    assert_eq!(store.run.readings.len(), 8);

    // Resumed with the cables swapped: the last stop (step 3) read again tells.
    physics.swapped = true;
    let mut session = Session::new(store.so_far().unwrap(), 100.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut untouched,
        &mut |_| true,
        None,
    );
    let Outcome::InstrumentError(message) = ran.outcome else {
        panic!("{:?}", ran.outcome)
    };
    assert!(
        message.contains("ac1 reads what ac2 stored") && message.contains("ports look swapped"),
        "{message}"
    );
    assert_eq!(store.run.readings.len(), 8, "nothing new kept");
    let compared: Vec<&LogRecord> = ran
        .logged
        .iter()
        .filter(|l| l.event == "compared")
        .collect();
    assert_eq!(compared.len(), 1);
    assert!(compared[0].text.contains("read again on resuming"));

    // With the cables as they were, the run completes without a reading twice.
    physics.swapped = false;
    let mut session = Session::new(store.so_far().unwrap(), 200.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut untouched,
        &mut |_| true,
        None,
    );
    assert_eq!(ran.outcome, Outcome::Completed);
    assert_eq!(store.run.readings.len(), 16);
}

#[test]
fn a_forgotten_remount_is_refused_before_any_reading_of_the_mounting() {
    let mut store = whole_run(1);
    store
        .run
        .add_mounting(Mounting::new(2).with_face_shift(3))
        .unwrap();
    // The operator confirms, but the polygon stays as it was.
    let mut physics = Physics::new();
    let mut asked = 0;
    let mut session = Session::new(store.so_far().unwrap(), 10.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut untouched,
        &mut |_| {
            asked += 1;
            true
        },
        None,
    );
    assert_eq!(asked, 1);
    let Outcome::InstrumentError(message) = ran.outcome else {
        panic!("{:?}", ran.outcome)
    };
    assert!(
        message.contains("the polygon was not remounted"),
        "{message}"
    );
    assert!(store.run.readings.iter().all(|r| r.setup == 1));
    assert!(store.run.awaits_remount(), "the remount is asked for again");

    // Remounted as stated (turned three faces): measured.
    let mut session = Session::new(store.so_far().unwrap(), 20.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut physics,
        &mut untouched,
        &mut |p| {
            p.turned = 3;
            true
        },
        None,
    );
    assert_eq!(ran.outcome, Outcome::Completed);
    let second: Vec<_> = store.run.readings.iter().filter(|r| r.setup == 2).collect();
    assert_eq!(second.len(), 16);
    assert!(
        second
            .iter()
            .all(|r| r.face == (r.step + r.ac as usize - 1 + 3) % FACES + 1)
    );
    assert!(
        ran.logged
            .iter()
            .any(|l| l.event == "remounted" && l.text.contains("confirmed"))
    );
}

#[test]
fn a_remount_declined_ends_the_session_as_interrupted() {
    let mut store = whole_run(1);
    store
        .run
        .add_mounting(Mounting::new(2).with_face_shift(3))
        .unwrap();
    let mut session = Session::new(store.so_far().unwrap(), 10.0);
    let ran = drive(
        &mut session,
        &mut store,
        &mut Physics::new(),
        &mut untouched,
        &mut |_| false,
        None,
    );
    assert_eq!(ran.outcome, Outcome::Interrupted);
    assert!(store.run.awaits_remount());
}

#[test]
fn an_event_that_does_not_answer_the_action_is_refused_and_changes_nothing() {
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    let first = session.poll();
    assert!(matches!(first, Action::Move { .. }), "{first:?}");
    let e = session
        .tell(0.0, Event::Read(AcReading::new(3, 0.0, None)))
        .unwrap_err();
    assert!(
        e.to_string().starts_with("the session asked for a move to"),
        "{e}"
    );
    assert_eq!(session.poll(), first, "the same action again");
}

#[test]
fn a_number_that_is_not_finite_is_refused_and_changes_nothing() {
    // A driver of the lab's own that reports a NaN position (an encoder read as garbage),
    // an infinite reading or a NaN time is refused at that event: the action is asked
    // again, and what is kept in the end holds only the finite values told after it.
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    let mut store = MemoryStore::new(settings(1));
    let mut physics = Physics::new();
    let mut refused = Vec::new();
    let mut t = 0.0;
    loop {
        t += 0.1;
        let action = session.poll();
        let (bad, good) = match &action {
            Action::Move { to_deg } => {
                physics.table_deg = *to_deg;
                (
                    Some(Event::Moved { at_deg: f64::NAN }),
                    Event::Moved { at_deg: *to_deg },
                )
            }
            Action::Position => (
                Some(Event::Position { deg: f64::INFINITY }),
                Event::Position {
                    deg: physics.table_deg,
                },
            ),
            Action::Read { ac } => {
                let reply = physics.reply(*ac);
                let bad = if refused.len() % 2 == 0 {
                    AcReading::new(reply.status, f64::NAN, reply.y_arcsec)
                } else {
                    AcReading::new(reply.status, reply.x_arcsec, Some(f64::NEG_INFINITY))
                };
                (Some(Event::Read(bad)), Event::Read(reply))
            }
            Action::Wait { .. } => (None, Event::Waited),
            Action::Keep(record) => {
                store.keep(record).unwrap();
                (None, Event::Kept)
            }
            Action::Finished(outcome) => {
                assert_eq!(*outcome, Outcome::Completed);
                break;
            }
            _ => continue,
        };
        if let Some(bad) = bad {
            let e = session.tell(t, bad).unwrap_err();
            assert!(e.to_string().contains("is not a finite number"), "{e}");
            assert_eq!(session.poll(), action, "the same action again");
            // and a finite event at a time that is not one
            let e = session.tell(f64::NAN, Event::Waited).unwrap_err();
            assert!(e.to_string().starts_with("the session asked for"), "{e}");
            refused.push(e);
        }
        session.tell(t, good).unwrap();
    }
    assert!(refused.len() >= 2 * FACES, "{}", refused.len());
    let readings = &store.run.readings;
    assert!(!readings.is_empty());
    for r in readings {
        assert!(r.encoder_degrees.is_some_and(f64::is_finite), "{r:?}");
        assert!(r.reading_arcsec.is_finite(), "{r:?}");
        assert!(r.reading_y_arcsec.is_none_or(f64::is_finite), "{r:?}");
    }
    // The time refused on its own, with an event that answers the action.
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    let Action::Move { to_deg } = session.poll() else {
        panic!()
    };
    let e = session
        .tell(f64::INFINITY, Event::Moved { at_deg: to_deg })
        .unwrap_err();
    assert!(
        e.to_string().contains("whose time is not a finite number"),
        "{e}"
    );
    assert_eq!(session.poll(), Action::Move { to_deg });
}

#[test]
fn a_table_that_reports_itself_off_the_stop_ends_the_session_with_nothing_stored_there() {
    // A driver of the lab's own whose table reports 0.002° off the commanded 90° (beyond
    // the 0.001° a stop allows, which polycal's own drivers hold a move to): the session
    // ends naming the table and both positions; the stops before are kept, nothing at 90°.
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    let mut store = MemoryStore::new(settings(1));
    let mut physics = Physics::new();
    let mut t = 0.0;
    let outcome = loop {
        t += 0.1;
        let event = match session.poll() {
            Action::Move { to_deg } => {
                physics.table_deg = to_deg;
                let off = if to_deg == 90.0 { 0.002 } else { 0.000_9 };
                Event::Moved {
                    at_deg: to_deg + off,
                }
            }
            Action::Read { ac } => Event::Read(physics.reply(ac)),
            Action::Keep(record) => {
                store.keep(&record).unwrap();
                Event::Kept
            }
            Action::Finished(outcome) => break outcome,
            _ => continue,
        };
        session.tell(t, event).unwrap();
    };
    let Outcome::InstrumentError(message) = outcome else {
        panic!("{outcome:?}")
    };
    assert_eq!(
        message,
        "rotary table at table: the table stopped at 90.002°, not at the commanded 90° (beyond 0.001°) (reported by its driver)"
    );
    let steps: Vec<usize> = store.run.readings.iter().map(|r| r.step).collect();
    assert_eq!(
        steps,
        [0, 0, 1, 1],
        "the stops at 0° and 45° kept, within 0.001°"
    );
}

#[test]
fn a_failed_instrument_or_store_ends_the_session_naming_it() {
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    assert!(matches!(session.poll(), Action::Move { .. }));
    let failure = polycal::lab::InstrumentError::Closed {
        port: "lab:table".into(),
        context: "moving".into(),
    };
    session.tell(0.0, Event::Failed(failure)).unwrap();
    assert_eq!(session.poll(), Action::Halt);
    let Action::Finished(Outcome::InstrumentError(message)) = session.poll() else {
        panic!()
    };
    assert!(message.starts_with("rotary table at "), "{message}");

    // A store that cannot keep a reading: the session ends at once, its message given.
    let mut session = Session::new(RunSoFar::new(settings(1)), 0.0);
    let mut physics = Physics::new();
    let outcome = loop {
        let event = match session.poll() {
            Action::Move { to_deg } => {
                physics.table_deg = to_deg;
                Event::Moved { at_deg: to_deg }
            }
            Action::Read { ac } => Event::Read(physics.reply(ac)),
            Action::Keep(_) => Event::NotKept("the database is read-only".into()),
            Action::Finished(outcome) => break outcome,
            _ => continue,
        };
        session.tell(0.0, event).unwrap();
    };
    assert_eq!(
        outcome,
        Outcome::FileError("the database is read-only".into())
    );
}
