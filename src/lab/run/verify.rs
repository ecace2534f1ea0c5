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
    let tolerance = run.settings.agreement_arcsec();
    let at = place(run.mounting(), &stop);
    let (seen, off) = read_again_against_stored(run, &stop, read, tolerance);
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
    let found = disagreements_text(run, &off, &at);
    let why = why_apart(run, &stop, &off, tolerance);
    Verdict {
        compared,
        refused: Some(Outcome::InstrumentError(format!(
            "{} (more than the agreement tolerance {tolerance:.3}″ apart): {why}; nothing new \
             was stored, resume once the readings there agree again",
            found.join("; ")
        ))),
    }
}

/// The reading autocollimator `ac` gave at `stop` of the run's current mounting, as the
/// run stored it.
fn stored_at<'a>(run: &'a RunSoFar, stop: &Stop, ac: u32) -> Option<&'a Reading> {
    let setup = run.mounting().setup;
    run.readings
        .iter()
        .find(|r| (r.setup, r.cycle, r.step, r.ac) == (setup, stop.cycle, stop.step, ac))
}

/// Whether a reading read again (X `x` and Y `y`, arcsec) is more than `tolerance`
/// arcsec from the stored reading `stored`: in X, and in Y where both have one (two
/// readings agree when neither is).
fn apart(x: f64, y: Option<f64>, stored: &Reading, tolerance: f64) -> (bool, bool) {
    let y_apart = match (y, stored.reading_y_arcsec) {
        (Some(a), Some(b)) => (a - b).abs() > tolerance,
        _ => false,
    };
    ((x - stored.reading_arcsec).abs() > tolerance, y_apart)
}

/// A Y reading as a message gives it, arcsec: `0.1234″`, or `none` without one.
fn y_text(y: Option<f64>) -> String {
    y.map_or_else(|| "none".to_string(), |y| format!("{y:.4}″"))
}

/// An autocollimator whose reading read again at a resumed mounting's last stop is more
/// than the agreement tolerance from the one the run stored there.
struct ReadApart<'a> {
    /// The autocollimator, 1 … K.
    ac: u32,
    /// Its reading now.
    read: &'a StopReading,
    /// Its reading the run stored there.
    stored: &'a Reading,
    /// Whether X is apart (else only Y is).
    x_apart: bool,
}

/// The stop read again against its stored readings: each autocollimator's X and Y now
/// and stored (arcsec) as the `compared` record lists them, and the autocollimators
/// whose readings are more than `tolerance` arcsec apart.
fn read_again_against_stored<'a>(
    run: &'a RunSoFar,
    stop: &Stop,
    read: &'a [StopReading],
    tolerance: f64,
) -> (Vec<String>, Vec<ReadApart<'a>>) {
    let mut seen = Vec::new();
    let mut off = Vec::new();
    for (i, r) in read.iter().enumerate() {
        let ac = i as u32 + 1;
        match stored_at(run, stop, ac) {
            Some(s) => {
                seen.push(format!(
                    "ac{ac} X {:.4}″, Y {} (stored {:.4}″, {})",
                    r.x_arcsec,
                    y_text(r.y_arcsec),
                    s.reading_arcsec,
                    y_text(s.reading_y_arcsec)
                ));
                let (x_apart, y_apart) = apart(r.x_arcsec, r.y_arcsec, s, tolerance);
                if x_apart || y_apart {
                    off.push(ReadApart {
                        ac,
                        read: r,
                        stored: s,
                        x_apart,
                    });
                }
            }
            None => seen.push(format!(
                "ac{ac} X {:.4}″, Y {} (none stored)",
                r.x_arcsec,
                y_text(r.y_arcsec)
            )),
        }
    }
    (seen, off)
}

/// What each autocollimator apart (`off`) reads now at `at` and what the run stored
/// there before the interruption, with its port: X (arcsec) where X is apart, else Y.
fn disagreements_text(run: &RunSoFar, off: &[ReadApart], at: &str) -> Vec<String> {
    let port = |ac: u32| {
        run.ac_names
            .get(ac as usize - 1)
            .map_or("", String::as_str)
            .to_string()
    };
    off.iter()
        .map(|&ReadApart {
            ac,
            read: r,
            stored: s,
            x_apart,
        }| {
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
        .collect()
}

/// Why the readings at `stop` are apart: the autocollimators' ports swapped when each
/// one apart (`off`) reads what another stored there (within `tolerance` arcsec, X and
/// Y); otherwise a question: the ports swapped, or the polygon or an autocollimator
/// moved, each to be put back as it was.
fn why_apart(run: &RunSoFar, stop: &Stop, off: &[ReadApart], tolerance: f64) -> String {
    // Each one off reads what another autocollimator stored there: swapped ports.
    let like: Vec<String> = off
        .iter()
        .filter_map(|&ReadApart { ac, read: r, .. }| {
            run.settings
                .acs()
                .filter(|&other| other != ac)
                .find(|&other| {
                    stored_at(run, stop, other).is_some_and(|s| {
                        apart(r.x_arcsec, r.y_arcsec, s, tolerance) == (false, false)
                    })
                })
                .map(|other| format!("ac{ac} reads what ac{other} stored"))
        })
        .collect();
    if like.len() == off.len() {
        format!(
            "{}: the autocollimators' ports look swapped — connect each to the port it had \
             before the interruption",
            like.join(", ")
        )
    } else {
        "are the ports swapped, or was the polygon or an autocollimator moved? Put them back \
         as they were"
            .to_string()
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
    let first = FirstStop::new(run, stop, read);
    let Some(stated_apart) = first.y_apart(first.mounting.face_shift) else {
        let (mounting, at) = (first.mounting, &first.at);
        return Verdict {
            compared: format!(
                "{mounting}, {at}, its first stop: X {}; no Y to compare",
                values_text(&first.x)
            ),
            refused: None,
        };
    };
    let shift_seen = first.shift_seen(stated_apart);
    let compared = first.compared(shift_seen.is_some());
    let Some(k) = shift_seen else {
        return Verdict {
            compared,
            refused: None,
        };
    };
    Verdict {
        compared,
        refused: Some(Outcome::InstrumentError(first.refusal(k))),
    }
}

/// A new mounting's first stop against the mountings before it: the readings there, and
/// each autocollimator's Y readings of each face before, from which a face shift
/// predicts the Y each autocollimator reads at the stop.
struct FirstStop<'a> {
    /// The run so far.
    run: &'a RunSoFar,
    /// The new mounting, as stated.
    mounting: Mounting,
    /// Its first stop.
    stop: Stop,
    /// The stop as messages give it: `cycle 1, step 0`.
    at: String,
    /// The readings the mountings before it stored.
    before: Vec<&'a Reading>,
    /// Each autocollimator's X reading at the stop, arcsec.
    x: Vec<f64>,
    /// Each autocollimator's Y reading at the stop, arcsec (`None` when one has none).
    y: Option<Vec<f64>>,
    /// Each autocollimator's Y readings of each face in the mountings before: their sum,
    /// arcsec, and their count.
    y_of: BTreeMap<(u32, usize), (f64, usize)>,
}

impl<'a> FirstStop<'a> {
    /// The readings `read` at `stop` (autocollimator 1 first) of the run's mounting, and
    /// what the mountings before it stored.
    fn new(run: &'a RunSoFar, stop: Stop, read: &[StopReading]) -> FirstStop<'a> {
        let mounting = run.mounting();
        let before: Vec<&Reading> = run
            .readings
            .iter()
            .filter(|r| r.setup < mounting.setup)
            .collect();
        // Each autocollimator's Y of each face in the mountings before.
        let mut y_of: BTreeMap<(u32, usize), (f64, usize)> = BTreeMap::new();
        for r in &before {
            if let Some(y) = r.reading_y_arcsec {
                let e = y_of.entry((r.ac, r.face)).or_insert((0.0, 0));
                *e = (e.0 + y, e.1 + 1);
            }
        }
        FirstStop {
            run,
            mounting,
            stop,
            at: format!("cycle {}, step {}", stop.cycle, stop.step),
            before,
            x: read.iter().map(|r| r.x_arcsec).collect(),
            y: read.iter().map(|r| r.y_arcsec).collect(),
            y_of,
        }
    }

    /// The faces the autocollimators (1 first) see at the stop with the polygon turned
    /// `k` faces.
    fn faces(&self, k: usize) -> Vec<usize> {
        let settings = &self.run.settings;
        let turned = Mounting::new(self.mounting.setup).with_face_shift(k);
        settings
            .acs()
            .map(|ac| turned.face(settings, ac, self.stop.step))
            .collect()
    }

    /// The Y each autocollimator reads at the stop with the polygon turned `k` faces, as
    /// the mountings before predict it: the mean of its Y readings of that face there,
    /// arcsec; `None` when an autocollimator has no Y reading of its face before.
    fn predicted_y(&self, k: usize) -> Option<Vec<f64>> {
        self.faces(k)
            .iter()
            .zip(self.run.settings.acs())
            .map(|(&f, ac)| {
                self.y_of
                    .get(&(ac, f))
                    .map(|&(sum, count)| sum / count as f64)
            })
            .collect()
    }

    /// How far the Y readings at the stop are from those the polygon turned `k` faces
    /// predicts: the largest difference, arcsec; `None` without a Y read and predicted
    /// for every autocollimator.
    fn y_apart(&self, k: usize) -> Option<f64> {
        let (y, p) = (self.y.as_ref()?, self.predicted_y(k)?);
        Some(
            y.iter()
                .zip(&p)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max),
        )
    }

    /// The face shift the Y readings show instead of the stated one, which is
    /// `stated_apart` arcsec from them: the face shift they match best, when it is
    /// within the agreement tolerance and the stated one is not; `None` otherwise.
    fn shift_seen(&self, stated_apart: f64) -> Option<usize> {
        let tolerance = self.run.settings.agreement_arcsec();
        let stated = self.mounting.face_shift;
        let best = (0..self.run.settings.faces)
            .filter_map(|k| self.y_apart(k).map(|s| (k, s)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        match best {
            Some((k, s)) if stated_apart > tolerance && s <= tolerance && k != stated => Some(k),
            _ => None,
        }
    }

    /// The `compared` record: the X and Y readings at the stop against the faces as
    /// stated and the Y they predict (arcsec), and whether they agree (`apart` when the
    /// Y readings show another face shift).
    fn compared(&self, apart: bool) -> String {
        let (mounting, at) = (self.mounting, &self.at);
        let stated = mounting.face_shift;
        format!(
            "{mounting}, {at}, its first stop: X {}, Y {} ({} as stated: Y {}): {}",
            values_text(&self.x),
            values_text(self.y.as_deref().unwrap_or_default()),
            faces_text(&self.faces(stated)),
            values_text(&self.predicted_y(stated).unwrap_or_default()),
            if apart { "do not agree" } else { "agree" }
        )
    }

    /// Why the session ends when the autocollimators see the faces of face shift `k`,
    /// not those stated: the polygon not remounted, or turned otherwise than stated.
    fn refusal(&self, k: usize) -> String {
        let seen = self.faces(k);
        // The mounting before: the faces it had at this table angle, and its X there.
        let angle = self.mounting.table_deg(&self.stop, self.run.settings.faces);
        match self.not_remounted(&seen, angle) {
            Some((b, x_before)) => self.not_remounted_text(b, &x_before, &seen, angle),
            None => self.turned_text(k, &seen),
        }
    }

    /// The mounting before this one, when the polygon was not remounted: at the stop's
    /// table angle `angle` (degrees) it had the faces `seen` before the autocollimators,
    /// and the X readings at the stop are within the agreement tolerance of its mean X
    /// readings there (arcsec, returned with it); `None` otherwise.
    fn not_remounted(&self, seen: &[usize], angle: f64) -> Option<(Mounting, Vec<f64>)> {
        let settings = &self.run.settings;
        let n = settings.faces;
        let tolerance = settings.agreement_arcsec();
        let b = self
            .run
            .mountings
            .iter()
            .rev()
            .map(|m| m.mounting)
            .find(|m| m.setup < self.mounting.setup)?;
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
                let (sum, count) = self
                    .before
                    .iter()
                    .filter(|r| r.setup == b.setup && r.ac == ac && r.step % n == step)
                    .fold((0.0, 0usize), |(s, c), r| (s + r.reading_arcsec, c + 1));
                (count > 0).then(|| sum / count as f64)
            })
            .collect();
        let x_before = x_before?;
        self.x
            .iter()
            .zip(&x_before)
            .all(|(a, b)| (a - b).abs() <= tolerance)
            .then_some((b, x_before))
    }

    /// The refusal when the polygon was not remounted: the autocollimators read at the
    /// table angle `angle` (degrees) what they read there in mounting `b` (X `x_before`,
    /// arcsec, and the faces `seen`).
    fn not_remounted_text(
        &self,
        b: Mounting,
        x_before: &[f64],
        seen: &[usize],
        angle: f64,
    ) -> String {
        let mounting = self.mounting;
        let at = &self.at;
        let stated_faces = self.faces(mounting.face_shift);
        let first_face = stated_faces.first().copied().unwrap_or(0);
        format!(
            "at the first stop of {mounting}, {at}, the table at {angle}°, the autocollimators \
             read what they read at this table angle in mounting {}: X {} against {} then, \
             and Y as {} (not {} as stated): the polygon was not remounted; mount it with face \
             {first_face} facing autocollimator 1, the table at {angle}°, and run the same \
             command again; nothing of mounting {} was stored",
            b.setup,
            values_text(&self.x),
            values_text(x_before),
            faces_text(seen),
            faces_text(&stated_faces),
            mounting.setup
        )
    }

    /// The refusal when the polygon was turned `k` faces, not as stated: the Y readings
    /// are those the mountings before had of the faces `seen`, and the mounting as it is
    /// is stated in `polycal run` options.
    fn turned_text(&self, k: usize, seen: &[usize]) -> String {
        let mounting = self.mounting;
        let at = &self.at;
        let stated = mounting.face_shift;
        let stated_faces = self.faces(stated);
        let mut told = mounting;
        told.face_shift = k;
        format!(
            "at the first stop of {mounting}, {at}, the autocollimators see {} (the polygon \
             turned {k} face(s)), not {} as stated: their Y readings {} are those of {} in \
             the mountings before ({}), not those of {} ({}); state the mounting as it is \
             ({}) or mount it as stated, and run again; nothing of mounting {} was stored",
            faces_text(seen),
            faces_text(&stated_faces),
            values_text(self.y.as_deref().unwrap_or_default()),
            faces_text(seen),
            values_text(&self.predicted_y(k).unwrap_or_default()),
            faces_text(&stated_faces),
            values_text(&self.predicted_y(stated).unwrap_or_default()),
            told.as_options(),
            mounting.setup
        )
    }
}
