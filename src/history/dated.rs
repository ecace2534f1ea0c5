//! A calibration as given on a command line, `FILE@DATE` (or a certificate's `FILE`,
//! dated by itself), and its file's bytes read into a [`Calibration`]: one home for
//! `polycal history` and `polycal report --history` (docs/FORMAT.md §13.2).

use std::path::PathBuf;
use std::str::FromStr;

use super::{Calibration, HistoryError};
use crate::input::FileError;
use crate::results::{certificate, read_results_from};

/// One calibration named as `FILE@DATE`, or as a certificate's `FILE` alone (dated by its
/// `dcc:endPerformanceDate` when read).
///
/// ```
/// use polycal::history::DatedPath;
/// let dated: DatedPath = "cal@2024.csv@2024-05-17".parse()?;
/// assert_eq!(dated.path.to_str(), Some("cal@2024.csv"));
/// assert_eq!(dated.date.as_deref(), Some("2024-05-17"));
/// assert!("cal.csv@2024-02-30".parse::<DatedPath>().is_err());
/// # Ok::<(), polycal::history::NotDated>(())
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub struct DatedPath {
    /// The file.
    pub path: PathBuf,
    /// The day it was calibrated, `YYYY-MM-DD`; `None`: a certificate that states it.
    pub date: Option<String>,
    /// The argument as given.
    pub text: String,
}

/// An argument that is not `FILE@DATE`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "expected FILE@DATE (a result file, `@`, the day it was calibrated, e.g. \
     cal.csv@2024-05-17), got {text:?}: {why}"
)]
#[non_exhaustive]
pub struct NotDated {
    /// The argument.
    pub text: String,
    /// What is wrong with it.
    pub why: String,
}

impl FromStr for DatedPath {
    type Err = NotDated;

    /// Parses `FILE@DATE`, split at the last `@`, the date a day `YYYY-MM-DD`; a `FILE`
    /// without `@` is taken as a certificate that states its own date (checked when read).
    fn from_str(text: &str) -> Result<DatedPath, NotDated> {
        let not = |why: &str| NotDated {
            text: text.to_string(),
            why: why.to_string(),
        };
        let Some((path, date)) = text.rsplit_once('@') else {
            if text.is_empty() {
                return Err(not("no file"));
            }
            return Ok(DatedPath {
                path: PathBuf::from(text),
                date: None,
                text: text.to_string(),
            });
        };
        if path.is_empty() {
            return Err(not("no file before @"));
        }
        if crate::clock::days_from_date(date).is_none() {
            return Err(not(&format!(
                "{date:?} is not a day YYYY-MM-DD of the calendar"
            )));
        }
        Ok(DatedPath {
            path: PathBuf::from(path),
            date: Some(date.to_string()),
            text: text.to_string(),
        })
    }
}

/// Why a dated calibration's file cannot be read.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DatedReadError {
    /// The file is not a result file or certificate (file, line and column).
    #[error(transparent)]
    File(#[from] FileError),
    /// A result file given without `@DATE`.
    #[error(
        "{text}: no @DATE, and a result file carries no date: give the calibration as \
         FILE@DATE, e.g. \
         {text}@2024-05-17 (a certificate is dated by its dcc:endPerformanceDate)"
    )]
    Undated {
        /// The argument as given.
        text: String,
    },
    /// A certificate given without `@DATE` that states no day.
    #[error("{file}: {why}; give the calibration as FILE@DATE")]
    CertificateDate {
        /// The file.
        file: String,
        /// What the certificate states.
        why: String,
    },
    /// The date refused.
    #[error("{text}: {source}")]
    Date {
        /// The argument as given.
        text: String,
        /// Why.
        source: HistoryError,
    },
}

impl DatedPath {
    /// The calibration in `bytes` (the file's, named `source` in messages): a result file
    /// (docs/FORMAT.md §3) or a DCC (§13.3), dated by its `@DATE`, else by the
    /// certificate's `dcc:endPerformanceDate` (its `dcc:beginPerformanceDate` when it has
    /// no end).
    ///
    /// # Errors
    ///
    /// [`DatedReadError`]: a file that is not a result file or certificate (file, line,
    /// column), a result file without `@DATE`, a certificate without a performance day.
    pub fn calibration(&self, bytes: &[u8], source: &str) -> Result<Calibration, DatedReadError> {
        let (file, date) = match &self.date {
            Some(date) => (read_results_from(bytes, source)?, date.clone()),
            None if certificate::looks_like_xml(bytes) => {
                let read = certificate::read_certificate(bytes, source)?;
                let stated = read
                    .end_performance_date
                    .clone()
                    .or_else(|| read.begin_performance_date.clone());
                let refuse = |why: String| DatedReadError::CertificateDate {
                    file: source.to_string(),
                    why,
                };
                match stated {
                    Some(day) if crate::clock::days_from_date(&day).is_some() => {
                        (read.results, day)
                    }
                    Some(day) => {
                        return Err(refuse(format!(
                            "the certificate's performance date {day:?} is not a day YYYY-MM-DD"
                        )));
                    }
                    None => {
                        return Err(refuse(
                            "the certificate states no performance date (dcc:endPerformanceDate)"
                                .to_string(),
                        ));
                    }
                }
            }
            None => {
                return Err(DatedReadError::Undated {
                    text: self.text.clone(),
                });
            }
        };
        Calibration::new(&date, file).map_err(|source| DatedReadError::Date {
            text: self.text.clone(),
            source,
        })
    }
}
