//! The evaluation of a key comparison: the results lined up, the reference of every
//! quantity with the exclusions, the closed vector, the pilot's stability, and the
//! degrees of equivalence (the formulas are in the module's documentation, [`super`]).

use nalgebra::DMatrix;

use super::covariance;
use super::input::{self, Aligned};
use super::reference::{self, Estimate, chi2_quantile_95};
use super::{
    DegreeOfEquivalence, Exclusion, KcError, KcOptions, KeyComparison, LabResult, PairDifference,
    PilotStability, ReferenceMethod, VectorTest,
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
        Quantity::EncoderError => input::encoder(&all)?,
        other => return Err(KcError::Quantity(other)),
    };
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
    Ok(evaluate_aligned(
        labs,
        pilot,
        options,
        aligned,
        &covariances,
    ))
}

/// The estimates of every quantity from the laboratories `inside`.
fn estimates(aligned: &Aligned, inside: &[usize], random_effects: bool) -> Vec<Estimate> {
    (0..aligned.index.len())
        .map(|k| {
            let x: Vec<f64> = inside.iter().map(|&r| aligned.values[r][k]).collect();
            let u: Vec<f64> = inside.iter().map(|&r| aligned.u[r][k]).collect();
            reference::estimate(&x, &u, random_effects)
        })
        .collect()
}

fn evaluate_aligned(
    labs: &[LabResult],
    pilot: &[LabResult],
    options: &KcOptions,
    aligned: Aligned,
    covariances: &[Option<DMatrix<f64>>],
) -> KeyComparison {
    let random_effects = options.method == ReferenceMethod::DersimonianLaird;
    let positions = aligned.index.len();
    let mut inside: Vec<usize> = (0..labs.len()).collect();
    let mut excluded = Vec::new();
    let mut notes = aligned.notes.clone();
    let mut found = estimates(&aligned, &inside, random_effects);
    let fails = |e: &Estimate| e.chi2 > chi2_quantile_95(e.dof);
    // The largest consistent subset: the worst laboratory of the failing quantities out,
    // one at a time, for the whole comparison.
    while !random_effects && options.largest_consistent_subset && inside.len() > 2 {
        let mut worst: Option<(f64, usize, usize)> = None; // (|d|/u(d), lab, position)
        for (k, e) in found.iter().enumerate().filter(|(_, e)| fails(e)) {
            for &r in &inside {
                let u = aligned.u[r][k];
                let z = (aligned.values[r][k] - e.reference).abs()
                    / (u * u - e.reference_u * e.reference_u).sqrt();
                if worst.is_none_or(|(best, _, _)| z > best) {
                    worst = Some((z, r, k));
                }
            }
        }
        let Some((z, r, k)) = worst else { break };
        let e = found[k];
        let critical = chi2_quantile_95(e.dof);
        excluded.push(Exclusion {
            lab: labs[r].name.clone(),
            reason: format!(
                "{} {}: χ² = {:.3} > χ²_0.95({}) = {:.3} with {} laboratories; its |d|/u(d) = {:.3} \
                 there is the largest of the failing quantities; left out of the whole comparison",
                options.quantity,
                aligned.index[k],
                e.chi2,
                e.dof,
                critical,
                inside.len(),
                z
            ),
            index: aligned.index[k],
            normalised_deviation: z,
            chi2_before: e.chi2,
            chi2_critical: critical,
        });
        inside.retain(|&i| i != r);
        found = estimates(&aligned, &inside, random_effects);
    }
    let in_reference: Vec<bool> = (0..labs.len()).map(|r| inside.contains(&r)).collect();

    // The pilot's stability.
    let repeats: Vec<usize> = (labs.len()..labs.len() + pilot.len()).collect();
    let mut stability_u = vec![0.0; positions];
    let mut pilot_report = None;
    if !repeats.is_empty() {
        let m = repeats.len();
        let (mut mean, mut spread, mut chi2, mut significant) =
            (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for (k, stab) in stability_u.iter_mut().enumerate() {
            let y: Vec<f64> = repeats.iter().map(|&r| aligned.values[r][k]).collect();
            let u: Vec<f64> = repeats.iter().map(|&r| aligned.u[r][k]).collect();
            let plain = y.iter().sum::<f64>() / m as f64;
            let s = (y.iter().map(|y| (y - plain).powi(2)).sum::<f64>() / (m - 1) as f64).sqrt();
            let (_, _, c) = reference::weighted_mean(&y, &u);
            let signal = c > chi2_quantile_95(m - 1);
            if signal {
                *stab = s;
            }
            mean.push(plain);
            spread.push(s);
            chi2.push(c);
            significant.push(signal);
        }
        let flagged: Vec<String> = significant
            .iter()
            .zip(&aligned.index)
            .filter(|(s, _)| **s)
            .map(|(_, i)| i.to_string())
            .collect();
        if !flagged.is_empty() {
            notes.push(format!(
                "the pilot's repeats differ beyond their uncertainties at {} {} (χ² about their \
                 weighted mean > χ²_0.95({})): their sample standard deviation is added in \
                 quadrature to u_ref and to every u(d_i) there",
                options.quantity,
                flagged.join(", "),
                m - 1
            ));
        }
        pilot_report = Some(PilotStability {
            repeats: pilot.iter().map(|p| p.name.clone()).collect(),
            mean,
            spread,
            chi2,
            chi2_dof: m - 1,
            significant,
            stability_u: stability_u.clone(),
            degrees_of_equivalence: Vec::new(),
        });
    }

    let doe = |r: usize, inside_reference: bool| {
        let (mut d, mut expanded_u) = (Vec::new(), Vec::new());
        for (k, e) in found.iter().enumerate() {
            let (u, tau) = (aligned.u[r][k], e.tau);
            let sign = if inside_reference { -1.0 } else { 1.0 };
            let variance = u * u
                + tau * tau
                + sign * e.reference_u * e.reference_u
                + stability_u[k] * stability_u[k];
            d.push(aligned.values[r][k] - e.reference);
            expanded_u.push(2.0 * variance.sqrt());
        }
        (d, expanded_u)
    };
    let degrees_of_equivalence = (0..labs.len())
        .map(|r| {
            let (d, expanded_u) = doe(r, in_reference[r]);
            DegreeOfEquivalence {
                lab: labs[r].name.clone(),
                d,
                expanded_u,
                in_reference: in_reference[r],
            }
        })
        .collect();
    if let Some(report) = pilot_report.as_mut() {
        report.degrees_of_equivalence = repeats
            .iter()
            .map(|&r| {
                let (d, expanded_u) = doe(r, false);
                DegreeOfEquivalence {
                    lab: all_name(labs, pilot, r),
                    d,
                    expanded_u,
                    in_reference: false,
                }
            })
            .collect();
    }
    let mut pairs = Vec::new();
    for a in 0..labs.len() {
        for b in a + 1..labs.len() {
            pairs.push(PairDifference {
                a: labs[a].name.clone(),
                b: labs[b].name.clone(),
                d: (0..positions)
                    .map(|k| aligned.values[a][k] - aligned.values[b][k])
                    .collect(),
                expanded_u: (0..positions)
                    .map(|k| 2.0 * aligned.u[a][k].hypot(aligned.u[b][k]))
                    .collect(),
            });
        }
    }

    let own: Vec<&str> = inside
        .iter()
        .filter(|&&r| covariances[r].is_some())
        .map(|&r| labs[r].name.as_str())
        .collect();
    if options.quantity == Quantity::PitchDeviation && !own.is_empty() {
        notes.push(format!(
            "the closed vector uses the laboratories' own covariances of their pitch deviations \
             for {}; the others are taken as closed with V = N/(N − 1)·P·diag(u²)·P",
            own.join(", ")
        ));
    }
    let vector = if options.quantity == Quantity::PitchDeviation {
        let x: Vec<&[f64]> = inside
            .iter()
            .map(|&r| aligned.values[r].as_slice())
            .collect();
        let v: Vec<DMatrix<f64>> = inside
            .iter()
            .map(|&r| {
                covariances[r]
                    .clone()
                    .unwrap_or_else(|| reference::closed_covariance(&aligned.u[r]))
            })
            .collect();
        reference::closed_vector(&x, &v).map(|fit| {
            let critical = chi2_quantile_95(fit.dof);
            VectorTest {
                chi2: fit.chi2,
                dof: fit.dof,
                consistent: fit.chi2 <= critical,
                chi2_critical: critical,
                reference: fit.reference,
            }
        })
    } else {
        notes.push(
            "encoder errors are not closed: no test of the whole vector (vector is null)"
                .to_string(),
        );
        None
    };
    if random_effects {
        notes.push(
            "DerSimonian–Laird: nobody is left out; χ² and consistent are those of the weighted \
             mean (Cochran's Q), τ is the dark uncertainty in u_ref and every u(d_i)"
                .to_string(),
        );
    }
    if !excluded.is_empty() {
        // the per-quantity tests are many: say how often a consistent comparison fails one
        let tests = aligned.index.len() as i32;
        notes.push(format!(
            "each of the {tests} quantities is tested at 5 %: a comparison of consistent \
             laboratories fails at least one of them by chance with probability \
             1 − 0.95^{tests} = {:.0} %, and a laboratory left out for one quantity may be \
             consistent; the closed vector's test weighs every quantity at once",
            100.0 * (1.0 - 0.95_f64.powi(tests))
        ));
    }
    let chi2_critical: Vec<f64> = found.iter().map(|e| chi2_quantile_95(e.dof)).collect();
    let consistent: Vec<bool> = found
        .iter()
        .zip(&chi2_critical)
        .map(|(e, q)| e.chi2 <= *q)
        .collect();
    let comparison_consistent =
        consistent.iter().all(|c| *c) && vector.as_ref().is_none_or(|v| v.consistent);
    KeyComparison {
        quantity: options.quantity,
        method: options.method,
        index: aligned.index.clone(),
        angle_deg: aligned.angle_deg.clone(),
        labs: labs.iter().map(|l| l.name.clone()).collect(),
        reference: found.iter().map(|e| e.reference).collect(),
        reference_u: found
            .iter()
            .zip(&stability_u)
            .map(|(e, s)| e.reference_u.hypot(*s))
            .collect(),
        chi2: found.iter().map(|e| e.chi2).collect(),
        chi2_dof: found.iter().map(|e| e.dof).collect(),
        chi2_critical,
        consistent,
        vector,
        excluded,
        tau: found.iter().map(|e| e.tau).collect(),
        degrees_of_equivalence,
        pairs,
        pilot: pilot_report,
        comparison_consistent,
        notes,
    }
}

/// The name of result `r` of the laboratories followed by the pilot's repeats.
fn all_name(labs: &[LabResult], pilot: &[LabResult], r: usize) -> String {
    labs.iter()
        .chain(pilot)
        .nth(r)
        .map_or_else(String::new, |l| l.name.clone())
}
