//! Encoder errors compared on the positions each laboratory reports: the verdicts at their
//! stated rates (docs/verdicts.md; docs/FORMAT.md §12, "What each laboratory measured"),
//! measured on comparisons drawn with a known truth by `kc_support::encoder`: 12 encoder
//! positions, 6–10 laboratories, u drawn in 0.05–0.2″ per laboratory and position, each
//! laboratory's zero a random constant (encoder errors are defined up to one), each
//! laboratory missing each position with probability 0.2 (every position kept by at least
//! two laboratories), its noise closed over the positions it reports with the covariance
//! the comparison takes, N_i/(N_i − 1)·P_S·diag(u²)·P_S (its u the u of its closed values,
//! as a self-calibration over its own positions gives them); and, for comparison, with
//! N(0, u²) on each value independently (its u the u of a value against its own zero).
//!
//! `cargo test --test sweeps kc_encoder_subsets_rates:: -- --nocapture` prints the figures
//! docs/verdicts.md quotes.

use crate::kc_support::encoder::{Design, Encoder, draw, largest_subset, subset_gls};
use polycal::kc::{KcOptions, ReferenceMethod, evaluate};
use polycal::results::Quantity;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const POSITIONS: usize = 12;
const MISSING: f64 = 0.2;

fn encoder() -> KcOptions {
    KcOptions::new().with_quantity(Quantity::EncoderError)
}

/// The design of every comparison here; `closed_noise`: each laboratory's noise closed over
/// its own positions with the covariance the comparison states, else N(0, u²) on each
/// value.
fn design(rng: &mut ChaCha8Rng, closed_noise: bool) -> Design {
    Design {
        positions: POSITIONS,
        labs: rng.random_range(6..=10),
        missing: MISSING,
        missing_count: None,
        u_range: (0.05, 0.2),
        equal_u: false,
        closed_noise,
    }
}

fn rate(count: usize, of: usize) -> f64 {
    count as f64 / of as f64
}

/// The positions `data`'s laboratory i does not report.
fn missing(data: &Encoder) -> usize {
    data.x.iter().flatten().filter(|x| x.is_none()).count()
}

/// Consistent comparisons (n = 2 000): `vector_all` fails in 5 % ± 1.5 % (its χ² and ν the
/// dense GLS's every time), DerSimonian–Laird's status 1 is that same test; every
/// laboratory's U(d_i) covers its true degree of equivalence (0, closed over its own
/// positions) on at least 93 % of (laboratory, position); each pair's test fails in 5 % ±
/// 1 % of the pairs.
#[test]
fn kc_encoder_subsets_consistent_comparisons() {
    let mut rng = ChaCha8Rng::seed_from_u64(9201);
    let trials = 2000;
    let (mut failed, mut left_out, mut status_1, mut dl_status_1) = (0, 0, 0, 0);
    let (mut cells, mut absent) = (0, 0);
    let (mut covered, mut judged, mut covered_in, mut judged_in) = (0, 0, 0, 0);
    let (mut pairs, mut pairs_failed, mut pair_cells, mut pair_covered) = (0, 0, 0, 0);
    // per number of positions a laboratory reports: (laboratories, left out)
    let mut by_reported = [(0usize, 0usize); POSITIONS + 1];
    for _ in 0..trials {
        let d = design(&mut rng, true);
        let data = draw(&mut rng, d, None);
        cells += d.labs * POSITIONS;
        absent += missing(&data);
        let results = data.results();
        let kc = evaluate(&results, &[], &encoder()).unwrap();
        let all = kc.vector_all.as_ref().unwrap();
        let everyone: Vec<usize> = (0..d.labs).collect();
        let dense = subset_gls(&data, &everyone).unwrap();
        assert!((all.chi2 - dense.chi2).abs() <= 1e-9 * dense.chi2.max(1.0));
        assert_eq!(all.dof, dense.dof);
        failed += usize::from(!all.consistent);
        left_out += usize::from(!kc.excluded.is_empty());
        status_1 += usize::from(!kc.comparison_consistent);
        for (i, doe) in kc.degrees_of_equivalence.iter().enumerate() {
            let reported = data.reported(i).len();
            by_reported[reported].0 += 1;
            by_reported[reported].1 += usize::from(!doe.in_reference);
            for k in 0..POSITIONS {
                assert_eq!(doe.d[k].is_finite(), data.x[i][k].is_some());
                if data.x[i][k].is_none() {
                    continue;
                }
                // the truth: 0 (unbiased, closed over its own positions)
                let inside = doe.d[k].abs() <= doe.expanded_u[k];
                judged += 1;
                covered += usize::from(inside);
                if doe.in_reference {
                    judged_in += 1;
                    covered_in += usize::from(inside);
                }
            }
        }
        for pair in &kc.pairs {
            if let Some(test) = &pair.vector {
                pairs += 1;
                pairs_failed += usize::from(!test.consistent);
            }
            for (d, u) in pair.d.iter().zip(&pair.expanded_u) {
                if d.is_finite() {
                    pair_cells += 1;
                    pair_covered += usize::from(d.abs() <= *u);
                }
            }
        }
        let dl = evaluate(
            &results,
            &[],
            &encoder().with_method(ReferenceMethod::DersimonianLaird),
        )
        .unwrap();
        assert!(dl.excluded.is_empty());
        assert_eq!(dl.comparison_consistent, all.consistent);
        dl_status_1 += usize::from(!dl.comparison_consistent);
    }
    let coverage = rate(covered, judged);
    println!(
        "verdict kc encoder subsets: vector_all false alarm {:.4} (n = {trials}; 12 positions, \
         6–10 laboratories, {:.3} of the positions not reported); left out {:.4}; status 1 \
         {:.4}; DerSimonian–Laird status 1 {:.4}",
        rate(failed, trials),
        rate(absent, cells),
        rate(left_out, trials),
        rate(status_1, trials),
        rate(dl_status_1, trials),
    );
    println!(
        "verdict kc encoder subsets: U(d_i) covers the true degree of equivalence on {coverage:.4} \
         of {judged} (laboratory, position); {:.4} of {judged_in} in the reference",
        rate(covered_in, judged_in)
    );
    println!(
        "verdict kc encoder subsets: pairs' test false alarm {:.4} of {pairs} pairs; |d_ab| ≤ \
         U(d_ab) on {:.4} of {pair_cells} (pair, position)",
        rate(pairs_failed, pairs),
        rate(pair_covered, pair_cells)
    );
    let by_reported: Vec<String> = (2..=POSITIONS)
        .filter(|&k| by_reported[k].0 > 0)
        .map(|k| {
            format!(
                "{k}: {:.4} of {}",
                rate(by_reported[k].1, by_reported[k].0),
                by_reported[k].0
            )
        })
        .collect();
    println!(
        "verdict kc encoder subsets: a laboratory left out, by the positions it reports: {}",
        by_reported.join(", ")
    );
    assert!((rate(failed, trials) - 0.05).abs() <= 0.015);
    assert!((rate(left_out, trials) - 0.05).abs() <= 0.015);
    assert!((rate(dl_status_1, trials) - 0.05).abs() <= 0.015);
    // after the search nobody consistent is left unresolved (status 1)
    assert!(
        rate(status_1, trials) <= 0.005,
        "{}",
        rate(status_1, trials)
    );
    assert!((coverage - 0.9545).abs() <= 0.01, "{coverage}");
    assert!(
        (rate(covered_in, judged_in) - 0.9545).abs() <= 0.015,
        "{}",
        rate(covered_in, judged_in)
    );
    assert!((rate(pairs_failed, pairs) - 0.05).abs() <= 0.01);
    assert!(
        (rate(pair_covered, pair_cells) - 0.9545).abs() <= 0.015,
        "{}",
        rate(pair_covered, pair_cells)
    );
}

/// One laboratory 3u off on 3 of the positions it reports (n = 1 000): how often
/// `vector_all` fails, the biased laboratory is left out alone, an innocent one is left
/// out; every decision the brute-force search's (the dense GLS's χ² of every subset).
#[test]
fn kc_encoder_subsets_a_laboratory_off_on_three_positions() {
    let mut rng = ChaCha8Rng::seed_from_u64(9202);
    let trials = 1000;
    let (mut failed, mut alone, mut innocent) = (0, 0, 0);
    let (mut biased_pairs, mut biased_pairs_failed) = (0, 0);
    for _ in 0..trials {
        let d = design(&mut rng, true);
        let biased = rng.random_range(0..d.labs);
        let sign = if rng.random::<bool>() { 3.0 } else { -3.0 };
        // three positions, of those it reports once the missing ones are drawn: drawn
        // after, as the bias adds to values only where reported
        let mut at = Vec::new();
        while at.len() < 3 {
            let k = rng.random_range(0..POSITIONS);
            if !at.contains(&k) {
                at.push(k);
            }
        }
        let mut data = draw(&mut rng, d, None);
        // every one of the three reported: a missing one is moved to a reported one
        let reported = data.reported(biased);
        let mut on: Vec<usize> = at
            .iter()
            .copied()
            .filter(|k| reported.contains(k))
            .collect();
        for &k in &reported {
            if on.len() == 3.min(reported.len()) {
                break;
            }
            if !on.contains(&k) {
                on.push(k);
            }
        }
        for &k in &on {
            let shift = sign * data.u[biased][k];
            data.x[biased][k] = data.x[biased][k].map(|x| x + shift);
        }
        let kc = evaluate(&data.results(), &[], &encoder()).unwrap();
        failed += usize::from(!kc.vector_all.as_ref().unwrap().consistent);
        let inside: Vec<usize> = (0..d.labs)
            .filter(|&i| kc.degrees_of_equivalence[i].in_reference)
            .collect();
        assert_eq!(inside, largest_subset(&data));
        let out: Vec<&str> = kc.excluded.iter().map(|e| e.lab.as_str()).collect();
        let name = format!("L{biased}");
        alone += usize::from(out == [name.as_str()]);
        innocent += usize::from(out.iter().any(|l| *l != name));
        for pair in &kc.pairs {
            if (pair.a == name || pair.b == name)
                && let Some(test) = &pair.vector
            {
                biased_pairs += 1;
                biased_pairs_failed += usize::from(!test.consistent);
            }
        }
    }
    let (failed, alone, innocent) = (
        rate(failed, trials),
        rate(alone, trials),
        rate(innocent, trials),
    );
    let pairs_power = rate(biased_pairs_failed, biased_pairs);
    println!(
        "verdict kc encoder subsets: power {failed:.3} (vector_all fails; one laboratory 3u off \
         on 3 of the 12 positions, n = {trials}); the biased laboratory left out alone \
         {alone:.3}; an innocent one left out {innocent:.3}; its pairs fail their test \
         {pairs_power:.3} (of {biased_pairs})"
    );
    assert!(failed >= 0.33, "{failed}");
    assert!(alone >= 0.24, "{alone}");
    assert!(innocent <= 0.12, "{innocent}");
    assert!(pairs_power >= 0.35, "{pairs_power}");
}

/// The same comparisons with N(0, u²) on each value independently (a laboratory's u the u
/// of a value against its own zero, not of its closed value): the comparison takes each
/// result's covariance N_i/(N_i − 1) times the real one, so its tests are conservative —
/// the figures docs/verdicts.md states beside the row above.
#[test]
fn kc_encoder_subsets_independent_noise_is_conservative() {
    let mut rng = ChaCha8Rng::seed_from_u64(9203);
    let trials = 2000;
    let (mut failed, mut covered, mut judged, mut pairs, mut pairs_failed) = (0, 0, 0, 0, 0);
    for _ in 0..trials {
        let d = design(&mut rng, false);
        let data = draw(&mut rng, d, None);
        let kc = evaluate(&data.results(), &[], &encoder()).unwrap();
        failed += usize::from(!kc.vector_all.as_ref().unwrap().consistent);
        for doe in &kc.degrees_of_equivalence {
            for (d, u) in doe.d.iter().zip(&doe.expanded_u) {
                if d.is_finite() {
                    judged += 1;
                    covered += usize::from(d.abs() <= *u);
                }
            }
        }
        for pair in &kc.pairs {
            if let Some(test) = &pair.vector {
                pairs += 1;
                pairs_failed += usize::from(!test.consistent);
            }
        }
    }
    let (failed, coverage, pairs_rate) = (
        rate(failed, trials),
        rate(covered, judged),
        rate(pairs_failed, pairs),
    );
    println!(
        "verdict kc encoder subsets, independent noise: vector_all false alarm {failed:.4} \
         (n = {trials}); U(d_i) covers {coverage:.4} of {judged}; pairs' test false alarm \
         {pairs_rate:.4} of {pairs}"
    );
    assert!(failed < 0.035, "{failed}");
    assert!(coverage >= 0.9545, "{coverage}");
    assert!(pairs_rate < 0.05, "{pairs_rate}");
}
