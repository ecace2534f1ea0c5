//! The measuring loop: start and identify the instruments, then visit every remaining
//! stop of the plan, read every autocollimator there until its readings agree
//! (`repeat`), and put each reading on disk before the table moves again. Every stop is
//! approached from its cycle's direction (a re-measured reading from its own): the last
//! move onto it increases the angle in a clockwise cycle and decreases it in a
//! counter-clockwise one, from a pre-position [`approach_overshoot_deg`] past the stop
//! when the table is not already on that side.

use std::fmt;
use std::time::{Duration, Instant};

use super::live::{self, Cell, CycleCheck, MAX_REMEASURED_PER_CYCLE};
use super::noise::RepeatNoise;
use super::repeat::{DeviceMemory, RepeatError, read_at_stop};
use super::verify::{self, Bench};
use super::{
    Identification, MEASUREMENTS, REMOUNT_TOLERANCE_DEG, Remeasured, Remount, RunDir, RunError,
    Suspect, TRAFFIC,
};
use crate::lab::traffic::TrafficLog;
use crate::lab::{Autocollimator, InstrumentError, RotaryTable, StopFlag};
use crate::measurement::{Direction, Reading};
use crate::measurement::{MeasurementSet, Stop};

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
    pub(super) fn from_instrument(role: &str, e: InstrumentError) -> Outcome {
        if e.is_interrupted() {
            Outcome::Interrupted
        } else {
            Outcome::InstrumentError(format!("{role} at {e}"))
        }
    }
}

/// The table's name in messages.
pub(super) const TABLE: &str = "rotary table";

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

/// Moves the table onto `target_deg` so that its last move comes from `direction`
/// (clockwise: increasing angle, counter-clockwise: decreasing). When the position last
/// commanded (`commanded`, `None` when not known) is not on that side of the target, or
/// is the target, the table first goes to a pre-position past the target by
/// [`approach_overshoot_deg`] on that side. Every move is sent once (the driver's rule).
/// Returns the position the table reports at the target; `commanded` follows every move.
fn approach(
    table: &mut dyn RotaryTable,
    target_deg: f64,
    direction: Direction,
    faces: usize,
    commanded: &mut Option<f64>,
) -> Result<f64, InstrumentError> {
    let from_its_side = commanded.is_some_and(|at| match direction {
        Direction::Cw => at < target_deg,
        Direction::Ccw => at > target_deg,
    });
    if !from_its_side {
        let overshoot = approach_overshoot_deg(faces);
        let pre_deg = match direction {
            Direction::Cw => target_deg - overshoot,
            Direction::Ccw => target_deg + overshoot,
        };
        // A move that failed leaves the table somewhere unknown.
        *commanded = None;
        table.move_to(pre_deg)?;
        *commanded = Some(pre_deg);
    }
    *commanded = None;
    let at = table.move_to(target_deg)?;
    *commanded = Some(target_deg);
    Ok(at)
}

/// Autocollimator `ac`'s name in messages, `autocollimator 3`.
pub(super) fn role(ac: u32) -> String {
    format!("autocollimator {ac}")
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

/// Where a run is, for a progress display.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct Progress {
    /// Readings on disk.
    pub done: usize,
    /// The mounting measured (1 for a run of one).
    pub setup: u32,
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
    /// At the end of a cycle: what the check of the run so far found (docs/FORMAT.md
    /// §7.3, *Checked while it runs*), after any reading it measured again.
    pub cycle_check: Option<CycleCheck>,
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
/// [`REMOUNT_TOLERANCE_DEG`] (else [`Outcome::InstrumentError`]: the table was moved
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
            return Ok(Outcome::from_instrument(&role, e));
        }
    };
    let mut memory = verify::carried_memory(run);
    let outcome = match run.begin_session(identification) {
        Ok(()) => match log_failure(run, traffic) {
            Some(failed) => failed,
            None => {
                let awaited = run.awaits_remount();
                let mut bench = Bench {
                    acs: &mut acs,
                    table: &mut *table,
                    memory: &mut memory,
                    stop_flag,
                    traffic,
                };
                let checked = match remounted(run, &mut bench, attendant) {
                    Some(failed) => Some(failed),
                    // A remount checked its first stop already.
                    None if awaited => None,
                    None => verify::before_first_reading(run, &mut bench),
                };
                match checked {
                    Some(failed) => failed,
                    None => measure_stops(
                        run,
                        &mut acs,
                        table,
                        &mut memory,
                        stop_flag,
                        traffic,
                        attendant,
                    ),
                }
            }
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
pub(super) fn log_failure(run: &RunDir, traffic: Option<&TrafficLog>) -> Option<Outcome> {
    let e = traffic?.check().err()?;
    Some(Outcome::FileError(format!(
        "{}: {e}",
        run.dir.join(TRAFFIC).display()
    )))
}

/// A mounting that awaits its remount: the table to the mounting's first stop, the
/// attendant's confirmation, the table's position checked, the first stop's readings
/// against the mountings before ([`verify::new_mounting_fits`]), and the confirmation
/// recorded. The outcome that ends the session, if any.
fn remounted(
    run: &mut RunDir,
    bench: &mut Bench<'_, '_>,
    attendant: &mut dyn Attendant,
) -> Option<Outcome> {
    if !run.awaits_remount() {
        return None;
    }
    let (stop_flag, traffic) = (bench.stop_flag, bench.traffic);
    let mounting = run.mounting();
    let settings = run.manifest.settings.clone();
    let stop = run.remaining().first()?.0;
    let commanded = mounting.table_deg(&stop, settings.faces);
    let at = match bench.table.move_to(commanded) {
        Ok(p) => p,
        Err(e) => return Some(Outcome::from_instrument(TABLE, e)),
    };
    if let Some(failed) = log_failure(run, traffic) {
        return Some(failed);
    }
    let remount = Remount {
        mounting,
        table_deg: at,
        faces: settings
            .acs()
            .map(|ac| (ac, mounting.face(&settings, ac, stop.step)))
            .collect(),
    };
    if !attendant.remount(&remount) || stop_flag.is_set() {
        return Some(Outcome::Interrupted);
    }
    let reported = match bench.table.position() {
        Ok(p) => p,
        Err(e) => return Some(Outcome::from_instrument(TABLE, e)),
    };
    let off_deg = (reported - commanded).abs();
    if off_deg.is_nan() || off_deg > REMOUNT_TOLERANCE_DEG {
        return Some(Outcome::InstrumentError(format!(
            "{TABLE}: after the remount of {mounting} it reports {reported}°, not {commanded}° \
             where the polygon was to be mounted: the table was moved while the polygon was \
             remounted; mount it again with the table at {commanded}°"
        )));
    }
    // Every autocollimator must see a face: a polygon mounted off the faces' directions
    // leaves them without light (whole faces off: the first stop's check below).
    for (i, ac) in bench.acs.iter_mut().enumerate() {
        if let Err(e) = ac.measure() {
            if e.is_interrupted() {
                return Some(Outcome::Interrupted);
            }
            let face = remount.faces.get(i).map_or(0, |f| f.1);
            return Some(Outcome::InstrumentError(format!(
                "{} sees no face after the remount of {mounting} ({e}): mount the polygon with \
                 face {face} facing it, the table at {commanded}°",
                role(i as u32 + 1)
            )));
        }
    }
    // The faces the autocollimators see are those the mounting says.
    if let Some(stopped) = verify::new_mounting_fits(run, bench) {
        return Some(stopped.outcome());
    }
    if let Some(log) = traffic {
        log.record(
            "",
            "",
            "remounted",
            &format!("{mounting}: confirmed, the table at {reported}°"),
        );
    }
    if let Err(e) = run.confirm_remount(reported) {
        return Some(Outcome::FileError(e.to_string()));
    }
    log_failure(run, traffic)
}

fn identify(
    acs: &mut [&mut dyn Autocollimator],
    table: &mut dyn RotaryTable,
) -> Result<Identification, (String, InstrumentError)> {
    let mut ids = Vec::with_capacity(acs.len());
    for (i, ac) in acs.iter_mut().enumerate() {
        let named = |e| (role(i as u32 + 1), e);
        ac.start().map_err(named)?;
        ids.push(ac.identify().map_err(named)?);
    }
    let named = |e| (TABLE.to_string(), e);
    table.start().map_err(named)?;
    let id_table = table.identify().map_err(named)?;
    Ok(Identification::new(ids, id_table))
}

fn measure_stops(
    run: &mut RunDir,
    acs: &mut [&mut dyn Autocollimator],
    table: &mut dyn RotaryTable,
    memory: &mut [DeviceMemory],
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    attendant: &mut dyn Attendant,
) -> Outcome {
    let settings = run.manifest.settings.clone();
    let mounting = run.mounting();
    let total = run.manifest.expected_readings;
    let stops_per_cycle = settings.stops_per_cycle();
    let session_start = Instant::now();
    let before = run.readings_done();
    let settle = Duration::try_from_secs_f64(settings.settle_seconds).unwrap_or(Duration::ZERO);

    let mut refused = 0;
    let mut handled: Vec<Cell> = Vec::new();
    let plan = settings.plan();
    // Where the table was last sent: not known at the start of a session, so the first
    // stop is approached from a pre-position.
    let mut commanded: Option<f64> = None;
    let mut progress_now =
        |run: &RunDir, stop: Stop, refused: usize, cycle_check: Option<CycleCheck>| {
            let done = run.readings_done();
            let this_session = done - before;
            let elapsed = session_start.elapsed().as_secs_f64();
            let position = match stop.direction {
                Direction::Cw => stop.step + 1,
                Direction::Ccw => stops_per_cycle - stop.step,
            };
            attendant.progress(&Progress {
                done,
                setup: mounting.setup,
                total,
                cycle: (stop.cycle, settings.cycles),
                stop: (position, stops_per_cycle),
                step: stop.step,
                seconds_left: (this_session > 0)
                    .then(|| elapsed / this_session as f64 * (total - done) as f64),
                refused,
                cycle_check,
            });
        };
    for work in session_work(run) {
        let (stop, to_read) = match work {
            Work::Stop(stop, to_read) => (stop, to_read),
            Work::Check(cycle) => {
                let checked = check_cycle(
                    run,
                    Devices {
                        acs: &mut *acs,
                        table: &mut *table,
                    },
                    &mut *memory,
                    stop_flag,
                    traffic,
                    cycle,
                    &mut handled,
                    &mut refused,
                    &mut commanded,
                );
                let check = match checked {
                    Ok(check) => check,
                    Err(outcome) => return outcome,
                };
                if let Err(e) = run.record_checked(cycle) {
                    return Outcome::FileError(e.to_string());
                }
                if let Some(&last) = plan.iter().rfind(|s| s.cycle == cycle) {
                    progress_now(run, last, refused, Some(check));
                }
                continue;
            }
        };
        if stop_flag.is_set() {
            return Outcome::Interrupted;
        }
        // Everything on disk before the table moves.
        if let Some(log) = traffic
            && let Err(e) = log.sync()
        {
            return Outcome::FileError(format!("{}: {e}", run.dir.join(TRAFFIC).display()));
        }
        let target = mounting.table_deg(&stop, settings.faces);
        let approached = approach(
            table,
            target,
            stop.direction,
            settings.faces,
            &mut commanded,
        );
        let encoder = match approached {
            Ok(p) => p,
            Err(e) => return Outcome::from_instrument(TABLE, e),
        };
        if let Some(failed) = log_failure(run, traffic) {
            return failed;
        }
        if stop_flag.sleep(settle) {
            return Outcome::Interrupted;
        }
        for ac in to_read {
            if stop_flag.is_set() {
                return Outcome::Interrupted;
            }
            let taken = take_reading(
                run,
                acs,
                &mut *memory,
                traffic,
                stop,
                ac,
                encoder,
                &mut refused,
            );
            let reading = match taken {
                Ok(reading) => reading,
                Err(outcome) => return outcome,
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
            progress_now(run, stop, refused, None);
        }
    }
    Outcome::Completed
}

/// One piece of a session's work, in order.
enum Work {
    /// Visit the stop and read these autocollimators.
    Stop(Stop, Vec<u32>),
    /// The check after this cycle.
    Check(u32),
}

/// The session's work: the check of a cycle the session before did not check, then the
/// remaining stops, each cycle followed by its check.
fn session_work(run: &RunDir) -> Vec<Work> {
    let mut work = Vec::new();
    if let Some(cycle) = run.unchecked_cycle() {
        // The session before ended before the check after this cycle: done now, while
        // the polygon is still mounted so.
        work.push(Work::Check(cycle));
    }
    let remaining = run.remaining();
    for (index, (stop, to_read)) in remaining.iter().enumerate() {
        work.push(Work::Stop(*stop, to_read.clone()));
        let cycle_ends = remaining
            .get(index + 1)
            .is_none_or(|(next, _)| next.cycle != stop.cycle);
        if cycle_ends {
            work.push(Work::Check(stop.cycle));
        }
    }
    work
}

/// The instruments the check after a cycle drives.
struct Devices<'a, 'b> {
    acs: &'a mut [&'b mut dyn Autocollimator],
    table: &'a mut dyn RotaryTable,
}

/// Reads autocollimator `ac` at `stop` (the table at `encoder`) until its readings agree
/// and gives the reading to store; the outcome that ends the session otherwise.
#[allow(clippy::too_many_arguments)]
fn take_reading(
    run: &RunDir,
    acs: &mut [&mut dyn Autocollimator],
    memory: &mut [DeviceMemory],
    traffic: Option<&TrafficLog>,
    stop: Stop,
    ac: u32,
    encoder: f64,
    refused: &mut usize,
) -> Result<Reading, Outcome> {
    let settings = &run.manifest.settings;
    let mounting = run.mounting();
    let i = ac as usize - 1;
    let role = role(ac);
    let at = if mounting.setup > 1 {
        format!(
            "mounting {}, cycle {}, step {}",
            mounting.setup, stop.cycle, stop.step
        )
    } else {
        format!("cycle {}, step {}", stop.cycle, stop.step)
    };
    let label = format!("ac{ac}");
    let (Some(device), Some(memory)) = (acs.get_mut(i), memory.get_mut(i)) else {
        return Err(Outcome::InstrumentError(format!("{role} is not connected")));
    };
    let taken = read_at_stop(
        &mut **device,
        memory,
        settings,
        traffic,
        (&label, &role, &at),
        mounting.table_deg(&stop, settings.faces),
    );
    let (x_arcsec, y_arcsec) = match taken {
        Ok(r) => {
            *refused += r.refused;
            (r.x_arcsec, r.y_arcsec)
        }
        Err(RepeatError::Instrument(e)) => return Err(Outcome::from_instrument(&role, e)),
        Err(RepeatError::NoAgreement(message)) => return Err(Outcome::InstrumentError(message)),
    };
    Ok(Reading {
        setup: mounting.setup,
        cycle: stop.cycle,
        step: stop.step,
        ac,
        face: mounting.face(settings, ac, stop.step),
        reading_arcsec: x_arcsec,
        direction: stop.direction,
        time_seconds: Some(run.clock.now()),
        reading_y_arcsec: y_arcsec,
        temperature_celsius: None,
        encoder_degrees: Some(encoder),
        line: 0,
    })
}

/// The check after `cycle` (module `live`): fits the measurement file as it is on disk,
/// measures again the stop of the reading furthest beyond the run's noise (at most
/// [`MAX_REMEASURED_PER_CYCLE`] stops, each cell once a session: `handled`) and
/// replaces the reading of that stop's cell that disagrees with the new one (the
/// flagged reading or, with two cycles, its twin), or names the flagged reading suspect
/// when none does. Returns the cycle's summary.
#[allow(clippy::too_many_arguments)]
fn check_cycle(
    run: &mut RunDir,
    devices: Devices<'_, '_>,
    memory: &mut [DeviceMemory],
    stop_flag: &StopFlag,
    traffic: Option<&TrafficLog>,
    cycle: u32,
    handled: &mut Vec<Cell>,
    refused: &mut usize,
    commanded: &mut Option<f64>,
) -> Result<CycleCheck, Outcome> {
    let Devices { acs, table } = devices;
    let settings = run.manifest.settings.clone();
    let mounting = run.mounting();
    let path = run.dir.join(MEASUREMENTS);
    let read = || MeasurementSet::read_path(&path, Some(settings.faces)).ok();
    let mut remeasured = Vec::new();
    let mut suspect = Vec::new();
    let mut offsets = Vec::new();
    for round in 0..=MAX_REMEASURED_PER_CYCLE {
        let Some(set) = read() else {
            break;
        };
        let fit = live::fit(&set, &settings, judged_noise(memory, &settings));
        if round == 0 {
            offsets = live::summary(&set, fit.as_ref(), mounting.setup, cycle).offsets;
        }
        let Some(fit) = fit else {
            break;
        };
        if round == MAX_REMEASURED_PER_CYCLE {
            break;
        }
        let Some(i) = live::worst(&fit, mounting.setup, handled, &offsets) else {
            break;
        };
        if stop_flag.is_set() {
            return Err(Outcome::Interrupted);
        }
        let flagged = fit.readings[i].clone();
        let residual = fit.residuals[i];
        handled.push(live::cell(&flagged));
        let stop = Stop {
            cycle: flagged.cycle,
            step: flagged.step,
            direction: flagged.direction,
        };
        // Measured again from the reading's own direction.
        let target = mounting.table_deg(&stop, settings.faces);
        let encoder = match approach(
            &mut *table,
            target,
            stop.direction,
            settings.faces,
            commanded,
        ) {
            Ok(p) => p,
            Err(e) => return Err(Outcome::from_instrument(TABLE, e)),
        };
        if let Some(failed) = log_failure(run, traffic) {
            return Err(failed);
        }
        let settle = Duration::try_from_secs_f64(settings.settle_seconds).unwrap_or(Duration::ZERO);
        if stop_flag.sleep(settle) {
            return Err(Outcome::Interrupted);
        }
        let again = take_reading(
            run, &mut *acs, memory, traffic, stop, flagged.ac, encoder, refused,
        )?;
        // The reading of the cell furthest from the new one is replaced if it disagrees
        // beyond the tolerance of the autocollimator's measured noise (two means of
        // `reads` readings each differ by less than two readings do).
        let tolerance = memory
            .get(flagged.ac as usize - 1)
            .map_or(settings.agreement_arcsec(), |m| {
                m.noise.agreement_arcsec(settings.reading_noise_arcsec)
            });
        // Each compared with the table's offset from the stop taken out (a table that
        // stopped within its tolerance but off the stop is no fault of the reading).
        let at_stop = |r: &Reading| {
            r.reading_arcsec - live::stop_offset_arcsec(r, settings.faces, mounting.shift_deg)
        };
        let apart = |r: &Reading| (at_stop(r) - at_stop(&again)).abs();
        let off = fit
            .readings
            .iter()
            .filter(|r| live::cell(r) == live::cell(&flagged))
            .max_by(|a, b| apart(a).total_cmp(&apart(b)))
            .filter(|r| apart(r) > tolerance)
            .cloned();
        match off {
            Some(first) => {
                let residual_of_first = fit
                    .readings
                    .iter()
                    .position(|r| super::directory::key(r) == super::directory::key(&first))
                    .map_or(residual, |j| fit.residuals[j]);
                let replacement = Reading {
                    cycle: first.cycle,
                    ..again.clone()
                };
                let record = Remeasured {
                    setup: first.setup,
                    cycle: first.cycle,
                    step: first.step,
                    ac: first.ac,
                    first_arcsec: first.reading_arcsec,
                    reading_arcsec: replacement.reading_arcsec,
                    residual_arcsec: residual_of_first,
                    sigma_arcsec: fit.sigma,
                    found_after_cycle: cycle,
                };
                if let Some(log) = traffic {
                    log.record(
                        "",
                        "",
                        "remeasured",
                        &format!(
                            "cycle {}, step {}, autocollimator {}: {}″ replaced by {}″ (residual {:+.4}″, σ {:.4}″)",
                            first.cycle,
                            first.step,
                            first.ac,
                            first.reading_arcsec,
                            replacement.reading_arcsec,
                            residual_of_first,
                            fit.sigma
                        ),
                    );
                }
                if let Err(e) = run.replace_reading(&first, &replacement, record.clone()) {
                    return Err(Outcome::FileError(format!(
                        "{e} (the reading measured again not written: {})",
                        run.row(&replacement)
                    )));
                }
                remeasured.push(record);
            }
            None => {
                let record = Suspect {
                    setup: flagged.setup,
                    cycle: flagged.cycle,
                    step: flagged.step,
                    ac: flagged.ac,
                    reading_arcsec: flagged.reading_arcsec,
                    measured_again_arcsec: again.reading_arcsec,
                    residual_arcsec: residual,
                    sigma_arcsec: fit.sigma,
                    found_after_cycle: cycle,
                };
                if let Err(e) = run.record_suspect(record.clone()) {
                    return Err(Outcome::FileError(e.to_string()));
                }
                suspect.push(record);
            }
        }
    }
    let set = read();
    let mut check = match &set {
        Some(set) => live::summary(
            set,
            live::fit(set, &settings, judged_noise(memory, &settings)).as_ref(),
            mounting.setup,
            cycle,
        ),
        None => live::unchecked(mounting.setup, cycle),
    };
    check.remeasured = remeasured;
    check.suspect = suspect;
    let noise: Vec<RepeatNoise> = memory.iter().map(|m| m.noise).collect();
    if let Err(e) = run.record_noise(&noise) {
        return Err(Outcome::FileError(e.to_string()));
    }
    if let Some(warning) = &check.misfit
        && let Err(e) = run.record_misfit(warning)
    {
        return Err(Outcome::FileError(e.to_string()));
    }
    Ok(check)
}

/// The noise of one reading the live check judges by: the largest of the
/// autocollimators' [`RepeatNoise::sigma_used_arcsec`] (each the stated noise until its
/// repeats show less), so that no autocollimator's readings are judged by another's
/// smaller noise.
fn judged_noise(memory: &[DeviceMemory], settings: &super::RunSettings) -> f64 {
    let stated = settings.reading_noise_arcsec;
    if memory.is_empty() {
        return stated;
    }
    memory
        .iter()
        .map(|m| m.noise.sigma_used_arcsec(stated))
        .fold(0.0, f64::max)
        .min(stated)
        .max(f64::MIN_POSITIVE)
}
