//! Writing the self-calibration CSV (docs/FORMAT.md §9.2).
//!
//! Floats are written with Rust's `{}` formatting, the shortest text that reads back to
//! the same `f64`; a time not recorded is an empty field; lines end with `\n`.

use std::fmt::Write as _;
use std::io::{self, BufWriter, Write};

use crate::measurement::Direction;
use crate::selfcal::{HeadReading, SelfcalSet};

/// The header `SelfcalSet::write_to` writes for `set`: the required columns, then
/// `direction` if some reading is counter-clockwise and `time` if some reading has one.
fn header(set: &SelfcalSet) -> (String, bool, bool) {
    let direction = set.readings.iter().any(|r| r.direction == Direction::Ccw);
    let time = set.readings.iter().any(|r| r.time_seconds.is_some());
    let mut header = String::from("cycle,step,head,head_angle,reading");
    if direction {
        header.push_str(",direction");
    }
    if time {
        header.push_str(",time");
    }
    (header, direction, time)
}

fn row(r: &HeadReading, direction: bool, time: bool, out: &mut String) {
    // Writing to a String cannot fail.
    let _ = write!(
        out,
        "{},{},{},{},{}",
        r.cycle, r.step, r.head, r.head_angle_deg, r.reading_arcsec
    );
    if direction {
        out.push(',');
        out.push_str(r.direction.as_str());
    }
    if time {
        out.push(',');
        if let Some(t) = r.time_seconds {
            let _ = write!(out, "{t}");
        }
    }
    out.push('\n');
}

/// Writes `set` with `comments` as leading `# ` lines (a comment holding line breaks
/// becomes several lines, an empty line a lone `#`).
pub(super) fn write(set: &SelfcalSet, writer: impl Write, comments: &[String]) -> io::Result<()> {
    let mut w = BufWriter::new(writer);
    let mut text = String::new();
    for comment in comments {
        let lines = comment
            .split('\n')
            .flat_map(|line| line.strip_suffix('\r').unwrap_or(line).split('\r'));
        for line in lines {
            if line.is_empty() {
                text.push_str("#\n");
            } else {
                let _ = writeln!(text, "# {line}");
            }
        }
    }
    let (header, direction, time) = header(set);
    text.push_str(&header);
    text.push('\n');
    w.write_all(text.as_bytes())?;
    for r in &set.readings {
        text.clear();
        row(r, direction, time, &mut text);
        w.write_all(text.as_bytes())?;
    }
    w.flush()
}
