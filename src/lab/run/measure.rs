//! `polycal run`'s own driver of the run's session (`session.rs`): it starts and
//! identifies the instruments, then carries out every action the session asks with the
//! ports, the profiles' drivers and the wall clock, and keeps every record in the run
//! directory, each reading synced to disk before the table moves again.

use std::fmt;
use std::time::Duration;

use super::session::{Action, Event, Outcome, Session};
use super::store::Store;
use super::{Identification, Remount, RunDir, RunError};
use crate::lab::traffic::TrafficLog;
use crate::lab::{Autocollimator, InstrumentError, RotaryTable, StopFlag};

use super::session::Progress;

/// How far past a stop the table is pre-positioned so that its last move onto the stop
/// comes from the cycle's direction, degrees: 0.5°, or a quarter of the pitch when that
/// is less (a pre-position is never another stop). Far more than any backlash of a
/// rotary table, little enough not to cost time.
pub const APPROACH_OVERSHOOT_DEG: f64 = 0.5;

/// The overshoot of the pre-position before a stop of a polygon of `faces` faces,
/// degrees: [`APPROACH_OVERSHOOT_DEG`] or a quarter of the pitch, the smaller.
///
/// ```
/// use polycal::lab::run::approach_overshoot_deg;
/// assert_eq!(approach_overshoot_deg(8), 0.5);
/// assert_eq!(approach_overshoot_deg(1440), 0.0625);
/// ```
pub fn approach_overshoot_deg(faces: usize) -> f64 {
    APPROACH_OVERSHOOT_DEG.min(360.0 / faces.max(1) as f64 / 4.0)
}

/// The instruments of a run: the autocollimators 1 … K (as many as the run's
/// `ac_faces`) and the rotary table.
pub struct Instruments<'a> {
    /// Autocollimators 1 … K, in order (two for the paper's design).
    pub autocollimators: Vec<&'a mut dyn Autocollimator>,
    /// The rotary table.
    pub table: &'a mut dyn RotaryTable,
}

impl<'a> Instruments<'a> {
    /// The autocollimators 1 … K, in order, and the table.
    pub fn new(
        autocollimators: Vec<&'a mut dyn Autocollimator>,
        table: &'a mut dyn RotaryTable,
    ) -> Instruments<'a> {
        Instruments {
            autocollimators,
            table,
        }
    }

    /// Autocollimators of one kind, 1 … K in order, and the table.
    pub fn of<A: Autocollimator>(
        autocollimators: &'a mut [A],
        table: &'a mut dyn RotaryTable,
    ) -> Instruments<'a> {
        Instruments {
            autocollimators: autocollimators
                .iter_mut()
                .map(|a| a as &mut dyn Autocollimator)
                .collect(),
            table,
        }
    }
}

impl fmt::Debug for Instruments<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let acs: Vec<&str> = self.autocollimators.iter().map(|a| a.port()).collect();
        f.debug_struct("Instruments")
            .field("autocollimators", &acs)
            .field("table", &self.table.port())
            .finish()
    }
}

/// What a run asks of the person at the table, and tells them.
pub trait Attendant {
    /// Where the run is: after every reading, and with the check after every cycle.
    fn progress(&mut self, progress: &Progress);

    /// The polygon is to be remounted for `remount.mounting`, the table standing at the
    /// mounting's step 0: returns once it is, `true` to measure it, `false` to end the
    /// session without measuring (then [`Outcome::Interrupted`]).
    fn remount(&mut self, remount: &Remount) -> bool;
}

/// An attendant that shows progress through a closure and confirms no remount.
struct Unattended<'a>(&'a mut dyn FnMut(&Progress));

impl Attendant for Unattended<'_> {
    fn progress(&mut self, progress: &Progress) {
        (self.0)(progress);
    }

    fn remount(&mut self, _remount: &Remount) -> bool {
        false
    }
}

/// [`measure_attended`] without anyone at the table: `progress` is told where the run is,
/// and a mounting that awaits its remount ([`RunDir::awaits_remount`]) is not measured
/// (the session ends as [`Outcome::Interrupted`]).
///
/// # Errors
///
/// As [`measure_attended`].
pub fn measure(
    run: &mut RunDir,
    instruments: Instruments<'_>,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    progress: &mut dyn FnMut(&Progress),
) -> Result<Outcome, RunError> {
    measure_attended(
        run,
        instruments,
        stop_flag,
        traffic,
        &mut Unattended(progress),
    )
}

/// Starts and identifies the instruments, then measures every remaining reading of
/// `run` in its mounting, syncing each to disk (and the traffic log, if given) before
/// the table moves again. Returns how the session ended; on anything but completion the
/// table is sent a stop. The manifest is not finished here: call [`RunDir::finish`].
///
/// A mounting that awaits its remount ([`RunDir::awaits_remount`]) is measured only once
/// the attendant confirmed it ([`Attendant::remount`], the table sent to the mounting's
/// step 0 before) and the table still reports that position within
/// [`REMOUNT_TOLERANCE_DEG`](super::REMOUNT_TOLERANCE_DEG) (else [`Outcome::InstrumentError`]: the table was moved
/// while the polygon was remounted); the confirmation and the position are recorded in
/// the manifest ([`RunDir::confirm_remount`]).
///
/// Nothing is stored before the instruments are shown to be where the run left them
/// (docs/FORMAT.md §7.3, *Before the first reading of a session*): a mounting with
/// readings on disk has its last stop read again and compared with them, a new mounting
/// its first stop compared with the mountings before; readings that do not agree end the
/// session with [`Outcome::InstrumentError`] saying what was found. The values each
/// autocollimator gave before the session are refused as stale at another stop.
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
pub fn measure_attended(
    run: &mut RunDir,
    instruments: Instruments<'_>,
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    attendant: &mut dyn Attendant,
) -> Result<Outcome, RunError> {
    let Instruments {
        autocollimators: mut acs,
        table,
    } = instruments;
    let k = run.manifest.settings.autocollimators();
    if acs.len() != k {
        let _ = table.stop();
        return Ok(Outcome::InstrumentError(format!(
            "the run has {k} autocollimators, {} were connected",
            acs.len()
        )));
    }
    let identification = match identify(&mut acs, table) {
        Ok(id) => id,
        Err((role, e)) => {
            let _ = table.stop();
            return Ok(Outcome::from_instrument(&role, &e));
        }
    };
    let outcome = match run.begin_session(identification) {
        Ok(()) => match log_failure(run, traffic) {
            Some(failed) => failed,
            None => match run.so_far() {
                Ok(mut so_far) => {
                    // Messages and the log name the ports connected now.
                    so_far.ac_names = acs.iter().map(|a| a.port().to_string()).collect();
                    so_far.table_name = table.port().to_string();
                    let mut session = Session::new(so_far, run.clock.now());
                    let mut bench = Bench {
                        acs: &mut acs,
                        table: &mut *table,
                        stop_flag,
                        traffic,
                    };
                    drive(&mut session, run, &mut bench, attendant)
                }
                Err(e) => Outcome::FileError(e.to_string()),
            },
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
        && let Some(failed) = run.traffic_failure(log, true)
        && outcome == Outcome::Completed
    {
        return Ok(Outcome::FileError(failed));
    }
    Ok(outcome)
}

/// The outcome of a traffic log that failed to write, if it did.
fn log_failure(run: &RunDir, traffic: Option<&TrafficLog>) -> Option<Outcome> {
    run.traffic_failure(traffic?, false).map(Outcome::FileError)
}

fn identify(
    acs: &mut [&mut dyn Autocollimator],
    table: &mut dyn RotaryTable,
) -> Result<Identification, (String, InstrumentError)> {
    let mut ids = Vec::with_capacity(acs.len());
    for (i, ac) in acs.iter_mut().enumerate() {
        let named = |e| (super::session::role(i as u32 + 1), e);
        ac.start().map_err(named)?;
        ids.push(ac.identify().map_err(named)?);
    }
    let named = |e| (super::session::TABLE.to_string(), e);
    table.start().map_err(named)?;
    let id_table = table.identify().map_err(named)?;
    Ok(Identification::new(ids, id_table))
}

/// The instruments, the stop flag and the traffic log the driver carries the session's
/// actions out with.
struct Bench<'a, 'b> {
    acs: &'a mut [&'b mut dyn Autocollimator],
    table: &'a mut dyn RotaryTable,
    stop_flag: &'a StopFlag,
    traffic: Option<&'a TrafficLog>,
}

/// Carries out `session`'s actions until it is over: the instruments asked, the run
/// directory keeping the records, the traffic log the lines. A stop requested ends the
/// session before its next instrument action (never between a reading and its keeping).
fn drive(
    session: &mut Session,
    run: &mut RunDir,
    bench: &mut Bench<'_, '_>,
    attendant: &mut dyn Attendant,
) -> Outcome {
    let clock = run.clock;
    loop {
        let action = session.poll();
        let instrument = matches!(
            action,
            Action::Move { .. }
                | Action::Position
                | Action::Read { .. }
                | Action::Wait { .. }
                | Action::Remount(_)
        );
        if instrument && bench.stop_flag.is_set() {
            session.interrupt();
            continue;
        }
        let event = match action {
            Action::Move { to_deg } => {
                // Everything on disk before the table moves.
                if let Some(log) = bench.traffic
                    && let Some(failed) = run.traffic_failure(log, true)
                {
                    session.file_failed(failed);
                    continue;
                }
                let moved = bench.table.move_to(to_deg);
                if let Some(Outcome::FileError(m)) = log_failure(run, bench.traffic) {
                    session.file_failed(m);
                    continue;
                }
                match moved {
                    Ok(at_deg) => Event::Moved { at_deg },
                    Err(e) => Event::Failed(e),
                }
            }
            Action::Position => match bench.table.position() {
                Ok(deg) => Event::Position { deg },
                Err(e) => Event::Failed(e),
            },
            Action::Read { ac } => match bench.acs.get_mut(ac as usize - 1) {
                Some(device) => match device.measure() {
                    Ok(reading) => Event::Read(reading),
                    Err(e) => Event::Failed(e),
                },
                None => Event::Failed(InstrumentError::Reported {
                    port: format!("ac{ac}"),
                    message: "not connected".to_string(),
                }),
            },
            Action::Wait { until_seconds } => {
                let wait = Duration::try_from_secs_f64(until_seconds - clock.now())
                    .unwrap_or(Duration::ZERO);
                if bench.stop_flag.sleep(wait) {
                    session.interrupt();
                    continue;
                }
                Event::Waited
            }
            Action::Remount(remount) => Event::Remounted {
                confirmed: attendant.remount(&remount) && !bench.stop_flag.is_set(),
            },
            Action::Keep(record) => match run.keep_logged(&record, bench.traffic) {
                Ok(()) => Event::Kept,
                Err(e) => Event::NotKept(e.to_string()),
            },
            Action::Log(line) => {
                if let Some(log) = bench.traffic {
                    log.record(&line.device, &line.port, &line.event, &line.text);
                }
                continue;
            }
            Action::Progress(progress) => {
                attendant.progress(&progress);
                continue;
            }
            Action::Halt => {
                let _ = bench.table.stop();
                continue;
            }
            Action::Finished(outcome) => return outcome,
        };
        if let Err(e) = session.tell(clock.now(), event) {
            // The driver answers what is asked; this would be its own fault.
            return Outcome::InstrumentError(e.to_string());
        }
    }
}
