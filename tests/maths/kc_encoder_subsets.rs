//! Encoder errors compared on the positions each laboratory reports (`polycal kc
//! --quantity encoder_error`, docs/FORMAT.md §12, "What each laboratory measured"):
//! against the independent dense implementation of `kc_support::encoder` (each
//! laboratory's closed vector over its own positions, the GLS A = Σ M_iᵀ V_i⁺ M_i with
//! pseudo-inverses by eigen-decomposition, U = 2√diag(V_i ∓ P_S M_i C M_iᵀ P_S)) on seeded
//! random designs, the textbook per-position weighted mean on full data, the search
//! against a brute-force one, and the refusals. The verdicts' rates are in
//! `tests/sweeps/kc_encoder_subsets_rates.rs`.

// The hand calculations are written with indices, as the textbooks write them.
#![allow(clippy::needless_range_loop)]

use crate::kc_support::encoder::{
    Design, Encoder, angle_of, degree_of_equivalence, draw, largest_subset, pair_covariance,
    pair_test, subset_gls,
};
use polycal::kc::{KcError, KcOptions, KeyComparison, LabResult, ReferenceMethod, evaluate, link};
use polycal::results::{Quantity, ResultRow, read_results_from};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn encoder() -> KcOptions {
    KcOptions::new().with_quantity(Quantity::EncoderError)
}

/// Every laboratory in the reference (no search).
fn everyone() -> KcOptions {
    encoder().with_largest_consistent_subset(false)
}

/// Within 1e-9 of `expected` relative to the larger of |expected| and 0.01 (″ or χ²), or
/// both NaN.
fn close(got: f64, expected: f64, what: &str) {
    if expected.is_nan() {
        assert!(got.is_nan(), "{what}: {got}, expected none (NaN)");
        return;
    }
    assert!(
        (got - expected).abs() <= 1e-9 * expected.abs().max(0.01),
        "{what}: {got} vs {expected} (dense)"
    );
}

/// A random design: 4–7 laboratories, 8–16 positions, each missing 0–4 of them (every
/// position reported by at least 2), u 0.05–0.2″ per laboratory and position; one
/// laboratory 4u off on 2 positions in every third design.
fn random_design(rng: &mut ChaCha8Rng, trial: usize) -> Encoder {
    let design = Design {
        positions: rng.random_range(8..=16),
        labs: rng.random_range(4..=7),
        missing: 0.0,
        missing_count: Some(4),
        u_range: (0.05, 0.2),
        equal_u: false,
        closed_noise: false,
    };
    let biased = rng.random_range(0..design.labs);
    let at = [
        rng.random_range(0..design.positions),
        rng.random_range(0..design.positions),
    ];
    let bias = trial.is_multiple_of(3).then_some((biased, &at[..], 4.0));
    draw(rng, design, bias)
}

/// The comparison `kc` of `data` with the laboratories `inside` in the reference, against
/// the dense GLS: the reference, its u, the one test of `candidates` (`vector_all`), the
/// per-position χ², every degree of equivalence (in and out of the reference) and every
/// pair's test.
fn check_against_dense(kc: &KeyComparison, data: &Encoder, candidates: &[usize], inside: &[usize]) {
    let positions = data.positions();
    let labs = data.names.len();
    let all = subset_gls(data, candidates).expect("the candidates link every position");
    let vector_all = kc.vector_all.as_ref().unwrap();
    close(vector_all.chi2, all.chi2, "vector_all χ²");
    assert_eq!(vector_all.dof, all.dof, "vector_all ν");
    let n_sum: usize = candidates.iter().map(|&i| data.reported(i).len()).sum();
    assert_eq!(all.dof, n_sum - candidates.len() - (positions - 1));
    let fit = subset_gls(data, inside).unwrap();
    let vector = kc.vector.as_ref().unwrap();
    close(vector.chi2, fit.chi2, "vector χ²");
    assert_eq!(vector.dof, fit.dof);
    assert_eq!(kc.reference.len(), positions);
    for k in 0..positions {
        close(kc.reference[k], fit.reference[k], &format!("x_ref at {k}"));
        close(
            kc.reference_u[k],
            fit.covariance[(k, k)].sqrt(),
            &format!("u_ref at {k}"),
        );
        // the per-position χ² (information): the weighted mean of the values of the
        // laboratories inside that report k, each closed over its own positions and put
        // on the reference's level (less its mean difference from x_ref there)
        let (mut sw, mut swx) = (0.0, 0.0);
        let mut reporting = Vec::new();
        for &i in inside {
            if data.x[i][k].is_some() {
                let s = data.reported(i);
                let closed = data.closed(i);
                let level = s
                    .iter()
                    .zip(&closed)
                    .map(|(&q, x)| x - fit.reference[q])
                    .sum::<f64>()
                    / s.len() as f64;
                let x = closed[s.iter().position(|&q| q == k).unwrap()] - level;
                let w = 1.0 / data.u[i][k].powi(2);
                sw += w;
                swx += w * x;
                reporting.push((x, w));
            }
        }
        let mean = swx / sw;
        let chi2: f64 = reporting.iter().map(|(x, w)| w * (x - mean).powi(2)).sum();
        close(kc.chi2[k], chi2, &format!("χ² at {k}"));
        assert_eq!(kc.chi2_dof[k], reporting.len() - 1);
    }
    let sum: f64 = fit.reference.iter().sum();
    assert!(sum.abs() < 1e-12, "Σ x_ref = {sum}");
    for i in 0..labs {
        let doe = &kc.degrees_of_equivalence[i];
        let is_in = inside.contains(&i);
        assert_eq!(doe.lab, data.names[i]);
        assert_eq!(doe.in_reference, is_in, "{}", doe.lab);
        let (d, u) = degree_of_equivalence(data, &fit, i, is_in);
        for k in 0..positions {
            close(doe.d[k], d[k], &format!("d of {} at {k}", doe.lab));
            close(doe.expanded_u[k], u[k], &format!("U of {} at {k}", doe.lab));
        }
        let sum_d: f64 = doe.d.iter().filter(|d| d.is_finite()).sum();
        assert!(sum_d.abs() < 1e-12, "Σ d of {} = {sum_d}", doe.lab);
    }
    for pair in &kc.pairs {
        let a = data.names.iter().position(|n| *n == pair.a).unwrap();
        let b = data.names.iter().position(|n| *n == pair.b).unwrap();
        match pair_test(data, a, b) {
            None => assert!(pair.vector.is_none(), "{}–{}", pair.a, pair.b),
            Some((chi2, dof, d)) => {
                let test = pair.vector.as_ref().unwrap();
                close(test.chi2, chi2, &format!("χ² of {}–{}", pair.a, pair.b));
                assert_eq!(test.dof, dof, "ν of {}–{}", pair.a, pair.b);
                for k in 0..positions {
                    close(
                        pair.d[k],
                        d[k],
                        &format!("d of {}–{} at {k}", pair.a, pair.b),
                    );
                }
            }
        }
    }
}

/// Seeded random designs (4–7 laboratories, 8–16 positions, each missing 0–4): the
/// reference, u_ref, χ², ν, every d and U and every pair's χ² and ν are the dense GLS's to
/// 1e-9, with every laboratory in the reference and with one kept out of it; the positions
/// matched by angle (one laboratory's angles 4·10⁻⁷° off, its position 0 given as
/// 359.9999996°) or, without angles, by index.
#[test]
fn kc_encoder_subsets_are_the_dense_gls() {
    let mut rng = ChaCha8Rng::seed_from_u64(9101);
    let mut missing_seen = 0;
    let mut kept_out_checked = 0;
    for trial in 0..40 {
        let data = random_design(&mut rng, trial);
        let positions = data.positions();
        let labs = data.names.len();
        missing_seen += data.x.iter().flatten().filter(|x| x.is_none()).count();
        let mut results = data.results();
        // laboratory 1's angles a little off (within 10⁻⁶°), the circle's 0 as 360 − ε
        for row in &mut results[1].rows {
            let angle = row.angle_deg.unwrap();
            row.angle_deg = Some(if angle == 0.0 {
                360.0 - 4e-7
            } else {
                angle + 4e-7
            });
        }
        let kc = evaluate(&results, &[], &everyone()).unwrap();
        let expected: Vec<f64> = (0..positions)
            .map(|k| {
                let first = (0..labs).find(|&i| data.x[i][k].is_some()).unwrap();
                match (first, k) {
                    (1, 0) => 360.0 - 4e-7,
                    (1, _) => angle_of(k, positions) + 4e-7,
                    _ => angle_of(k, positions),
                }
            })
            .collect();
        assert_eq!(kc.angle_deg.as_deref(), Some(&expected[..]));
        let all: Vec<usize> = (0..labs).collect();
        check_against_dense(&kc, &data, &all, &all);

        // by index: the same comparison
        let by_index: Vec<LabResult> = (0..labs)
            .map(|i| {
                let rows = data
                    .reported(i)
                    .iter()
                    .map(|&k| {
                        ResultRow::new(Quantity::EncoderError, k as u32 + 1, data.x[i][k].unwrap())
                            .with_u(data.u[i][k])
                    })
                    .collect();
                LabResult::from_rows(data.names[i].clone(), rows)
            })
            .collect();
        let kc_index = evaluate(&by_index, &[], &everyone()).unwrap();
        assert!(kc_index.angle_deg.is_none());
        assert_eq!(kc_index.index, (1..=positions as u32).collect::<Vec<_>>());
        check_against_dense(&kc_index, &data, &all, &all);

        // one laboratory kept out of the reference: one whose absence leaves every
        // position reported and linked
        let start = rng.random_range(0..labs);
        let out = (0..labs).map(|j| (start + j) % labs).find(|&o| {
            let rest: Vec<usize> = all.iter().copied().filter(|&i| i != o).collect();
            (0..positions).all(|k| rest.iter().any(|&i| data.x[i][k].is_some()))
                && subset_gls(&data, &rest).is_some()
        });
        if let Some(out) = out {
            let rest: Vec<usize> = all.iter().copied().filter(|&i| i != out).collect();
            let options = everyone().with_not_in_reference([data.names[out].clone()]);
            let kc = evaluate(&results, &[], &options).unwrap();
            assert_eq!(kc.not_in_reference, [data.names[out].clone()]);
            check_against_dense(&kc, &data, &rest, &rest);
            kept_out_checked += 1;
        }
    }
    assert!(missing_seen > 40, "{missing_seen} positions missing in all");
    assert!(kept_out_checked >= 30, "{kept_out_checked}");
}

/// On the same designs with the search on, the laboratories in the reference are those of
/// a brute-force search over every subset with the dense GLS's χ² (the most consistent of
/// a size by the p-value when ν differ), and every number is the dense GLS's of them.
#[test]
fn kc_encoder_subsets_the_search_is_the_brute_force_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(9102);
    let mut searched = 0;
    for trial in 0..30 {
        let mut data = random_design(&mut rng, 3 * trial);
        // a second laboratory 5u off on 3 positions in half of them
        if trial % 2 == 0 {
            let labs = data.names.len();
            let other = (trial / 2) % labs;
            for k in data.reported(other).into_iter().take(3) {
                let shift = 5.0 * data.u[other][k];
                data.x[other][k] = data.x[other][k].map(|x| x + shift);
            }
        }
        let kc = evaluate(&data.results(), &[], &encoder()).unwrap();
        let labs = data.names.len();
        let inside: Vec<usize> = (0..labs)
            .filter(|&i| kc.degrees_of_equivalence[i].in_reference)
            .collect();
        assert_eq!(inside, largest_subset(&data), "trial {trial}");
        searched += usize::from(kc.search.is_some());
        let all: Vec<usize> = (0..labs).collect();
        check_against_dense(&kc, &data, &all, &inside);
    }
    assert!(searched >= 10, "{searched} searches");
}

/// Full data with one u per laboratory: the numbers of a comparison of every position,
/// the textbook per-position weighted mean of the values less their mean — x_ref, u_ref =
/// (Σ 1/u_i²)^(−1/2), d = x_i − x_ref, U = 2√(u_i² − u_ref²), ν = (K − 1)(n − 1).
#[test]
fn kc_encoder_full_data_is_the_per_position_weighted_mean() {
    let mut rng = ChaCha8Rng::seed_from_u64(9103);
    for _ in 0..10 {
        let design = Design {
            positions: rng.random_range(8..=16),
            labs: rng.random_range(4..=7),
            missing: 0.0,
            missing_count: Some(0),
            u_range: (0.05, 0.2),
            equal_u: true,
            closed_noise: false,
        };
        let data = draw(&mut rng, design, None);
        let (positions, labs) = (design.positions, design.labs);
        let kc = evaluate(&data.results(), &[], &everyone()).unwrap();
        let x: Vec<Vec<f64>> = (0..labs)
            .map(|i| {
                let mean = data.x[i].iter().map(|x| x.unwrap()).sum::<f64>() / positions as f64;
                data.x[i].iter().map(|x| x.unwrap() - mean).collect()
            })
            .collect();
        assert_eq!(
            kc.vector_all.as_ref().unwrap().dof,
            (positions - 1) * (labs - 1)
        );
        let mut chi2 = 0.0;
        for k in 0..positions {
            let (mut sw, mut swx) = (0.0, 0.0);
            for i in 0..labs {
                let w = 1.0 / data.u[i][k].powi(2);
                sw += w;
                swx += w * x[i][k];
            }
            let (mean, u_ref) = (swx / sw, 1.0 / sw.sqrt());
            close(kc.reference[k], mean, "x_ref");
            close(kc.reference_u[k], u_ref, "u_ref");
            for i in 0..labs {
                let doe = &kc.degrees_of_equivalence[i];
                close(doe.d[k], x[i][k] - mean, "d");
                let u = data.u[i][k];
                close(doe.expanded_u[k], 2.0 * (u * u - u_ref * u_ref).sqrt(), "U");
                chi2 += (x[i][k] - mean).powi(2) / (u * u);
            }
        }
        // with one u per laboratory V_i⁺ = P/(c·u_i²), c = K/(K − 1), and the residuals are
        // closed: the closed χ² is (K − 1)/K times the sum of the per-position ones
        let c = positions as f64 / (positions - 1) as f64;
        close(kc.vector_all.as_ref().unwrap().chi2, chi2 / c, "χ²");
        for pair in &kc.pairs {
            let test = pair.vector.as_ref().unwrap();
            assert_eq!(test.dof, positions - 1);
        }
    }
}

/// Rows of encoder errors at `angles` (degrees) with `values`, u = 0.1″.
fn at(name: &str, angles: &[f64], values: &[f64]) -> LabResult {
    let rows = angles
        .iter()
        .zip(values)
        .enumerate()
        .map(|(p, (&angle, &x))| {
            ResultRow::new(Quantity::EncoderError, p as u32 + 1, x)
                .with_u(0.1)
                .with_angle_deg(angle)
        })
        .collect();
    LabResult::from_rows(name, rows)
}

/// A position one laboratory reports alone is left out and named "(by B only)"; a
/// laboratory with fewer than 2 positions compared is refused; Monte Carlo U is drawn; a
/// link through a laboratory with missing positions is made, and refused only where a
/// position has no linking laboratory or the linking ones share no position; a pilot's repeat
/// missing a position kept is refused at its last encoder_error row's file:line:column.
#[test]
fn kc_encoder_subsets_left_out_and_refused() {
    let quarter = [0.0, 90.0, 180.0, 270.0];
    let a = at("A", &quarter, &[0.1, 0.2, 0.3, 0.4]);
    let b = at(
        "B",
        &[0.0, 45.0, 90.0, 180.0, 270.0],
        &[0.12, 9.0, 0.18, 0.33, 0.41],
    );
    // C without 90°: compared on 0°, 180°, 270°
    let c = at("C", &[0.0, 180.0, 270.0], &[5.11, 5.29, 5.38]);
    let kc = evaluate(&[a.clone(), b.clone(), c.clone()], &[], &encoder()).unwrap();
    assert_eq!(kc.angle_deg.as_deref(), Some(&quarter[..]));
    let note = kc
        .notes
        .iter()
        .find(|n| n.contains("reported by fewer than two laboratories left out"))
        .unwrap_or_else(|| panic!("{:#?}", kc.notes));
    assert!(note.contains("45° (by B only)"), "{note}");
    assert!(note.contains("1 position(s)"), "{note}");
    let c_doe = &kc.degrees_of_equivalence[2];
    assert!(c_doe.d[1].is_nan() && c_doe.expanded_u[1].is_nan());
    assert!(
        c_doe
            .d
            .iter()
            .enumerate()
            .all(|(k, d)| k == 1 || d.is_finite())
    );
    // ν = Σ N_i − n − (K − 1) = 4 + 4 + 3 − 3 − 3
    assert_eq!(kc.vector_all.as_ref().unwrap().dof, 5);

    // a laboratory whose positions are compared once: 0° only (135° is its alone)
    let lone = at("D", &[0.0, 135.0], &[0.0, 0.1]);
    match evaluate(&[a.clone(), b.clone(), lone], &[], &encoder()) {
        Err(
            e @ KcError::LabNotCompared {
                compared: 1,
                needed: 2,
                ..
            },
        ) => {
            let message = e.to_string();
            assert!(
                message.starts_with(
                    "D (laboratory D): 1 of its encoder_error positions compared, fewer than 2"
                ),
                "{message}"
            );
        }
        other => panic!("expected LabNotCompared, got {other:?}"),
    }

    // Monte Carlo U over different positions: the draws are made (each result's noise
    // closed over its own positions), with every position reported too
    let c_full = at("C", &quarter, &[5.11, 5.2, 5.29, 5.38]);
    let full = [a.clone(), b.clone(), c_full.clone()];
    assert!(evaluate(&full, &[], &encoder().with_monte_carlo(2000)).is_ok());
    assert!(
        evaluate(
            &[a.clone(), b.clone(), c.clone()],
            &[],
            &encoder().with_monte_carlo(2000)
        )
        .is_ok()
    );

    // a link through C alone, which misses 90° here, is refused: no linking laboratory
    // reports 90° in both, so Δ there is not determined
    let x = at("X", &quarter, &[-0.1, 0.0, 0.05, 0.05]);
    let linked = evaluate(&[a.clone(), c_full.clone(), x.clone()], &[], &encoder()).unwrap();
    let z = at("Z", &quarter, &[0.2, 0.1, 0.0, 0.1]);
    let mut this = evaluate(&[b.clone(), c.clone(), z.clone()], &[], &encoder()).unwrap();
    assert_eq!(this.angle_deg.as_deref(), Some(&quarter[..]));
    match link(&mut this, &linked) {
        Err(KcError::Link(reason)) => {
            assert!(
                reason.starts_with("no linking laboratory reports 90° in both comparisons"),
                "{reason}"
            );
        }
        other => panic!("expected Link, got {other:?}"),
    }
    // through A and C it is made, C's d_linked closed over its three positions
    let mut through_a_c = evaluate(&[a.clone(), c.clone(), z.clone()], &[], &encoder()).unwrap();
    link(&mut through_a_c, &linked).unwrap();
    assert_eq!(through_a_c.link.as_ref().unwrap().labs, ["A", "C"]);
    let c_linked = through_a_c.degrees_of_equivalence[1]
        .d_linked
        .clone()
        .unwrap();
    assert!(c_linked[1].is_nan());
    assert!((c_linked[0] + c_linked[2] + c_linked[3]).abs() < 1e-12);
    // A on 0° and 90° only and C on 180° and 270° only in the linked comparison: every
    // position is linked, but the two laboratories share none — refused, naming them
    let linked_apart = evaluate(
        &[
            at("A", &[0.0, 90.0], &[0.1, 0.2]),
            at("C", &[180.0, 270.0], &[5.29, 5.38]),
            x,
            at("W", &quarter, &[0.0, 0.1, 0.0, -0.1]),
        ],
        &[],
        &encoder(),
    )
    .unwrap();
    let mut full = evaluate(&[a.clone(), c_full.clone(), z.clone()], &[], &encoder()).unwrap();
    match link(&mut full, &linked_apart) {
        Err(KcError::Link(reason)) => {
            assert!(
                reason.starts_with(
                    "the linking laboratories fall into groups that share no position ({A} and {C})"
                ),
                "{reason}"
            );
        }
        other => panic!("expected Link, got {other:?}"),
    }
    let y = at("Y", &[0.0, 90.0, 270.0], &[0.3, 0.2, 0.0]);
    let mut through_a = evaluate(&[a.clone(), y, z], &[], &encoder()).unwrap();
    assert_eq!(through_a.angle_deg.as_deref(), Some(&quarter[..]));
    link(&mut through_a, &linked).unwrap();
    assert_eq!(through_a.link.as_ref().unwrap().labs, ["A"]);

    // a pilot's repeat without 180°: at its last encoder_error row's index
    let file = |source: &str, text: &str| {
        LabResult::from_file(source, read_results_from(text.as_bytes(), source).unwrap())
    };
    let start = file(
        "start.csv",
        "quantity,index,value,u,angle_deg\n\
         encoder_error,1,0.10,0.05,0\n\
         encoder_error,2,0.20,0.05,90\n\
         encoder_error,3,0.30,0.05,180\n\
         encoder_error,4,0.40,0.05,270\n",
    );
    let end = file(
        "end.csv",
        "quantity,index,value,u,angle_deg\n\
         encoder_error,1,0.11,0.05,0\n\
         encoder_error,2,0.21,0.05,90\n\
         encoder_error,4,0.41,0.05,270\n",
    );
    match evaluate(&[a, b, c], &[start, end], &encoder()) {
        Err(e @ KcError::RepeatMissesPosition { .. }) => {
            let message = e.to_string();
            // line 4, the index field (after "encoder_error,": column 15)
            assert!(
                message.starts_with(
                    "end.csv:4:15: the pilot's repeat end.csv has no encoder_error at 180°"
                ),
                "{message}"
            );
        }
        other => panic!("expected RepeatMissesPosition, got {other:?}"),
    }
}

/// DerSimonian–Laird on designs with missing positions (a third with a laboratory 4u off on
/// 2 positions) runs, leaves nobody out, and its verdict is the weighted mean's
/// `vector_all`.
#[test]
fn kc_encoder_subsets_dersimonian_laird_verdict_is_vector_all() {
    let mut rng = ChaCha8Rng::seed_from_u64(9104);
    let (mut consistent, mut not) = (0, 0);
    for trial in 0..30 {
        let data = random_design(&mut rng, trial);
        let results = data.results();
        let wm = evaluate(&results, &[], &encoder()).unwrap();
        let dl = evaluate(
            &results,
            &[],
            &encoder().with_method(ReferenceMethod::DersimonianLaird),
        )
        .unwrap();
        let all = wm.vector_all.as_ref().unwrap();
        assert_eq!(dl.vector_all.as_ref(), Some(all));
        // the test of τ = 0 is the dense GLS's of every laboratory
        let everyone: Vec<usize> = (0..data.names.len()).collect();
        let dense = subset_gls(&data, &everyone).unwrap();
        close(all.chi2, dense.chi2, "vector_all χ²");
        assert_eq!(all.dof, dense.dof);
        assert_eq!(
            all.consistent,
            dense.chi2 <= crate::kc_support::critical(dense.dof)
        );
        assert_eq!(dl.comparison_consistent, all.consistent);
        assert!(dl.excluded.is_empty());
        assert!(dl.reference.iter().all(|r| r.is_finite()));
        for doe in &dl.degrees_of_equivalence {
            for k in 0..data.positions() {
                let i = data.names.iter().position(|n| *n == doe.lab).unwrap();
                assert_eq!(doe.d[k].is_finite(), data.x[i][k].is_some());
                assert_eq!(doe.expanded_u[k].is_finite(), data.x[i][k].is_some());
            }
        }
        if all.consistent {
            consistent += 1;
        } else {
            not += 1;
        }
    }
    assert!(
        consistent > 0 && not > 0,
        "{consistent} consistent, {not} not"
    );
}

/// The pilot's repeats (every position, never in the reference) against a reference of
/// laboratories that report different positions: d and U as a laboratory's out of it.
#[test]
fn kc_encoder_subsets_pilot_repeats_are_out_of_the_reference() {
    let mut rng = ChaCha8Rng::seed_from_u64(9105);
    for trial in 0..10 {
        let data = random_design(&mut rng, trial + 1);
        let positions = data.positions();
        let labs = data.names.len();
        // two repeats on the truth (each with its own zero), u = 0.03″: they agree
        let mut extended = data.clone();
        for (r, zero) in [("start", 1.5), ("end", -2.0)] {
            extended.names.push(r.to_string());
            extended.x.push(
                (0..positions)
                    .map(|k| Some(crate::kc_support::encoder::truth(k, positions) + zero))
                    .collect(),
            );
            extended.u.push(vec![0.03; positions]);
        }
        let results = extended.results();
        let kc = evaluate(&results[..labs], &results[labs..], &everyone()).unwrap();
        let pilot = kc.pilot.as_ref().unwrap();
        assert!(pilot.vector.as_ref().unwrap().consistent);
        assert!(pilot.stability_u.iter().all(|s| *s == 0.0));
        let all: Vec<usize> = (0..labs).collect();
        check_against_dense(&kc, &data, &all, &all);
        let fit = subset_gls(&extended, &all).unwrap();
        for (j, doe) in pilot.degrees_of_equivalence.iter().enumerate() {
            assert!(!doe.in_reference);
            let (d, u) = degree_of_equivalence(&extended, &fit, labs + j, false);
            for k in 0..positions {
                close(doe.d[k], d[k], &format!("d of {} at {k}", doe.lab));
                close(doe.expanded_u[k], u[k], &format!("U of {} at {k}", doe.lab));
            }
        }
    }
}

/// A pair's U is that of its d: d_ab is closed over the M positions both report, and its
/// covariance there is P_M·diag(c_a·u_a² + c_b·u_b²)·P_M (each result's stated closed
/// covariance, c = N/(N − 1) of its own positions, propagated; `pair_covariance`), which is
/// what its test takes too; U(d_ab) is 2√ of that covariance's diagonal, as with full data
/// (before the fix it was 2√(v_a + v_b), each diagonal over its own positions: up to 24 %
/// off on these designs).
#[test]
fn kc_encoder_subsets_a_pairs_u_is_that_of_its_closed_difference() {
    use crate::kc_support::encoder::pair_covariance;
    let mut rng = ChaCha8Rng::seed_from_u64(9101);
    for trial in 0..40 {
        let data = random_design(&mut rng, trial);
        let kc = evaluate(&data.results(), &[], &everyone()).unwrap();
        for pair in &kc.pairs {
            let a = data.names.iter().position(|n| *n == pair.a).unwrap();
            let b = data.names.iter().position(|n| *n == pair.b).unwrap();
            let (v, common) = pair_covariance(&data, a, b);
            for (j, &k) in common.iter().enumerate() {
                let what = format!("U of {}–{} at {k}", pair.a, pair.b);
                close(pair.expanded_u[k], 2.0 * v[(j, j)].sqrt(), &what);
            }
        }
    }
}

/// A laboratory outside the reference that reports a position no laboratory inside
/// reports (there the reference is NaN): its d is closed over the positions it shares with
/// the reference, d = P_S′(x_i − M x_ref) with S′ = S_i ∩ (the reference's positions), and
/// its own variance is its stated closed covariance propagated there,
/// c_i·P_S′·diag(u²)·P_S′ with its own c_i = N_i/(N_i − 1) (`degree_of_equivalence` of the
/// dense support); before the fix d was x_i closed over all of S_i less x_ref (Σ d ≠ 0).
#[test]
fn kc_encoder_subsets_outside_on_a_position_the_reference_lacks() {
    let mut rng = ChaCha8Rng::seed_from_u64(9106);
    let design = Design {
        positions: 8,
        labs: 6,
        missing: 0.0,
        missing_count: Some(0),
        u_range: (0.05, 0.2),
        equal_u: false,
        closed_noise: false,
    };
    let mut data = draw(&mut rng, design, None);
    // position 3 reported by L4 and L5 only, both kept out of the reference
    for i in 0..4 {
        data.x[i][3] = None;
    }
    let options = everyone().with_not_in_reference(["L4", "L5"]);
    let kc = evaluate(&data.results(), &[], &options).unwrap();
    assert!(kc.reference[3].is_nan());
    let inside: Vec<usize> = (0..4).collect();
    let fit = subset_gls(&data, &inside).unwrap();
    for i in 4..6 {
        let doe = &kc.degrees_of_equivalence[i];
        let sum: f64 = doe.d.iter().filter(|d| d.is_finite()).sum();
        assert!(sum.abs() < 1e-12, "Σ d = {sum}");
        let (d, u) = degree_of_equivalence(&data, &fit, i, false);
        for k in 0..8 {
            close(
                doe.d[k],
                d[k],
                &format!("d of {} at {k} (Σ d = {sum})", doe.lab),
            );
            close(doe.expanded_u[k], u[k], &format!("U of {} at {k}", doe.lab));
        }
    }
}

/// Monte Carlo U with laboratories reporting different positions: each draw closes every
/// result's noise over its own positions and the drawn degree of equivalence over them, as
/// the formulas do; with the weighted mean the drawn U(d_i) and u_ref are the formulas'
/// within 5 % (M = 20 000; independent draws, so the quantile's own scatter, about 1 %).
#[test]
fn kc_encoder_subsets_monte_carlo_u_is_the_formulas() {
    let mut rng = ChaCha8Rng::seed_from_u64(9107);
    for trial in 0..3 {
        let data = random_design(&mut rng, trial);
        let drawn = evaluate(&data.results(), &[], &everyone().with_monte_carlo(20_000)).unwrap();
        // the formulas, from the dense GLS of every laboratory written in kc_support
        let everyone_in: Vec<usize> = (0..data.names.len()).collect();
        let fit = subset_gls(&data, &everyone_in).unwrap();
        let ratio_ok = |u_m: f64, u_f: f64, what: &str| {
            assert_eq!(u_f.is_nan(), u_m.is_nan(), "{what}");
            if u_f.is_finite() {
                let ratio = u_m / u_f;
                assert!((ratio - 1.0).abs() < 0.05, "{what}: {ratio}");
            }
        };
        for (i, m) in drawn.degrees_of_equivalence.iter().enumerate() {
            let (_, u_dense) = degree_of_equivalence(&data, &fit, i, true);
            for (k, (&u_f, &u_m)) in u_dense.iter().zip(&m.expanded_u).enumerate() {
                ratio_ok(u_m, u_f, &format!("{} at {k}", m.lab));
            }
        }
        for (k, &u_m) in drawn.reference_u.iter().enumerate() {
            ratio_ok(u_m, fit.covariance[(k, k)].sqrt(), &format!("u_ref at {k}"));
        }
        // the pairs' U drawn too (d_ab closed over the positions both report): 2√diag of
        // the pair's closed covariance
        assert!(drawn.notes.iter().any(|n| n.contains("the pairs' U too")));
        for m in &drawn.pairs {
            let a = data.names.iter().position(|n| *n == m.a).unwrap();
            let b = data.names.iter().position(|n| *n == m.b).unwrap();
            let (cov, common) = pair_covariance(&data, a, b);
            for (k, &u_m) in m.expanded_u.iter().enumerate() {
                let u_f = match common.iter().position(|&q| q == k) {
                    Some(j) if common.len() >= 2 => 2.0 * cov[(j, j)].sqrt(),
                    _ => f64::NAN,
                };
                ratio_ok(u_m, u_f, &format!("{}–{} at {k}", m.a, m.b));
            }
        }
    }
}

/// Laboratories that agree exactly, each with its own zero, reporting different positions
/// of a large encoder error: on one level (each less its mean difference from the
/// reference over its own positions) they coincide, so every per-position χ² is 0 and
/// DerSimonian–Laird's and Mandel–Paule's τ are 0 — not the spread of the truth's means
/// over the laboratories' different positions (about 1″ here), which closing each over
/// its own positions would put between them.
#[test]
fn kc_encoder_subsets_per_position_estimates_are_levelled() {
    let angles = [0.0, 60.0, 120.0, 180.0, 240.0, 300.0];
    let lab = |name: &str, zero: f64, missing: &[f64]| {
        let kept: Vec<f64> = angles
            .iter()
            .copied()
            .filter(|a| !missing.contains(a))
            .collect();
        let values: Vec<f64> = kept
            .iter()
            .map(|a| 2.0 * a.to_radians().sin() + zero)
            .collect();
        at(name, &kept, &values)
    };
    let labs = [
        lab("A", 1.0, &[]),
        lab("B", -3.0, &[60.0]),
        lab("C", 5.0, &[180.0, 240.0]),
        lab("D", 0.5, &[0.0]),
    ];
    for method in [
        ReferenceMethod::DersimonianLaird,
        ReferenceMethod::MandelPaule,
    ] {
        let kc = evaluate(&labs, &[], &everyone().with_method(method)).unwrap();
        assert!(kc.chi2.iter().all(|c| c.abs() < 1e-18), "{:?}", kc.chi2);
        assert!(kc.tau.iter().all(|t| *t == 0.0), "{method:?}: {:?}", kc.tau);
        // the reference is the truth less its mean (2 sin over the six angles sums to 0)
        for (k, a) in angles.iter().enumerate() {
            let truth = 2.0 * a.to_radians().sin();
            assert!((kc.reference[k] - truth).abs() < 1e-12, "{k}");
        }
    }
}
