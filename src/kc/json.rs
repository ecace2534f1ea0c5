//! A key comparison read back from its JSON (`polycal kc --format json`, docs/FORMAT.md
//! §12): what `report --kc` puts in a report and `kc --link` links to. Refused with serde's
//! line and column when it is not that JSON, and when its lists do not hold one entry per
//! compared quantity.

use super::KeyComparison;
use crate::input::Location;

/// Why the bytes are not a key comparison's JSON.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum KcJsonError {
    /// Not the JSON of `polycal kc --format json`.
    #[error("{location}: {message}")]
    NotJson {
        /// Where, as serde found it.
        location: Location,
        /// What is wrong.
        message: String,
    },
    /// The JSON's lists do not have the shape every reader relies on.
    #[error("{file}: {problem}")]
    Shape {
        /// The file.
        file: String,
        /// What is wrong.
        problem: KeyComparisonShapeError,
    },
}

/// Reads a key comparison from the bytes of `polycal kc --format json` (`name` names the
/// file in errors).
///
/// # Errors
///
/// [`KcJsonError::NotJson`] with serde's line and column; [`KcJsonError::Shape`] when a
/// list does not hold one entry per compared quantity or a degree of equivalence is of
/// no laboratory of the comparison.
pub fn read_json(bytes: &[u8], name: &str) -> Result<KeyComparison, KcJsonError> {
    let comparison: KeyComparison = serde_json::from_slice(bytes).map_err(|e| {
        // serde's message without its position, which the location states
        let text = e.to_string();
        let position = format!(" at line {} column {}", e.line(), e.column());
        KcJsonError::NotJson {
            location: Location::new(name, e.line() as u64, e.column() as u64),
            message: format!(
                "not the JSON of `polycal kc --format json` (docs/FORMAT.md §12): {}",
                text.strip_suffix(&position).unwrap_or(&text)
            ),
        }
    })?;
    check_shape(&comparison).map_err(|problem| KcJsonError::Shape {
        file: name.to_string(),
        problem,
    })?;
    Ok(comparison)
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
pub(crate) fn check_shape(kc: &KeyComparison) -> Result<(), KeyComparisonShapeError> {
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
