//! The run directory as a session's store ([`Store`] for [`RunDir`]): the run read back
//! from its files when a session starts — the measurement file, the manifest, and each
//! autocollimator's last reply in the traffic log — and every record kept in them.

use super::repeat::LastValue;
use super::store::{Record, RunSoFar, Store, StoreError};
use super::{MEASUREMENTS, RunDir, TRAFFIC};
use crate::lab::profile::Profile;
use crate::lab::traffic::TrafficLog;
use crate::measurement::{Reading, read_rows};

/// The readings on disk, all mountings, in the file's order (none when the file cannot
/// be read: it was checked when the run was opened).
fn stored(run: &RunDir) -> Vec<Reading> {
    let path = run.dir.join(MEASUREMENTS);
    std::fs::read(&path)
        .ok()
        .and_then(|bytes| read_rows(bytes.as_slice(), &path.display().to_string()).ok())
        .unwrap_or_default()
}

/// The profiles the run speaks (the manifest's `profiles`, each loaded by the name it was
/// given and only if its text is still the one recorded); the bundled `elcomat3000` and
/// `smc100` for a run that recorded none (an older run, or one driven through the
/// library). `None` when a recorded profile cannot be loaded as it was.
fn run_profiles(run: &RunDir) -> Option<(Profile, Profile)> {
    let Some(recorded) = run.profiles() else {
        return Some((
            Profile::load("elcomat3000").ok()?,
            Profile::load("smc100").ok()?,
        ));
    };
    let load =
        |r: &super::ProfileRecord| Profile::load(&r.name).ok().filter(|p| p.sha256 == r.sha256);
    Some((load(&recorded.ac)?, load(&recorded.table)?))
}

/// The last measurement reply of each autocollimator (index 0 … K−1) the traffic log
/// holds, with the table position commanded last before it, degrees; its lines read with
/// the run's profiles (nothing is read back from the log's free text).
fn last_replies(run: &RunDir, k: usize) -> Vec<Option<(LastValue, f64)>> {
    let Ok(text) = std::fs::read_to_string(run.dir.join(TRAFFIC)) else {
        return vec![None; k];
    };
    let Some((ac_profile, table_profile)) = run_profiles(run) else {
        return vec![None; k];
    };
    let mut angle: Option<f64> = None;
    let mut last: Vec<Option<(LastValue, f64)>> = vec![None; k];
    for line in text.lines() {
        let Ok(record) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        let field = |name: &str| record.get(name).and_then(|v| v.as_str()).unwrap_or("");
        let (device, event, text) = (field("device"), field("event"), field("text"));
        if device == "table" && event == "sent" {
            if let Ok(table) = table_profile.table()
                && let Some(deg) = table.commanded_deg(text)
            {
                angle = Some(deg);
            }
            continue;
        }
        if event != "received" {
            continue;
        }
        let index = device
            .strip_prefix("ac")
            .and_then(|n| n.parse::<usize>().ok())
            .and_then(|n| n.checked_sub(1))
            .filter(|&i| i < k);
        let reply = ac_profile
            .autocollimator()
            .ok()
            .and_then(|ac| ac.reading(text).ok());
        if let (Some(i), Some(deg), Some(reply)) = (index, angle, reply) {
            last[i] = Some((
                LastValue {
                    x_arcsec: reply.x_arcsec,
                    y_arcsec: reply.y_arcsec,
                    status: Some(reply.status),
                },
                deg,
            ));
        }
    }
    last
}

impl RunDir {
    /// Keeps `record` as a driver of the session keeps it in the run directory
    /// ([`Action::Keep`](super::Action::Keep)), with its traffic log: a reading only when
    /// the log holds every line before it, so that every reading on disk has its traffic
    /// logged (a reading after the log failed is not appended, and the error gives it as
    /// its row would read). `polycal run`'s driver and the Python package's keep every
    /// record so.
    ///
    /// # Errors
    ///
    /// The log failed before a reading, or the record could not be written
    /// ([`Store::keep`]); the session then ends with
    /// [`Outcome::FileError`](super::Outcome::FileError) and this message.
    pub fn keep_logged(
        &mut self,
        record: &Record,
        traffic: Option<&TrafficLog>,
    ) -> Result<(), StoreError> {
        if let Record::Reading(reading) = record
            && let Some(log) = traffic
            && let Err(e) = log.check()
        {
            return Err(StoreError::NotWritten {
                source: Box::new(StoreError::Log {
                    path: self.dir.join(TRAFFIC),
                    source: e,
                }),
                what: "the reading",
                row: self.row(reading),
            });
        }
        Store::keep(self, record)
    }

    /// The message that ends a session when the run's traffic log `traffic` failed to
    /// write (`PATH: why`, for [`Outcome::FileError`](super::Outcome::FileError)), if it
    /// did; with `sync`, the log is put on disk first (as before every move of the table)
    /// and a failed sync is such a failure too.
    pub fn traffic_failure(&self, traffic: &TrafficLog, sync: bool) -> Option<String> {
        let result = if sync {
            traffic.sync()
        } else {
            traffic.check()
        };
        let e = result.err()?;
        Some(format!("{}: {e}", self.dir.join(TRAFFIC).display()))
    }
}

impl Store for RunDir {
    fn so_far(&self) -> Result<RunSoFar, StoreError> {
        let manifest = &self.manifest;
        let settings = manifest.settings.clone();
        let k = settings.autocollimators();
        let mut mountings = manifest.mountings.clone();
        if mountings.is_empty() {
            mountings.push(super::MountingRecord::new(self.mounting));
        }
        Ok(RunSoFar {
            ac_names: (1..=k as u32)
                .map(|ac| manifest.ports.ac(ac).cloned().unwrap_or_default())
                .collect(),
            table_name: match manifest.ports.table.as_str() {
                "" => "table".to_string(),
                port => port.to_string(),
            },
            last_replies: last_replies(self, k),
            readings: stored(self),
            checked_cycles: manifest.checked_cycles.clone(),
            repeat_noise: manifest.repeat_noise.clone(),
            mountings,
            settings,
        })
    }

    fn keep(&mut self, record: &Record) -> Result<(), StoreError> {
        let not_written = |e, what, row| StoreError::NotWritten {
            source: Box::new(StoreError::Run(e)),
            what,
            row,
        };
        match record {
            Record::Reading(r) => self
                .append(r)
                .map_err(|e| not_written(e, "the reading", self.row(r))),
            Record::Replacement {
                first,
                replacement,
                remeasured,
            } => {
                let row = self.row(replacement);
                self.replace_reading(first, replacement, remeasured.clone())
                    .map_err(|e| not_written(e, "the reading measured again", row))
            }
            Record::Suspect(s) => Ok(self.record_suspect(s.clone())?),
            Record::Noise(noise) => Ok(self.record_noise(noise)?),
            Record::Misfit(warning) => Ok(self.record_misfit(warning)?),
            Record::Checked { cycle } => Ok(self.record_checked(*cycle)?),
            Record::Remounted { table_deg } => Ok(self.confirm_remount(*table_deg)?),
            Record::RemountWithdrawn => Ok(self.withdraw_remount()?),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::repeat::{DeviceMemory, Offered, StopReads};
    use super::super::verify::carried_memory;
    use super::super::{Ports, RunSettings};
    use super::*;
    use crate::lab::AcReading;

    /// The reading `values` give at a stop of `angle` (X; Y 0, status 003), with how
    /// many replies were refused.
    fn read(
        memory: &mut DeviceMemory,
        settings: &RunSettings,
        values: &[f64],
        angle: f64,
    ) -> Option<(f64, usize)> {
        let mut reads = StopReads::new(memory, settings, angle);
        for &x in values {
            let names = ("autocollimator 1", "mem", "cycle 1, step 2");
            match reads.offer(AcReading::new(3, x, Some(0.0)), memory, settings, names) {
                Offered::Again => {}
                Offered::Accepted(r) => return Some((r.x_arcsec, r.refused)),
                Offered::NoAgreement(_) => return None,
            }
        }
        None
    }

    #[test]
    fn the_last_reply_in_the_traffic_log_is_carried_over_with_its_table_position() {
        let dir = std::env::temp_dir().join(format!("polycal-dir-store-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let settings = RunSettings::new(8, 1).with_reading_noise_arcsec(0.05);
        let run = RunDir::open(&dir, &settings, &Ports::default(), false).unwrap();
        // ac1 last replied 1.5″ with the table sent to 405° (= 45°); a line that is not a
        // measurement and a record cut short change nothing.
        let records = [
            r#"{"t":0,"device":"table","port":"p","event":"sent","text":"1PA405\r\n"}"#,
            r#"{"t":0,"device":"ac1","port":"p","event":"received","text":"4 003 1.5 0.0"}"#,
            r#"{"t":0,"device":"ac1","port":"p","event":"received","text":"8 ELCOMAT 3000"}"#,
            r#"{"t":0,"device":"ac2","port":"p","event":"recei"#,
        ];
        std::fs::write(dir.join(TRAFFIC), records.join("\n")).unwrap();
        let so_far = run.so_far().unwrap();
        assert!(so_far.last_replies[1].is_none());
        let mut carried = carried_memory(&so_far);
        assert_eq!(carried.len(), 2);
        // At another stop the value is refused as stale, at 45° read again.
        let (x, refused) =
            read(&mut carried[0].clone(), &settings, &[1.5, 1.6, 1.7], 90.0).unwrap();
        assert_eq!(refused, 1);
        assert!((x - 1.65).abs() < 1e-12);
        let (_, refused) = read(&mut carried[0], &settings, &[1.5, 1.6], 45.0).unwrap();
        assert_eq!(refused, 0);
        // ac2 has nothing carried over.
        let (_, refused) = read(&mut carried[1], &settings, &[1.5, 1.6], 90.0).unwrap();
        assert_eq!(refused, 0);
        drop(run);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
