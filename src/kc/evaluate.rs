//! The evaluation of a key comparison: the results lined up, the reference of every
//! quantity with the exclusions, the closed vector, the pilot's stability, and the
//! degrees of equivalence (the formulas are in the module's documentation, [`super`]).

use nalgebra::DMatrix;

use super::closed::{ClosedCovariance, ClosedFit};
use super::covariance;
use super::dof;
use super::input::{self, Aligned};
use super::monte_carlo;
use super::notes::{closing_notes, exclusions, pilot_decision_notes, quantity_notes, search_notes};
use super::pairs::pair_differences;
use super::reference::{self, Estimate, chi2_quantile_95};
use super::scaled::{Reference, Scaled};
use super::search;
use super::{
    DegreeOfEquivalence, KcError, KcOptions, KeyComparison, LabResult, PilotStability,
    ReferenceMethod, VectorTest, Wording,
};
use crate::results::Quantity;

/// Evaluates a key comparison of `labs` (at least 2), with the pilot's repeated results
/// `pilot` (none, or at least 2) for the artefact's stability; see the module's
/// documentation ([`crate::kc`]) for every formula.
///
/// # Errors
///
/// [`KcError`]: fewer than 2 laboratories or a single pilot repeat, a name given twice, a
/// result without rows of the quantity, with a face missing or with another number of
/// faces, a row without a positive standard uncertainty (named by file and line), no
/// encoder error position in every result.
///
/// # Examples
///
/// Three laboratories, a 4-face polygon, u = 0.1″ each:
///
/// ```
/// use polycal::kc::{evaluate, KcOptions, LabResult};
/// use polycal::results::{Quantity, ResultRow};
///
/// let lab = |name: &str, beta: [f64; 4]| {
///     let rows = (1..=4)
///         .map(|face| {
///             ResultRow::new(Quantity::PitchDeviation, face, beta[face as usize - 1])
///                 .with_expanded_u(0.2)
///                 .with_k(2.0)
///         })
///         .collect();
///     LabResult::from_rows(name, rows)
/// };
/// let labs = [
///     lab("A", [0.30, -0.10, -0.05, -0.15]),
///     lab("B", [0.36, -0.16, 0.00, -0.20]),
///     lab("C", [0.24, -0.04, -0.10, -0.10]),
/// ];
/// let kc = evaluate(&labs, &[], &KcOptions::new())?;
/// assert!((kc.reference[0] - 0.30).abs() < 1e-12); // the weighted mean of face 1
/// assert!((kc.reference_u[0] - 0.1 / 3f64.sqrt()).abs() < 1e-12);
/// assert!(kc.comparison_consistent);
/// let vector = kc.vector.as_ref().expect("pitch deviations are closed");
/// assert_eq!(vector.dof, 6); // (N − 1)(n − 1)
/// # Ok::<(), polycal::kc::KcError>(())
/// ```
pub fn evaluate(
    labs: &[LabResult],
    pilot: &[LabResult],
    options: &KcOptions,
) -> Result<KeyComparison, KcError> {
    if labs.len() < 2 {
        return Err(KcError::TooFewLabs(labs.len()));
    }
    if pilot.len() == 1 {
        return Err(KcError::TooFewRepeats(1));
    }
    let all: Vec<&LabResult> = labs.iter().chain(pilot).collect();
    for (i, result) in all.iter().enumerate() {
        if let Some(first) = all[..i].iter().find(|other| other.name == result.name) {
            return Err(KcError::DuplicateName {
                name: result.name.clone(),
                first: first.source.clone(),
                second: result.source.clone(),
            });
        }
    }
    let aligned = match options.quantity {
        Quantity::PitchDeviation => input::pitch(&all)?,
        Quantity::EncoderError => input::encoder_reported(&all, labs.len())?,
        Quantity::AngleBlock => super::blocks::blocks(&all, labs.len())?,
        other => return Err(KcError::Quantity(other)),
    };
    let aligned = super::names::with_look_alike_notes(&all, aligned);
    compared_enough(labs, &aligned, options.quantity)?;
    // Every laboratory's own covariance is checked, whether or not it ends in the
    // reference (pitch deviations only: encoder errors have no closed vector).
    let mut covariances = Vec::with_capacity(labs.len());
    for lab in labs {
        covariances.push(match (&lab.covariance, options.quantity) {
            (Some(_), Quantity::PitchDeviation) => {
                Some(covariance::checked(lab, aligned.index.len())?)
            }
            _ => None,
        });
    }
    evaluate_aligned(labs, pilot, options, aligned, &covariances)
}

/// Refuses laboratories `among` (closed results at different positions) whose positions
/// fall into groups that share none: results defined up to a constant cannot be put on one
/// reference across them.
fn connected(
    labs: &[LabResult],
    aligned: &Aligned,
    among: &[usize],
    quantity: Quantity,
) -> Result<(), KcError> {
    let (true, Some(measured)) = (aligned.closed, &aligned.measured) else {
        return Ok(());
    };
    let names: Vec<&str> = among.iter().map(|&r| labs[r].name.as_str()).collect();
    let rows: Vec<Vec<bool>> = among.iter().map(|&r| measured[r].clone()).collect();
    match super::positions::groups_apart(&rows, &names) {
        Some(groups) => Err(KcError::PositionsApart { quantity, groups }),
        None => Ok(()),
    }
}

/// Refuses a laboratory whose positions are compared too few times to be compared at all:
/// none of its angle blocks, or fewer than two of its encoder positions (each reported by
/// no other laboratory).
fn compared_enough(
    labs: &[LabResult],
    aligned: &Aligned,
    quantity: Quantity,
) -> Result<(), KcError> {
    let Some(measured) = &aligned.measured else {
        return Ok(());
    };
    let needed = if aligned.closed { 2 } else { 1 };
    let everyone: Vec<usize> = (0..labs.len()).collect();
    connected(labs, aligned, &everyone, quantity)?;
    for (lab, reported) in labs.iter().zip(measured) {
        let compared = reported.iter().filter(|m| **m).count();
        if compared < needed {
            return Err(KcError::LabNotCompared {
                lab: lab.name.clone(),
                file: lab.source.clone(),
                quantity,
                compared,
                needed,
            });
        }
    }
    Ok(())
}

/// The estimates of every quantity from the results `inside` that report it (values as
/// `scaled` holds them, u as given in `u`); a quantity none of them reports has a
/// reference of NaN, χ² 0 and ν 0.
fn estimates(
    scaled: &Scaled,
    u: &[Vec<f64>],
    inside: &[usize],
    method: ReferenceMethod,
    fitted: &[f64],
) -> Vec<Estimate> {
    // closed over different positions: on one level first (`closed::levelled`)
    let levelled = (scaled.closed && scaled.measured.is_some()).then(|| {
        super::positions::levelled(&scaled.values, |r, k| scaled.is_measured(r, k), fitted)
    });
    let values = levelled.as_ref().unwrap_or(&scaled.values);
    (0..scaled.positions)
        .map(|k| {
            let reporting: Vec<usize> = inside
                .iter()
                .copied()
                .filter(|&r| scaled.is_measured(r, k))
                .collect();
            if reporting.is_empty() {
                return Estimate {
                    reference: f64::NAN,
                    reference_u: f64::NAN,
                    chi2: 0.0,
                    dof: 0,
                    tau: 0.0,
                };
            }
            let x: Vec<f64> = reporting.iter().map(|&r| values[r][k]).collect();
            let u: Vec<f64> = reporting.iter().map(|&r| u[r][k]).collect();
            reference::estimate(&x, &u, method)
        })
        .collect()
}

/// A closed fit's test at 5 %, in arcseconds (`scale` undone).
pub(super) fn vector_test(fit: &ClosedFit, scale: f64) -> VectorTest {
    let critical = chi2_quantile_95(fit.dof);
    VectorTest {
        chi2: fit.chi2,
        dof: fit.dof,
        consistent: fit.chi2 <= critical,
        chi2_critical: critical,
        reference: fit.reference.iter().map(|r| r * scale).collect(),
    }
}

/// Evaluates the key comparison of the results lined up in `aligned` (the laboratories
/// `labs`, then the pilot's repeats `pilot`), each laboratory's own covariance checked in
/// `covariances`.
fn evaluate_aligned(
    labs: &[LabResult],
    pilot: &[LabResult],
    options: &KcOptions,
    aligned: Aligned,
    covariances: &[Option<DMatrix<f64>>],
) -> Result<KeyComparison, KcError> {
    let random_effects = options.method.is_random_effects();
    let wording = Wording::of(options.quantity).with_uneven(aligned.measured.is_some());
    let positions = aligned.index.len();
    let results = labs.len() + pilot.len();
    if aligned.closed && positions < 2 {
        return Err(KcError::TooFewPositions(positions));
    }
    let mut notes = aligned.notes.clone();
    let kept = kept_in_reference(labs, options)?;
    // The laboratories that may be in the reference (all but those the pilot keeps out).
    let candidates = reference_candidates(labs, options, &kept)?;
    // (a laboratory kept out of the reference may have been what linked the others)
    connected(labs, &aligned, &candidates, options.quantity)?;
    let mut scaled = Scaled::of(labs, &aligned, covariances);
    let scale = scaled.scale;
    notes.extend(quantity_notes(options.quantity, wording));
    let mut stated: Vec<ClosedCovariance> = (0..results)
        .map(|r| scaled.covariance(r, None))
        .collect::<Result<_, _>>()?;

    // The pilot's stability first: one test of the repeats' closed vectors. When it fails,
    // every laboratory's u includes u_stab from here on (the reference, every test, the
    // search), so that nobody is left out for the artefact's motion.
    let repeats: Vec<usize> = (labs.len()..results).collect();
    let (stability_u, mut pilot_report) = pilot_stability(&scaled, pilot, &repeats, &stated)?;
    if stability_u.iter().any(|s| *s > 0.0) {
        scaled.stability = stability_u.iter().map(|s| s / scale).collect();
        stated = (0..results)
            .map(|r| scaled.covariance(r, None))
            .collect::<Result<_, _>>()?;
    }
    let judged_u = scaled.judged_u();

    let all_fit = scaled.fit(&candidates, &stated).ok_or_else(not_fitted)?;
    let vector_all = vector_test(&all_fit, scale);

    let decision = decide_reference(&scaled, &stated, &candidates, &kept, &vector_all, options);
    let (search, inside, decided_consistent) =
        (decision.search, decision.inside, decision.consistent);
    let in_reference: Vec<bool> = (0..labs.len()).map(|r| inside.contains(&r)).collect();
    let mut excluded = Vec::new();
    if let Some(search) = &search {
        excluded = exclusions(
            labs,
            &candidates,
            search,
            &in_reference,
            &vector_all,
            wording,
        );
        notes.extend(search_notes(
            search,
            decided_consistent,
            &decision.withheld,
            wording,
        ));
    }
    let kept_out: Vec<usize> = (0..labs.len())
        .filter(|r| !candidates.contains(r))
        .collect();
    notes.extend(pilot_decision_notes(labs, &kept, &kept_out));

    // The reference: the closed GLS of the laboratories inside (with τ for DL).
    let (tau, widened) =
        dark_uncertainty(&scaled, &judged_u, &candidates, &stated, options, &all_fit)?;
    let final_fit = scaled.fit(&inside, &widened).ok_or_else(not_fitted)?;
    let vector = vector_test(&final_fit, scale);
    let found = estimates(
        &scaled,
        &judged_u,
        &inside,
        options.method,
        &final_fit.reference,
    );

    // Degrees of equivalence against the closed reference: Σ_k d_ik = 0.
    let reference = Reference {
        fit: &final_fit,
        widened: &widened,
    };
    let degrees_of_equivalence =
        degrees_of_equivalence(&scaled, pilot, &in_reference, &reference, &mut pilot_report);
    let pairs = pair_differences(&scaled, &widened);
    notes.extend(closing_notes(
        labs,
        covariances,
        &inside,
        options.method,
        positions,
        wording,
    ));

    let chi2_critical: Vec<f64> = found.iter().map(|e| chi2_quantile_95(e.dof)).collect();
    let consistent: Vec<bool> = found
        .iter()
        .zip(&chi2_critical)
        .map(|(e, q)| e.chi2 <= *q)
        .collect();
    let comparison_consistent = if random_effects {
        vector_all.consistent
    } else {
        decided_consistent && vector.consistent
    };
    let mut comparison = KeyComparison {
        quantity: options.quantity,
        method: options.method,
        index: aligned.index.clone(),
        angle_deg: aligned.angle_deg.clone(),
        nominal_deg: aligned.nominal_deg.clone(),
        labs: labs.iter().map(|l| l.name.clone()).collect(),
        reference: final_fit.reference.iter().map(|r| r * scale).collect(),
        reference_u: final_fit
            .reference_variance
            .iter()
            .map(|v| v.sqrt() * scale)
            .collect(),
        chi2: found.iter().map(|e| e.chi2).collect(),
        chi2_dof: found.iter().map(|e| e.dof).collect(),
        chi2_critical,
        consistent,
        vector_all: Some(vector_all),
        vector: Some(vector),
        search,
        kept: kept.iter().map(|&r| labs[r].name.clone()).collect(),
        not_in_reference: kept_out.iter().map(|&r| labs[r].name.clone()).collect(),
        excluded,
        tau: tau.iter().map(|t| t * scale).collect(),
        degrees_of_equivalence,
        pairs,
        pilot: pilot_report,
        link: None,
        comparison_consistent,
        withheld: decision
            .withheld
            .iter()
            .map(|&r| labs[r].name.clone())
            .collect(),
        notes,
    };
    if let Some(statement) = comparison.pilot_statement()
        && let Some(pilot) = comparison.pilot.as_mut()
    {
        pilot.statement = statement;
    }
    let fitted = Fitted {
        reference: &final_fit.reference,
        judged_u: &judged_u,
        tau: &tau,
        inside: &inside,
    };
    beyond_the_formulas(
        &mut comparison,
        options,
        &scaled,
        &fitted,
        &aligned,
        pilot.len(),
    )?;
    Ok(comparison)
}

/// The reference as fitted, in the comparison's scaled units: what the Monte Carlo draws
/// start from and what ν_eff is worked out from.
struct Fitted<'a> {
    /// The reference per quantity.
    reference: &'a [f64],
    /// Every result's u with the pilot's u_stab in it.
    judged_u: &'a [Vec<f64>],
    /// τ per quantity (0 for the weighted mean).
    tau: &'a [f64],
    /// The laboratories in the reference.
    inside: &'a [usize],
}

/// Every U by Monte Carlo when asked, else with the Welch–Satterthwaite ν_eff when some
/// laboratory states the degrees of freedom of its u; as the formulas gave them otherwise.
fn beyond_the_formulas(
    comparison: &mut KeyComparison,
    options: &KcOptions,
    scaled: &Scaled,
    fitted: &Fitted,
    aligned: &Aligned,
    repeats: usize,
) -> Result<(), KcError> {
    match options.monte_carlo {
        Some(draws) => {
            let model = monte_carlo::Model {
                reference: fitted.reference,
                u: fitted.judged_u,
                tau: fitted.tau,
                inside: fitted.inside,
                method: options.method,
                closed: scaled.closed,
                measured: scaled.measured.as_deref(),
                labs: scaled.labs.len(),
            };
            monte_carlo::apply(comparison, &model, draws, scaled.covariances, scaled.scale)?;
        }
        None if aligned.dof.iter().flatten().any(|d| d.is_finite()) => {
            let sources = dof::Sources {
                u: &scaled.u,
                dof: &aligned.dof,
                stability: &scaled.stability,
                stability_dof: repeats.saturating_sub(1) as f64,
                tau: fitted.tau,
                inside: fitted.inside,
                measured: scaled.measured.as_deref(),
            };
            dof::apply(comparison, &sources);
        }
        None => {}
    }
    Ok(())
}

/// τ per quantity from the `candidates` (0 for the weighted mean) and every result's
/// covariance widened by it (`stated` as it is for the weighted mean).
fn dark_uncertainty(
    scaled: &Scaled,
    judged_u: &[Vec<f64>],
    candidates: &[usize],
    stated: &[ClosedCovariance],
    options: &KcOptions,
    fit: &ClosedFit,
) -> Result<(Vec<f64>, Vec<ClosedCovariance>), KcError> {
    if !options.method.is_random_effects() {
        return Ok((vec![0.0; scaled.positions], stated.to_vec()));
    }
    let tau: Vec<f64> = estimates(scaled, judged_u, candidates, options.method, &fit.reference)
        .iter()
        .map(|e| e.tau)
        .collect();
    let widened = (0..stated.len())
        .map(|r| scaled.covariance(r, Some(&tau)))
        .collect::<Result<_, _>>()?;
    Ok((tau, widened))
}

/// Every laboratory's degree of equivalence against `reference` (returned) and every
/// pilot's repeat's (into `pilot_report`), the repeats never in the reference.
fn degrees_of_equivalence(
    scaled: &Scaled,
    pilot: &[LabResult],
    in_reference: &[bool],
    reference: &Reference,
    pilot_report: &mut Option<PilotStability>,
) -> Vec<DegreeOfEquivalence> {
    let labs = scaled.labs;
    if let Some(report) = pilot_report.as_mut() {
        report.degrees_of_equivalence = (labs.len()..labs.len() + pilot.len())
            .map(|r| scaled.degree_of_equivalence(r, false, all_name(labs, pilot, r), reference))
            .collect();
    }
    (0..labs.len())
        .map(|r| {
            let lab = labs[r].name.clone();
            scaled.degree_of_equivalence(r, in_reference[r], lab, reference)
        })
        .collect()
}

/// The laboratories the pilot keeps in the reference whatever the tests say (indices,
/// sorted, once each).
fn kept_in_reference(labs: &[LabResult], options: &KcOptions) -> Result<Vec<usize>, KcError> {
    let mut kept = Vec::new();
    for name in &options.keep {
        match labs.iter().position(|l| &l.name == name) {
            Some(r) => kept.push(r),
            None => return Err(KcError::UnknownKeep(name.clone())),
        }
    }
    kept.sort_unstable();
    kept.dedup();
    Ok(kept)
}

/// The laboratories that may be in the reference: all but those the pilot keeps out
/// ([`KcOptions::with_not_in_reference`]), at least 2, none of them also held in.
fn reference_candidates(
    labs: &[LabResult],
    options: &KcOptions,
    kept: &[usize],
) -> Result<Vec<usize>, KcError> {
    let mut out = Vec::new();
    for name in &options.not_in_reference {
        match labs.iter().position(|l| &l.name == name) {
            Some(r) if kept.contains(&r) => {
                return Err(KcError::KeptAndKeptOut(name.clone()));
            }
            Some(r) => out.push(r),
            None => return Err(KcError::UnknownNotInReference(name.clone())),
        }
    }
    let candidates: Vec<usize> = (0..labs.len()).filter(|r| !out.contains(r)).collect();
    if candidates.len() < 2 {
        return Err(KcError::TooFewInReference(candidates.len()));
    }
    Ok(candidates)
}

/// The error of a closed vector that cannot be fitted.
fn not_fitted() -> KcError {
    KcError::NotComputable(
        "the closed vector of the laboratories cannot be fitted (a covariance singular on the \
         closed subspace, or numbers out of range)"
            .to_string(),
    )
}

/// What the one decision at 5 % and the search after it decided.
struct Decision {
    /// The search made (weighted mean, when the closed vector of every laboratory failed).
    search: Option<search::SubsetSearch>,
    /// The laboratories in the reference (indices, ascending).
    inside: Vec<usize>,
    /// Whether the comparison is decided consistent.
    consistent: bool,
    /// The laboratories the subset that passed would have left out, when they were more
    /// than half: none is left out.
    withheld: Vec<usize>,
}

/// The one decision at 5 %, then (weighted mean, when asked) the largest subset that
/// passes — unless it leaves out more than half of the laboratories, when nobody is left
/// out and the comparison is not consistent.
fn decide_reference(
    scaled: &Scaled,
    stated: &[ClosedCovariance],
    candidates: &[usize],
    kept: &[usize],
    vector_all: &VectorTest,
    options: &KcOptions,
) -> Decision {
    let labs = scaled.labs;
    let random_effects = options.method.is_random_effects();
    let mut decision = Decision {
        search: None,
        inside: candidates.to_vec(),
        consistent: vector_all.consistent,
        withheld: Vec::new(),
    };
    if random_effects || !options.largest_consistent_subset || vector_all.consistent {
        return decision;
    }
    // The search is over the candidates, numbered 0 … m − 1 among themselves.
    let names: Vec<String> = candidates.iter().map(|&r| labs[r].name.clone()).collect();
    let kept_among: Vec<usize> = (0..candidates.len())
        .filter(|&i| kept.contains(&candidates[i]))
        .collect();
    let found = search::largest_consistent(&names, &kept_among, &|set| {
        let set: Vec<usize> = set.iter().map(|&i| candidates[i]).collect();
        scaled.fit(&set, stated)
    });
    decision.search = Some(found.search);
    if found.passed {
        let inside: Vec<usize> = found.inside.iter().map(|&i| candidates[i]).collect();
        let outside: Vec<usize> = candidates
            .iter()
            .copied()
            .filter(|r| !inside.contains(r))
            .collect();
        if 2 * outside.len() > candidates.len() {
            decision.withheld = outside;
        } else {
            decision.inside = inside;
            decision.consistent = true;
        }
    }
    decision
}

/// The pilot's stability: one test of the closed vectors of the `repeats` (indices of the
/// results), with each quantity's mean, spread and χ². Returns the stability standard
/// uncertainty per quantity in arcsec (the repeats' spread when their closed vector
/// fails, else 0) and the report (`None` without repeats).
fn pilot_stability(
    scaled: &Scaled,
    pilot: &[LabResult],
    repeats: &[usize],
    stated: &[ClosedCovariance],
) -> Result<(Vec<f64>, Option<PilotStability>), KcError> {
    let positions = scaled.positions;
    let scale = scaled.scale;
    let mut stability_u = vec![0.0; positions];
    if repeats.is_empty() {
        return Ok((stability_u, None));
    }
    let m = repeats.len();
    let (mut mean, mut spread, mut chi2, mut significant) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for k in 0..positions {
        let y: Vec<f64> = repeats.iter().map(|&r| scaled.values[r][k]).collect();
        let uk: Vec<f64> = repeats.iter().map(|&r| scaled.u[r][k]).collect();
        let plain = y.iter().sum::<f64>() / m as f64;
        let s = (y.iter().map(|y| (y - plain).powi(2)).sum::<f64>() / (m - 1) as f64).sqrt();
        let (_, _, c) = reference::weighted_mean(&y, &uk);
        mean.push(plain * scale);
        spread.push(s * scale);
        chi2.push(c);
        significant.push(c > chi2_quantile_95(m - 1));
    }
    let pilot_fit = scaled.fit(repeats, stated).ok_or_else(not_fitted)?;
    let pilot_vector = vector_test(&pilot_fit, scale);
    if !pilot_vector.consistent {
        // stated by `KeyComparison::pilot_statement`
        stability_u.clone_from(&spread);
    }
    let report = PilotStability {
        repeats: pilot.iter().map(|p| p.name.clone()).collect(),
        mean,
        spread,
        chi2,
        chi2_dof: m - 1,
        significant,
        stability_u: stability_u.clone(),
        vector: Some(pilot_vector),
        degrees_of_equivalence: Vec::new(),
        statement: String::new(),
    };
    Ok((stability_u, Some(report)))
}

/// The name of result `r` of the laboratories followed by the pilot's repeats.
fn all_name(labs: &[LabResult], pilot: &[LabResult], r: usize) -> String {
    labs.iter()
        .chain(pilot)
        .nth(r)
        .map_or_else(String::new, |l| l.name.clone())
}
