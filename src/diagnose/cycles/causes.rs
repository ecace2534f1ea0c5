//! The usual logging errors of one cycle, and how each is undone on the readings.
//!
//! Each repair keeps every reading's own record (its time, its line of the file, its
//! values) and only says which stop, face or autocollimator it belongs to; a reading the
//! repair leaves without a stop of the cycle is set aside and named.

use std::collections::HashMap;

use crate::measurement::{MeasurementSet, Reading, face_at};

/// A logging error that explains a cycle's disagreement with the rest of its run
/// (docs/FORMAT.md §5, `cycles[].cause`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum CycleCause {
    /// Autocollimators `a` and `b`'s readings exchanged at every stop of the cycle.
    SwappedAcs {
        /// The first autocollimator of the pair.
        a: u32,
        /// The second.
        b: u32,
    },
    /// Every reading stored against a stop is the reading of the stop before it in time
    /// (the logger latched before the table settled).
    OneStopLate,
    /// Every reading stored against a stop is the reading of the stop after it in time.
    OneStopEarly,
    /// The autocollimators read the face `by` (±1) after the one the file names (the
    /// polygon sat a pitch round for that cycle).
    FacesShifted {
        /// +1 or −1.
        by: i64,
    },
    /// The cycle was run the other way round and logged in the order of the logged
    /// direction: the k-th stop in time holds the reading of the k-th from the end.
    Reversed,
    /// No usual logging error explains it (or several explain it equally well).
    Unexplained,
}

impl CycleCause {
    /// The cause as spelled in the JSON: `swapped-acs`, `one-stop-late`,
    /// `one-stop-early`, `faces-shifted`, `reversed`, `unexplained`.
    pub fn as_str(self) -> &'static str {
        match self {
            CycleCause::SwappedAcs { .. } => "swapped-acs",
            CycleCause::OneStopLate => "one-stop-late",
            CycleCause::OneStopEarly => "one-stop-early",
            CycleCause::FacesShifted { .. } => "faces-shifted",
            CycleCause::Reversed => "reversed",
            CycleCause::Unexplained => "unexplained",
        }
    }

    /// The cause for people: "autocollimators 1 and 2 exchanged", ….
    pub fn describe(self) -> String {
        match self {
            CycleCause::SwappedAcs { a, b } => {
                format!("the readings of autocollimators {a} and {b} exchanged at every stop")
            }
            CycleCause::OneStopLate => {
                "every reading logged one stop late (against the next stop in time)".into()
            }
            CycleCause::OneStopEarly => {
                "every reading logged one stop early (against the previous stop in time)".into()
            }
            CycleCause::FacesShifted { by } => format!(
                "every autocollimator read the face {} the one the file names",
                if by > 0 { "after" } else { "before" }
            ),
            CycleCause::Reversed => {
                "the cycle run the other way round and logged in the logged direction's order"
                    .into()
            }
            CycleCause::Unexplained => "no usual logging error explains it".into(),
        }
    }
}

/// The usual logging errors of readings by the autocollimators `acs` (ascending, each
/// once): every pair exchanged, one stop late or early, faces shifted by ±1, reversed.
pub(super) fn of_autocollimators(acs: &[u32]) -> Vec<CycleCause> {
    let mut causes = Vec::new();
    for (i, &a) in acs.iter().enumerate() {
        for &b in &acs[i + 1..] {
            causes.push(CycleCause::SwappedAcs { a, b });
        }
    }
    causes.extend([
        CycleCause::OneStopLate,
        CycleCause::OneStopEarly,
        CycleCause::FacesShifted { by: 1 },
        CycleCause::FacesShifted { by: -1 },
        CycleCause::Reversed,
    ]);
    causes
}

/// The stops (steps) of a cycle in time order: by the readings' times when every reading
/// of the cycle has one, else by the cycle's direction.
fn stops_in_time_order(readings: &[&Reading]) -> Vec<usize> {
    let mut first: HashMap<usize, f64> = HashMap::new();
    let timed = readings.iter().all(|r| r.time_seconds.is_some());
    for r in readings {
        let key = if timed {
            r.time_seconds.unwrap_or(0.0)
        } else if r.direction == crate::measurement::Direction::Ccw {
            -(r.step as f64)
        } else {
            r.step as f64
        };
        let entry = first.entry(r.step).or_insert(key);
        *entry = entry.min(key);
    }
    let mut stops: Vec<(f64, usize)> = first.into_iter().map(|(s, k)| (k, s)).collect();
    stops.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    stops.into_iter().map(|(_, s)| s).collect()
}

/// A cycle's readings with a cause undone ([`Cycle::undo`]).
pub(super) struct Undone {
    /// The cycle's readings the repair keeps, each with its index into the set, as
    /// repaired.
    pub readings: Vec<(usize, Reading)>,
    /// The indices (into the set) of the readings the repair leaves without a stop of
    /// the cycle.
    pub aside: Vec<usize>,
    /// The mounting a faces-shifted cycle becomes (a new one), with its shift.
    new_setup: Option<(u32, Option<f64>)>,
}

/// One cycle of a set, prepared for its causes to be undone one after the other.
pub(super) struct Cycle<'s> {
    set: &'s MeasurementSet,
    setup: u32,
    /// The indices (into the set) of the cycle's readings.
    in_cycle: Vec<usize>,
    /// The cycle's stops in time order.
    stops: Vec<usize>,
    /// Each stop's place in `stops`.
    ranks: HashMap<usize, usize>,
    /// The set's face offsets ([`MeasurementSet::face_offsets`]).
    offsets: Vec<((u32, u32), usize)>,
}

impl<'s> Cycle<'s> {
    /// Cycle `cycle` of `setup` of `set`; `None` for a cycle of fewer than two stops.
    pub(super) fn of(set: &'s MeasurementSet, setup: u32, cycle: u32) -> Option<Cycle<'s>> {
        let in_cycle: Vec<usize> = (0..set.readings.len())
            .filter(|&i| set.readings[i].setup == setup && set.readings[i].cycle == cycle)
            .collect();
        let refs: Vec<&Reading> = in_cycle.iter().map(|&i| &set.readings[i]).collect();
        let stops = stops_in_time_order(&refs);
        if stops.len() < 2 {
            return None;
        }
        let ranks = stops.iter().enumerate().map(|(k, &s)| (s, k)).collect();
        Some(Cycle {
            set,
            setup,
            in_cycle,
            stops,
            ranks,
            offsets: set.face_offsets(),
        })
    }

    /// The causes worth trying on the cycle.
    pub(super) fn candidates(&self) -> Vec<CycleCause> {
        let mut acs: Vec<u32> = self.readings().map(|r| r.ac).collect();
        acs.sort_unstable();
        acs.dedup();
        of_autocollimators(&acs)
    }

    /// The polygon's number of faces.
    pub(super) fn faces(&self) -> usize {
        self.set.faces
    }

    /// The face offset of autocollimator `ac` in mounting `setup`.
    pub(super) fn offset_of(&self, setup: u32, ac: u32) -> Option<usize> {
        self.offsets
            .iter()
            .find(|((s, a), _)| *s == setup && *a == ac)
            .map(|(_, d)| *d)
    }

    /// The autocollimator of the cycle's mounting with face offset `offset`.
    pub(super) fn ac_with_offset(&self, offset: usize) -> Option<u32> {
        self.offsets
            .iter()
            .find(|((s, _), d)| *s == self.setup && *d == offset)
            .map(|((_, ac), _)| *ac)
    }

    /// The cycle's readings as logged.
    pub(super) fn readings(&self) -> impl Iterator<Item = &'s Reading> + '_ {
        self.in_cycle.iter().map(|&i| &self.set.readings[i])
    }

    /// The cycle with `cause` undone, without touching the rest of the set; `None` when
    /// the cause cannot be undone on this cycle (an autocollimator missing at some stop).
    pub(super) fn undo(&self, cause: CycleCause) -> Option<Undone> {
        let set = self.set;
        let n = set.faces;
        let refs: Vec<&Reading> = self.readings().collect();
        let rank = |step: usize| self.ranks.get(&step).copied();
        // the cycle's readings, parallel to `in_cycle`
        let mut readings: Vec<Reading> = refs.iter().map(|&r| r.clone()).collect();
        let mut aside = Vec::new();
        let mut new_setup = None;
        let relabel = |r: &mut Reading, step: usize| -> Option<()> {
            r.step = step;
            r.face = face_at(step, self.offset_of(r.setup, r.ac)?, n);
            Some(())
        };
        match cause {
            CycleCause::SwappedAcs { a, b } => {
                let of_b: HashMap<usize, usize> = refs
                    .iter()
                    .enumerate()
                    .filter(|(_, r)| r.ac == b)
                    .map(|(k, r)| (r.step, k))
                    .collect();
                for (k, r) in refs.iter().enumerate() {
                    if r.ac != a {
                        continue;
                    }
                    let j = *of_b.get(&r.step)?;
                    let other = refs[j];
                    readings[k].reading_arcsec = other.reading_arcsec;
                    readings[k].reading_y_arcsec = other.reading_y_arcsec;
                    readings[j].reading_arcsec = r.reading_arcsec;
                    readings[j].reading_y_arcsec = r.reading_y_arcsec;
                }
                if refs.iter().filter(|r| r.ac == a || r.ac == b).count() % 2 != 0 {
                    return None;
                }
            }
            CycleCause::OneStopLate | CycleCause::OneStopEarly | CycleCause::Reversed => {
                let last = self.stops.len() - 1;
                for (k, r) in readings.iter_mut().enumerate() {
                    let at = rank(r.step)?;
                    let to = match cause {
                        CycleCause::OneStopLate if at == 0 => None,
                        CycleCause::OneStopLate => Some(at - 1),
                        CycleCause::OneStopEarly if at == last => None,
                        CycleCause::OneStopEarly => Some(at + 1),
                        _ => Some(last - at),
                    };
                    match to {
                        Some(to) => relabel(r, self.stops[to])?,
                        None => aside.push(self.in_cycle[k]),
                    }
                }
            }
            CycleCause::FacesShifted { by } => {
                let shifted = set
                    .readings
                    .iter()
                    .map(|r| r.setup)
                    .max()
                    .unwrap_or(1)
                    .checked_add(1)?;
                for r in &mut readings {
                    r.setup = shifted;
                    r.face = ((r.face as i64 - 1 + by).rem_euclid(n as i64) + 1) as usize;
                }
                new_setup = Some((shifted, set.setup_shift_deg.get(&self.setup).copied()));
            }
            CycleCause::Unexplained => return None,
        }
        let readings = self
            .in_cycle
            .iter()
            .copied()
            .zip(readings)
            .filter(|(i, _)| !aside.contains(i))
            .collect();
        Some(Undone {
            readings,
            aside,
            new_setup,
        })
    }
}

/// `set` with `cause` undone in cycle `cycle` of `setup` ([`Cycle::undo`]), and the indices
/// (into `set`) of the readings the repair leaves without a stop of the cycle (removed
/// from the repaired set).
pub(super) fn repair(
    set: &MeasurementSet,
    setup: u32,
    cycle: u32,
    cause: CycleCause,
) -> Option<(MeasurementSet, Vec<usize>)> {
    let undone = Cycle::of(set, setup, cycle)?.undo(cause)?;
    let mut readings = set.readings.clone();
    for (i, r) in &undone.readings {
        readings[*i] = r.clone();
    }
    let aside_set: std::collections::HashSet<usize> = undone.aside.iter().copied().collect();
    let keep: Vec<Reading> = readings
        .into_iter()
        .enumerate()
        .filter(|(i, _)| !aside_set.contains(i))
        .map(|(_, r)| r)
        .collect();
    let mut shifts = set.setup_shift_deg.clone();
    if let Some((new_setup, Some(shift))) = undone.new_setup {
        shifts.insert(new_setup, shift);
    }
    Some((
        MeasurementSet {
            faces: set.faces,
            readings: keep,
            source: set.source.clone(),
            setup_shift_deg: shifts,
        },
        undone.aside,
    ))
}

/// `set` without the readings of cycle `cycle` of `setup`, and their indices.
pub(super) fn without_cycle(
    set: &MeasurementSet,
    setup: u32,
    cycle: u32,
) -> (MeasurementSet, Vec<usize>) {
    let aside: Vec<usize> = (0..set.readings.len())
        .filter(|&i| set.readings[i].setup == setup && set.readings[i].cycle == cycle)
        .collect();
    let readings = set
        .readings
        .iter()
        .filter(|r| !(r.setup == setup && r.cycle == cycle))
        .cloned()
        .collect();
    (
        MeasurementSet {
            faces: set.faces,
            readings,
            source: set.source.clone(),
            setup_shift_deg: set.setup_shift_deg.clone(),
        },
        aside,
    )
}
