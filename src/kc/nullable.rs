//! Numbers that may be absent in a key comparison's JSON: a degree of equivalence where a
//! laboratory did not measure an angle block, the reference of a block nobody in the
//! reference reports, χ²_0.95(0). They are NaN (or +∞ for a quantile) in memory, written as
//! `null` (serde_json writes every number that is not finite so) and read back as NaN, so
//! that a comparison read back equals the one written where every number is finite.

use serde::{Deserialize, Deserializer};

/// A list of numbers, `null` read as NaN.
pub(crate) fn numbers<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    let read = Vec::<Option<f64>>::deserialize(deserializer)?;
    Ok(read.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect())
}

/// An optional list of numbers, `null` entries read as NaN.
pub(crate) fn optional_numbers<'de, D: Deserializer<'de>>(
    deserializer: D,
) -> Result<Option<Vec<f64>>, D::Error> {
    let read = Option::<Vec<Option<f64>>>::deserialize(deserializer)?;
    Ok(read.map(|list| list.into_iter().map(|x| x.unwrap_or(f64::NAN)).collect()))
}

/// A number, `null` read as +∞ (a quantile of χ² with no degree of freedom).
pub(crate) fn quantile<'de, D: Deserializer<'de>>(deserializer: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(deserializer)?.unwrap_or(f64::INFINITY))
}

/// A list of quantiles, `null` read as +∞.
pub(crate) fn quantiles<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<f64>, D::Error> {
    let read = Vec::<Option<f64>>::deserialize(deserializer)?;
    Ok(read
        .into_iter()
        .map(|x| x.unwrap_or(f64::INFINITY))
        .collect())
}

/// Whether a number is given: finite. What a table prints as "—" and a CSV as an empty
/// field otherwise.
pub fn is_given(x: f64) -> bool {
    x.is_finite()
}
