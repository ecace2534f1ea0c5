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
    let comparison: KeyComparison =
        serde_json::from_slice(bytes).map_err(|e| not_json(name, &e))?;
    check_shape(&comparison).map_err(|problem| KcJsonError::Shape {
        file: name.to_string(),
        problem,
    })?;
    Ok(comparison)
}

/// serde's error as [`KcJsonError::NotJson`]: its line and column in the whole file.
fn not_json(name: &str, e: &serde_json::Error) -> KcJsonError {
    // serde's message without its position, which the location states
    let text = e.to_string();
    let position = format!(" at line {} column {}", e.line(), e.column());
    // (serde's end of file is column 0 of the line after: its first column)
    KcJsonError::NotJson {
        location: Location::new(name, e.line().max(1) as u64, e.column().max(1) as u64),
        message: format!(
            "not the JSON of `polycal kc --format json` (docs/FORMAT.md §12): {}",
            text.strip_suffix(&position).unwrap_or(&text)
        ),
    }
}

/// Reads every key comparison of the bytes of `polycal kc --format json`: one object, or
/// one per line (JSON Lines, a comparison of each quantity the files share), in the
/// file's order (`name` names the file in errors). A file of one object reads as
/// [`read_json`] reads it.
///
/// ```
/// use polycal::kc::read_json_lines;
/// assert!(read_json_lines(b"", "kc.json").is_err());
/// assert!(read_json_lines(b"{}\n", "kc.json").is_err());
/// ```
///
/// # Errors
///
/// As [`read_json`], each at the file's line and column of the object concerned (a
/// list's shape at the `file:line:column` where its object begins when the file holds
/// several); [`KcJsonError::NotJson`] for a file without an object, and for a second
/// comparison of one quantity, at the line of the second.
pub fn read_json_lines(bytes: &[u8], name: &str) -> Result<Vec<KeyComparison>, KcJsonError> {
    let mut comparisons: Vec<(KeyComparison, Location)> = Vec::new();
    let mut stream = serde_json::Deserializer::from_slice(bytes).into_iter::<KeyComparison>();
    let mut end = 0;
    while let Some(next) = stream.next() {
        let start = end
            + bytes[end..]
                .iter()
                .take_while(|b| b.is_ascii_whitespace())
                .count();
        let line_start = bytes[..start]
            .iter()
            .rposition(|&b| b == b'\n')
            .map_or(0, |i| i + 1);
        let line = 1 + bytes[..start].iter().filter(|&&b| b == b'\n').count();
        let at = Location::new(name, line as u64, (start - line_start + 1) as u64);
        let comparison = next.map_err(|e| match e.is_eof() {
            // cut short: at the object that is not ended
            true => KcJsonError::NotJson {
                location: at.clone(),
                message: "not the JSON of `polycal kc --format json` (docs/FORMAT.md §12): the \
                          object that begins here ends with the file, unfinished"
                    .to_string(),
            },
            false => not_json(name, &e),
        })?;
        end = stream.byte_offset();
        if let Some((_, first)) = comparisons
            .iter()
            .find(|(c, _)| c.quantity == comparison.quantity)
        {
            return Err(KcJsonError::NotJson {
                location: at,
                message: format!(
                    "a second comparison of {} (the first at line {}): `polycal kc --format \
                     json` writes one comparison per quantity",
                    comparison.quantity,
                    first.line()
                ),
            });
        }
        comparisons.push((comparison, at));
    }
    if comparisons.is_empty() {
        // no object: read_json's refusal (serde's end of file)
        return read_json(bytes, name).map(|c| vec![c]);
    }
    let several = comparisons.len() > 1;
    comparisons
        .into_iter()
        .map(|(comparison, at)| {
            check_shape(&comparison).map_err(|problem| KcJsonError::Shape {
                file: if several {
                    at.to_string()
                } else {
                    name.to_string()
                },
                problem,
            })?;
            Ok(comparison)
        })
        .collect()
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
    /// A number `null` (not given) where the number it goes with is given: a U beside a
    /// d, a u_ref beside a reference value.
    #[error(
        "{list} is null at position {position} where {beside} is given: a value without its \
         uncertainty (or one without its value)"
    )]
    NotGivenBeside {
        /// The list with the null.
        list: String,
        /// The position, from 1.
        position: usize,
        /// The list whose number is given there.
        beside: String,
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
    if let Some(nominal) = &kc.nominal_deg {
        lists.push(("nominal_deg".into(), nominal.len()));
    }
    let pilot_doe = kc.pilot.iter().flat_map(|p| &p.degrees_of_equivalence);
    for d in kc.degrees_of_equivalence.iter().chain(pilot_doe.clone()) {
        lists.push((format!("d of {}", d.lab), d.d.len()));
        lists.push((format!("U of {}", d.lab), d.expanded_u.len()));
        for (what, list) in [
            ("k", &d.k),
            ("d_linked", &d.d_linked),
            ("U_linked", &d.expanded_u_linked),
        ] {
            if let Some(list) = list {
                lists.push((format!("{what} of {}", d.lab), list.len()));
            }
        }
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
    // a value and its uncertainty are given together or not at all
    let mut pairs: Vec<(String, &[f64], String, &[f64])> = vec![(
        "reference".into(),
        &kc.reference,
        "reference_u".into(),
        &kc.reference_u,
    )];
    for d in kc.degrees_of_equivalence.iter().chain(pilot_doe) {
        pairs.push((
            format!("d of {}", d.lab),
            &d.d,
            format!("U of {}", d.lab),
            &d.expanded_u,
        ));
        if let (Some(v), Some(u)) = (&d.d_linked, &d.expanded_u_linked) {
            pairs.push((
                format!("d_linked of {}", d.lab),
                v,
                format!("U_linked of {}", d.lab),
                u,
            ));
        }
    }
    for (value_list, values, u_list, us) in pairs {
        if let Some(k) = (0..n).find(|&k| values[k].is_finite() != us[k].is_finite()) {
            let (list, beside) = if values[k].is_finite() {
                (u_list, value_list)
            } else {
                (value_list, u_list)
            };
            return Err(KeyComparisonShapeError::NotGivenBeside {
                list,
                position: k + 1,
                beside,
            });
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kc::{KcOptions, LabResult, evaluate};
    use crate::results::{Quantity, ResultRow};

    /// Two laboratories' comparisons of their pitch deviations and their encoder errors,
    /// and the JSON Lines `polycal kc` writes of them.
    fn two_lines() -> (Vec<KeyComparison>, String) {
        let lab = |name: &str, shift: f64| {
            let mut rows = Vec::new();
            for (i, v) in [0.1, -0.05, -0.05].iter().enumerate() {
                let i = i as u32;
                rows.push(ResultRow::new(Quantity::PitchDeviation, i + 1, v + shift).with_u(0.1));
                rows.push(ResultRow::new(Quantity::EncoderError, i, v - shift).with_u(0.1));
            }
            LabResult::from_rows(name, rows)
        };
        let labs = [lab("A", 0.0), lab("B", 0.01)];
        let comparisons: Vec<KeyComparison> = [Quantity::PitchDeviation, Quantity::EncoderError]
            .into_iter()
            .map(|q| evaluate(&labs, &[], &KcOptions::new().with_quantity(q)).unwrap())
            .collect();
        let mut text = Vec::new();
        for kc in &comparisons {
            crate::output::write_json(&mut text, kc).unwrap();
        }
        (comparisons, String::from_utf8(text).unwrap())
    }

    #[test]
    fn every_line_read_back_in_order() {
        let (comparisons, text) = two_lines();
        assert_eq!(
            read_json_lines(text.as_bytes(), "kc.json").unwrap(),
            comparisons
        );
        // blank lines and a pretty-printed object read too
        let (first, second) = text.split_once('\n').unwrap();
        let value: serde_json::Value = serde_json::from_str(first).unwrap();
        let pretty = serde_json::to_string_pretty(&value).unwrap();
        let spaced = format!("\n{pretty}\n\n{second}");
        assert_eq!(
            read_json_lines(spaced.as_bytes(), "kc.json").unwrap(),
            comparisons
        );
        // one object: as read_json reads it
        assert_eq!(
            read_json_lines(first.as_bytes(), "kc.json").unwrap(),
            [read_json(first.as_bytes(), "kc.json").unwrap()]
        );
    }

    #[test]
    fn refusals_at_the_line_concerned() {
        let (_, text) = two_lines();
        let first = text.lines().next().unwrap();
        let broken = format!("{first}\n{{\"quantity\": oops}}\n");
        let e = read_json_lines(broken.as_bytes(), "kc.json").unwrap_err();
        let KcJsonError::NotJson { location, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!((location.line(), location.column()), (2, 14), "{e}");
        let twice = format!("{first}\n  {first}\n");
        let e = read_json_lines(twice.as_bytes(), "kc.json").unwrap_err();
        assert!(
            e.to_string().starts_with(
                "kc.json:2:3: a second comparison of pitch_deviation (the first at line 1)"
            ),
            "{e}"
        );
        // a list one short in the second object: its line named
        let second = text.lines().nth(1).unwrap();
        let mut value: serde_json::Value = serde_json::from_str(second).unwrap();
        value["tau"].as_array_mut().unwrap().pop();
        let short = format!("{first}\n{value}\n");
        let e = read_json_lines(short.as_bytes(), "kc.json").unwrap_err();
        assert!(
            e.to_string().starts_with("kc.json:2:1: tau has 2 entries"),
            "{e}"
        );
        // a U null beside a given d, a reference given without its u: refused, named
        let mut value: serde_json::Value = serde_json::from_str(second).unwrap();
        value["degrees_of_equivalence"][1]["U"][2] = serde_json::Value::Null;
        let e = read_json_lines(format!("{first}\n{value}\n").as_bytes(), "kc.json").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("kc.json:2:1: U of B is null at position 3 where d of B is given"),
            "{e}"
        );
        let mut value: serde_json::Value = serde_json::from_str(second).unwrap();
        value["reference_u"][0] = serde_json::Value::Null;
        let e = read_json_lines(format!("{first}\n{value}\n").as_bytes(), "kc.json").unwrap_err();
        assert!(
            e.to_string().starts_with(
                "kc.json:2:1: reference_u is null at position 1 where reference is given"
            ),
            "{e}"
        );
        // the second object cut short: at the line and column where it begins
        let cut = format!("{first}\n  {}\n", &second[..second.len() / 2]);
        let e = read_json_lines(cut.as_bytes(), "kc.json").unwrap_err();
        assert!(
            e.to_string().starts_with("kc.json:2:3: not the JSON")
                && e.to_string().contains("ends with the file, unfinished"),
            "{e}"
        );
        // nothing: serde's end of file, as read_json says it
        assert_eq!(
            read_json_lines(b" \n", "kc.json").unwrap_err(),
            read_json(b" \n", "kc.json").unwrap_err()
        );
    }
}
