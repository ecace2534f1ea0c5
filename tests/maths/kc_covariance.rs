//! A key comparison's closed vector with the laboratories' own covariances
//! (`LabResult::with_covariance`, docs/FORMAT.md §12): the GLS reference against the
//! per-face means where they must agree, the χ² against its degrees of freedom on
//! simulated laboratories whose faces are really correlated, and the refusals.

#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use polycal::kc::{KcError, KcOptions, LabResult, evaluate};
use polycal::results::{Quantity, ResultRow};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

const FACES: usize = 12;

fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

fn lab(name: &str, values: &[f64], u: &[f64]) -> LabResult {
    let rows = values
        .iter()
        .zip(u)
        .enumerate()
        .map(|(f, (&x, &u))| ResultRow::new(Quantity::PitchDeviation, f as u32 + 1, x).with_u(u))
        .collect();
    LabResult::from_rows(name, rows)
}

/// P = I − J/N, written here.
fn projector(n: usize) -> DMatrix<f64> {
    DMatrix::identity(n, n) - DMatrix::from_element(n, n, 1.0 / n as f64)
}

fn flat(m: &DMatrix<f64>) -> Vec<f64> {
    let n = m.nrows();
    (0..n * n).map(|k| m[(k / n, k % n)]).collect()
}

/// The Moore–Penrose pseudo-inverse by SVD (independent of polycal's (V + J/N)⁻¹ − J/N).
fn pinv(m: &DMatrix<f64>) -> DMatrix<f64> {
    m.clone().pseudo_inverse(1e-10).expect("SVD converges")
}

fn truth() -> Vec<f64> {
    let raw: Vec<f64> = (0..FACES).map(|f| (f as f64 * 0.9).cos() * 0.4).collect();
    let mean = raw.iter().sum::<f64>() / FACES as f64;
    raw.iter().map(|b| b - mean).collect()
}

/// (a) Covariances diagonal up to the closure term, V_i = c_i²·P·diag(s²)·P, with per-face
/// u_if = c_i·s_f: the per-face weights are c_i⁻² on every face, so the per-face weighted
/// mean of closed vectors is closed and is the GLS reference; and χ² is the textbook
/// Σ dᵀ V⁺ d with the SVD pseudo-inverse.
#[test]
fn kc_covariance_diagonal_up_to_closure_gives_the_per_face_means() {
    let s: Vec<f64> = (0..FACES).map(|f| 0.05 + 0.01 * (f % 5) as f64).collect();
    let scale = [1.0, 1.6, 0.7, 2.2];
    let p = projector(FACES);
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let truth = truth();
    let mut labs = Vec::new();
    let mut vs = Vec::new();
    let mut xs = Vec::new();
    for (i, c) in scale.iter().enumerate() {
        let d = DMatrix::from_diagonal(&DVector::from_iterator(
            FACES,
            s.iter().map(|s| (c * s).powi(2)),
        ));
        let v = &p * d * &p;
        let z: Vec<f64> = (0..FACES).map(|f| c * s[f] * normal(&mut rng)).collect();
        let noise = &p * DVector::from_vec(z);
        let x: Vec<f64> = truth.iter().zip(noise.iter()).map(|(t, e)| t + e).collect();
        let u: Vec<f64> = s.iter().map(|s| c * s).collect();
        labs.push(lab(&format!("L{i}"), &x, &u).with_covariance(flat(&v)));
        vs.push(v);
        xs.push(DVector::from_vec(x));
    }
    let kc = evaluate(
        &labs,
        &[],
        &KcOptions::new().with_largest_consistent_subset(false),
    )
    .unwrap();
    let vector = kc.vector.as_ref().unwrap();
    // the per-face weighted mean, written out: Σ x_if/c_i² / Σ 1/c_i²
    let weights: f64 = scale.iter().map(|c| c.powi(-2)).sum();
    let mut worst: f64 = 0.0;
    for f in 0..FACES {
        let mean: f64 = xs
            .iter()
            .zip(&scale)
            .map(|(x, c)| x[f] / (c * c))
            .sum::<f64>()
            / weights;
        worst = worst.max((vector.reference[f] - mean).abs());
        assert!((kc.reference[f] - mean).abs() < 1e-12);
    }
    eprintln!("diagonal up to closure: |x_ref,GLS − per-face mean| ≤ {worst:.1e}″");
    assert!(worst < 1e-12, "{worst}");
    let reference = DVector::from_vec(vector.reference.clone());
    let chi2: f64 = xs
        .iter()
        .zip(&vs)
        .map(|(x, v)| {
            let d = x - &reference;
            (d.transpose() * pinv(v) * &d)[(0, 0)]
        })
        .sum();
    assert!(
        (vector.chi2 - chi2).abs() < 1e-9 * chi2,
        "{} vs {chi2}",
        vector.chi2
    );
    assert_eq!(vector.dof, (FACES - 1) * (scale.len() - 1));
}

/// The raw covariance s²·R, R_jk = σ_j σ_k ρ^|j − k| with σ_j = 1 + 0.5·sin(j): faces
/// near each other correlated, unequally spread (not circulant).
fn raw(s: f64, rho: f64) -> DMatrix<f64> {
    let sigma = |j: usize| 1.0 + 0.5 * (j as f64).sin();
    DMatrix::from_fn(FACES, FACES, |j, k| {
        s * s * sigma(j) * sigma(k) * rho.powi(j.abs_diff(k) as i32)
    })
}

/// The closed covariance s²·P·R·P of a draw P·y, y ~ N(0, s²R).
fn correlated(s: f64, rho: f64) -> DMatrix<f64> {
    let p = projector(FACES);
    &p * raw(s, rho) * &p
}

/// (b) Laboratories whose faces are really correlated (each drawn from its own closed
/// covariance s_i²·P·R(ρ_i)·P): with the true covariances the closed vector's χ² has mean
/// ν = (N − 1)(n − 1) within its Monte Carlo error and the test rejects 5 %; taken as
/// independent (closed diagonal of the same u) the mean is biased and the test rejects
/// about twice as often (measured: 44.04 ± 0.22 against 41.71 ± 0.32, rejecting 5.9 %
/// against 10.5 %).
#[test]
fn kc_covariance_of_correlated_faces_gives_chi2_its_dof_and_independence_does_not() {
    let labs_s = [0.05, 0.07, 0.09, 0.12, 0.15];
    let labs_rho = [0.8, 0.85, 0.9, 0.75, 0.8];
    let truth = truth();
    let models: Vec<(DMatrix<f64>, DMatrix<f64>, Vec<f64>)> = labs_s
        .iter()
        .zip(&labs_rho)
        .map(|(&s, &rho)| {
            let v = correlated(s, rho);
            // draw y ~ N(0, s²R) by Cholesky, then close it: Cov(P y) = s²·P·R·P
            let r = raw(s, rho);
            let l = r.cholesky().expect("R is positive definite").l();
            let u = (0..FACES).map(|f| v[(f, f)].sqrt()).collect();
            (v, l, u)
        })
        .collect();
    let p = projector(FACES);
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let trials = 2000;
    let (mut with, mut without) = (Vec::new(), Vec::new());
    let (mut rejected_with, mut rejected_without) = (0usize, 0usize);
    for _ in 0..trials {
        let mut given = Vec::new();
        let mut plain = Vec::new();
        for (i, (v, l, u)) in models.iter().enumerate() {
            let z = DVector::from_iterator(FACES, (0..FACES).map(|_| normal(&mut rng)));
            let e = &p * (l * z);
            let x: Vec<f64> = truth.iter().zip(e.iter()).map(|(t, e)| t + e).collect();
            given.push(lab(&format!("L{i}"), &x, u).with_covariance(flat(v)));
            plain.push(lab(&format!("L{i}"), &x, u));
        }
        let options = KcOptions::new().with_largest_consistent_subset(false);
        let vector = evaluate(&given, &[], &options).unwrap().vector.unwrap();
        rejected_with += usize::from(!vector.consistent);
        with.push(vector.chi2);
        let vector = evaluate(&plain, &[], &options).unwrap().vector.unwrap();
        rejected_without += usize::from(!vector.consistent);
        without.push(vector.chi2);
    }
    let dof = ((FACES - 1) * (labs_s.len() - 1)) as f64;
    let summary = |x: &[f64]| {
        let m = x.iter().sum::<f64>() / x.len() as f64;
        let var = x.iter().map(|v| (v - m).powi(2)).sum::<f64>() / (x.len() - 1) as f64;
        (m, (var / x.len() as f64).sqrt())
    };
    let (mean_with, se_with) = summary(&with);
    let (mean_without, se_without) = summary(&without);
    eprintln!(
        "correlated faces, {trials} comparisons, ν = {dof}: mean χ² with the true covariances \
         {mean_with:.2} ± {se_with:.2}, taken as independent {mean_without:.2} ± {se_without:.2}; \
         rejected at 5 %: {:.3} and {:.3}",
        rejected_with as f64 / trials as f64,
        rejected_without as f64 / trials as f64
    );
    assert!(
        (mean_with - dof).abs() < 4.0 * se_with,
        "with covariances: {mean_with} ± {se_with} vs {dof}"
    );
    assert!(
        (mean_without - dof).abs() > 5.0 * se_without,
        "independent: {mean_without} ± {se_without} vs {dof}"
    );
    // the test's size: 5 % with the true covariances (binomial SE 0.005), not as independent
    let size_with = rejected_with as f64 / trials as f64;
    let size_without = rejected_without as f64 / trials as f64;
    assert!((size_with - 0.05).abs() < 0.015, "{size_with}");
    assert!(size_without > 0.08, "{size_without}");
}

fn refused(covariance: Vec<f64>) -> String {
    let u = vec![0.1; FACES];
    let labs = [
        lab("A", &truth(), &u).with_covariance(covariance),
        lab("B", &truth(), &u),
    ];
    match evaluate(&labs, &[], &KcOptions::new()) {
        Err(e @ KcError::Covariance { .. }) => e.to_string(),
        other => panic!("not refused: {other:?}"),
    }
}

#[test]
fn kc_covariance_refusals_name_the_laboratory_and_the_reason() {
    let good = correlated(0.1, 0.5);
    let message = refused(flat(&good)[..FACES * FACES - 1].to_vec());
    assert!(
        message.contains("laboratory A") && message.contains("144"),
        "{message}"
    );
    let mut asymmetric = good.clone();
    asymmetric[(0, 1)] += 1e-4;
    asymmetric[(0, 0)] -= 1e-4; // keeps row 1 closed
    assert!(refused(flat(&asymmetric)).contains("not symmetric"));
    let open = &good + DMatrix::from_element(FACES, FACES, 1e-3);
    assert!(refused(flat(&open)).contains("not closed"));
    // closed and symmetric, but with a negative eigenvalue: −w wᵀ for a closed w
    let mut w = DVector::from_element(FACES, 0.0);
    w[0] = 0.3;
    w[1] = -0.3;
    let indefinite = &good - &w * w.transpose();
    assert!(refused(flat(&indefinite)).contains("not positive semi-definite"));
    // rank N − 2: a closed direction with no uncertainty
    let p = projector(FACES);
    let q = &p - &w * w.transpose() / w.norm_squared();
    let singular = &q * &good * &q;
    assert!(refused(flat(&singular)).contains("singular on the closed subspace"));
    let mut not_a_number = flat(&good);
    not_a_number[5] = f64::NAN;
    assert!(refused(not_a_number).contains("entry (1, 6)"));
}
