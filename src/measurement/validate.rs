//! The structural rules of a measurement set (docs/FORMAT.md §2): ranges, missing faces and
//! steps, duplicates, face offsets per autocollimator, one direction per cycle.

use std::collections::hash_map::Entry;
use std::collections::{BTreeSet, HashMap};

use super::Reading;
use super::columns::{Col, direction_text};
use crate::input::FileError;
use crate::input::table::Locator;

/// (face − 1 − step) mod N, without overflow for any N ≥ 1.
pub(super) fn face_offset(face: usize, step: usize, n: usize) -> usize {
    let n128 = n as u128;
    if n128 == 0 {
        return 0;
    }
    let step = (step as u128) % n128;
    // face ≥ 1 in a validated set; `face + N − 1 − step` cannot underflow as step < N.
    let d = (face as u128 + n128 - 1 - step) % n128;
    usize::try_from(d).unwrap_or(0)
}

/// The face that offset `d` puts in front of the autocollimator at `step`.
pub(super) fn expected_face(step: usize, d: usize, n: usize) -> u128 {
    let n128 = n as u128;
    if n128 == 0 {
        return 0;
    }
    ((step as u128) % n128 + d as u128) % n128 + 1
}

/// The values of `lo ..= hi` not in `present`, as ranges, and how many there are.
pub(super) fn missing_ranges(
    present: &BTreeSet<usize>,
    lo: usize,
    hi: usize,
) -> (Vec<(usize, usize)>, u128) {
    let mut ranges = Vec::new();
    let mut next = Some(lo);
    for &x in present.range(lo..=hi) {
        let Some(cur) = next else { break };
        if x > cur {
            ranges.push((cur, x - 1));
        }
        next = x.checked_add(1);
    }
    if let Some(cur) = next
        && cur <= hi
    {
        ranges.push((cur, hi));
    }
    let count = ranges.iter().map(|&(a, b)| (b - a) as u128 + 1).sum();
    (ranges, count)
}

pub(super) fn format_ranges(ranges: &[(usize, usize)]) -> String {
    const MAX: usize = 20;
    let mut parts: Vec<String> = ranges
        .iter()
        .take(MAX)
        .map(|&(a, b)| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}-{b}")
            }
        })
        .collect();
    if ranges.len() > MAX {
        parts.push("...".to_string());
    }
    parts.join(", ")
}

/// Checks readings against the structural rules; returns N.
pub(super) fn validate(
    readings: &[Reading],
    faces: Option<usize>,
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
    let (n, n_from) = number_of_faces(readings, faces, loc, source)?;

    // Row by row, in order.
    let mut rows = RowChecks {
        readings,
        loc,
        source,
        first_read: HashMap::new(),
        cycle_direction: HashMap::new(),
        stream_offset: HashMap::new(),
    };
    for (i, r) in readings.iter().enumerate() {
        rows.check(i, r, n, n_from)?;
    }
    check_every_face_and_step(readings, (n, n_from), loc, source)?;
    Ok(n)
}

/// Values (already checked, with their text, when read from a file): cycle, ac, face and
/// setup at least 1, every number within its limit.
fn check_values(readings: &[Reading], loc: &Locator<'_>, source: &str) -> Result<(), FileError> {
    let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
    for (i, r) in readings.iter().enumerate() {
        let p = loc.prefix(i, readings);
        for (col, zero) in [
            (Col::Cycle, r.cycle == 0),
            (Col::Ac, r.ac == 0),
            (Col::Face, r.face == 0),
            (Col::Setup, r.setup == 0),
        ] {
            if zero {
                let name = col.name();
                return Err(err(
                    loc.row(i, readings, col.at()),
                    format!("{p}column {name:?}: 0 is not allowed; {name} must be at least 1"),
                ));
            }
        }
        for (col, x) in [
            (Col::Reading, Some(r.reading_arcsec)),
            (Col::Time, r.time_seconds),
            (Col::ReadingY, r.reading_y_arcsec),
            (Col::Temperature, r.temperature_celsius),
            (Col::Encoder, r.encoder_degrees),
        ] {
            if let (Some(x), Some((limit, what))) = (x, col.limit())
                && let Err(rule) = limit.check(x, what)
            {
                return Err(err(
                    loc.row(i, readings, col.at()),
                    format!("{p}column {:?}: {rule}", col.name()),
                ));
            }
        }
    }
    Ok(())
}

/// N, the number of faces: as stated, or the largest face; at least 3. Returned with
/// where it comes from, for messages.
fn number_of_faces(
    readings: &[Reading],
    faces: Option<usize>,
    loc: &Locator<'_>,
    source: &str,
) -> Result<(usize, &'static str), FileError> {
    let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
    match faces {
        Some(n) => {
            if n < 3 {
                return Err(err(
                    loc.header(Col::Face.at()),
                    format!("a polygon needs at least 3 faces, {n} were stated"),
                ));
            }
            Ok((n, "the number of faces stated"))
        }
        None => {
            let mut largest = 0;
            let mut at = 0;
            for (i, r) in readings.iter().enumerate() {
                if r.face > largest {
                    largest = r.face;
                    at = i;
                }
            }
            if largest < 3 {
                return Err(err(
                    loc.row(at, readings, Col::Face.at()),
                    format!(
                        "{}column \"face\": the largest face is {largest}, so N = {largest}; \
                         a polygon needs at least 3 faces",
                        loc.prefix(at, readings)
                    ),
                ));
            }
            Ok((largest, "the largest face"))
        }
    }
}

/// The rules checked row by row, in order, with what the rows before have set.
struct RowChecks<'a> {
    readings: &'a [Reading],
    loc: &'a Locator<'a>,
    source: &'a str,
    /// The row that first read each (setup, cycle, step, ac).
    first_read: HashMap<(u32, u32, usize, u32), usize>,
    /// The row that set each (setup, cycle)'s direction.
    cycle_direction: HashMap<(u32, u32), usize>,
    /// Each (setup, ac) stream's face offset, and the row that set it.
    stream_offset: HashMap<(u32, u32), (usize, usize)>,
}

impl RowChecks<'_> {
    /// Row `i` (`r`): face and step within range (N = `n`, from `n_from`), not read
    /// before, its cycle's one direction, its stream's one face offset.
    fn check(&mut self, i: usize, r: &Reading, n: usize, n_from: &str) -> Result<(), FileError> {
        let (loc, readings, source) = (self.loc, self.readings, self.source);
        let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
        let p = loc.prefix(i, readings);
        let mut range = Vec::new();
        if r.face > n {
            range.push((
                loc.row(i, readings, Col::Face.at()),
                format!(
                    "{p}column \"face\": {} is outside 1 to {n} (N = {n}, {n_from})",
                    r.face
                ),
            ));
        }
        if r.step > n {
            range.push((
                loc.row(i, readings, Col::Step.at()),
                format!(
                    "{p}column \"step\": {} is outside 0 to {n} (N = {n}, {n_from})",
                    r.step
                ),
            ));
        }
        if let Some((at, message)) = range.into_iter().min_by_key(|(at, _)| *at) {
            return Err(err(at, message));
        }

        match self.first_read.entry((r.setup, r.cycle, r.step, r.ac)) {
            Entry::Occupied(first) => {
                return Err(err(
                    loc.row_start(i, readings),
                    format!(
                        "{p}duplicate reading: setup {}, cycle {}, step {}, ac {} was already \
                         read at {}",
                        r.setup,
                        r.cycle,
                        r.step,
                        r.ac,
                        loc.name(*first.get(), readings)
                    ),
                ));
            }
            Entry::Vacant(slot) => {
                slot.insert(i);
            }
        }

        match self.cycle_direction.entry((r.setup, r.cycle)) {
            Entry::Occupied(first) => {
                let j = *first.get();
                let direction = readings.get(j).map(|f| f.direction).unwrap_or_default();
                if direction != r.direction {
                    return Err(err(
                        loc.row(i, readings, Col::Direction.at()),
                        format!(
                            "{p}column \"direction\": {} disagrees with {} set for setup {}, \
                             cycle {} at {}; a cycle has one direction",
                            direction_text(loc, i, Col::Direction.at(), r.direction),
                            direction_text(loc, j, Col::Direction.at(), direction),
                            r.setup,
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

        let d = face_offset(r.face, r.step, n);
        match self.stream_offset.entry((r.setup, r.ac)) {
            Entry::Occupied(first) => {
                let (d0, j) = *first.get();
                if d != d0 {
                    return Err(err(
                        loc.row(i, readings, Col::Face.at()),
                        format!(
                            "{p}column \"face\": face {} at step {} does not fit setup {}, \
                             ac {}: face {} was expected, as {} set the offset \
                             (face - 1 - step) mod {n} = {d0} (N = {n}, {n_from})",
                            r.face,
                            r.step,
                            r.setup,
                            r.ac,
                            expected_face(r.step, d0, n),
                            loc.name(j, readings)
                        ),
                    ));
                }
            }
            Entry::Vacant(slot) => {
                slot.insert((d, i));
            }
        }
        Ok(())
    }
}

/// Every face 1 … N read and every step 0 … N−1 present (N = `n`, from `n_from`).
fn check_every_face_and_step(
    readings: &[Reading],
    (n, n_from): (usize, &str),
    loc: &Locator<'_>,
    source: &str,
) -> Result<(), FileError> {
    let err = |at: (u64, u64), message: String| FileError::invalid(source, at, message);
    let present: BTreeSet<usize> = readings.iter().map(|r| r.face).collect();
    let (missing, count) = missing_ranges(&present, 1, n);
    if count > 0 {
        let (what, verb) = if count == 1 {
            ("face", "is")
        } else {
            ("faces", "are")
        };
        return Err(err(
            loc.header(Col::Face.at()),
            format!(
                "column \"face\": {what} {} {verb} never read; every face 1 to {n} must be \
                 read (N = {n}, {n_from})",
                format_ranges(&missing)
            ),
        ));
    }
    let present: BTreeSet<usize> = readings.iter().map(|r| r.step).collect();
    let (missing, count) = missing_ranges(&present, 0, n - 1);
    if count > 0 {
        let (what, verb) = if count == 1 {
            ("step", "is")
        } else {
            ("steps", "are")
        };
        return Err(err(
            loc.header(Col::Step.at()),
            format!(
                "column \"step\": {what} {} {verb} never present; every step 0 to {} must be \
                 present (N = {n}, {n_from})",
                format_ranges(&missing),
                n - 1
            ),
        ));
    }
    Ok(())
}
