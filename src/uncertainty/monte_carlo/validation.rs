//! The validation of a GUM result by Monte Carlo (JCGM 101 §8).

use serde::Serialize;

use super::{OutputSummary, numerical_tolerance};

/// The comparison of a GUM result with Monte Carlo (JCGM 101 §8.2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct GumValidation {
    /// Numerical tolerance `δ` of the GUM standard uncertainty.
    pub delta: f64,
    /// `|y − U_p − y_low|`.
    pub d_low: f64,
    /// `|y + U_p − y_high|`.
    pub d_high: f64,
    /// Whether both are within `δ`: the GUM uncertainty framework is validated.
    pub passed: bool,
}

/// Validates the GUM result `y ± U_p` (standard uncertainty `u`) against the Monte Carlo
/// probabilistically symmetric interval, to `significant_digits` digits of `u`
/// (JCGM 101 §8.2).
///
/// ```
/// use polycal::uncertainty::monte_carlo::{validate_gum, OutputSummary};
/// let mc = OutputSummary::new(0.0, 2.0, 0.95, -3.88, 3.88);
/// // u = 2.0 to two digits: δ = 0.05; the GUM ends ±3.92 differ by 0.04: validated.
/// let v = validate_gum(0.0, 2.0, 3.92, &mc, 2);
/// assert!(v.passed && (v.delta - 0.05).abs() < 1e-15);
/// assert!(!validate_gum(0.0, 2.0, 3.92, &mc, 3).passed);
/// ```
pub fn validate_gum(
    estimate: f64,
    u: f64,
    expanded_u: f64,
    mc: &OutputSummary,
    significant_digits: u32,
) -> GumValidation {
    let delta = numerical_tolerance(u, significant_digits);
    let d_low = (estimate - expanded_u - mc.low).abs();
    let d_high = (estimate + expanded_u - mc.high).abs();
    GumValidation {
        delta,
        d_low,
        d_high,
        passed: d_low <= delta && d_high <= delta,
    }
}
