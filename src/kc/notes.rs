//! What a key comparison's evaluation says in words beside its numbers: the notes on the
//! quantity compared (encoder errors up to a constant, angle blocks each on its own), the
//! search for the largest consistent subset and why each laboratory was left out, the
//! pilot's decisions, the covariances used and the random-effects methods.

use nalgebra::DMatrix;

use super::search::{self, SearchMethod};
use super::{Exclusion, LabResult, ReferenceMethod, VectorTest, Wording};
use crate::results::Quantity;

/// The notes on the compared quantity: encoder errors defined up to a constant (and
/// reported at different positions), angle blocks each on its own.
pub(super) fn quantity_notes(quantity: Quantity, wording: Wording) -> Vec<String> {
    match quantity {
        Quantity::EncoderError if wording.is_uneven() => {
            vec![ENCODER_NOTE.to_string(), ENCODER_SUBSETS_NOTE.to_string()]
        }
        Quantity::EncoderError => vec![ENCODER_NOTE.to_string()],
        Quantity::AngleBlock => vec![BLOCKS_NOTE.to_string()],
        _ => Vec::new(),
    }
}

/// The names of `set` joined with commas.
pub(super) fn joined(labs: &[LabResult], set: &[usize]) -> String {
    set.iter()
        .map(|&r| labs[r].name.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The notes on the pilot's decisions: the laboratories held in the reference (`kept`)
/// and those kept out of it (`kept_out`), by name.
pub(super) fn pilot_decision_notes(
    labs: &[LabResult],
    kept: &[usize],
    kept_out: &[usize],
) -> Vec<String> {
    let mut notes = Vec::new();
    if !kept.is_empty() {
        notes.push(format!(
            "kept in the reference whatever the tests say, as the pilot decided: {}",
            joined(labs, kept)
        ));
    }
    if !kept_out.is_empty() {
        notes.push(format!(
            "kept out of the reference, as the pilot decided, and given degrees of equivalence \
             against it (in_reference false): {}; the one test at 5 % and the search are of \
             the other laboratories",
            joined(labs, kept_out)
        ));
    }
    notes
}

/// The note on encoder errors, compared less their mean.
const ENCODER_NOTE: &str = "encoder errors are defined up to a constant: each result's mean over the compared \
     positions is taken out before it is compared (so a laboratory with another zero \
     convention is not left out), and each is taken as closed with \
     V = N/(N − 1)·P·diag(u²)·P";

/// The note on encoder errors the laboratories report at different positions.
const ENCODER_SUBSETS_NOTE: &str = "the laboratories report different encoder positions: each is \
     compared on those it reports — its result closed over them (N_i positions, V_i = \
     N_i/(N_i − 1)·P·diag(u²)·P), the reference the GLS of what is there, ν = Σ N_i − n − \
     (N − 1) — and its degree of equivalence is closed over its positions, U(d_i) = \
     2·√(v_i ∓ diag(P·C·P)) with C the reference's covariance on them (null in the JSON where \
     it did not measure a position)";

/// The note on angle blocks, compared each on its own.
const BLOCKS_NOTE: &str = "angle blocks are single angles, not a closed vector: each block's reference is \
     the weighted mean of the laboratories in the reference that report it, and the blocks' \
     consistency is one test at 5 %, χ² = Σ_b Σ_i (x_ib − x_ref,b)²/u_ib² with \
     ν = Σ_b (n_b − 1), n_b the laboratories reporting block b; a laboratory that did not \
     measure a block is compared on the blocks it did (no degree of equivalence there, null \
     in the JSON)";

/// Why each of the `candidates` outside the reference was left out by the subset `search`.
pub(super) fn exclusions(
    labs: &[LabResult],
    candidates: &[usize],
    search: &search::SubsetSearch,
    in_reference: &[bool],
    vector_all: &VectorTest,
    wording: Wording,
) -> Vec<Exclusion> {
    let uneven = wording.is_uneven();
    let whole = wording.whole();
    let mut excluded = Vec::new();
    let last = search.steps.last();
    for &r in candidates.iter().filter(|r| !in_reference[**r]) {
        let Some(chosen) = last else { break };
        let before = search
            .steps
            .iter()
            .rev()
            .nth(1)
            .map(|s| {
                format!(
                    "; the best subset of {} laboratories ({}) fails, χ² = {} > {:.3}",
                    s.size,
                    s.best.join(", "),
                    super::chi2_text(s.chi2, 3),
                    s.chi2_critical
                )
            })
            .unwrap_or_default();
        excluded.push(Exclusion {
            lab: labs[r].name.clone(),
            reason: format!(
                "left out of the whole comparison: the {whole} of all {} laboratories \
                 fails (χ² = {} > χ²_0.95({}) = {:.3}); the largest subset that passes \
                 is {} ({} laboratories, χ² = {} ≤ χ²_0.95({}) = {:.3}, {}){before}",
                candidates.len(),
                super::chi2_text(vector_all.chi2, 3),
                vector_all.dof,
                vector_all.chi2_critical,
                chosen.best.join(", "),
                chosen.size,
                super::chi2_text(chosen.chi2, 3),
                chosen.dof,
                chosen.chi2_critical,
                if uneven {
                    "the most consistent of its size: the largest p-value, the laboratories \
                     reporting different positions"
                } else {
                    "the smallest χ² of its size"
                },
            ),
        });
    }
    excluded
}

/// The notes on how the subset `search` went, on its failing when no subset passed, and
/// on the laboratories `withheld` (more than half) that were not left out.
pub(super) fn search_notes(
    search: &search::SubsetSearch,
    decided_consistent: bool,
    withheld: &[usize],
    wording: Wording,
) -> Vec<String> {
    let uneven = wording.is_uneven();
    let mut notes = vec![match search.method {
        SearchMethod::Exhaustive => format!(
            "the largest consistent subset was found by trying every subset of each size \
             ({} in all), ties broken by the smaller χ²{}",
            search.subsets_tested,
            if uneven {
                " — or, the laboratories reporting different positions, subsets of one size \
                 having different ν, by the larger p-value P(χ²_ν > χ²)"
            } else {
                ""
            }
        ),
        SearchMethod::Greedy => format!(
            "the subsets were too many to try every one (more than {}): from the size where \
             they were, the laboratory whose removal lowers χ² most was left out one at a \
             time; a larger consistent subset may exist",
            search::EXHAUSTIVE_SUBSETS
        ),
    }];
    if !withheld.is_empty() {
        notes.push(format!(
            "the largest subset that passes would leave out {} laboratories, more than half: \
             nobody is left out, and the comparison is not consistent. When most laboratories \
             disagree with the others beyond their stated uncertainties, the stated \
             uncertainties look too small for the spread of the results (or the artefact \
             changed): a random-effects reference (dersimonian-laird) takes that spread into \
             its dark uncertainty τ instead of leaving laboratories out",
            withheld.len()
        ));
    } else if !decided_consistent {
        notes.push(format!(
            "no subset of the laboratories passes the {}'s test: every laboratory is kept in \
             the reference, and the comparison is not consistent",
            wording.whole()
        ));
    }
    notes
}

/// The notes on the covariances the closed vector used, on the random-effects `method`,
/// and on the one decision at 5 %.
pub(super) fn closing_notes(
    labs: &[LabResult],
    covariances: &[Option<DMatrix<f64>>],
    inside: &[usize],
    method: ReferenceMethod,
    positions: usize,
    wording: Wording,
) -> Vec<String> {
    let whole = wording.whole();
    let mut notes = Vec::new();
    let with_own: Vec<&str> = inside
        .iter()
        .filter(|&&r| covariances[r].is_some())
        .map(|&r| labs[r].name.as_str())
        .collect();
    if !with_own.is_empty() {
        notes.push(format!(
            "the closed vector uses the laboratories' own covariances of their pitch deviations \
             for {}; the others are taken as closed with V = N/(N − 1)·P·diag(u²)·P",
            with_own.join(", ")
        ));
    }
    if method.is_random_effects() {
        let estimator = if method == ReferenceMethod::MandelPaule {
            "τ² such that the χ² about the mean with the widened uncertainties equals n − 1"
        } else {
            "the method of moments from χ² about the weighted mean"
        };
        notes.push(format!(
            "{}: nobody is left out. τ is the dark uncertainty: the spread of the \
             laboratories' results on each quantity beyond their stated uncertainties \
             ({estimator}), added to every laboratory's variance there, so that it enters u_ref \
             and every U(d_i). The verdict is the test of τ = 0 for the whole comparison (the \
             {whole} of every laboratory, vector_all): not consistent means the \
             laboratories differ beyond their stated uncertainties, and τ carries that into \
             the reference",
            method.title()
        ));
    }
    notes.push(format!(
        "the comparison is decided by one test at 5 %, the {}; the χ² of each \
         of the {positions} quantities is information (by chance about 1 in 20 fails in a \
         consistent comparison)",
        wording.whole_chi2()
    ));
    notes
}
