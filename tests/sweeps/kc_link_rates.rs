//! Linking one comparison to another (docs/FORMAT.md §12, "Linking"; docs/verdicts.md):
//! the link's one test at its stated rate, and the degrees of equivalence against the
//! linked reference covering the truth at k = 2, on pairs of comparisons drawn by the
//! independent generator of `kc_support` (two artefacts, laboratories without bias).
//!
//! `cargo test --test sweeps kc_link_rates:: -- --nocapture` prints the figures.

use crate::kc_support::{closed_noise, lab};
use polycal::kc::{KcOptions, LabResult, evaluate, link};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const FACES: usize = 12;

/// One comparison of `truth`: laboratory i measures with u = `u[i]`, closed noise.
fn draw(rng: &mut ChaCha8Rng, names: &[String], u: &[f64], truth: &[f64]) -> Vec<LabResult> {
    names
        .iter()
        .zip(u)
        .map(|(name, &u)| {
            let u = vec![u; FACES];
            let noise = closed_noise(rng, &u);
            let x: Vec<f64> = truth.iter().zip(&noise).map(|(t, e)| t + e).collect();
            lab(name, &x, &u)
        })
        .collect()
}

/// The comparison of every laboratory, nobody left out.
fn everyone(results: &[LabResult]) -> polycal::kc::KeyComparison {
    evaluate(
        results,
        &[],
        &KcOptions::new().with_largest_consistent_subset(false),
    )
    .unwrap()
}

/// A CIPM comparison of 8 laboratories and an RMO one of 6, three of them in both, each
/// of its own artefact: the link's test fails in 5 % ± 1.5 % of pairs of comparisons;
/// U_linked covers the RMO laboratories' true degree of equivalence (0: nobody biased) on
/// about 95 % of faces.
#[test]
fn kc_the_link_test_keeps_its_rate_and_linked_u_covers() {
    let mut rng = ChaCha8Rng::seed_from_u64(5504);
    let trials = 2000;
    let truth_cipm: Vec<f64> = crate::kc_support::truth(FACES);
    let truth_rmo: Vec<f64> = truth_cipm.iter().rev().copied().collect();
    let cipm_names: Vec<String> = (0..8).map(|i| format!("L{i}")).collect();
    let rmo_names: Vec<String> = ["L1", "L4", "L6", "R1", "R2", "R3"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    let (mut failed, mut does, mut covered) = (0, 0, 0);
    for _ in 0..trials {
        let u_cipm: Vec<f64> = (0..8).map(|_| rng.random_range(0.04..0.2)).collect();
        let u_rmo: Vec<f64> = (0..6).map(|_| rng.random_range(0.04..0.2)).collect();
        let cipm = everyone(&draw(&mut rng, &cipm_names, &u_cipm, &truth_cipm));
        let mut rmo = everyone(&draw(&mut rng, &rmo_names, &u_rmo, &truth_rmo));
        link(&mut rmo, &cipm).unwrap();
        let vector = rmo.link.as_ref().unwrap().vector.as_ref().unwrap();
        assert_eq!(vector.dof, (FACES - 1) * 2);
        failed += usize::from(!vector.consistent);
        for doe in &rmo.degrees_of_equivalence {
            let (d, u) = (
                doe.d_linked.as_ref().unwrap(),
                doe.expanded_u_linked.as_ref().unwrap(),
            );
            for (d, u) in d.iter().zip(u) {
                does += 1;
                covered += usize::from(d.abs() <= *u);
            }
        }
    }
    // power: linking laboratory L4 off by 4u on 3 faces (then closed) in the RMO comparison
    let mut found = 0;
    for _ in 0..trials / 2 {
        let u_cipm: Vec<f64> = (0..8).map(|_| rng.random_range(0.04..0.2)).collect();
        let u_rmo: Vec<f64> = (0..6).map(|_| rng.random_range(0.04..0.2)).collect();
        let cipm = everyone(&draw(&mut rng, &cipm_names, &u_cipm, &truth_cipm));
        let mut results = draw(&mut rng, &rmo_names, &u_rmo, &truth_rmo);
        let shift = 4.0 * u_rmo[1];
        let mut x: Vec<f64> = results[1].rows.iter().map(|r| r.value).collect();
        for (f, sign) in [(2, 1.0), (5, -1.0), (9, 1.0)] {
            x[f] += sign * shift;
        }
        let mean = x.iter().sum::<f64>() / FACES as f64;
        let x: Vec<f64> = x.iter().map(|v| v - mean).collect();
        results[1] = lab("L4", &x, &[u_rmo[1]; FACES]);
        let mut rmo = everyone(&results);
        link(&mut rmo, &cipm).unwrap();
        found += usize::from(
            !rmo.link
                .as_ref()
                .unwrap()
                .vector
                .as_ref()
                .unwrap()
                .consistent,
        );
    }
    let power = found as f64 / (trials / 2) as f64;
    let rate = failed as f64 / trials as f64;
    let coverage = covered as f64 / does as f64;
    println!(
        "verdict kc link: false alarm {rate:.4} (n = {trials}; 8 and 6 laboratories, 3 in both, \
         12 faces); U_linked covers the true degree of equivalence on {coverage:.4} of {does}; \
         power {power:.3} (a linking laboratory 4u off on 3 faces in one comparison, n = {})",
        trials / 2
    );
    assert!(power >= 0.5, "{power}");
    assert!((rate - 0.05).abs() <= 0.015, "{rate}");
    assert!((coverage - 0.9545).abs() <= 0.01, "{coverage}");
}

/// Encoder comparisons whose laboratories, the linking ones among them, each miss up to 2
/// of 12 positions (docs/FORMAT.md §12, "Linking"): the link over positions, each linking
/// laboratory with a constant of its own, fails its test in 5 % ± 1.5 % of the pairs of
/// comparisons it links; U_linked covers the true degree of equivalence (0: nobody biased)
/// on about 95 % of the positions reported; a linking laboratory 4u off on 3 positions in
/// one comparison is found.
#[test]
fn kc_the_link_over_different_positions_keeps_its_rate_and_linked_u_covers() {
    use crate::kc_support::encoder::{Design, draw};
    use polycal::results::Quantity;

    let mut rng = ChaCha8Rng::seed_from_u64(5507);
    let design = |labs| Design {
        positions: FACES,
        labs,
        missing: 0.0,
        missing_count: Some(2),
        u_range: (0.04, 0.2),
        equal_u: false,
        closed_noise: true,
    };
    let options = KcOptions::new()
        .with_quantity(Quantity::EncoderError)
        .with_largest_consistent_subset(false);
    let rmo_names: Vec<String> = ["L1", "L4", "L6", "R1", "R2", "R3"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    // one pair of comparisons, in the RMO one (`shifted`) L4 4u off on 3 of the positions
    // it reports there: the link's test and whether a linking laboratory misses a position
    // (`None`: refused, a position without a linking laboratory)
    let trial = |rng: &mut ChaCha8Rng, shifted: bool, covered: &mut (usize, usize)| {
        let cipm = evaluate(&draw(rng, design(8), None).results(), &[], &options).unwrap();
        let mut rmo_data = draw(rng, design(6), None);
        rmo_data.names = rmo_names.clone();
        if shifted {
            for k in rmo_data.reported(1).into_iter().step_by(3).take(3) {
                let u = rmo_data.u[1][k];
                if let Some(x) = rmo_data.x[1][k].as_mut() {
                    *x += 4.0 * u;
                }
            }
        }
        let mut rmo = evaluate(&rmo_data.results(), &[], &options).unwrap();
        link(&mut rmo, &cipm).ok()?;
        let gapped = ["L1", "L4", "L6"].iter().any(|name| {
            [&rmo, &cipm].iter().any(|kc| {
                kc.degrees_of_equivalence
                    .iter()
                    .any(|d| d.lab == *name && d.d.iter().any(|x| x.is_nan()))
            })
        });
        if !shifted {
            for doe in &rmo.degrees_of_equivalence {
                let (d, u) = (
                    doe.d_linked.as_ref().unwrap(),
                    doe.expanded_u_linked.as_ref().unwrap(),
                );
                for (d, u) in d.iter().zip(u).filter(|(d, _)| d.is_finite()) {
                    covered.0 += 1;
                    covered.1 += usize::from(d.abs() <= *u);
                }
            }
        }
        let vector = rmo.link.as_ref().unwrap().vector.clone()?;
        Some((vector.consistent, gapped))
    };
    let trials = 2000;
    let (mut tested, mut failed, mut gapped_links) = (0, 0, 0);
    let mut coverage = (0, 0);
    for _ in 0..trials {
        if let Some((consistent, gapped)) = trial(&mut rng, false, &mut coverage) {
            tested += 1;
            failed += usize::from(!consistent);
            gapped_links += usize::from(gapped);
        }
    }
    let (mut tested_power, mut found) = (0, 0);
    for _ in 0..trials / 2 {
        if let Some((consistent, _)) = trial(&mut rng, true, &mut (0, 0)) {
            tested_power += 1;
            found += usize::from(!consistent);
        }
    }
    let rate = failed as f64 / tested as f64;
    let covers = coverage.1 as f64 / coverage.0 as f64;
    let power = found as f64 / tested_power as f64;
    println!(
        "verdict kc link over different positions: false alarm {rate:.4} (n = {tested} linked \
         of {trials}, {gapped_links} through a laboratory missing positions; 8 and 6 \
         laboratories, 3 in both, each missing up to 2 of 12 positions); U_linked covers the \
         true degree of equivalence on {covers:.4} of {}; power {power:.3} (a linking \
         laboratory 4u off on 3 positions in one comparison, n = {tested_power})",
        coverage.0
    );
    assert!(tested >= trials * 3 / 4, "{tested}");
    assert!(gapped_links >= tested / 2, "{gapped_links}");
    assert!((rate - 0.05).abs() <= 0.015, "{rate}");
    assert!((covers - 0.9545).abs() <= 0.01, "{covers}");
    assert!(power >= 0.3, "{power}");
}
