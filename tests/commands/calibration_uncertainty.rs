//! The uncertainty of the calibration results (`polycal solve --budget`,
//! `--monte-carlo`), checked against independent truth:
//!
//! - hand-derived propagation through the paper's design: on the bare N-face cycle an
//!   each-reading error u_B gives u(β_k)² = 2(σ² + u_B²)(1 − 1/N) and
//!   u(φ_f)² = 2(σ² + u_B²)·f(N − f)/N exactly; a constant offset per autocollimator adds
//!   exactly 0 to β, φ and α (and u² to its setup error); an error per table position
//!   adds u²(1 − 1/N) to α only, one per stop u²(1 − 1/N)/R; a `result` component adds
//!   u² to every quantity; Welch–Satterthwaite and k by hand;
//! - Monte Carlo against the propagation (a property over random designs and budgets),
//!   against the exact quantiles of a normal ⊕ rectangular sum, and reproducibility
//!   whatever the number of threads;
//! - the binary end to end: `solve --budget --format csv` fills `U` and `k`, and the file
//!   goes straight into `polycal compare` against the simulation's truth.

use std::path::PathBuf;
use std::process::{Command, Output};

use crate::common::{Stream, Truth, readings};
use polycal::measurement::MeasurementSet;
use polycal::measurement::Sigma;
use polycal::solve::{self, Method, Solution, SolveOptions};
use polycal::uncertainty::DofPolicy;
use polycal::uncertainty::budget::EvaluationType;
use polycal::uncertainty::calibration::{
    self, CalibrationUncertainty, InstrumentBudget, McOptions, McSolver, Scope, ScopedComponent,
};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::Trials;
use polycal::uncertainty::student::{normal_cdf, t_quantile};
use proptest::prelude::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution as _, Normal};
use serde_json::Value;

const PAIR: [Stream; 2] = [(1, 1, 0, 0.4), (1, 2, 1, -0.7)];

fn truth(n: usize) -> Truth {
    let beta: Vec<f64> = (0..n).map(|k| (k as f64 * 1.3).sin() * 0.6).collect();
    let alpha: Vec<f64> = (0..n)
        .map(|p| (2.0 * std::f64::consts::PI * p as f64 / n as f64 + 0.3).sin() * 0.5)
        .collect();
    Truth::closed(&beta, &alpha)
}

/// Noisy readings of the two-autocollimator design.
fn design(n: usize, cycles: u32, closing: bool, seed: u64) -> MeasurementSet {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 0.05).unwrap();
    readings(&truth(n), &PAIR, cycles, closing, || noise.sample(&mut rng))
}

fn solved(set: &MeasurementSet, method: Method, sigma: Option<f64>) -> Solution {
    solve::solve(
        set,
        &SolveOptions::new()
            .with_method(method)
            .with_sigma_opt(sigma.map(|s| Sigma::new(s).unwrap())),
    )
    .unwrap()
}

fn one(distribution: Distribution, scope: Scope) -> InstrumentBudget {
    InstrumentBudget::new(vec![ScopedComponent::type_b("x", distribution, scope)])
}

fn close(a: f64, b: f64, tolerance: f64) -> bool {
    (a - b).abs() <= tolerance * b.abs().max(1e-300)
}

/// The bare cycle with a stated σ and an each-reading error: the hand-derived variances,
/// φ[N] without uncertainty, ν_eff and k by hand, for both solvers.
#[test]
fn bare_cycle_each_reading_error_is_hand_derived() {
    let n = 24;
    let (sigma, u_b, nu_b) = (0.05, 0.03, 20.0);
    let set = design(n, 1, false, 1);
    for method in [Method::ClosedForm, Method::LeastSquares] {
        let solution = solved(&set, method, Some(sigma));
        assert_eq!(solution.dof, 0);
        let budget = InstrumentBudget::new(vec![
            ScopedComponent::type_b(
                "resolution",
                Distribution::Rectangular {
                    half_width: u_b * 3f64.sqrt(),
                },
                Scope::EachReading,
            )
            .with_dof(Some(nu_b)),
        ]);
        let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
        assert_eq!((unc.sigma_source, unc.type_a_dof), ("stated", None));
        let nf = n as f64;
        for k in 0..n {
            let expected = 2.0 * (sigma * sigma + u_b * u_b) * (1.0 - 1.0 / nf);
            let got = unc.pitch_deviation.u[k].powi(2);
            assert!(
                close(got, expected, 1e-12),
                "β{}: {got} vs {expected}",
                k + 1
            );
            // ν_eff = u_c⁴ / (c_B⁴/ν_B), the type A part having ν = ∞ (stated σ)
            let c_b2 = 2.0 * u_b * u_b * (1.0 - 1.0 / nf);
            let nu = expected * expected / (c_b2 * c_b2 / nu_b);
            assert!(close(unc.pitch_deviation.dof_eff[k].unwrap(), nu, 1e-9));
            let kf = t_quantile(0.95, Some(nu));
            assert!(close(unc.pitch_deviation.k[k].unwrap(), kf, 1e-12));
            assert!(close(
                unc.pitch_deviation.expanded_u[k],
                kf * expected.sqrt(),
                1e-12
            ));
        }
        for f in 1..n {
            let ff = f as f64;
            let expected = 2.0 * (sigma * sigma + u_b * u_b) * ff * (nf - ff) / nf;
            let got = unc.face_deviation.u[f - 1].powi(2);
            assert!(close(got, expected, 1e-10), "φ{f}: {got} vs {expected}");
        }
        // φ[N] is the reference: no uncertainty, no k
        assert_eq!(unc.face_deviation.u[n - 1], 0.0);
        assert_eq!(unc.face_deviation.expanded_u[n - 1], 0.0);
        assert_eq!(unc.face_deviation.k[n - 1], None);
        // the type A part is the fit's own u(β), u(α)
        let fit_u = solution.pitch_deviation_u().unwrap();
        let fit_ua = solution.encoder_error_u().unwrap();
        for k in 0..n {
            assert!(close(unc.pitch_deviation.u_a[k], fit_u[k], 1e-12));
            assert!(close(unc.encoder_error.u_a[k], fit_ua[k], 1e-12));
        }
    }
}

/// A constant offset of each autocollimator is absorbed by the setup errors: exactly
/// (to rounding) nothing for β, φ and α, the whole u for the setup errors — for the bare
/// cycle, for repeated cycles with closing readings, and for three autocollimators.
#[test]
fn constant_offsets_add_nothing_to_beta_phi_alpha() {
    let u = 0.5;
    let three: [Stream; 3] = [(1, 1, 0, 0.1), (1, 2, 1, 0.2), (1, 3, 5, -0.3)];
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let sets = [
        design(24, 1, false, 2),
        design(12, 4, true, 3),
        readings(&truth(12), &three, 2, true, || noise.sample(&mut rng)),
    ];
    for set in &sets {
        let solution = solved(set, Method::Auto, Some(0.05));
        let budget = one(Distribution::Normal { u }, Scope::EachAutocollimator);
        let unc = calibration::evaluate(set, &solution, &budget).unwrap();
        let c = &unc.components[0];
        for v in c
            .pitch_deviation
            .iter()
            .chain(&c.face_deviation)
            .chain(&c.encoder_error)
        {
            assert!(v.abs() < 1e-12, "offset leaks {v}");
        }
        for v in &c.setup_error {
            assert!(close(*v, u, 1e-12), "setup error gets {v}");
        }
        let fit_u = solution.pitch_deviation_u().unwrap();
        for (uc, ua) in unc.pitch_deviation.u.iter().zip(&fit_u) {
            assert!(close(*uc, *ua, 1e-12));
        }
    }
}

/// An error per table position moves α[p] by e_p − ē and nothing else: u²(1 − 1/N) for
/// α, 0 for β and φ, whatever the design; one per stop of R cycles of the paper's design
/// averages to u²(1 − 1/N)/R.
#[test]
fn position_and_stop_errors_reach_alpha_only() {
    let u = 0.02;
    for (set, n) in [(design(24, 1, false, 4), 24), (design(10, 3, true, 5), 10)] {
        let solution = solved(&set, Method::Auto, Some(0.05));
        let unc = calibration::evaluate(
            &set,
            &solution,
            &one(
                Distribution::Rectangular {
                    half_width: u * 3f64.sqrt(),
                },
                Scope::EachPosition,
            ),
        )
        .unwrap();
        let c = &unc.components[0];
        let expected = u * (1.0 - 1.0 / n as f64).sqrt();
        for p in 0..n {
            assert!(close(c.encoder_error[p], expected, 1e-12));
            assert!(c.pitch_deviation[p].abs() < 1e-12);
            assert!(c.face_deviation[p].abs() < 1e-12);
        }
    }
    let (n, r) = (16, 5);
    let set = design(n, r, false, 6);
    let solution = solved(&set, Method::Auto, None);
    let unc = calibration::evaluate(
        &set,
        &solution,
        &one(Distribution::Normal { u }, Scope::EachStop),
    )
    .unwrap();
    let c = &unc.components[0];
    let expected = u * ((1.0 - 1.0 / n as f64) / r as f64).sqrt();
    for p in 0..n {
        assert!(close(c.encoder_error[p], expected, 1e-12));
        assert!(c.pitch_deviation[p].abs() < 1e-12);
    }
}

/// A `result` component adds u² to every quantity (the paper's Table 1 way), except the
/// reference face φ[N].
#[test]
fn result_components_add_directly() {
    let set = design(12, 3, true, 7);
    let solution = solved(&set, Method::Auto, None);
    let u = 0.2050;
    let unc = calibration::evaluate(
        &set,
        &solution,
        &one(
            Distribution::Rectangular {
                half_width: 0.71 / 2.0,
            },
            Scope::Result,
        ),
    )
    .unwrap();
    for (name, family) in unc.families() {
        for (i, (uc, ua)) in family.u.iter().zip(&family.u_a).enumerate() {
            if name == "face_deviation" && i == 11 {
                assert_eq!(*uc, 0.0);
                continue;
            }
            assert!(
                close(uc * uc, ua * ua + (0.71f64 / 12f64.sqrt()).powi(2), 1e-12),
                "{name} {i}"
            );
            assert!((uc * uc - ua * ua).sqrt() - u < 1e-4);
        }
    }
}

/// Welch–Satterthwaite with the fit's residual degrees of freedom, and the three dof
/// policies, by hand on R cycles of the paper's design.
#[test]
fn welch_satterthwaite_and_policies_by_hand() {
    let (n, r) = (24, 6);
    let set = design(n, r, false, 8);
    let solution = solved(&set, Method::Auto, None);
    let dof = (2 * n * r as usize - 2 * n) as f64;
    assert_eq!(solution.dof as f64, dof);
    let sigma = solution.sigma.unwrap().0;
    let (u_b, nu_b) = (0.04, 12.0);
    let component =
        ScopedComponent::type_b("e", Distribution::Normal { u: u_b }, Scope::EachReading)
            .with_dof(Some(nu_b));
    let gain = 2.0 * (1.0 - 1.0 / n as f64) / r as f64;
    let ua2 = sigma * sigma * gain;
    let ub2 = u_b * u_b * gain;
    let nu = (ua2 + ub2).powi(2) / (ua2 * ua2 / dof + ub2 * ub2 / nu_b);
    for (policy, k) in [
        (DofPolicy::Fractional, t_quantile(0.95, Some(nu))),
        (DofPolicy::Floor, t_quantile(0.95, Some(nu.floor()))),
        (DofPolicy::K2, 2.0),
    ] {
        let budget = InstrumentBudget::new(vec![component.clone()]).with_dof_policy(policy);
        let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
        assert_eq!(unc.type_a_dof, Some(dof));
        for j in 0..n {
            assert!(close(unc.pitch_deviation.u[j], (ua2 + ub2).sqrt(), 1e-12));
            assert!(close(unc.pitch_deviation.dof_eff[j].unwrap(), nu, 1e-9));
            assert!(
                close(unc.pitch_deviation.k[j].unwrap(), k, 1e-12),
                "{policy}"
            );
        }
    }
    // p = 0.99 gives the t factor at 99 %
    let budget = InstrumentBudget::new(vec![component]).with_coverage(0.99);
    let unc = calibration::evaluate(&set, &solution, &budget).unwrap();
    assert!(close(
        unc.pitch_deviation.k[0].unwrap(),
        t_quantile(0.99, Some(nu)),
        1e-12
    ));
}

/// Without σ (exactly determined, nothing stated) there is no type A: refused.
#[test]
fn no_sigma_is_refused() {
    let set = design(8, 1, false, 9);
    let solution = solved(&set, Method::Auto, None);
    let error = calibration::evaluate(
        &set,
        &solution,
        &one(Distribution::Normal { u: 0.1 }, Scope::Result),
    )
    .unwrap_err();
    assert!(
        matches!(error, calibration::CalibrationError::NoSigma),
        "{error}"
    );
    assert!(!error.to_string().contains("--"), "{error}");
}

/// The budget file: `acts_on` per component, inherited by nested components, default
/// `result`; unknown values, `acts_on` inside an inline table, typos and correlations are
/// refused with the place.
#[test]
fn budget_file_scopes() {
    let text = r#"
p = 0.99
dof_policy = "k2"

[[component]]
name = "Autocollimator"
acts_on = "each-reading"

  [[component.component]]
  name = "Resolution"
  type = "B"
  distribution = "rectangular"
  full_width = 0.001

  [[component.component]]
  name = "Zero"
  type = "B"
  u = 0.3
  sensitivity = 2
  acts_on = "each-autocollimator"

[[component]]
name = "Mounting"
type = "B"
u = 0.02
"#;
    let budget = InstrumentBudget::from_toml_str(text, "b.toml").unwrap();
    assert_eq!((budget.p, budget.dof_policy), (0.99, DofPolicy::K2));
    let scopes: Vec<(&str, Scope)> = budget
        .components
        .iter()
        .map(|c| (c.name.as_str(), c.scope))
        .collect();
    assert_eq!(
        scopes,
        [
            ("Autocollimator / Resolution", Scope::EachReading),
            ("Autocollimator / Zero", Scope::EachAutocollimator),
            ("Mounting", Scope::Result),
        ]
    );
    assert!(close(
        budget.components[1].standard_uncertainty(),
        0.6,
        1e-15
    ));

    let refused = |text: &str, wanted: &str| {
        let error = InstrumentBudget::from_toml_str(text, "b.toml")
            .unwrap_err()
            .to_string();
        assert!(error.contains(wanted), "{error:?} lacks {wanted:?}");
    };
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\nacts_on = \"each-cycle\"\n",
        "b.toml:5:11: unknown acts_on \"each-cycle\"",
    );
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\nact_on = \"result\"\n",
        "b.toml:5:1",
    );
    refused(
        "component = [{ name = \"a\", type = \"B\", u = 0.1, acts_on = \"result\" }]\n",
        "acts_on on a line of its own",
    );
    refused(
        "[[component]]\nname = \"a\"\ntype = \"B\"\nu = 0.1\n[[component]]\nname = \"b\"\n\
         type = \"B\"\nu = 0.1\n[[correlation]]\nbetween = [\"a\", \"b\"]\nr = 0.5\n",
        "correlations are not supported",
    );
    // the paper's Table 1 file reads (every line acting on the result) and its type A
    // lines draw a caution: the fit gives the repeatability already
    let paper = InstrumentBudget::read_path(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("examples/budgets/paper-table1.toml"),
    )
    .unwrap();
    assert!(paper.components.iter().all(|c| c.scope == Scope::Result));
    assert_eq!(paper.notes().len(), 2);
}

/// u_c of Monte Carlo: the propagated variance, with the type A part inflated to the
/// variance of the multivariate t noise, ν/(ν − 2), when σ comes from the residuals.
fn propagated_u(unc: &CalibrationUncertainty, family: usize, j: usize) -> f64 {
    let f = unc.families()[family].1;
    let inflation = unc.type_a_dof.map_or(1.0, |nu| nu / (nu - 2.0));
    (f.u_a[j].powi(2) * inflation + f.u[j].powi(2) - f.u_a[j].powi(2)).sqrt()
}

fn mc(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    trials: usize,
    seed: u64,
    solver: McSolver,
) -> (CalibrationUncertainty, calibration::CalibrationMonteCarlo) {
    let unc = calibration::evaluate(set, solution, budget).unwrap();
    let options = McOptions::new(Trials::Fixed(trials))
        .with_seed(seed)
        .with_significant_digits(2)
        .with_solver(solver);
    let result = calibration::monte_carlo(set, solution, budget, &unc, &options).unwrap();
    (unc, result)
}

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

// ---------------------------------------------------------------------------------------
// A model with effect terms (the final model of `diagnose`)
// ---------------------------------------------------------------------------------------

/// A diagnosed run whose final model has effect terms: 12 faces, 3 cycles with closing
/// readings, autocollimator 2 drifting 1.5″/h and one reading 2″ off.
fn diagnosed_run() -> (MeasurementSet, polycal::diagnose::Diagnosis) {
    use polycal::effects::Effect;
    use polycal::simulate::{SimulationConfig, simulate};
    let config = SimulationConfig {
        faces: 12,
        cycles: 3,
        closing: true,
        noise_arcsec: 0.05,
        effects: vec![
            Effect::Drift {
                ac: 2,
                value: 1.5,
                quadratic: None,
            },
            Effect::Outlier {
                cycle: 2,
                step: 5,
                ac: 1,
                setup: None,
                value: 2.0,
            },
        ],
        seed: 11,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).unwrap();
    let diagnosis =
        polycal::diagnose::diagnose(&set, &polycal::diagnose::DiagnoseOptions::default()).unwrap();
    assert!(
        !diagnosis.effects.is_empty(),
        "the injected effects are found"
    );
    assert_eq!(diagnosis.after.layout.effects, diagnosis.effects.len());
    (set, diagnosis)
}

/// The reported quantities of a refit with the given effect columns:
/// [β (N), φ (N), α (N), setup errors (K)].
fn refit(set: &MeasurementSet, regressors: &[Vec<f64>]) -> Vec<f64> {
    let s = solve::least_squares_with_regressors(set, regressors, None).unwrap();
    let mut out = s.pitch_deviation.clone();
    out.extend_from_slice(&s.face_deviation);
    out.extend_from_slice(&s.encoder_error);
    out.extend(s.setup_error.iter().map(|e| e.value));
    out
}

/// The budget through a model with effect terms, against independent truth: the
/// regressors are rebuilt from the effects found (`Effect::regressor`), and the gain of
/// every scope, G_j = Σ_g (Σ_{i∈g} L_ji)², is measured by refitting the readings with
/// those of one group g moved by 1″ (the fit is linear, so the change of quantity j is
/// Σ_{i∈g} L_ji) — no solution operator, no cofactor matrix. Every component's
/// contribution to every β, φ, α and setup error is u·√G_j.
#[test]
fn effect_terms_propagate_like_refits() {
    use polycal::effects::EffectContext;
    let (set, diagnosis) = diagnosed_run();
    let context = EffectContext::of(&set.readings);
    let regressors: Vec<Vec<f64>> = diagnosis
        .effects
        .iter()
        .map(|found| {
            set.readings
                .iter()
                .map(|r| found.effect.regressor(r, &context))
                .collect()
        })
        .collect();
    let centre = refit(&set, &regressors);
    let after = &diagnosis.after;
    for (f, b) in after.pitch_deviation.iter().enumerate() {
        assert!((centre[f] - b).abs() < 1e-12, "the final model, refitted");
    }
    let u = 0.01;
    let scopes = [
        Scope::EachReading,
        Scope::EachAutocollimator,
        Scope::EachPosition,
        Scope::EachStop,
    ];
    let budget = InstrumentBudget::new(
        scopes
            .iter()
            .map(|&scope| {
                ScopedComponent::type_b(scope.as_str(), Distribution::Normal { u }, scope)
            })
            .collect(),
    );
    let unc = calibration::evaluate(&set, after, &budget).unwrap();
    let n = set.faces;
    for (c, scope) in unc.components.iter().zip(scopes) {
        let mut groups: std::collections::BTreeMap<(u32, u32, usize, usize), Vec<usize>> =
            Default::default();
        for (i, r) in set.readings.iter().enumerate() {
            let key = match scope {
                Scope::EachReading => (0, 0, 0, i),
                Scope::EachAutocollimator => (r.ac, 0, 0, 0),
                Scope::EachPosition => (0, 0, r.step % n, 0),
                _ => (r.setup, r.cycle, r.step, 0),
            };
            groups.entry(key).or_default().push(i);
        }
        let mut gain = vec![0.0; centre.len()];
        for members in groups.values() {
            let mut moved = set.clone();
            for &i in members {
                moved.readings[i].reading_arcsec += 1.0;
            }
            for (g, (m, c)) in gain
                .iter_mut()
                .zip(refit(&moved, &regressors).iter().zip(&centre))
            {
                *g += (m - c).powi(2);
            }
        }
        let got: Vec<f64> = c
            .pitch_deviation
            .iter()
            .chain(&c.face_deviation)
            .chain(&c.encoder_error)
            .chain(&c.setup_error)
            .copied()
            .collect();
        assert_eq!(got.len(), gain.len());
        for (j, (got, g)) in got.iter().zip(&gain).enumerate() {
            let expected = u * g.sqrt();
            assert!(
                (got - expected).abs() < 1e-9,
                "{scope}, quantity {j}: {got} vs {expected}"
            );
        }
    }
}

/// The budget of the final model with no component but the fit's own type A gives
/// U/k = σ√Q_jj of that model's covariance, read directly from the solution (β and α
/// from its diagonal, φ_f from the sum of the β block up to f); one more each-reading
/// type-A component of u = σ with the fit's dof doubles the variance, with
/// ν_eff = 2·dof (Welch–Satterthwaite: (2u²)² / (u⁴/dof + u⁴/dof)).
#[test]
fn final_model_budget_is_its_covariance() {
    let (set, diagnosis) = diagnosed_run();
    let after = &diagnosis.after;
    let n = set.faces;
    let cov = after.covariance().unwrap();
    let sigma = after.sigma.unwrap().0;
    let dof = after.dof as f64;
    let mut fit_u = vec![0.0; 3 * n];
    for f in 0..n {
        fit_u[f] = cov[(f, f)].sqrt();
        fit_u[2 * n + f] = cov[(n + f, n + f)].sqrt();
        let mut var = 0.0;
        for i in 0..=f {
            for j in 0..=f {
                var += cov[(i, j)];
            }
        }
        fit_u[n + f] = var.max(0.0).sqrt();
    }
    let families = |unc: &CalibrationUncertainty| {
        let mut v: Vec<(f64, Option<f64>, Option<f64>)> = Vec::new();
        for fam in [
            &unc.pitch_deviation,
            &unc.face_deviation,
            &unc.encoder_error,
        ] {
            for i in 0..n {
                v.push((fam.expanded_u[i], fam.k[i], fam.dof_eff[i]));
            }
        }
        v
    };
    let alone = calibration::evaluate(&set, after, &InstrumentBudget::new(Vec::new())).unwrap();
    let doubled = calibration::evaluate(
        &set,
        after,
        &InstrumentBudget::new(vec![ScopedComponent {
            evaluation: EvaluationType::A,
            ..ScopedComponent::type_b(
                "reading noise",
                Distribution::Normal { u: sigma },
                Scope::EachReading,
            )
            .with_dof(Some(dof))
        }]),
    )
    .unwrap();
    for (j, ((big_u, k, nu), (big_u2, k2, nu2))) in families(&alone)
        .into_iter()
        .zip(families(&doubled))
        .enumerate()
    {
        if j == 2 * n - 1 {
            assert_eq!((big_u, k, big_u2, k2), (0.0, None, 0.0, None), "φ[N]");
            continue;
        }
        let (k, k2) = (k.unwrap(), k2.unwrap());
        assert!(
            close(big_u / k, fit_u[j], 1e-9),
            "{j}: {} vs {}",
            big_u / k,
            fit_u[j]
        );
        assert!(close(nu.unwrap(), dof, 1e-9));
        assert!(close(k, t_quantile(0.95, Some(dof)), 1e-12));
        assert!(
            close(big_u2 / k2, 2f64.sqrt() * fit_u[j], 1e-9),
            "{j}: {} vs √2·{}",
            big_u2 / k2,
            fit_u[j]
        );
        assert!(close(nu2.unwrap(), 2.0 * dof, 1e-9), "{j}: ν_eff {nu2:?}");
        assert!(close(k2, t_quantile(0.95, Some(2.0 * dof)), 1e-12));
    }
}

/// Monte Carlo through a model with effect terms: each trial is solved by the
/// least-squares operator with the effect columns (the closed form has none), and its
/// means are the final model's estimates and its u the propagated u_c, within the Monte
/// Carlo noise.
#[test]
fn monte_carlo_through_a_model_with_effects() {
    let (set, diagnosis) = diagnosed_run();
    let budget = InstrumentBudget::new(vec![
        ScopedComponent::type_b(
            "angle",
            Distribution::Normal { u: 0.04 },
            Scope::EachReading,
        ),
        ScopedComponent::type_b(
            "encoder",
            Distribution::Normal { u: 0.02 },
            Scope::EachPosition,
        ),
    ]);
    let (unc, result) = mc(&set, &diagnosis.after, &budget, 40_000, 7, McSolver::Auto);
    assert_eq!(result.solver, "lsq");
    for (family_index, mc_family, estimates) in [
        (0, &result.pitch_deviation, &diagnosis.after.pitch_deviation),
        (2, &result.encoder_error, &diagnosis.after.encoder_error),
    ] {
        for (j, estimate) in estimates.iter().enumerate() {
            let u = propagated_u(&unc, family_index, j);
            assert!(
                (mc_family.mean[j] - estimate).abs() < 5.0 * u / (40_000f64).sqrt(),
                "family {family_index}, {j}: mean {} vs {estimate}",
                mc_family.mean[j]
            );
            assert!(
                close(mc_family.u[j], u, 0.03),
                "family {family_index}, {j}: u {} vs {u}",
                mc_family.u[j]
            );
        }
    }
}

// ---------------------------------------------------------------------------------------
// The binary
// ---------------------------------------------------------------------------------------

fn polycal(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_polycal"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the binary runs")
}

/// `polycal args` is refused: status 2 and one `error:` line that contains `wanted`.
fn refused(args: &[&str], wanted: &str) {
    let out = polycal(args);
    assert_eq!(out.status.code(), Some(2), "{args:?}");
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(
        stderr.starts_with("error: ") && stderr.contains(wanted),
        "{stderr:?} lacks {wanted:?}"
    );
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("polycal-unc-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

const INSTRUMENT: &str = "examples/budgets/instrument.toml";

/// `solve --budget --format csv` fills U and k on every row (U = k·u), leaves out the
/// reference face φ[N], carries the JSON's numbers, and goes straight into `compare`
/// against the simulation's truth (which it covers: |En| ≤ 1 throughout).
#[test]
fn cli_budget_csv_goes_into_compare() {
    let dir = temp_dir("compare");
    let data = dir.join("run.csv");
    let truth = dir.join("truth.json");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "3",
        "--closing",
        "--seed",
        "5",
        "--out",
        data.to_str().unwrap(),
        "--truth-out",
        truth.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let out = polycal(&[
        "solve",
        data.to_str().unwrap(),
        "--budget",
        INSTRUMENT,
        "--format",
        "csv",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv_text = String::from_utf8(out.stdout).unwrap();
    let result = dir.join("result.csv");
    std::fs::write(&result, &csv_text).unwrap();
    let rows = polycal::results::read_results_path(&result).unwrap();
    assert_eq!(rows.len(), 24 * 3 - 1 + 2);
    assert!(
        !rows
            .iter()
            .any(|r| r.quantity == "face_deviation" && r.index == 24)
    );
    for r in &rows {
        let (u, big_u, k) = (r.u.unwrap(), r.expanded_u.unwrap(), r.k.unwrap());
        assert!(close(big_u, k * u, 1e-12), "{} {}", r.quantity, r.index);
        assert!(k > 1.9 && k < 2.1);
    }
    let json: Value = serde_json::from_slice(
        &polycal(&[
            "solve",
            data.to_str().unwrap(),
            "--budget",
            INSTRUMENT,
            "--format",
            "json",
        ])
        .stdout,
    )
    .unwrap();
    assert_eq!(json["p"], 0.95);
    let big_u = json["pitch_deviation_U"].as_array().unwrap();
    let k = json["pitch_deviation_k"].as_array().unwrap();
    assert_eq!((big_u.len(), k.len()), (24, 24));
    for r in rows.iter().filter(|r| r.quantity == "pitch_deviation") {
        let i = r.index as usize - 1;
        assert_eq!(r.expanded_u.unwrap(), big_u[i].as_f64().unwrap());
        assert_eq!(r.k.unwrap(), k[i].as_f64().unwrap());
    }
    assert!(json["face_deviation_k"][23].is_null());
    assert_eq!(
        json["uncertainty"]["components"].as_array().unwrap().len(),
        5
    );
    assert!(json["setup_error"][0]["U"].as_f64().unwrap() > 0.9); // the zero offset

    // the truth as a reference result with U = u = 0 (exact)
    let t: Value = serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let mut reference = String::from("quantity,index,value,U,u\n");
    let pitch: Vec<f64> = t["pitch_deviation"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let mut phi = 0.0;
    for (k, b) in pitch.iter().enumerate() {
        reference += &format!("pitch_deviation,{},{b},0,0\n", k + 1);
        phi += b;
        if k < 23 {
            reference += &format!("face_deviation,{},{phi},0,0\n", k + 1);
        }
    }
    for (p, a) in t["encoder_error"].as_array().unwrap().iter().enumerate() {
        reference += &format!("encoder_error,{p},{},0,0\n", a.as_f64().unwrap());
    }
    let reference_path = dir.join("truth.csv");
    std::fs::write(&reference_path, reference).unwrap();
    let out = polycal(&[
        "compare",
        result.to_str().unwrap(),
        reference_path.to_str().unwrap(),
        "--format",
        "json",
    ]);
    let comparison: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(comparison["rows"].as_array().unwrap().len(), 24 * 3 - 1);
    let max_en = comparison["max_abs_en"].as_f64().unwrap();
    assert!(
        max_en <= 1.0,
        "the budget's U covers the truth: max |En| = {max_en}"
    );
    assert_eq!(comparison["vector"]["consistent"], true);
    assert_eq!(out.status.code(), Some(0));
    std::fs::remove_dir_all(&dir).ok();
}

/// `--monte-carlo` adds the monte_carlo object (and a table section), with status 0 when
/// validated and 1 when not; it needs --budget; bad budgets and an exactly determined fit
/// without --sigma are refused with status 2 and the place.
#[test]
fn cli_monte_carlo_and_refusals() {
    let dir = temp_dir("mc");
    let data = dir.join("bare.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "12",
        "--cycles",
        "1",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let d = data.to_str().unwrap();
    let out = polycal(&[
        "solve",
        d,
        "--sigma",
        "0.05",
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "1e5",
        "--mc-digits",
        "1",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    assert_eq!(mc["trials"], 100_000);
    assert_eq!(mc["solver"], "closed-form");
    for family in ["pitch_deviation", "face_deviation", "encoder_error"] {
        for key in [
            "mean", "u", "low", "high", "d_low", "d_high", "delta", "passed",
        ] {
            assert_eq!(
                mc[family][key].as_array().unwrap().len(),
                12,
                "{family} {key}"
            );
        }
    }
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    let u_mc = mc["pitch_deviation"]["u"][0].as_f64().unwrap();
    let u_gum = json["uncertainty"]["pitch_deviation"]["u"][0]
        .as_f64()
        .unwrap();
    assert!(close(u_mc, u_gum, 0.02), "{u_mc} vs {u_gum}");

    let table = polycal(&[
        "solve",
        d,
        "--sigma",
        "0.05",
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "20000",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 20000 trials"),
        "{text}"
    );
    assert!(text.contains("U(β)") && text.contains("each-autocollimator"));

    refused(
        &["solve", d, "--sigma", "0.05", "--monte-carlo", "1e5"],
        "--budget",
    );
    refused(&["solve", d, "--budget", INSTRUMENT], "--sigma");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[[component]]\nname = \"a\"\nu = 0.1\nacts_on = \"everywhere\"\n",
    )
    .unwrap();
    refused(
        &[
            "solve",
            d,
            "--sigma",
            "0.05",
            "--budget",
            bad.to_str().unwrap(),
        ],
        "bad.toml:4:11: unknown acts_on",
    );
    refused(
        &[
            "solve",
            d,
            "--sigma",
            "0.05",
            "--budget",
            INSTRUMENT,
            "--monte-carlo",
            "lots",
        ],
        "adaptive",
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// `diagnose --budget --monte-carlo` adds the final model's monte_carlo object (its JSON
/// `after`, and a table section after the final model's results) with the effect columns
/// in the trials: its u follows the final model's GUM u_c, not the base model's; status 1
/// when an effect makes the model inadequate or the GUM is not validated, 0 otherwise; it
/// needs --budget; a self-calibration file's diagnosis gets its final model's too.
#[test]
fn cli_diagnose_monte_carlo_on_the_final_model() {
    let dir = temp_dir("diagnose-mc");
    let data = dir.join("drift.csv");
    let out = polycal(&[
        "simulate",
        "--faces",
        "24",
        "--cycles",
        "3",
        "--closing",
        "--drift",
        "2:3",
        "--offset-step",
        "1:2:10:0.6",
        "--seed",
        "3",
        "--out",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let d = data.to_str().unwrap();
    let out = polycal(&[
        "diagnose",
        d,
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "2e4",
        "--mc-digits",
        "1",
        "--seed",
        "7",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(json["effects"].as_array().unwrap().len() >= 2, "{json}");
    let after = &json["after"];
    let mc = &after["monte_carlo"];
    assert_eq!(mc["trials"], 20_000);
    assert_eq!(mc["seed"], 7);
    assert_eq!(mc["solver"], "lsq");
    for family in ["pitch_deviation", "face_deviation", "encoder_error"] {
        let u_mc = mc[family]["u"].as_array().unwrap();
        let u_gum = after["uncertainty"][family]["u"].as_array().unwrap();
        assert_eq!(u_mc.len(), 24);
        for (a, b) in u_mc.iter().zip(u_gum) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            // the t-scaled noise (JCGM 101 §6.4.9) makes the Monte Carlo u slightly larger
            if b > 0.0 {
                assert!(close(a, b, 0.05), "{family}: {a} vs {b}");
            }
        }
    }
    let verdict = !json["adequate"].as_bool().unwrap() || !mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if verdict { 1 } else { 0 }));
    assert!(json["before"].get("monte_carlo").is_none());

    let table = polycal(&[
        "diagnose",
        d,
        "--budget",
        INSTRUMENT,
        "--monte-carlo",
        "20000",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    let final_model = text.find("Calibration of the final model").unwrap();
    let monte_carlo = text.find("Monte Carlo (JCGM 101): 20000 trials").unwrap();
    assert!(final_model < monte_carlo, "{text}");

    refused(&["diagnose", d, "--monte-carlo", "1e4"], "--budget");
    // a self-calibration file: the final model's Monte Carlo in its `after`, its u the
    // budget's on the final model
    let out = polycal(&[
        "diagnose",
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--monte-carlo",
        "1e4",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["after"]["monte_carlo"];
    selfcal_mc_follows_the_budget(mc, &json["after"]["uncertainty"], (168, 11), 0.05);
    let verdict = !json["adequate"].as_bool().unwrap() || !mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if verdict { 1 } else { 0 }));
    let table = polycal(&[
        "diagnose",
        "examples/data/selfa-168.csv",
        "--budget",
        "examples/budgets/selfcal.toml",
        "--monte-carlo",
        "1e4",
    ]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 10000 trials"),
        "{text}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// A self-calibration's `monte_carlo` JSON object against the budget's `uncertainty`
/// object: (P, M − 1) values of u for e and the heads' errors, each within `tolerance`
/// (relative) of u_c.
fn selfcal_mc_follows_the_budget(
    mc: &Value,
    uncertainty: &Value,
    (positions, heads): (usize, usize),
    tolerance: f64,
) {
    for (family, len) in [("encoder_error", positions), ("head_error", heads)] {
        let u_mc = mc[family]["u"].as_array().unwrap();
        let u_gum = uncertainty[family]["u"].as_array().unwrap();
        assert_eq!((u_mc.len(), u_gum.len()), (len, len));
        for (a, b) in u_mc.iter().zip(u_gum) {
            let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
            assert!(close(a, b, tolerance), "{family}: {a} vs {b}");
        }
    }
}

/// `selfcal --budget --monte-carlo` adds the budget's monte_carlo object (e and the heads'
/// errors; its u that of the budget), a table section, status 1 when some GUM interval is
/// not validated; it needs --budget; heads between the positions are evaluated alike.
#[test]
fn cli_selfcal_monte_carlo() {
    let dir = temp_dir("selfcal-mc");
    let budget = "examples/budgets/selfcal.toml";
    let data = "examples/data/selfa-168.csv";
    let out = polycal(&[
        "selfcal",
        data,
        "--budget",
        budget,
        "--monte-carlo",
        "2e4",
        "--seed",
        "5",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    assert_eq!(
        (mc["trials"].as_u64(), mc["seed"].as_u64()),
        (Some(20_000), Some(5))
    );
    selfcal_mc_follows_the_budget(mc, &json["uncertainty"], (168, 11), 0.03);
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    let table = polycal(&["selfcal", data, "--budget", budget, "--monte-carlo", "2e4"]);
    let text = String::from_utf8(table.stdout).unwrap();
    assert!(
        text.contains("Monte Carlo (JCGM 101): 20000 trials"),
        "{text}"
    );

    refused(&["selfcal", data, "--monte-carlo", "1e4"], "--budget");
    let off_grid = dir.join("off-grid.csv");
    let out = polycal(&[
        "simulate",
        "--selfcal",
        "--positions",
        "24",
        "--heads",
        "0,97,180",
        "--cycles",
        "2",
        "--out",
        off_grid.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // heads between the positions: the same evaluation, through the band-limited fit
    let out = polycal(&[
        "selfcal",
        off_grid.to_str().unwrap(),
        "--budget",
        budget,
        "--monte-carlo",
        "1e4",
        "--format",
        "json",
    ]);
    let json: Value = serde_json::from_slice(&out.stdout).unwrap();
    let mc = &json["monte_carlo"];
    selfcal_mc_follows_the_budget(mc, &json["uncertainty"], (24, 2), 0.05);
    let validated = mc["validated"].as_bool().unwrap();
    assert_eq!(out.status.code(), Some(if validated { 0 } else { 1 }));
    std::fs::remove_dir_all(&dir).ok();
}
