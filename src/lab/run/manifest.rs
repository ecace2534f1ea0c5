//! The run's manifest (`manifest.json`): its settings, the instruments, the ports, how
//! each session ended; the time stamps it is written with, and how it is replaced.

pub use crate::clock::{rfc3339, unix_now};

use std::fs::{self, File};
use std::io::{self, Write};
use std::path::Path;

use serde::{Deserialize, Serialize};

use super::error::io_error;
use super::{MANIFEST, RunError, RunSettings};
use crate::lab::{PerInstrument, WriteBudget};

/// The manifest format tag.
pub const MANIFEST_FORMAT: &str = "polycal-run/1";

/// The ports of the instruments: autocollimators 1 … K and the rotary table (the
/// manifest's `ports`).
pub type Ports = PerInstrument<String>;

/// The instruments' identification (the manifest's `instruments`): each
/// autocollimator's reply to its identification query, and the table controller's.
pub type Identification = PerInstrument<String>;

/// One session of a run: the first start, or one resumption.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct SessionRecord {
    /// The software, e.g. `polycal 0.1.0`.
    pub software: String,
    /// Start, RFC 3339 UTC.
    pub started: String,
    /// End, RFC 3339 UTC; `null` while running (or if the process was killed).
    pub ended: Option<String>,
    /// How the session ended (see [`super::Outcome`]); `running` until then.
    pub outcome: String,
    /// Ports used.
    pub ports: Ports,
    /// Readings on disk when the session started.
    pub readings_before: usize,
    /// Readings on disk when it ended.
    pub readings_after: usize,
}

/// A profile a run speaks with its instruments (the manifest's `profiles`): its name as
/// it was given (a bundled name or a profile file's path) and the SHA-256 of its text.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct ProfileRecord {
    /// The name given (`pi-gcs2`, `lab/table.toml`).
    pub name: String,
    /// The SHA-256 of its text, lower-case hex.
    pub sha256: String,
}

impl ProfileRecord {
    /// The record of a profile given as `name`.
    pub fn new(name: impl Into<String>, sha256: impl Into<String>) -> ProfileRecord {
        ProfileRecord {
            name: name.into(),
            sha256: sha256.into(),
        }
    }
}

/// The profiles of a run (the manifest's `profiles`): the autocollimators' and the
/// table's.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[non_exhaustive]
pub struct RunProfiles {
    /// The autocollimators' profile.
    pub ac: ProfileRecord,
    /// The table's profile.
    pub table: ProfileRecord,
}

impl RunProfiles {
    /// The autocollimators' profile and the table's.
    pub fn new(ac: ProfileRecord, table: ProfileRecord) -> RunProfiles {
        RunProfiles { ac, table }
    }
}

/// The profiles the run in `dir` recorded (its manifest's `profiles`), when its manifest
/// can be read and records them: what `--resume` speaks when no profile is given.
/// Opening the run ([`RunDir::open`](super::RunDir::open)) reports a manifest that
/// cannot be read.
pub fn recorded_profiles(dir: &Path) -> Option<RunProfiles> {
    let text = std::fs::read_to_string(dir.join(MANIFEST)).ok()?;
    let manifest: serde_json::Value = serde_json::from_str(&text).ok()?;
    serde_json::from_value(manifest.get("profiles")?.clone()).ok()
}

/// `manifest.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Manifest {
    /// [`MANIFEST_FORMAT`].
    pub format: String,
    /// The software of the latest session, e.g. `polycal 0.1.0`.
    pub software: String,
    /// The run's settings.
    pub settings: RunSettings,
    /// The instruments' identification (`null` until they answered).
    pub instruments: Option<Identification>,
    /// Ports of the latest session.
    pub ports: Ports,
    /// Start of the run, RFC 3339 UTC.
    pub started: String,
    /// Start of the run, seconds since the Unix epoch (the origin of `time`).
    pub started_unix: f64,
    /// End of the latest session, RFC 3339 UTC.
    pub ended: Option<String>,
    /// How the latest session ended: `running`, `completed`, `interrupted`,
    /// `instrument-error: …` or `file-error: …`.
    pub outcome: String,
    /// Readings on disk.
    pub readings: usize,
    /// Readings of the complete run.
    pub expected_readings: usize,
    /// Every session, oldest first.
    pub sessions: Vec<SessionRecord>,
    /// Readings measured again at the end of their cycle because they lay far beyond
    /// the run's noise; their first values are in `remeasured.csv` (docs/FORMAT.md §7.3).
    #[serde(default)]
    pub remeasured: Vec<super::Remeasured>,
    /// Readings far beyond the run's noise that measuring their stop again confirmed.
    #[serde(default)]
    pub suspect: Vec<super::Suspect>,
    /// The polygon's mountings, in the order measured (docs/FORMAT.md §7.3, *Several
    /// mountings*); the last is the one being measured. Absent from older manifests: the
    /// first mounting alone.
    #[serde(default)]
    pub mountings: Vec<super::MountingRecord>,
    /// The cycles whose check after the cycle (docs/FORMAT.md §7.3, *Checked while it
    /// runs*) was done, as (setup, cycle): a session that ended before the check of its
    /// last complete cycle has it done when the run is resumed. Absent from older
    /// manifests (`None`): every complete cycle counts as checked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub checked_cycles: Option<Vec<(u32, u32)>>,
    /// The noise the run judged each autocollimator's readings by at its latest check
    /// after a cycle: measured from the repeats at the stops, bounded by the stated one
    /// (docs/FORMAT.md §7.3, *The noise the run measures*). Absent from older manifests.
    #[serde(default)]
    pub repeat_noise: Vec<super::NoiseRecord>,
    /// The profiles the run speaks with its instruments, recorded when its first session
    /// begins (docs/FORMAT.md §7.5); `--resume` takes them from here. Absent from older
    /// manifests and from runs driven by software of the lab's own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub profiles: Option<RunProfiles>,
}

/// The software of this build, e.g. `polycal 0.1.0`.
pub(super) fn software() -> String {
    format!("polycal {}", env!("CARGO_PKG_VERSION"))
}

impl Manifest {
    /// The mountings, the first alone when the manifest lists none (an older one).
    pub(super) fn normalize_mountings(&mut self) {
        if self.mountings.is_empty() {
            self.mountings
                .push(super::MountingRecord::new(super::Mounting::default()));
        }
    }

    /// Starts a session of this software on the manifest's ports, with `readings_before`
    /// readings on disk: the outcome is `running` again.
    pub(super) fn open_session(&mut self, readings_before: usize) {
        self.software = software();
        self.outcome = "running".into();
        self.ended = None;
        self.sessions.push(SessionRecord {
            software: software(),
            started: rfc3339(unix_now()),
            ended: None,
            outcome: "running".into(),
            ports: self.ports.clone(),
            readings_before,
            readings_after: readings_before,
        });
    }

    /// Records that the latest session ended now with `outcome`, `readings` on disk.
    pub(super) fn end_session(&mut self, outcome: &str, readings: usize) {
        let now = rfc3339(unix_now());
        self.outcome = outcome.to_string();
        self.ended = Some(now.clone());
        self.readings = readings;
        if let Some(session) = self.sessions.last_mut() {
            session.ended = Some(now);
            session.outcome = outcome.to_string();
            session.readings_after = readings;
        }
    }

    /// Replaces `dir`'s manifest with this one atomically: written beside (through
    /// `budget`), synced, renamed. A failed write leaves the manifest that was there and
    /// removes what it wrote beside.
    pub(super) fn write_to(&self, dir: &Path, budget: &WriteBudget) -> Result<(), RunError> {
        let path = dir.join(MANIFEST);
        let tmp = dir.join(format!("{MANIFEST}.tmp"));
        let text = serde_json::to_string_pretty(self).map_err(|e| RunError::Io {
            path: path.clone(),
            source: io::Error::other(e),
        })? + "\n";
        let write = || -> io::Result<()> {
            let file = File::create(&tmp)?;
            let mut out = budget.writer(MANIFEST, &file);
            out.write_all(text.as_bytes())?;
            file.sync_all()?;
            fs::rename(&tmp, &path)?;
            if let Ok(d) = File::open(dir) {
                let _ = d.sync_all();
            }
            Ok(())
        };
        write().map_err(|e| {
            // Whatever was written beside goes, so that the space it took is free again.
            let _ = fs::remove_file(&tmp);
            io_error(&path)(e)
        })
    }
}
