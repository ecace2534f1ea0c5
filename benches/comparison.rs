//! Speed of the comparisons of results (criterion): `polycal kc` and `polycal compare` as
//! their commands run them, each file read from its bytes. Figures go in docs/speed.md;
//! nothing here is asserted.
//!
//! Run with `cargo bench --bench comparison` (registered in Cargo.toml with
//! `harness = false`).
//!
//! - `kc/{8,100}x3000`: that many laboratories' result files of 3 000 pitch deviations
//!   each (u from 0.04″ to 0.18″, values written at full precision) read and evaluated,
//!   the pairs formed lazily ([`polycal::kc::Pairs`]) and not written;
//! - `kc_json/20x3000`: the JSON of 20 such laboratories (190 pairs of 3 000 faces, 11 MB)
//!   written into a sink, which is what the JSON of many laboratories costs beyond the
//!   evaluation (it grows with the pairs, n(n − 1)/2);
//! - `compare/12000`: two encoder results of 12 000 positions with `angle_deg` read and
//!   compared (matched by angle, the vector verdict);
//! - `kc_link/{every,some}_3000`: an encoder comparison of 10 laboratories at 3 000
//!   positions linked to another of 10 through the 5 in both, every laboratory reporting
//!   every position (the closed link, position by position) or each missing 1 % of them
//!   (the link over positions, a constant per linking laboratory).

use criterion::{BenchmarkId, Criterion, SamplingMode, criterion_group, criterion_main};
use polycal::compare::{CompareOptions, compare_files};
use polycal::kc::{KcOptions, KeyComparison, LabResult, evaluate, link};
use polycal::results::{Quantity, ResultRow, read_results_from, write_results};
use std::hint::black_box;

/// A reproducible standard normal draw (xorshift and Box–Muller: no generator crate).
struct Draw(u64);

impl Draw {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    fn normal(&mut self) -> f64 {
        let (a, b) = (self.uniform(), self.uniform());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }
}

/// The result files of `labs` laboratories measuring one closed polygon of `faces` faces.
fn kc_files(labs: usize, faces: u32) -> Vec<Vec<u8>> {
    let mut draw = Draw(0x9E37_79B9_7F4A_7C15);
    let truth: Vec<f64> = (0..faces).map(|_| 0.5 * draw.normal()).collect();
    (0..labs)
        .map(|l| {
            let u = 0.04 + 0.14 * l as f64 / (labs - 1).max(1) as f64;
            let x: Vec<f64> = truth.iter().map(|t| t + u * draw.normal()).collect();
            let mean = x.iter().sum::<f64>() / f64::from(faces);
            let rows: Vec<ResultRow> = (1..=faces)
                .zip(&x)
                .map(|(face, x)| {
                    ResultRow::new(Quantity::PitchDeviation, face, x - mean)
                        .with_expanded_u(2.0 * u)
                        .with_u(u)
                        .with_k(2.0)
                })
                .collect();
            let mut bytes = Vec::new();
            write_results(&mut bytes, &rows).expect("rows a result file holds");
            bytes
        })
        .collect()
}

/// Every file read as `kc` reads it, then the comparison.
fn kc_of(files: &[Vec<u8>]) -> polycal::kc::KeyComparison {
    let labs: Vec<LabResult> = files
        .iter()
        .enumerate()
        .map(|(l, bytes)| {
            let file = read_results_from(&bytes[..], "bench.csv").expect("a valid result file");
            LabResult::from_file(format!("L{l}"), file)
        })
        .collect();
    evaluate(&labs, &[], &KcOptions::new()).expect("a comparison")
}

fn bench_kc(c: &mut Criterion) {
    let mut group = c.benchmark_group("kc");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    for labs in [8, 100] {
        let files = kc_files(labs, 3_000);
        group.bench_with_input(
            BenchmarkId::from_parameter(format!("{labs}x3000")),
            &files,
            |b, files| b.iter(|| kc_of(black_box(files)).labs.len()),
        );
    }
    group.finish();

    let mut group = c.benchmark_group("kc_json");
    group.sample_size(10);
    group.sampling_mode(SamplingMode::Flat);
    let kc = kc_of(&kc_files(20, 3_000));
    group.bench_function("20x3000", |b| {
        b.iter(|| polycal::output::write_json(std::io::sink(), black_box(&kc)))
    });
    group.finish();
}

/// An encoder result of `positions` table angles, errors of 0.05″ about 0, U = 0.2″.
fn encoder_file(positions: u32, seed: u64) -> Vec<u8> {
    let mut draw = Draw(seed);
    let rows: Vec<ResultRow> = (0..positions)
        .map(|p| {
            ResultRow::new(Quantity::EncoderError, p, 0.05 * draw.normal())
                .with_expanded_u(0.2)
                .with_u(0.1)
                .with_k(2.0)
                .with_angle_deg(f64::from(p) * 360.0 / f64::from(positions))
        })
        .collect();
    let mut bytes = Vec::new();
    write_results(&mut bytes, &rows).expect("rows a result file holds");
    bytes
}

fn bench_compare(c: &mut Criterion) {
    let mut group = c.benchmark_group("compare");
    group.sample_size(10);
    let (a, b) = (encoder_file(12_000, 1), encoder_file(12_000, 2));
    group.bench_function("12000", |bench| {
        bench.iter(|| {
            let a = read_results_from(black_box(&a[..]), "a.csv").expect("a valid result file");
            let b = read_results_from(black_box(&b[..]), "b.csv").expect("a valid result file");
            compare_files(&a, &b, &CompareOptions::new())
                .expect("a comparison")
                .rows
                .len()
        })
    });
    group.finish();
}

/// An encoder comparison of `names` at `positions` angles (their own zeros, u from 0.04″
/// to 0.18″), each missing `missing` of the positions (drawn), every laboratory in the
/// reference.
fn encoder_comparison(names: &[String], positions: u32, missing: f64, seed: u64) -> KeyComparison {
    let mut draw = Draw(seed);
    let labs: Vec<LabResult> = names
        .iter()
        .enumerate()
        .map(|(l, name)| {
            let u = 0.04 + 0.14 * l as f64 / (names.len() - 1) as f64;
            let zero = draw.normal();
            let mut rows = Vec::new();
            for p in 0..positions {
                if draw.uniform() < missing {
                    continue;
                }
                let angle = f64::from(p) * 360.0 / f64::from(positions);
                let truth = 0.8 * angle.to_radians().sin();
                rows.push(
                    ResultRow::new(Quantity::EncoderError, p, truth + zero + u * draw.normal())
                        .with_u(u)
                        .with_angle_deg(angle),
                );
            }
            LabResult::from_rows(name.clone(), rows)
        })
        .collect();
    let options = KcOptions::new()
        .with_quantity(Quantity::EncoderError)
        .with_largest_consistent_subset(false);
    evaluate(&labs, &[], &options).expect("a comparison")
}

fn bench_link(c: &mut Criterion) {
    let mut group = c.benchmark_group("kc_link");
    group.sample_size(10);
    let cipm: Vec<String> = (0..10).map(|l| format!("L{l}")).collect();
    let rmo: Vec<String> = (0..5)
        .map(|l| format!("L{l}"))
        .chain((0..5).map(|l| format!("R{l}")))
        .collect();
    for (case, missing) in [("every_3000", 0.0), ("some_3000", 0.01)] {
        let linked = encoder_comparison(&cipm, 3_000, missing, 11);
        let this = encoder_comparison(&rmo, 3_000, missing, 12);
        group.bench_function(case, |b| {
            b.iter(|| {
                let mut this = this.clone();
                link(&mut this, black_box(&linked)).expect("a link");
                this.link.map_or(0, |l| l.labs.len())
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench_kc, bench_compare, bench_link);
criterion_main!(benches);
