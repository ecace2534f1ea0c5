//! Key comparisons (`polycal::kc`, docs/FORMAT.md §12): against an independent
//! implementation of the textbook formulas written here, and by simulated comparisons
//! (the χ² test's size, the coverage of U(d_i), the biased laboratory found first, the
//! closed vector's degrees of freedom).

// The independent implementation is written with indices, as the textbooks write it.
#![allow(clippy::needless_range_loop)]

use polycal::kc::{KcOptions, LabResult, ReferenceMethod, evaluate};
use polycal::results::{Quantity, ResultRow};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const FACES: usize = 12;

fn lab(name: &str, values: &[f64], u: &[f64]) -> LabResult {
    let rows = values
        .iter()
        .zip(u)
        .enumerate()
        .map(|(f, (&x, &u))| {
            ResultRow::new(Quantity::PitchDeviation, f as u32 + 1, x)
                .with_expanded_u(2.0 * u)
                .with_k(2.0)
        })
        .collect();
    LabResult::from_rows(name, rows)
}

// ------------------------------------------------------- the independent implementation

/// Weighted mean, its u and χ², from the textbook (Cox 2002, procedure A), written out.
fn textbook_weighted_mean(x: &[f64], u: &[f64]) -> (f64, f64, f64) {
    let mut sum_w = 0.0;
    let mut sum_wx = 0.0;
    for i in 0..x.len() {
        sum_w += 1.0 / (u[i] * u[i]);
        sum_wx += x[i] / (u[i] * u[i]);
    }
    let mean = sum_wx / sum_w;
    let mut chi2 = 0.0;
    for i in 0..x.len() {
        chi2 += (x[i] - mean) * (x[i] - mean) / (u[i] * u[i]);
    }
    (mean, 1.0 / sum_w.sqrt(), chi2)
}

/// DerSimonian–Laird (1986): τ², the random-effects mean and its u.
fn textbook_dersimonian_laird(x: &[f64], u: &[f64]) -> (f64, f64, f64) {
    let (_, _, q) = textbook_weighted_mean(x, u);
    let w: Vec<f64> = u.iter().map(|u| 1.0 / (u * u)).collect();
    let s1: f64 = w.iter().sum();
    let s2: f64 = w.iter().map(|w| w * w).sum();
    let mut tau2 = (q - (x.len() as f64 - 1.0)) / (s1 - s2 / s1);
    if tau2 < 0.0 {
        tau2 = 0.0;
    }
    let mut sum_w = 0.0;
    let mut sum_wx = 0.0;
    for i in 0..x.len() {
        let wi = 1.0 / (u[i] * u[i] + tau2);
        sum_w += wi;
        sum_wx += wi * x[i];
    }
    (tau2.sqrt(), sum_wx / sum_w, 1.0 / sum_w.sqrt())
}

/// Five laboratories of a 12-face polygon, hand-chosen and consistent, u varying by face.
fn fixed_data() -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let truth = [
        0.82, -0.35, -0.12, -0.21, 0.58, 0.03, -0.64, 0.27, -0.09, -0.33, 0.41, -0.37,
    ];
    let offsets = [
        [
            0.01, -0.02, 0.03, 0.0, -0.01, 0.02, -0.03, 0.01, 0.0, 0.02, -0.02, -0.01,
        ],
        [
            -0.04, 0.05, -0.01, 0.02, 0.03, -0.05, 0.04, -0.02, 0.01, -0.03, 0.0, 0.0,
        ],
        [
            0.06, -0.03, 0.02, -0.07, 0.05, 0.01, -0.02, 0.03, -0.06, 0.04, -0.01, -0.02,
        ],
        [
            -0.02, 0.08, -0.09, 0.05, -0.04, 0.07, 0.02, -0.08, 0.03, -0.01, 0.06, -0.07,
        ],
        [
            0.1, -0.12, 0.05, 0.09, -0.11, 0.0, 0.13, -0.04, -0.06, 0.08, -0.1, -0.02,
        ],
    ];
    let base_u = [0.03, 0.05, 0.07, 0.09, 0.12];
    let values = offsets
        .iter()
        .map(|o| (0..FACES).map(|f| truth[f] + o[f]).collect())
        .collect();
    let u = base_u
        .iter()
        .map(|u| (0..FACES).map(|f| u * (1.0 + 0.05 * f as f64)).collect())
        .collect();
    (values, u)
}

#[test]
fn kc_weighted_mean_and_degrees_of_equivalence_match_the_textbook() {
    let (values, u) = fixed_data();
    let names = ["A", "B", "C", "D", "E"];
    let labs: Vec<LabResult> = (0..5).map(|i| lab(names[i], &values[i], &u[i])).collect();
    let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    assert!(kc.excluded.is_empty(), "{:?}", kc.excluded);
    for f in 0..FACES {
        let x: Vec<f64> = values.iter().map(|v| v[f]).collect();
        let s: Vec<f64> = u.iter().map(|v| v[f]).collect();
        let (mean, mean_u, chi2) = textbook_weighted_mean(&x, &s);
        assert!((kc.reference[f] - mean).abs() < 1e-12);
        assert!((kc.reference_u[f] - mean_u).abs() < 1e-12);
        assert!((kc.chi2[f] - chi2).abs() < 1e-12);
        assert_eq!(kc.chi2_dof[f], 4);
        assert_eq!(kc.tau[f], 0.0);
        for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
            assert!(doe.in_reference);
            assert!((doe.d[f] - (x[i] - mean)).abs() < 1e-12);
            let expected_u = 2.0 * (s[i] * s[i] - mean_u * mean_u).sqrt();
            assert!((doe.expanded_u[f] - expected_u).abs() < 1e-12);
        }
        for pair in &kc.pairs {
            let a = names.iter().position(|n| *n == pair.a).unwrap();
            let b = names.iter().position(|n| *n == pair.b).unwrap();
            assert!((pair.d[f] - (x[a] - x[b])).abs() < 1e-12);
            let expected_u = 2.0 * (s[a] * s[a] + s[b] * s[b]).sqrt();
            assert!((pair.expanded_u[f] - expected_u).abs() < 1e-12);
        }
    }
    assert_eq!(kc.pairs.len(), 10);
    assert!(kc.comparison_consistent);
}

#[test]
fn kc_dersimonian_laird_matches_the_textbook() {
    let (mut values, u) = fixed_data();
    // Spread the laboratories beyond their uncertainties, so that τ > 0 on most faces.
    for (i, v) in values.iter_mut().enumerate() {
        for (f, x) in v.iter_mut().enumerate() {
            *x += 0.15 * ((i * 7 + f * 3) % 5) as f64 - 0.3;
        }
    }
    let labs: Vec<LabResult> = (0..5)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let options = KcOptions::new().with_method(ReferenceMethod::DersimonianLaird);
    let kc = evaluate(&labs, &[], &options).unwrap();
    assert!(kc.excluded.is_empty());
    let mut positive = 0;
    for f in 0..FACES {
        let x: Vec<f64> = values.iter().map(|v| v[f]).collect();
        let s: Vec<f64> = u.iter().map(|v| v[f]).collect();
        let (tau, reference, reference_u) = textbook_dersimonian_laird(&x, &s);
        positive += usize::from(tau > 0.0);
        assert!((kc.tau[f] - tau).abs() < 1e-12, "{} vs {tau}", kc.tau[f]);
        assert!((kc.reference[f] - reference).abs() < 1e-12);
        assert!((kc.reference_u[f] - reference_u).abs() < 1e-12);
        // u²(d_i) = (1 − w'_i)² v_i + Σ_{j≠i} w'_j² v_j, v = u² + τ², written out.
        let v: Vec<f64> = s.iter().map(|s| s * s + tau * tau).collect();
        let total: f64 = v.iter().map(|v| 1.0 / v).sum();
        for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
            let mut variance = 0.0;
            for j in 0..5 {
                let w = (1.0 / v[j]) / total;
                variance += if j == i {
                    (1.0 - w) * (1.0 - w) * v[j]
                } else {
                    w * w * v[j]
                };
            }
            assert!((doe.d[f] - (x[i] - reference)).abs() < 1e-12);
            assert!((doe.expanded_u[f] - 2.0 * variance.sqrt()).abs() < 1e-12);
        }
    }
    assert!(positive >= 6, "τ > 0 on {positive} faces only");
}

#[test]
fn kc_exclusion_leaves_out_the_worst_laboratory_for_the_whole_comparison() {
    let (mut values, u) = fixed_data();
    values[3][6] += 1.0; // laboratory D, face 7: far out
    let names = ["A", "B", "C", "D", "E"];
    let labs: Vec<LabResult> = (0..5).map(|i| lab(names[i], &values[i], &u[i])).collect();
    let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    assert_eq!(kc.excluded.len(), 1, "{:?}", kc.excluded);
    let e = &kc.excluded[0];
    assert_eq!((e.lab.as_str(), e.index), ("D", 7));
    let x: Vec<f64> = values.iter().map(|v| v[6]).collect();
    let s: Vec<f64> = u.iter().map(|v| v[6]).collect();
    let (mean, mean_u, chi2) = textbook_weighted_mean(&x, &s);
    assert!((e.chi2_before - chi2).abs() < 1e-12);
    let z = (x[3] - mean).abs() / (s[3] * s[3] - mean_u * mean_u).sqrt();
    assert!((e.normalised_deviation - z).abs() < 1e-12);
    assert!(e.reason.contains("face") || e.reason.contains("pitch_deviation 7"));
    // Out of the reference on every face; its U(d) with the plus.
    let d = &kc.degrees_of_equivalence[3];
    assert!(!d.in_reference);
    for f in 0..FACES {
        let x: Vec<f64> = [0, 1, 2, 4].iter().map(|&i| values[i][f]).collect();
        let s4: Vec<f64> = [0, 1, 2, 4].iter().map(|&i| u[i][f]).collect();
        let (mean, mean_u, _) = textbook_weighted_mean(&x, &s4);
        assert!((kc.reference[f] - mean).abs() < 1e-12);
        let expected_u = 2.0 * (u[3][f] * u[3][f] + mean_u * mean_u).sqrt();
        assert!((d.expanded_u[f] - expected_u).abs() < 1e-12);
    }
    assert!(kc.comparison_consistent);
    assert_eq!(kc.vector.as_ref().unwrap().dof, 11 * 3);
}

// ------------------------------------------------------------ simulated comparisons

/// A closed draw with marginal standard deviations `u`: e = √(N/(N−1))·P·(u ⊙ z), whose
/// covariance is N/(N−1)·P·diag(u²)·P.
fn closed_noise(rng: &mut ChaCha8Rng, u: &[f64]) -> Vec<f64> {
    let n = u.len() as f64;
    let scaled: Vec<f64> = u
        .iter()
        .map(|u| {
            let z: f64 = StandardNormal.sample(rng);
            u * z
        })
        .collect();
    let mean = scaled.iter().sum::<f64>() / n;
    scaled
        .iter()
        .map(|e| (n / (n - 1.0)).sqrt() * (e - mean))
        .collect()
}

fn truth() -> Vec<f64> {
    let raw: Vec<f64> = (0..FACES).map(|f| (f as f64 * 1.3).sin() * 0.5).collect();
    let mean = raw.iter().sum::<f64>() / FACES as f64;
    raw.iter().map(|b| b - mean).collect()
}

const LAB_U: [f64; 8] = [0.04, 0.05, 0.06, 0.08, 0.1, 0.12, 0.15, 0.2];
const BIASED: usize = 4;
/// The faces of the biased laboratory and the sign of its 3u bias there (closed).
const BIAS_FACES: [(usize, f64); 4] = [(3, 1.0), (5, 1.0), (8, -1.0), (10, -1.0)];

/// One simulated comparison of 8 laboratories, u constant over the faces; with `biased`
/// laboratory 4 is off by +3u on faces 3 and 5 and −3u on faces 8 and 10 (still closed).
fn simulated(rng: &mut ChaCha8Rng, biased: bool) -> Vec<LabResult> {
    let truth = truth();
    LAB_U
        .iter()
        .enumerate()
        .map(|(i, &u)| {
            let u_faces = vec![u; FACES];
            let noise = closed_noise(rng, &u_faces);
            let mut values: Vec<f64> = truth.iter().zip(&noise).map(|(t, e)| t + e).collect();
            if biased && i == BIASED {
                for (face, sign) in BIAS_FACES {
                    values[face - 1] += sign * 3.0 * u;
                }
            }
            lab(&format!("L{i}"), &values, &u_faces)
        })
        .collect()
}

#[test]
fn kc_simulated_comparisons_have_the_stated_size_coverage_and_find_the_biased_lab() {
    let mut rng = ChaCha8Rng::seed_from_u64(37);
    let trials = 1000;
    let all_in = KcOptions::new().with_largest_consistent_subset(false);
    let (mut tests, mut rejected, mut covered, mut does) = (0usize, 0usize, 0usize, 0usize);
    let (mut vector_rejected, mut vector_sum) = (0usize, 0.0);
    let mut vector_rejected_wrong_dof = 0usize;
    let wrong_dof_critical = polycal::kc::chi2_quantile_95(FACES * (LAB_U.len() - 1));
    for _ in 0..trials {
        let labs = simulated(&mut rng, false);
        let kc = evaluate(&labs, &[], &all_in).unwrap();
        tests += kc.consistent.len();
        rejected += kc.consistent.iter().filter(|c| !**c).count();
        for doe in &kc.degrees_of_equivalence {
            for (d, expanded_u) in doe.d.iter().zip(&doe.expanded_u) {
                does += 1;
                covered += usize::from(d.abs() <= *expanded_u);
            }
        }
        let vector = kc.vector.unwrap();
        assert_eq!(vector.dof, (FACES - 1) * (LAB_U.len() - 1));
        vector_rejected += usize::from(!vector.consistent);
        vector_rejected_wrong_dof += usize::from(vector.chi2 > wrong_dof_critical);
        vector_sum += vector.chi2;
    }
    let rejection = rejected as f64 / tests as f64;
    let coverage = covered as f64 / does as f64;
    let vector_rejection = vector_rejected as f64 / trials as f64;
    let vector_mean = vector_sum / trials as f64;
    let dof = ((FACES - 1) * (LAB_U.len() - 1)) as f64;

    let (mut with_exclusion, mut biased_first) = (0usize, 0usize);
    for _ in 0..trials {
        let labs = simulated(&mut rng, true);
        let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
        if let Some(first) = kc.excluded.first() {
            with_exclusion += 1;
            biased_first += usize::from(first.lab == format!("L{BIASED}"));
        }
    }
    let first_rate = biased_first as f64 / with_exclusion as f64;
    eprintln!(
        "per-face rejection {:.2} %, coverage of U(d_i) {:.2} %, vector rejection {:.2} % \
         (with N(n−1) dof: {:.2} %), mean vector χ² {vector_mean:.2} (ν = {dof}), biased \
         comparisons with an exclusion {with_exclusion} of {trials}, the biased laboratory \
         first in {:.2} %",
        100.0 * rejection,
        100.0 * coverage,
        100.0 * vector_rejection,
        100.0 * vector_rejected_wrong_dof as f64 / trials as f64,
        100.0 * first_rate
    );
    assert!((rejection - 0.05).abs() <= 0.015, "rejection {rejection}");
    assert!((coverage - 0.9545).abs() <= 0.015, "coverage {coverage}");
    assert!(
        (vector_rejection - 0.05).abs() <= 0.015,
        "vector rejection {vector_rejection}"
    );
    // The mean of χ²_vector is its dof (N − 1)(n − 1) within 4 standard errors
    // (√(2ν/trials)), and far from N(n − 1) = ν + n − 1.
    let standard_error = (2.0 * dof / trials as f64).sqrt();
    assert!(
        (vector_mean - dof).abs() < 4.0 * standard_error,
        "{vector_mean}"
    );
    let wrong = (FACES * (LAB_U.len() - 1)) as f64;
    assert!((vector_mean - wrong).abs() > 10.0 * standard_error);
    assert!(with_exclusion >= trials / 2, "{with_exclusion}");
    assert!(
        first_rate >= 0.9,
        "the biased laboratory first in {first_rate}"
    );
}

#[test]
fn kc_closed_vector_reference_is_the_weighted_mean_with_equal_u_over_faces() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    let labs = simulated(&mut rng, false);
    let kc = evaluate(
        &labs,
        &[],
        &KcOptions::new().with_largest_consistent_subset(false),
    )
    .unwrap();
    let vector = kc.vector.unwrap();
    for f in 0..FACES {
        assert!(
            (vector.reference[f] - kc.reference[f]).abs() < 1e-12,
            "face {}: {} vs {}",
            f + 1,
            vector.reference[f],
            kc.reference[f]
        );
    }
}

/// With u varying over the faces the closed vector's χ² still has (N − 1)(n − 1) degrees
/// of freedom: its mean over closed comparisons is that, not N(n − 1).
#[test]
fn kc_closed_vector_chi2_has_its_degrees_of_freedom_with_varying_u() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let labs_u: Vec<Vec<f64>> = (0..6)
        .map(|i| {
            (0..FACES)
                .map(|f| 0.05 + 0.02 * i as f64 + 0.01 * (f % 4) as f64)
                .collect()
        })
        .collect();
    let trials = 1000;
    let (mut sum, mut rejected) = (0.0, 0usize);
    let truth = truth();
    for _ in 0..trials {
        let labs: Vec<LabResult> = labs_u
            .iter()
            .enumerate()
            .map(|(i, u)| {
                let noise = closed_noise(&mut rng, u);
                let values: Vec<f64> = truth.iter().zip(&noise).map(|(t, e)| t + e).collect();
                lab(&format!("L{i}"), &values, u)
            })
            .collect();
        let kc = evaluate(
            &labs,
            &[],
            &KcOptions::new().with_largest_consistent_subset(false),
        )
        .unwrap();
        let vector = kc.vector.unwrap();
        sum += vector.chi2;
        rejected += usize::from(!vector.consistent);
    }
    let dof = ((FACES - 1) * 5) as f64;
    let mean = sum / trials as f64;
    let rejection = rejected as f64 / trials as f64;
    eprintln!("varying u: mean vector χ² {mean:.2} (ν = {dof}), rejection {rejection:.3}");
    assert!((mean - dof).abs() < 4.0 * (2.0 * dof / trials as f64).sqrt());
    assert!((rejection - 0.05).abs() <= 0.015);
}

#[test]
fn kc_pilot_repeats_add_their_spread_where_they_disagree() {
    let (values, u) = fixed_data();
    let labs: Vec<LabResult> = (0..3)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let mut moved = values[0].clone();
    moved[0] += 0.5; // face 1 moved by far more than u = 0.03
    let pilot = [lab("start", &values[0], &u[0]), lab("end", &moved, &u[0])];
    let kc = evaluate(&labs, &pilot, &KcOptions::new()).unwrap();
    let report = kc.pilot.as_ref().unwrap();
    assert_eq!(report.repeats, ["start", "end"]);
    assert!(report.significant[0]);
    assert!(!report.significant[1]);
    let s = 0.5 / 2f64.sqrt(); // the sample standard deviation of two values 0.5 apart
    assert!((report.stability_u[0] - s).abs() < 1e-12);
    let x: Vec<f64> = (0..3).map(|i| values[i][0]).collect();
    let s3: Vec<f64> = (0..3).map(|i| u[i][0]).collect();
    let (_, mean_u, _) = textbook_weighted_mean(&x, &s3);
    assert!((kc.reference_u[0] - (mean_u * mean_u + s * s).sqrt()).abs() < 1e-12);
    assert!(kc.notes.iter().any(|n| n.contains("pilot")));
    assert_eq!(report.degrees_of_equivalence.len(), 2);
    assert!(!report.degrees_of_equivalence[1].in_reference);
    // One repeat is no stability test.
    assert!(evaluate(&labs, &pilot[..1], &KcOptions::new()).is_err());
}

#[test]
fn kc_encoder_errors_are_matched_by_angle_and_the_others_named() {
    let at = |values: &[(f64, f64)]| -> Vec<ResultRow> {
        values
            .iter()
            .enumerate()
            .map(|(p, &(angle, x))| {
                ResultRow::new(Quantity::EncoderError, p as u32, x)
                    .with_u(0.1)
                    .with_angle_deg(angle)
            })
            .collect()
    };
    let a = LabResult::from_rows(
        "A",
        at(&[(0.0, 0.1), (90.0, 0.2), (180.0, 0.3), (270.0, 0.4)]),
    );
    let b = LabResult::from_rows(
        "B",
        at(&[
            (0.0, 0.12),
            (45.0, 9.0),
            (90.0, 0.18),
            (180.0, 0.33),
            (270.0, 0.41),
        ]),
    );
    let c = LabResult::from_rows(
        "C",
        at(&[
            (359.99999999, 0.11),
            (90.0, 0.2),
            (180.0, 0.29),
            (270.0, 0.38),
        ]),
    );
    let options = KcOptions::new().with_quantity(Quantity::EncoderError);
    let kc = evaluate(&[a, b, c], &[], &options).unwrap();
    assert_eq!(kc.index, [0, 1, 2, 3]);
    assert_eq!(
        kc.angle_deg.as_deref(),
        Some(&[0.0, 90.0, 180.0, 270.0][..])
    );
    assert!((kc.reference[0] - 0.11).abs() < 1e-12);
    assert!(kc.vector.is_none());
    assert!(kc.notes.iter().any(|n| n.contains("45°")), "{:?}", kc.notes);
}
