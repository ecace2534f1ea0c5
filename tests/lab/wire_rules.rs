//! The wire rules without the wire (issue 54, docs/FORMAT.md §7.7): the machines
//! `Exchange`, `AcWire` and `TableWire` told scripted events — a stale line, a late reply,
//! a lost acknowledgement, a table that never stops, a stop request — and decided as
//! polycal's own drivers decide; and a lab's own port (a `TcpStream` read by the test's
//! code, not polycal's transport) homing every make's unhomed axis through `TableWire`.

use std::collections::VecDeque;
use std::time::Duration;

use polycal::lab::driver::{
    AcOp, AcOutcome, AcWire, TableOp, TableOptions, TableOutcome, TableWire,
};
use polycal::lab::profile::Profile;
use polycal::lab::wire::{Wire, WireAction, WireEvent};
use polycal::lab::{InstrumentError, QueryOptions};

/// A device as a script: each command sent is answered by the lines given for it (in
/// order of sending); lines pushed as pending arrive before the next drain.
struct Script {
    /// (command expected, lines it produces)
    replies: VecDeque<(String, Vec<String>)>,
    /// Lines arrived and not read.
    pending: VecDeque<String>,
    sent: Vec<String>,
    notes: Vec<(String, String)>,
    now: f64,
    /// Seconds each action takes.
    step_seconds: f64,
}

impl Script {
    fn new(replies: &[(&str, &[&str])]) -> Script {
        Script {
            replies: replies
                .iter()
                .map(|(c, r)| (c.to_string(), r.iter().map(|s| s.to_string()).collect()))
                .collect(),
            pending: VecDeque::new(),
            sent: Vec::new(),
            notes: Vec::new(),
            now: 0.0,
            step_seconds: 0.01,
        }
    }

    /// Carries out `wire`'s actions until it is done, then its outcome.
    fn run<W: Wire>(&mut self, wire: &mut W) -> Result<W::Output, InstrumentError> {
        self.run_until(wire, |_| false)
    }

    /// As [`Script::run`]; `interrupt` is asked after every action whether to interrupt.
    fn run_until<W: Wire>(
        &mut self,
        wire: &mut W,
        mut interrupt: impl FnMut(&Script) -> bool,
    ) -> Result<W::Output, InstrumentError> {
        for _ in 0..100_000 {
            self.now += self.step_seconds;
            let event = match wire.poll() {
                WireAction::Drain | WireAction::AwaitInput(_) => {
                    WireEvent::Drained(self.pending.drain(..).collect())
                }
                WireAction::ClearInput => {
                    self.pending.clear();
                    WireEvent::Cleared
                }
                WireAction::Send(text) => {
                    self.sent.push(text.clone());
                    match self.replies.front() {
                        Some((command, _)) if *command == text => {
                            let (_, lines) = self.replies.pop_front().unwrap();
                            self.pending.extend(lines);
                        }
                        _ => {}
                    }
                    WireEvent::Sent
                }
                WireAction::ReadLine(timeout) => match self.pending.pop_front() {
                    Some(line) => WireEvent::Line(Some(line)),
                    None => {
                        self.now += timeout.as_secs_f64();
                        WireEvent::Line(None)
                    }
                },
                WireAction::Wait(d) => {
                    self.now += d.as_secs_f64();
                    WireEvent::Waited
                }
                WireAction::Note { event, text } => {
                    self.notes.push((event, text));
                    continue;
                }
                WireAction::Done => return wire.outcome().expect("an outcome once done"),
                other => panic!("an action the script does not know: {other:?}"),
            };
            wire.tell(self.now, event).unwrap();
            if interrupt(self) {
                wire.interrupt();
            }
        }
        panic!("the machine never ended");
    }
}

fn elcomat() -> AcWire {
    let profile = Profile::load("elcomat3000").unwrap();
    AcWire::new(
        "lab:ac1",
        &profile,
        QueryOptions::new(Duration::from_millis(100), 3),
    )
    .unwrap()
}

#[test]
fn a_stale_line_is_drained_and_a_reply_with_another_behind_it_is_asked_again_in_step() {
    // Before the query: a reply to an earlier one is waiting (drained, not taken). The
    // first answer comes with a second line right behind it (a late reply read as this
    // one's): not taken; the device is brought back in step with its identification, the
    // line before the identification's reply discarded, and the query asked again.
    let mut script = Script::new(&[
        (
            "a\n",
            &["4 003 1.000000 0.000000", "4 003 2.000000 0.000000"],
        ),
        ("d\n", &["4 003 2.500000 0.000000", "8 ELCOMAT 3000 S/N 1"]),
        ("a\n", &["4 003 3.000000 0.500000"]),
    ]);
    script.pending.push_back("4 003 9.000000 0.000000".into());
    let mut ac = elcomat();
    ac.begin(AcOp::Measure);
    let outcome = script.run(&mut ac).unwrap();
    let AcOutcome::Reading(r) = outcome else {
        panic!("{outcome:?}")
    };
    assert_eq!((r.x_arcsec, r.y_arcsec), (3.0, Some(0.5)));
    assert_eq!(script.sent, ["a\n", "d\n", "a\n"]);
    assert_eq!(
        script.notes,
        [(
            "discarded".to_string(),
            "4 003 2.500000 0.000000".to_string()
        )]
    );
}

#[test]
fn a_query_that_never_gets_a_valid_reply_ends_after_its_retries_naming_the_last() {
    // X invalid (status 002) four times: retried without resynchronisation (the reply was
    // its own), then refused naming the reply and the attempts.
    let replies: Vec<(&str, &[&str])> = vec![("a\n", &["4 002 0.000000 0.000000"]); 4];
    let mut script = Script::new(&replies);
    let mut ac = elcomat();
    ac.begin(AcOp::Measure);
    let e = script.run(&mut ac).unwrap_err();
    assert_eq!(script.sent, ["a\n"; 4]);
    let message = e.to_string();
    assert!(message.starts_with("lab:ac1: reply \"4 002"), "{message}");
    assert!(message.ends_with("(4 attempts)"), "{message}");
    // and silence: a time-out, each retry after a resynchronisation that gets no answer
    let mut script = Script::new(&[]);
    ac.begin(AcOp::Measure);
    let e = script.run(&mut ac).unwrap_err();
    assert!(
        matches!(e, InstrumentError::Timeout { attempts: 4, .. }),
        "{e}"
    );
    assert_eq!(script.sent, ["a\n", "d\n", "d\n", "d\n"]);
}

fn table(name: &str) -> TableWire {
    let options = TableOptions::new(QueryOptions::new(Duration::from_millis(100), 2))
        .with_poll_interval(Duration::from_millis(20))
        .with_motion_timeout(Duration::from_secs(2));
    TableWire::new("lab:table", &Profile::load(name).unwrap(), options).unwrap()
}

#[test]
fn a_motion_whose_acknowledgement_is_lost_is_never_sent_again() {
    // An Aerotech `MOVEABS` acknowledged by `%`: the acknowledgement lost, and the error
    // query's first answer lost too (asked again after a resynchronisation). The motion
    // went once; the error, the state and the position tell what happened.
    let mut t = table("aerotech-ascii");
    t.begin(TableOp::MoveTo(45.0));
    let mut sent: Vec<String> = Vec::new();
    let mut notes: Vec<(String, String)> = Vec::new();
    let mut pending: VecDeque<String> = VecDeque::new();
    let mut now = 0.0;
    let outcome = loop {
        now += 0.01;
        let event = match t.poll() {
            WireAction::Drain | WireAction::AwaitInput(_) => {
                WireEvent::Drained(pending.drain(..).collect())
            }
            WireAction::Send(text) => {
                let asked_before = sent.iter().filter(|s| **s == text).count();
                let reply: Option<&str> = match (text.as_str(), asked_before) {
                    ("AXISSTATUS(@0)\n", _) => Some("%7"), // Enabled, Homed, InPosition
                    ("AXISFAULT(@0)\n", 0) => None,        // lost
                    ("AXISFAULT(@0)\n", _) => Some("%0"),
                    ("GETPARM(@0, 140)\n", _) => Some("%X"),
                    ("PFBKPROG(@0)\n", _) => Some("%45.0000"),
                    _ => None, // the motion's `%` lost
                };
                pending.extend(reply.map(String::from));
                sent.push(text);
                WireEvent::Sent
            }
            WireAction::ReadLine(_) => WireEvent::Line(pending.pop_front()),
            WireAction::Note { event, text } => {
                notes.push((event, text));
                continue;
            }
            WireAction::Done => break t.outcome().unwrap(),
            other => panic!("{other:?}"),
        };
        t.tell(now, event).unwrap();
    };
    assert_eq!(
        sent,
        [
            "AXISSTATUS(@0)\n",
            "MOVEABS @0 45 F10\n",
            "AXISFAULT(@0)\n",
            "GETPARM(@0, 140)\n",
            "AXISFAULT(@0)\n",
            "AXISSTATUS(@0)\n",
            "PFBKPROG(@0)\n",
        ]
    );
    assert_eq!(
        notes,
        [(
            "no acknowledgement".to_string(),
            "MOVEABS @0 45 F10\n".to_string()
        )]
    );
    assert!(matches!(outcome, Ok(TableOutcome::At(deg)) if (deg - 45.0).abs() < 1e-9));
}

#[test]
fn a_table_that_never_stops_is_stopped_at_its_time_out_and_on_request() {
    // SMC100: `1TS` says MOVING (28) for ever. At the motion time-out (2 s on the clock
    // told) the stop is sent and the move refused; on a stop request during the wait, the
    // stop is sent at once and the move ends as interrupted. The motion went once.
    // A third time with a clock that stands still (every event told at 0 s): the
    // time-out is reached all the same, counted on the polls' waits.
    for (interrupt_after, frozen) in [(None, false), (Some(5usize), false), (None, true)] {
        let mut t = table("smc100");
        t.begin(TableOp::MoveTo(10.0));
        let mut states = 0usize;
        let mut sent: Vec<String> = Vec::new();
        let mut pending: VecDeque<String> = VecDeque::new();
        let mut now = 0.0;
        let outcome = loop {
            let event = match t.poll() {
                WireAction::Drain | WireAction::AwaitInput(_) => {
                    WireEvent::Drained(pending.drain(..).collect())
                }
                WireAction::Send(text) => {
                    match text.as_str() {
                        "1TS\r\n" => {
                            states += 1;
                            pending.push_back(
                                if states == 1 {
                                    "1TS000033"
                                } else {
                                    "1TS000028"
                                }
                                .into(),
                            );
                        }
                        "1TE\r\n" => pending.push_back("1TE@".into()),
                        _ => {}
                    }
                    sent.push(text);
                    WireEvent::Sent
                }
                WireAction::ReadLine(_) => WireEvent::Line(pending.pop_front()),
                WireAction::Wait(d) => {
                    now += d.as_secs_f64();
                    WireEvent::Waited
                }
                WireAction::Note { .. } => continue,
                WireAction::Done => break t.outcome().unwrap(),
                other => panic!("{other:?}"),
            };
            now += 0.005;
            t.tell(if frozen { 0.0 } else { now }, event).unwrap();
            if interrupt_after.is_some_and(|n| states > n) {
                t.interrupt();
            }
        };
        let e = outcome.unwrap_err();
        assert_eq!(sent.iter().filter(|s| s.starts_with("1PA")).count(), 1);
        assert_eq!(sent.last().map(String::as_str), Some("1ST\r\n"), "{sent:?}");
        match interrupt_after {
            None => {
                assert!(
                    e.to_string()
                        .contains("not ready 2 s after the motion command; stopped it"),
                    "{e}"
                );
                if frozen {
                    // 2 s of 20 ms polls: the state before the move and 100 or 101 polls
                    assert!((101..=103).contains(&states), "{states} state queries");
                } else {
                    assert!((2.0..2.1).contains(&now), "stopped at {now} s");
                }
            }
            Some(n) => {
                assert!(e.is_interrupted(), "{e}");
                assert_eq!(
                    states,
                    n + 1,
                    "the stop sent at the first step after the request"
                );
            }
        }
    }
}

#[test]
fn an_event_that_does_not_answer_or_a_time_that_is_not_finite_is_refused() {
    let mut ac = elcomat();
    ac.begin(AcOp::Measure);
    assert_eq!(ac.poll(), WireAction::Drain);
    let e = ac.tell(0.0, WireEvent::Sent).unwrap_err();
    assert!(
        e.to_string().starts_with("the wire rules asked for Drain"),
        "{e}"
    );
    let e = ac.tell(f64::NAN, WireEvent::Drained(vec![])).unwrap_err();
    assert!(
        e.to_string().contains("a time that is not a finite number"),
        "{e}"
    );
    assert_eq!(ac.poll(), WireAction::Drain, "unchanged");
    let mut t = table("pi-gcs2");
    assert_eq!(
        t.poll(),
        WireAction::Done,
        "nothing begun: done, with no outcome"
    );
    assert!(t.outcome().is_none());
    assert!(t.tell(0.0, WireEvent::Sent).is_err());
}

/// A lab's own port: a `TcpStream` read and written by this code alone (its own line
/// buffer, its own deadlines), the rules in `TableWire`.
#[cfg(unix)]
mod own_port {
    use std::io::{ErrorKind, Read, Write};
    use std::net::TcpStream;
    use std::time::{Duration, Instant};

    use super::super::emulator_support::{self, Log, aerotech, esp301, pi_gcs2, smc100};
    use super::super::table_emulators::{Expect, TARGET, check, options};
    use polycal::lab::driver::{TableOp, TableOutcome, TableWire};
    use polycal::lab::profile::Profile;
    use polycal::lab::sim::SimDevice;
    use polycal::lab::wire::{Wire, WireAction, WireEvent};

    struct Port {
        stream: TcpStream,
        buffer: Vec<u8>,
    }

    impl Port {
        fn take_line(&mut self) -> Option<String> {
            while let Some(end) = self.buffer.iter().position(|&b| b == b'\r' || b == b'\n') {
                let line: Vec<u8> = self.buffer.drain(..=end).collect();
                let text = String::from_utf8_lossy(&line[..end]).into_owned();
                if !text.is_empty() {
                    return Some(text);
                }
            }
            None
        }

        fn fill(&mut self, wait: Duration) -> bool {
            self.stream
                .set_read_timeout(Some(wait.max(Duration::from_millis(1))))
                .unwrap();
            let mut chunk = [0u8; 256];
            match self.stream.read(&mut chunk) {
                Ok(0) => panic!("the controller closed the connection"),
                Ok(n) => {
                    self.buffer.extend_from_slice(&chunk[..n]);
                    true
                }
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => false,
                Err(e) => panic!("{e}"),
            }
        }

        fn read_line(&mut self, timeout: Duration) -> Option<String> {
            let deadline = Instant::now() + timeout;
            loop {
                if let Some(line) = self.take_line() {
                    return Some(line);
                }
                let left = deadline.saturating_duration_since(Instant::now());
                if left.is_zero() {
                    return None;
                }
                self.fill(left);
            }
        }

        fn drain(&mut self) -> Vec<String> {
            while self.fill(Duration::from_millis(1)) {}
            let mut lines = Vec::new();
            while let Some(line) = self.take_line() {
                lines.push(line);
            }
            if !self.buffer.is_empty() {
                lines.push(String::from_utf8_lossy(&self.buffer).into_owned());
                self.buffer.clear();
            }
            lines
        }
    }

    /// Starts the table behind `path` and moves it to [`TARGET`] through `TableWire`.
    fn session(profile: &Profile, device: Box<dyn SimDevice>, log: &Log) -> Result<f64, String> {
        let (lab, path) = emulator_support::serve(device, true);
        let address = path.trim_start_matches("tcp://");
        let mut port = Port {
            stream: TcpStream::connect(address).unwrap(),
            buffer: Vec::new(),
        };
        let mut table = TableWire::new("own:table", profile, options()).unwrap();
        let clock = Instant::now();
        let mut outcome = Ok(0.0);
        for op in [TableOp::Start, TableOp::MoveTo(TARGET)] {
            table.begin(op);
            let result = loop {
                let event = match table.poll() {
                    WireAction::Drain => WireEvent::Drained(port.drain()),
                    WireAction::AwaitInput(wait) => {
                        port.fill(wait);
                        WireEvent::Input(port.drain())
                    }
                    WireAction::ClearInput => {
                        port.drain();
                        WireEvent::Cleared
                    }
                    WireAction::Send(text) => {
                        port.stream.write_all(text.as_bytes()).unwrap();
                        WireEvent::Sent
                    }
                    WireAction::ReadLine(timeout) => WireEvent::Line(port.read_line(timeout)),
                    WireAction::Wait(d) => {
                        std::thread::sleep(d);
                        WireEvent::Waited
                    }
                    WireAction::Note { .. } => continue,
                    WireAction::Done => break table.outcome().unwrap(),
                    other => panic!("{other:?}"),
                };
                table.tell(clock.elapsed().as_secs_f64(), event).unwrap();
            };
            match result {
                Ok(TableOutcome::At(deg)) => outcome = Ok(deg),
                Ok(_) => {}
                Err(e) => {
                    outcome = Err(e.to_string());
                    break;
                }
            }
        }
        lab.shutdown();
        let _ = log;
        outcome
    }

    #[test]
    fn every_make_is_homed_before_its_first_move_through_a_port_of_the_labs_own() {
        let cases: Vec<(&str, Box<dyn SimDevice>, Log)> = {
            let (a, p, e, s) = (
                Log::default(),
                Log::default(),
                Log::default(),
                Log::default(),
            );
            vec![
                (
                    "aerotech-ascii",
                    Box::new(aerotech::Ensemble::new(
                        aerotech::PowerOn::EnabledNotHomed,
                        a.clone(),
                    )),
                    a,
                ),
                (
                    "pi-gcs2",
                    Box::new(pi_gcs2::C863::new(
                        pi_gcs2::PowerOn::ServoOnNotReferenced,
                        p.clone(),
                    )),
                    p,
                ),
                (
                    "esp301",
                    Box::new(esp301::Esp301::new(
                        esp301::PowerOn::MotorOnNotHomed,
                        e.clone(),
                    )),
                    e,
                ),
                (
                    "smc100",
                    Box::new(smc100::Smc100::new(
                        smc100::PowerOn::NotReferenced,
                        s.clone(),
                    )),
                    s,
                ),
            ]
        };
        for (name, device, log) in cases {
            let profile = Profile::load(name).unwrap();
            let outcome = session(&profile, device, &log);
            let what = format!("{name} not homed, through a port of the lab's own");
            check(&what, Expect::Lands { home: true }, &outcome, &log.record());
        }
    }
}
