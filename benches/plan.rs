//! Speed of `plan` (criterion). Nothing here is asserted; the figures go in the closing
//! notes.
//!
//! - `plan/24x6_u`: the paper's design with closing readings, the uncertainties alone;
//! - `plan/24x6_detect`: the same with what a diagnosis can see (the first round of the
//!   selection emulated with 2000 draws, every term sized by bisection);
//! - `plan/360x6_u`: 360 positions × 6 cycles, the uncertainties alone.

use criterion::{Criterion, criterion_group, criterion_main};
use polycal::measurement::Sigma;
use polycal::plan::{Design, PlanOptions, plan};
use std::hint::black_box;
use std::time::Duration;

fn bench_plan(c: &mut Criterion) {
    let sigma = Sigma::new(0.05).expect("a valid σ");
    let paper = Design::default()
        .with_spec("closing")
        .expect("a valid design");
    let large = paper.with_spec("faces=360").expect("a valid design");
    let mut group = c.benchmark_group("plan");
    let u_only = PlanOptions::new(sigma).with_detect(false);
    group.bench_function("24x6_u", |b| b.iter(|| plan(black_box(&paper), &u_only)));
    group.bench_function("360x6_u", |b| b.iter(|| plan(black_box(&large), &u_only)));
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    let detect = PlanOptions::new(sigma);
    group.bench_function("24x6_detect", |b| {
        b.iter(|| plan(black_box(&paper), &detect))
    });
    group.finish();
}

criterion_group!(benches, bench_plan);
criterion_main!(benches);
