//! Why two results cannot be compared (docs/FORMAT.md §5.4): every refusal of
//! [`super::compare`], named by file and line where there is one.

use crate::results::{ANGLE_TOLERANCE_DEG, Quantity};

/// Why two results cannot be compared.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum CompareError {
    /// A row in the verdict has `U` but no standard uncertainty: neither `u` nor a coverage
    /// factor `k` (the vector's test needs u = U/k).
    #[error(
        "{location}: {quantity} {index} has U but no standard uncertainty (neither u nor k): the \
         verdict's vector test needs u, or U with its coverage factor k (columns u, k)"
    )]
    NoStandardU {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// The difference of a row in the vector's test has no variance (or one beyond the
    /// range of numbers beside the family's largest u).
    #[error(
        "{quantity} {index}: the difference has no variance for the vector test \
         (u_a = {u_a}, u_b = {u_b}, r = {r}): the test would divide by zero"
    )]
    NoVariance {
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// Standard uncertainty in the first result, arcseconds.
        u_a: f64,
        /// Standard uncertainty in the second result, arcseconds.
        u_b: f64,
        /// The correlation coefficient.
        r: f64,
    },
    /// The vector's χ² of a family is beyond the range of numbers: its differences are more
    /// than about 1e150 times their standard uncertainties.
    #[error(
        "the {quantity} differences are more than about 1e150 times their standard \
         uncertainties: the vector's χ² is beyond the range of numbers"
    )]
    Chi2OutOfRange {
        /// The family.
        quantity: Quantity,
    },
    /// No family can be tested as a vector: fewer than 2 pitch deviations and fewer than 2
    /// encoder errors in common (and no setup errors counted).
    #[error(
        "{a} and {b} have nothing to test as one vector: the verdict needs 2 or more pitch \
         deviations or encoder errors in common (face deviations are the pitch deviations \
         accumulated and do not enter it; setup errors enter only when counted)"
    )]
    NoVector {
        /// First label.
        a: String,
        /// Second label.
        b: String,
    },
    /// A row has no expanded uncertainty.
    #[error(
        "{location}: {quantity} {index} has no expanded uncertainty U: compare needs U for \
         every row (column U)"
    )]
    MissingU {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// A `(quantity, index)` appears twice in one result.
    #[error("{location}: {quantity} {index} appears twice")]
    Duplicate {
        /// `file:line`, or the label and row number.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// The denominator of En is zero.
    #[error(
        "{quantity} {index}: En is undefined, U_a² + U_b² − 2·r·U_a·U_b = {denominator} \
         (U_a = {expanded_u_a}, U_b = {expanded_u_b}, r = {r})"
    )]
    Undefined {
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// `U_a² + U_b² − 2·r·U_a·U_b`.
        denominator: f64,
        /// `U_a`.
        expanded_u_a: f64,
        /// `U_b`.
        expanded_u_b: f64,
        /// `r`.
        r: f64,
    },
    /// No quantity is in both results.
    #[error("{a} and {b} have no (quantity, index) in common: nothing to compare")]
    NothingInCommon {
        /// First label.
        a: String,
        /// Second label.
        b: String,
    },
    /// The correlation coefficient is not in [−1, 1].
    #[error(
        "the correlation coefficient must be between -1 and 1, got {}",
        crate::input::limits::show(*.0)
    )]
    Correlation(f64),
    /// The rows in common are setup errors only, and they are left out of the verdict:
    /// there is nothing to judge.
    #[error(
        "{a} and {b} have only setup errors in common, and setup errors are left out of the \
         verdict (they depend on the mounting): nothing to judge"
    )]
    OnlySetupInCommon {
        /// First label.
        a: String,
        /// Second label.
        b: String,
    },
    /// A row breaks the angle rules of a result (docs/FORMAT.md §3.2): an angle outside
    /// 0 ≤ angle < 360 or on a row that is not an encoder error, encoder errors with and
    /// without angles in one result, two at one position. (Only rows given as slices can;
    /// a result file that does is refused when read.)
    #[error("{location}: {reason}")]
    Angle {
        /// The label and row number.
        location: String,
        /// What is wrong.
        reason: String,
    },
    /// An encoder error is within the matching tolerance of two encoder errors of the
    /// other result, so matching by angle would have to guess.
    #[error(
        "{label}: encoder_error {index} at {angle_deg}° is within {tolerance:e}° of two encoder \
         errors of {other}, {first} and {second}: matching by angle would be a guess",
        tolerance = ANGLE_TOLERANCE_DEG
    )]
    AmbiguousAngle {
        /// The result of the encoder error.
        label: String,
        /// Its index.
        index: u32,
        /// Its angle, degrees.
        angle_deg: f64,
        /// The other result.
        other: String,
        /// The smaller index of two encoder errors of the other result near it.
        first: u32,
        /// The larger.
        second: u32,
    },
}
