//! The self-calibration CSV (docs/FORMAT.md §9): reading, validation, writing.
//! (Placeholder: the reader and the rules are being written.)

use super::{HeadReading, SelfcalSet};
use crate::input::Location;

/// A self-calibration file that cannot be read, or breaks a rule.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SelfcalError {
    /// A file that breaks the rules: names the file, 1-based line and 1-based column.
    #[error("{location}: {message}")]
    Invalid {
        /// Where: the file, line and column.
        location: Location,
        /// What is wrong, naming the column and quoting the offending text.
        message: String,
    },
    /// The file could not be opened, read or written.
    #[error("{file}: {source}")]
    Io {
        /// The file.
        file: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

impl SelfcalSet {
    /// Checks readings built in memory by the rules of the file; P is the largest step
    /// + 1 unless given.
    ///
    /// # Errors
    ///
    /// [`SelfcalError::Invalid`] for the first reading that breaks a rule.
    pub fn from_readings(
        readings: Vec<HeadReading>,
        positions: Option<usize>,
    ) -> Result<Self, SelfcalError> {
        let positions =
            positions.unwrap_or_else(|| readings.iter().map(|r| r.step + 1).max().unwrap_or(0));
        Ok(Self {
            positions,
            readings,
        })
    }
}
