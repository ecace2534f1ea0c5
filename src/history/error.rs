//! Why a standard's history cannot be evaluated.

use crate::kc::KcError;
use crate::results::Quantity;

/// Why a standard's history cannot be evaluated: every refusal names the file (and the
/// line and column of the row) or the date at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HistoryError {
    /// A date that is not a day of the calendar `YYYY-MM-DD`.
    #[error("{of}: the date {text:?} is not a day YYYY-MM-DD of the calendar (ISO 8601)")]
    Date {
        /// The text given.
        text: String,
        /// What it dates (a file, or the prediction).
        of: String,
    },
    /// Fewer than two calibrations.
    #[error("a standard's history needs at least 2 calibrations, {0} given")]
    TooFewCalibrations(usize),
    /// One file given for two calibrations.
    #[error("{file} is given twice (dated {first} and {second}): one result is one calibration")]
    FileTwice {
        /// The file.
        file: String,
        /// The first date given with it.
        first: String,
        /// The second.
        second: String,
    },
    /// Every calibration on one day: no drift can be estimated.
    #[error(
        "every calibration is dated {0}: a drift needs calibrations on at least 2 different days"
    )]
    NoTimeSpan(String),
    /// A quantity a history does not follow.
    #[error(
        "a standard's history follows pitch_deviation, face_deviation or encoder_error, not {0} \
         (setup errors belong to a mounting, not to the standard)"
    )]
    Quantity(Quantity),
    /// A calibration without rows of the quantity.
    #[error("{file} has no {quantity} rows")]
    NoRows {
        /// The file.
        file: String,
        /// The quantity.
        quantity: Quantity,
    },
    /// A row without a standard uncertainty.
    #[error(
        "{location}: {quantity} {index} has no standard uncertainty: a standard's history \
         needs u, or U with its k, on every row (columns u, U, k)"
    )]
    MissingUncertainty {
        /// `file:line:column` where it is missing.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
    },
    /// A row whose uncertainty is not positive, or too small to be a measured one.
    #[error("{location}: {quantity} {index} has {column} = {value:e}: {why}")]
    BadUncertainty {
        /// `file:line:column` of the uncertainty.
        location: String,
        /// The quantity.
        quantity: Quantity,
        /// Its index.
        index: u32,
        /// `U` or `u`.
        column: &'static str,
        /// The value.
        value: f64,
        /// Why it is refused.
        why: String,
    },
    /// Encoder positions that are not the same in every calibration.
    #[error(
        "{file}: its encoder error positions are not those of the other calibrations ({detail}): \
         every calibration must carry the same positions"
    )]
    PositionsDiffer {
        /// The first file whose positions differ.
        file: String,
        /// Which positions differ.
        detail: String,
    },
    /// Results that cannot be lined up face by face (another number of faces, a face
    /// missing or given twice), in the words of the key comparison's line-up.
    #[error(transparent)]
    LineUp(KcError),
    /// Fewer than two positions.
    #[error("{0} position(s): a standard's history follows vectors of at least 2 positions")]
    TooFewPositions(usize),
    /// More positions than the dense fit takes.
    #[error(
        "{0} positions: a standard's history fits at most {max} (its normal matrix is dense)",
        max = super::MAX_POSITIONS
    )]
    TooManyPositions(usize),
    /// A fit that cannot be computed (uncertainties spanning too many orders of magnitude).
    #[error(
        "the drift cannot be computed from these calibrations (a normal matrix that is not \
         positive definite: uncertainties spanning too many orders of magnitude?)"
    )]
    NotComputable,
}

impl HistoryError {
    /// A refusal of the key comparison's line-up, in the history's words where they
    /// differ.
    pub(crate) fn from_line_up(error: KcError) -> HistoryError {
        match error {
            KcError::NoRows { file, quantity, .. } => HistoryError::NoRows { file, quantity },
            KcError::MissingUncertainty {
                location,
                quantity,
                index,
            } => HistoryError::MissingUncertainty {
                location,
                quantity,
                index,
            },
            KcError::NonPositiveUncertainty {
                location,
                quantity,
                index,
                column,
                value,
            } => HistoryError::BadUncertainty {
                location,
                quantity,
                index,
                column,
                value,
                why: "an uncertainty must be positive".to_string(),
            },
            KcError::UncertaintyTooSmall {
                location,
                quantity,
                index,
                value,
                minimum,
            } => HistoryError::BadUncertainty {
                location,
                quantity,
                index,
                column: "u",
                value,
                why: format!(
                    "below {minimum:e}″, an angle's uncertainty that small is not a measured \
                     one (a unit mistake?)"
                ),
            },
            other => HistoryError::LineUp(other),
        }
    }
}
