//! The clock drift terms run on: the readings' `time`, or, in a file without one (the
//! reference paper's data have none; `time` is optional, docs/FORMAT.md §2), the run's
//! stop order, one unit per stop of the table.

use crate::measurement::{Direction, MeasurementSet};

/// What a drift's unit of time is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Clock {
    /// The readings' `time`: drift in arcsec per hour.
    Time,
    /// The run's stop order (the file has no `time` for every reading): drift in arcsec
    /// per stop.
    StopOrder,
}

impl Clock {
    /// The unit of a drift's `value` on this clock, as in the JSON: `arcsec/h` or
    /// `arcsec/stop`.
    pub fn drift_unit(self) -> &'static str {
        match self {
            Clock::Time => "arcsec/h",
            Clock::StopOrder => "arcsec/stop",
        }
    }

    /// The unit for people: `″/h` or `″/stop`.
    pub fn drift_unit_text(self) -> &'static str {
        match self {
            Clock::Time => "″/h",
            Clock::StopOrder => "″/stop",
        }
    }
}

/// The seconds one stop counts as on the stop clock: an hour, so that a drift's regressor
/// (time in hours) counts stops.
const SECONDS_PER_STOP: f64 = 3600.0;

/// The set the diagnosis works on, and its clock: `set` itself when every reading has a
/// `time`; otherwise a copy whose `time` is the reading's stop in the run's order (setup,
/// then cycle, then the cycle's stops in the order the table took them: 0 … N clockwise,
/// N … 0 counter-clockwise), one stop counting as one hour so that a drift's value is
/// arcsec per stop.
pub fn clocked(set: &MeasurementSet) -> (std::borrow::Cow<'_, MeasurementSet>, Clock) {
    if set.readings.iter().all(|r| r.time_seconds.is_some()) {
        return (std::borrow::Cow::Borrowed(set), Clock::Time);
    }
    let key = |i: usize| {
        let r = &set.readings[i];
        let within = match r.direction {
            Direction::Cw => r.step as i64,
            Direction::Ccw => -(r.step as i64),
        };
        (r.setup, r.cycle, within)
    };
    let mut stops: Vec<(u32, u32, i64)> = (0..set.readings.len()).map(key).collect();
    stops.sort_unstable();
    stops.dedup();
    let mut copy = set.clone();
    for (i, r) in copy.readings.iter_mut().enumerate() {
        let ordinal = stops.binary_search(&key(i)).unwrap_or(0);
        r.time_seconds = Some(ordinal as f64 * SECONDS_PER_STOP);
    }
    (std::borrow::Cow::Owned(copy), Clock::StopOrder)
}
