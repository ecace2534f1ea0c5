//! Monte Carlo propagation (JCGM 101:2008) against its published examples and analytic
//! results.

use polycal::uncertainty::BudgetFile;
use polycal::uncertainty::budget::DofPolicy;
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::{
    BLOCK_SIZE, McError, McInput, MonteCarlo, Trials, linear_budget_inputs, numerical_tolerance,
    validate_gum,
};
use polycal::uncertainty::student::normal_quantile;
use proptest::prelude::*;

fn sum_model(x: &[f64], y: &mut Vec<f64>) {
    y.push(x.iter().sum());
}

fn four(distribution: Distribution) -> Vec<McInput> {
    (1..=4)
        .map(|i| McInput::new(format!("X{i}"), 0.0, distribution))
        .collect()
}

/// The 97.5 % quantile of the sum of four independent rectangular variables of unit
/// variance (Irwin–Hall, n = 4, scaled by 2√3): the exact half-width of the 95 % interval.
const IRWIN_HALL_4_HALF_WIDTH: f64 = 3.879_406_741_347_815;

#[test]
fn jcgm101_9_2_additive_model_normal_inputs() {
    // JCGM 101 §9.2.2: Y = X1 + X2 + X3 + X4, Xi ~ N(0, 1): GUM and MC both give ±3.92.
    let m = 2_000_000;
    let r = MonteCarlo::new(four(Distribution::Normal { u: 1.0 }))
        .with_trials(Trials::Fixed(m))
        .with_seed(101)
        .run(sum_model)
        .unwrap();
    let y = r.outputs[0];
    let exact = 2.0 * -normal_quantile(0.025); // 3.9199
    // Standard errors with M = 2e6: mean 0.0014, u 0.001, half-width ≈ 0.003 (0.0075 the
    // worst of 25 seeds).
    assert!(y.mean.abs() < 0.008, "{y:?}");
    assert!((y.u - 2.0).abs() < 0.006, "{y:?}");
    assert!((y.half_width() - exact).abs() < 0.015, "{y:?}");
    // ... and a rectangular sampler (3.88) would fail.
    assert!(
        (y.half_width() - IRWIN_HALL_4_HALF_WIDTH).abs() > 0.02,
        "{y:?}"
    );
    // Symmetric distribution: shortest and symmetric intervals nearly coincide.
    assert!((y.shortest_high - y.shortest_low - (y.high - y.low)).abs() < 0.02);
}

#[test]
fn jcgm101_9_2_additive_model_rectangular_inputs() {
    // JCGM 101 §9.2.3: rectangular inputs of unit standard deviation. The GUM interval is
    // still ±3.92; Monte Carlo gives ±3.88 (exactly 3.8794, Irwin–Hall).
    let m = 4_000_000;
    let r = MonteCarlo::new(four(Distribution::Rectangular {
        half_width: 3f64.sqrt(),
    }))
    .with_trials(Trials::Fixed(m))
    .with_seed(9)
    .run(sum_model)
    .unwrap();
    let y = r.outputs[0];
    assert!((y.u - 2.0).abs() < 0.004, "{y:?}");
    // Standard error of the half-width ≈ 0.0025 (0.0063 the worst of 25 seeds): 0.013
    // is 5σ, and a normal sampler (3.92, 0.04 away = 16σ) would fail.
    assert!(
        (y.half_width() - IRWIN_HALL_4_HALF_WIDTH).abs() < 0.013,
        "{y:?}"
    );
    assert!((y.half_width() - 3.92).abs() > 0.02, "{y:?}");
    // JCGM 101 §8: the GUM interval ±3.92 against Monte Carlo, d ≈ 0.04: within
    // δ = 0.5 at one significant digit of u = 2, not within δ = 0.005 at three.
    let gum_u = 2.0;
    let gum_expanded = 2.0 * -normal_quantile(0.025);
    let one = validate_gum(0.0, gum_u, gum_expanded, &y, 1);
    assert_eq!(one.delta, 0.5);
    assert!(one.passed, "{one:?}");
    assert!(
        (one.d_low - 0.04).abs() < 0.012 && (one.d_high - 0.04).abs() < 0.012,
        "{one:?}"
    );
    let three = validate_gum(0.0, gum_u, gum_expanded, &y, 3);
    assert_eq!(three.delta, 0.005);
    assert!(!three.passed);
}

#[test]
fn numerical_tolerance_follows_jcgm101_7_9_2() {
    // u = 0.028 47, n_dig = 2: u = 28 × 10⁻³, δ = 0.5 × 10⁻³.
    assert!((numerical_tolerance(0.028_47, 2) - 0.0005).abs() < 1e-18);
    assert!((numerical_tolerance(2.0, 2) - 0.05).abs() < 1e-15);
    assert!((numerical_tolerance(2.0, 1) - 0.5).abs() < 1e-15);
    // 0.996 to two digits is 1.0 = 10 × 10⁻¹.
    assert!((numerical_tolerance(0.996, 2) - 0.05).abs() < 1e-15);
    assert!((numerical_tolerance(31.66, 2) - 0.5).abs() < 1e-15);
}

#[test]
fn results_do_not_depend_on_the_number_of_threads() {
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            MonteCarlo::new(vec![
                McInput::new("a", 1.0, Distribution::Normal { u: 0.1 }),
                McInput::new(
                    "b",
                    2.0,
                    Distribution::StudentT {
                        scale: 0.2,
                        dof: 4.0,
                    },
                ),
                McInput::new("c", 0.0, Distribution::Arcsine { half_width: 0.3 }),
                McInput::new("d", 0.0, Distribution::Triangular { half_width: 0.3 }),
            ])
            .with_trials(Trials::Fixed(54_321))
            .with_seed(7)
            .with_samples(true)
            .run(|x, y| {
                y.push(x[0] * x[1] + x[2]);
                y.push(x[3] - x[0]);
            })
            .unwrap()
        })
    };
    let one = run(1);
    let four = run(4);
    assert_eq!(one, four);
    assert_eq!(one.samples, four.samples);
    assert_eq!(one.outputs.len(), 2);
    // A different seed gives different draws.
    let other = MonteCarlo::new(vec![McInput::new(
        "a",
        0.0,
        Distribution::Normal { u: 1.0 },
    )])
    .with_trials(Trials::Fixed(10_000))
    .with_seed(8)
    .run(sum_model)
    .unwrap();
    assert_ne!(other.outputs[0].mean, 0.0);
}

#[test]
fn trial_t_draws_the_same_inputs_whatever_the_number_of_trials() {
    let run = |m: usize| {
        MonteCarlo::new(four(Distribution::Normal { u: 1.0 }))
            .with_trials(Trials::Fixed(m))
            .with_seed(3)
            .with_samples(true)
            .run(sum_model)
            .unwrap()
            .samples
            .unwrap()
            .remove(0)
    };
    let short = run(2 * BLOCK_SIZE + 17);
    let long = run(7 * BLOCK_SIZE);
    assert_eq!(short.len(), 2 * BLOCK_SIZE + 17);
    assert_eq!(short[..], long[..short.len()]);
}

#[test]
fn adaptive_procedure_stabilizes() {
    let mc = MonteCarlo::new(four(Distribution::Normal { u: 1.0 })).with_trials(Trials::Adaptive {
        significant_digits: 2,
        max_trials: 10_000_000,
    });
    assert_eq!(mc.sequence_length(), 10_000); // max(10⁴, 100/(1 − 0.95))
    let r = mc.run(sum_model).unwrap();
    let seq = r.sequences.unwrap();
    assert!(seq >= 2);
    assert_eq!(r.trials, seq * 10_000);
    // Stabilized to δ = 0.05 on u = 2: the results are within a few δ.
    let y = r.outputs[0];
    assert!((y.u - 2.0).abs() < 0.05, "{y:?}");
    assert!((y.half_width() - 3.92).abs() < 0.1, "{y:?}");
    // Three digits need far more trials than allowed here.
    let e = MonteCarlo::new(four(Distribution::Normal { u: 1.0 }))
        .with_trials(Trials::Adaptive {
            significant_digits: 3,
            max_trials: 50_000,
        })
        .run(sum_model)
        .unwrap_err();
    assert!(matches!(e, McError::NotStabilized { digits: 3, .. }), "{e}");
    // p = 0.99: sequences of max(10⁴, 100/0.01) = 10⁴; p = 0.999: 10⁵.
    assert_eq!(
        MonteCarlo::new(vec![])
            .with_coverage(0.999)
            .sequence_length(),
        100_000
    );
}

#[test]
fn samplers_have_the_stated_standard_deviations() {
    let a = 0.6;
    for (d, sd) in [
        (Distribution::Rectangular { half_width: a }, a / 3f64.sqrt()),
        (Distribution::Triangular { half_width: a }, a / 6f64.sqrt()),
        (Distribution::Arcsine { half_width: a }, a / 2f64.sqrt()),
        (Distribution::Normal { u: a }, a),
        (
            Distribution::StudentT {
                scale: a,
                dof: 10.0,
            },
            a * (10.0f64 / 8.0).sqrt(),
        ),
    ] {
        let r = MonteCarlo::new(vec![McInput::new("x", 5.0, d)])
            .with_trials(Trials::Fixed(1_000_000))
            .with_samples(true)
            .run(sum_model)
            .unwrap();
        let y = r.outputs[0];
        assert!((y.mean - 5.0).abs() < 5.0 * sd / 1000.0, "{d:?}: {y:?}");
        assert!((y.u / sd - 1.0).abs() < 0.005, "{d:?}: {y:?} vs {sd}");
        assert_eq!(d.standard_deviation().unwrap(), sd);
        if !matches!(
            d,
            Distribution::Normal { .. } | Distribution::StudentT { .. }
        ) {
            let values = &r.samples.as_ref().unwrap()[0];
            assert!(
                values.iter().all(|v| (v - 5.0).abs() <= a),
                "{d:?} out of bounds"
            );
        }
    }
}

#[test]
fn paper_table1_by_monte_carlo() {
    // The paper's budget as the linear model ε = Σ Xᵢ, Type A inputs as t with ν = 5
    // (JCGM 101 §6.4.9). The t inputs raise u (0.234 against 0.229) while the dominant
    // rectangular setup error shortens the interval: ±0.428 against the GUM's ±0.456.
    let f = BudgetFile::read_path("examples/budgets/paper-table1.toml").unwrap();
    let gum = f.budget.evaluate(0.95, DofPolicy::Fractional).unwrap();
    let (inputs, c) = linear_budget_inputs(&f.budget).unwrap();
    assert_eq!(inputs.len(), 7);
    assert!(matches!(
        inputs[0].distribution,
        Distribution::StudentT { dof: 5.0, .. }
    ));
    let r = MonteCarlo::new(inputs)
        .with_trials(Trials::Fixed(1_000_000))
        .run(|x, y| y.push(x.iter().zip(&c).map(|(x, c)| x * c).sum()))
        .unwrap();
    let y = r.outputs[0];
    let sd_t = 0.045 * (5.0f64 / 3.0).sqrt();
    let exact_u = (gum.combined_u.powi(2) - 2.0 * 0.045f64.powi(2) + 2.0 * sd_t.powi(2)).sqrt();
    assert!((y.u / exact_u - 1.0).abs() < 0.005, "{y:?} vs {exact_u}");
    assert!((y.half_width() - 0.428).abs() < 0.003, "{y:?}");
    // JCGM 101 §8: the GUM result is validated to one significant digit of u_c
    // (δ = 0.05), not to two (δ = 0.005): d ≈ 0.028.
    let one = validate_gum(0.0, gum.combined_u, gum.expanded_u, &y, 1);
    let two = validate_gum(0.0, gum.combined_u, gum.expanded_u, &y, 2);
    assert!(one.passed && !two.passed, "{one:?} {two:?}");
    assert!((one.d_low - 0.028).abs() < 0.003, "{one:?}");
}

#[test]
fn monte_carlo_refusals() {
    let normal = || vec![McInput::new("x", 0.0, Distribution::Normal { u: 1.0 })];
    let e = MonteCarlo::new(normal())
        .with_trials(Trials::Fixed(5_000))
        .run(|x, y| y.push(if x[0] > 2.5 { f64::NAN } else { x[0] }))
        .unwrap_err();
    assert!(matches!(e, McError::NonFinite { output: 0, .. }), "{e}");
    let e = MonteCarlo::new(normal())
        .with_trials(Trials::Fixed(5_000))
        .run(|x, y| {
            y.push(x[0]);
            if x[0] > 2.0 {
                y.push(0.0);
            }
        })
        .unwrap_err();
    assert!(
        matches!(
            e,
            McError::OutputCount {
                expected: 1,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
    let e = MonteCarlo::new(normal())
        .with_trials(Trials::Fixed(5_000))
        .run(|_, _| {})
        .unwrap_err();
    assert_eq!(e, McError::NoOutputs);
    let e = MonteCarlo::new(normal())
        .with_trials(Trials::Fixed(10))
        .run(sum_model)
        .unwrap_err();
    assert!(matches!(e, McError::TooFewTrials { needed: 20, .. }), "{e}");
    let e = MonteCarlo::new(vec![McInput::new(
        "x",
        0.0,
        Distribution::Rectangular { half_width: -1.0 },
    )])
    .run(sum_model)
    .unwrap_err();
    assert!(
        e.to_string()
            .starts_with("input \"x\": half width must not be negative"),
        "{e}"
    );
    let e = MonteCarlo::new(vec![McInput::new(
        "x",
        f64::NAN,
        Distribution::Normal { u: 1.0 },
    )])
    .run(sum_model)
    .unwrap_err();
    assert_eq!(e, McError::Estimate("x".into()));
    let e = MonteCarlo::new(normal())
        .with_coverage(1.0)
        .run(sum_model)
        .unwrap_err();
    assert_eq!(e, McError::Coverage(1.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// For Y = Σ cᵢ Xᵢ with normal Xᵢ, Monte Carlo's mean and u match E[Y] = Σ cᵢ μᵢ and
    /// u(Y) = √Σ cᵢ² σᵢ² within six standard errors (σ/√M and σ/√(2(M − 1))).
    #[test]
    fn linear_model_of_normal_inputs_matches_the_analytic_values(
        params in prop::collection::vec((-10.0f64..10.0, 0.01f64..5.0, -3.0f64..3.0), 1..6),
        seed in any::<u64>(),
    ) {
        let inputs: Vec<McInput> = params
            .iter()
            .enumerate()
            .map(|(i, &(mu, sigma, _))| McInput::new(format!("X{i}"), mu, Distribution::Normal { u: sigma }))
            .collect();
        let c: Vec<f64> = params.iter().map(|p| p.2).collect();
        let mean: f64 = params.iter().map(|&(mu, _, c)| c * mu).sum();
        let sd: f64 = params.iter().map(|&(_, s, c)| (c * s).powi(2)).sum::<f64>().sqrt();
        prop_assume!(sd > 1e-6);
        let m = 20_000;
        let r = MonteCarlo::new(inputs)
            .with_trials(Trials::Fixed(m))
            .with_seed(seed)
            .run(|x, y| y.push(x.iter().zip(&c).map(|(x, c)| x * c).sum()))
            .unwrap();
        let y = r.outputs[0];
        let se_mean = sd / (m as f64).sqrt();
        let se_u = sd / (2.0 * (m as f64 - 1.0)).sqrt();
        prop_assert!((y.mean - mean).abs() < 6.0 * se_mean, "mean {} vs {} (se {})", y.mean, mean, se_mean);
        prop_assert!((y.u - sd).abs() < 6.0 * se_u, "u {} vs {} (se {})", y.u, sd, se_u);
    }
}
