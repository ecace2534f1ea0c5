//! What a number read from a file may be: the documented range of every numeric column
//! and value (docs/FORMAT.md §2.2, "Limits").
//!
//! A number can be finite and still absurd: a reading of 1e300″ parses, but its square
//! overflows and every result after it is `inf`. Every reader of the crate therefore
//! refuses a number outside the range of its kind, at its file, line and column, and the
//! same check guards values built in memory. The ranges are far wider than any instrument
//! reads (an autocollimator reads within a few thousand arcseconds), and narrow enough that
//! no sum, square or product the evaluations form can overflow.

use std::fmt;

/// A closed range a number must lie in, with its unit.
///
/// ```
/// use polycal::input::limits::READING_ARCSEC;
///
/// assert!(READING_ARCSEC.contains(-4000.0));
/// assert!(!READING_ARCSEC.contains(1e300));
/// assert!(!READING_ARCSEC.contains(f64::NAN));
/// assert_eq!(READING_ARCSEC.to_string(), "−1e6 … 1e6″");
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limit {
    min: f64,
    max: f64,
    /// The smallest magnitude a number other than zero may have (0 for none): squares
    /// of smaller numbers lose their precision or vanish.
    smallest_nonzero: f64,
    unit: &'static str,
}

impl Limit {
    /// The range `min ..= max` in `unit` (written after the numbers, e.g. `″`, ` s`).
    pub const fn new(min: f64, max: f64, unit: &'static str) -> Limit {
        Limit {
            min,
            max,
            smallest_nonzero: 0.0,
            unit,
        }
    }

    /// The same range with no magnitude between 0 and `smallest` (exclusive) allowed.
    pub const fn with_smallest_nonzero(mut self, smallest: f64) -> Limit {
        self.smallest_nonzero = smallest;
        self
    }

    /// The smallest value allowed.
    pub const fn min(&self) -> f64 {
        self.min
    }

    /// The largest value allowed.
    pub const fn max(&self) -> f64 {
        self.max
    }

    /// Whether `x` is finite and within the range.
    pub fn contains(&self, x: f64) -> bool {
        x.is_finite()
            && x >= self.min
            && x <= self.max
            && (x == 0.0 || x.abs() >= self.smallest_nonzero)
    }

    /// `Ok(x)` when [`Limit::contains`] it, otherwise the rule it breaks, e.g.
    /// `1e300 is beyond the limits of a reading, −1e6 … 1e6″ (docs/FORMAT.md §2.2)`.
    ///
    /// # Errors
    ///
    /// [`LimitError`] naming `what` (e.g. "a reading"), the value and the range; the
    /// caller adds where the number stands (a reader: file, line and column).
    pub fn check(&self, x: f64, what: &str) -> Result<f64, LimitError> {
        if self.contains(x) {
            Ok(x)
        } else if x.is_finite() {
            self.check_shown(x, &show(x), what)
        } else {
            self.check_shown(x, &x.to_string(), what)
        }
    }

    /// As [`Limit::check`], with the value shown as `shown` (a reader shows the text as
    /// the file has it, e.g. `"-1000000.5"`).
    ///
    /// # Errors
    ///
    /// [`LimitError`] naming `shown`, `what` and the range.
    pub fn check_shown(&self, x: f64, shown: &str, what: &str) -> Result<f64, LimitError> {
        if self.contains(x) {
            return Ok(x);
        }
        if !x.is_finite() {
            return Err(LimitError::NotFinite {
                shown: shown.to_string(),
            });
        }
        if x != 0.0 && x.abs() < self.smallest_nonzero {
            return Err(LimitError::TooSmall {
                shown: shown.to_string(),
                what: what.to_string(),
                smallest: self.smallest_nonzero,
                unit: self.unit,
            });
        }
        Err(LimitError::Beyond {
            shown: shown.to_string(),
            what: what.to_string(),
            limit: *self,
        })
    }
}

/// Why a number was refused by its [`Limit`] (docs/FORMAT.md §2.2). Displayed as the rule
/// it breaks; the caller puts it where the number stands (a reader's file, line and
/// column, or a result's quantity and index).
///
/// ```
/// use polycal::input::limits::{LimitError, READING_ARCSEC};
///
/// let refused = READING_ARCSEC.check(1e300, "a reading").unwrap_err();
/// assert!(matches!(refused, LimitError::Beyond { .. }));
/// assert_eq!(
///     refused.to_string(),
///     "1e300 is beyond the limits of a reading, −1e6 … 1e6″ (docs/FORMAT.md §2.2)"
/// );
/// ```
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LimitError {
    /// Not a finite number (NaN or ±∞).
    #[error("{shown} is not a finite number")]
    NotFinite {
        /// The value as shown (a reader: its text as the file has it).
        shown: String,
    },
    /// A magnitude other than 0 below the smallest the kind allows.
    #[error(
        "{shown} is too small for {what}: a magnitude other than 0 must be at least {smallest:e}{unit} (docs/FORMAT.md §2.2)"
    )]
    TooSmall {
        /// The value as shown.
        shown: String,
        /// What the number is, e.g. "a reading".
        what: String,
        /// The smallest magnitude allowed.
        smallest: f64,
        /// Its unit.
        unit: &'static str,
    },
    /// Outside the range of its kind.
    #[error("{shown} is beyond the limits of {what}, {limit} (docs/FORMAT.md §2.2)")]
    Beyond {
        /// The value as shown.
        shown: String,
        /// What the number is, e.g. "a reading".
        what: String,
        /// The range it breaks.
        limit: Limit,
    },
}

impl fmt::Display for Limit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} … {}{}", show(self.min), show(self.max), self.unit)
    }
}

/// A number as people write it: plain up to a million, `1e6` beyond, `−` for minus.
pub(crate) fn show(x: f64) -> String {
    let text = if x != 0.0 && (x.abs() >= 1e6 || x.abs() < 1e-4) {
        format!("{x:e}")
    } else {
        format!("{x}")
    };
    match text.strip_prefix('-') {
        Some(magnitude) => format!("−{magnitude}"),
        None => text,
    }
}

/// `x` with `digits` significant digits, in fixed notation between 10⁻⁴ and 10⁶.
pub(crate) fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return format!("{x}");
    }
    if x == 0.0 {
        return "0".to_string();
    }
    let magnitude = x.abs().log10().floor() as i32;
    if !(-4..6).contains(&magnitude) {
        return format!("{:.*e}", digits.saturating_sub(1), x);
    }
    let decimals = (digits as i32 - 1 - magnitude).max(0) as usize;
    format!("{x:.decimals$}")
}

/// An autocollimator reading (`reading`, `reading_y`), arcseconds: |x| ≤ 10⁶″ (about
/// 278°; an autocollimator reads within a few thousand arcseconds). Also a self-calibration
/// head's reading and the angles of a truth file.
pub const READING_ARCSEC: Limit = Limit::new(-1e6, 1e6, "″");

/// A value, U or u of a result file, arcseconds: |x| ≤ 10¹²″. Far wider than a reading
/// (a face deviation sums up to N pitch deviations), so that the results of any file of
/// valid readings are written and read back.
pub const RESULT_ARCSEC: Limit = Limit::new(-1e12, 1e12, "″");

/// A coverage factor `k` of a result file: 0.1 … 10⁶ (Student's t for one degree of
/// freedom at p = 0.9999 is 3183).
pub const COVERAGE_FACTOR: Limit = Limit::new(0.1, 1e6, "");

/// A coverage probability `p` (a budget's, a Monte Carlo's): 0.5 … 0.9999. Beyond it
/// the coverage factor is meaningless (p → 0) or unbounded (p → 1: Student's t for one
/// degree of freedom at 0.9999 is 6366).
pub const COVERAGE_PROBABILITY: Limit = Limit::new(0.5, 0.9999, "");

/// A `time` column, seconds since the run started: |t| ≤ 10⁹ s (about 32 years).
pub const TIME_SECONDS: Limit = Limit::new(-1e9, 1e9, " s");

/// A `temperature` column, degrees Celsius: −273.15 … 1000 °C.
pub const TEMPERATURE_CELSIUS: Limit = Limit::new(-273.15, 1000.0, " °C");

/// An `encoder` column (the position a table reported), degrees: |x| ≤ 10⁶°.
pub const ENCODER_DEGREES: Limit = Limit::new(-1e6, 1e6, "°");

/// A number of an uncertainty budget (a width, an uncertainty, a sensitivity, a scale,
/// in the budget's own unit): 0, or a magnitude 1e-100 … 1e100. A budget may be in any
/// unit (the GUM's example H.1 is in nanometres with sensitivities of 5·10⁶), so the
/// range is wide; its squares and their sums stay finite and exact to the last digits.
pub const BUDGET_VALUE: Limit = Limit::new(-1e100, 1e100, "").with_smallest_nonzero(1e-100);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_edges_are_inside_and_the_next_numbers_outside() {
        assert!(READING_ARCSEC.contains(1e6) && READING_ARCSEC.contains(-1e6));
        assert!(!READING_ARCSEC.contains(1e6 + 1e-9) && !READING_ARCSEC.contains(f64::INFINITY));
        assert!(TEMPERATURE_CELSIUS.contains(-273.15) && !TEMPERATURE_CELSIUS.contains(-273.16));
        assert!(BUDGET_VALUE.contains(0.0) && BUDGET_VALUE.contains(-0.0));
        assert!(BUDGET_VALUE.contains(1e-100) && !BUDGET_VALUE.contains(1e-101));
        assert!(BUDGET_VALUE.contains(-1e100) && !BUDGET_VALUE.contains(1e101));
        assert!(COVERAGE_FACTOR.contains(2.0) && !COVERAGE_FACTOR.contains(0.0));
    }

    #[test]
    fn the_message_names_the_value_the_kind_and_the_range() {
        assert_eq!(
            READING_ARCSEC
                .check(1e300, "a reading")
                .unwrap_err()
                .to_string(),
            "1e300 is beyond the limits of a reading, −1e6 … 1e6″ (docs/FORMAT.md §2.2)"
        );
        assert_eq!(
            TEMPERATURE_CELSIUS
                .check(-300.0, "a temperature")
                .unwrap_err()
                .to_string(),
            "−300 is beyond the limits of a temperature, −273.15 … 1000 °C (docs/FORMAT.md §2.2)"
        );
        assert_eq!(
            BUDGET_VALUE.check(1e-200, "u").unwrap_err().to_string(),
            "1e-200 is too small for u: a magnitude other than 0 must be at least 1e-100 \
             (docs/FORMAT.md §2.2)"
        );
        assert_eq!(
            READING_ARCSEC
                .check(f64::NAN, "a reading")
                .unwrap_err()
                .to_string(),
            "NaN is not a finite number"
        );
        assert_eq!(READING_ARCSEC.check(-12.5, "a reading"), Ok(-12.5));
    }
}
