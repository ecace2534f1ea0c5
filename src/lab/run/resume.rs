//! Continuing an interrupted run: the manifest must be the run's and its settings the
//! same, a last line cut short when the run stopped (in the measurement file or the
//! traffic log) is removed, and the measurement file must hold exactly the first
//! readings of the run in order.

use std::collections::BTreeSet;
use std::fs::{self, OpenOptions};
use std::io;
use std::path::Path;

use super::directory::{COLUMNS, first_comment, lock_exclusive, start_file};
use super::error::io_error;
use super::{MANIFEST, MEASUREMENTS, Manifest, Ports, RunDir, RunError, RunSettings, TRAFFIC};
use crate::input::Location;
use crate::lab::WriteBudget;
use crate::lab::disk::LineFile;
use crate::lab::traffic::RunClock;
use crate::measurement::{Columns, ReadingWriter, read_rows};

use super::unix_now;

impl RunDir {
    /// Opens `dir` to continue the run it holds (see [`RunDir::open`]).
    pub(super) fn resume(
        dir: &Path,
        settings: &RunSettings,
        ports: &Ports,
        budget: &WriteBudget,
    ) -> Result<RunDir, RunError> {
        let manifest_path = dir.join(MANIFEST);
        let text = match fs::read_to_string(&manifest_path) {
            Ok(text) => text,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Err(RunError::NoRunToResume {
                    path: dir.to_path_buf(),
                });
            }
            Err(e) => return Err(io_error(&manifest_path)(e)),
        };
        let mut manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| RunError::NotAManifest {
                path: manifest_path.clone(),
                message: e.to_string(),
            })?;
        if !manifest.settings.differences(settings).is_empty() {
            return Err(RunError::OtherSettings {
                path: manifest_path,
                started: Box::new(manifest.settings.clone()),
                requested: Box::new(settings.clone()),
            });
        }
        let path = dir.join(MEASUREMENTS);
        let mut file = LineFile::open(&path, false, budget).map_err(io_error(&path))?;
        lock_exclusive(file.file(), &path)?;
        let mut warnings = Vec::new();
        let existing = read_existing(&path, settings, &mut warnings)?;
        // The line removed (if any) is no longer in the file.
        file.reload_len().map_err(io_error(&path))?;
        repair_cut_line(&dir.join(TRAFFIC), &mut warnings)?;
        let measurements = if existing.header {
            ReadingWriter::resume(file, Columns::new(COLUMNS))
        } else if existing.empty {
            start_file(file, &[first_comment(&manifest)])?
        } else {
            // Comment lines only (the header was cut short): the header, then the rows.
            start_file(file, &[])?
        };
        manifest.ports = ports.clone();
        manifest.readings = existing.done.len();
        let offset = (unix_now() - manifest.started_unix).max(0.0);
        Ok(RunDir::assemble(
            dir,
            manifest,
            measurements,
            existing.done,
            RunClock::new(offset),
            warnings,
            budget,
        ))
    }
}

/// What an interrupted run left in its measurement file.
struct Existing {
    /// Whether the file has no byte (after the repair of a cut last line).
    empty: bool,
    /// Whether it has the header.
    header: bool,
    /// The (cycle, step, ac) of each reading.
    done: BTreeSet<(u32, usize, u32)>,
}

/// Removes a last line cut short when the run stopped (no line feed at the end of the
/// file), with a warning; returns the bytes that remain.
fn repair_cut_line(path: &Path, warnings: &mut Vec<String>) -> Result<Vec<u8>, RunError> {
    let mut bytes = match fs::read(path) {
        Ok(b) => b,
        Err(e) if e.kind() == io::ErrorKind::NotFound => return Ok(Vec::new()),
        Err(e) => return Err(io_error(path)(e)),
    };
    if !bytes.is_empty() && bytes.last() != Some(&b'\n') {
        let keep = bytes.iter().rposition(|&b| b == b'\n').map_or(0, |i| i + 1);
        let cut = String::from_utf8_lossy(&bytes[keep..]).into_owned();
        let file = OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(io_error(path))?;
        file.set_len(keep as u64)
            .and_then(|()| file.sync_all())
            .map_err(io_error(path))?;
        bytes.truncate(keep);
        warnings.push(format!(
            "{}: removed the last line, cut short when the run stopped: {cut:?}",
            path.display()
        ));
    }
    Ok(bytes)
}

/// Reads the readings already on disk, after removing a cut-short last line: the file
/// must have the run's header (unless it has no header yet) and hold exactly the first
/// readings of the run, in order.
fn read_existing(
    path: &Path,
    settings: &RunSettings,
    warnings: &mut Vec<String>,
) -> Result<Existing, RunError> {
    let bytes = repair_cut_line(path, warnings)?;
    let name = path.display().to_string();
    // The header is the first line that is neither a comment nor blank.
    let text = String::from_utf8_lossy(&bytes);
    let header = text
        .lines()
        .enumerate()
        .find(|(_, line)| !line.starts_with('#') && !line.trim().is_empty());
    let expected = Columns::new(COLUMNS).header();
    if let Some((index, line)) = header
        && line != expected
    {
        return Err(RunError::Header {
            at: Location::new(name, index as u64 + 1, 0),
            found: line.to_string(),
            expected,
        });
    }
    let readings =
        read_rows(bytes.as_slice(), &name).map_err(|error| RunError::Unreadable { error })?;
    let order = settings.readings();
    let mut done = BTreeSet::new();
    for (k, reading) in readings.iter().enumerate() {
        let at = || Location::new(name.clone(), reading.line, 0);
        let Some(&(stop, ac)) = order.get(k) else {
            return Err(RunError::TooManyReadings { at: at() });
        };
        let face = settings.face(ac, stop.step);
        let found = (reading.cycle, reading.step, reading.ac, reading.face);
        if found != (stop.cycle, stop.step, ac, face) || reading.direction != stop.direction {
            return Err(RunError::OutOfOrder {
                at: at(),
                found: format!("{},{},{},{}", found.0, found.1, found.2, found.3),
                found_direction: reading.direction,
                number: k + 1,
                expected: format!("{},{},{},{face}", stop.cycle, stop.step, ac),
                expected_direction: stop.direction,
            });
        }
        for (column, value) in [
            ("time", reading.time_seconds),
            ("encoder", reading.encoder_degrees),
        ] {
            if value.is_none() {
                return Err(RunError::Missing { at: at(), column });
            }
        }
        done.insert((stop.cycle, stop.step, ac));
    }
    Ok(Existing {
        empty: bytes.is_empty(),
        header: header.is_some(),
        done,
    })
}
