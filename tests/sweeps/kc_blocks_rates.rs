//! The angle blocks' verdicts at their stated rates (docs/verdicts.md; docs/FORMAT.md §12,
//! `--quantity angle_block`), measured on comparisons drawn with a known truth by
//! `kc_support::blocks`: 4 blocks, 6–10 laboratories, each u drawn in 0.05–0.2″ per
//! laboratory and block, each result the truth plus N(0, u²), each laboratory missing each
//! block with probability 0.2 (every block kept by at least two).
//!
//! `cargo test --test sweeps kc_blocks_rates:: -- --nocapture` prints the figures
//! docs/verdicts.md quotes.

use crate::kc_support::blocks::{Blocks, block_comparison, block_fit, block_largest_subset};
use polycal::kc::{KcOptions, KeyComparison, ReferenceMethod, evaluate, link};
use polycal::results::Quantity;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const BLOCKS: usize = 4;
const MISSING: f64 = 0.2;
const TRIALS: usize = 2000;

fn blocks() -> KcOptions {
    KcOptions::new().with_quantity(Quantity::AngleBlock)
}

fn rate(count: usize, of: usize) -> f64 {
    count as f64 / of as f64
}

/// Consistent comparisons: the joint χ² of every laboratory (`vector_all`) fails in
/// 5 % ± 1.5 %, and a laboratory is left out as often; DerSimonian–Laird's status 1 is that
/// same test in every comparison; each pair's test (`pairs[].vector`) fails in 5 % ± 1 %
/// of the pairs that share a block.
#[test]
fn kc_blocks_consistent_comparisons_fail_at_five_percent() {
    let mut rng = ChaCha8Rng::seed_from_u64(7301);
    let (mut failed, mut left_out, mut status_1, mut dl_status_1) = (0, 0, 0, 0);
    let (mut pairs, mut pairs_failed, mut pairs_untested, mut missing, mut cells) = (0, 0, 0, 0, 0);
    let mut by_blocks = [(0usize, 0usize); BLOCKS + 1];
    for _ in 0..TRIALS {
        let labs = rng.random_range(6..=10);
        let drawn = block_comparison(&mut rng, BLOCKS, labs, MISSING, None);
        missing += drawn.x.iter().flatten().filter(|x| x.is_none()).count();
        cells += labs * BLOCKS;
        let results = drawn.results();
        let kc = evaluate(&results, &[], &blocks()).unwrap();
        let all = kc.vector_all.as_ref().unwrap();
        let reported: usize = (0..BLOCKS)
            .map(|b| drawn.x.iter().filter(|x| x[b].is_some()).count() - 1)
            .sum();
        assert_eq!(all.dof, reported);
        let everyone: Vec<usize> = (0..labs).collect();
        let hand = block_fit(&drawn.x, &drawn.u, &everyone);
        assert!((all.chi2 - hand.chi2).abs() <= 1e-9 * hand.chi2.max(1.0));
        failed += usize::from(!all.consistent);
        left_out += usize::from(!kc.excluded.is_empty());
        for (i, x) in drawn.x.iter().enumerate() {
            let k = x.iter().filter(|x| x.is_some()).count();
            by_blocks[k].0 += 1;
            by_blocks[k].1 += usize::from(kc.excluded.iter().any(|e| e.lab == format!("L{i}")));
        }
        status_1 += usize::from(!kc.comparison_consistent);
        for pair in &kc.pairs {
            match &pair.vector {
                Some(test) => {
                    pairs += 1;
                    pairs_failed += usize::from(!test.consistent);
                }
                None => pairs_untested += 1,
            }
        }
        let dl = evaluate(
            &results,
            &[],
            &blocks().with_method(ReferenceMethod::DersimonianLaird),
        )
        .unwrap();
        assert!(dl.excluded.is_empty());
        assert_eq!(dl.comparison_consistent, all.consistent);
        dl_status_1 += usize::from(!dl.comparison_consistent);
    }
    println!(
        "verdict kc blocks: vector_all false alarm {:.4} (n = {TRIALS}; 4 blocks, 6–10 \
         laboratories, {:.3} of the blocks not reported); left out {:.4}; status 1 {:.4}; \
         DerSimonian–Laird status 1 {:.4}; pairs' test false alarm {:.4} of {pairs} pairs \
         ({pairs_untested} sharing no block, untested)",
        rate(failed, TRIALS),
        rate(missing, cells),
        rate(left_out, TRIALS),
        rate(status_1, TRIALS),
        rate(dl_status_1, TRIALS),
        rate(pairs_failed, pairs)
    );
    let by_blocks: Vec<String> = (1..=BLOCKS)
        .map(|k| format!("{k}: {:.4}", rate(by_blocks[k].1, by_blocks[k].0)))
        .collect();
    println!(
        "verdict kc blocks: a laboratory left out, by the number of blocks it reports (of \
         the laboratories of every comparison): {}",
        by_blocks.join(", ")
    );
    assert!((rate(failed, TRIALS) - 0.05).abs() <= 0.015);
    // after the search nobody consistent is left unresolved (status 1)
    assert!(
        rate(status_1, TRIALS) <= 0.005,
        "{}",
        rate(status_1, TRIALS)
    );
    assert!((rate(left_out, TRIALS) - 0.05).abs() <= 0.015);
    assert!((rate(dl_status_1, TRIALS) - 0.05).abs() <= 0.015);
    assert!((rate(pairs_failed, pairs) - 0.05).abs() <= 0.01);
}

/// One laboratory 3u (then 5u) off on one block, which it reports, among 6–10: how often
/// the joint test fails, how often the biased laboratory is left out alone, and how often
/// an innocent one is left out, and how often its pairs that share the block fail; every
/// decision against the brute-force search of `kc_support::blocks`.
#[test]
fn kc_blocks_a_laboratory_off_on_one_block() {
    let mut rng = ChaCha8Rng::seed_from_u64(7302);
    let trials = 1000;
    let mut measured = Vec::new();
    for amount in [3.0, 5.0] {
        let (mut failed, mut alone, mut innocent) = (0, 0, 0);
        let (mut biased_pairs, mut biased_pairs_failed) = (0, 0);
        for _ in 0..trials {
            let labs = rng.random_range(6..=10);
            let biased = rng.random_range(0..labs);
            let block = rng.random_range(0..BLOCKS);
            let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
            let drawn = block_comparison(
                &mut rng,
                BLOCKS,
                labs,
                MISSING,
                Some((biased, block, amount * sign)),
            );
            let kc = evaluate(&drawn.results(), &[], &blocks()).unwrap();
            failed += usize::from(!kc.vector_all.as_ref().unwrap().consistent);
            // the decision against the brute-force search
            let inside: Vec<usize> = (0..labs)
                .filter(|&i| kc.degrees_of_equivalence[i].in_reference)
                .collect();
            assert_eq!(inside, block_largest_subset(&drawn.x, &drawn.u));
            let out: Vec<&str> = kc.excluded.iter().map(|e| e.lab.as_str()).collect();
            let name = format!("L{biased}");
            alone += usize::from(out == [name.as_str()]);
            innocent += usize::from(out.iter().any(|l| *l != name));
            // the pairs of the biased laboratory that share its biased block
            for pair in &kc.pairs {
                let shares = pair.d[block].is_finite();
                if (pair.a == name || pair.b == name) && shares {
                    biased_pairs += 1;
                    let test = pair.vector.as_ref().unwrap();
                    biased_pairs_failed += usize::from(!test.consistent);
                }
            }
        }
        let pairs_power = rate(biased_pairs_failed, biased_pairs);
        let (failed, alone, innocent) = (
            rate(failed, trials),
            rate(alone, trials),
            rate(innocent, trials),
        );
        println!(
            "verdict kc blocks: power {failed:.3} (vector_all fails; one laboratory {amount}u \
             off on one of 4 blocks, n = {trials}); the biased laboratory left out alone \
             {alone:.3}; an innocent one left out {innocent:.3}; its pairs that share the \
             block fail their test {pairs_power:.3} (of {biased_pairs})"
        );
        measured.push((failed, alone, innocent));
        assert!(
            pairs_power >= if amount < 4.0 { 0.3 } else { 0.7 },
            "{pairs_power}"
        );
    }
    let (failed_3u, alone_3u, innocent_3u) = measured[0];
    assert!(failed_3u >= 0.25, "{failed_3u}");
    assert!(alone_3u >= 0.17, "{alone_3u}");
    assert!(innocent_3u <= 0.12, "{innocent_3u}");
    let (failed_5u, alone_5u, innocent_5u) = measured[1];
    assert!(failed_5u >= 0.72, "{failed_5u}");
    assert!(alone_5u >= 0.65, "{alone_5u}");
    assert!(innocent_5u <= 0.11, "{innocent_5u}");
}

/// Two comparisons of one set of blocks (8 and 6 laboratories, 3 in both, each missing
/// blocks as above): the link's test fails in 5 % ± 1.5 %; with a linking laboratory 4u
/// off on one block in one comparison, how often it fails.
#[test]
fn kc_blocks_the_link_test_keeps_its_rate() {
    let mut rng = ChaCha8Rng::seed_from_u64(7303);
    let trials = 2000;
    let everyone = blocks().with_largest_consistent_subset(false);
    let named = |drawn: &Blocks, names: &[&str]| {
        let mut results = drawn.results();
        for (result, name) in results.iter_mut().zip(names) {
            result.name = name.to_string();
            result.source = name.to_string();
        }
        results
    };
    let cipm_names = ["L1", "L2", "L3", "L4", "L5", "L6", "L7", "L8"];
    let rmo_names = ["L2", "L5", "L7", "R1", "R2", "R3"];
    let (mut failed, mut tested) = (0, 0);
    for _ in 0..trials {
        let cipm = block_comparison(&mut rng, BLOCKS, 8, MISSING, None);
        let rmo = block_comparison(&mut rng, BLOCKS, 6, MISSING, None);
        let cipm: KeyComparison = evaluate(&named(&cipm, &cipm_names), &[], &everyone).unwrap();
        let mut rmo = evaluate(&named(&rmo, &rmo_names), &[], &everyone).unwrap();
        link(&mut rmo, &cipm).unwrap();
        if let Some(test) = &rmo.link.as_ref().unwrap().vector {
            tested += 1;
            failed += usize::from(!test.consistent);
        }
    }
    // power: linking laboratory L5 4u off on one block in the RMO comparison
    let (mut found, mut tested_power) = (0, 0);
    for _ in 0..trials / 2 {
        let block = rng.random_range(0..BLOCKS);
        let cipm = block_comparison(&mut rng, BLOCKS, 8, MISSING, None);
        let rmo = block_comparison(&mut rng, BLOCKS, 6, MISSING, Some((1, block, 4.0)));
        let linked_there = cipm.x[4][block].is_some();
        let cipm: KeyComparison = evaluate(&named(&cipm, &cipm_names), &[], &everyone).unwrap();
        let mut rmo = evaluate(&named(&rmo, &rmo_names), &[], &everyone).unwrap();
        link(&mut rmo, &cipm).unwrap();
        // only where L5 links the block (it reports it in both) can the link see it
        if let (true, Some(test)) = (linked_there, &rmo.link.as_ref().unwrap().vector) {
            tested_power += 1;
            found += usize::from(!test.consistent);
        }
    }
    let failed = rate(failed, tested);
    let power = rate(found, tested_power);
    println!(
        "verdict kc blocks link: false alarm {failed:.4} (n = {tested} pairs of comparisons \
         tested of {trials}; 8 and 6 laboratories, 3 in both, 4 blocks); power {power:.3} (a \
         linking laboratory 4u off on one block in one comparison, n = {tested_power})"
    );
    assert!((failed - 0.05).abs() <= 0.015, "{failed}");
    assert!(power >= 0.25, "{power}");
}
