//! The Möller-Wedel ELCOMAT 3000 autocollimator protocol (FORMAT.md §7).
//!
//! The host sends one-character commands ending in LF; the device ends every reply with
//! CR. The driver uses:
//!
//! | command | reply | use |
//! |---|---|---|
//! | `s` | none | stop any stream (on start, followed by clearing the input) |
//! | `d` | `8 <text>` | identification |
//! | `a` | `4 <sss> <x> <y>` | one absolute measurement |
//!
//! `<sss>` is a three-digit status whose last digit says which axes are valid: 1 X, 2 Y,
//! 3 both (0 none). A reply whose X is not valid (no reflected light, out of range) is
//! not a reading: the measurement is retried as a query and, if X stays invalid, fails.

use std::time::Duration;

use super::transport::query;
use super::{AcReading, Autocollimator, InstrumentError, QueryOptions, Transport};

/// Identification command.
pub const IDENTIFY: &str = "d\n";
/// Stop-streaming command (no reply).
pub const STOP_STREAM: &str = "s\n";
/// One absolute measurement.
pub const MEASURE: &str = "a\n";

/// Parses a `d` reply, `8 <text>`, into the text.
///
/// ```
/// use polycal::instrument::elcomat::parse_identification;
/// assert_eq!(parse_identification("8 ELCOMAT 3000 S/N 12").unwrap(), "ELCOMAT 3000 S/N 12");
/// assert!(parse_identification("4 003 1.0 2.0").is_err());
/// ```
pub fn parse_identification(line: &str) -> Result<String, String> {
    match line.strip_prefix("8 ") {
        Some(text) if !text.trim().is_empty() => Ok(text.trim().to_string()),
        _ => Err("not a device-information reply (`8 <text>`)".into()),
    }
}

/// Parses a measurement reply `<type> <sss> <x> <y>` of the expected type (`'4'` for
/// `a`, `'2'` for `r`). Refused: another type, a status that is not three digits, a
/// number that is not finite, anything extra, and a status whose X axis is not valid.
///
/// ```
/// use polycal::instrument::elcomat::parse_measurement;
/// let r = parse_measurement("4 001 12.5 0.0", '4').unwrap();
/// assert_eq!((r.status, r.x_arcsec, r.y_arcsec), (1, 12.5, None)); // Y not valid
/// assert!(parse_measurement("4 002 12.5 0.0", '4').unwrap_err().contains("X axis not valid"));
/// ```
pub fn parse_measurement(line: &str, expected_type: char) -> Result<AcReading, String> {
    let form = format!("`{expected_type} <sss> <x> <y>`");
    let parts: Vec<&str> = line.split_whitespace().collect();
    if parts.len() != 4 {
        return Err(format!(
            "{} field(s), a measurement reply is {form}",
            parts.len()
        ));
    }
    if parts[0] != expected_type.to_string() {
        return Err(format!(
            "reply type {:?}, expected {expected_type:?} ({form})",
            parts[0]
        ));
    }
    let status_text = parts[1];
    if status_text.len() != 3 || !status_text.bytes().all(|b| b.is_ascii_digit()) {
        return Err(format!("status {status_text:?} is not three digits"));
    }
    let status: u16 = status_text
        .parse()
        .map_err(|_| format!("status {status_text:?} is not three digits"))?;
    let number = |name: &str, text: &str| match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("{name} {text:?} is not a finite number")),
    };
    let x = number("X", parts[2])?;
    let y = number("Y", parts[3])?;
    let (x_valid, y_valid) = match status % 10 {
        0 => (false, false),
        1 => (true, false),
        2 => (false, true),
        3 => (true, true),
        d => return Err(format!("status {status_text}: axis digit {d} is not 0 … 3")),
    };
    if !x_valid {
        return Err(format!(
            "X axis not valid (status {status_text}: no reflected light, or out of range)"
        ));
    }
    Ok(AcReading {
        status,
        x_arcsec: x,
        y_arcsec: y_valid.then_some(y),
    })
}

/// The ELCOMAT 3000 driver over any [`Transport`].
#[derive(Debug)]
pub struct Elcomat3000<T> {
    transport: T,
    options: QueryOptions,
    drain: Duration,
}

impl<T: Transport> Elcomat3000<T> {
    /// A driver over `transport`. On [`Autocollimator::start`] it waits 50 ms after `s`
    /// for stream lines still on their way before it clears the input
    /// ([`Elcomat3000::with_drain`] changes that).
    pub fn new(transport: T, options: QueryOptions) -> Self {
        Elcomat3000 {
            transport,
            options,
            drain: Duration::from_millis(50),
        }
    }

    /// Sets the wait between `s` and clearing the input on start.
    pub fn with_drain(mut self, drain: Duration) -> Self {
        self.drain = drain;
        self
    }

    /// The transport.
    pub fn transport(&self) -> &T {
        &self.transport
    }

    /// The transport, mutably.
    pub fn transport_mut(&mut self) -> &mut T {
        &mut self.transport
    }
}

impl<T: Transport> Autocollimator for Elcomat3000<T> {
    fn port(&self) -> &str {
        self.transport.port()
    }

    fn start(&mut self) -> Result<(), InstrumentError> {
        self.transport.send(STOP_STREAM)?;
        if !self.drain.is_zero() {
            std::thread::sleep(self.drain);
        }
        self.transport.clear_input()
    }

    fn identify(&mut self) -> Result<String, InstrumentError> {
        query(
            &mut self.transport,
            &self.options,
            IDENTIFY,
            parse_identification,
        )
        .map(|(text, _)| text)
    }

    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        query(&mut self.transport, &self.options, MEASURE, |line| {
            parse_measurement(line, '4')
        })
        .map(|(reading, _)| reading)
    }
}
