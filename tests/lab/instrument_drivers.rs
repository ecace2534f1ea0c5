//! The instrument layer over in-memory transports: the transport's line deadline and
//! framing, the traffic log, and the drivers with the ELCOMAT 3000 and SMC100 profiles: each command's
//! exact bytes, each reply form, each error state, retries of queries, and motion never
//! sent twice.

use std::io::{self, Read, Write};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use polycal::lab::driver::{ProfileAutocollimator, ProfileTable, TableOptions, TableState};
use polycal::lab::profile::{Profile, format_degrees};
use polycal::lab::scripted::ScriptedStream;
use polycal::lab::traffic::{LoggedTransport, RunClock, TrafficLog};
use polycal::lab::transport::{StreamTransport, Transport};
use polycal::lab::{
    Autocollimator, InstrumentError, QueryOptions, ReplyError, RotaryTable, StopFlag,
};

/// Fast queries for tests: a lost reply costs 30 ms.
fn fast() -> QueryOptions {
    QueryOptions::new(Duration::from_millis(30), 3)
}

fn elcomat(stream: ScriptedStream) -> ProfileAutocollimator<StreamTransport<ScriptedStream>> {
    ProfileAutocollimator::elcomat3000(StreamTransport::new("mem:ac", stream), fast())
        .with_drain(Duration::ZERO)
}

fn smc(stream: ScriptedStream) -> ProfileTable<StreamTransport<ScriptedStream>> {
    ProfileTable::smc100(
        StreamTransport::new("mem:table", stream),
        TableOptions::new(fast())
            .with_poll_interval(Duration::from_millis(1))
            .with_motion_timeout(Duration::from_secs(2))
            .with_position_tolerance_deg(0.001),
    )
}

fn count(haystack: &str, needle: &str) -> usize {
    haystack.matches(needle).count()
}

// ---------------------------------------------------------------- transport

/// Gives one byte per read, 5 ms apart, and never a terminator.
struct Trickle;

impl Read for Trickle {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        std::thread::sleep(Duration::from_millis(5));
        buf[0] = b'7';
        Ok(1)
    }
}

impl Write for Trickle {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn a_trickling_device_cannot_stretch_the_reply_deadline() {
    let mut t = StreamTransport::new("mem:trickle", Trickle);
    let start = Instant::now();
    let line = t.read_line(Duration::from_millis(40)).unwrap();
    assert_eq!(line, None, "no terminator, no line");
    assert!(start.elapsed() < Duration::from_millis(200));
}

#[test]
fn lines_split_at_cr_or_lf_and_empty_lines_are_skipped() {
    let stream = ScriptedStream::new().initially("1TS000033\r\n\r\n4 003 1 2\rlast\n");
    let mut t = StreamTransport::new("mem", stream);
    let timeout = Duration::from_millis(10);
    assert_eq!(t.read_line(timeout).unwrap().as_deref(), Some("1TS000033"));
    assert_eq!(t.read_line(timeout).unwrap().as_deref(), Some("4 003 1 2"));
    assert_eq!(t.read_line(timeout).unwrap().as_deref(), Some("last"));
    assert_eq!(t.read_line(timeout).unwrap(), None);
}

#[test]
fn an_endless_line_is_cut_and_invalid_utf8_does_not_panic() {
    let mut long = "x".repeat(3000);
    long.push('\r');
    let mut t = StreamTransport::new("mem", ScriptedStream::new().initially(&long));
    let first = t.read_line(Duration::from_millis(10)).unwrap().unwrap();
    assert_eq!(first.len(), polycal::lab::transport::MAX_LINE_BYTES);

    struct Bad(bool);
    impl Read for Bad {
        fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
            if std::mem::replace(&mut self.0, true) {
                return Err(io::ErrorKind::WouldBlock.into());
            }
            buf[..4].copy_from_slice(&[0xff, 0xfe, b'a', b'\r']);
            Ok(4)
        }
    }
    impl Write for Bad {
        fn write(&mut self, b: &[u8]) -> io::Result<usize> {
            Ok(b.len())
        }
        fn flush(&mut self) -> io::Result<()> {
            Ok(())
        }
    }
    let mut t = StreamTransport::new("mem", Bad(false));
    let line = t.read_line(Duration::from_millis(10)).unwrap().unwrap();
    assert!(line.ends_with('a'));
}

#[test]
fn end_of_input_is_a_closed_port() {
    let mut t = StreamTransport::new("mem:gone", ScriptedStream::new().close_when_done());
    match t.read_line(Duration::from_millis(10)) {
        Err(InstrumentError::Closed { port, .. }) => assert_eq!(port, "mem:gone"),
        other => panic!("expected a closed port, got {other:?}"),
    }
}

#[derive(Clone, Default)]
struct SharedBuf(Arc<Mutex<Vec<u8>>>);

impl Write for SharedBuf {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn the_traffic_log_records_every_line_with_time_and_port() {
    let buf = SharedBuf::default();
    let log = TrafficLog::new(buf.clone(), RunClock::new(10.0));
    let stream = ScriptedStream::new()
        .expect("a\n", "")
        .expect("d\n", "8 ELCOMAT\r") // back in step after the lost reply
        .expect("a\n", "4 003 1.5 -2.5\r");
    let transport = LoggedTransport::new(StreamTransport::new("/dev/ttyX", stream), "ac1", log);
    let mut ac = ProfileAutocollimator::elcomat3000(transport, fast());
    let r = ac.measure().unwrap();
    assert_eq!((r.x_arcsec, r.y_arcsec), (1.5, Some(-2.5)));
    let text = String::from_utf8(buf.0.lock().unwrap().clone()).unwrap();
    let records: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    let events: Vec<&str> = records
        .iter()
        .map(|r| r["event"].as_str().unwrap())
        .collect();
    assert_eq!(
        events,
        ["sent", "timeout", "sent", "received", "sent", "received"]
    );
    for r in &records {
        assert_eq!(r["port"], "/dev/ttyX");
        assert_eq!(r["device"], "ac1");
        assert!(r["t"].as_f64().unwrap() >= 10.0, "on the run's clock");
    }
    assert_eq!(
        records[0]["text"], "a\n",
        "sent text is exact, terminator included"
    );
    assert_eq!(records[2]["text"], "d\n", "resynchronised with `d`");
    assert_eq!(records[5]["text"], "4 003 1.5 -2.5");
}

// ---------------------------------------------------------------- ELCOMAT 3000

#[test]
fn elcomat_start_stops_the_stream_and_clears_the_input() {
    let stream = ScriptedStream::new()
        .initially("3 003 1.000000 2.000000\r3 003 1.100000 2.000000\r")
        .expect("s\n", "")
        .expect("d\n", "8 ELCOMAT 3000 V2.1 S/N 815\r");
    let written = stream.written();
    let mut ac = elcomat(stream);
    ac.start().unwrap();
    assert_eq!(ac.identify().unwrap(), "ELCOMAT 3000 V2.1 S/N 815");
    assert_eq!(written.text(), "s\nd\n");
}

#[test]
fn elcomat_measurement_reply_forms() {
    let stream = ScriptedStream::new()
        .expect("a\n", "4 003 12.345000 -1.234000\r")
        .expect("a\n", "4 001 -0.5 99.0\r")
        .expect("a\n", "4 103 1e-3 0\r");
    let written = stream.written();
    let mut ac = elcomat(stream);
    let both = ac.measure().unwrap();
    assert_eq!(
        (both.status, both.x_arcsec, both.y_arcsec),
        (3, 12.345, Some(-1.234))
    );
    let x_only = ac.measure().unwrap();
    assert_eq!((x_only.x_arcsec, x_only.y_arcsec), (-0.5, None));
    let other_status = ac.measure().unwrap();
    assert_eq!((other_status.status, other_status.x_arcsec), (103, 0.001));
    assert_eq!(written.text(), "a\na\na\n");
}

#[test]
fn elcomat_x_invalid_is_retried_and_then_refused() {
    // Once invalid, then valid: one retry.
    let stream = ScriptedStream::new()
        .expect("a\n", "4 002 0.000000 3.000000\r")
        .expect("a\n", "4 003 7.000000 3.000000\r");
    let written = stream.written();
    let mut ac = elcomat(stream);
    assert_eq!(ac.measure().unwrap().x_arcsec, 7.0);
    assert_eq!(written.text(), "a\na\n");

    // Never valid: four attempts, then an error naming the status.
    let mut stream = ScriptedStream::new();
    for _ in 0..4 {
        stream = stream.expect("a\n", "4 000 0.000000 0.000000\r");
    }
    let written = stream.written();
    let mut ac = elcomat(stream);
    match ac.measure() {
        Err(e @ InstrumentError::BadReply { .. }) => {
            let text = e.to_string();
            assert!(text.contains("X axis not valid"), "{text}");
            assert!(text.contains("4 attempts"), "{text}");
            assert!(text.contains("mem:ac"), "{text}");
        }
        other => panic!("expected a refused reading, got {other:?}"),
    }
    assert_eq!(count(&written.text(), "a\n"), 4);
}

#[test]
fn elcomat_lost_and_garbled_replies_are_retried() {
    let stream = ScriptedStream::new()
        .expect("a\n", "")
        .expect("d\n", "8 ELCOMAT\r") // a lost reply may still come: back in step first
        .expect("a\n", "?3 0?3 1.?00000\r")
        .expect("a\n", "4 003 1.000000 2.000000\r");
    let written = stream.written();
    let mut ac = elcomat(stream);
    assert_eq!(ac.measure().unwrap().x_arcsec, 1.0);
    assert_eq!(written.text(), "a\nd\na\na\n");
}

#[test]
fn elcomat_refuses_wrong_reply_forms() {
    for bad in [
        "2 003 1.0 2.0\r",     // a relative reply to an absolute request
        "4 03 1.0 2.0\r",      // status not three digits
        "4 003 1.0\r",         // missing Y
        "4 003 1.0 2.0 3.0\r", // extra field
        "4 003 NaN 2.0\r",     // not finite
        "4 007 1.0 2.0\r",     // unknown axis digit
        "4 003 1.0 2.0 x\r",   // trailing junk
        "\u{1b}[A garbage\r",  // noise on the line
    ] {
        let mut stream = ScriptedStream::new();
        for _ in 0..4 {
            stream = stream.expect("a\n", bad);
        }
        let mut ac = elcomat(stream);
        match ac.measure() {
            Err(InstrumentError::BadReply { received, .. }) => {
                assert_eq!(received, bad.trim_end_matches('\r'))
            }
            other => panic!("{bad:?}: expected a bad reply, got {other:?}"),
        }
    }
}

/// Each refused reply is a typed reason whose message says what is wrong.
#[test]
fn refused_replies_are_typed_reasons_with_their_messages() {
    for (line, reason, text) in [
        (
            "2 003 1.0 2.0",
            ReplyError::NotTheForm {
                form: "4 {status:d3} {x:f} {y:f}".into(),
            },
            "not of the form `4 {status:d3} {x:f} {y:f}`",
        ),
        (
            "4 002 1.0 2.0",
            ReplyError::XNotValid {
                status: "002".into(),
            },
            "X axis not valid (status 002: no reflected light, or out of range)",
        ),
    ] {
        let mut stream = ScriptedStream::new();
        for _ in 0..4 {
            stream = stream.expect("a\n", &format!("{line}\r"));
        }
        match elcomat(stream).measure() {
            Err(InstrumentError::BadReply { reason: e, .. }) => {
                assert_eq!(*e, reason, "{line}");
                assert_eq!(e.to_string(), text, "{line}");
            }
            other => panic!("{line}: {other:?}"),
        }
    }
}

#[test]
fn elcomat_silence_is_a_timeout_after_four_attempts() {
    let mut stream = ScriptedStream::new();
    for _ in 0..4 {
        stream = stream.expect("d\n", "");
    }
    let written = stream.written();
    let mut ac = elcomat(stream);
    match ac.identify() {
        Err(e @ InstrumentError::Timeout { .. }) => {
            let text = e.to_string();
            assert!(text.contains("no reply to \"d\\n\""), "{text}");
            assert!(text.contains("4 attempts"), "{text}");
        }
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert_eq!(written.text(), "d\nd\nd\nd\n");
}

#[test]
fn elcomat_identification_must_be_type_8() {
    let mut stream = ScriptedStream::new();
    for _ in 0..4 {
        stream = stream.expect("d\n", "4 003 1.0 2.0\r");
    }
    assert!(matches!(
        elcomat(stream).identify(),
        Err(InstrumentError::BadReply { .. })
    ));
}

#[test]
fn elcomat_a_closed_port_is_not_retried() {
    let stream = ScriptedStream::new().expect("a\n", "").close_when_done();
    let written = stream.written();
    let mut ac = elcomat(stream);
    assert!(matches!(ac.measure(), Err(InstrumentError::Closed { .. })));
    assert_eq!(written.text(), "a\n");
}

// ---------------------------------------------------------------- SMC100

/// The SMC100 profile reads every state of the manual's table as the old driver did.
#[test]
fn smc100_status_replies() {
    let profile = Profile::load("smc100").unwrap();
    let state = |reply: &str| {
        let stream = ScriptedStream::new().expect("1TS\r\n", &format!("{reply}\r\n"));
        ProfileTable::new(
            StreamTransport::new("mem:table", stream),
            &profile,
            TableOptions::new(fast()),
        )
        .unwrap()
        .state()
    };
    assert_eq!(state("1TS00000A").unwrap(), TableState::NotReferenced);
    assert_eq!(state("1TS000011").unwrap(), TableState::NotReferenced);
    assert_eq!(state("1TS00001E").unwrap(), TableState::Moving);
    assert_eq!(state("1TS000028").unwrap(), TableState::Moving);
    for code in ["32", "33", "34"] {
        assert_eq!(
            state(&format!("1TS0000{code}")).unwrap(),
            TableState::Ready,
            "{code}"
        );
    }
    for (code, name) in [
        ("3C", "DISABLE from READY"),
        ("3D", "DISABLE from MOVING"),
        ("14", "CONFIGURATION"),
    ] {
        let e = state(&format!("1TS0000{code}")).unwrap_err().to_string();
        assert!(e.contains(code) && e.contains(name), "{e}");
    }
    let e = state("1TS020033").unwrap_err().to_string();
    assert!(
        e.contains("fault") && e.contains("0200") && e.contains("80 W output power exceeded"),
        "{e}"
    );
    assert_eq!(format_degrees(45.0), "45");
    assert_eq!(format_degrees(360.0), "360");
    assert_eq!(format_degrees(360.0 / 7.0), "51.428571");
    assert_eq!(format_degrees(-0.0), "0");
}

#[test]
fn smc100_start_when_ready_only_asks_the_state() {
    let stream = ScriptedStream::new()
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1VE\r\n", "1VE SMC_CC - Version 3.1.0\r\n");
    let written = stream.written();
    let mut table = smc(stream);
    table.start().unwrap();
    assert_eq!(table.identify().unwrap(), "SMC_CC - Version 3.1.0");
    assert_eq!(written.text(), "1TE\r\n1TS\r\n1VE\r\n");
}

#[test]
fn smc100_start_homes_a_table_that_is_not_referenced() {
    let stream = ScriptedStream::new()
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS00000A\r\n")
        .expect("1OR\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS00001E\r\n")
        .expect("1TS\r\n", "1TS000032\r\n");
    let written = stream.written();
    let mut table = smc(stream);
    table.start().unwrap();
    assert_eq!(
        written.text(),
        "1TE\r\n1TS\r\n1OR\r\n1TE\r\n1TS\r\n1TS\r\n",
        "the error latched before read away; home sent once, then polled until READY from HOMING"
    );
}

#[test]
fn smc100_start_refuses_disable_configuration_and_error_bits() {
    for (reply, says) in [
        ("1TS00003C\r\n", "DISABLE from READY"),
        ("1TS00003D\r\n", "DISABLE from MOVING"),
        ("1TS000014\r\n", "CONFIGURATION"),
        ("1TS002033\r\n", "following error"),
        ("1TS000146\r\n", "fault (errors 0001: negative end of run)"),
    ] {
        let stream = ScriptedStream::new()
            .expect("1TE\r\n", "1TE@\r\n")
            .expect("1TS\r\n", reply);
        let written = stream.written();
        let mut table = smc(stream);
        match table.start() {
            Err(e @ InstrumentError::Device { .. }) => {
                let text = e.to_string();
                assert!(text.contains(says), "{reply:?}: {text}");
                assert!(text.contains("mem:table"), "{text}");
            }
            other => panic!("{reply:?}: expected a device error, got {other:?}"),
        }
        assert_eq!(written.text(), "1TE\r\n1TS\r\n", "no motion sent");
    }
}

#[test]
fn smc100_move_exact_bytes() {
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000028\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1TP\r\n", "1TP45.000000\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA360\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1TP\r\n", "1TP359.9999995\r\n")
        .expect("1ST\r\n", "");
    let written = stream.written();
    let mut table = smc(stream);
    assert_eq!(table.move_to(45.0).unwrap(), 45.0);
    assert_eq!(table.move_to(360.0).unwrap(), 359.9999995);
    table.stop().unwrap();
    assert_eq!(
        written.text(),
        "1TS\r\n1PA45\r\n1TE\r\n1TS\r\n1TS\r\n1TP\r\n1TS\r\n1PA360\r\n1TE\r\n1TS\r\n1TP\r\n1ST\r\n"
    );
}

#[test]
fn smc100_a_lost_reply_during_a_move_asks_again_and_never_resends_the_move() {
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA90\r\n", "")
        .expect("1TE\r\n", "") // lost
        .expect("1VE\r\n", "1VE SMC100CC\r\n") // back in step
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "") // lost
        .expect("1VE\r\n", "1VE SMC100CC\r\n")
        .expect("1TS\r\n", "1T?00?02?\r\n") // garbled: asked again at once
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1TP\r\n", "") // lost
        .expect("1VE\r\n", "1VE SMC100CC\r\n")
        .expect("1TP\r\n", "1TP90\r\n");
    let written = stream.written();
    let mut table = smc(stream);
    assert_eq!(table.move_to(90.0).unwrap(), 90.0);
    let text = written.text();
    assert_eq!(count(&text, "1PA"), 1, "{text}");
    assert_eq!(count(&text, "1TS\r\n"), 4, "{text}");
}

#[test]
fn smc100_a_silent_controller_ends_the_move_without_resending_it() {
    let mut stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA90\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "");
    // No reply either to the resynchronisation, on every attempt left.
    for _ in 0..3 {
        stream = stream.expect("1VE\r\n", "");
    }
    let written = stream.written();
    let mut table = smc(stream);
    assert!(matches!(
        table.move_to(90.0),
        Err(InstrumentError::Timeout { .. })
    ));
    assert_eq!(count(&written.text(), "1PA"), 1);
}

#[test]
fn smc100_a_refused_move_is_an_error_naming_the_code() {
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA900\r\n", "")
        .expect("1TE\r\n", "1TEG\r\n");
    let mut table = smc(stream);
    let e = table.move_to(900.0).unwrap_err().to_string();
    assert!(e.contains("refused") && e.contains("error G"), "{e}");
    assert!(e.contains("displacement out of limits"), "{e}");
}

#[test]
fn smc100_errors_during_and_after_a_move() {
    // Disabled midway.
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000028\r\n")
        .expect("1TS\r\n", "1TS00003D\r\n");
    let e = smc(stream).move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("3D") && e.contains("DISABLE"), "{e}");

    // Error bits while moving.
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS002028\r\n");
    let e = smc(stream).move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("following error"), "{e}");

    // Not ready before the move: nothing is sent.
    let stream = ScriptedStream::new().expect("1TS\r\n", "1TS000028\r\n");
    let written = stream.written();
    let e = smc(stream).move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("not ready"), "{e}");
    assert_eq!(written.text(), "1TS\r\n");

    // Arrived somewhere else.
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1TP\r\n", "1TP44.5\r\n");
    let e = smc(stream).move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("44.5") && e.contains("45"), "{e}");

    // Lost its reference.
    let stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n")
        .expect("1TS\r\n", "1TS00000F\r\n");
    let e = smc(stream).move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("lost its reference"), "{e}");
}

#[test]
fn smc100_a_stop_request_prevents_the_move() {
    let stream = ScriptedStream::new();
    let written = stream.written();
    let stop = StopFlag::new();
    stop.request();
    let mut table = smc(stream).with_stop_flag(stop);
    assert!(table.move_to(45.0).unwrap_err().is_interrupted());
    assert_eq!(written.text(), "");
}

#[test]
fn smc100_a_move_that_never_ends_is_stopped() {
    let mut stream = ScriptedStream::new()
        .expect("1TS\r\n", "1TS000033\r\n")
        .expect("1PA45\r\n", "")
        .expect("1TE\r\n", "1TE@\r\n");
    for _ in 0..2000 {
        stream = stream.expect("1TS\r\n", "1TS000028\r\n");
    }
    let written = stream.written();
    let mut table = ProfileTable::smc100(
        StreamTransport::new("mem:table", stream),
        TableOptions::new(fast())
            .with_poll_interval(Duration::from_millis(1))
            .with_motion_timeout(Duration::from_millis(50))
            .with_position_tolerance_deg(0.001),
    );
    // The script has no "1ST": the driver's stop attempt fails, the error stands.
    let e = table.move_to(45.0).unwrap_err().to_string();
    assert!(e.contains("not ready"), "{e}");
    assert!(written.text().ends_with("1ST\r\n"));
    assert_eq!(count(&written.text(), "1PA"), 1);
}

#[test]
fn transports_are_usable_as_trait_objects() {
    let boxed: Box<dyn Transport> = Box::new(StreamTransport::new(
        "mem",
        ScriptedStream::new().expect("d\n", "8 X\r"),
    ));
    let mut ac = ProfileAutocollimator::elcomat3000(boxed, fast());
    assert_eq!(ac.identify().unwrap(), "X");
    assert_eq!(ac.port(), "mem");
}
