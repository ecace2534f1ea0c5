//! The checks before a session stores its first reading (docs/FORMAT.md §7.3, *Before
//! the first reading of a session*): what the autocollimators gave before the session,
//! carried over so that a stale repeat of it is refused; a resumed mounting's last stop
//! read again and compared with what the run stored there; and a new mounting's first
//! stop compared with what the mountings before it predict of each autocollimator's Y
//! axis (the face it sees) and X axis (the polygon not remounted).
//!
//! None of the readings taken here is stored: the `compared` record of `traffic.jsonl`
//! keeps them.

use std::collections::BTreeMap;
use std::time::Duration;

use super::measure::{Outcome, TABLE, log_failure, role};
use super::repeat::{DeviceMemory, LastValue, RepeatError, StopReading, read_at_stop};
use super::{MEASUREMENTS, Mounting, RunDir, TRAFFIC};
use crate::lab::profile::Profile;
use crate::lab::traffic::TrafficLog;
use crate::lab::{Autocollimator, RotaryTable, StopFlag};
use crate::measurement::{Reading, Stop, read_rows};

/// The readings on disk, all mountings, in the file's order (none when the file cannot
/// be read: it was checked when the run was opened).
fn stored(run: &RunDir) -> Vec<Reading> {
    let path = run.dir.join(MEASUREMENTS);
    std::fs::read(&path)
        .ok()
        .and_then(|bytes| read_rows(bytes.as_slice(), &path.display().to_string()).ok())
        .unwrap_or_default()
}

/// Mounting `setup` as the manifest records it.
fn mounting_of(run: &RunDir, setup: u32) -> Mounting {
    run.manifest
        .mountings
        .iter()
        .find(|m| m.mounting.setup == setup)
        .map_or_else(|| Mounting::new(setup), |m| m.mounting)
}

/// The stop of a stored reading.
fn stop_of(reading: &Reading) -> Stop {
    Stop {
        cycle: reading.cycle,
        step: reading.step,
        direction: reading.direction,
    }
}

/// Each autocollimator's memory at the start of the session: the values it gave before,
/// which it must not give again at another stop — its last reply in the traffic log
/// (with the table position commanded before it) and its last stored reading (the
/// latest `time`, with its stop's table angle).
pub(super) fn carried_memory(run: &RunDir) -> Vec<DeviceMemory> {
    let settings = &run.manifest.settings;
    let mut values: Vec<Vec<(LastValue, f64)>> = vec![Vec::new(); settings.autocollimators()];
    let rows = stored(run);
    for ac in settings.acs() {
        let last = rows.iter().filter(|r| r.ac == ac).max_by(|a, b| {
            a.time_seconds
                .unwrap_or(f64::NEG_INFINITY)
                .total_cmp(&b.time_seconds.unwrap_or(f64::NEG_INFINITY))
        });
        if let (Some(r), Some(slot)) = (last, values.get_mut(ac as usize - 1)) {
            let angle = mounting_of(run, r.setup).table_deg(&stop_of(r), settings.faces);
            slot.push((
                LastValue {
                    x_arcsec: r.reading_arcsec,
                    y_arcsec: r.reading_y_arcsec,
                    status: None,
                },
                angle,
            ));
        }
    }
    for (ac, value) in last_replies(run, settings.autocollimators()) {
        if let Some(slot) = values.get_mut(ac) {
            slot.push(value);
        }
    }
    let mut memory: Vec<DeviceMemory> =
        values.into_iter().map(DeviceMemory::carried_over).collect();
    // The noise the sessions before measured, as the manifest recorded it.
    for record in &run.manifest.repeat_noise {
        if let Some(m) = memory.get_mut((record.ac as usize).wrapping_sub(1)) {
            m.noise = super::noise::RepeatNoise::from_record(record);
        }
    }
    memory
}

/// The profiles a session's `session` line in the traffic log names (`--ac-profile NAME
/// --table-profile NAME`, as `polycal run` writes it); the bundled `elcomat3000` and
/// `smc100` when it names none (a run driven through the library). `None` when a named
/// profile cannot be loaded any more (a file moved away).
fn session_profiles(text: &str) -> Option<(Profile, Profile)> {
    let named = |option: &str, default: &str| -> Option<Profile> {
        let name = match text.split(option).nth(1) {
            Some(rest) => rest.split_whitespace().next()?,
            None => default,
        };
        Profile::load(name).ok()
    };
    Some((
        named("--ac-profile ", "elcomat3000")?,
        named("--table-profile ", "smc100")?,
    ))
}

/// The last measurement reply of each autocollimator (index 0 … K−1) the traffic log
/// holds, with the table position commanded last before it, degrees; each session's
/// lines read with the profiles it names.
fn last_replies(run: &RunDir, k: usize) -> Vec<(usize, (LastValue, f64))> {
    let Ok(text) = std::fs::read_to_string(run.dir.join(TRAFFIC)) else {
        return Vec::new();
    };
    let mut profiles = session_profiles("");
    let mut angle: Option<f64> = None;
    let mut last: Vec<Option<(LastValue, f64)>> = vec![None; k];
    for line in text.lines() {
        let Ok(record) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let field = |name: &str| record.get(name).and_then(|v| v.as_str()).unwrap_or("");
        let (device, event, text) = (field("device"), field("event"), field("text"));
        if event == "session" {
            profiles = session_profiles(text);
            continue;
        }
        let Some((ac_profile, table_profile)) = &profiles else {
            continue;
        };
        if device == "table" && event == "sent" {
            if let Ok(table) = table_profile.table()
                && let Some(deg) = table.commanded_deg(text)
            {
                angle = Some(deg);
            }
            continue;
        }
        if event != "received" {
            continue;
        }
        let index = device
            .strip_prefix("ac")
            .and_then(|n| n.parse::<usize>().ok())
            .and_then(|n| n.checked_sub(1))
            .filter(|&i| i < k);
        let reply = ac_profile
            .autocollimator()
            .ok()
            .and_then(|ac| ac.reading(text).ok());
        if let (Some(i), Some(deg), Some(reply)) = (index, angle, reply) {
            last[i] = Some((
                LastValue {
                    x_arcsec: reply.x_arcsec,
                    y_arcsec: reply.y_arcsec,
                    status: Some(reply.status),
                },
                deg,
            ));
        }
    }
    last.into_iter()
        .enumerate()
        .filter_map(|(i, v)| v.map(|v| (i, v)))
        .collect()
}

/// The instruments and what the checks share with the measuring loop.
pub(super) struct Bench<'a, 'b> {
    /// The autocollimators 1 … K.
    pub(super) acs: &'a mut [&'b mut dyn Autocollimator],
    /// The table.
    pub(super) table: &'a mut dyn RotaryTable,
    /// Each autocollimator's memory, handed on to the measuring loop.
    pub(super) memory: &'a mut [DeviceMemory],
    /// The stop flag.
    pub(super) stop_flag: &'a StopFlag,
    /// The traffic log.
    pub(super) traffic: Option<&'a TrafficLog>,
}

/// `cycle 2, step 5` (`mounting 2, cycle 1, step 0` after the first mounting).
fn place(mounting: Mounting, stop: &Stop) -> String {
    if mounting.setup > 1 {
        format!(
            "mounting {}, cycle {}, step {}",
            mounting.setup, stop.cycle, stop.step
        )
    } else {
        format!("cycle {}, step {}", stop.cycle, stop.step)
    }
}

/// Moves the table to `stop` of the session's mounting (the commanded position the run
/// sends there), waits the settle time and reads every autocollimator until its readings
/// agree (`repeat`). Nothing is stored.
fn read_every_ac(
    run: &RunDir,
    bench: &mut Bench<'_, '_>,
    stop: &Stop,
) -> Result<Vec<StopReading>, Outcome> {
    let settings = &run.manifest.settings;
    let mounting = run.mounting();
    let angle = mounting.table_deg(stop, settings.faces);
    if bench.stop_flag.is_set() {
        return Err(Outcome::Interrupted);
    }
    if let Err(e) = bench.table.move_to(angle) {
        return Err(Outcome::from_instrument(TABLE, e));
    }
    if let Some(failed) = log_failure(run, bench.traffic) {
        return Err(failed);
    }
    let settle = Duration::try_from_secs_f64(settings.settle_seconds).unwrap_or(Duration::ZERO);
    if bench.stop_flag.sleep(settle) {
        return Err(Outcome::Interrupted);
    }
    let at = place(mounting, stop);
    let mut read = Vec::with_capacity(bench.acs.len());
    for (i, (device, memory)) in bench
        .acs
        .iter_mut()
        .zip(bench.memory.iter_mut())
        .enumerate()
    {
        if bench.stop_flag.is_set() {
            return Err(Outcome::Interrupted);
        }
        let ac = i as u32 + 1;
        let (label, role) = (format!("ac{ac}"), role(ac));
        match read_at_stop(
            &mut **device,
            memory,
            settings,
            bench.traffic,
            (&label, &role, &at),
            angle,
        ) {
            Ok(r) => read.push(r),
            Err(RepeatError::Instrument(e)) => return Err(Outcome::from_instrument(&role, e)),
            Err(RepeatError::NoAgreement(m)) => return Err(Outcome::InstrumentError(m)),
        }
    }
    if let Some(failed) = log_failure(run, bench.traffic) {
        return Err(failed);
    }
    Ok(read)
}

/// Records a check's readings in the traffic log (`compared`).
fn record(bench: &Bench<'_, '_>, text: &str) {
    if let Some(log) = bench.traffic {
        log.record("", "", "compared", text);
    }
}

/// The checks before the session's first reading, when it did not begin with a remount
/// (whose own check is [`new_mounting_fits`]): a mounting with readings on disk has its
/// last stop read again ([`last_stop_agrees`]); a mounting after the first without any
/// has its first stop checked ([`new_mounting_fits`]). The outcome that ends the session,
/// if any; nothing is stored either way.
pub(super) fn before_first_reading(run: &mut RunDir, bench: &mut Bench<'_, '_>) -> Option<Outcome> {
    if run.remaining().is_empty() && run.unchecked_cycle().is_none() {
        return None;
    }
    let setup = run.mounting().setup;
    let rows = stored(run);
    if rows.iter().any(|r| r.setup == setup) {
        return last_stop_agrees(run, bench, &rows);
    }
    if setup > 1 {
        return match new_mounting_fits(run, bench)? {
            Stopped::Ended(outcome) => Some(outcome),
            Stopped::Refused(outcome) => {
                // The polygon is to be mounted again: its remount is asked for again.
                if let Err(e) = run.withdraw_remount() {
                    return Some(Outcome::FileError(e.to_string()));
                }
                Some(outcome)
            }
        };
    }
    None
}

/// How the check of a new mounting's first stop ended the session.
#[derive(Debug)]
pub(super) enum Stopped {
    /// An instrument or a file failed, or the run was interrupted.
    Ended(Outcome),
    /// The readings show the polygon not mounted as stated ([`Outcome::InstrumentError`]
    /// saying how).
    Refused(Outcome),
}

impl Stopped {
    /// The session's outcome.
    pub(super) fn outcome(self) -> Outcome {
        match self {
            Stopped::Ended(outcome) | Stopped::Refused(outcome) => outcome,
        }
    }
}

/// A resumed mounting: the last stop with readings on disk is visited again, every
/// autocollimator read there, and each reading compared with the one the run stored of
/// it at that stop; they must agree within
/// [`RunSettings::agreement_arcsec`](super::RunSettings::agreement_arcsec), X and (where
/// both have one) Y, the face's pyramidal error. Otherwise the autocollimators are not where
/// they were (their ports swapped: autocollimators that identify alike pass
/// [`RunDir::begin_session`]) or the polygon moved, and the session ends with
/// [`Outcome::InstrumentError`] saying which.
fn last_stop_agrees(run: &RunDir, bench: &mut Bench<'_, '_>, rows: &[Reading]) -> Option<Outcome> {
    let mounting = run.mounting();
    let settings = run.manifest.settings.clone();
    let last = rows.iter().rfind(|r| r.setup == mounting.setup)?;
    let stop = stop_of(last);
    let at_stop = |ac: u32| {
        rows.iter().find(|r| {
            (r.setup, r.cycle, r.step, r.ac) == (mounting.setup, stop.cycle, stop.step, ac)
        })
    };
    let read = match read_every_ac(run, bench, &stop) {
        Ok(read) => read,
        Err(outcome) => return Some(outcome),
    };
    let tolerance = settings.agreement_arcsec();
    let at = place(mounting, &stop);
    // Two axes agree when X does, and Y too where both have one.
    let apart = |x: f64, y: Option<f64>, s: &Reading| -> (bool, bool) {
        let y_apart = match (y, s.reading_y_arcsec) {
            (Some(a), Some(b)) => (a - b).abs() > tolerance,
            _ => false,
        };
        ((x - s.reading_arcsec).abs() > tolerance, y_apart)
    };
    let y_text = |y: Option<f64>| y.map_or_else(|| "none".to_string(), |y| format!("{y:.4}″"));
    let mut seen = Vec::new();
    let mut off = Vec::new();
    for (i, r) in read.iter().enumerate() {
        let ac = i as u32 + 1;
        match at_stop(ac) {
            Some(s) => {
                seen.push(format!(
                    "ac{ac} X {:.4}″, Y {} (stored {:.4}″, {})",
                    r.x_arcsec,
                    y_text(r.y_arcsec),
                    s.reading_arcsec,
                    y_text(s.reading_y_arcsec)
                ));
                let (x_apart, y_apart) = apart(r.x_arcsec, r.y_arcsec, s);
                if x_apart || y_apart {
                    off.push((ac, r, s, x_apart));
                }
            }
            None => seen.push(format!(
                "ac{ac} X {:.4}″, Y {} (none stored)",
                r.x_arcsec,
                y_text(r.y_arcsec)
            )),
        }
    }
    let agree = if off.is_empty() {
        "agree"
    } else {
        "do not agree"
    };
    record(
        bench,
        &format!("{at}, read again on resuming: {}: {agree}", seen.join(", ")),
    );
    if off.is_empty() {
        return None;
    }
    let port = |ac: u32| {
        bench
            .acs
            .get(ac as usize - 1)
            .map_or("", |a| a.port())
            .to_string()
    };
    let found: Vec<String> = off
        .iter()
        .map(|&(ac, r, s, x_apart)| {
            let (now, before) = if x_apart {
                (
                    format!("{:.3}″", r.x_arcsec),
                    format!("{:.3}″", s.reading_arcsec),
                )
            } else {
                (
                    format!("Y {}", y_text(r.y_arcsec)),
                    format!("Y {}", y_text(s.reading_y_arcsec)),
                )
            };
            format!(
                "ac{ac} ({}) reads {now} at {at} where the run stored {before} before the interruption",
                port(ac)
            )
        })
        .collect();
    // Each one off reads what another autocollimator stored there: swapped ports.
    let like: Vec<String> = off
        .iter()
        .filter_map(|&(ac, r, _, _)| {
            settings
                .acs()
                .filter(|&other| other != ac)
                .find(|&other| {
                    at_stop(other)
                        .is_some_and(|s| apart(r.x_arcsec, r.y_arcsec, s) == (false, false))
                })
                .map(|other| format!("ac{ac} reads what ac{other} stored"))
        })
        .collect();
    let why = if like.len() == off.len() {
        format!(
            "{}: the autocollimators' ports look swapped — connect each to the port it had \
             before the interruption",
            like.join(", ")
        )
    } else {
        "are the ports swapped, or was the polygon or an autocollimator moved? Put them back \
         as they were"
            .to_string()
    };
    Some(Outcome::InstrumentError(format!(
        "{} (more than the agreement tolerance {tolerance:.3}″ apart): {why}; nothing new \
         was stored, resume once the readings there agree again",
        found.join("; ")
    )))
}

/// Faces as a message lists them: `faces 4, 5`.
fn faces_text(faces: &[usize]) -> String {
    let list: Vec<String> = faces.iter().map(usize::to_string).collect();
    format!("faces {}", list.join(", "))
}

/// Values as a message lists them, arcsec: `1.234″, -0.567″`.
fn values_text(values: &[f64]) -> String {
    let list: Vec<String> = values.iter().map(|v| format!("{v:.3}″")).collect();
    list.join(", ")
}

/// A mounting after the first, before any reading of it is stored: its first stop is
/// visited, every autocollimator read there (nothing stored), and the readings compared
/// with what the mountings before it predict. Each face's Y reading (its pyramidal
/// error, the same in every mounting) tells which face each autocollimator sees: the
/// faces the stated face shift puts there must match within
/// [`RunSettings::agreement_arcsec`](super::RunSettings::agreement_arcsec), or — when
/// another face shift's faces do — the session ends with [`Outcome::InstrumentError`]:
/// the polygon not remounted (the faces and X readings the mounting before had at this
/// table angle) or turned otherwise than stated. Without Y readings to compare (an
/// autocollimator whose Y is not valid), or when no face shift matches, nothing is
/// decided here (the check after the first cycle tests the mounting as a whole).
pub(super) fn new_mounting_fits(run: &RunDir, bench: &mut Bench<'_, '_>) -> Option<Stopped> {
    let mounting = run.mounting();
    let settings = run.manifest.settings.clone();
    let n = settings.faces;
    let stop = run.remaining().first()?.0;
    let rows: Vec<Reading> = stored(run)
        .into_iter()
        .filter(|r| r.setup < mounting.setup)
        .collect();
    let read = match read_every_ac(run, bench, &stop) {
        Ok(read) => read,
        Err(outcome) => return Some(Stopped::Ended(outcome)),
    };
    let at = format!("cycle {}, step {}", stop.cycle, stop.step);
    let x: Vec<f64> = read.iter().map(|r| r.x_arcsec).collect();
    // Each autocollimator's Y of each face in the mountings before.
    let mut y_of: BTreeMap<(u32, usize), (f64, usize)> = BTreeMap::new();
    for r in &rows {
        if let Some(y) = r.reading_y_arcsec {
            let e = y_of.entry((r.ac, r.face)).or_insert((0.0, 0));
            *e = (e.0 + y, e.1 + 1);
        }
    }
    let faces = |k: usize| -> Vec<usize> {
        let turned = Mounting::new(mounting.setup).with_face_shift(k);
        settings
            .acs()
            .map(|ac| turned.face(&settings, ac, stop.step))
            .collect()
    };
    let predicted = |k: usize| -> Option<Vec<f64>> {
        faces(k)
            .iter()
            .zip(settings.acs())
            .map(|(&f, ac)| y_of.get(&(ac, f)).map(|&(sum, count)| sum / count as f64))
            .collect()
    };
    let y: Option<Vec<f64>> = read.iter().map(|r| r.y_arcsec).collect();
    let score = |k: usize| -> Option<f64> {
        let (y, p) = (y.as_ref()?, predicted(k)?);
        Some(
            y.iter()
                .zip(&p)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max),
        )
    };
    let tolerance = settings.agreement_arcsec();
    let stated = mounting.face_shift;
    let Some(stated_score) = score(stated) else {
        record(
            bench,
            &format!(
                "{mounting}, {at}, its first stop: X {}; no Y to compare",
                values_text(&x)
            ),
        );
        return None;
    };
    let best = (0..n)
        .filter_map(|k| score(k).map(|s| (k, s)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let y = y.unwrap_or_default();
    let verdict = match best {
        Some((k, s)) if stated_score > tolerance && s <= tolerance && k != stated => Some(k),
        _ => None,
    };
    record(
        bench,
        &format!(
            "{mounting}, {at}, its first stop: X {}, Y {} ({} as stated: Y {}): {}",
            values_text(&x),
            values_text(&y),
            faces_text(&faces(stated)),
            values_text(&predicted(stated).unwrap_or_default()),
            if verdict.is_some() {
                "do not agree"
            } else {
                "agree"
            }
        ),
    );
    let k = verdict?;
    let seen = faces(k);
    // The mounting before: the faces it had at this table angle, and its X there.
    let angle = mounting.table_deg(&stop, n);
    let before = run
        .manifest
        .mountings
        .iter()
        .rev()
        .map(|m| m.mounting)
        .find(|m| m.setup < mounting.setup);
    let not_remounted = before.and_then(|b| {
        let q = (angle - b.shift_deg) * n as f64 / 360.0;
        if (q - q.round()).abs() > 1e-6 {
            return None;
        }
        let step = (q.round() as i64).rem_euclid(n as i64) as usize;
        let old: Vec<usize> = settings
            .acs()
            .map(|ac| b.face(&settings, ac, step))
            .collect();
        if old != seen {
            return None;
        }
        let x_before: Option<Vec<f64>> = settings
            .acs()
            .map(|ac| {
                let (sum, count) = rows
                    .iter()
                    .filter(|r| r.setup == b.setup && r.ac == ac && r.step % n == step)
                    .fold((0.0, 0usize), |(s, c), r| (s + r.reading_arcsec, c + 1));
                (count > 0).then(|| sum / count as f64)
            })
            .collect();
        let x_before = x_before?;
        x.iter()
            .zip(&x_before)
            .all(|(a, b)| (a - b).abs() <= tolerance)
            .then_some((b, x_before))
    });
    let stated_faces = faces(stated);
    let first_face = stated_faces.first().copied().unwrap_or(0);
    let message = match not_remounted {
        Some((b, x_before)) => format!(
            "at the first stop of {mounting}, {at}, the table at {angle}°, the autocollimators \
             read what they read at this table angle in mounting {}: X {} against {} then, \
             and Y as {} (not {} as stated): the polygon was not remounted; mount it with face \
             {first_face} facing autocollimator 1, the table at {angle}°, and run the same \
             command again; nothing of mounting {} was stored",
            b.setup,
            values_text(&x),
            values_text(&x_before),
            faces_text(&seen),
            faces_text(&stated_faces),
            mounting.setup
        ),
        None => {
            let mut told = mounting;
            told.face_shift = k;
            format!(
                "at the first stop of {mounting}, {at}, the autocollimators see {} (the polygon \
                 turned {k} face(s)), not {} as stated: their Y readings {} are those of {} in \
                 the mountings before ({}), not those of {} ({}); state the mounting as it is \
                 ({}) or mount it as stated, and run again; nothing of mounting {} was stored",
                faces_text(&seen),
                faces_text(&stated_faces),
                values_text(&y),
                faces_text(&seen),
                values_text(&predicted(k).unwrap_or_default()),
                faces_text(&stated_faces),
                values_text(&predicted(stated).unwrap_or_default()),
                told.as_options(),
                mounting.setup
            )
        }
    };
    Some(Stopped::Refused(Outcome::InstrumentError(message)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lab::run::{Ports, RunSettings};
    use crate::lab::{AcReading, InstrumentError};

    /// An autocollimator that gives a list of X values, Y 0, status 003.
    struct Replay(Vec<f64>);

    impl Autocollimator for Replay {
        fn port(&self) -> &str {
            "mem"
        }
        fn start(&mut self) -> Result<(), InstrumentError> {
            Ok(())
        }
        fn identify(&mut self) -> Result<String, InstrumentError> {
            Ok("replay".into())
        }
        fn measure(&mut self) -> Result<AcReading, InstrumentError> {
            if self.0.is_empty() {
                return Err(InstrumentError::Closed {
                    port: "mem".into(),
                    context: "end".into(),
                });
            }
            Ok(AcReading::new(3, self.0.remove(0), Some(0.0)))
        }
    }

    #[test]
    fn the_last_reply_in_the_traffic_log_is_carried_over_with_its_table_position() {
        let dir = std::env::temp_dir().join(format!("polycal-verify-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let settings = RunSettings::new(8, 1).with_reading_noise_arcsec(0.05);
        let run = RunDir::open(&dir, &settings, &Ports::default(), false).unwrap();
        // ac1 last replied 1.5″ with the table sent to 405° (= 45°); a line that is not a
        // measurement and a record cut short change nothing.
        let records = [
            r#"{"t":0,"device":"table","port":"p","event":"sent","text":"1PA405\r\n"}"#,
            r#"{"t":0,"device":"ac1","port":"p","event":"received","text":"4 003 1.5 0.0"}"#,
            r#"{"t":0,"device":"ac1","port":"p","event":"received","text":"8 ELCOMAT 3000"}"#,
            r#"{"t":0,"device":"ac2","port":"p","event":"recei"#,
        ];
        std::fs::write(dir.join(TRAFFIC), records.join("\n")).unwrap();
        let read = |memory: &mut DeviceMemory, values: &[f64], angle: f64| {
            read_at_stop(
                &mut Replay(values.to_vec()),
                memory,
                &settings,
                None,
                ("ac1", "autocollimator 1", "cycle 1, step 2"),
                angle,
            )
            .map_err(|_| "no reading")
        };
        let mut carried = carried_memory(&run);
        assert_eq!(carried.len(), 2);
        // At another stop the value is refused as stale, at 45° read again.
        let r = read(&mut carried[0].clone(), &[1.5, 1.6, 1.7], 90.0).unwrap();
        assert_eq!(r.refused, 1);
        assert!((r.x_arcsec - 1.65).abs() < 1e-12);
        let r = read(&mut carried[0], &[1.5, 1.6], 45.0).unwrap();
        assert_eq!(r.refused, 0);
        // ac2 has nothing carried over.
        let r = read(&mut carried[1], &[1.5, 1.6], 90.0).unwrap();
        assert_eq!(r.refused, 0);
        drop(run);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
