//! The verdict of a comparison (docs/FORMAT.md §5.4, "The verdict"): the differences of the
//! closed quantities tested as one vector at 5 %, the rows with |En| > 1 counted beside the
//! number expected by chance, and the one sentence that states it in every document.
//!
//! **The vector.** Pitch deviations and encoder errors are closed (Σβ = 0 over the faces,
//! Σα = 0 over the positions: an encoder error is defined up to a constant). A result file
//! carries no covariance, so each result is taken as closed (docs/FORMAT.md §12): over its
//! own M rows of the family, V = M/(M − 1)·P·diag(u²)·P, P = I − J/M. Of the n rows in
//! common the differences d = a − b are tested after their weighted mean is taken out:
//! on the common rows the parts of the closure that couple them to the rest are constant
//! across them and vanish with the mean, so the covariance of the centred differences is
//! P_n·D·P_n, D = diag(c_a·u_a² + c_b·u_b² − 2·r·√(c_a·c_b)·u_a·u_b), c = M/(M − 1), and
//! χ² = dᵀ(P_n·D·P_n)⁺d = Σ w_i·(d_i − d̄_w)², w_i = 1/D_i, with ν = n − 1
//! (`kc::closed::difference_chi2`, Sherman–Morrison: O(n), no matrix).
//! When both results have the same n rows (the usual case, faces 1 … N) this is the test of
//! the closed vector with V_d = V_a + V_b exactly; with fewer rows in common (24 angles of a
//! 168-position self-calibration) it costs the one degree of freedom of the mean.
//!
//! Face deviations are the pitch deviations accumulated (φ_k = Σ_{j≤k} β_j): the same
//! information, so they do not enter the vector. Setup errors enter only when counted
//! ([`super::CompareOptions::with_include_setup`]), as independent rows, ν = their number.
//! The families are taken as independent of each other: the χ² and ν add up, and the one
//! test is χ² ≤ χ²_0.95(ν).

use std::collections::HashMap;
use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use super::{CompareError, Comparison};
use crate::kc::chi2_quantile_95;
use crate::kc::closed::difference_chi2;
use crate::results::Quantity;

/// Which rule gives the comparison's verdict and its exit status (JSON `verdict`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum VerdictRule {
    /// One test of the whole comparison at 5 %: the differences of the closed quantities as
    /// one vector (the default).
    #[default]
    Vector,
    /// The per-row rule, for schemes that prescribe it: the comparison fails when some
    /// |En| > 1 among the rows in the verdict.
    En,
}

impl VerdictRule {
    /// The rule's word in files and on the command line: `vector` or `en`.
    pub fn name(self) -> &'static str {
        match self {
            VerdictRule::Vector => "vector",
            VerdictRule::En => "en",
        }
    }
}

impl fmt::Display for VerdictRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A word that is not a verdict rule.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown verdict rule '{0}': expected vector or en")]
#[non_exhaustive]
pub struct UnknownVerdictRule(pub String);

impl FromStr for VerdictRule {
    type Err = UnknownVerdictRule;

    fn from_str(word: &str) -> Result<Self, Self::Err> {
        match word {
            "vector" => Ok(VerdictRule::Vector),
            "en" => Ok(VerdictRule::En),
            _ => Err(UnknownVerdictRule(word.to_string())),
        }
    }
}

/// One family's part of the vector test.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct FamilyTest {
    /// The family: `pitch_deviation`, `encoder_error` or (when counted) `setup_error`.
    pub quantity: Quantity,
    /// The rows of the family in common.
    pub rows: usize,
    /// Its χ² (dimensionless).
    pub chi2: f64,
    /// Its degrees of freedom: rows − 1 for a closed family, rows for setup errors.
    pub dof: usize,
}

/// The test of the whole comparison as one vector (JSON `vector`).
#[derive(Debug, Clone, PartialEq, Serialize)]
#[non_exhaustive]
pub struct VectorTest {
    /// χ², the sum over the families.
    pub chi2: f64,
    /// ν, the sum over the families.
    pub dof: usize,
    /// χ²_0.95(ν), the 95 % quantile of χ² with ν degrees of freedom.
    pub critical: f64,
    /// Whether χ² ≤ χ²_0.95(ν): the results are consistent at 5 %.
    pub consistent: bool,
    /// Each family's part, in the order pitch deviations, encoder errors, setup errors.
    pub families: Vec<FamilyTest>,
}

/// One row of the verdict's families with its two standard uncertainties, arcseconds.
#[derive(Debug, Clone, Copy)]
pub(super) struct Pair {
    pub quantity: Quantity,
    pub index: u32,
    pub difference_arcsec: f64,
    pub u_a_arcsec: f64,
    pub u_b_arcsec: f64,
}

/// How many rows of each family a result has (the M of its closure).
pub(super) type FamilySizes = HashMap<Quantity, usize>;

/// The vector test of the rows in the verdict (`pairs`), the results' families of
/// `sizes_a` and `sizes_b` rows, correlation `r`.
///
/// # Errors
///
/// A difference without variance, a χ² beyond the range of numbers, no family to test.
pub(super) fn vector_test(
    pairs: &[Pair],
    sizes_a: &FamilySizes,
    sizes_b: &FamilySizes,
    r: f64,
    labels: (&str, &str),
) -> Result<VectorTest, CompareError> {
    let mut families = Vec::new();
    for quantity in [
        Quantity::PitchDeviation,
        Quantity::EncoderError,
        Quantity::SetupError,
    ] {
        let rows: Vec<&Pair> = pairs.iter().filter(|p| p.quantity == quantity).collect();
        let closed = quantity != Quantity::SetupError;
        if rows.is_empty() || (closed && rows.len() < 2) {
            continue;
        }
        // The closure's factor M/(M − 1) of each result (M ≥ n ≥ 2 for a closed family).
        let factor = |sizes: &FamilySizes| {
            let m = sizes.get(&quantity).copied().unwrap_or(rows.len()).max(2) as f64;
            if closed { m / (m - 1.0) } else { 1.0 }
        };
        let (c_a, c_b) = (factor(sizes_a), factor(sizes_b));
        // Scaled by the largest u, so that tiny (or huge) uncertainties neither underflow
        // nor overflow when squared.
        let scale = rows
            .iter()
            .map(|p| p.u_a_arcsec.max(p.u_b_arcsec))
            .fold(0.0, f64::max);
        let mut differences = Vec::with_capacity(rows.len());
        let mut variances = Vec::with_capacity(rows.len());
        for p in &rows {
            let (ua, ub) = (p.u_a_arcsec / scale, p.u_b_arcsec / scale);
            let variance = c_a * ua * ua + c_b * ub * ub - 2.0 * r * (c_a * c_b).sqrt() * ua * ub;
            if !(scale > 0.0 && scale.is_finite() && variance > 0.0 && (1.0 / variance).is_finite())
            {
                return Err(CompareError::NoVariance {
                    quantity: p.quantity,
                    index: p.index,
                    u_a: p.u_a_arcsec,
                    u_b: p.u_b_arcsec,
                    r,
                });
            }
            differences.push(p.difference_arcsec / scale);
            variances.push(variance);
        }
        let (chi2, dof) = if closed {
            (difference_chi2(&differences, &variances).0, rows.len() - 1)
        } else {
            let chi2 = differences
                .iter()
                .zip(&variances)
                .map(|(d, v)| d * d / v)
                .sum();
            (chi2, rows.len())
        };
        if !chi2.is_finite() {
            return Err(CompareError::Chi2OutOfRange { quantity });
        }
        families.push(FamilyTest {
            quantity,
            rows: rows.len(),
            chi2,
            dof,
        });
    }
    let dof: usize = families.iter().map(|f| f.dof).sum();
    if dof == 0 {
        return Err(CompareError::NoVector {
            a: labels.0.to_string(),
            b: labels.1.to_string(),
        });
    }
    let chi2: f64 = families.iter().map(|f| f.chi2).sum();
    if !chi2.is_finite() {
        return Err(CompareError::Chi2OutOfRange {
            quantity: families[0].quantity,
        });
    }
    let critical = chi2_quantile_95(dof);
    Ok(VectorTest {
        chi2,
        dof,
        critical,
        consistent: chi2 <= critical,
        families,
    })
}

/// The probability that a row of consistent results has |En| > 1: En is normal with mean
/// 0 and standard deviation s = √(u_a² + u_b² − 2·r·u_a·u_b) / √(U_a² + U_b² − 2·r·U_a·U_b),
/// so P(|En| > 1) = 2·(1 − Φ(1/s)) = erfc(1/(s·√2)); 4.55 % for k = 2 on both sides.
fn probability_en_exceeds_one(
    u_a: f64,
    u_b: f64,
    expanded_u_a: f64,
    expanded_u_b: f64,
    r: f64,
) -> f64 {
    let scale = u_a.max(u_b).max(expanded_u_a).max(expanded_u_b);
    if !(scale > 0.0 && scale.is_finite()) {
        return 0.0;
    }
    let (ua, ub, ea, eb) = (
        u_a / scale,
        u_b / scale,
        expanded_u_a / scale,
        expanded_u_b / scale,
    );
    let variance = (ua * ua + ub * ub - 2.0 * r * ua * ub).max(0.0);
    let denominator = ea * ea + eb * eb - 2.0 * r * ea * eb;
    let s = (variance / denominator).sqrt();
    if s.is_nan() || s <= 0.0 {
        return 0.0;
    }
    statrs::function::erf::erfc(1.0 / (s * std::f64::consts::SQRT_2))
}

impl super::ComparisonRow {
    /// The probability that this row has |En| > 1 by chance when the results are
    /// consistent, with the correlation `correlation` between them: 2·(1 − Φ(1/s)),
    /// s = √(u_a² + u_b² − 2·r·u_a·u_b) / √(U_a² + U_b² − 2·r·U_a·U_b) (4.55 % for k = 2 on
    /// both sides). `None` when a standard uncertainty is not known.
    pub fn probability_en_exceeds_one(&self, correlation: f64) -> Option<f64> {
        Some(probability_en_exceeds_one(
            self.u_a?,
            self.u_b?,
            self.expanded_u_a,
            self.expanded_u_b,
            correlation,
        ))
    }
}

/// `1 row` or `n rows`.
fn rows_word(n: usize) -> String {
    if n == 1 {
        "1 row".to_string()
    } else {
        format!("{n} rows")
    }
}

impl Comparison {
    /// Whether the comparison passes by its verdict rule ([`Comparison::verdict`]): the
    /// vector's test (χ² ≤ χ²_0.95(ν)), or with [`VerdictRule::En`] every |En| ≤ 1 among
    /// the rows in the verdict. `polycal compare` exits with status 1 when it does not.
    pub fn verdict_ok(&self) -> bool {
        match self.verdict {
            VerdictRule::Vector => self.vector.as_ref().is_some_and(|v| v.consistent),
            VerdictRule::En => self.en_exceeding == 0,
        }
    }

    /// The verdict in one sentence, the same words in the table, the report and the DCC,
    /// e.g. `consistent: χ² = 18.31 ≤ χ²_0.95(23) = 35.17, the differences tested as one
    /// vector at 5 %; 1 row with |En| > 1, about 3.2 expected by chance`.
    pub fn verdict_sentence(&self) -> String {
        let vector = self.vector.as_ref().map(|v| {
            format!(
                "χ² = {:.2} {} χ²_0.95({}) = {:.2}",
                v.chi2,
                if v.consistent { "≤" } else { ">" },
                v.dof,
                v.critical
            )
        });
        let counted = self.rows.iter().filter(|r| r.in_verdict).count();
        let exceeding = match self.en_expected {
            Some(expected) => format!(
                "{} of {counted} with |En| > 1, about {expected:.1} expected by chance",
                rows_word(self.en_exceeding)
            ),
            None => format!(
                "{} of {counted} with |En| > 1",
                rows_word(self.en_exceeding)
            ),
        };
        let word = if self.verdict_ok() {
            "consistent"
        } else {
            "NOT consistent"
        };
        match (self.verdict, vector) {
            (VerdictRule::Vector, Some(vector)) => format!(
                "{word}: {vector}, the differences tested as one vector at 5 %; {exceeding}"
            ),
            (VerdictRule::Vector, None) => format!("{word}: no vector test; {exceeding}"),
            (VerdictRule::En, vector) => {
                let mut sentence = format!("{word} by the per-row rule (|En| ≤ 1): {exceeding}");
                if let Some(vector) = vector {
                    sentence.push_str(&format!("; as one vector (not the verdict): {vector}"));
                }
                sentence
            }
        }
    }
}
