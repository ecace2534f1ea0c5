//! "More than half would be left out: nobody is" (docs/FORMAT.md §12, `withheld`;
//! docs/verdicts.md) for angle blocks and for encoder errors at different positions, as
//! `kc_pairs_motion.rs` measures it for the pitch deviations: every laboratory
//! understating its u by 1.5× on comparisons drawn with a known truth by `kc_support`
//! (blocks: 4, each missed with probability 0.2; encoder: 12 positions, likewise), and the
//! same comparisons with the u stated right, where it should (nearly) never be said.
//!
//! And the pilot's test of the artefact's stability for those quantities.
//!
//! `cargo test --test sweeps kc_understated_rates:: -- --nocapture` prints the figures.

use crate::kc_support::blocks::block_comparison;
use crate::kc_support::encoder::{Design, draw};
use polycal::kc::{KcOptions, LabResult, evaluate};
use polycal::results::Quantity;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Draws a comparison of `labs` laboratories whose noise is `understated` × their stated u.
type Drawn = dyn Fn(&mut ChaCha8Rng, usize, f64) -> Vec<LabResult>;

/// Over `trials` comparisons of 8–12 laboratories: the rates of half or more left out, of
/// nobody left out for more than half (`withheld`) and of its statement, with u understated
/// 1.5×, and of `withheld` with u stated right; asserting that a withheld comparison
/// leaves nobody out, is not consistent and says why (naming the random-effects method).
fn rates(seed: u64, trials: usize, quantity: Quantity, drawn: &Drawn) -> (f64, f64, f64, f64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let options = KcOptions::new().with_quantity(quantity);
    let (mut half_or_more, mut withheld, mut withheld_right, mut failed) = (0, 0, 0, 0);
    for _ in 0..trials {
        let labs = rng.random_range(8..=12);
        let kc = evaluate(&drawn(&mut rng, labs, 1.5), &[], &options).unwrap();
        half_or_more += usize::from(2 * kc.excluded.len() >= labs);
        failed += usize::from(!kc.vector_all.as_ref().is_some_and(|v| v.consistent));
        assert!(2 * kc.excluded.len() <= labs, "more than half left out");
        if !kc.withheld.is_empty() {
            withheld += 1;
            assert!(kc.excluded.is_empty() && !kc.comparison_consistent);
            assert!(
                kc.verdict_statement()
                    .contains("stated uncertainties look too small")
                    && kc.notes.iter().any(|n| n.contains("dersimonian-laird")),
                "{}",
                kc.verdict_statement()
            );
        }
        let right = evaluate(&drawn(&mut rng, labs, 1.0), &[], &options).unwrap();
        withheld_right += usize::from(!right.withheld.is_empty());
    }
    let rate = |count: usize| count as f64 / trials as f64;
    (
        rate(failed),
        rate(half_or_more),
        rate(withheld),
        rate(withheld_right),
    )
}

#[test]
fn kc_understated_uncertainties_of_angle_blocks() {
    let drawn = |rng: &mut ChaCha8Rng, labs: usize, understated: f64| {
        let mut blocks = block_comparison(rng, 4, labs, 0.2, None);
        // the noise drawn with u, the u stated smaller by `understated`
        blocks
            .u
            .iter_mut()
            .flatten()
            .for_each(|u| *u /= understated);
        blocks.results()
    };
    let (failed, half, withheld, right) = rates(5510, 1000, Quantity::AngleBlock, &drawn);
    println!(
        "verdict kc blocks understated u (1.5×, 4 blocks, 8–12 laboratories, n = 1000): \
         vector_all fails {failed:.3}; half or more left out {half:.3}, nobody left out for \
         more than half {withheld:.3}; on comparisons with u stated right withheld {right:.4}"
    );
    assert!(half <= 0.1, "{half}");
    assert!(withheld > 0.0, "{withheld}");
    assert!(right <= 0.01, "{right}");
}

#[test]
fn kc_understated_uncertainties_of_encoder_errors_at_different_positions() {
    let drawn = |rng: &mut ChaCha8Rng, labs: usize, understated: f64| {
        let design = Design {
            positions: 12,
            labs,
            missing: 0.2,
            missing_count: None,
            u_range: (0.05, 0.2),
            equal_u: false,
            closed_noise: true,
        };
        let mut data = draw(rng, design, None);
        data.u.iter_mut().flatten().for_each(|u| *u /= understated);
        data.results()
    };
    let (failed, half, withheld, right) = rates(5511, 500, Quantity::EncoderError, &drawn);
    println!(
        "verdict kc encoder subsets understated u (1.5×, 12 positions, 8–12 laboratories, \
         n = 500): vector_all fails {failed:.3}; half or more left out {half:.3}, nobody left \
         out for more than half {withheld:.3}; on comparisons with u stated right withheld \
         {right:.4}"
    );
    assert!(half <= 0.3, "{half}");
    assert!(withheld >= 0.2, "{withheld}");
    assert!(right <= 0.01, "{right}");
}

/// The pilot's repeats of angle blocks and of encoder errors (3 repeats reporting every
/// block or position, the pilot's u 0.05–0.2″) beside 6–10 laboratories: the artefact is
/// called unstable (`pilot.vector` fails) in 5 % ± 1.5 % of comparisons of a stable
/// artefact, and found when the last repeat is 4u off on one block or three positions.
#[test]
fn kc_pilot_repeats_of_blocks_and_encoder_errors_keep_their_rate() {
    let mut rng = ChaCha8Rng::seed_from_u64(5512);
    let named = |mut results: Vec<LabResult>| {
        for (r, name) in results.iter_mut().zip(["start", "middle", "end"]) {
            r.name = name.to_string();
        }
        results
    };
    let blocks = KcOptions::new().with_quantity(Quantity::AngleBlock);
    let encoder = KcOptions::new().with_quantity(Quantity::EncoderError);
    let design = |labs: usize, missing: f64| Design {
        positions: 12,
        labs,
        missing,
        missing_count: None,
        u_range: (0.05, 0.2),
        equal_u: false,
        closed_noise: true,
    };
    let trials = 4000;
    let unstable = |kc: &polycal::kc::KeyComparison| {
        !kc.pilot
            .as_ref()
            .and_then(|p| p.vector.as_ref())
            .is_some_and(|v| v.consistent)
    };
    let (mut blocks_fa, mut blocks_found, mut encoder_fa, mut encoder_found) = (0, 0, 0, 0);
    for trial in 0..trials {
        let moved = trial % 2 == 1;
        let labs = rng.random_range(6..=10);
        // angle blocks: the last repeat 4u off on block 2 when the artefact moved
        let lab_results = block_comparison(&mut rng, 4, labs, 0.2, None).results();
        let mut repeats = block_comparison(&mut rng, 4, 3, 0.0, None);
        if moved {
            let u = repeats.u[2][1];
            if let Some(x) = repeats.x[2][1].as_mut() {
                *x += 4.0 * u;
            }
        }
        let kc = evaluate(&lab_results, &named(repeats.results()), &blocks).unwrap();
        match moved {
            false => blocks_fa += usize::from(unstable(&kc)),
            true => blocks_found += usize::from(unstable(&kc)),
        }
        // encoder errors at different positions: the last repeat 4u off on 3 positions
        let lab_results = draw(&mut rng, design(labs, 0.2), None).results();
        let mut repeats = draw(&mut rng, design(3, 0.0), None);
        if moved {
            for k in [1, 5, 9] {
                let u = repeats.u[2][k];
                if let Some(x) = repeats.x[2][k].as_mut() {
                    *x += 4.0 * u;
                }
            }
        }
        let kc = evaluate(&lab_results, &named(repeats.results()), &encoder).unwrap();
        match moved {
            false => encoder_fa += usize::from(unstable(&kc)),
            true => encoder_found += usize::from(unstable(&kc)),
        }
    }
    let half = (trials / 2) as f64;
    let rates = [blocks_fa, blocks_found, encoder_fa, encoder_found].map(|c| c as f64 / half);
    println!(
        "verdict kc pilot unstable: angle blocks false alarm {:.4}, power {:.3} (last repeat 4u \
         off on one of 4 blocks); encoder errors at different positions false alarm {:.4}, \
         power {:.3} (4u off on 3 of 12 positions); n = {} each",
        rates[0],
        rates[1],
        rates[2],
        rates[3],
        trials / 2
    );
    assert!((rates[0] - 0.05).abs() <= 0.015, "{}", rates[0]);
    assert!((rates[2] - 0.05).abs() <= 0.015, "{}", rates[2]);
    assert!(rates[1] >= 0.5 && rates[3] >= 0.5, "{rates:?}");
}
