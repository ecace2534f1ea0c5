//! A command's JSON against its reference, number by number (docs/FORMAT.md §13.1).

use std::collections::BTreeMap;

use serde_json::Value;

use super::Tolerance;

/// The largest deviation found.
pub(super) struct Found {
    /// The largest deviation (0 when no number was compared).
    pub deviation: Option<f64>,
    /// Where it is.
    pub worst: Option<String>,
    /// Numbers compared.
    pub compared: usize,
}

/// A number of the reference and polycal's number at the same place.
struct Pair {
    /// Where: `pitch_deviation[3]`, `setup_error[1].u`.
    path: String,
    /// The same with every index `[*]`: the numbers that share a scale.
    family: String,
    reference: f64,
    actual: f64,
    /// The `u` polycal states beside the number, if any.
    u: Option<f64>,
}

/// Compares every value of `reference` with the value at the same place in `actual`:
/// numbers by `kind`, anything else (a string, a boolean, `null`, a list's length) exactly.
/// `Err` names the first place that cannot be compared.
pub(super) fn compare(reference: &Value, actual: &Value, kind: Tolerance) -> Result<Found, String> {
    let mut pairs = Vec::new();
    walk(
        reference,
        Some(actual),
        None,
        String::new(),
        String::new(),
        &mut pairs,
    )?;
    let mut scale: BTreeMap<&str, f64> = BTreeMap::new();
    for pair in &pairs {
        let s = scale.entry(&pair.family).or_insert(0.0);
        *s = s.max(pair.reference.abs());
    }
    let mut worst: Option<(f64, &str)> = None;
    for pair in &pairs {
        let difference = (pair.actual - pair.reference).abs();
        let divisor = match kind {
            Tolerance::Absolute => 1.0,
            Tolerance::Relative => scale.get(pair.family.as_str()).copied().unwrap_or(0.0),
            Tolerance::RelativeEach => pair.reference.abs(),
            Tolerance::StandardUncertainties => pair
                .u
                .ok_or_else(|| format!("{}: polycal states no u beside it", pair.path))?,
        };
        let deviation = if divisor > 0.0 {
            difference / divisor
        } else if difference == 0.0 || kind == Tolerance::Relative {
            // a family of zeros is compared absolutely
            difference
        } else {
            f64::INFINITY
        };
        if deviation.is_nan() {
            return Err(format!("{}: not a finite number", pair.path));
        }
        if worst.is_none_or(|(w, _)| deviation > w) {
            worst = Some((deviation, &pair.path));
        }
    }
    Ok(Found {
        deviation: Some(worst.map_or(0.0, |(d, _)| d)),
        worst: worst.map(|(_, p)| p.to_string()),
        compared: pairs.len(),
    })
}

/// Collects the numbers of `reference` with polycal's at the same place.
fn walk(
    reference: &Value,
    actual: Option<&Value>,
    u: Option<f64>,
    path: String,
    family: String,
    pairs: &mut Vec<Pair>,
) -> Result<(), String> {
    let shown = |p: &str| {
        if p.is_empty() {
            "the output".to_string()
        } else {
            p.to_string()
        }
    };
    let Some(actual) = actual else {
        return Err(format!("{}: missing from polycal's output", shown(&path)));
    };
    match (reference, actual) {
        (Value::Object(r), Value::Object(a)) => {
            let u = a.get("u").and_then(Value::as_f64);
            for (key, value) in r {
                let join = |p: &str| {
                    if p.is_empty() {
                        key.clone()
                    } else {
                        format!("{p}.{key}")
                    }
                };
                walk(value, a.get(key), u, join(&path), join(&family), pairs)?;
            }
            Ok(())
        }
        (Value::Array(r), Value::Array(a)) => {
            if r.len() != a.len() {
                return Err(format!(
                    "{}: {} values in the reference, {} in polycal's output",
                    shown(&path),
                    r.len(),
                    a.len()
                ));
            }
            for (i, (rv, av)) in r.iter().zip(a).enumerate() {
                walk(
                    rv,
                    Some(av),
                    None,
                    format!("{path}[{i}]"),
                    format!("{family}[*]"),
                    pairs,
                )?;
            }
            Ok(())
        }
        (Value::Number(r), Value::Number(a)) => {
            let (Some(reference), Some(actual)) = (r.as_f64(), a.as_f64()) else {
                return Err(format!("{}: not a number", shown(&path)));
            };
            pairs.push(Pair {
                path,
                family,
                reference,
                actual,
                u,
            });
            Ok(())
        }
        (r, a) if r == a => Ok(()),
        (r, a) => Err(format!(
            "{}: the reference has {r}, polycal {a}",
            shown(&path)
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn relative_to_the_largest_of_a_list_and_absolute_for_zeros() {
        let r = json!({"x": [1.0, -4.0, 0.0], "z": [0.0, 0.0], "o": [{"v": 2.0}, {"v": 8.0}]});
        let a = json!({"x": [1.0, -4.0, 0.002], "z": [0.0, 1e-13], "o": [{"v": 2.0}, {"v": 8.4}], "more": 1});
        let found = compare(&r, &a, Tolerance::Relative).unwrap();
        assert_eq!(found.compared, 7);
        assert!((found.deviation.unwrap() - 0.05).abs() < 1e-15);
        assert_eq!(found.worst.as_deref(), Some("o[1].v"));
        let each = compare(&r, &a, Tolerance::RelativeEach).unwrap();
        assert_eq!(each.deviation, Some(f64::INFINITY));
        assert_eq!(each.worst.as_deref(), Some("x[2]"));
    }

    #[test]
    fn a_place_missing_or_different_is_named() {
        let r = json!({"x": [1.0, 2.0], "ok": true, "k": null});
        let short = compare(
            &r,
            &json!({"x": [1.0], "ok": true, "k": null}),
            Tolerance::Absolute,
        );
        assert_eq!(
            short.err().unwrap(),
            "x: 2 values in the reference, 1 in polycal's output"
        );
        let missing = compare(
            &r,
            &json!({"x": [1.0, 2.0], "ok": true}),
            Tolerance::Absolute,
        );
        assert_eq!(missing.err().unwrap(), "k: missing from polycal's output");
        let other = compare(
            &r,
            &json!({"x": [1.0, 2.0], "ok": false, "k": null}),
            Tolerance::Absolute,
        );
        assert_eq!(
            other.err().unwrap(),
            "ok: the reference has true, polycal false"
        );
    }
}
