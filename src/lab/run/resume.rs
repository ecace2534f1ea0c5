//! Continuing an interrupted run, or a run in its next mounting: the manifest must be
//! the run's and its settings the same, a last line cut short when the run stopped (in
//! the measurement file or the traffic log) is removed, the measurement file must hold
//! exactly the first readings of the run's mountings in order, and a next mounting must
//! follow a complete one.

use std::collections::BTreeSet;
use std::fs::{self, OpenOptions};
use std::io;
use std::path::Path;

use super::directory::{
    COLUMNS, Key, columns_without_shift, first_comment, key, lock_exclusive, start_file,
};
use super::error::io_error;
use super::{
    MANIFEST, MEASUREMENTS, Manifest, Mounting, MountingRecord, Ports, RunDir, RunError,
    RunSettings, TRAFFIC,
};
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
        mounting: Option<Mounting>,
        budget: &WriteBudget,
    ) -> Result<RunDir, RunError> {
        let manifest_path = dir.join(MANIFEST);
        let text = match fs::read_to_string(&manifest_path) {
            Ok(text) => text,
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                return Err(match mounting {
                    Some(m) if m.setup > 1 => RunError::NoRunForMounting {
                        path: dir.to_path_buf(),
                        setup: m.setup,
                    },
                    _ => RunError::NoRunToResume {
                        path: dir.to_path_buf(),
                    },
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
        manifest.normalize_mountings();
        let existing = read_existing(&path, settings, &manifest.mountings, &mut warnings)?;
        let mountings_before = manifest.mountings.clone();
        choose_mounting(&mut manifest, &manifest_path, settings, mounting, &existing)?;
        let mountings_changed = manifest.mountings != mountings_before;
        // The line removed (if any) is no longer in the file.
        file.reload_len().map_err(io_error(&path))?;
        repair_cut_line(&dir.join(TRAFFIC), &mut warnings)?;
        let measurements = if let Some(columns) = existing.columns {
            ReadingWriter::resume(file, columns)
        } else if existing.empty {
            start_file(file, &[first_comment(&manifest)])?
        } else {
            // Comment lines only (the header was cut short): the header, then the rows.
            start_file(file, &[])?
        };
        manifest.ports = ports.clone();
        manifest.readings = existing.done.len();
        manifest.expected_readings = settings.reading_count() * manifest.mountings.len();
        let offset = (unix_now() - manifest.started_unix).max(0.0);
        let mut run = RunDir::assemble(
            dir,
            manifest,
            measurements,
            existing.done,
            RunClock::new(offset),
            warnings,
            budget,
        );
        // A mounting begun or restated is on record before anything is measured in it.
        if mountings_changed {
            run.write_manifest(false)?;
        }
        Ok(run)
    }
}

/// The mounting a session measures (module docs of [`RunDir::open_mounting`]): the
/// manifest's last, restated, or the next one after a complete last one, which is then
/// added to the manifest.
fn choose_mounting(
    manifest: &mut Manifest,
    path: &Path,
    settings: &RunSettings,
    requested: Option<Mounting>,
    existing: &Existing,
) -> Result<(), RunError> {
    let Some(last) = manifest.mountings.last().map(|m| m.mounting) else {
        return Ok(());
    };
    let target = requested.unwrap_or(last);
    let readings_of = |setup: u32| existing.done.iter().filter(|k| k.0 == setup).count();
    let shifted_without_column = existing
        .columns
        .as_ref()
        .is_some_and(|c| !c.as_slice().contains(&crate::measurement::Column::SHIFT))
        && target.shift_deg != 0.0;
    if let Some(i) = manifest
        .mountings
        .iter()
        .position(|m| m.mounting.setup == target.setup)
    {
        if target.setup != last.setup {
            return Err(RunError::MountingDone {
                path: path.to_path_buf(),
                setup: target.setup,
                last: last.setup,
            });
        }
        let recorded = manifest.mountings[i].mounting;
        if recorded != target {
            if readings_of(target.setup) > 0 || target.setup == 1 {
                return Err(RunError::OtherMounting {
                    path: path.to_path_buf(),
                    recorded,
                    requested: target,
                });
            }
            // Nothing measured in it yet: restated, and to be confirmed again.
            if shifted_without_column {
                return Err(RunError::NoShiftColumn {
                    path: path.to_path_buf(),
                    mounting: target,
                });
            }
            manifest.mountings[i] = MountingRecord::new(target);
        }
        return Ok(());
    }
    if target.setup != last.setup + 1 {
        return Err(RunError::MountingOrder {
            path: path.to_path_buf(),
            requested: target.setup,
            last: last.setup,
        });
    }
    let done = readings_of(last.setup);
    if done < settings.reading_count() {
        return Err(RunError::MountingIncomplete {
            path: path.to_path_buf(),
            setup: last.setup,
            done,
            expected: settings.reading_count(),
        });
    }
    if shifted_without_column {
        return Err(RunError::NoShiftColumn {
            path: path.to_path_buf(),
            mounting: target,
        });
    }
    manifest.mountings.push(MountingRecord::new(target));
    Ok(())
}

/// What an interrupted run left in its measurement file.
struct Existing {
    /// Whether the file has no byte (after the repair of a cut last line).
    empty: bool,
    /// Its columns, when it has a header.
    columns: Option<Columns>,
    /// The place of each reading.
    done: BTreeSet<Key>,
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
/// must have the run's header (or that of a run started before the `shift` column; none
/// yet is fine) and hold exactly the first readings of the run's `mountings`, in order.
fn read_existing(
    path: &Path,
    settings: &RunSettings,
    mountings: &[MountingRecord],
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
    let columns = match header {
        None => None,
        Some((index, line)) => {
            let known = [Columns::new(COLUMNS), columns_without_shift()];
            let Some(columns) = known.into_iter().find(|c| c.header() == line) else {
                return Err(RunError::Header {
                    at: Location::new(name, index as u64 + 1, 0),
                    found: line.to_string(),
                    expected: Columns::new(COLUMNS).header(),
                });
            };
            Some(columns)
        }
    };
    let readings =
        read_rows(bytes.as_slice(), &name).map_err(|error| RunError::Unreadable { error })?;
    let several = mountings.len() > 1;
    let place = |setup: u32, rest: String| {
        if several {
            format!("setup {setup}: {rest}")
        } else {
            rest
        }
    };
    let mut order = mountings.iter().flat_map(|m| {
        settings
            .readings()
            .into_iter()
            .map(move |(stop, ac)| (m.mounting, stop, ac))
    });
    let mut done = BTreeSet::new();
    for (k, reading) in readings.iter().enumerate() {
        let at = || Location::new(name.clone(), reading.line, 0);
        let Some((mounting, stop, ac)) = order.next() else {
            return Err(RunError::TooManyReadings { at: at() });
        };
        let face = mounting.face(settings, ac, stop.step);
        let found = (
            reading.setup,
            reading.cycle,
            reading.step,
            reading.ac,
            reading.face,
        );
        let expected = (mounting.setup, stop.cycle, stop.step, ac, face);
        if found != expected || reading.direction != stop.direction {
            return Err(RunError::OutOfOrder {
                at: at(),
                found: place(
                    found.0,
                    format!("{},{},{},{}", found.1, found.2, found.3, found.4),
                ),
                found_direction: reading.direction,
                number: k + 1,
                expected: place(
                    expected.0,
                    format!("{},{},{},{face}", stop.cycle, stop.step, ac),
                ),
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
        done.insert(key(reading));
    }
    Ok(Existing {
        empty: bytes.is_empty(),
        columns,
        done,
    })
}
