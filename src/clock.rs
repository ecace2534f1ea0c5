//! Time stamps: seconds since the Unix epoch and their RFC 3339 UTC text, the one clock
//! of run manifests and calibration reports; and the days a report states, `YYYY-MM-DD`.

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
    let (year, month, day) = civil_from_days(days);
    format!(
        "{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}.{ms:03}Z",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60
    )
}

/// The civil (proleptic Gregorian) date of a count of days since 1970-01-01: year, month,
/// day (H. Hinnant's algorithm).
fn civil_from_days(days: i64) -> (i64, i64, i64) {
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    (year, month, day)
}

/// The days since 1970-01-01 of a day `YYYY-MM-DD` of the calendar ([`is_date`]), or
/// `None` when `text` is not one (H. Hinnant's algorithm, the inverse of the dates
/// [`rfc3339`] and [`date_of_days`] write).
///
/// ```
/// assert_eq!(polycal::clock::days_from_date("1970-01-01"), Some(0));
/// assert_eq!(polycal::clock::days_from_date("2024-03-01"), Some(19_783));
/// assert_eq!(polycal::clock::days_from_date("2023-02-29"), None);
/// ```
pub fn days_from_date(text: &str) -> Option<i64> {
    if !is_date(text) {
        return None;
    }
    let field = |r: std::ops::Range<usize>| text.get(r).and_then(|s| s.parse::<i64>().ok());
    let (year, month, day) = (field(0..4)?, field(5..7)?, field(8..10)?);
    let year = year - i64::from(month <= 2);
    let era = year.div_euclid(400);
    let yoe = year - era * 400;
    let mp = if month > 2 { month - 3 } else { month + 9 };
    let doy = (153 * mp + 2) / 5 + day - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    Some(era * 146_097 + doe - 719_468)
}

/// The day `YYYY-MM-DD` of a count of days since 1970-01-01.
///
/// ```
/// assert_eq!(polycal::clock::date_of_days(19_783), "2024-03-01");
/// ```
pub fn date_of_days(days: i64) -> String {
    let (year, month, day) = civil_from_days(days);
    format!("{year:04}-{month:02}-{day:02}")
}

/// Today, `YYYY-MM-DD`, in UTC, from the system clock.
pub fn today() -> String {
    date_of_days((unix_now() / 86_400.0).floor() as i64)
}

/// Whether `text` is a day `YYYY-MM-DD` of the calendar (an `xs:date` without a time zone,
/// as a certificate's dates are): `2024-02-29` is, `2026-02-29` and `2026-1-03` are not.
pub fn is_date(text: &str) -> bool {
    let b = text.as_bytes();
    if b.len() != 10 || b[4] != b'-' || b[7] != b'-' {
        return false;
    }
    let digits = |r: std::ops::Range<usize>| -> Option<u32> {
        text.get(r.clone())
            .filter(|s| s.bytes().all(|c| c.is_ascii_digit()))
            .and_then(|s| s.parse().ok())
    };
    let (Some(year), Some(month), Some(day)) = (digits(0..4), digits(5..7), digits(8..10)) else {
        return false;
    };
    let leap = (year % 4 == 0 && year % 100 != 0) || year % 400 == 0;
    let days = match month {
        1 | 3 | 5 | 7 | 8 | 10 | 12 => 31,
        4 | 6 | 9 | 11 => 30,
        2 if leap => 29,
        2 => 28,
        _ => return false,
    };
    year > 0 && (1..=days).contains(&day)
}
