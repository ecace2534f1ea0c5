//! A key comparison in a report (`polycal report --kc`, docs/FORMAT.md §10.2, §12): the
//! JSON `polycal kc --format json` printed — one object, or one per line for a comparison
//! of each quantity the files share — read back through the library's own
//! [`KeyComparison`], checked for the shape the documents rely on (one entry per compared
//! quantity in every list), and the laboratory the report is for, when one is named.

use crate::kc::KeyComparison;

use super::ReportError;

/// A key comparison as a report shows it: the comparison, the laboratory the report is
/// for (when named) and the file it came from, named by its file name and SHA-256 only.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct KeyComparisonSection {
    /// The comparison, as `polycal kc --format json` printed it.
    pub comparison: KeyComparison,
    /// The laboratory the report is for; `None`: every laboratory's degrees of
    /// equivalence are shown (the pilot's Draft A).
    pub lab: Option<String>,
    /// The file's name without its directories.
    pub file_name: String,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub sha256: String,
}

impl KeyComparisonSection {
    /// The degrees of equivalence the report shows: the named laboratory's alone, or every
    /// laboratory's in the order given (the pilot's repeats are in
    /// [`crate::kc::PilotStability`]).
    pub fn shown_degrees_of_equivalence(&self) -> Vec<&crate::kc::DegreeOfEquivalence> {
        self.comparison
            .degrees_of_equivalence
            .iter()
            .filter(|d| self.lab.as_ref().is_none_or(|lab| &d.lab == lab))
            .collect()
    }

    /// The exclusion of the named laboratory, when it was left out of the reference.
    pub fn lab_exclusion(&self) -> Option<&crate::kc::Exclusion> {
        let lab = self.lab.as_ref()?;
        self.comparison.excluded.iter().find(|e| &e.lab == lab)
    }
}

/// Reads every key comparison of the bytes of `polycal kc --format json` (`name` names
/// the file in errors), one section each in the file's order: refused with serde's line
/// and column when it is not that JSON, or when a list does not hold one entry per
/// compared quantity ([`crate::kc::read_json_lines`]); a `lab` that is not one of a
/// comparison's laboratories is refused naming them.
pub(super) fn parse(
    bytes: &[u8],
    name: &str,
    sha256: &str,
    lab: Option<&str>,
) -> Result<Vec<KeyComparisonSection>, ReportError> {
    let comparisons = crate::kc::read_json_lines(bytes, name).map_err(|e| match e {
        crate::kc::KcJsonError::NotJson { location, message } => {
            ReportError::KeyComparison { location, message }
        }
        crate::kc::KcJsonError::Shape { file, problem } => {
            ReportError::KeyComparisonShape { file, problem }
        }
    })?;
    comparisons
        .into_iter()
        .map(|comparison| {
            if let Some(lab) = lab
                && !comparison.labs.iter().any(|l| l == lab)
            {
                return Err(ReportError::KeyComparisonLab {
                    file: name.to_string(),
                    lab: lab.to_string(),
                    labs: comparison.labs.join(", "),
                });
            }
            Ok(KeyComparisonSection {
                comparison,
                lab: lab.map(str::to_string),
                file_name: crate::input::document_name(name),
                sha256: sha256.to_string(),
            })
        })
        .collect()
}
