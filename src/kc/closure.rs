//! Pitch deviations that do not close (docs/FORMAT.md §12). A polygon's pitch deviations
//! sum to 0: its angles make the full circle. A result's written pitch deviations may miss
//! it by their rounding, at most N × half a unit of their last written decimal; the
//! comparison takes every result's mean out anyway ([`super::closed`]). Beyond the rounding
//! the misclosure is stated in a note, with its size and the fact that the mean is taken
//! out (a nominal angle rounded, a closure not applied). It is refused when taking the mean
//! out would move every face by more than the result's own expanded uncertainty 2u of its
//! most precise face: the comparison would then judge values the laboratory did not
//! state within their uncertainty, and no covariance of the stated u explains it (u(Σβ) ≤
//! Σu_k, so a misclosure of an unclosed measurement beyond 2·N·min u is beyond k = 2 of
//! even fully correlated errors) — face deviations given as pitch deviations, a face left
//! out, a sign or a nominal angle wrong.

use super::input::{Aligned, MIN_STANDARD_U_ARCSEC};
use super::{KcError, LabResult};
use crate::input::limits::sig;

/// The notes on the results (in the order of `results`, lined up in `aligned`) whose
/// pitch deviations do not close beyond their rounding.
///
/// # Errors
///
/// [`KcError::NotClosed`] for the first result whose misclosure is gross.
pub(super) fn misclosures(
    results: &[&LabResult],
    aligned: &Aligned,
) -> Result<Vec<String>, KcError> {
    let mut notes = Vec::new();
    for ((result, x), u) in results.iter().zip(&aligned.values).zip(&aligned.u) {
        let faces = x.len();
        let sum: f64 = x.iter().sum();
        let decimals = x.iter().map(|x| written_decimals(*x)).max().unwrap_or(0);
        let rounding = rounding_bound_arcsec(faces, decimals);
        // Below the rounding, or below any angle measurement (the floating-point sum of
        // values written at full precision).
        if sum.abs() <= rounding + MIN_STANDARD_U_ARCSEC {
            continue;
        }
        let Some((k, &u_min)) = u.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)) else {
            continue;
        };
        let shift = sum / faces as f64;
        if shift.abs() > 2.0 * u_min {
            return Err(KcError::NotClosed {
                file: result.source.clone(),
                lab: result.name.clone(),
                sum_arcsec: sum,
                faces,
                u_arcsec: u_min,
                face: aligned.index.get(k).copied().unwrap_or(0),
            });
        }
        notes.push(format!(
            "{} ({}): its pitch deviations sum to {}″ over {faces} faces, more than the \
             rounding of its written digits explains (at most {}″, {faces} × half a unit of \
             its last decimal, 10^−{decimals}″); their mean, {}″, is taken out of every face, \
             as the comparison does for every result",
            result.name,
            result.source,
            sig(sum, 3),
            sig(rounding, 3),
            sig(shift, 3)
        ));
    }
    Ok(notes)
}

/// The decimals of `x` as written: those of its shortest text that reads back to it (a
/// value read from `0.1230` has 3: the written zero is not known, so a result's rounding is
/// taken from the most decimals of its values).
fn written_decimals(x: f64) -> u32 {
    let text = format!("{x}");
    text.split_once('.').map_or(0, |(_, fraction)| {
        u32::try_from(fraction.len()).unwrap_or(u32::MAX)
    })
}

/// The largest |Σβ| that rounding `faces` values to `decimals` decimals can give:
/// N × ½·10^−decimals, arcsec.
fn rounding_bound_arcsec(faces: usize, decimals: u32) -> f64 {
    let exponent = i32::try_from(decimals).unwrap_or(i32::MAX);
    faces as f64 * 0.5 * 10f64.powi(-exponent)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kc::input;
    use crate::results::{Quantity, ResultRow};

    #[test]
    fn decimals_are_those_written_and_the_bound_is_half_a_unit_per_face() {
        assert_eq!(written_decimals(0.1230), 3);
        assert_eq!(written_decimals(-0.0001), 4);
        assert_eq!(written_decimals(12.0), 0);
        assert_eq!(written_decimals(0.1 + 0.2), 17);
        assert!((rounding_bound_arcsec(12, 4) - 0.0006).abs() < 1e-18);
        assert_eq!(rounding_bound_arcsec(7, 0), 3.5);
    }

    fn lab(name: &str, values: &[f64], u: f64) -> LabResult {
        let rows = values
            .iter()
            .zip(1..)
            .map(|(x, face)| ResultRow::new(Quantity::PitchDeviation, face, *x).with_u(u))
            .collect();
        LabResult::from_rows(name, rows)
    }

    fn notes(labs: &[LabResult]) -> Result<Vec<String>, KcError> {
        let all: Vec<&LabResult> = labs.iter().collect();
        input::pitch(&all).map(|aligned| aligned.notes)
    }

    #[test]
    fn a_misclosure_within_the_rounding_is_silent_beyond_it_noted_and_gross_refused() {
        // 4 faces written to 0.01″: rounding explains |Σβ| ≤ 0.02″.
        let closed = lab("A", &[0.10, -0.05, 0.02, -0.07], 0.05);
        let rounded = lab("B", &[0.10, -0.05, 0.02, -0.05], 0.05); // Σβ = 0.02
        assert!(notes(&[closed.clone(), rounded]).unwrap().is_empty());
        // Σβ = 0.04: noted, its mean 0.01″ taken out (2u = 0.1″ per face).
        let open = lab("C", &[0.10, -0.05, 0.02, -0.03], 0.05);
        let noted = notes(&[closed.clone(), open]).unwrap();
        assert_eq!(noted.len(), 1, "{noted:?}");
        assert!(
            noted[0].starts_with("C (C): its pitch deviations sum to 0.0400″ over 4 faces")
                && noted[0].contains("at most 0.0200″")
                && noted[0].contains("their mean, 0.0100″, is taken out"),
            "{}",
            noted[0]
        );
        // Σβ = 0.44: the mean 0.11″ > 2u = 0.1″: refused.
        let gross = lab("D", &[0.50, -0.05, 0.02, -0.03], 0.05);
        let refused = notes(&[closed.clone(), gross]).unwrap_err();
        assert!(
            matches!(refused, KcError::NotClosed { ref lab, faces: 4, .. } if lab == "D"),
            "{refused:?}"
        );
        assert!(refused.to_string().contains("sum to 0.4400″ over 4 faces"));
        assert!(refused.to_string().contains("by 0.110″"));
        // The same sum with u = 0.06 (2u = 0.12″ > 0.11″): noted, not refused.
        let wider = lab("E", &[0.50, -0.05, 0.02, -0.03], 0.06);
        assert_eq!(notes(&[closed, wider]).unwrap().len(), 1);
    }

    #[test]
    fn values_at_full_precision_closed_by_computation_are_silent() {
        let x: Vec<f64> = (0..3000)
            .map(|i| (f64::from(i) * 0.37).sin() * 0.5)
            .collect();
        let mean = x.iter().sum::<f64>() / 3000.0;
        let closed: Vec<f64> = x.iter().map(|x| x - mean).collect();
        // not exactly 0 in floating point, far below any measurement
        let sum: f64 = closed.iter().sum();
        assert!(sum != 0.0 && sum.abs() < 1e-12, "{sum}");
        let (a, b) = (lab("A", &closed, 0.1), lab("B", &closed, 0.2));
        assert_eq!(notes(&[a, b]).unwrap(), Vec::<String>::new());
    }
}
