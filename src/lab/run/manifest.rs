//! The run's manifest (`manifest.json`): its settings, the instruments, the ports, how
//! each session ended; and the time stamps it is written with.

pub use crate::clock::{rfc3339, unix_now};

use serde::{Deserialize, Serialize};

use super::RunSettings;

/// The manifest format tag.
pub const MANIFEST_FORMAT: &str = "polycal-run/1";

/// The ports of the three instruments.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Ports {
    /// Autocollimator 1.
    pub ac1: String,
    /// Autocollimator 2.
    pub ac2: String,
    /// The rotary table.
    pub table: String,
}

impl Ports {
    /// The ports of autocollimator 1, autocollimator 2 and the rotary table.
    pub fn new(ac1: impl Into<String>, ac2: impl Into<String>, table: impl Into<String>) -> Ports {
        Ports {
            ac1: ac1.into(),
            ac2: ac2.into(),
            table: table.into(),
        }
    }
}

/// The instruments' identification: ELCOMAT `d` replies and the SMC100 `1VE` reply.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Identification {
    /// Autocollimator 1.
    pub ac1: String,
    /// Autocollimator 2.
    pub ac2: String,
    /// The rotary table's controller.
    pub table: String,
}

impl Identification {
    /// The identification of autocollimator 1, autocollimator 2 and the table's controller.
    pub fn new(
        ac1: impl Into<String>,
        ac2: impl Into<String>,
        table: impl Into<String>,
    ) -> Identification {
        Identification {
            ac1: ac1.into(),
            ac2: ac2.into(),
            table: table.into(),
        }
    }
}

/// One session of a run: the first start, or one resumption.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[non_exhaustive]
pub struct Session {
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
    pub sessions: Vec<Session>,
}

/// The software of this build, e.g. `polycal 0.1.0`.
pub(super) fn software() -> String {
    format!("polycal {}", env!("CARGO_PKG_VERSION"))
}
