//! σ: the standard deviation of one reading, the crate's one type for it.

use std::fmt;

use crate::input::limits::{Limit, READING_ARCSEC};

/// The range of σ: positive, at most a reading's largest magnitude, and not so small that
/// σ² vanishes.
const SIGMA_ARCSEC: Limit =
    Limit::new(0.0, READING_ARCSEC.max(), "″").with_smallest_nonzero(1e-100);

/// The standard deviation σ of one autocollimator reading, arcseconds: a positive, finite
/// number, checked once where it enters ([`Sigma::new`]) so that every entry point
/// (`solve`, `diagnose`, the uncertainty layer) can rely on it.
///
/// A stated σ is used for the uncertainties of an exactly determined fit (dof = 0, such as
/// the paper's bare cycle) and for `diagnose`'s χ² check; with residual degrees of freedom
/// the fit's own residual standard deviation is used.
///
/// ```
/// use polycal::measurement::{Sigma, SigmaError};
///
/// let sigma = Sigma::new(0.05)?;
/// assert_eq!(sigma.arcsec(), 0.05);
/// assert!(Sigma::new(-0.05).is_err());
/// assert!(Sigma::new(f64::NAN).is_err());
/// assert!(Sigma::new(0.0).is_err());
/// assert!(Sigma::new(1e300).is_err()); // beyond the limit of a reading, 1e6″
/// # Ok::<(), SigmaError>(())
/// ```
#[derive(Debug, Clone, Copy, PartialEq, PartialOrd)]
pub struct Sigma(f64);

/// Why a number is not a σ.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SigmaError {
    /// Zero, negative, infinite or NaN.
    #[error(
        "the standard deviation of one reading must be a positive, finite number of \
         arcseconds, got {0}"
    )]
    NotPositive(f64),
    /// Beyond the limits of a reading (docs/FORMAT.md §2.2): a σ larger than any reading
    /// may be, or so small that its square vanishes.
    #[error("the standard deviation of one reading: {0}")]
    OutOfLimits(crate::input::limits::LimitError),
    /// Text that is not a number.
    #[error("the standard deviation of one reading must be a number of arcseconds, got {0:?}")]
    NotANumber(String),
}

impl Sigma {
    /// σ in arcseconds; refused unless positive, finite and within 1e-100 … 1e6″ (the
    /// limit of a reading, docs/FORMAT.md §2.2).
    ///
    /// # Errors
    ///
    /// [`SigmaError::NotPositive`] for zero, a negative number, infinity or NaN;
    /// [`SigmaError::OutOfLimits`] beyond the limits.
    pub fn new(arcsec: f64) -> Result<Sigma, SigmaError> {
        if !(arcsec.is_finite() && arcsec > 0.0) {
            return Err(SigmaError::NotPositive(arcsec));
        }
        SIGMA_ARCSEC
            .check(arcsec, "a standard deviation of one reading")
            .map(Sigma)
            .map_err(SigmaError::OutOfLimits)
    }

    /// σ in arcseconds.
    pub fn arcsec(self) -> f64 {
        self.0
    }
}

impl fmt::Display for Sigma {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(&self.0, f)
    }
}

impl std::str::FromStr for Sigma {
    type Err = SigmaError;

    /// Parses arcseconds, e.g. `"0.05"`; refuses what [`Sigma::new`] refuses.
    fn from_str(text: &str) -> Result<Sigma, SigmaError> {
        let arcsec = text
            .trim()
            .parse::<f64>()
            .map_err(|_| SigmaError::NotANumber(text.to_string()))?;
        Sigma::new(arcsec)
    }
}
