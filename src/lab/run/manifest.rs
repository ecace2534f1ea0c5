//! The run's manifest (`manifest.json`): its settings, the instruments, the ports, how
//! each session ended; and the time stamps it is written with.

use std::time::{SystemTime, UNIX_EPOCH};

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

/// Seconds since the Unix epoch.
pub fn unix_now() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map(|d| d.as_secs_f64())
        .unwrap_or(0.0)
}

/// An RFC 3339 UTC time stamp (`2026-11-03T14:05:09.123Z`) of seconds since the epoch.
///
/// ```
/// assert_eq!(polycal::lab::run::rfc3339(0.0), "1970-01-01T00:00:00.000Z");
/// assert_eq!(polycal::lab::run::rfc3339(1_700_000_000.25), "2023-11-14T22:13:20.250Z");
/// ```
pub fn rfc3339(unix_seconds: f64) -> String {
    let total_ms = (unix_seconds.max(0.0) * 1000.0).round() as i64;
    let (secs, ms) = (total_ms.div_euclid(1000), total_ms.rem_euclid(1000));
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    // Days to civil date (H. Hinnant's algorithm).
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{ms:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// The software of this build, e.g. `polycal 0.1.0`.
pub(super) fn software() -> String {
    format!("polycal {}", env!("CARGO_PKG_VERSION"))
}
