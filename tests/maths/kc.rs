//! Key comparisons (`polycal::kc`, docs/FORMAT.md §12): against an independent
//! implementation of the textbook formulas and of the closed GLS (dense, by SVD, in
//! `kc_support`), the decision against a brute-force search, and by simulated comparisons
//! (the coverage of U(d_i), the closed vector's degrees of freedom). The verdicts' rates
//! are in `tests/sweeps/kc_rates.rs`.

// The independent implementation is written with indices, as the textbooks write it.
#![allow(clippy::needless_range_loop)]

use crate::kc_support;

use crate::kc_support::{closed_cov, gls, lab, largest_subset, one_at_a_time};
use nalgebra::DMatrix;
use polycal::kc::{KcOptions, LabResult, ReferenceMethod, evaluate};
use polycal::results::{Quantity, ResultRow};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

const FACES: usize = 12;

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

/// Mandel–Paule (Paule & Mandel 1982), by their own iteration: from τ² = 0, Newton steps on
/// F(τ²) = Σ w_i (x_i − x̄)² − (n − 1), w_i = 1/(u_i² + τ²), with F'(τ²) ≈ −Σ w_i² (x_i − x̄)²
/// (the step the paper gives), until it changes by less than 1e-15 of τ². Returns τ, the mean
/// and its u.
fn textbook_mandel_paule(x: &[f64], u: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let mean_of = |tau2: f64| {
        let w: Vec<f64> = u.iter().map(|u| 1.0 / (u * u + tau2)).collect();
        let sw: f64 = w.iter().sum();
        let mean = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / sw;
        (w, sw, mean)
    };
    let mut tau2 = 0.0f64;
    for _ in 0..1000 {
        let (w, _, mean) = mean_of(tau2);
        let f: f64 = x
            .iter()
            .zip(&w)
            .map(|(x, w)| w * (x - mean).powi(2))
            .sum::<f64>()
            - (n - 1.0);
        if f <= 0.0 && tau2 == 0.0 {
            break;
        }
        let slope: f64 = x
            .iter()
            .zip(&w)
            .map(|(x, w)| w * w * (x - mean).powi(2))
            .sum();
        let next = (tau2 + f / slope).max(0.0);
        let done = (next - tau2).abs() <= 1e-15 * next.max(1e-300);
        tau2 = next;
        if done {
            break;
        }
    }
    let (_, sw, mean) = mean_of(tau2);
    (tau2.sqrt(), mean, 1.0 / sw.sqrt())
}

/// Spreads the laboratories of [`fixed_data`] beyond their uncertainties (each closed
/// again), so that τ > 0 on most faces.
fn spread_beyond_u(values: &mut [Vec<f64>]) {
    for (i, v) in values.iter_mut().enumerate() {
        for (f, x) in v.iter_mut().enumerate() {
            *x += 0.15 * ((i * 7 + f * 3) % 5) as f64 - 0.3;
        }
        *v = closed(v);
    }
}

/// Five laboratories of a 12-face polygon, hand-chosen, closed and consistent; with
/// `varying` their u varies by face, else each laboratory has one u on every face.
fn fixed_data(varying: bool) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
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
        .map(|o| closed(&(0..FACES).map(|f| truth[f] + o[f]).collect::<Vec<_>>()))
        .collect();
    let u = base_u
        .iter()
        .map(|u| {
            (0..FACES)
                .map(|f| {
                    if varying {
                        u * (1.0 + 0.05 * f as f64)
                            + 0.01 * ((f * 3 + (u * 100.0) as usize) % 4) as f64
                    } else {
                        *u
                    }
                })
                .collect()
        })
        .collect();
    (values, u)
}

/// `x` less its mean.
fn closed(x: &[f64]) -> Vec<f64> {
    let mean = x.iter().sum::<f64>() / x.len() as f64;
    x.iter().map(|x| x - mean).collect()
}

/// With one u per laboratory the closed GLS reference is the textbook weighted mean of
/// each face, and every degree of equivalence and pair the textbook's.
#[test]
fn kc_weighted_mean_and_degrees_of_equivalence_match_the_textbook() {
    let (values, u) = fixed_data(false);
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
    let all = kc.vector_all.as_ref().unwrap();
    assert_eq!(all, kc.vector.as_ref().unwrap());
    assert!(kc.search.is_none());
}

/// With u varying over the faces the reference is the closed GLS one (the independent
/// dense implementation): Σ_k d_ik = 0 for every laboratory, U(d_i)² from the diagonals
/// of V_i and of the reference's covariance.
#[test]
fn kc_with_u_varying_by_face_the_degrees_of_equivalence_are_against_the_closed_reference() {
    let (values, u) = fixed_data(true);
    let labs: Vec<LabResult> = (0..5)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    let v: Vec<DMatrix<f64>> = u.iter().map(|u| closed_cov(u)).collect();
    let g = gls(&values, &v);
    let all = kc.vector_all.as_ref().unwrap();
    assert!((all.chi2 - g.chi2).abs() < 1e-9 * g.chi2);
    assert_eq!(all.dof, g.dof);
    for f in 0..FACES {
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        assert!((kc.reference_u[f] - g.covariance[(f, f)].sqrt()).abs() < 1e-12);
    }
    // The per-face weighted means do not close here: the reference is not theirs.
    let per_face: f64 = (0..FACES)
        .map(|f| {
            let x: Vec<f64> = values.iter().map(|v| v[f]).collect();
            let s: Vec<f64> = u.iter().map(|v| v[f]).collect();
            textbook_weighted_mean(&x, &s).0
        })
        .sum();
    assert!(per_face.abs() > 1e-4, "{per_face}");
    for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
        assert!(doe.d.iter().sum::<f64>().abs() < 1e-12, "Σ d of L{i}");
        for f in 0..FACES {
            assert!((doe.d[f] - (values[i][f] - g.reference[f])).abs() < 1e-12);
            let variance = v[i][(f, f)] - g.covariance[(f, f)];
            assert!((doe.expanded_u[f] - 2.0 * variance.sqrt()).abs() < 1e-12);
        }
    }
}

#[test]
fn kc_dersimonian_laird_matches_the_textbook() {
    let (mut values, u) = fixed_data(false);
    spread_beyond_u(&mut values);
    let labs: Vec<LabResult> = (0..5)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let options = KcOptions::new().with_method(ReferenceMethod::DersimonianLaird);
    let kc = evaluate(&labs, &[], &options).unwrap();
    assert!(kc.excluded.is_empty());
    // τ per face from the textbook; then the closed GLS with every variance widened by τ².
    let tau: Vec<f64> = (0..FACES)
        .map(|f| {
            let x: Vec<f64> = values.iter().map(|v| v[f]).collect();
            let s: Vec<f64> = u.iter().map(|v| v[f]).collect();
            textbook_dersimonian_laird(&x, &s).0
        })
        .collect();
    let widened: Vec<Vec<f64>> = u
        .iter()
        .map(|u| u.iter().zip(&tau).map(|(u, t)| u.hypot(*t)).collect())
        .collect();
    let v: Vec<DMatrix<f64>> = widened.iter().map(|u| closed_cov(u)).collect();
    let g = gls(&values, &v);
    let positive = tau.iter().filter(|t| **t > 0.0).count();
    for f in 0..FACES {
        assert!(
            (kc.tau[f] - tau[f]).abs() < 1e-12,
            "{} vs {}",
            kc.tau[f],
            tau[f]
        );
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        assert!((kc.reference_u[f] - g.covariance[(f, f)].sqrt()).abs() < 1e-12);
        for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
            assert!((doe.d[f] - (values[i][f] - g.reference[f])).abs() < 1e-12);
            let variance = v[i][(f, f)] - g.covariance[(f, f)];
            assert!((doe.expanded_u[f] - 2.0 * variance.sqrt()).abs() < 1e-12);
        }
    }
    assert!(positive >= 6, "τ > 0 on {positive} faces only");
    // Its verdict is the test of τ = 0: the closed vector of every laboratory, untouched.
    let plain: Vec<DMatrix<f64>> = u.iter().map(|u| closed_cov(u)).collect();
    let all = gls(&values, &plain);
    let vector_all = kc.vector_all.as_ref().unwrap();
    assert!((vector_all.chi2 - all.chi2).abs() < 1e-9 * all.chi2);
    assert!(!vector_all.consistent);
    assert!(!kc.comparison_consistent);
    assert!(kc.verdict_statement().contains("τ = 0 rejected"));
}

#[test]
fn kc_exclusion_leaves_out_the_largest_consistent_subset_for_the_whole_comparison() {
    let (mut values, u) = fixed_data(true);
    values[3][6] += 2.0; // laboratory D, face 7: far out
    values[3] = closed(&values[3]);
    let names = ["A", "B", "C", "D", "E"];
    let labs: Vec<LabResult> = (0..5).map(|i| lab(names[i], &values[i], &u[i])).collect();
    let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    assert_eq!(kc.excluded.len(), 1, "{:?}", kc.excluded);
    assert_eq!(kc.excluded[0].lab, "D");
    assert_eq!(largest_subset(&values, &u, &[]), [0, 1, 2, 4]);
    let all = kc.vector_all.as_ref().unwrap();
    assert!(!all.consistent);
    let v: Vec<DMatrix<f64>> = u.iter().map(|u| closed_cov(u)).collect();
    assert!((all.chi2 - gls(&values, &v).chi2).abs() < 1e-9 * all.chi2);
    let search = kc.search.as_ref().unwrap();
    assert_eq!(search.steps.len(), 1);
    assert_eq!(search.steps[0].subsets, 5);
    assert_eq!(search.steps[0].best, ["A", "B", "C", "E"]);
    assert!(kc.excluded[0].reason.contains("A, B, C, E"));
    // Out of the reference on every face; its U(d) with the plus, against the four.
    let four = [0, 1, 2, 4];
    let xs: Vec<Vec<f64>> = four.iter().map(|&i| values[i].clone()).collect();
    let vs: Vec<DMatrix<f64>> = four.iter().map(|&i| v[i].clone()).collect();
    let g = gls(&xs, &vs);
    let d = &kc.degrees_of_equivalence[3];
    assert!(!d.in_reference);
    for f in 0..FACES {
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        let expected_u = 2.0 * (v[3][(f, f)] + g.covariance[(f, f)]).sqrt();
        assert!((d.expanded_u[f] - expected_u).abs() < 1e-12);
    }
    assert!(kc.comparison_consistent);
    assert_eq!(kc.vector.as_ref().unwrap().dof, 11 * 3);
    assert!(
        kc.verdict_statement()
            .starts_with("Consistent after leaving out D")
    );
    // Kept in by the pilot: D stays, another laboratory goes or the comparison fails.
    let kept = evaluate(&labs, &[], &KcOptions::new().with_keep(["D"])).unwrap();
    assert!(kept.degrees_of_equivalence[3].in_reference);
    assert_eq!(kept.kept, ["D"]);
    assert_eq!(
        largest_subset(&values, &u, &[3]),
        (0..5)
            .filter(|&r| kept.degrees_of_equivalence[r].in_reference)
            .collect::<Vec<_>>()
    );
    assert!(evaluate(&labs, &[], &KcOptions::new().with_keep(["Z"])).is_err());
}

/// The decision against the brute-force search of the independent implementation, on
/// fixed simulated comparisons with one or two biased laboratories — among them one where
/// leaving laboratories out one at a time keeps fewer than the largest consistent subset.
#[test]
fn kc_the_search_finds_the_largest_consistent_subset_where_one_at_a_time_does_not() {
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    let (mut compared, mut greedy_smaller) = (0, 0);
    for trial in 0..400 {
        let labs = 5 + trial % 3;
        let faces = 6;
        let shifts: Vec<(usize, f64)> = vec![(1, 4.0), (3, -3.5), (4, 3.0)];
        let (mut values, u) =
            kc_support::comparison(&mut rng, faces, labs, Some((trial % labs, &shifts)));
        // a second laboratory off in another pattern on some trials
        if trial % 2 == 0 {
            let other = (trial / 2) % labs;
            let lab_u = u[other][0];
            values[other][0] += 3.0 * lab_u;
            values[other][5] -= 3.0 * lab_u;
        }
        let (x, us) = (values.clone(), u.clone());
        let expected = largest_subset(&x, &us, &[]);
        let greedy = one_at_a_time(&x, &us);
        let kc = evaluate(&kc_support::results(&x, &us), &[], &KcOptions::new()).unwrap();
        let inside: Vec<usize> = (0..labs)
            .filter(|&r| kc.degrees_of_equivalence[r].in_reference)
            .collect();
        assert_eq!(inside, expected, "trial {trial}");
        compared += 1;
        if greedy.len() < expected.len() {
            greedy_smaller += 1;
        }
    }
    // Two laboratories of small u that share a bias pull the reference to themselves: left
    // out one at a time, the three others go first and two remain; the largest subset that
    // passes is the three.
    let bias = [0.3, -0.3, 0.3, -0.3, 0.0, 0.0];
    let small = [0.004, -0.003, 0.002, 0.0, -0.002, -0.001];
    let x: Vec<Vec<f64>> = (0..5)
        .map(|i| {
            closed(
                &(0..6)
                    .map(|f| {
                        let wobble = small[(f + i) % 6] * (i as f64 + 1.0);
                        if i < 2 { bias[f] + wobble } else { wobble }
                    })
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let us: Vec<Vec<f64>> = (0..5)
        .map(|i| vec![if i < 2 { 0.02 } else { 0.1 }; 6])
        .collect();
    assert_eq!(largest_subset(&x, &us, &[]), [2, 3, 4]);
    assert_eq!(one_at_a_time(&x, &us), [0, 1]);
    let kc = evaluate(&kc_support::results(&x, &us), &[], &KcOptions::new()).unwrap();
    let inside: Vec<usize> = (0..5)
        .filter(|&r| kc.degrees_of_equivalence[r].in_reference)
        .collect();
    assert_eq!(inside, [2, 3, 4]);
    greedy_smaller += 1;
    eprintln!("{compared} comparisons; one at a time kept fewer in {greedy_smaller}");
    assert!(
        greedy_smaller >= 1,
        "no comparison where one at a time keeps fewer"
    );
}

// ------------------------------------------------------------ simulated comparisons

/// Over 1 000 consistent comparisons: U(d_i) covers d_i in 95 %, the closed vector's χ²
/// has mean (N − 1)(n − 1) (not N(n − 1)), with u the same or varying over the faces.
#[test]
fn kc_closed_vector_chi2_has_its_degrees_of_freedom_and_u_d_covers() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for varying in [false, true] {
        let labs_u: Vec<Vec<f64>> = (0..6)
            .map(|i| {
                (0..FACES)
                    .map(|f| {
                        0.05 + 0.02 * i as f64 + if varying { 0.01 * (f % 4) as f64 } else { 0.0 }
                    })
                    .collect()
            })
            .collect();
        let trials = 1000;
        let (mut sum, mut covered, mut does) = (0.0, 0usize, 0usize);
        let truth = kc_support::truth(FACES);
        for _ in 0..trials {
            let labs: Vec<LabResult> = labs_u
                .iter()
                .enumerate()
                .map(|(i, u)| {
                    let noise = kc_support::closed_noise(&mut rng, u);
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
            sum += kc.vector_all.unwrap().chi2;
            for doe in &kc.degrees_of_equivalence {
                for (d, expanded_u) in doe.d.iter().zip(&doe.expanded_u) {
                    does += 1;
                    covered += usize::from(d.abs() <= *expanded_u);
                }
            }
        }
        let dof = ((FACES - 1) * 5) as f64;
        let mean = sum / trials as f64;
        let coverage = covered as f64 / does as f64;
        eprintln!(
            "varying u {varying}: mean vector χ² {mean:.2} (ν = {dof}), coverage {coverage:.4}"
        );
        let standard_error = (2.0 * dof / trials as f64).sqrt();
        assert!((mean - dof).abs() < 4.0 * standard_error, "{mean}");
        assert!((mean - (FACES * 5) as f64).abs() > 10.0 * standard_error);
        assert!((coverage - 0.9545).abs() <= 0.01, "coverage {coverage}");
    }
}

#[test]
fn kc_pilot_repeats_are_one_test_of_their_closed_vectors() {
    let (values, u) = fixed_data(false);
    let labs: Vec<LabResult> = (0..3)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    // Face 1 and 2 moved by far more than u = 0.03 between the repeats (still closed).
    let mut moved = values[0].clone();
    moved[0] += 0.5;
    moved[1] -= 0.5;
    let pilot = [lab("start", &values[0], &u[0]), lab("end", &moved, &u[0])];
    let kc = evaluate(&labs, &pilot, &KcOptions::new()).unwrap();
    let report = kc.pilot.as_ref().unwrap();
    assert_eq!(report.repeats, ["start", "end"]);
    let vector = report.vector.as_ref().unwrap();
    // Two repeats with one u: χ² = Σ (y1 − y2)²/(2·c·u²)·… by the dense GLS.
    let v = vec![closed_cov(&u[0]), closed_cov(&u[0])];
    let g = gls(&[values[0].clone(), moved.clone()], &v);
    assert!((vector.chi2 - g.chi2).abs() < 1e-9 * g.chi2);
    assert_eq!(vector.dof, FACES - 1);
    assert!(!vector.consistent);
    // u_stab is the repeats' sample standard deviation on every face, and it is in every
    // laboratory's u: the reference is the dense closed GLS with u_i² + u_stab².
    let s: Vec<f64> = (0..FACES)
        .map(|f| (values[0][f] - moved[f]).abs() / 2f64.sqrt())
        .collect();
    let widened: Vec<DMatrix<f64>> = (0..3)
        .map(|i| closed_cov(&(0..FACES).map(|f| u[i][f].hypot(s[f])).collect::<Vec<_>>()))
        .collect();
    let g = gls(&values[..3], &widened);
    for f in 0..FACES {
        assert!((report.stability_u[f] - s[f]).abs() < 1e-12);
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        assert!((kc.reference_u[f] - g.covariance[(f, f)].sqrt()).abs() < 1e-12);
        // U(d_i) of a laboratory in the reference: 2·√(diag V_i − diag of the reference's)
        let expected = 2.0 * (widened[1][(f, f)] - g.covariance[(f, f)]).sqrt();
        assert!((kc.degrees_of_equivalence[1].expanded_u[f] - expected).abs() < 1e-12);
    }
    // every test is judged with u_stab: the closed vector of every laboratory too
    assert!((kc.vector_all.as_ref().unwrap().chi2 - g.chi2).abs() < 1e-9 * g.chi2.max(1.0));
    assert!(kc.pilot_statement().unwrap().contains("unstable"));
    assert_eq!(report.degrees_of_equivalence.len(), 2);
    assert!(!report.degrees_of_equivalence[1].in_reference);
    // Repeats that agree: u_stab = 0 everywhere.
    let same = [
        lab("start", &values[0], &u[0]),
        lab("end", &values[0], &u[0]),
    ];
    let kc = evaluate(&labs, &same, &KcOptions::new()).unwrap();
    assert!(
        kc.pilot
            .as_ref()
            .unwrap()
            .stability_u
            .iter()
            .all(|s| *s == 0.0)
    );
    // One repeat is no stability test.
    assert!(evaluate(&labs, &pilot[..1], &KcOptions::new()).is_err());
}

#[test]
fn kc_encoder_errors_are_matched_by_angle_compared_less_their_mean() {
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
    // C's zero is 5″ elsewhere: the same encoder errors up to a constant.
    let c = LabResult::from_rows(
        "C",
        at(&[
            (359.99999999, 5.11),
            (90.0, 5.2),
            (180.0, 5.29),
            (270.0, 5.38),
        ]),
    );
    let options = KcOptions::new().with_quantity(Quantity::EncoderError);
    let kc = evaluate(&[a, b, c], &[], &options).unwrap();
    assert_eq!(kc.index, [0, 1, 2, 3]);
    assert_eq!(
        kc.angle_deg.as_deref(),
        Some(&[0.0, 90.0, 180.0, 270.0][..])
    );
    // Each less its mean (0.25, 0.26, 5.245), then the weighted mean of equal u.
    let expected = ((0.1 - 0.25) + (0.12 - 0.26) + (5.11 - 5.245)) / 3.0;
    assert!(
        (kc.reference[0] - expected).abs() < 1e-12,
        "{}",
        kc.reference[0]
    );
    assert!(kc.excluded.is_empty(), "{:?}", kc.excluded);
    assert!(kc.comparison_consistent);
    assert_eq!(kc.vector_all.as_ref().unwrap().dof, 3 * 2);
    assert!(kc.notes.iter().any(|n| n.contains("45°")), "{:?}", kc.notes);
    assert!(kc.notes.iter().any(|n| n.contains("up to a constant")));
}

/// χ² is scale-free: the same comparison in units 10⁸ times smaller (u = 10⁻⁹″ … 10⁻⁸″)
/// gives the same χ² to 1e-9; a u below 10⁻⁹″ is refused, named by its row.
#[test]
fn kc_tiny_uncertainties_are_computed_in_scaled_form_or_refused() {
    let (values, u) = fixed_data(true);
    let labs: Vec<LabResult> = (0..5)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let scale = 1e-7;
    let small: Vec<LabResult> = (0..5)
        .map(|i| {
            let x: Vec<f64> = values[i].iter().map(|x| x * scale).collect();
            let s: Vec<f64> = u[i].iter().map(|u| u * scale).collect();
            lab(&format!("L{i}"), &x, &s)
        })
        .collect();
    let a = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    let b = evaluate(&small, &[], &KcOptions::new()).unwrap();
    let (ca, cb) = (a.vector_all.unwrap().chi2, b.vector_all.unwrap().chi2);
    assert!((ca - cb).abs() < 1e-9 * ca, "{ca} vs {cb}");
    for f in 0..FACES {
        assert!((a.reference[f] * scale - b.reference[f]).abs() < 1e-9 * scale);
        assert!((a.chi2[f] - b.chi2[f]).abs() < 1e-9 * a.chi2[f].max(1.0));
    }
    let tiny: Vec<LabResult> = (0..5)
        .map(|i| {
            let s: Vec<f64> = u[i].iter().map(|u| u * 1e-10).collect();
            lab(&format!("L{i}"), &values[i], &s)
        })
        .collect();
    let error = evaluate(&tiny, &[], &KcOptions::new())
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("L0 (row 1)") && error.contains("below 1e-9″"),
        "{error}"
    );
}

/// 3 000 faces, 8 laboratories: the closed vector without an N × N matrix (a dense GLS
/// would need 8 matrices of 72 MB each); its χ² has mean ν within reason for one draw.
#[test]
fn kc_three_thousand_faces_are_compared_in_linear_memory() {
    let mut rng = ChaCha8Rng::seed_from_u64(3000);
    let (values, u) = kc_support::comparison(&mut rng, 3000, 8, None);
    let kc = evaluate(&kc_support::results(&values, &u), &[], &KcOptions::new()).unwrap();
    let all = kc.vector_all.as_ref().unwrap();
    assert_eq!(all.dof, 2999 * 7);
    let z = (all.chi2 - all.dof as f64) / (2.0 * all.dof as f64).sqrt();
    assert!(z.abs() < 4.0, "χ² = {} for ν = {}", all.chi2, all.dof);
    for doe in &kc.degrees_of_equivalence {
        assert!(doe.d.iter().sum::<f64>().abs() < 1e-9);
    }
}

/// Each pair's test is the dense closed GLS of the two laboratories alone (χ², ν = N − 1),
/// and U(d_ij) is 2·√ of the diagonals of V_i + V_j, with τ in them for DerSimonian–Laird.
#[test]
fn kc_each_pair_is_the_two_laboratories_closed_vector_test() {
    let (values, u) = fixed_data(true);
    let labs: Vec<LabResult> = (0..values.len())
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    for method in [
        ReferenceMethod::WeightedMean,
        ReferenceMethod::DersimonianLaird,
    ] {
        let kc = evaluate(&labs, &[], &KcOptions::new().with_method(method)).unwrap();
        assert_eq!(kc.pairs.len(), labs.len() * (labs.len() - 1) / 2);
        let widened =
            |i: usize| -> Vec<f64> { (0..FACES).map(|f| u[i][f].hypot(kc.tau[f])).collect() };
        let mut failing = 0;
        for pair in &kc.pairs {
            let a: usize = pair.a[1..].parse().unwrap();
            let b: usize = pair.b[1..].parse().unwrap();
            let (va, vb) = (closed_cov(&widened(a)), closed_cov(&widened(b)));
            let g = gls(
                &[values[a].clone(), values[b].clone()],
                &[va.clone(), vb.clone()],
            );
            let vector = pair.vector.as_ref().unwrap();
            assert!(
                (vector.chi2 - g.chi2).abs() < 1e-9 * g.chi2.max(1.0),
                "{method:?}"
            );
            assert_eq!(vector.dof, FACES - 1);
            assert_eq!(vector.consistent, g.chi2 <= kc_support::critical(FACES - 1));
            failing += usize::from(!vector.consistent);
            for f in 0..FACES {
                let expected = 2.0 * (va[(f, f)] + vb[(f, f)]).sqrt();
                assert!((pair.expanded_u[f] - expected).abs() < 1e-12);
                assert!(
                    (pair.d[f] - (closed(&values[a])[f] - closed(&values[b])[f])).abs() < 1e-12
                );
            }
        }
        eprintln!("{method:?}: {failing} of {} pairs fail", kc.pairs.len());
    }
}

/// A laboratory kept out of the reference: the reference, the one test and the search are
/// those of the others alone, and its degree of equivalence is against that reference with
/// U = 2·√(diag V_i + diag of the reference's covariance) (dense GLS here).
#[test]
fn kc_a_laboratory_kept_out_of_the_reference_has_degrees_of_equivalence_against_it() {
    let (values, u) = fixed_data(true);
    let n = values.len();
    let labs: Vec<LabResult> = (0..n)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let out = "L0".to_string();
    let kc = evaluate(
        &labs,
        &[],
        &KcOptions::new().with_not_in_reference([out.clone()]),
    )
    .unwrap();
    let others = evaluate(&labs[1..], &[], &KcOptions::new()).unwrap();
    assert_eq!(kc.not_in_reference, ["L0"]);
    assert!(kc.excluded.iter().all(|e| e.lab != out));
    assert!(!kc.degrees_of_equivalence[0].in_reference);
    assert_eq!(
        kc.vector_all.as_ref().unwrap().dof,
        (FACES - 1) * (n - 2),
        "the one test is of the others"
    );
    let inside: Vec<usize> = (1..n)
        .filter(|&r| kc.degrees_of_equivalence[r].in_reference)
        .collect();
    let v: Vec<DMatrix<f64>> = inside.iter().map(|&r| closed_cov(&u[r])).collect();
    let x: Vec<Vec<f64>> = inside.iter().map(|&r| values[r].clone()).collect();
    let g = gls(&x, &v);
    let v0 = closed_cov(&u[0]);
    for f in 0..FACES {
        assert!((kc.reference[f] - others.reference[f]).abs() < 1e-12);
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        let d = closed(&values[0])[f] - g.reference[f];
        assert!((kc.degrees_of_equivalence[0].d[f] - d).abs() < 1e-12);
        let expected = 2.0 * (v0[(f, f)] + g.covariance[(f, f)]).sqrt();
        assert!((kc.degrees_of_equivalence[0].expanded_u[f] - expected).abs() < 1e-12);
    }
    // refused: a name that is no laboratory's, one also held in, too few left
    let refuse = |options: KcOptions| evaluate(&labs, &[], &options).unwrap_err().to_string();
    assert!(refuse(KcOptions::new().with_not_in_reference(["X"])).contains("\"X\""));
    assert!(
        refuse(
            KcOptions::new()
                .with_keep(["L1"])
                .with_not_in_reference(["L1"])
        )
        .contains("both held in")
    );
    let all_but_one: Vec<String> = (1..n).map(|i| format!("L{i}")).collect();
    assert!(refuse(KcOptions::new().with_not_in_reference(all_but_one)).contains("at least 2"));
}

/// Mandel–Paule: τ per face equals the paper's own iteration (an independent algorithm:
/// Newton steps, where the library bisects), the χ² with the widened u equals n − 1 where
/// τ > 0, and the reference is the closed GLS with every variance widened by τ².
#[test]
fn kc_mandel_paule_matches_its_iteration_and_its_defining_equation() {
    let (mut values, u) = fixed_data(false);
    spread_beyond_u(&mut values);
    let labs: Vec<LabResult> = (0..5)
        .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
        .collect();
    let options = KcOptions::new().with_method(ReferenceMethod::MandelPaule);
    let kc = evaluate(&labs, &[], &options).unwrap();
    assert!(kc.excluded.is_empty());
    let dl = evaluate(
        &labs,
        &[],
        &KcOptions::new().with_method(ReferenceMethod::DersimonianLaird),
    )
    .unwrap();
    let mut positive = 0;
    for f in 0..FACES {
        let x: Vec<f64> = values.iter().map(|v| v[f]).collect();
        let s: Vec<f64> = u.iter().map(|v| v[f]).collect();
        let (tau, _, _) = textbook_mandel_paule(&x, &s);
        assert!(
            (kc.tau[f] - tau).abs() < 1e-9 * tau.max(1e-3),
            "{} vs {tau}",
            kc.tau[f]
        );
        if tau > 0.0 {
            // the library's τ solves Σ (x_i − x̄)²/(u_i² + τ²) = n − 1 about the weighted mean
            positive += 1;
            let t2 = kc.tau[f] * kc.tau[f];
            let w: Vec<f64> = s.iter().map(|u| 1.0 / (u * u + t2)).collect();
            let mean = x.iter().zip(&w).map(|(x, w)| x * w).sum::<f64>() / w.iter().sum::<f64>();
            let chi2: f64 = x.iter().zip(&w).map(|(x, w)| w * (x - mean).powi(2)).sum();
            assert!((chi2 - 4.0).abs() < 1e-9, "face {}: {chi2}", f + 1);
        }
        // τ is 0 for both estimators on the same faces (both when Q ≤ n − 1)
        assert_eq!(kc.tau[f] == 0.0, dl.tau[f] == 0.0);
    }
    assert!(positive >= 6, "τ > 0 on {positive} faces only");
    // the reference: the dense closed GLS with every variance widened by τ²
    let v: Vec<DMatrix<f64>> = u
        .iter()
        .map(|u| {
            closed_cov(
                &u.iter()
                    .zip(&kc.tau)
                    .map(|(u, t)| u.hypot(*t))
                    .collect::<Vec<_>>(),
            )
        })
        .collect();
    let g = gls(&values, &v);
    for f in 0..FACES {
        assert!((kc.reference[f] - g.reference[f]).abs() < 1e-12);
        assert!((kc.reference_u[f] - g.covariance[(f, f)].sqrt()).abs() < 1e-12);
    }
    assert_eq!(kc.vector_all, dl.vector_all);
    assert_eq!(kc.comparison_consistent, dl.comparison_consistent);
    assert!(kc.verdict_statement().contains("Mandel–Paule"));
    assert_eq!("mandel-paule".parse(), Ok(ReferenceMethod::MandelPaule));
}

/// A comparison's JSON with two faces, written by hand: `labs` as (name, d, u(d), in the
/// reference), the same on both faces but for the sign of d (closed), and u_ref.
fn two_face_comparison(
    labs: &[(&str, f64, f64, bool)],
    reference_u: f64,
) -> polycal::kc::KeyComparison {
    let doe: Vec<String> = labs
        .iter()
        .map(|(name, d, u, inside)| {
            format!(
                r#"{{"lab": "{name}", "d": [{d}, {}], "U": [{}, {}], "in_reference": {inside}}}"#,
                -d,
                2.0 * u,
                2.0 * u
            )
        })
        .collect();
    let names: Vec<String> = labs.iter().map(|l| format!("\"{}\"", l.0)).collect();
    let text = format!(
        r#"{{"quantity": "pitch_deviation", "method": "weighted-mean", "index": [1, 2],
        "labs": [{}], "reference": [0.0, 0.0], "reference_u": [{reference_u}, {reference_u}],
        "chi2": [0.0, 0.0], "chi2_dof": [1, 1], "chi2_critical": [3.84, 3.84],
        "consistent": [true, true], "vector": null, "excluded": [], "tau": [0.0, 0.0],
        "degrees_of_equivalence": [{}], "pairs": [], "comparison_consistent": true,
        "notes": []}}"#,
        names.join(", "),
        doe.join(", ")
    );
    polycal::kc::read_json(text.as_bytes(), "hand.json").unwrap()
}

/// Linking worked by hand (two faces, two linking laboratories A and B, in both
/// references): on face 1 the offsets are Δ_A = 0.1 − 0 = 0.1, Δ_B = −0.05 − 0.05 = −0.1;
/// C = Cov_CIPM + Cov_RMO = [[0.01 + 0.0064, −0.0025 − 0.0016], [·, 0.0225 + 0.0144]]
/// = [[0.0164, −0.0041], [−0.0041, 0.0369]], det = 5.8835e-4, C⁻¹1 ∝ [0.041, 0.0205], so
/// a = [2/3, 1/3], Δ = 0.1/3, u²(Δ) = det/0.0615; χ² per face 0.2·0.00191333/det, the link's
/// χ² = (N − 1)/N·(both faces) = the one face's, ν = 1. Y (out of the RMO reference):
/// d + Δ, u² = 0.0625 + u²(Δ) (no covariance with A and B in it); A: u² = 0.0064 + u²(Δ)
/// − 2(⅔·0.0064 − ⅓·0.0016) = 0.0085.
#[test]
fn kc_linking_matches_a_hand_worked_two_comparison_case() {
    let cipm = two_face_comparison(
        &[
            ("A", 0.1, 0.1, true),
            ("B", -0.05, 0.15, true),
            ("X", 0.0, 0.2, true),
        ],
        0.05,
    );
    let mut rmo = two_face_comparison(
        &[
            ("A", 0.0, 0.08, true),
            ("B", 0.05, 0.12, true),
            ("Y", 0.2, 0.25, false),
        ],
        0.04,
    );
    polycal::kc::link(&mut rmo, &cipm).unwrap();
    let link = rmo.link.as_ref().unwrap();
    assert_eq!(link.labs, ["A", "B"]);
    let det = 0.0164 * 0.0369 - 0.0041 * 0.0041;
    let u_delta = (det / 0.0615f64).sqrt();
    assert!((link.correction[0] - 0.1 / 3.0).abs() < 1e-12);
    assert!((link.correction[1] + 0.1 / 3.0).abs() < 1e-12);
    assert!((link.correction_u[0] - u_delta).abs() < 1e-12);
    let chi2_face = 0.2 * (0.0369 * (0.2 / 3.0) - 0.0041 * (0.4 / 3.0)) / det;
    let vector = link.vector.as_ref().unwrap();
    assert!(
        (vector.chi2 - chi2_face).abs() < 1e-9,
        "{} vs {chi2_face}",
        vector.chi2
    );
    assert_eq!(vector.dof, 1);
    assert!(vector.consistent);
    let y = &rmo.degrees_of_equivalence[2];
    let d = y.d_linked.as_ref().unwrap();
    let u = y.expanded_u_linked.as_ref().unwrap();
    assert!((d[0] - (0.2 + 0.1 / 3.0)).abs() < 1e-12);
    assert!((u[0] - 2.0 * (0.0625 + u_delta * u_delta).sqrt()).abs() < 1e-12);
    let a = &rmo.degrees_of_equivalence[0];
    assert!((a.expanded_u_linked.as_ref().unwrap()[0] - 2.0 * 0.0085f64.sqrt()).abs() < 1e-12);
    // Y's U with a Welch–Satterthwaite k = 2.5: u(d) = U/k is the same 0.25, so is U_linked
    let mut with_k = two_face_comparison(
        &[
            ("A", 0.0, 0.08, true),
            ("B", 0.05, 0.12, true),
            ("Y", 0.2, 0.25, false),
        ],
        0.04,
    );
    with_k.degrees_of_equivalence[2].k = Some(vec![2.5, 2.5]);
    with_k.degrees_of_equivalence[2].expanded_u = vec![2.5 * 0.25; 2];
    polycal::kc::link(&mut with_k, &cipm).unwrap();
    let y_k = with_k.degrees_of_equivalence[2]
        .expanded_u_linked
        .as_ref()
        .unwrap();
    assert!((y_k[0] - u[0]).abs() < 1e-12, "{} vs {}", y_k[0], u[0]);
    // refused: another quantity, no laboratory in both
    let lonely = two_face_comparison(&[("P", 0.0, 0.1, true), ("Q", 0.0, 0.1, true)], 0.05);
    let mut again = two_face_comparison(&[("A", 0.0, 0.08, true), ("Y", 0.2, 0.25, true)], 0.04);
    assert!(
        polycal::kc::link(&mut again, &lonely)
            .unwrap_err()
            .to_string()
            .contains("no laboratory")
    );
}

/// Monte Carlo U: for the weighted mean the draws are normal and give the formulas' U(d_i)
/// = 2·√(u_i² ∓ u_ref²) and u_ref within 3 % (the 95.45 % quantile of 20 000 draws has a
/// relative standard error of 0.7 %); for DerSimonian–Laird, τ estimated again in every
/// draw widens U beyond the formula's on average; the same inputs give the same U; refusals.
#[test]
fn kc_monte_carlo_u_is_the_formulas_for_the_weighted_mean_and_wider_with_tau() {
    let (mut values, u) = fixed_data(false);
    let labs = |values: &[Vec<f64>]| -> Vec<LabResult> {
        (0..5)
            .map(|i| lab(&format!("L{i}"), &values[i], &u[i]))
            .collect()
    };
    let plain = evaluate(&labs(&values), &[], &KcOptions::new()).unwrap();
    let options = KcOptions::new().with_monte_carlo(20_000);
    let drawn = evaluate(&labs(&values), &[], &options).unwrap();
    for (a, b) in plain
        .degrees_of_equivalence
        .iter()
        .zip(&drawn.degrees_of_equivalence)
    {
        assert_eq!(a.d, b.d);
        for (x, y) in a.expanded_u.iter().zip(&b.expanded_u) {
            assert!((y / x - 1.0).abs() < 0.03, "{} {x} vs {y}", a.lab);
        }
    }
    for (x, y) in plain.reference_u.iter().zip(&drawn.reference_u) {
        assert!((y / x - 1.0).abs() < 0.03, "u_ref {x} vs {y}");
    }
    assert!(
        drawn
            .notes
            .iter()
            .any(|n| n.contains("Monte Carlo: 20000 draws"))
    );
    assert_eq!(
        drawn,
        evaluate(&labs(&values), &[], &options).unwrap(),
        "seeded"
    );
    // DerSimonian–Laird with spread laboratories: τ's own uncertainty widens U
    spread_beyond_u(&mut values);
    let dl = KcOptions::new().with_method(ReferenceMethod::DersimonianLaird);
    let formula = evaluate(&labs(&values), &[], &dl).unwrap();
    let drawn = evaluate(&labs(&values), &[], &dl.clone().with_monte_carlo(20_000)).unwrap();
    let ratios: Vec<f64> = formula
        .degrees_of_equivalence
        .iter()
        .zip(&drawn.degrees_of_equivalence)
        .flat_map(|(a, b)| a.expanded_u.iter().zip(&b.expanded_u).map(|(x, y)| y / x))
        .collect();
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    eprintln!("DerSimonian–Laird: Monte Carlo U / formula U, mean {mean:.3}");
    assert!(mean > 1.03 && mean < 2.0, "{mean}");
    // refusals
    let refused = |options: KcOptions| {
        evaluate(&labs(&values), &[], &options)
            .unwrap_err()
            .to_string()
    };
    assert!(refused(KcOptions::new().with_monte_carlo(10)).contains("at least 1000"));
    assert!(refused(KcOptions::new().with_monte_carlo(1_000_000)).contains("fewer draws"));
}

/// Welch–Satterthwaite by hand: three laboratories of one u each (A 0.1″ with ν = 4, B
/// 0.2″ with none stated, C 0.1″ with ν = 9), four faces. Weights 100 : 25 : 100, so
/// w' = 4/9, 1/9, 4/9; A's d = 5/9 x_A − 1/9 x_B − 4/9 x_C, u_c² = (25·0.01 + 0.04 +
/// 16·0.01)/81 = u_A² − u_ref², ν_eff = u_c⁴ / ((25/81·0.01)²/4 + (16/81·0.01)²/9) = 10.96,
/// k = t_95.45(ν_eff) between the GUM's 2.28 (ν = 10) and 2.13 (ν = 20).
#[test]
fn kc_stated_degrees_of_freedom_give_each_u_its_welch_satterthwaite_k() {
    let values = [
        [0.1, -0.05, 0.0, -0.05],
        [0.2, -0.1, -0.1, 0.0],
        [0.05, 0.0, -0.02, -0.03],
    ];
    let stated = [(0.1, Some(4.0)), (0.2, None), (0.1, Some(9.0))];
    let labs: Vec<LabResult> = ["A", "B", "C"]
        .iter()
        .zip(values.iter().zip(stated))
        .map(|(name, (x, (u, dof)))| {
            let rows = (0..4)
                .map(|f| {
                    let row =
                        ResultRow::new(Quantity::PitchDeviation, f as u32 + 1, x[f]).with_u(u);
                    match dof {
                        Some(dof) => row.with_dof(dof),
                        None => row,
                    }
                })
                .collect();
            LabResult::from_rows(*name, rows)
        })
        .collect();
    let kc = evaluate(&labs, &[], &KcOptions::new()).unwrap();
    let plain = {
        let no_dof: Vec<LabResult> = values
            .iter()
            .zip(stated)
            .zip(["A", "B", "C"])
            .map(|((x, (u, _)), name)| lab(name, x, &[u; 4]))
            .collect();
        evaluate(&no_dof, &[], &KcOptions::new()).unwrap()
    };
    let u_c2: f64 = (25.0 * 0.01 + 0.04 + 16.0 * 0.01) / 81.0;
    let nu = u_c2 * u_c2
        / ((25.0 / 81.0 * 0.01f64).powi(2) / 4.0 + (16.0 / 81.0 * 0.01f64).powi(2) / 9.0);
    let a = &kc.degrees_of_equivalence[0];
    let k_expected = statrs::distribution::StudentsT::new(0.0, 1.0, nu)
        .map(|t| statrs::distribution::ContinuousCDF::inverse_cdf(&t, 0.5 + 0.9545 / 2.0))
        .unwrap();
    assert!(k_expected > 2.24 && k_expected < 2.28, "{k_expected}");
    for f in 0..4 {
        let got = a.dof_effective.as_ref().unwrap()[f].unwrap();
        assert!((got - nu).abs() < 1e-9 * nu, "{got} vs {nu}");
        assert!((a.k.as_ref().unwrap()[f] - k_expected).abs() < 1e-9);
        // U = k·u(d), u(d) the formula's: U/2 of the run without dof
        let expected = k_expected * plain.degrees_of_equivalence[0].expanded_u[f] / 2.0;
        assert!((a.expanded_u[f] - expected).abs() < 1e-12);
        assert!((plain.degrees_of_equivalence[0].expanded_u[f] - 2.0 * u_c2.sqrt()).abs() < 1e-12);
    }
    // B states none, but its d has A's and C's parts: ν_eff finite, k above 2
    assert!(kc.degrees_of_equivalence[1].k.as_ref().unwrap()[0] > 2.0);
    assert!(plain.degrees_of_equivalence[0].k.is_none());
}
