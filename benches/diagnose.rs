//! Speed of `diagnose` (criterion). Nothing here is asserted; the figures go in the
//! closing notes and the README.
//!
//! - `diagnose/24x6_drift`: the paper's design (24 faces, 6 cycles with closing readings)
//!   with a drift: one effect found, 300 readings;
//! - `diagnose/360x6_drift_step_3_outliers`: 360 positions × 6 cycles with closing readings
//!   (4 332 readings), a drift, a jump in the middle of a cycle and three outliers, none
//!   declared: the speed target (under 0.3 s on 2 cores);
//! - `diagnose/24x4_subpitch_drift_step_outlier`: two mountings at 0° and 7.5° (sub-pitch,
//!   two cosets of 24 angles), 4 cycles with closing readings (400 readings), a drift, a
//!   jump inside mounting 2 and an outlier: the base model carries the cosets' 23
//!   differences as columns.
//! - `diagnose/{360,1440,5760}x6_drift_step`: 360, 1 440 and 5 760 positions × 6 cycles
//!   with closing readings (4 332, 17 292 and 69 132 readings), a drift and a jump: the
//!   structured geometry (issue 22's targets: 0.1 s at 1 440, 1 s at 5 760, growth at
//!   most N^1.3);
//! - `side_by_side/{solve,diagnose}_{1440,5760}x6_{drift_step,clean}`: `solve` and
//!   `diagnose` of the same runs (1 440 and 5 760 positions × 6 cycles with closing
//!   readings, with a drift and a jump, and without effects), each from the file's bytes
//!   in memory as the commands read them (parsing included, output and process start-up
//!   not), so that their ratio is measured in one run (issue 35: `diagnose` at most 3×
//!   `solve`); after them, `side_by_side/interleaved` (printed, not a criterion
//!   measurement) times the same pairs one after the other, a solve then a diagnosis, 30
//!   times at 1 440 and 10 at 5 760, and prints the median of each pair's ratio: a busy
//!   machine slows both halves of a pair alike, where criterion measures the two seconds
//!   apart;
//! - `diagnose/selfa168x3_drift_step_outlier`: a SelfA self-calibration (12 heads, 168
//!   positions, 3 cycles, 6 048 readings) with a head's drift, another head's jump and an
//!   outlier: the closure model with the table's error at every stop taken out.

use criterion::{Criterion, criterion_group, criterion_main};
use polycal::diagnose::selfcal::diagnose_selfcal;
use polycal::diagnose::{DiagnoseOptions, diagnose};
use polycal::effects::Effect;
use polycal::measurement::MeasurementSet;
use polycal::selfcal::SelfcalOptions;
use polycal::simulate::{SelfcalSimConfig, simulate_selfcal};
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{SolveOptions, solve};
use std::hint::black_box;
use std::time::{Duration, Instant};

fn outlier(cycle: u32, step: usize, ac: u32, value: f64) -> Effect {
    Effect::Outlier {
        cycle,
        step,
        ac,
        setup: None,
        value,
    }
}

fn bench_diagnose(c: &mut Criterion) {
    let small = SimulationConfig {
        effects: vec![Effect::Drift {
            ac: 2,
            value: 2.0,
            quadratic: None,
        }],
        ..SimulationConfig::default()
    };
    let large = SimulationConfig {
        faces: 360,
        step_seconds: 5.0,
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.8,
                quadratic: None,
            },
            Effect::OffsetStep {
                ac: 2,
                cycle: 4,
                step: Some(150),
                setup: None,
                value: 0.3,
            },
            outlier(2, 100, 1, 1.0),
            outlier(3, 200, 2, -1.2),
            outlier(5, 17, 1, 0.9),
        ],
        ..SimulationConfig::default()
    };
    let options = DiagnoseOptions::default();
    let mut group = c.benchmark_group("diagnose");
    let (set, _) = simulate(&small).expect("a valid simulation");
    group.bench_function("24x6_drift", |b| {
        b.iter(|| diagnose(black_box(&set), &options))
    });
    let shifted = SimulationConfig {
        setups: 2,
        setup_shift_faces: 5,
        table_shift_deg: vec![0.0, 7.5],
        cycles: 4,
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.5,
                quadratic: None,
            },
            Effect::OffsetStep {
                ac: 2,
                cycle: 2,
                step: Some(9),
                setup: Some(2),
                value: 0.4,
            },
            Effect::Outlier {
                cycle: 3,
                step: 5,
                ac: 1,
                setup: Some(1),
                value: 1.0,
            },
        ],
        ..SimulationConfig::default()
    };
    let (set, _) = simulate(&shifted).expect("a valid simulation");
    group.bench_function("24x4_subpitch_drift_step_outlier", |b| {
        b.iter(|| diagnose(black_box(&set), &options))
    });
    let (set, _) = simulate(&large).expect("a valid simulation");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(8));
    group.bench_function("360x6_drift_step_3_outliers", |b| {
        b.iter(|| diagnose(black_box(&set), &options))
    });
    for faces in [360, 1440, 5760] {
        let config = SimulationConfig {
            faces,
            closing: true,
            step_seconds: 2.0,
            effects: vec![
                Effect::Drift {
                    ac: 1,
                    value: 0.8,
                    quadratic: None,
                },
                Effect::OffsetStep {
                    ac: 2,
                    cycle: 4,
                    step: Some(faces / 3),
                    setup: None,
                    value: 0.3,
                },
            ],
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).expect("a valid simulation");
        group.bench_function(format!("{faces}x6_drift_step"), |b| {
            b.iter(|| diagnose(black_box(&set), &options))
        });
    }
    let mut selfa = SelfcalSimConfig::default();
    selfa.cycles = 3;
    selfa.step_seconds = Some(20.0);
    let (mut set, _) = simulate_selfcal(&selfa).expect("a valid simulation");
    for r in &mut set.readings {
        let hours = r.time_seconds.unwrap_or(0.0) / 3600.0;
        match r.head {
            5 => r.reading_arcsec += 0.2 * hours,
            9 if (r.cycle, r.step) >= (2, 80) => r.reading_arcsec += 0.15,
            3 if (r.cycle, r.step) == (3, 7) => r.reading_arcsec += 0.3,
            _ => {}
        }
    }
    let selfcal_options = SelfcalOptions::new();
    group.bench_function("selfa168x3_drift_step_outlier", |b| {
        b.iter(|| diagnose_selfcal(black_box(&set), &options, &selfcal_options))
    });
    group.finish();
}

/// `solve` against `diagnose` of the same file, both from its bytes (parsing included).
fn bench_side_by_side(c: &mut Criterion) {
    let mut group = c.benchmark_group("side_by_side");
    group.sample_size(10);
    group.measurement_time(Duration::from_secs(5));
    for faces in [1440, 5760] {
        for (name, effects) in [
            (
                "drift_step",
                vec![
                    Effect::Drift {
                        ac: 1,
                        value: 0.8,
                        quadratic: None,
                    },
                    Effect::OffsetStep {
                        ac: 2,
                        cycle: 4,
                        step: Some(faces / 3),
                        setup: None,
                        value: 0.3,
                    },
                ],
            ),
            ("clean", Vec::new()),
        ] {
            let config = SimulationConfig {
                faces,
                closing: true,
                step_seconds: 2.0,
                effects,
                ..SimulationConfig::default()
            };
            let (set, _) = simulate(&config).expect("a valid simulation");
            let mut bytes = Vec::new();
            set.write_to(&mut bytes, &[]).expect("written to memory");
            let read = |bytes: &[u8]| {
                MeasurementSet::read_from(bytes, "run.csv", None).expect("a valid file")
            };
            let solve_options = SolveOptions::default();
            group.bench_function(format!("solve_{faces}x6_{name}"), |b| {
                b.iter(|| solve(&read(black_box(&bytes)), &solve_options))
            });
            let options = DiagnoseOptions::default();
            group.bench_function(format!("diagnose_{faces}x6_{name}"), |b| {
                b.iter(|| diagnose(&read(black_box(&bytes)), &options))
            });
            if interleaved_wanted() {
                let pairs = if faces <= 1440 { 30 } else { 10 };
                let time = |f: &dyn Fn()| {
                    let start = Instant::now();
                    f();
                    start.elapsed().as_secs_f64()
                };
                let mut solve_seconds = Vec::new();
                let mut diagnose_seconds = Vec::new();
                let mut ratios = Vec::new();
                for _ in 0..pairs {
                    let s = time(&|| {
                        black_box(solve(&read(black_box(&bytes)), &solve_options).ok());
                    });
                    let d = time(&|| {
                        black_box(diagnose(&read(black_box(&bytes)), &options).ok());
                    });
                    solve_seconds.push(s);
                    diagnose_seconds.push(d);
                    ratios.push(d / s);
                }
                println!(
                    "side_by_side/interleaved_{faces}x6_{name}: {pairs} pairs, solve median {:.1} ms, \
                     diagnose median {:.1} ms, median of the pairs' ratios {:.2} (least {:.2}, most {:.2})",
                    1e3 * median(&mut solve_seconds),
                    1e3 * median(&mut diagnose_seconds),
                    median(&mut ratios),
                    ratios.iter().copied().fold(f64::INFINITY, f64::min),
                    ratios.iter().copied().fold(0.0, f64::max),
                );
            }
        }
    }
    group.finish();
}

/// The middle value (the upper of the two middle ones for an even count).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
}

/// Whether the interleaved pairs run: under `cargo bench` (not `cargo test`'s single
/// pass), without a filter or with one naming them (criterion takes an argument that is
/// not an option, nor an option's number, as its filter).
fn interleaved_wanted() -> bool {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if !args.iter().any(|a| a == "--bench") {
        return false;
    }
    let filters: Vec<&String> = args
        .iter()
        .filter(|a| !a.starts_with('-') && a.parse::<f64>().is_err())
        .collect();
    filters.is_empty()
        || filters
            .iter()
            .any(|f| f.contains("side_by_side") || f.contains("interleaved"))
}

criterion_group!(benches, bench_diagnose, bench_side_by_side);
criterion_main!(benches);
