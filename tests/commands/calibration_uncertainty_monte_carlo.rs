//! The Monte Carlo evaluation of the calibration results' uncertainty
//! (`polycal solve --monte-carlo`), checked against independent truth: against the
//! propagation (a property over random designs and budgets), against the exact quantiles
//! of a normal ⊕ rectangular sum, validating the GUM where it holds, reproducible
//! whatever the number of threads, and its progress reported.

use std::path::PathBuf;

use polycal::solve::{self, Method};
use polycal::uncertainty::calibration::{
    self, InstrumentBudget, McOptions, McSolver, Scope, ScopedComponent,
};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::Trials;
use polycal::uncertainty::student::normal_cdf;
use proptest::prelude::*;

use crate::calibration_uncertainty_support::{close, design, mc, one, propagated_u, solved};

const SCOPES: [Scope; 5] = [
    Scope::EachReading,
    Scope::EachAutocollimator,
    Scope::EachPosition,
    Scope::EachStop,
    Scope::Result,
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(8))]

    /// For the linear solver, the Monte Carlo standard uncertainties match the
    /// propagated ones within the Monte Carlo noise, and the means the estimates, over
    /// random designs (faces, cycles, closing readings, solver), σ stated or from the
    /// residuals, and budgets of rectangular, normal and triangular errors of any scope.
    #[test]
    fn monte_carlo_matches_the_propagation(
        n in 5usize..13,
        cycles in 1u32..4,
        closing in any::<bool>(),
        lsq in any::<bool>(),
        scopes in proptest::array::uniform3(0usize..5),
        widths in proptest::array::uniform3(0.01f64..0.08),
        seed in 0u64..10_000,
    ) {
        let set = design(n, cycles, closing, seed);
        let mut solution = solved(&set, Method::Auto, Some(0.05));
        if solution.dof < 10 {
            solution = solved(&set, Method::Auto, None);
            solution.sigma = Some((0.05, solve::SigmaSource::Stated));
        }
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "rectangular",
                Distribution::Rectangular { half_width: widths[0] },
                SCOPES[scopes[0]],
            ),
            ScopedComponent::type_b("normal", Distribution::Normal { u: widths[1] }, SCOPES[scopes[1]]),
            ScopedComponent::type_b(
                "triangular",
                Distribution::Triangular { half_width: widths[2] },
                SCOPES[scopes[2]],
            ),
        ]);
        let trials = 40_000;
        let solver = if lsq { McSolver::LeastSquares } else { McSolver::Auto };
        let (unc, result) = mc(&set, &solution, &budget, trials, seed, solver);
        let families = [&result.pitch_deviation, &result.face_deviation, &result.encoder_error];
        let estimates = [&solution.pitch_deviation, &solution.face_deviation, &solution.encoder_error];
        for (f, (family, estimates)) in families.iter().zip(estimates).enumerate() {
            for (j, estimate) in estimates.iter().enumerate() {
                let expected = propagated_u(&unc, f, j);
                if expected == 0.0 {
                    prop_assert_eq!(family.u[j], 0.0); // φ[N]
                    continue;
                }
                // relative noise of a standard deviation ≈ √((κ − 1)/(4M)) ≤ 0.6 %
                prop_assert!(
                    close(family.u[j], expected, 0.035),
                    "family {} index {}: Monte Carlo {} vs propagated {}", f, j, family.u[j], expected
                );
                prop_assert!(
                    (family.mean[j] - estimate).abs() < 5.0 * expected / (trials as f64).sqrt()
                );
                prop_assert!(family.low[j] < family.mean[j] && family.mean[j] < family.high[j]);
            }
        }
    }
}

/// The interval of Monte Carlo is the exact one: a normal type A part (stated σ) plus a
/// dominant rectangular `result` error has the quantiles of N(0, s²) ⊕ U(−a, a),
/// computed here by bisection on its distribution function; the GUM interval (k from the
/// normal) is then too wide and is not validated. On one cycle by the closed form, and
/// on three cycles by least squares, whose trials draw each cell's three readings as one
/// sum: s = σ·√(2(N − 1)/(N·R)) by hand (the paper's eq. (11) over R cycles) checks both.
#[test]
fn monte_carlo_interval_is_the_exact_convolution() {
    for (cycles, solver, name) in [
        (1, McSolver::Auto, "closed-form"),
        (3, McSolver::LeastSquares, "lsq"),
    ] {
        exact_convolution(cycles, solver, name);
    }
}

fn exact_convolution(cycles: u32, solver: McSolver, name: &str) {
    let n = 8;
    let sigma = 0.05;
    let a = 0.3;
    let set = design(n, cycles, false, 11);
    let mut solution = solved(&set, Method::Auto, Some(sigma));
    // σ stated (the fit of several cycles would take it from its residuals)
    solution.sigma = Some((sigma, solve::SigmaSource::Stated));
    let budget = one(Distribution::Rectangular { half_width: a }, Scope::Result);
    let trials = 200_000;
    let (unc, result) = mc(&set, &solution, &budget, trials, 5, solver);
    assert_eq!(result.solver, name);
    let s = unc.pitch_deviation.u_a[0];
    assert!(close(
        s,
        sigma * (2.0 * 7.0 / (8.0 * f64::from(cycles))).sqrt(),
        1e-12
    ));
    let g = |z: f64| z * normal_cdf(z) + (-0.5 * z * z).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let cdf = |x: f64| s / (2.0 * a) * (g((x + a) / s) - g((x - a) / s));
    let density = |x: f64| (normal_cdf((x + a) / s) - normal_cdf((x - a) / s)) / (2.0 * a);
    let (mut lo, mut hi) = (0.0, a + 10.0 * s);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if cdf(mid) < 0.975 { lo = mid } else { hi = mid }
    }
    let q = 0.5 * (lo + hi);
    let tolerance = 5.0 * (0.025 * 0.975 / trials as f64).sqrt() / density(q);
    for k in 0..n {
        let beta = solution.pitch_deviation[k];
        let f = &result.pitch_deviation;
        assert!(
            (f.high[k] - (beta + q)).abs() < tolerance,
            "{} vs {}",
            f.high[k],
            beta + q
        );
        assert!(
            (f.low[k] - (beta - q)).abs() < tolerance,
            "{} vs {}",
            f.low[k],
            beta - q
        );
        // GUM: 1.96·√(s² + a²/3) overshoots the exact q by far more than δ
        assert!(unc.pitch_deviation.expanded_u[k] - q > 0.03);
        assert!(!f.passed[k]);
    }
    assert!(!result.validated);
}

/// Where the GUM holds (normal errors, σ stated), Monte Carlo validates it.
#[test]
fn monte_carlo_validates_a_normal_calibration() {
    let set = design(12, 1, false, 12);
    let solution = solved(&set, Method::Auto, Some(0.05));
    let budget = one(Distribution::Normal { u: 0.03 }, Scope::EachReading);
    let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
    let options = McOptions::new(Trials::Fixed(200_000))
        .with_seed(3)
        .with_significant_digits(1)
        .with_solver(McSolver::Auto);
    let result = calibration::monte_carlo(&set, &solution, &budget, &unc, &options).unwrap();
    assert!(result.validated);
    assert_eq!(
        (result.solver, result.reading_noise),
        ("closed-form", "normal")
    );
}

/// The same seed gives the same numbers with one thread or two, fixed or adaptive; another
/// seed gives other numbers.
#[test]
fn monte_carlo_is_reproducible_whatever_the_threads() {
    let budget = InstrumentBudget::read_path(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/budgets/instrument.toml"),
    )
    .unwrap();
    let set = design(24, 2, true, 13);
    let solution = solved(&set, Method::Auto, None);
    let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
    let run = |threads: usize, trials: Trials, seed: u64| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let options = McOptions::new(trials)
            .with_seed(seed)
            .with_significant_digits(1);
        pool.install(|| calibration::monte_carlo(&set, &solution, &budget, &unc, &options))
            .unwrap()
    };
    let fixed = Trials::Fixed(25_500);
    let one = run(1, fixed, 7);
    assert_eq!(one, run(2, fixed, 7));
    assert_ne!(
        one.pitch_deviation.mean,
        run(2, fixed, 8).pitch_deviation.mean
    );
    let adaptive = Trials::Adaptive {
        significant_digits: 1,
        max_trials: 1_000_000,
    };
    let a = run(1, adaptive, 7);
    assert_eq!(a, run(2, adaptive, 7));
    assert_eq!(a.trials % 10_000, 0);
    assert!(a.sequences.unwrap() >= 2);
}

/// The progress observer of the options sees every trial, block by block (the total of a
/// fixed run known, none for the adaptive procedure), and changes no number.
#[test]
fn monte_carlo_reports_progress() {
    let budget = one(
        Distribution::Rectangular { half_width: 0.1 },
        Scope::EachStop,
    );
    let set = design(12, 2, false, 14);
    let solution = solved(&set, Method::Auto, None);
    let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
    let seen = std::sync::Mutex::new(Vec::new());
    let observer = |done: u64, total: Option<u64>| seen.lock().unwrap().push((done, total));
    let adaptive = Trials::Adaptive {
        significant_digits: 1,
        max_trials: 1_000_000,
    };
    for trials in [Trials::Fixed(31_234), adaptive] {
        let options = McOptions::new(trials).with_seed(2);
        let quiet = calibration::monte_carlo(&set, &solution, &budget, &unc, &options).unwrap();
        let observed = calibration::monte_carlo(
            &set,
            &solution,
            &budget,
            &unc,
            &options.with_progress(&observer),
        )
        .unwrap();
        assert_eq!(quiet, observed);
        let calls = std::mem::take(&mut *seen.lock().unwrap());
        assert!(calls.windows(2).all(|w| w[0].0 < w[1].0), "{calls:?}");
        let (done, total) = *calls.last().unwrap();
        match trials {
            Trials::Fixed(m) => {
                assert_eq!(done, quiet.trials as u64);
                assert_eq!(total, Some(m as u64));
                assert_eq!(calls.len(), m.div_ceil(1000));
            }
            Trials::Adaptive { .. } => {
                // The sequences, then all their trials again for the exact intervals.
                assert_eq!(done, 2 * quiet.trials as u64);
                assert!(calls.iter().all(|c| c.1.is_none()));
            }
        }
    }
}
