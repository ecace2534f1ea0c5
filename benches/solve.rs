//! Speed of the closure solvers (criterion). Figures go in the closing notes as ratios
//! between variants measured in one run; nothing here is asserted.
//!
//! - `closed_form/24`: the paper's closed form for N = 24 on per-step means, with a
//!   compile-time (`Const`) and a run-time (`Dyn`) dimension;
//! - `lsq_all_u/24x6_closing_300`: least squares with every standard uncertainty, N = 24,
//!   6 cycles with closing readings (300 readings), on the circulant engine and on the
//!   dense reference;
//! - `lsq_growth/{circulant,dense}/N`: the same for N = 24 … 5760 × 6 cycles (dense up to
//!   1440), to show how the cost grows with N;
//! - `bare_cycle/65536`: the bare two-autocollimator cycle at 65 536 positions, σ stated,
//!   every u (the closed form and its covariance in closed form);
//! - `sub_pitch_all_u/{coset,dense}/N`: sub-pitch mountings through `solve_shifted` with
//!   every u (α at every table angle of every coset): N × 2 cycles with closing readings,
//!   two mountings at 0° and 0.1° for N = 360 and 1440 (the design), four at 0°,
//!   0.0125°, 0.03° and 0.05° for N = 5760; on the coset engine, and with the differences
//!   as effect columns of the dense reference at N = 360.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::{DVector, SVector};
use polycal::measurement::Sigma;
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::sub_pitch::{SubPitchSolution, solve_shifted};
use polycal::solve::{Method, Solution, SolveOptions, closed_form, dense_least_squares, solve};
use std::hint::black_box;
use std::time::Duration;

fn config(faces: usize, closing: bool) -> SimulationConfig {
    SimulationConfig {
        faces,
        cycles: 6,
        closing,
        ..SimulationConfig::default()
    }
}

fn bench_closed_form(c: &mut Criterion) {
    let m1: [f64; 24] = std::array::from_fn(|p| (p as f64 * 0.7).sin());
    let m2: [f64; 24] = std::array::from_fn(|p| (p as f64 * 1.3).cos());
    let s1 = SVector::<f64, 24>::from(m1);
    let s2 = SVector::<f64, 24>::from(m2);
    let d1 = DVector::from_column_slice(&m1);
    let d2 = DVector::from_column_slice(&m2);
    let mut group = c.benchmark_group("closed_form/24");
    group.bench_function("const", |b| {
        b.iter(|| closed_form(black_box(&s1), black_box(&s2)))
    });
    group.bench_function("dyn", |b| {
        b.iter(|| closed_form(black_box(&d1), black_box(&d2)))
    });
    group.finish();
}

/// Every standard uncertainty a report prints: β, φ, α, U and the effect terms.
fn all_u(solution: &Solution) -> f64 {
    [
        solution.pitch_deviation_u(),
        solution.face_deviation_u(),
        solution.encoder_error_u(),
        solution.setup_error_u(),
        solution.effect_u(),
    ]
    .into_iter()
    .flatten()
    .flatten()
    .sum()
}

fn bench_lsq(c: &mut Criterion) {
    let (set, _) = simulate(&config(24, true)).expect("valid configuration");
    assert_eq!(set.readings.len(), 300);
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    let mut group = c.benchmark_group("lsq_all_u/24x6_closing_300");
    group.bench_function("circulant", |b| {
        b.iter(|| all_u(&solve(black_box(&set), &options).expect("solvable")))
    });
    group.bench_function("dense", |b| {
        b.iter(|| all_u(&dense_least_squares(black_box(&set), &[], None).expect("solvable")))
    });
    group.finish();
}

/// Growth with N: least squares with every u, N × 6 cycles with closing readings (the
/// circulant engine), and the dense reference up to 1440.
fn bench_growth(c: &mut Criterion) {
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    let mut group = c.benchmark_group("lsq_growth");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    for faces in [24usize, 90, 360, 1440, 5760] {
        let (set, _) = simulate(&config(faces, true)).expect("valid configuration");
        group.bench_with_input(BenchmarkId::new("circulant", faces), &set, |b, set| {
            b.iter(|| all_u(&solve(black_box(set), &options).expect("solvable")))
        });
        if faces <= 1440 {
            group.bench_with_input(BenchmarkId::new("dense", faces), &set, |b, set| {
                b.iter(|| all_u(&dense_least_squares(black_box(set), &[], None).expect("solvable")))
            });
        }
    }
    group.finish();
}

/// The bare two-autocollimator cycle at 65 536 positions (one cycle, σ stated): the closed
/// form with its covariance in closed form, every u.
fn bench_bare_cycle(c: &mut Criterion) {
    let config = SimulationConfig {
        faces: 65_536,
        cycles: 1,
        closing: false,
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&config).expect("valid configuration");
    let options = SolveOptions::new().with_sigma(Sigma::new(0.05).expect("positive"));
    let mut group = c.benchmark_group("bare_cycle");
    group.sample_size(10);
    group.bench_function("65536", |b| {
        b.iter(|| all_u(&solve(black_box(&set), &options).expect("solvable")))
    });
    group.finish();
}

/// Every u of a sub-pitch result: α at every table angle of every coset, β, φ and U.
fn all_sub_pitch_u(solved: &SubPitchSolution) -> f64 {
    solved.encoder_error_u.iter().flatten().sum::<f64>() + all_u(&solved.solution)
}

/// Sub-pitch mountings on the coset engine and, at N = 360, with the cosets' differences
/// as effect columns of the dense reference.
fn bench_sub_pitch(c: &mut Criterion) {
    let mut group = c.benchmark_group("sub_pitch_all_u");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    let designs: [(usize, Vec<f64>); 3] = [
        (360, vec![0.0, 0.1]),
        (1440, vec![0.0, 0.1]),
        (5760, vec![0.0, 0.0125, 0.03, 0.05]),
    ];
    for (faces, shifts) in designs {
        let config = SimulationConfig {
            faces,
            cycles: 2,
            closing: true,
            setups: shifts.len() as u32,
            table_shift_deg: shifts,
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).expect("valid configuration");
        let options = SolveOptions::new();
        group.bench_with_input(BenchmarkId::new("coset", faces), &set, |b, set| {
            b.iter(|| all_sub_pitch_u(&solve_shifted(black_box(set), &options).expect("solvable")))
        });
        if faces <= 360 {
            let dense = SolveOptions::new().with_method(Method::Dense);
            group.bench_with_input(BenchmarkId::new("dense", faces), &set, |b, set| {
                b.iter(|| {
                    all_sub_pitch_u(&solve_shifted(black_box(set), &dense).expect("solvable"))
                })
            });
        }
    }
    group.finish();
}

criterion_group!(
    benches,
    bench_closed_form,
    bench_lsq,
    bench_growth,
    bench_bare_cycle,
    bench_sub_pitch
);
criterion_main!(benches);
