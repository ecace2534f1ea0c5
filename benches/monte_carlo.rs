//! Benchmarks of the uncertainty layer: Monte Carlo throughput and Student's t.
//!
//! Run with `cargo bench --bench monte_carlo` (registered in Cargo.toml with
//! `harness = false`).

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use polycal::uncertainty::distribution::Distribution;
use polycal::uncertainty::monte_carlo::{McInput, MonteCarlo, Trials};
use polycal::uncertainty::student::t_quantile;

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

fn student(c: &mut Criterion) {
    c.bench_function("t_quantile_95_nu_72.6", |b| {
        b.iter(|| t_quantile(black_box(0.95), black_box(Some(72.6))))
    });
    c.bench_function("t_quantile_95_nu_1e6", |b| {
        b.iter(|| t_quantile(black_box(0.95), black_box(Some(1e6))))
    });
}

criterion_group!(benches, monte_carlo, student);
criterion_main!(benches);
