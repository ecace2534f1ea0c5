//! Speed of the readers of the crate's files (criterion). Figures go in the closing notes;
//! nothing here is asserted.
//!
//! Run with `cargo bench --bench input` (registered in Cargo.toml with `harness = false`).
//!
//! - `results_read/{3000,30000}`: `read_results_from` on a result file of that many rows
//!   as `solve --format csv --budget` writes it (pitch, face and encoder deviations with
//!   `U`, `u`, `k`, the encoder errors with their `angle_deg`): the time should grow with
//!   the rows, not with their square (issue 55: the reader once found each field's
//!   position by scanning from the start of the file).

use criterion::{
    BenchmarkId, Criterion, SamplingMode, Throughput, criterion_group, criterion_main,
};
use polycal::results::{Quantity, ResultRow, read_results_from, write_results};
use std::hint::black_box;

/// A result file of `rows` rows (a multiple of 3): `rows / 3` faces.
fn result_file(rows: usize) -> Vec<u8> {
    let faces = rows / 3;
    let value = |i: usize| ((i as f64) * 0.37).sin() * 0.5;
    let mut all = Vec::with_capacity(rows);
    for quantity in [Quantity::PitchDeviation, Quantity::FaceDeviation] {
        for face in 1..=faces {
            all.push(
                ResultRow::new(quantity, face as u32, value(face))
                    .with_expanded_u(0.46)
                    .with_u(0.2287)
                    .with_k(2.0),
            );
        }
    }
    for p in 0..faces {
        all.push(
            ResultRow::new(Quantity::EncoderError, p as u32, value(p + 7))
                .with_expanded_u(0.46)
                .with_u(0.2287)
                .with_k(2.0)
                .with_angle_deg(p as f64 * 360.0 / faces as f64),
        );
    }
    let mut bytes = Vec::new();
    write_results(&mut bytes, &all).expect("rows a result file holds");
    bytes
}

fn bench_results_read(c: &mut Criterion) {
    let mut group = c.benchmark_group("results_read");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    for rows in [3_000, 30_000] {
        let bytes = result_file(rows);
        group.throughput(Throughput::Elements(rows as u64));
        group.bench_with_input(BenchmarkId::from_parameter(rows), &bytes, |b, bytes| {
            b.iter(|| {
                read_results_from(black_box(&bytes[..]), "bench.csv")
                    .expect("a valid result file")
                    .rows
                    .len()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_results_read);
criterion_main!(benches);
