//! The rules of a self-calibration set (docs/FORMAT.md §9.2) that go beyond one field:
//! P, steps in range, duplicates, one direction per cycle, one angle per head, head 1 at
//! 0, distinct head angles, and every step read by every head in every cycle.

use std::collections::hash_map::Entry;
use std::collections::{BTreeMap, BTreeSet, HashMap};

use super::columns::{Col, angle_outside};
use crate::input::FileError;
use crate::input::table::Locator;
use crate::measurement::direction_text;
use crate::selfcal::HeadReading;

/// Two head angles closer than this (degrees, modulo 360) are the same place.
pub(super) const SAME_ANGLE_DEG: f64 = 1e-9;

/// Row `i`'s head angle as it was written (quoted), or its value for a reading built in
/// memory.
fn angle_text(loc: &Locator<'_>, i: usize, readings: &[HeadReading]) -> String {
    loc.shown(i, Col::HeadAngle.at()).unwrap_or_else(|| {
        readings
            .get(i)
            .map_or_else(String::new, |r| r.head_angle_deg.to_string())
    })
}

/// A list of numbers for a message, cut after 20.
fn list<T: ToString>(items: impl IntoIterator<Item = T>) -> String {
    const MAX: usize = 20;
    let mut parts: Vec<String> = items
        .into_iter()
        .take(MAX + 1)
        .map(|x| x.to_string())
        .collect();
    if parts.len() > MAX {
        parts.truncate(MAX);
        parts.push("...".to_string());
    }
    parts.join(", ")
}

/// Distance of two angles in [0, 360) degrees, modulo 360.
fn angle_distance(a: f64, b: f64) -> f64 {
    let d = (a - b).abs();
    d.min(360.0 - d)
}

/// Checks readings against the rules; returns P.
pub(super) fn validate(
    readings: &[HeadReading],
    positions: Option<usize>,
    loc: &Locator<'_>,
    source: &str,
) -> Result<usize, FileError> {
    if readings.is_empty() {
        return Err(FileError::invalid(
            source,
            loc.header_start(),
            loc.no_rows().to_string(),
        ));
    }
    check_values(readings, loc, source)?;
    let (n, n_from) = number_of_positions(readings, positions, loc, source)?;

    // Row by row, in order.
    let mut rows = RowChecks {
        readings,
        loc,
        source,
        first_read: HashMap::new(),
        cycle_direction: HashMap::new(),
        head_first: HashMap::new(),
        by_angle: BTreeMap::new(),
    };
    for (i, r) in readings.iter().enumerate() {
        rows.check(i, r, n, n_from)?;
    }

    // The heads.
    let heads: BTreeSet<u32> = rows.head_first.keys().copied().collect();
    check_heads(&heads, loc, source)?;
    check_every_step_read(readings, &heads, (n, n_from), loc, source)?;
    Ok(n)
}

/// Values (already checked, with their text, when read from a file): cycle and head at
/// least 1, every number finite and within its limit, the head angle in [0, 360) degrees.
fn check_values(
    readings: &[HeadReading],
    loc: &Locator<'_>,
    source: &str,
) -> Result<(), FileError> {
    let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
    for (i, r) in readings.iter().enumerate() {
        let p = loc.prefix(i, readings);
        for (col, zero) in [(Col::Cycle, r.cycle == 0), (Col::Head, r.head == 0)] {
            if zero {
                let name = col.name();
                return Err(err(
                    loc.row(i, readings, col.at()),
                    format!("{p}column {name:?}: 0 is not allowed; {name} must be at least 1"),
                ));
            }
        }
        for (col, x) in [
            (Col::HeadAngle, Some(r.head_angle_deg)),
            (Col::Reading, Some(r.reading_arcsec)),
            (Col::Time, r.time_seconds),
        ] {
            let rule = match (x, col.limit()) {
                (Some(x), Some((limit, what))) => limit.check(x, what).err().map(|e| e.to_string()),
                (Some(x), None) if !x.is_finite() => Some(format!("{x} is not a finite number")),
                _ => None,
            };
            if let Some(rule) = rule {
                return Err(err(
                    loc.row(i, readings, col.at()),
                    format!("{p}column {:?}: {rule}", col.name()),
                ));
            }
        }
        if !(0.0..360.0).contains(&r.head_angle_deg) {
            return Err(err(
                loc.row(i, readings, Col::HeadAngle.at()),
                format!("{p}{}", angle_outside(&r.head_angle_deg.to_string())),
            ));
        }
    }
    Ok(())
}

/// P, the number of positions: as stated, or the largest step + 1; at least 3. Returned
/// with where it comes from, for messages.
fn number_of_positions(
    readings: &[HeadReading],
    positions: Option<usize>,
    loc: &Locator<'_>,
    source: &str,
) -> Result<(usize, &'static str), FileError> {
    let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
    match positions {
        Some(n) => {
            if n < 3 {
                return Err(err(
                    loc.header(Col::Step.at()),
                    format!(
                        "column \"step\": {n} positions were stated; self-calibration needs \
                         at least 3 positions"
                    ),
                ));
            }
            Ok((n, "the number of positions stated"))
        }
        None => {
            let mut largest = 0;
            let mut at = 0;
            for (i, r) in readings.iter().enumerate() {
                if r.step > largest {
                    largest = r.step;
                    at = i;
                }
            }
            let p = loc.prefix(at, readings);
            let at = loc.row(at, readings, Col::Step.at());
            let Some(n) = largest.checked_add(1) else {
                return Err(err(
                    at,
                    format!("{p}column \"step\": {largest} is too large; P would not fit"),
                ));
            };
            if n < 3 {
                return Err(err(
                    at,
                    format!(
                        "{p}column \"step\": the largest step is {largest}, so P = {n}; \
                         self-calibration needs at least 3 positions (steps 0 to 2)"
                    ),
                ));
            }
            Ok((n, "the largest step + 1"))
        }
    }
}

/// The rules checked row by row, in order, with what the rows before have set.
struct RowChecks<'a> {
    readings: &'a [HeadReading],
    loc: &'a Locator<'a>,
    source: &'a str,
    /// The row that first read each (cycle, step, head).
    first_read: HashMap<(u32, usize, u32), usize>,
    /// The row that set each cycle's direction.
    cycle_direction: HashMap<u32, usize>,
    /// The row that set each head's angle.
    head_first: HashMap<u32, usize>,
    /// The heads by angle: key the angle's bits (angles in [0, 360), so the order of the
    /// bits is the order of the angles), value the reading that set the head.
    by_angle: BTreeMap<u64, usize>,
}

impl RowChecks<'_> {
    fn err(&self, at: (u64, u64), message: String) -> FileError {
        FileError::invalid(self.source, at, message)
    }

    /// Row `i` (`r`): its step within 0 … P−1 (P = `n`, from `n_from`), not read before,
    /// its cycle's one direction, its head's one angle.
    fn check(
        &mut self,
        i: usize,
        r: &HeadReading,
        n: usize,
        n_from: &str,
    ) -> Result<(), FileError> {
        let (loc, readings) = (self.loc, self.readings);
        let p = loc.prefix(i, readings);
        if r.step >= n {
            return Err(self.err(
                loc.row(i, readings, Col::Step.at()),
                format!(
                    "{p}column \"step\": {} is outside 0 to {} (P = {n}, {n_from})",
                    r.step,
                    n - 1
                ),
            ));
        }

        match self.first_read.entry((r.cycle, r.step, r.head)) {
            Entry::Occupied(first) => {
                return Err(FileError::invalid(
                    self.source,
                    loc.row_start(i, readings),
                    format!(
                        "{p}duplicate reading: cycle {}, step {}, head {} was already read at {}",
                        r.cycle,
                        r.step,
                        r.head,
                        loc.name(*first.get(), readings)
                    ),
                ));
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
            }
        }

        match self.cycle_direction.entry(r.cycle) {
            Entry::Occupied(first) => {
                let j = *first.get();
                let direction = readings.get(j).map(|f| f.direction).unwrap_or_default();
                if direction != r.direction {
                    return Err(FileError::invalid(
                        self.source,
                        loc.row(i, readings, Col::Direction.at()),
                        format!(
                            "{p}column \"direction\": {} disagrees with {} set for cycle {} at \
                             {}; a cycle has one direction",
                            direction_text(loc, i, Col::Direction.at(), r.direction),
                            direction_text(loc, j, Col::Direction.at(), direction),
                            r.cycle,
                            loc.name(j, readings)
                        ),
                    ));
                }
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
            }
        }
        self.head_angle(i, r, &p)
    }

    /// Row `i`'s head angle (`p`: the row's prefix for messages): 0 for head 1, the one
    /// angle of its head, and for a head new, not the angle of another head.
    fn head_angle(&mut self, i: usize, r: &HeadReading, p: &str) -> Result<(), FileError> {
        let (loc, readings) = (self.loc, self.readings);
        let angle_at = loc.row(i, readings, Col::HeadAngle.at());
        let angle = r.head_angle_deg;
        if r.head == 1 && angle != 0.0 {
            return Err(self.err(
                angle_at,
                format!(
                    "{p}column \"head_angle\": {} for head 1; head 1 is the reference and its \
                     angle must be 0",
                    angle_text(loc, i, readings)
                ),
            ));
        }
        match self.head_first.entry(r.head) {
            Entry::Occupied(first) => {
                let j = *first.get();
                if readings.get(j).is_some_and(|f| f.head_angle_deg != angle) {
                    return Err(FileError::invalid(
                        self.source,
                        angle_at,
                        format!(
                            "{p}column \"head_angle\": {} disagrees with {} set for head {} at \
                             {}; a head has one angle",
                            angle_text(loc, i, readings),
                            angle_text(loc, j, readings),
                            r.head,
                            loc.name(j, readings)
                        ),
                    ));
                }
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
                // -0 and 0 are the same angle: adding 0 turns -0 into 0.
                let key = (angle + 0.0).to_bits();
                let by_angle = &self.by_angle;
                let neighbours = [
                    by_angle.range(..=key).next_back(),
                    by_angle.range(key..).next(),
                    by_angle.first_key_value(),
                    by_angle.last_key_value(),
                ];
                let same = neighbours.into_iter().flatten().find(|&(&other, _)| {
                    angle_distance(angle, f64::from_bits(other)) <= SAME_ANGLE_DEG
                });
                if let Some((_, &j)) = same {
                    let other = readings.get(j).map_or(0, |f| f.head);
                    return Err(FileError::invalid(
                        self.source,
                        angle_at,
                        format!(
                            "{p}column \"head_angle\": head {} at {} is at the angle of head \
                             {other} ({} at {}); two heads cannot be at the same angle (equal \
                             modulo 360 within {SAME_ANGLE_DEG:e} degrees)",
                            r.head,
                            angle_text(loc, i, readings),
                            angle_text(loc, j, readings),
                            loc.name(j, readings)
                        ),
                    ));
                }
                self.by_angle.insert(key, i);
            }
        }
        Ok(())
    }
}

/// The heads read: at least 2, head 1 (the reference) among them.
fn check_heads(heads: &BTreeSet<u32>, loc: &Locator<'_>, source: &str) -> Result<(), FileError> {
    if heads.len() < 2 {
        return Err(FileError::invalid(
            source,
            loc.header(Col::Head.at()),
            format!(
                "column \"head\": only head {} is read; self-calibration needs at least 2 heads",
                list(heads)
            ),
        ));
    }
    if !heads.contains(&1) {
        return Err(FileError::invalid(
            source,
            loc.header(Col::Head.at()),
            format!(
                "column \"head\": head 1, the reference, is never read (the heads read are {})",
                list(heads)
            ),
        ));
    }
    Ok(())
}

/// Every step 0 … P−1 (P = `n`, from `n_from`) read by every head in every cycle: for
/// each (cycle, head) the steps read, sorted; the first missing one is the first gap.
fn check_every_step_read(
    readings: &[HeadReading],
    heads: &BTreeSet<u32>,
    (n, n_from): (usize, &str),
    loc: &Locator<'_>,
    source: &str,
) -> Result<(), FileError> {
    let mut steps: BTreeMap<u32, BTreeMap<u32, Vec<usize>>> = BTreeMap::new();
    for r in readings {
        steps
            .entry(r.cycle)
            .or_default()
            .entry(r.head)
            .or_default()
            .push(r.step);
    }
    for (cycle, read) in &mut steps {
        let mut first_missing: Option<(usize, u32)> = None;
        for &head in heads {
            let missing = match read.get_mut(&head) {
                None => 0,
                Some(s) => {
                    s.sort_unstable();
                    s.iter()
                        .enumerate()
                        .find(|&(k, &step)| k != step)
                        .map_or(s.len(), |(k, _)| k)
                }
            };
            if missing < n && first_missing.is_none_or(|m| (missing, head) < m) {
                first_missing = Some((missing, head));
            }
        }
        if let Some((step, head)) = first_missing {
            return Err(FileError::invalid(
                source,
                loc.header(Col::Step.at()),
                format!(
                    "column \"step\": cycle {cycle}, step {step} is never read by head {head}; \
                     every head must read every step 0 to {} in every cycle (P = {n}, {n_from})",
                    n - 1
                ),
            ));
        }
    }
    Ok(())
}
