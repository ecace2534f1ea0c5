//! What a standard's history says in words: its one decision, the chosen model's fit,
//! and what the reader must know about the prediction (the table, the report and the
//! JSON's `notes` state the same sentences).

use super::{Calibration, DAYS_PER_YEAR, DriftModel, History};
use crate::results::Quantity;

impl History {
    /// The one decision in words: the test of the drift vector at 5 % and the model it
    /// chooses; no final stop.
    pub fn verdict_statement(&self) -> String {
        let v = &self.vector;
        match self.model {
            DriftModel::Constant => format!(
                "No drift found: the drift vector's χ² = {:.2} ≤ χ²_0.95({}) = {:.2} (b = 0 not \
                 rejected at 5 %); the model is constant",
                v.chi2, v.dof, v.chi2_critical
            ),
            DriftModel::Linear => format!(
                "Drift found: the drift vector's χ² = {:.2} > χ²_0.95({}) = {:.2} (b = 0 rejected \
                 at 5 %); the model is linear on every position",
                v.chi2, v.dof, v.chi2_critical
            ),
        }
    }

    /// The chosen model's fit in words: whether its residual χ² passes its test at 5 %,
    /// and what follows when it does not; no final stop.
    pub fn fit_statement(&self) -> String {
        match &self.fit {
            None => "The linear model's fit is not tested: 2 calibrations leave it no degree \
                     of freedom (a third calibration tests it)"
                .to_string(),
            Some(fit) if fit.test.consistent => format!(
                "The {} model fits the calibrations: residual χ² = {:.2} ≤ χ²_0.95({}) = {:.2}",
                fit.model.name(),
                fit.test.chi2,
                fit.test.dof,
                fit.test.chi2_critical
            ),
            Some(fit) => format!(
                "The {} model does NOT fit the calibrations: residual χ² = {:.2} > χ²_0.95({}) = \
                 {:.2}. The calibrations scatter beyond their stated uncertainties (their stated \
                 u look too small, or the standard changes otherwise than the model says): the \
                 drift test's rate is then not its 5 %, and the predicted u, which takes the \
                 stated u as they are, is too small",
                fit.model.name(),
                fit.test.chi2,
                fit.test.dof,
                fit.test.chi2_critical
            ),
        }
    }
}

/// The notes of a history: the statements above, and what the prediction extrapolates.
pub(super) fn notes(history: &History, sorted: &[&Calibration]) -> Vec<String> {
    let mut notes = vec![history.verdict_statement(), history.fit_statement()];
    if history.quantity == Quantity::EncoderError {
        notes.push(
            "encoder errors are defined up to a constant: each calibration's mean over the \
             positions is taken out before they are compared"
                .to_string(),
        );
    }
    let (first, last) = (
        sorted.first().map_or(0, |c| c.days),
        sorted.last().map_or(0, |c| c.days),
    );
    let at = crate::clock::days_from_date(&history.at).unwrap_or(last);
    if at > last {
        let years = (at - last) as f64 / DAYS_PER_YEAR;
        if history.model == DriftModel::Linear {
            notes.push(format!(
                "the prediction at {} extrapolates the drift {years:.2} year(s) beyond the newest \
                 calibration; its u includes the drift's uncertainty over that time",
                history.at
            ));
        } else if years > (last - first) as f64 / DAYS_PER_YEAR {
            notes.push(format!(
                "the prediction at {} is {years:.2} year(s) after the newest calibration, longer \
                 than the calibrations span: a drift too small to be found in them may have \
                 grown since",
                history.at
            ));
        }
    } else if at < first {
        notes.push(format!(
            "the prediction at {} is before the oldest calibration",
            history.at
        ));
    }
    if let Some(max_u) = history.max_u {
        match (history.model, &history.recalibrate_by) {
            (DriftModel::Constant, _) => notes.push(format!(
                "with the constant model the prediction's U does not grow with time: U = {max_u}″ \
                 is {} (the calibrations found no drift to extrapolate; the interval is then a \
                 matter of the laboratory's policy)",
                if history
                    .predicted_u
                    .iter()
                    .any(|u| super::COVERAGE_FACTOR * u > max_u)
                {
                    "exceeded already on some position"
                } else {
                    "never reached"
                }
            )),
            (DriftModel::Linear, Some(date)) => notes.push(format!(
                "the prediction's U reaches {max_u}″ on {date} (the earliest position): \
                 recalibrate by then{}",
                if *date < history.at {
                    format!(" (already past at {})", history.at)
                } else {
                    String::new()
                }
            )),
            (DriftModel::Linear, None) => {
                let above: Vec<String> = history
                    .max_u_date
                    .iter()
                    .flatten()
                    .zip(&history.index)
                    .filter(|(date, _)| date.is_none())
                    .map(|(_, index)| index.to_string())
                    .collect();
                notes.push(format!(
                    "the prediction's U exceeds {max_u}″ at every date at position(s) {}: no \
                     recalibration interval meets it",
                    above.join(", ")
                ));
            }
        }
    }
    notes
}
