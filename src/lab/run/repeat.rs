//! A reading tied to its stop: each autocollimator is read several times at a stop, and
//! a reading is stored only when the last [`RunSettings::reads_per_stop`] readings agree
//! within the tolerance of the noise the run measured ([`RepeatNoise::agreement_arcsec`],
//! never wider than [`RunSettings::agreement_arcsec`]); their mean is stored, and their
//! scatter joins the measured noise (docs/FORMAT.md §7.3, *No reading on the wrong
//! stop*).
//!
//! What the drivers cannot see — a reply that belongs to another query but looks like a
//! good one — shows here: a value carried over from an earlier stop (a stale reply, the
//! very same X, Y and status as the device's last reply at an earlier stop) is refused,
//! and a value from anywhere else (an unsolicited line, a late or swapped reply) does not
//! agree with the readings around it. (The same value at the same table angle — the
//! closing stop at 360° and the next cycle's first at 0° — is no sign of staleness: a
//! steady instrument reads it again.) A resumed session carries the values each device
//! gave before it over ([`DeviceMemory::carried_over`]): until the device gave a reading
//! in the session, they are refused as stale at any other table angle. Every refused
//! reading is named, with why, for the traffic log (`refused`).
//!
//! The rule does no input or output: [`StopReads`] is offered one reply at a time and
//! says whether it wants another, has a reading, or gives up (the session asks for the
//! replies, `session.rs`).

use super::RunSettings;
use super::noise::RepeatNoise;
use crate::lab::AcReading;

/// Readings beyond [`RunSettings::reads_per_stop`] an autocollimator may be asked for at
/// one stop before the run gives up on it.
pub const EXTRA_READS: u32 = 4;

/// One autocollimator's readings at one stop, accepted.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct StopReading {
    /// The mean X of the agreeing readings, arcsec.
    pub(super) x_arcsec: f64,
    /// The mean Y of the agreeing readings when every one has a valid Y, arcsec.
    pub(super) y_arcsec: Option<f64>,
    /// Readings taken and not used (refused or not among the agreeing ones).
    pub(super) refused: usize,
}

/// What the run remembers of one autocollimator between stops.
#[derive(Debug, Clone, Default)]
pub(super) struct DeviceMemory {
    /// Its last reply at an earlier stop, and that stop's table angle (degrees, 0 … 360).
    last_at_earlier_stop: Option<(AcReading, f64)>,
    /// The scatter of its readings at the stops so far in the session.
    pub(super) noise: RepeatNoise,
    /// Until it gave a reading in this session: its last values before the session (the
    /// last reply the traffic log holds, its last stored reading), each with the table
    /// angle it was read at (degrees, 0 … 360), refused as stale at another angle.
    before_session: Vec<(LastValue, f64)>,
}

/// A value an autocollimator gave before this session, which it must not give again as
/// a new stop's reading (docs/FORMAT.md §7.3, *A stale reply is refused*).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LastValue {
    /// X, arcsec.
    pub x_arcsec: f64,
    /// Y, arcsec, when valid.
    pub y_arcsec: Option<f64>,
    /// The status, when known (a reply's; not a stored reading's).
    pub status: Option<u16>,
}

impl LastValue {
    /// Whether `reading` repeats this value exactly (X, Y and, when known, the status).
    fn repeated_by(&self, reading: &AcReading) -> bool {
        reading.x_arcsec == self.x_arcsec
            && reading.y_arcsec == self.y_arcsec
            && self.status.is_none_or(|s| s == reading.status)
    }
}

impl DeviceMemory {
    /// The memory of a device at the start of a resumed session: `values` it gave before,
    /// each with the table angle it was read at, degrees.
    pub(super) fn carried_over(values: Vec<(LastValue, f64)>) -> DeviceMemory {
        DeviceMemory {
            last_at_earlier_stop: None,
            noise: RepeatNoise::default(),
            before_session: values
                .into_iter()
                .map(|(value, angle)| (value, turn(angle)))
                .collect(),
        }
    }
}

/// A table angle in 0 … 360°.
fn turn(angle_deg: f64) -> f64 {
    angle_deg.rem_euclid(360.0)
}

/// What [`StopReads::offer`] makes of a reply.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Offered {
    /// Ask the autocollimator again.
    Again,
    /// The readings agree: this is the stop's reading.
    Accepted(StopReading),
    /// Every reading was taken, and no `reads_per_stop` consecutive ones agreed: the
    /// message says what was seen.
    NoAgreement(String),
}

/// One autocollimator read at one stop until `settings.reads_per_stop` consecutive
/// readings agree (at most that many plus [`EXTRA_READS`]). Each reply refused on the
/// way is kept, with why, for the traffic log ([`StopReads::take_refused`]).
#[derive(Debug, Clone)]
pub(super) struct StopReads {
    here: f64,
    stale_value: Option<AcReading>,
    carried: Vec<LastValue>,
    needed: usize,
    most: usize,
    tolerance: f64,
    taken: Vec<AcReading>,
    asked: usize,
    stale: usize,
    last_here: Option<AcReading>,
    refused_now: Vec<String>,
}

impl StopReads {
    /// The reads of a device whose memory is `memory` at a stop of table angle
    /// `angle_deg`.
    pub(super) fn new(memory: &DeviceMemory, settings: &RunSettings, angle_deg: f64) -> StopReads {
        let here = turn(angle_deg);
        let needed = settings.reads_per_stop.max(2) as usize;
        StopReads {
            here,
            stale_value: memory
                .last_at_earlier_stop
                .filter(|&(_, angle)| (angle - here).abs() > 1e-9)
                .map(|(reading, _)| reading),
            carried: memory
                .before_session
                .iter()
                .filter(|&&(_, angle)| (angle - here).abs() > 1e-9)
                .map(|&(value, _)| value)
                .collect(),
            needed,
            most: needed + EXTRA_READS as usize,
            tolerance: memory.noise.agreement_arcsec(settings.reading_noise_arcsec),
            taken: Vec::new(),
            asked: 0,
            stale: 0,
            last_here: None,
            refused_now: Vec::new(),
        }
    }

    /// The replies refused since the last call, each as the traffic log's `refused`
    /// record gives it: the reply, then why in brackets.
    pub(super) fn take_refused(&mut self) -> Vec<String> {
        std::mem::take(&mut self.refused_now)
    }

    fn refuse(&mut self, reading: &AcReading, why: &str) {
        self.refused_now.push(format!("{} ({why})", text(reading)));
    }

    /// Takes one reply of the device; `memory` learns from the stop once it is decided.
    /// `(role, port, at)` name the device and the stop in a message.
    pub(super) fn offer(
        &mut self,
        reading: AcReading,
        memory: &mut DeviceMemory,
        settings: &RunSettings,
        (role, port, at): (&str, &str, &str),
    ) -> Offered {
        self.asked += 1;
        self.last_here = Some(reading);
        if self.stale_value == Some(reading) {
            self.stale += 1;
            self.refuse(
                &reading,
                "stale: the same X, Y and status as the last reply at an earlier stop",
            );
            return self.again_or_give_up(memory, settings, (role, port, at));
        }
        if self.carried.iter().any(|v| v.repeated_by(&reading)) {
            self.stale += 1;
            self.refuse(
                &reading,
                "stale: the same value as its last one before this session, at another stop",
            );
            return self.again_or_give_up(memory, settings, (role, port, at));
        }
        self.taken.push(reading);
        if self.taken.len() >= self.needed {
            let window = &self.taken[self.taken.len() - self.needed..];
            if spread(window) <= self.tolerance {
                let xs: Vec<f64> = window.iter().map(|r| r.x_arcsec).collect();
                let accepted = StopReading {
                    x_arcsec: mean(xs.iter().copied()),
                    y_arcsec: window
                        .iter()
                        .map(|r| r.y_arcsec)
                        .collect::<Option<Vec<f64>>>()
                        .map(|y| mean(y.into_iter())),
                    refused: self.asked - self.needed,
                };
                memory.last_at_earlier_stop = self.last_here.map(|r| (r, self.here));
                memory.noise.add_stop(&xs);
                memory.before_session.clear();
                let early: Vec<AcReading> = self.taken[..self.taken.len() - self.needed].to_vec();
                for r in &early {
                    self.refuse(r, "does not agree with the readings after it");
                }
                return Offered::Accepted(accepted);
            }
        }
        self.again_or_give_up(memory, settings, (role, port, at))
    }

    /// [`Offered::Again`] while replies may still be asked for; the refusal once not.
    fn again_or_give_up(
        &mut self,
        memory: &mut DeviceMemory,
        settings: &RunSettings,
        (role, port, at): (&str, &str, &str),
    ) -> Offered {
        if self.asked < self.most {
            return Offered::Again;
        }
        memory.last_at_earlier_stop = self.last_here.map(|r| (r, self.here));
        memory.before_session.clear();
        let taken = std::mem::take(&mut self.taken);
        for reading in &taken {
            self.refuse(reading, "no agreement at this stop");
        }
        let (needed, asked, tolerance) = (self.needed, self.asked, self.tolerance);
        let values: Vec<String> = taken.iter().map(|r| format!("{}", r.x_arcsec)).collect();
        let judged = match memory.noise.measured_arcsec() {
            Some(s) if tolerance < settings.agreement_arcsec() => format!(
                "the noise measured at the stops before, {s:.4}″ on {} degrees of freedom \
                 (the stated reading noise {}″ bounds it)",
                memory.noise.dof(),
                settings.reading_noise_arcsec
            ),
            _ => format!(
                "5·√2 times the stated reading noise {}″",
                settings.reading_noise_arcsec
            ),
        };
        Offered::NoAgreement(format!(
            "{role} ({port}) at {at}: no {needed} consecutive readings of {asked} agreed within \
             {tolerance:.3}″ ({judged}): X {}{}; the reading is \
             not stored — check the autocollimator, the polygon's mounting and the air, or state \
             the autocollimator's real noise",
            if values.is_empty() {
                "none".to_string()
            } else {
                values.join(", ")
            },
            if self.stale > 0 {
                format!(" ({} stale repeated from an earlier stop)", self.stale)
            } else {
                String::new()
            }
        ))
    }
}

/// The largest minus the smallest X, arcsec.
fn spread(readings: &[AcReading]) -> f64 {
    let (lo, hi) = readings
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
            (lo.min(r.x_arcsec), hi.max(r.x_arcsec))
        });
    hi - lo
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    sum / n as f64
}

/// A reading as the log shows it: `status 003, X 12.345, Y -1.234`.
fn text(reading: &AcReading) -> String {
    match reading.y_arcsec {
        Some(y) => format!(
            "status {:03}, X {}, Y {y}",
            reading.status, reading.x_arcsec
        ),
        None => format!("status {:03}, X {}", reading.status, reading.x_arcsec),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The outcome of reading a device that gives `values` (X; Y 0, status 003) in turn.
    fn read_at(
        values: &[f64],
        memory: &mut DeviceMemory,
        angle_deg: f64,
    ) -> Result<StopReading, String> {
        let settings = RunSettings::new(8, 1).with_reading_noise_arcsec(0.05); // 0.354″
        let mut reads = StopReads::new(memory, &settings, angle_deg);
        for &x in values {
            let names = ("autocollimator 1", "mem", "cycle 1, step 0");
            match reads.offer(AcReading::new(3, x, Some(0.0)), memory, &settings, names) {
                Offered::Again => {}
                Offered::Accepted(r) => return Ok(r),
                Offered::NoAgreement(m) => return Err(m),
            }
        }
        Err("the device gave no more readings".to_string())
    }

    fn read(values: &[f64], memory: &mut DeviceMemory) -> Result<StopReading, String> {
        read_at(values, memory, 0.0)
    }
    #[test]
    fn two_agreeing_readings_give_their_mean() {
        let r = read(&[1.0, 1.2], &mut DeviceMemory::default()).unwrap();
        assert!((r.x_arcsec - 1.1).abs() < 1e-12);
        assert_eq!((r.y_arcsec, r.refused), (Some(0.0), 0));
    }

    #[test]
    fn a_reading_from_elsewhere_is_outvoted_and_counted() {
        // 99″ off (an unsolicited line), then two that agree.
        let r = read(&[100.0, 1.0, 1.1], &mut DeviceMemory::default()).unwrap();
        assert!((r.x_arcsec - 1.05).abs() < 1e-12);
        assert_eq!(r.refused, 1);
        // 0.36″ apart is beyond 5·√2·0.05″ = 0.3536″; 0.35″ is within.
        let r = read(&[1.0, 1.36, 1.5], &mut DeviceMemory::default()).unwrap();
        assert_eq!(r.refused, 1);
        assert!((r.x_arcsec - 1.43).abs() < 1e-12);
        let r = read(&[1.0, 1.35], &mut DeviceMemory::default()).unwrap();
        assert_eq!(r.refused, 0);
    }

    #[test]
    fn a_value_repeated_from_an_earlier_stop_is_refused() {
        let mut memory = DeviceMemory::default();
        read_at(&[5.0, 5.0], &mut memory, 0.0).unwrap();
        // The next stop's first reply is the last one again (stale): not used.
        let r = read_at(&[5.0, 5.1, 5.2], &mut memory, 45.0).unwrap();
        assert!((r.x_arcsec - 5.15).abs() < 1e-12);
        assert_eq!(r.refused, 1);
        // At the same table angle (360° after 0°... here 405° after 45°) a steady
        // instrument may read the very same value again.
        let r = read_at(&[5.2, 5.2], &mut memory, 405.0).unwrap();
        assert_eq!((r.x_arcsec, r.refused), (5.2, 0));
    }

    #[test]
    fn a_wrong_value_within_the_stated_tolerance_is_refused_once_the_noise_is_measured() {
        // Stated 0.05″ (tolerance 0.354″), real scatter 0.02″ apart at 40 stops.
        let r = read(&[1.0, 1.3], &mut DeviceMemory::default()).unwrap();
        assert_eq!(r.refused, 0, "stated tolerance before any repeats");
        let mut memory = DeviceMemory::default();
        for i in 0..40 {
            let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
            read(&[5.0, 5.0 + sign * 0.02], &mut memory).unwrap();
        }
        // 0.3″ off: within the stated tolerance, beyond the measured one.
        let r = read(&[1.0, 1.3, 1.31], &mut memory).unwrap();
        assert_eq!(r.refused, 1);
        assert!((r.x_arcsec - 1.305).abs() < 1e-12);
    }

    #[test]
    fn an_error_names_the_measured_noise_it_judged_by() {
        let mut memory = DeviceMemory::default();
        for _ in 0..40 {
            read(&[5.0, 5.02], &mut memory).unwrap();
        }
        let e = read(&[0.0, 0.3, 0.6, 0.9, 1.2, 1.5], &mut memory).unwrap_err();
        let message = e;
        assert!(
            message.contains("the noise measured at the stops before, 0.0141″ on 40 degrees"),
            "{message}"
        );
    }

    #[test]
    fn a_value_from_before_the_session_is_refused_at_another_stop_only() {
        let value = |status| LastValue {
            x_arcsec: 5.0,
            y_arcsec: Some(0.0),
            status,
        };
        // Its last reply (status known) and its stored reading (status not), at 405° = 45°.
        let carried = || DeviceMemory::carried_over(vec![(value(Some(3)), 405.0)]);
        let r = read_at(&[5.0, 5.1, 5.2], &mut carried(), 90.0).unwrap();
        assert_eq!(r.refused, 1);
        assert!((r.x_arcsec - 5.15).abs() < 1e-12);
        // At the angle it was given at, a steady instrument may read it again.
        let r = read_at(&[5.0, 5.1], &mut carried(), 45.0).unwrap();
        assert_eq!(r.refused, 0);
        // A stored reading's value repeats whatever the status.
        let mut memory = DeviceMemory::carried_over(vec![(value(None), 0.0)]);
        let r = read_at(&[5.0, 5.0, 5.1, 5.15], &mut memory, 90.0).unwrap();
        assert_eq!(r.refused, 2);
        assert!((r.x_arcsec - 5.125).abs() < 1e-12);
        // Once the device gave a reading in the session, the carried value is forgotten.
        let r = read_at(&[5.0, 5.0], &mut memory, 180.0).unwrap();
        assert_eq!(r.refused, 0);
    }

    #[test]
    fn readings_that_never_agree_end_in_an_error_naming_them() {
        let e = read(
            &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0],
            &mut DeviceMemory::default(),
        )
        .unwrap_err();
        let message = e;
        assert!(
            message.contains("no 2 consecutive readings of 6 agreed within 0.354″"),
            "{message}"
        );
        assert!(message.contains("X 0, 1, 2, 3, 4, 5"), "{message}");
    }
}
