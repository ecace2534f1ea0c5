//! Cross-talk stated from an autocollimator's calibration (docs/FORMAT.md §6): the
//! reading changes by C times the elevation reading `reading_y`, C known with standard
//! uncertainty u. The readings are corrected as reading − C·`reading_y`, and u enters the
//! budget as a [`KnownCorrection`](crate::uncertainty::calibration::KnownCorrection)
//! whose column is `reading_y` on that autocollimator's readings.
//!
//! Closure data determine only the differences of the autocollimators' cross-talk
//! coefficients; stating one autocollimator's lets the data give the others'.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use super::{MeasurementSet, Reading};
use crate::input::Location;
use crate::input::limits::READING_ARCSEC;

/// The largest |C| and the largest U accepted (dimensionless): a cross-talk of one
/// arcsecond per arcsecond is already far beyond any autocollimator. No `Limit` of
/// [`crate::input::limits`] fits a dimensionless coefficient, so this is its range.
pub const MAX_COEFFICIENT: f64 = 1.0;

/// One autocollimator's cross-talk coefficient, stated from its calibration.
///
/// Its JSON form (the `stated_cross_talk` entries of docs/FORMAT.md §5.1, §5.2) is
/// `{"ac": 1, "coefficient": 0.01, "u": 0.001}`, `u` `null` when not stated; its text
/// form ([`fmt::Display`], [`FromStr`]) is `AC:C` or `AC:C:U`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[non_exhaustive]
pub struct StatedCrossTalk {
    /// Autocollimator number (≥ 1).
    pub ac: u32,
    /// C: arcsec of reading per arcsec of `reading_y` (dimensionless), |C| ≤
    /// [`MAX_COEFFICIENT`].
    pub coefficient: f64,
    /// Standard uncertainty of C (dimensionless, 0 … [`MAX_COEFFICIENT`]), when stated.
    pub u: Option<f64>,
}

/// Why a stated cross-talk, or the correction with it, was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CrossTalkError {
    /// A stated cross-talk that cannot be read or is out of its range.
    #[error(
        "cross-talk \"{spec}\": {message} (expected AC:C or AC:C:U, e.g. 2:0 or 1:0.004:0.0005)"
    )]
    Spec {
        /// The text as given.
        spec: String,
        /// What is wrong.
        message: String,
    },
    /// An autocollimator stated twice.
    #[error("the cross-talk of autocollimator {ac} is stated twice")]
    Twice {
        /// The autocollimator.
        ac: u32,
    },
    /// An autocollimator the measurement set does not have.
    #[error("{source_name}: no autocollimator {ac} for its stated cross-talk")]
    NoSuchAutocollimator {
        /// The set's source.
        source_name: String,
        /// The autocollimator.
        ac: u32,
    },
    /// A corrected reading beyond the limits of a reading (docs/FORMAT.md §2.2).
    #[error(
        "{location}: the reading of autocollimator {ac} corrected for its stated cross-talk: {message}"
    )]
    CorrectedReading {
        /// The set's source and the reading's line (0, left out, for a reading built in
        /// memory).
        location: Location,
        /// The autocollimator.
        ac: u32,
        /// The rule it breaks, naming the value and the limits.
        message: String,
    },
    /// Readings of that autocollimator without `reading_y`: the correction cannot be made.
    #[error(
        "{source_name}: {count} reading(s) of autocollimator {ac} have no reading_y (the first at cycle {cycle}, step {step}), so its stated cross-talk cannot be corrected for"
    )]
    MissingReadingY {
        /// The set's source.
        source_name: String,
        /// The autocollimator.
        ac: u32,
        /// How many readings lack `reading_y`.
        count: usize,
        /// The first one's cycle.
        cycle: u32,
        /// The first one's step.
        step: usize,
    },
}

impl StatedCrossTalk {
    /// A stated cross-talk: autocollimator ≥ 1, |C| ≤ [`MAX_COEFFICIENT`], u (if given) a
    /// finite number within 0 … [`MAX_COEFFICIENT`].
    ///
    /// ```
    /// use polycal::measurement::cross_talk::StatedCrossTalk;
    /// let stated = StatedCrossTalk::new(2, 0.004, Some(0.0005))?;
    /// assert_eq!(stated.ac, 2);
    /// assert!(StatedCrossTalk::new(0, 0.0, None).is_err());
    /// # Ok::<(), polycal::measurement::cross_talk::CrossTalkError>(())
    /// ```
    ///
    /// # Errors
    ///
    /// [`CrossTalkError::Spec`] naming what is out of range.
    pub fn new(ac: u32, coefficient: f64, u: Option<f64>) -> Result<Self, CrossTalkError> {
        let stated = Self { ac, coefficient, u };
        let bad = |message: String| CrossTalkError::Spec {
            spec: stated.to_string(),
            message,
        };
        if ac == 0 {
            return Err(bad("autocollimator numbers start at 1".into()));
        }
        if !(coefficient.is_finite() && coefficient.abs() <= MAX_COEFFICIENT) {
            return Err(bad(format!(
                "C must be a finite number within ±{MAX_COEFFICIENT}"
            )));
        }
        if let Some(u) = u
            && !(u.is_finite() && (0.0..=MAX_COEFFICIENT).contains(&u))
        {
            return Err(bad(format!(
                "U must be a finite number within 0 … {MAX_COEFFICIENT}"
            )));
        }
        Ok(stated)
    }

    /// In words, for tables and the report: `autocollimator 1: C = 0.01, u(C) = 0.001`
    /// (without `u(C)` when not stated), the numbers as given.
    pub fn describe(&self) -> String {
        let mut text = format!("autocollimator {}: C = {}", self.ac, self.coefficient);
        if let Some(u) = self.u {
            text.push_str(&format!(", u(C) = {u}"));
        }
        text
    }

    /// The column of a [`KnownCorrection`](crate::uncertainty::calibration::KnownCorrection)
    /// for this cross-talk on `set`: `reading_y` on its autocollimator's readings, 0
    /// elsewhere (when the true coefficient is C + e, a corrected reading keeps
    /// e·`reading_y`).
    pub fn column(&self, set: &MeasurementSet) -> Vec<f64> {
        set.readings
            .iter()
            .map(|r| {
                if r.ac == self.ac {
                    r.reading_y_arcsec.unwrap_or(0.0)
                } else {
                    0.0
                }
            })
            .collect()
    }
}

impl fmt::Display for StatedCrossTalk {
    /// `AC:C` or `AC:C:U`, the numbers in the shortest form that reads back the same.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.ac, self.coefficient)?;
        match self.u {
            Some(u) => write!(f, ":{u}"),
            None => Ok(()),
        }
    }
}

impl FromStr for StatedCrossTalk {
    type Err = CrossTalkError;

    /// Parses `AC:C` or `AC:C:U`, e.g. `2:0` or `1:0.004:0.0005`.
    fn from_str(s: &str) -> Result<Self, CrossTalkError> {
        let bad = |message: String| CrossTalkError::Spec {
            spec: s.to_string(),
            message,
        };
        let parts: Vec<&str> = s.split(':').map(str::trim).collect();
        if !(2..=3).contains(&parts.len()) {
            return Err(bad(format!(
                "{} part(s) separated by ':', want 2 or 3",
                parts.len()
            )));
        }
        let ac = parts[0]
            .parse::<u32>()
            .map_err(|_| bad(format!("AC \"{}\" is not a whole number ≥ 1", parts[0])))?;
        let number = |name: &str, text: &str| {
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("{name} \"{text}\" is not a finite number")))
        };
        let coefficient = number("C", parts[1])?;
        let u = parts.get(2).map(|t| number("U", t)).transpose()?;
        Self::new(ac, coefficient, u).map_err(|e| match e {
            CrossTalkError::Spec { message, .. } => bad(message),
            other => other,
        })
    }
}

/// Refuses an autocollimator stated twice: each has one coefficient.
///
/// # Errors
///
/// [`CrossTalkError::Twice`] naming the first autocollimator stated again.
pub fn check_distinct(stated: &[StatedCrossTalk]) -> Result<(), CrossTalkError> {
    match stated
        .iter()
        .enumerate()
        .find(|(k, s)| stated[..*k].iter().any(|t| t.ac == s.ac))
    {
        Some((_, s)) => Err(CrossTalkError::Twice { ac: s.ac }),
        None => Ok(()),
    }
}

/// The set with every stated cross-talk corrected for: each reading of autocollimator A
/// becomes reading − C_A·`reading_y`; the readings of other autocollimators are kept as
/// they are.
///
/// ```
/// use polycal::measurement::cross_talk::{StatedCrossTalk, correct_cross_talk};
/// use polycal::simulate::{ElevationModel, SimulationConfig, simulate};
///
/// let config = SimulationConfig { elevation: Some(ElevationModel::default()), ..SimulationConfig::default() };
/// let (set, _) = simulate(&config)?;
/// let corrected = correct_cross_talk(&set, &[StatedCrossTalk::new(2, 0.01, None)?])?;
/// let (r, c) = (&set.readings[1], &corrected.readings[1]);
/// assert_eq!(r.ac, 2);
/// assert_eq!(c.reading_arcsec, r.reading_arcsec - 0.01 * r.reading_y_arcsec.unwrap());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Errors
///
/// [`CrossTalkError`]: an autocollimator stated twice or not in the set, readings of it
/// without `reading_y` (how many, and the first one's cycle and step), or a corrected
/// reading beyond the limits of a reading (docs/FORMAT.md §2.2).
pub fn correct_cross_talk(
    set: &MeasurementSet,
    stated: &[StatedCrossTalk],
) -> Result<MeasurementSet, CrossTalkError> {
    check_distinct(stated)?;
    for s in stated {
        if !set.readings.iter().any(|r| r.ac == s.ac) {
            return Err(CrossTalkError::NoSuchAutocollimator {
                source_name: set.source.clone(),
                ac: s.ac,
            });
        }
        let missing: Vec<&Reading> = set
            .readings
            .iter()
            .filter(|r| r.ac == s.ac && r.reading_y_arcsec.is_none())
            .collect();
        if let Some(first) = missing.first() {
            return Err(CrossTalkError::MissingReadingY {
                source_name: set.source.clone(),
                ac: s.ac,
                count: missing.len(),
                cycle: first.cycle,
                step: first.step,
            });
        }
    }
    let mut corrected = set.clone();
    for r in &mut corrected.readings {
        if let Some(s) = stated.iter().find(|s| s.ac == r.ac)
            && let Some(y) = r.reading_y_arcsec
        {
            let value = r.reading_arcsec - s.coefficient * y;
            r.reading_arcsec = READING_ARCSEC
                .check(value, "a reading")
                .map_err(|message| CrossTalkError::CorrectedReading {
                    location: Location::new(set.source.clone(), r.line, 0),
                    ac: r.ac,
                    message: message.to_string(),
                })?;
        }
    }
    Ok(corrected)
}
