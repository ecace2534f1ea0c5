//! Which quantities a key comparison compares, and which of them every result carries:
//! what a pilot's whole comparison evaluates, one comparison per quantity
//! (docs/FORMAT.md §12, "Every quantity the files share").

use super::{KcError, LabResult};
use crate::results::Quantity;

/// The quantities a key comparison compares, in the order a whole comparison evaluates
/// and writes them. Every list of compared quantities (the names accepted,
/// [`shared_quantities`], the messages) is this one.
pub const COMPARED_QUANTITIES: [Quantity; 3] = [
    Quantity::PitchDeviation,
    Quantity::EncoderError,
    Quantity::AngleBlock,
];

/// The compared quantities' names in words: `pitch_deviation, encoder_error or angle_block`.
pub(crate) fn compared_names() -> String {
    let names: Vec<&str> = COMPARED_QUANTITIES.iter().map(|q| q.name()).collect();
    match names.split_last() {
        Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
        _ => names.concat(),
    }
}

/// How many results lacking a quantity a message names before it says how many more.
const NAMED_AT_MOST: usize = 3;

/// The compared quantities ([`COMPARED_QUANTITIES`], in its order) of which every
/// laboratory's result and every one of the pilot's repeats has at least one row: the
/// comparisons a pilot's whole comparison evaluates, each with [`super::evaluate`].
///
/// # Errors
///
/// [`KcError::NoSharedQuantity`] when no compared quantity is in every result, naming
/// per quantity the results that lack it.
///
/// ```
/// use polycal::kc::{LabResult, shared_quantities};
/// use polycal::results::{Quantity, ResultRow};
/// let row = |quantity, index| ResultRow::new(quantity, index, 0.0).with_u(0.1);
/// let a = LabResult::from_rows("A", vec![
///     row(Quantity::PitchDeviation, 1),
///     row(Quantity::EncoderError, 0),
/// ]);
/// let b = LabResult::from_rows("B", vec![row(Quantity::EncoderError, 0)]);
/// assert_eq!(shared_quantities(&[a.clone(), a.clone()], &[])?,
///            [Quantity::PitchDeviation, Quantity::EncoderError]);
/// assert_eq!(shared_quantities(&[a, b.clone()], &[])?, [Quantity::EncoderError]);
/// let c = LabResult::from_rows("C", vec![row(Quantity::PitchDeviation, 1)]);
/// assert!(shared_quantities(&[b, c], &[]).is_err());
/// # Ok::<(), polycal::kc::KcError>(())
/// ```
pub fn shared_quantities(
    labs: &[LabResult],
    pilot: &[LabResult],
) -> Result<Vec<Quantity>, KcError> {
    let has = |result: &LabResult, quantity: Quantity| {
        result.rows.iter().any(|row| row.quantity == quantity)
    };
    let shared: Vec<Quantity> = COMPARED_QUANTITIES
        .into_iter()
        .filter(|&q| labs.iter().chain(pilot).all(|result| has(result, q)))
        .collect();
    if !shared.is_empty() {
        return Ok(shared);
    }
    let lacking = COMPARED_QUANTITIES
        .into_iter()
        .map(|q| {
            let results: Vec<String> = labs
                .iter()
                .chain(pilot)
                .filter(|result| !has(result, q))
                .map(|result| format!("{} (laboratory {})", result.source, result.name))
                .collect();
            let more = results.len().saturating_sub(NAMED_AT_MOST);
            let mut named = results[..results.len().min(NAMED_AT_MOST)].join(", ");
            if more > 0 {
                named.push_str(&format!(" and {more} more"));
            }
            format!("no {q} rows in {named}")
        })
        .collect();
    Err(KcError::NoSharedQuantity {
        quantities: compared_names(),
        lacking,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::results::ResultRow;

    fn lab(name: &str, quantities: &[Quantity]) -> LabResult {
        let rows = quantities
            .iter()
            .map(|&q| ResultRow::new(q, 1, 0.0).with_u(0.1))
            .collect();
        LabResult::from_rows(name, rows)
    }

    #[test]
    fn in_the_lists_order_whatever_the_rows_order() {
        use Quantity::{EncoderError, FaceDeviation, PitchDeviation};
        let labs = [
            lab("A", &[EncoderError, FaceDeviation, PitchDeviation]),
            lab("B", &[PitchDeviation, EncoderError]),
        ];
        assert_eq!(
            shared_quantities(&labs, &[]).unwrap(),
            [PitchDeviation, EncoderError]
        );
        // a pilot's repeat without encoder errors: the pitch deviations alone
        let pilot = [
            lab("start", &[PitchDeviation]),
            lab("end", &[PitchDeviation]),
        ];
        assert_eq!(shared_quantities(&labs, &pilot).unwrap(), [PitchDeviation]);
    }

    #[test]
    fn none_shared_names_per_quantity_the_results_lacking_it() {
        use Quantity::{EncoderError, FaceDeviation, PitchDeviation};
        let mut labs = vec![lab("A", &[PitchDeviation]), lab("B", &[EncoderError])];
        labs.extend((0..4).map(|i| lab(&format!("F{i}"), &[FaceDeviation])));
        let message = shared_quantities(&labs, &[]).unwrap_err().to_string();
        assert_eq!(
            message,
            "no quantity a key comparison compares (pitch_deviation, encoder_error or \
             angle_block) has rows in every result: no pitch_deviation rows in B (laboratory B), \
             F0 (laboratory F0), F1 (laboratory F1) and 2 more; no encoder_error rows in A \
             (laboratory A), F0 (laboratory F0), F1 (laboratory F1) and 2 more; no angle_block \
             rows in A (laboratory A), B (laboratory B), F0 (laboratory F0) and 3 more"
        );
    }

    #[test]
    fn the_names_in_words_follow_the_list() {
        assert_eq!(
            compared_names(),
            "pitch_deviation, encoder_error or angle_block"
        );
        for q in COMPARED_QUANTITIES {
            assert_eq!(super::super::compared_quantity(q.name()), Ok(q));
        }
    }
}
