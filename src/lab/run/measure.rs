//! The measuring loop: start and identify the instruments, then visit every remaining
//! stop of the plan, read both autocollimators there until their readings agree
//! (`repeat`), and put each reading on disk before the table moves again.

use std::fmt;
use std::time::{Duration, Instant};

use super::repeat::{DeviceMemory, RepeatError, read_at_stop};
use super::{Identification, RunDir, RunError, TRAFFIC};
use crate::lab::traffic::TrafficLog;
use crate::lab::{Autocollimator, InstrumentError, RotaryTable, StopFlag};
use crate::measurement::{Direction, Reading};

/// How a measuring session ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    /// Every reading of the run is on disk.
    Completed,
    /// Stopped on request (Ctrl-C).
    Interrupted,
    /// An instrument failed (the text says which and how).
    InstrumentError(String),
    /// A file of the run directory could not be written.
    FileError(String),
}

impl fmt::Display for Outcome {
    /// `completed`, `interrupted`, `instrument-error: …` or `file-error: …`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Outcome::Completed => f.write_str("completed"),
            Outcome::Interrupted => f.write_str("interrupted"),
            Outcome::InstrumentError(m) => write!(f, "instrument-error: {m}"),
            Outcome::FileError(m) => write!(f, "file-error: {m}"),
        }
    }
}

impl Outcome {
    /// The outcome of an instrument's failure; `role` names the instrument
    /// (`autocollimator 1`, `rotary table`).
    fn from_instrument(role: &str, e: InstrumentError) -> Outcome {
        if e.is_interrupted() {
            Outcome::Interrupted
        } else {
            Outcome::InstrumentError(format!("{role} at {e}"))
        }
    }
}

/// The instruments' names in messages.
const ROLES: [&str; 3] = ["autocollimator 1", "autocollimator 2", "rotary table"];

/// The three instruments of a run.
pub struct Instruments<'a> {
    /// Autocollimator 1.
    pub ac1: &'a mut dyn Autocollimator,
    /// Autocollimator 2.
    pub ac2: &'a mut dyn Autocollimator,
    /// The rotary table.
    pub table: &'a mut dyn RotaryTable,
}

impl fmt::Debug for Instruments<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Instruments")
            .field("ac1", &self.ac1.port())
            .field("ac2", &self.ac2.port())
            .field("table", &self.table.port())
            .finish()
    }
}

/// Where a run is, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
#[non_exhaustive]
pub struct Progress {
    /// Readings on disk.
    pub done: usize,
    /// Readings of the whole run.
    pub total: usize,
    /// Current cycle, and the number of cycles.
    pub cycle: (u32, u32),
    /// Current stop within the cycle (1-based), and stops per cycle.
    pub stop: (usize, usize),
    /// Current step (0 … N).
    pub step: usize,
    /// Estimated seconds until the run is complete, once a reading was taken.
    pub seconds_left: Option<f64>,
    /// Readings taken in this session and not stored: refused (stale, not agreeing
    /// with the others at their stop) or beyond the agreeing ones.
    pub refused: usize,
}

/// Starts and identifies the instruments, then measures every remaining reading of
/// `run`, syncing each to disk (and the traffic log, if given) before the table moves
/// again. Returns how the session ended; on anything but completion the table is sent a
/// stop. The manifest is not finished here: call [`RunDir::finish`].
///
/// The first write that fails ends the session with [`Outcome::FileError`]: a reading
/// that cannot be appended (the measurement file is cut back to its last whole line, and
/// the message gives the reading), the traffic log (checked after every exchange with an
/// instrument, so that every reading on disk has its traffic logged; a reading taken
/// after the log failed is not appended, and the message gives it) or the manifest when
/// the session starts.
///
/// # Errors
///
/// [`RunError::OtherInstruments`] when a resumed run meets other instruments than it
/// started with (nothing was measured then).
pub fn measure(
    run: &mut RunDir,
    instruments: Instruments<'_>,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Outcome, RunError> {
    let Instruments { ac1, ac2, table } = instruments;
    let identification = match identify(ac1, ac2, table) {
        Ok(id) => id,
        Err((role, e)) => {
            let _ = table.stop();
            return Ok(Outcome::from_instrument(role, e));
        }
    };
    let outcome = match run.begin_session(identification) {
        Ok(()) => match log_failure(run, traffic) {
            Some(failed) => failed,
            None => measure_stops(run, ac1, ac2, table, stop_flag, traffic, progress),
        },
        Err(e @ RunError::OtherInstruments { .. }) => {
            let _ = table.stop();
            return Err(e);
        }
        Err(e) => Outcome::FileError(e.to_string()),
    };
    if outcome != Outcome::Completed {
        let _ = table.stop();
    }
    if let Some(log) = traffic
        && let Err(e) = log.sync()
        && outcome == Outcome::Completed
    {
        return Ok(Outcome::FileError(format!(
            "{}: {e}",
            run.dir.join(TRAFFIC).display()
        )));
    }
    Ok(outcome)
}

/// The outcome of a traffic log that failed to write, if it did.
fn log_failure(run: &RunDir, traffic: Option<&TrafficLog>) -> Option<Outcome> {
    let e = traffic?.check().err()?;
    Some(Outcome::FileError(format!(
        "{}: {e}",
        run.dir.join(TRAFFIC).display()
    )))
}

fn identify(
    ac1: &mut dyn Autocollimator,
    ac2: &mut dyn Autocollimator,
    table: &mut dyn RotaryTable,
) -> Result<Identification, (&'static str, InstrumentError)> {
    let role = |i: usize| move |e| (ROLES[i], e);
    ac1.start().map_err(role(0))?;
    let id1 = ac1.identify().map_err(role(0))?;
    ac2.start().map_err(role(1))?;
    let id2 = ac2.identify().map_err(role(1))?;
    table.start().map_err(role(2))?;
    let id_table = table.identify().map_err(role(2))?;
    Ok(Identification {
        ac1: id1,
        ac2: id2,
        table: id_table,
    })
}

fn measure_stops(
    run: &mut RunDir,
    ac1: &mut dyn Autocollimator,
    ac2: &mut dyn Autocollimator,
    table: &mut dyn RotaryTable,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    progress: &mut dyn FnMut(&Progress),
) -> Outcome {
    let settings = run.manifest.settings.clone();
    let total = settings.reading_count();
    let stops_per_cycle = settings.stops_per_cycle();
    let session_start = Instant::now();
    let before = run.readings_done();
    let settle = Duration::try_from_secs_f64(settings.settle_seconds).unwrap_or(Duration::ZERO);
    let mut memory = [DeviceMemory::default(); 2];
    let mut refused = 0;
    for (stop, acs) in run.remaining() {
        if stop_flag.is_set() {
            return Outcome::Interrupted;
        }
        // Everything on disk before the table moves.
        if let Some(log) = traffic
            && let Err(e) = log.sync()
        {
            return Outcome::FileError(format!("{}: {e}", run.dir.join(TRAFFIC).display()));
        }
        let encoder = match table.move_to(stop.degrees(settings.faces)) {
            Ok(p) => p,
            Err(e) => return Outcome::from_instrument(ROLES[2], e),
        };
        if let Some(failed) = log_failure(run, traffic) {
            return failed;
        }
        if stop_flag.sleep(settle) {
            return Outcome::Interrupted;
        }
        for ac in acs {
            if stop_flag.is_set() {
                return Outcome::Interrupted;
            }
            let device: &mut dyn Autocollimator = if ac == 1 { &mut *ac1 } else { &mut *ac2 };
            let role = ROLES[ac as usize - 1];
            let at = format!("cycle {}, step {}", stop.cycle, stop.step);
            let label = if ac == 1 { "ac1" } else { "ac2" };
            let taken = read_at_stop(
                device,
                &mut memory[ac as usize - 1],
                &settings,
                traffic,
                (label, role, &at),
                stop.degrees(settings.faces),
            );
            let (x_arcsec, y_arcsec) = match taken {
                Ok(r) => {
                    refused += r.refused;
                    (r.x_arcsec, r.y_arcsec)
                }
                Err(RepeatError::Instrument(e)) => return Outcome::from_instrument(role, e),
                Err(RepeatError::NoAgreement(message)) => {
                    return Outcome::InstrumentError(message);
                }
            };
            let reading = Reading {
                setup: 1,
                cycle: stop.cycle,
                step: stop.step,
                ac,
                face: settings.face(ac, stop.step),
                reading_arcsec: x_arcsec,
                direction: stop.direction,
                time_seconds: Some(run.clock.now()),
                reading_y_arcsec: y_arcsec,
                temperature_celsius: None,
                encoder_degrees: Some(encoder),
                line: 0,
            };
            // The reading was taken: when it cannot go on disk, say it, so that it is
            // not lost with the file. Every reading on disk has its traffic logged.
            let row = run.row(&reading);
            let not_written = |e: &dyn fmt::Display| {
                Outcome::FileError(format!("{e} (the reading not written: {row})"))
            };
            if let Some(Outcome::FileError(e)) = log_failure(run, traffic) {
                return not_written(&e);
            }
            if let Err(e) = run.append(&reading) {
                return not_written(&e);
            }
            let done = run.readings_done();
            let this_session = done - before;
            let elapsed = session_start.elapsed().as_secs_f64();
            let position = match stop.direction {
                Direction::Cw => stop.step + 1,
                Direction::Ccw => stops_per_cycle - stop.step,
            };
            progress(&Progress {
                done,
                total,
                cycle: (stop.cycle, settings.cycles),
                stop: (position, stops_per_cycle),
                step: stop.step,
                seconds_left: (this_session > 0)
                    .then(|| elapsed / this_session as f64 * (total - done) as f64),
                refused,
            });
        }
    }
    Outcome::Completed
}
