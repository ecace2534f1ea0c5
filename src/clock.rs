//! Time stamps: seconds since the Unix epoch and their RFC 3339 UTC text, the one clock
//! of run manifests and calibration reports.

use std::time::{SystemTime, UNIX_EPOCH};

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
/// assert_eq!(polycal::clock::rfc3339(0.0), "1970-01-01T00:00:00.000Z");
/// assert_eq!(polycal::clock::rfc3339(1_700_000_000.25), "2023-11-14T22:13:20.250Z");
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
