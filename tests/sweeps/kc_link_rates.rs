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
