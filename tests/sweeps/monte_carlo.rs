//! Monte Carlo propagation (JCGM 101:2008) against its published examples and analytic
//! results.

use polycal::uncertainty::BudgetFile;
use polycal::uncertainty::budget::DofPolicy;
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::{
    self, BLOCK_SIZE, EngineOptions, McError, McInput, MonteCarlo, Trial, TrialFailure, Trials,
    linear_budget_inputs, numerical_tolerance, validate_gum,
};
use polycal::uncertainty::student::normal_quantile;
use proptest::prelude::*;
use rand::Rng;
use rand_distr::{Distribution as _, StandardNormal};

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
    // Standard errors with M = 2e6: mean 0.0014, u 0.001, half-width ≈ 0.003 (0.0081 the
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
    let (shortest_low, shortest_high) = y.shortest.unwrap();
    assert!((shortest_high - shortest_low - (y.high - y.low)).abs() < 0.02);
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
    // Standard error of the half-width ≈ 0.0025 (0.0040 the worst of 25 seeds): 0.013
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

/// y₀ = z, y₁ = z² + u with z normal and u uniform: skewed and symmetric outputs.
struct Toy;

impl Trial for Toy {
    type Scratch = [f64; 2];
    fn outputs(&self) -> usize {
        2
    }
    fn centre(&self) -> &[f64] {
        &[0.0, 1.0]
    }
    fn scratch(&self) -> [f64; 2] {
        [0.0; 2]
    }
    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        scratch: &mut [f64; 2],
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        let z: f64 = StandardNormal.sample(rng);
        let u: f64 = rng.random();
        *scratch = [z, u];
        out[0] = z;
        out[1] = z * z + u;
        Ok(())
    }
    fn inputs(&self, scratch: &[f64; 2]) -> Vec<f64> {
        scratch.to_vec()
    }
}

/// Mean, u and the interval are those of a full sort of every trial, fixed (within the
/// pilot's brackets, and beyond ten and fifty pilots, where the brackets are refined)
/// and adaptive; keeping the samples changes no number.
#[test]
fn statistics_are_those_of_every_trial() {
    let adaptive = Trials::Adaptive {
        significant_digits: 2,
        max_trials: 1_000_000,
    };
    for trials in [
        Trials::Fixed(34_500),
        Trials::Fixed(7_000),
        Trials::Fixed(234_567),
        Trials::Fixed(543_210),
        adaptive,
    ] {
        let options = EngineOptions::new(trials).with_seed(11);
        let plain = monte_carlo::run(&Toy, &options).unwrap();
        let kept = monte_carlo::run(&Toy, &options.with_samples(true)).unwrap();
        let samples = kept.samples.as_ref().unwrap();
        let m = kept.trials;
        assert_eq!(plain.trials, m);
        assert_eq!(samples[0].len(), m);
        let (r_low, r_high) = monte_carlo::symmetric_interval_positions(m, 0.95);
        for (j, column) in samples.iter().enumerate() {
            let (a, b) = (plain.outputs[j], kept.outputs[j]);
            assert_eq!((a.mean, a.u, a.low, a.high), (b.mean, b.u, b.low, b.high));
            assert_eq!(a.shortest, None);
            let mut sorted = column.clone();
            sorted.sort_unstable_by(f64::total_cmp);
            assert_eq!((a.low, a.high), (sorted[r_low], sorted[r_high]));
            let mean = column.iter().sum::<f64>() / m as f64;
            let ss = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
            assert!((a.mean - mean).abs() < 1e-12);
            assert!((a.u - (ss / (m - 1) as f64).sqrt()).abs() < 1e-12);
            let (lo, hi) = b.shortest.unwrap();
            assert!(hi - lo <= a.high - a.low);
        }
    }
}

/// Many outputs: normal and uniform draws with drifting centres (3 000 outputs, so that
/// the engine brackets the interval ends from a pilot shorter than `J`).
struct Many {
    centre: Vec<f64>,
}

impl Many {
    fn new(outputs: usize) -> Self {
        Many {
            centre: (0..outputs).map(|j| j as f64 / outputs as f64).collect(),
        }
    }
}

impl Trial for Many {
    type Scratch = ();
    fn outputs(&self) -> usize {
        self.centre.len()
    }
    fn centre(&self) -> &[f64] {
        &self.centre
    }
    fn scratch(&self) {}
    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        _: &mut (),
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        for (j, (o, c)) in out.iter_mut().zip(&self.centre).enumerate() {
            let x: f64 = if j % 2 == 0 {
                StandardNormal.sample(rng)
            } else {
                rng.random::<f64>() - 0.5
            };
            *o = c + x;
        }
        Ok(())
    }
    fn inputs(&self, _: &()) -> Vec<f64> {
        Vec::new()
    }
}

/// With many outputs the pilot is shorter than `J` (its length depends on the number of
/// threads, and so do the stages of the refinements): the numbers are still those of a
/// full sort of every trial, and the same to the last bit with one thread or four.
#[test]
fn many_outputs_in_bounded_memory_are_exact_and_thread_independent() {
    let many = Many::new(3_000);
    let options = EngineOptions::new(Trials::Fixed(16_500)).with_seed(3);
    let in_pool = |threads: usize, options: EngineOptions<'_>| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| monte_carlo::run(&many, &options).unwrap())
    };
    let one = in_pool(1, options);
    let four = in_pool(4, options);
    assert_eq!(one, four);
    let kept = in_pool(2, options.with_samples(true));
    let samples = kept.samples.as_ref().unwrap();
    let m = kept.trials;
    let (r_low, r_high) = monte_carlo::symmetric_interval_positions(m, 0.95);
    for (j, column) in samples.iter().enumerate() {
        let a = one.outputs[j];
        let mut sorted = column.clone();
        sorted.sort_unstable_by(f64::total_cmp);
        assert_eq!(
            (a.low, a.high),
            (sorted[r_low], sorted[r_high]),
            "output {j}"
        );
        let mean = column.iter().sum::<f64>() / m as f64;
        let ss = column.iter().map(|x| (x - mean).powi(2)).sum::<f64>();
        assert!((a.mean - mean).abs() < 1e-12);
        assert!((a.u - (ss / (m - 1) as f64).sqrt()).abs() < 1e-12);
        // The sums are added in the same order with or without the samples.
        assert_eq!(
            (a.mean, a.u),
            (kept.outputs[j].mean, kept.outputs[j].u),
            "output {j}"
        );
    }
}

/// The observer sees every trial run, in increasing counts, with the total of a fixed
/// run and none for the adaptive procedure (which runs its trials twice).
#[test]
fn progress_is_reported_per_block() {
    let calls = std::sync::Mutex::new(Vec::new());
    let observe = |done: u64, total: Option<u64>| {
        calls.lock().unwrap().push((done, total));
    };
    let options = EngineOptions::new(Trials::Fixed(25_500)).with_progress(&observe);
    monte_carlo::run(&Toy, &options).unwrap();
    let seen = std::mem::take(&mut *calls.lock().unwrap());
    assert_eq!(seen.len(), 26);
    assert!(seen.windows(2).all(|w| w[0].0 < w[1].0));
    assert_eq!(seen.last(), Some(&(25_500, Some(25_500))));
    let adaptive = Trials::Adaptive {
        significant_digits: 1,
        max_trials: 1_000_000,
    };
    let r = monte_carlo::run(&Toy, &EngineOptions::new(adaptive).with_progress(&observe)).unwrap();
    let seen = std::mem::take(&mut *calls.lock().unwrap());
    assert!(seen.iter().all(|c| c.1.is_none()));
    assert!(seen.windows(2).all(|w| w[0].0 < w[1].0));
    // The sequences, then all their trials again for the exact intervals.
    assert_eq!(seen.last().map(|c| c.0), Some(2 * r.trials as u64));
}

/// A trial whose input is one uniform draw; it fails (or gives two outputs) for inputs
/// above `fail` (`count`).
struct Failing {
    fail: f64,
    count: f64,
}

impl Trial for Failing {
    type Scratch = f64;
    fn outputs(&self) -> usize {
        1
    }
    fn centre(&self) -> &[f64] {
        &[0.0]
    }
    fn scratch(&self) -> f64 {
        0.0
    }
    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        x: &mut f64,
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        *x = rng.random();
        out[0] = *x;
        if *x > self.count {
            Err(TrialFailure::OutputCount(2))
        } else if *x > self.fail {
            Err(TrialFailure::Failed)
        } else {
            Ok(())
        }
    }
    fn inputs(&self, x: &f64) -> Vec<f64> {
        vec![*x]
    }
}

/// The inputs of `Failing` replayed from the documented streams: trial t draws from the
/// stream of block t / BLOCK_SIZE, in order within its block — eight xoshiro256++
/// generators (`rand_xoshiro`), seeded with consecutive 32-byte pieces of ChaCha8
/// (`seed`, stream b), their outputs in turn.
fn replayed(seed: u64, trials: usize) -> Vec<f64> {
    use rand::{RngCore, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use rand_xoshiro::Xoshiro256PlusPlus;
    (0..trials.div_ceil(BLOCK_SIZE))
        .flat_map(|b| {
            let mut chacha = ChaCha8Rng::seed_from_u64(seed);
            chacha.set_stream(b as u64);
            let mut lanes: Vec<Xoshiro256PlusPlus> = (0..8)
                .map(|_| {
                    let mut state = [0u8; 32];
                    chacha.fill_bytes(&mut state);
                    Xoshiro256PlusPlus::from_seed(state)
                })
                .collect();
            // `random::<f64>()`: the high 53 bits of one draw, times 2⁻⁵³.
            (0..BLOCK_SIZE)
                .map(move |i| (lanes[i % 8].next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
        })
        .take(trials)
        .collect()
}

/// A failing trial stops the run with the first failing trial's index, output and
/// inputs, the same whatever the number of threads.
#[test]
fn failures_name_the_first_failing_trial() {
    let x = replayed(1, 100_000);
    let trial = Failing {
        fail: 0.999,
        count: 0.9999,
    };
    let first = x.iter().position(|&x| x > 0.999).unwrap();
    let wanted = if x[first] > 0.9999 {
        McError::OutputCount {
            trial: first,
            expected: 1,
            got: 2,
        }
    } else {
        McError::NonFinite {
            trial: first,
            output: 0,
            value: x[first],
            inputs: vec![x[first]],
        }
    };
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let options = EngineOptions::new(Trials::Fixed(100_000));
        let e = pool.install(|| monte_carlo::run(&trial, &options).unwrap_err());
        assert_eq!(e, wanted);
    }
    // The first failure after five good blocks, other blocks failing later: the first
    // in trial order is the one reported, whatever finishes first.
    let fail = x[..5 * BLOCK_SIZE].iter().copied().fold(0.0, f64::max);
    let late = Failing { fail, count: 2.0 };
    let first = x.iter().position(|&v| v > fail).unwrap();
    assert!(first >= 5 * BLOCK_SIZE);
    assert!(x[first + BLOCK_SIZE..].iter().any(|&v| v > fail));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let options = EngineOptions::new(Trials::Fixed(100_000));
    let e = pool.install(|| monte_carlo::run(&late, &options).unwrap_err());
    assert_eq!(
        e,
        McError::NonFinite {
            trial: first,
            output: 0,
            value: x[first],
            inputs: vec![x[first]],
        }
    );
    assert_eq!(
        monte_carlo::run(&trial, &EngineOptions::new(Trials::Fixed(10))).unwrap_err(),
        McError::TooFewTrials {
            trials: 10,
            p: 0.95,
            needed: 20
        }
    );
}

/// The additive model of JCGM 101 §9.2.2 written as a `Trial` of the engine: four
/// standard normal draws, their sum.
struct FourNormals;

impl Trial for FourNormals {
    type Scratch = [f64; 4];

    fn outputs(&self) -> usize {
        1
    }

    fn centre(&self) -> &[f64] {
        &[0.0]
    }

    fn scratch(&self) -> [f64; 4] {
        [0.0; 4]
    }

    fn draw<R: Rng + ?Sized>(
        &self,
        rng: &mut R,
        x: &mut [f64; 4],
        out: &mut [f64],
    ) -> Result<(), TrialFailure> {
        for xi in x.iter_mut() {
            let z: f64 = StandardNormal.sample(rng);
            *xi = z;
        }
        out[0] = x.iter().sum();
        Ok(())
    }

    fn inputs(&self, x: &[f64; 4]) -> Vec<f64> {
        x.to_vec()
    }
}

/// `MonteCarlo::run` is the engine running the model of its inputs: the same model
/// written as a `Trial` gives the same numbers, to the last bit, fixed and adaptive.
#[test]
fn monte_carlo_runs_on_the_engine() {
    let adaptive = Trials::Adaptive {
        significant_digits: 2,
        max_trials: 1_000_000,
    };
    for trials in [Trials::Fixed(45_678), adaptive] {
        let by_inputs = MonteCarlo::new(four(Distribution::Normal { u: 1.0 }))
            .with_trials(trials)
            .with_seed(21)
            .with_samples(true)
            .run(sum_model)
            .unwrap();
        let options = EngineOptions::new(trials).with_seed(21).with_samples(true);
        let by_trial = monte_carlo::run(&FourNormals, &options).unwrap();
        assert_eq!(by_inputs, by_trial);
        // JCGM 101 §9.2.2: ±3.92 (to the accuracy of these few trials).
        let y = by_trial.outputs[0];
        assert!((y.half_width() - 3.92).abs() < 0.1, "{y:?}");
    }
}

/// The progress observer sees the trials block by block, up to the total of a fixed run,
/// and does not change the numbers.
#[test]
fn progress_is_reported_without_changing_the_numbers() {
    let seen = std::sync::Mutex::new(Vec::new());
    let observer = |done: u64, total: Option<u64>| seen.lock().unwrap().push((done, total));
    let mc = MonteCarlo::new(four(Distribution::Normal { u: 1.0 }))
        .with_trials(Trials::Fixed(25_500))
        .with_seed(5);
    let quiet = mc.run(sum_model).unwrap();
    let observed = mc.clone().with_progress(&observer).run(sum_model).unwrap();
    assert_eq!(quiet, observed);
    let seen = seen.into_inner().unwrap();
    assert_eq!(seen.len(), 25_500usize.div_ceil(BLOCK_SIZE));
    assert!(seen.windows(2).all(|w| w[0].0 < w[1].0), "{seen:?}");
    assert_eq!(seen.last(), Some(&(25_500, Some(25_500))));
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
