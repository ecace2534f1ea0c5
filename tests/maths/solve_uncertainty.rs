//! Honest uncertainties: over 200 seeds of noisy simulated data with a fixed truth,
//! (estimate − truth)/u has an RMS close to 1 for β and for α, for the uncertainty from
//! the residuals (dof > 0) and from a stated reading noise (dof = 0).

use crate::common::{Stream, Truth, readings};
use polycal::measurement::Sigma;
use polycal::solve::{self, Method, SigmaSource, SolveOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const SEEDS: u64 = 200;

fn truth(n: usize) -> Truth {
    let beta: Vec<f64> = (0..n).map(|k| (k as f64 * 1.7).sin() * 0.8).collect();
    let alpha: Vec<f64> = (0..n)
        .map(|p| (2.0 * std::f64::consts::PI * p as f64 / n as f64 + 0.4).cos() * 0.6)
        .collect();
    Truth::closed(&beta, &alpha)
}

/// RMS of the normalised errors of β and α over all seeds.
fn normalised_rms(
    n: usize,
    streams: &[Stream],
    cycles: u32,
    closing: bool,
    sigma: f64,
    options: SolveOptions,
    expected_source: SigmaSource,
) -> (f64, f64) {
    let truth = truth(n);
    let normal = Normal::new(0.0, sigma).unwrap();
    let (mut sum_beta, mut sum_alpha, mut count) = (0.0, 0.0, 0.0);
    for seed in 0..SEEDS {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let set = readings(&truth, streams, cycles, closing, || normal.sample(&mut rng));
        let solution = solve::solve(&set, &options).unwrap();
        assert_eq!(solution.sigma.map(|s| s.1), Some(expected_source));
        let u_beta = solution.pitch_deviation_u().unwrap();
        let u_alpha = solution.encoder_error_u().unwrap();
        for k in 0..n {
            sum_beta += ((solution.pitch_deviation[k] - truth.beta[k]) / u_beta[k]).powi(2);
            sum_alpha += ((solution.encoder_error[k] - truth.alpha[k]) / u_alpha[k]).powi(2);
            count += 1.0;
        }
    }
    ((sum_beta / count).sqrt(), (sum_alpha / count).sqrt())
}

fn assert_honest((beta, alpha): (f64, f64), what: &str) {
    eprintln!("{what}: RMS of normalised errors β {beta:.4}, α {alpha:.4}");
    assert!(
        (0.85..=1.15).contains(&beta),
        "{what}: RMS of (β − truth)/u(β) = {beta}"
    );
    assert!(
        (0.85..=1.15).contains(&alpha),
        "{what}: RMS of (α − truth)/u(α) = {alpha}"
    );
}

#[test]
fn residual_sigma_with_repeats_and_closing_readings() {
    let streams = [(1, 1, 0, 0.3), (1, 2, 1, -0.6)];
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    let rms = normalised_rms(24, &streams, 6, true, 0.05, options, SigmaSource::Residual);
    assert_honest(rms, "24 faces, 6 cycles, closing");
}

#[test]
fn closed_form_with_repeats() {
    let streams = [(1, 1, 0, 0.3), (1, 2, 1, -0.6)];
    let options = SolveOptions::new().with_method(Method::ClosedForm);
    let rms = normalised_rms(24, &streams, 3, false, 0.05, options, SigmaSource::Residual);
    assert_honest(rms, "closed form, 3 cycles");
}

#[test]
fn stated_sigma_when_exactly_determined() {
    let streams = [(1, 1, 0, 0.3), (1, 2, 1, -0.6)];
    let options = SolveOptions::new()
        .with_method(Method::Auto)
        .with_sigma(Sigma::new(0.08).unwrap());
    let rms = normalised_rms(24, &streams, 1, false, 0.08, options, SigmaSource::Stated);
    assert_honest(rms, "bare cycle, stated σ");
}

#[test]
fn three_autocollimators_and_two_mountings() {
    let streams = [
        (1, 1, 0, 0.3),
        (1, 2, 5, -0.6),
        (2, 1, 2, 0.1),
        (2, 3, 9, 1.2),
    ];
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    let rms = normalised_rms(12, &streams, 2, true, 0.1, options, SigmaSource::Residual);
    assert_honest(rms, "12 faces, 4 streams");
}

/// Without a stated σ, an exactly determined fit has no uncertainties at all (null),
/// rather than invented ones.
#[test]
fn no_sigma_no_uncertainty() {
    let set = readings(
        &truth(8),
        &[(1, 1, 0, 0.0), (1, 2, 1, 0.0)],
        1,
        false,
        || 0.0,
    );
    let solution = solve::solve(&set, &SolveOptions::default()).unwrap();
    assert_eq!(solution.dof, 0);
    assert!(solution.residual_rms().is_none());
    assert!(solution.pitch_deviation_u().is_none());
    assert!(solution.encoder_error_u().is_none());
}

/// Hand-derived: on the bare two-autocollimator cycle, eqs. (7)–(8) give
/// β_k = δ[π(k)] − mean(δ) with N independent differences δ of variance 2σ², so
/// u(β_k) = σ·√(2(1 − 1/N)) and cov(β_j, β_k) = −2σ²/N (the closure covariance of
/// Estler, J. Res. NIST 103 (1998) 141, for N segments of variance 2σ²). Both solvers.
#[test]
fn bare_cycle_pitch_covariance_by_hand() {
    let sigma = 0.07;
    for n in [3usize, 7, 24, 60] {
        let set = readings(
            &truth(n),
            &[(1, 1, 0, 0.0), (1, 2, 1, 0.0)],
            1,
            false,
            || 0.0,
        );
        for method in [Method::ClosedForm, Method::LeastSquares] {
            let options = SolveOptions::new()
                .with_method(method)
                .with_sigma(Sigma::new(sigma).unwrap());
            let solution = solve::solve(&set, &options).unwrap();
            let cov = solution.covariance().unwrap();
            for j in 0..n {
                for k in 0..n {
                    let expected = if j == k {
                        2.0 * sigma * sigma * (1.0 - 1.0 / n as f64)
                    } else {
                        -2.0 * sigma * sigma / n as f64
                    };
                    assert!(
                        (cov[(j, k)] - expected).abs() < 1e-14,
                        "N={n} {method:?} ({j},{k})"
                    );
                }
            }
        }
    }
}

/// `Solution::family_covariance`: each family's block of σ²Q, its diagonal the family's
/// u², symmetric; φ's block the double prefix sum of β's (checked here by summing the
/// whole covariance matrix directly), on a design with closing readings and two setups.
#[test]
fn family_covariances_are_blocks_of_the_whole_covariance() {
    use polycal::results::Quantity;
    use polycal::simulate::{SimulationConfig, simulate};
    use polycal::solve::{SolveOptions, solve};
    let (set, _) = simulate(&SimulationConfig {
        faces: 9,
        setups: 2,
        setup_shift_faces: 2,
        cycles: 3,
        ..SimulationConfig::default()
    })
    .unwrap();
    let solution = solve(&set, &SolveOptions::default()).unwrap();
    let whole = solution.covariance().unwrap();
    let layout = solution.layout;
    let n = solution.faces;
    for (family, u) in [
        (
            Quantity::PitchDeviation,
            solution.pitch_deviation_u().unwrap(),
        ),
        (
            Quantity::FaceDeviation,
            solution.face_deviation_u().unwrap(),
        ),
        (Quantity::EncoderError, solution.encoder_error_u().unwrap()),
        (Quantity::SetupError, solution.setup_error_u().unwrap()),
    ] {
        let (m, cov) = solution.family_covariance(family).unwrap();
        assert_eq!(m, u.len(), "{family:?}");
        for i in 0..m {
            assert!(
                (cov[i * m + i].max(0.0).sqrt() - u[i]).abs() < 1e-12,
                "{family:?} {i}"
            );
            for j in 0..m {
                assert!((cov[i * m + j] - cov[j * m + i]).abs() < 1e-12);
                // against the whole matrix
                let expected = match family {
                    Quantity::PitchDeviation => whole[(layout.pitch(i + 1), layout.pitch(j + 1))],
                    Quantity::EncoderError => whole[(layout.encoder(i), layout.encoder(j))],
                    Quantity::SetupError => whole[(layout.setup(i), layout.setup(j))],
                    _ => (0..=i)
                        .flat_map(|a| (0..=j).map(move |b| (a, b)))
                        .map(|(a, b)| whole[(layout.pitch(a + 1), layout.pitch(b + 1))])
                        .sum(),
                };
                assert!(
                    (cov[i * m + j] - expected).abs() < 1e-12,
                    "{family:?} {i} {j}"
                );
            }
        }
    }
    assert_eq!(
        solution
            .family_covariance(Quantity::PitchDeviation)
            .unwrap()
            .0,
        n
    );
}
