//! Benchmarks of the uncertainty layer: Monte Carlo throughput and Student's t.
//!
//! Run with `cargo bench --bench monte_carlo` (registered in Cargo.toml with
//! `harness = false`).
//!
//! The `calibration` group runs 10⁶ trials of the 24-face two-autocollimator calibration
//! with the instrument budget `examples/budgets/instrument.toml`, on all threads, and
//! splits the time: `sample` draws the readings and the type-B errors only; `sample_solve`
//! also solves every trial (the closed form on `Const<24>`); `monte_carlo` is the whole
//! run (draw, solve, mean, u, exact coverage interval); `monte_carlo_lsq` solves with the
//! least-squares operator instead of the closed form; `monte_carlo_6_cycles_closing` is
//! the bundled example run (6 cycles with closing readings: least squares, 300 readings
//! drawn as 48 sums per cell).

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use polycal::measurement::MeasurementSet;
use polycal::measurement::Sigma;
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{Solution, SolveOptions, solve};
use polycal::uncertainty::calibration::{self, InstrumentBudget, McModel, McOptions, McSolver};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::{BLOCK_SIZE, McInput, MonteCarlo, Trials, block_rng};
use polycal::uncertainty::student::t_quantile;
use rayon::prelude::*;

fn monte_carlo(c: &mut Criterion) {
    let mut group = c.benchmark_group("monte_carlo");
    group.sample_size(10);
    let trials = 1_000_000;
    group.throughput(Throughput::Elements(trials as u64));
    // JCGM 101 §9.2: Y = X1 + X2 + X3 + X4, one million trials, all threads.
    for (name, d) in [
        ("additive_4_normal_1e6", Distribution::Normal { u: 1.0 }),
        (
            "additive_4_rectangular_1e6",
            Distribution::Rectangular {
                half_width: 3f64.sqrt(),
            },
        ),
    ] {
        let inputs: Vec<McInput> = (0..4)
            .map(|i| McInput::new(format!("X{i}"), 0.0, d))
            .collect();
        let mc = MonteCarlo::new(inputs).with_trials(Trials::Fixed(trials));
        group.bench_function(name, |b| {
            b.iter(|| mc.run(|x, y| y.push(x.iter().sum())).unwrap())
        });
    }
    group.finish();
}

/// The bare 24-face cycle of the paper's design, σ stated (dof = 0).
fn bare_cycle() -> (MeasurementSet, Solution) {
    let config = SimulationConfig {
        faces: 24,
        cycles: 1,
        closing: false,
        noise_arcsec: 0.05,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).unwrap();
    let options = SolveOptions::new().with_sigma(Sigma::new(0.05).unwrap());
    let solution = solve(&set, &options).unwrap();
    (set, solution)
}

/// Runs `trials` trials of `model` in blocks over all threads, each block on its own
/// stream as the engine draws them (`block_rng`): with `solve`, whole trials; without,
/// the draws only.
fn blocks(model: &McModel, trials: usize, solve: bool) -> f64 {
    (0..trials.div_ceil(BLOCK_SIZE))
        .into_par_iter()
        .map(|b| {
            let mut rng = block_rng(1, b as u64);
            let mut scratch = model.scratch();
            let mut out = vec![0.0; model.outputs()];
            let mut sum = 0.0;
            for _ in 0..BLOCK_SIZE {
                if solve {
                    model.trial(&mut rng, &mut scratch, &mut out);
                    sum += out[0];
                } else {
                    model.sample(&mut rng, &mut scratch);
                    sum += scratch.targets()[0];
                }
            }
            sum
        })
        .sum()
}

fn calibration(c: &mut Criterion) {
    let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
    let (set, solution) = bare_cycle();
    let gum = calibration::evaluate(&set, &solution, &budget).unwrap();
    let model = McModel::new(&set, &solution, &budget, McSolver::Auto).unwrap();
    assert_eq!(model.solver_name(), "closed-form");
    let trials = 1_000_000;
    let mut group = c.benchmark_group("calibration");
    group.sample_size(10);
    group.throughput(Throughput::Elements(trials as u64));
    group.bench_function("sample_24_faces_1e6", |b| {
        b.iter(|| black_box(blocks(&model, trials, false)))
    });
    group.bench_function("sample_solve_24_faces_1e6", |b| {
        b.iter(|| black_box(blocks(&model, trials, true)))
    });
    let options = McOptions::new(Trials::Fixed(trials));
    group.bench_function("monte_carlo_24_faces_1e6", |b| {
        b.iter(|| calibration::monte_carlo(&set, &solution, &budget, &gum, &options).unwrap())
    });
    let lsq = options.with_solver(McSolver::LeastSquares);
    group.bench_function("monte_carlo_lsq_24_faces_1e6", |b| {
        b.iter(|| calibration::monte_carlo(&set, &solution, &budget, &gum, &lsq).unwrap())
    });
    let example =
        MeasurementSet::read_path("examples/data/polygon24-2ac-6cycles.csv".as_ref(), None)
            .unwrap();
    let example_solution = solve(&example, &SolveOptions::default()).unwrap();
    let example_gum = calibration::evaluate(&example, &example_solution, &budget).unwrap();
    group.bench_function("monte_carlo_6_cycles_closing_1e6", |b| {
        b.iter(|| {
            calibration::monte_carlo(&example, &example_solution, &budget, &example_gum, &options)
                .unwrap()
        })
    });
    group.finish();

    // Many outputs in bounded memory: 1440 positions × 2 cycles with closing readings
    // (4319 outputs, a pilot shorter than J, brackets refined at every doubling).
    let config = SimulationConfig {
        faces: 1440,
        cycles: 2,
        closing: true,
        ..SimulationConfig::default()
    };
    let (large, _) = simulate(&config).unwrap();
    let large_solution = solve(&large, &SolveOptions::default()).unwrap();
    let large_gum = calibration::evaluate(&large, &large_solution, &budget).unwrap();
    let large_trials = 20_000;
    let mut group = c.benchmark_group("calibration_many_outputs");
    group.sample_size(10);
    group.throughput(Throughput::Elements(large_trials as u64));
    let options = McOptions::new(Trials::Fixed(large_trials));
    group.bench_function("monte_carlo_1440x2_closing_2e4", |b| {
        b.iter(|| {
            calibration::monte_carlo(&large, &large_solution, &budget, &large_gum, &options)
                .unwrap()
        })
    });
    group.finish();
}

fn student(c: &mut Criterion) {
    c.bench_function("t_quantile_95_nu_72.6", |b| {
        b.iter(|| t_quantile(black_box(0.95), black_box(Some(72.6))))
    });
    c.bench_function("t_quantile_95_nu_1e6", |b| {
        b.iter(|| t_quantile(black_box(0.95), black_box(Some(1e6))))
    });
}

criterion_group!(benches, monte_carlo, calibration, student);
criterion_main!(benches);
