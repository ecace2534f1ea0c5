//! Speed of the closure solvers (criterion). Figures go in the closing notes as ratios
//! between variants measured in one run; nothing here is asserted.
//!
//! - `closed_form/24`: the paper's closed form for N = 24 on per-step means, with a
//!   compile-time (`Const`) and a run-time (`Dyn`) dimension;
//! - `lsq_covariance/24x6_closing_300`: least squares with full covariance, N = 24, 6 cycles
//!   with closing readings (300 readings);
//! - `lsq_growth/N`: least squares with covariance for N = 24, 72, 360, 1440 × 6 cycles,
//!   to show how the cost grows with N.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use nalgebra::{DVector, SVector};
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{Method, SolveOptions, closed_form, solve};
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

fn bench_lsq(c: &mut Criterion) {
    let (set, _) = simulate(&config(24, true)).expect("valid configuration");
    assert_eq!(set.readings.len(), 300);
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    c.bench_function("lsq_covariance/24x6_closing_300", |b| {
        b.iter(|| solve(black_box(&set), &options))
    });
}

fn bench_growth(c: &mut Criterion) {
    let options = SolveOptions::new().with_method(Method::LeastSquares);
    let mut group = c.benchmark_group("lsq_growth");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    for faces in [24usize, 72, 360, 1440] {
        let (set, _) = simulate(&config(faces, true)).expect("valid configuration");
        group.bench_with_input(BenchmarkId::from_parameter(faces), &set, |b, set| {
            b.iter(|| solve(black_box(set), &options))
        });
    }
    group.finish();
}

criterion_group!(benches, bench_closed_form, bench_lsq, bench_growth);
criterion_main!(benches);
