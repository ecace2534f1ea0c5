//! The diagnosis anew with every fit weighted by the noise groups' σ, when the test of
//! equal noise fails ([`super::noise`]): the groups' σ estimated anew from each weighted
//! fit, the weighted diagnosis kept unless its residuals still vary slowly in time, and
//! the notes that say what was done.

use std::sync::Arc;

use super::base::Base;
use super::noise::{MAX_WEIGHTINGS, NoiseTest, SIGMA_TOLERANCE, change_words};
use super::{Clock, DiagnoseOptions, Diagnosis, Rejection};
use crate::measurement::MeasurementSet;
use crate::solve::SolveError;

/// The note of a test that failed: the changes in words, or the groups' σ, and whether
/// the fits are weighted.
fn note(test: &NoiseTest, several_setups: bool, weighted: bool) -> String {
    let found = if test.changes.is_empty() {
        let groups: Vec<String> = test
            .sigma
            .iter()
            .map(|g| {
                let mounting = if several_setups {
                    format!(" (setup {})", g.setup)
                } else {
                    String::new()
                };
                format!("autocollimator {}{mounting} {:.3}″", g.ac, g.sigma_arcsec)
            })
            .collect();
        format!(
            "the noise differs between autocollimators: {}",
            groups.join(", ")
        )
    } else {
        test.changes
            .iter()
            .map(|c| change_words(c, several_setups))
            .collect::<Vec<_>>()
            .join("; ")
    };
    let fits = if weighted {
        "every fit weights each group by its own σ (1/σ²), and the uncertainties follow"
    } else {
        "the design is too large for the weighted fit (more than 360 positions, or a self-calibration): the fits keep equal weights, and the uncertainties of the noisier groups' quantities are understated"
    };
    format!(
        "The noise is not the same in every cycle and autocollimator (Bartlett T = {:.1}, {} dof, p = {:.1e} < {}): {found}; {fits}.",
        test.statistic, test.dof, test.p_value, test.alpha
    )
}

/// Whether the final residuals of `diagnosis` vary slowly in time: a failed check of a
/// stream's time order, or a wandering zero left out.
fn varies_slowly(diagnosis: &Diagnosis) -> bool {
    diagnosis
        .adequacy
        .checks
        .iter()
        .any(|c| !c.passed && c.stream.is_some())
        || diagnosis
            .tried
            .iter()
            .any(|t| t.rejection == Rejection::LeftOutWandering)
}

/// The note of a test that failed beside residuals that vary slowly in time.
fn note_slow(test: &NoiseTest, several_setups: bool) -> String {
    let unequal = note(test, several_setups, false);
    let found = unequal
        .split_once("): ")
        .and_then(|(_, rest)| rest.split_once("; "))
        .map_or(String::new(), |(found, _)| format!(" ({found})"));
    format!(
        "The scatter of the residuals is not the same in every cycle and autocollimator (Bartlett T = {:.1}, {} dof, p = {:.1e}){found}, but the residuals also vary slowly in time (see the checks): the larger scatter may be that structure rather than noise, so the fits keep equal weights.",
        test.statistic, test.dof, test.p_value
    )
}

/// The diagnosis `first` (unweighted, its [`Diagnosis::noise`] tested) or, when its noise
/// is not equal, the diagnosis anew with every fit weighted by its groups' σ
/// (`diagnose_fitted` of a weighted `base`), the base model before kept as `first`'s
/// (what `solve` gives), the final residuals in arcsec.
pub(super) fn reweighted(
    set: &MeasurementSet,
    base: &Base<'_>,
    clock: Clock,
    options: &DiagnoseOptions,
    mut first: Diagnosis,
    diagnose_fitted: impl Fn(
        &MeasurementSet,
        &Base<'_>,
        Clock,
        &DiagnoseOptions,
    ) -> Result<Diagnosis, SolveError>,
) -> Result<Diagnosis, SolveError> {
    let Some(test) = first.noise.clone().filter(|t| !t.equal) else {
        return Ok(first);
    };
    let several_setups = set
        .readings
        .iter()
        .any(|r| r.setup != set.readings[0].setup);
    let mut test = test;
    let mut weighted_run = None;
    for _ in 0..MAX_WEIGHTINGS {
        let weights: Arc<[f64]> = test.weights(set).into();
        let Some(weighted) = base.with_weights(Arc::clone(&weights)) else {
            break;
        };
        let Ok(second) = diagnose_fitted(set, &weighted, clock, options) else {
            break;
        };
        let refit = second.noise.clone();
        weighted_run = Some((second, weights));
        let Some(refit) = refit else {
            break;
        };
        let (next, change) = test.with_sums_of(&refit);
        test = next;
        if change < SIGMA_TOLERANCE {
            break;
        }
    }
    let Some((mut second, weights)) = weighted_run else {
        first.notes.push(note(&test, several_setups, false));
        return Ok(first);
    };
    // residuals that still vary slowly in time with the weights (a failed serial-correlation
    // or slow-variation check, a wandering zero left out) scatter more in some cycles for
    // that reason: the groups' σ weigh the structure, not the noise, and the unweighted
    // diagnosis stands (a noise rise alone misleads the unweighted search, not the
    // weighted one)
    if varies_slowly(&second) {
        first.notes.push(note_slow(&test, several_setups));
        return Ok(first);
    }
    // the final model's residuals in arcsec (its fits' are whitened)
    for (e, w) in second.after.residuals.iter_mut().zip(weights.iter()) {
        *e /= w;
    }
    second.before = first.before;
    second.before_sub_pitch = first.before_sub_pitch;
    let mut reported = test.clone();
    reported.weighted = true;
    second.noise = Some(reported);
    second.notes.push(note(&test, several_setups, true));
    Ok(second)
}
