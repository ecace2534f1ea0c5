//! The checks before a session stores its first reading (docs/FORMAT.md §7.3, *Before
//! the first reading of a session*): what the autocollimators gave before the session,
//! carried over so that a stale repeat of it is refused; a resumed mounting's last stop
//! read again and compared with what the run stored there; and a new mounting's first
//! stop compared with what the mountings before it predict of each autocollimator's Y
//! axis (the face it sees) and X axis (the polygon not remounted).
//!
//! The verdicts are decided here from readings the session took (`session.rs` visits the
//! stop and reads it); none of those readings is stored: the `compared` record of the
//! traffic log keeps them.

use std::collections::BTreeMap;

use super::repeat::{DeviceMemory, LastValue, StopReading};
use super::store::RunSoFar;
use super::{Mounting, Outcome};
use crate::measurement::{Reading, Stop};

/// Mounting `setup` as the run records it.
fn mounting_of(run: &RunSoFar, setup: u32) -> Mounting {
    run.mountings
        .iter()
        .find(|m| m.mounting.setup == setup)
        .map_or_else(|| Mounting::new(setup), |m| m.mounting)
}

/// The stop of a stored reading.
pub(super) fn stop_of(reading: &Reading) -> Stop {
    Stop {
        cycle: reading.cycle,
        step: reading.step,
        direction: reading.direction,
    }
}

/// Each autocollimator's memory at the start of the session: the values it gave before,
/// which it must not give again at another stop — its last reply the store knows of
/// (with the table position commanded before it) and its last stored reading (the
/// latest `time`, with its stop's table angle) — and the noise the sessions before
/// measured.
pub(super) fn carried_memory(run: &RunSoFar) -> Vec<DeviceMemory> {
    let settings = &run.settings;
    let mut values: Vec<Vec<(LastValue, f64)>> = vec![Vec::new(); settings.autocollimators()];
    for ac in settings.acs() {
        let last = run.readings.iter().filter(|r| r.ac == ac).max_by(|a, b| {
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
    for (slot, reply) in values.iter_mut().zip(&run.last_replies) {
        if let Some(value) = reply {
            slot.push(*value);
        }
    }
    let mut memory: Vec<DeviceMemory> =
        values.into_iter().map(DeviceMemory::carried_over).collect();
    // The noise the sessions before measured, as the run recorded it.
    for record in &run.repeat_noise {
        if let Some(m) = memory.get_mut((record.ac as usize).wrapping_sub(1)) {
            m.noise = super::noise::RepeatNoise::from_record(record);
        }
    }
    memory
}

/// `cycle 2, step 5` (`mounting 2, cycle 1, step 0` after the first mounting).
pub(super) fn place(mounting: Mounting, stop: &Stop) -> String {
    if mounting.setup > 1 {
        format!(
            "mounting {}, cycle {}, step {}",
            mounting.setup, stop.cycle, stop.step
        )
    } else {
        format!("cycle {}, step {}", stop.cycle, stop.step)
    }
}

/// What a check before the first reading found: the `compared` record for the traffic
/// log, and the outcome that ends the session when the readings do not agree.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Verdict {
    /// The `compared` record.
    pub(super) compared: String,
    /// The refusal, if any ([`Outcome::InstrumentError`] saying what was found).
    pub(super) refused: Option<Outcome>,
}

/// The stop a resumed mounting reads again: the last with a stored reading of it.
pub(super) fn last_stop(run: &RunSoFar) -> Option<Stop> {
    let setup = run.mounting().setup;
    run.readings.iter().rfind(|r| r.setup == setup).map(stop_of)
}

/// A resumed mounting: the readings `read` again at its last stop with stored readings
/// (autocollimator 1 first) against the ones the run stored there; they must agree
/// within [`RunSettings::agreement_arcsec`](super::RunSettings::agreement_arcsec), X and
/// (where both have one) Y, the face's pyramidal error. Otherwise the autocollimators are
/// not where they were (their ports swapped: autocollimators that identify alike pass
/// the identification) or the polygon moved, and the session ends saying which.
pub(super) fn last_stop_verdict(run: &RunSoFar, stop: Stop, read: &[StopReading]) -> Verdict {
    let mounting = run.mounting();
    let settings = &run.settings;
    let rows = &run.readings;
    let at_stop = |ac: u32| {
        rows.iter().find(|r| {
            (r.setup, r.cycle, r.step, r.ac) == (mounting.setup, stop.cycle, stop.step, ac)
        })
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
    let compared = format!("{at}, read again on resuming: {}: {agree}", seen.join(", "));
    if off.is_empty() {
        return Verdict {
            compared,
            refused: None,
        };
    }
    let port = |ac: u32| {
        run.ac_names
            .get(ac as usize - 1)
            .map_or("", String::as_str)
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
    Verdict {
        compared,
        refused: Some(Outcome::InstrumentError(format!(
            "{} (more than the agreement tolerance {tolerance:.3}″ apart): {why}; nothing new \
             was stored, resume once the readings there agree again",
            found.join("; ")
        ))),
    }
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

/// A mounting after the first, before any reading of it is stored: the readings `read`
/// at its first stop `stop` (autocollimator 1 first; nothing stored) against what the
/// mountings before it predict. Each face's Y reading (its pyramidal error, the same in
/// every mounting) tells which face each autocollimator sees: the faces the stated face
/// shift puts there must match within
/// [`RunSettings::agreement_arcsec`](super::RunSettings::agreement_arcsec), or — when
/// another face shift's faces do — the session ends: the polygon not remounted (the
/// faces and X readings the mounting before had at this table angle) or turned otherwise
/// than stated. Without Y readings to compare (an autocollimator whose Y is not valid),
/// or when no face shift matches, nothing is decided here (the check after the first
/// cycle tests the mounting as a whole).
pub(super) fn new_mounting_verdict(run: &RunSoFar, stop: Stop, read: &[StopReading]) -> Verdict {
    let mounting = run.mounting();
    let settings = &run.settings;
    let n = settings.faces;
    let rows: Vec<&Reading> = run
        .readings
        .iter()
        .filter(|r| r.setup < mounting.setup)
        .collect();
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
            .map(|ac| turned.face(settings, ac, stop.step))
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
        return Verdict {
            compared: format!(
                "{mounting}, {at}, its first stop: X {}; no Y to compare",
                values_text(&x)
            ),
            refused: None,
        };
    };
    let best = (0..n)
        .filter_map(|k| score(k).map(|s| (k, s)))
        .min_by(|a, b| a.1.total_cmp(&b.1));
    let y = y.unwrap_or_default();
    let verdict = match best {
        Some((k, s)) if stated_score > tolerance && s <= tolerance && k != stated => Some(k),
        _ => None,
    };
    let compared = format!(
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
    );
    let Some(k) = verdict else {
        return Verdict {
            compared,
            refused: None,
        };
    };
    let seen = faces(k);
    // The mounting before: the faces it had at this table angle, and its X there.
    let angle = mounting.table_deg(&stop, n);
    let before = run
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
            .map(|ac| b.face(settings, ac, step))
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
    Verdict {
        compared,
        refused: Some(Outcome::InstrumentError(message)),
    }
}
