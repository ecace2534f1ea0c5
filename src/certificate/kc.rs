//! A key comparison in a report (`polycal report --kc`, docs/FORMAT.md §10.2, §12): the
//! JSON `polycal kc --format json` printed, read back through the library's own
//! [`KeyComparison`], checked for the shape the documents rely on (one entry per compared
//! quantity in every list), and the laboratory the report is for, when one is named.

use crate::input::Location;
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

/// Reads a key comparison from the bytes of `polycal kc --format json` (`name` names the
/// file in errors): refused with serde's line and column when it is not that JSON, or
/// when a list does not hold one entry per compared quantity; a `lab` that is not one of
/// its laboratories is refused naming them.
pub(super) fn parse(
    bytes: &[u8],
    name: &str,
    sha256: String,
    lab: Option<&str>,
) -> Result<KeyComparisonSection, ReportError> {
    let refuse = |line: u64, column: u64, message: String| ReportError::KeyComparison {
        location: Location::new(name, line, column),
        message,
    };
    let comparison: KeyComparison = serde_json::from_slice(bytes).map_err(|e| {
        // serde's message without its position, which the location states
        let text = e.to_string();
        let position = format!(" at line {} column {}", e.line(), e.column());
        refuse(
            e.line() as u64,
            e.column() as u64,
            format!(
                "not the JSON of `polycal kc --format json` (docs/FORMAT.md §12): {}",
                text.strip_suffix(&position).unwrap_or(&text)
            ),
        )
    })?;
    check_shape(&comparison).map_err(|problem| ReportError::KeyComparisonShape {
        file: name.to_string(),
        problem,
    })?;
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
        sha256,
    })
}

/// Why a key comparison's JSON does not have the shape the documents rely on.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum KeyComparisonShapeError {
    /// No compared quantity.
    #[error("no compared quantity (index is empty)")]
    NoQuantity,
    /// A list that does not hold one entry per compared quantity.
    #[error("{list} has {len} entries, but the comparison has {quantities} quantities (index)")]
    ListLength {
        /// The list: `reference`, `chi2`, `d of LAB`, `pilot.mean`, …
        list: String,
        /// Its number of entries.
        len: usize,
        /// The number of compared quantities.
        quantities: usize,
    },
    /// A degree of equivalence of a laboratory that is not in the comparison.
    #[error(
        "a degree of equivalence of {lab:?}, which is not among the laboratories ({})",
        labs.join(", ")
    )]
    UnknownLab {
        /// The laboratory of the degree of equivalence.
        lab: String,
        /// The comparison's laboratories.
        labs: Vec<String>,
    },
}

/// Every list of a key comparison holds one entry per compared quantity, there is at
/// least one, and every degree of equivalence is of a laboratory of the comparison: what
/// the documents index by.
fn check_shape(kc: &KeyComparison) -> Result<(), KeyComparisonShapeError> {
    let n = kc.index.len();
    if n == 0 {
        return Err(KeyComparisonShapeError::NoQuantity);
    }
    let mut lists: Vec<(String, usize)> = vec![
        ("reference".into(), kc.reference.len()),
        ("reference_u".into(), kc.reference_u.len()),
        ("chi2".into(), kc.chi2.len()),
        ("chi2_dof".into(), kc.chi2_dof.len()),
        ("chi2_critical".into(), kc.chi2_critical.len()),
        ("consistent".into(), kc.consistent.len()),
        ("tau".into(), kc.tau.len()),
    ];
    if let Some(angles) = &kc.angle_deg {
        lists.push(("angle_deg".into(), angles.len()));
    }
    let pilot_doe = kc.pilot.iter().flat_map(|p| &p.degrees_of_equivalence);
    for d in kc.degrees_of_equivalence.iter().chain(pilot_doe) {
        lists.push((format!("d of {}", d.lab), d.d.len()));
        lists.push((format!("U of {}", d.lab), d.expanded_u.len()));
    }
    if let Some(p) = &kc.pilot {
        for (what, len) in [
            ("mean", p.mean.len()),
            ("spread", p.spread.len()),
            ("chi2", p.chi2.len()),
            ("significant", p.significant.len()),
            ("stability_u", p.stability_u.len()),
        ] {
            lists.push((format!("pilot.{what}"), len));
        }
    }
    if let Some((list, len)) = lists.into_iter().find(|(_, len)| *len != n) {
        return Err(KeyComparisonShapeError::ListLength {
            list,
            len,
            quantities: n,
        });
    }
    if let Some(d) = kc
        .degrees_of_equivalence
        .iter()
        .find(|d| !kc.labs.contains(&d.lab))
    {
        return Err(KeyComparisonShapeError::UnknownLab {
            lab: d.lab.clone(),
            labs: kc.labs.clone(),
        });
    }
    Ok(())
}
