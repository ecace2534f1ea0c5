//! The plain words of a diagnosis: what could not be tested and why, what the data
//! cannot tell apart and what would decide it, what remains when no term expresses it.

use super::candidates::autocollimators;
use super::clock::Clock;
use super::lack_of_fit::LackOfFit;
use super::{FoundEffect, MAX_JUMPS_PER_STREAM, identify};
use crate::effects::Effect;
use crate::measurement::{Direction, MeasurementSet};

/// The plain words on a finding with alternatives: what cannot be told apart, how far
/// the calibration moves, and what would decide it.
pub(super) fn ambiguity(found: &FoundEffect, clock: Clock) -> String {
    let value = |e: &Effect| match e {
        Effect::Drift { .. } => format!("{:+.4}{}", e.value(), clock.drift_unit_text()),
        Effect::CrossTalk { value, .. } => format!("{value:+.5}″/″"),
        other => format!("{:+.4}″", other.value()),
    };
    let alternatives: Vec<String> = found
        .alternatives
        .iter()
        .map(|a| {
            let names: Vec<String> = a
                .effects
                .iter()
                .map(|e| format!("the {} ({})", e.label(), value(e)))
                .collect();
            format!(
                "{} (F = {:.2}, p = {:.2}; β would change by up to {:.4}″, α by up to {:.4}″)",
                names.join(" together with "),
                a.f_statistic,
                a.p_value,
                a.pitch_change_max,
                a.encoder_change_max
            )
        })
        .collect();
    let decide = match found.effect {
        Effect::CrossTalk { .. } => {
            "Closure data determine only the differences of the autocollimators' cross-talk coefficients. State the cross-talk of one autocollimator from its calibration (docs/FORMAT.md §6): the others' then follow from the data."
        }
        _ => {
            "A design whose readings separate them would decide it: another mounting of the polygon, a counter-clockwise cycle, or an instrument whose behaviour is known from its calibration."
        }
    };
    if found.ambiguous() {
        format!(
            "The data cannot tell the {} ({}) from {}: they fit equally well, but give calibrations that differ by more than the expanded uncertainty. This is not a finding, and the result is not certified. {decide}",
            found.effect.label(),
            value(&found.effect),
            alternatives.join("; or ")
        )
    } else {
        format!(
            "The data cannot tell the {} ({}) from {}; they fit equally well, and the calibrations they give agree within the expanded uncertainty.",
            found.effect.label(),
            value(&found.effect),
            alternatives.join("; or ")
        )
    }
}

/// The note on a cross-talk common to every autocollimator, which closure cannot see,
/// when `reading_y` spans more than a few arcseconds.
pub(super) fn common_cross_talk(
    set: &MeasurementSet,
    base: &super::base::Base<'_>,
    stated: &[u32],
) -> Option<String> {
    let (span, pitch, encoder) = identify::common_cross_talk_reach(set, base, 3.0)?;
    let every_stated = autocollimators(set).iter().all(|ac| stated.contains(ac));
    let stated_text = if every_stated {
        "Every autocollimator's cross-talk is stated from its calibration, so this is corrected for.".to_string()
    } else {
        "Only an autocollimator's calibration of its cross-talk can remove it: state it for each autocollimator (docs/FORMAT.md §6).".to_string()
    };
    Some(format!(
        "A cross-talk common to all autocollimators cannot be seen by closure: reading_y spans {span:.1}″, and a common cross-talk of 0.01″/″ would move β by up to {:.4}″ and α by up to {:.4}″ without leaving a residual. {stated_text}",
        0.01 * pitch,
        0.01 * encoder
    ))
}

/// The note when `reading_y` spans more than a few arcseconds but cross-talk cannot be
/// told apart from the polygon and the encoder.
pub(super) fn cross_talk_untestable(set: &MeasurementSet, ac: u32) -> Option<String> {
    let ys: Vec<f64> = set
        .readings
        .iter()
        .filter(|r| r.ac == ac)
        .filter_map(|r| r.reading_y_arcsec)
        .collect();
    let span = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        - ys.iter().copied().fold(f64::INFINITY, f64::min);
    (span > 3.0).then(|| format!(
        "Cross-talk of reading_y into the reading cannot be tested: reading_y spans {span:.1}″, but in this design it follows the faces and positions so closely that a cross-talk term cannot be told apart from the pitch deviations and encoder errors (it would bias them unseen). Measure in several mountings (shift the polygon on the table) so that each face is read at different elevations."
    ))
}

/// Effect kinds the data cannot show at all, and what would make them visible.
pub(super) fn untestable_kinds(set: &MeasurementSet, clock: Clock) -> Vec<String> {
    let mut notes = Vec::new();
    if clock == Clock::StopOrder {
        notes.push("The file has no `time` for every reading: drift is modelled in the run's stop order, one unit per stop of the table (its value in ″/stop), which assumes the stops took equal times.".into());
    }
    let with_temperature = set
        .readings
        .iter()
        .filter(|r| r.temperature_celsius.is_some())
        .count();
    if with_temperature > 0 && with_temperature < set.readings.len() {
        notes.push(format!(
            "A temperature coefficient cannot be tested: only {with_temperature} of {} readings have a `temperature`.",
            set.readings.len()
        ));
    }
    let first_cycle = set.readings.first().map(|r| r.cycle);
    if set.readings.iter().all(|r| Some(r.cycle) == first_cycle) {
        notes.push("A zero jump between cycles (offset-step) cannot be tested with one cycle: repeat the cycle.".into());
    }
    let has = |d: Direction| set.readings.iter().any(|r| r.direction == d);
    if !(has(Direction::Cw) && has(Direction::Ccw)) {
        notes.push("A direction offset cannot be tested: the run has no cycle in the other direction (add a counter-clockwise cycle).".into());
    }
    notes
}

/// The note on a zero that wanders in a way no term expresses.
pub(super) fn wandering(ac: u32) -> String {
    format!(
        "The zero of autocollimator {ac} seems to wander: with the drift and jumps found, residuals still vary slowly in time or a drift differs between the run's two halves (a random walk, or a drift no smooth term expresses). A polynomial or a string of jumps fitted to such a wander can leave β and α worse than the base model, so the final model leaves this autocollimator's drift and jumps out; β and α carry the wander's effect, and the result is not certified. Shorter runs, more frequent closing readings or a more stable instrument would decide it."
    )
}

/// The note on a zero that jumped once too often.
pub(super) fn string_of_jumps(ac: u32, setup: Option<u32>) -> String {
    format!(
        "The zero of autocollimator {ac}{} seems to jump again and again: after {MAX_JUMPS_PER_STREAM} jumps a further one is significant. That is a slow variation that neither a smooth drift nor a zero per cycle expresses, not a series of events. The final model leaves its jumps out (a string of jumps can leave β and α worse than the base model); what remains is listed below.",
        setup.map_or(String::new(), |s| format!(" in setup {s}"))
    )
}

/// The plain words on a lack of fit left beside the `effects` effects found: a finding of
/// its own, not theirs (each was kept because, judged against one pure error with and
/// without it, it reduces the lack of fit: the search's gate).
pub(super) fn lack_of_fit_left(lof: &LackOfFit, effects: usize) -> String {
    let statistic = if lof.f_statistic.is_finite() {
        format!("F = {:.2}", lof.f_statistic)
    } else {
        "F infinite".to_string()
    };
    format!(
        "A lack of fit against pure error is left beside the {} found ({statistic} with {} and {} degrees of freedom, limit {:.2}): it is a finding of its own, not {}. Each effect was kept because it reduces the lack of fit, the fits with and without it judged against one pure error (the scatter within cells the effect leaves); what remains is structure between cells that no term of the search expresses, and the result is not adequate.",
        if effects == 1 { "effect" } else { "effects" },
        lof.dof_lack,
        lof.dof_pure,
        lof.limit,
        if effects == 1 {
            "the effect's"
        } else {
            "the effects'"
        },
    )
}

/// The plain words on a lack of fit of a self-calibration whose heads sit between the
/// positions: the model's band limit is one explanation the data cannot rule out.
pub(super) fn band_limit(positions: usize) -> String {
    format!(
        "Some heads sit between the {positions} positions, where the model reads the encoder error as band-limited (orders below {half}, the order {half} as a cosine on the grid). Harmonic orders of the encoder error at or above the band limit {half} cannot be fitted between the positions: they read differently there and are left as lack of fit, whatever effects are found (a run without them shows the same lack of fit). A run on a number of positions where every head sits on a position would tell it from the other causes.",
        half = positions / 2
    )
}

/// The scatter the autocollimators share at a stop, carried into u(α).
pub(super) fn stop_scatter(scatter: &super::stop_scatter::StopScatter, faces: usize) -> String {
    format!(
        "The readings of one stop share a scatter of {:.4}″ beyond the autocollimators' own noise ({:.4}″): F = {:.2} on {} and {} degrees of freedom, p = {:.1e}. It is the table's angle at the stop, not an autocollimator: a table that stops off its nominal angle over an encoder error of orders above the band limit N/2 = {} (an interpolation error, say), which {} positions cannot resolve, samples that error at another phase at every stop. The encoder error at the nominal angle was sampled by no stop, so u(α) carries this scatter: each u(α) is the fit's combined with {:.4}″. The model lacks this term and no data of these positions can attribute it, so the run is not certified as adequate; to resolve it, measure at more positions or stop the table at its nominal angle (its reported position within a small fraction of the encoder's signal period).",
        scatter.sigma_arcsec,
        scatter.noise_sigma_arcsec,
        scatter.f_statistic,
        scatter.dof_numerator,
        scatter.dof_denominator,
        scatter.p_value,
        faces / 2,
        faces,
        scatter.sigma_arcsec,
    )
}

/// The plain words on a search a limit ended: which limit, and that the model may lack
/// what was still significant.
pub(super) fn search_stopped(stop: super::SearchStop) -> String {
    let advice = match stop {
        super::SearchStop::MaxEffects { .. } => {
            "Many terms found one after another usually approximate something no single term expresses (a cycle logged wrongly, a wandering zero): look at the cycles and streams the terms name, or raise the limit to see what follows."
        }
        super::SearchStop::TooFewDegreesOfFreedom { .. } => {
            "Measure with more redundancy (more cycles, closing readings, a counter-clockwise cycle) so that further terms can be tested."
        }
        super::SearchStop::JumpsPerZero { .. } => {
            "A string of jumps is a slow variation no term expresses; see the note on the jumps."
        }
        super::SearchStop::AttemptsPerRound { .. } => {
            "The significant terms each failed to reduce the lack of fit: the residuals carry a structure no term of the catalogue expresses."
        }
    };
    format!(
        "Not certified: {}, so the final model may lack what was still significant. {advice}",
        stop.describe()
    )
}

/// The plain words on a lack of fit too small to be true ([`LackOfFit::too_good`]).
pub(super) fn lack_of_fit_too_good(lof: &LackOfFit) -> String {
    format!(
        "Not certified: the lack of fit is too small to be true (F = {:.3} with {} and {} degrees of freedom, below its lower {} % quantile {:.3}). The scatter within the cells (σ = {:.4}″ from the readings of one cell) is larger than the model's lack of fit can explain: a group of readings — a cycle logged wrongly (autocollimators exchanged, one stop late), an autocollimator whose noise rose — inflates it and hides what the model lacks. Look at the residuals cycle by cycle and autocollimator by autocollimator for the group that scatters most.",
        lof.f_statistic,
        lof.dof_lack,
        lof.dof_pure,
        100.0 * super::lack_of_fit::LOWER_TAIL_ALPHA,
        lof.lower_limit,
        lof.pure_error_sigma
    )
}
