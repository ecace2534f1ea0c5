//! "More than half would be left out: nobody is" (docs/FORMAT.md §12, `withheld`;
//! docs/verdicts.md) for angle blocks and for encoder errors at different positions, as
//! `kc_pairs_motion.rs` measures it for the pitch deviations: every laboratory
//! understating its u by 1.5× on comparisons drawn with a known truth by `kc_support`
//! (blocks: 4, each missed with probability 0.2; encoder: 12 positions, likewise), and the
//! same comparisons with the u stated right, where it should (nearly) never be said.
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
