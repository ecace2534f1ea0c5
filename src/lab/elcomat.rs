//! The Möller-Wedel ELCOMAT 3000 autocollimator protocol (docs/FORMAT.md §7).
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

use super::query::{Resync, query};
use super::transport::Transport;
use super::{AcReading, Autocollimator, InstrumentError, QueryOptions, ReplyError};

/// Identification command.
pub const IDENTIFY: &str = "d\n";
/// Stop-streaming command (no reply).
pub const STOP_STREAM: &str = "s\n";
/// One absolute measurement.
pub const MEASURE: &str = "a\n";

/// How the driver brings the device back in step after a late or doubtful reply: `d`,
/// whose `8 …` reply no measurement can be mistaken for.
const RESYNC: Resync = Resync {
    command: IDENTIFY,
    is_reply: |line| parse_identification(line).is_ok(),
};

/// Parses a `d` reply, `8 <text>`, into the text.
///
/// ```
/// use polycal::lab::elcomat::parse_identification;
/// assert_eq!(parse_identification("8 ELCOMAT 3000 S/N 12").unwrap(), "ELCOMAT 3000 S/N 12");
/// assert!(parse_identification("4 003 1.0 2.0").is_err());
/// ```
///
/// # Errors
///
/// [`ReplyError::NotThisReply`] for anything but `8 ` and some text.
pub fn parse_identification(line: &str) -> Result<String, ReplyError> {
    match line.strip_prefix("8 ") {
        Some(text) if !text.trim().is_empty() => Ok(text.trim().to_string()),
        _ => Err(ReplyError::NotThisReply {
            what: "a device-information reply",
            form: "8 <text>",
        }),
    }
}

/// Parses a measurement reply `<type> <sss> <x> <y>` of the expected type (`'4'` for
/// `a`, `'2'` for `r`). Refused: another type, a status that is not three digits, a
/// number that is not finite, anything extra, and a status whose X axis is not valid.
///
/// ```
/// use polycal::lab::ReplyError;
/// use polycal::lab::elcomat::parse_measurement;
/// let r = parse_measurement("4 001 12.5 0.0", '4').unwrap();
/// assert_eq!((r.status, r.x_arcsec, r.y_arcsec), (1, 12.5, None)); // Y not valid
/// assert!(matches!(
///     parse_measurement("4 002 12.5 0.0", '4'),
///     Err(ReplyError::XNotValid { .. })
/// ));
/// ```
///
/// # Errors
///
/// The [`ReplyError`] saying what is wrong with the line.
pub fn parse_measurement(line: &str, expected_type: char) -> Result<AcReading, ReplyError> {
    let parts: Vec<&str> = line.split_whitespace().collect();
    let &[kind, status_text, x_text, y_text] = parts.as_slice() else {
        return Err(ReplyError::FieldCount {
            count: parts.len(),
            expected: expected_type,
        });
    };
    if kind != expected_type.to_string() {
        return Err(ReplyError::ReplyType {
            found: kind.to_string(),
            expected: expected_type,
        });
    }
    let bad_status = || ReplyError::Status {
        status: status_text.to_string(),
    };
    if status_text.len() != 3 || !status_text.bytes().all(|b| b.is_ascii_digit()) {
        return Err(bad_status());
    }
    let status: u16 = status_text.parse().map_err(|_| bad_status())?;
    let x = finite("X", x_text)?;
    let y = finite("Y", y_text)?;
    let (x_valid, y_valid) = match status % 10 {
        0 => (false, false),
        1 => (true, false),
        2 => (false, true),
        3 => (true, true),
        digit => {
            return Err(ReplyError::AxisDigit {
                status: status_text.to_string(),
                digit,
            });
        }
    };
    if !x_valid {
        return Err(ReplyError::XNotValid {
            status: status_text.to_string(),
        });
    }
    Ok(AcReading::new(status, x, y_valid.then_some(y)))
}

/// A finite number, or [`ReplyError::NotFinite`] naming the value.
fn finite(name: &'static str, text: &str) -> Result<f64, ReplyError> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(ReplyError::NotFinite {
            name,
            text: text.to_string(),
        }),
    }
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
            None,
            IDENTIFY,
            parse_identification,
        )
        .map(|(text, _)| text)
    }

    fn measure(&mut self) -> Result<AcReading, InstrumentError> {
        query(
            &mut self.transport,
            &self.options,
            Some(&RESYNC),
            MEASURE,
            |line| parse_measurement(line, '4'),
        )
        .map(|(reading, _)| reading)
    }
}
