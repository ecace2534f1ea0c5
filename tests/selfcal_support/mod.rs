//! What the self-calibration diagnosis tests share: simulated runs with time, the effects
//! they inject (each as its column, derived here from the effect's definition) and how a
//! finding is looked up.

#![allow(dead_code)]

use polycal::diagnose::FoundEffect;
use polycal::diagnose::selfcal::SelfcalDiagnosis;
use polycal::effects::Effect;
use polycal::measurement::Direction;
use polycal::selfcal::{self, SelfcalSet};
use polycal::simulate::{SelfcalSimConfig, SelfcalTruth, simulate_selfcal};

/// Seconds between two stops of the table.
pub const STEP_SECONDS: f64 = 20.0;

/// An effect put into the readings, and its column (one value per reading).
#[derive(Debug, Clone, Copy)]
pub enum Injected {
    /// The head's zero drifts, arcsec per hour.
    Drift { head: u32, per_hour: f64 },
    /// The head's zero jumps by `value` from (cycle, step) on, in time order.
    Jump {
        head: u32,
        cycle: u32,
        step: usize,
        value: f64,
    },
    /// One bad reading.
    Outlier {
        head: u32,
        cycle: u32,
        step: usize,
        value: f64,
    },
    /// The head reads `value` more in counter-clockwise cycles.
    Direction { head: u32, value: f64 },
}

impl Injected {
    pub fn column(self, set: &SelfcalSet) -> Vec<f64> {
        // time order: the stop's ordinal (every head of a stop shares it)
        let time_of = |r: &selfcal::HeadReading| r.time_seconds.unwrap_or(0.0);
        let start_of = |cycle: u32, step: usize| {
            set.readings
                .iter()
                .find(|r| r.cycle == cycle && r.step == step)
                .map_or(0.0, time_of)
        };
        set.readings
            .iter()
            .map(|r| match self {
                Injected::Drift { head, per_hour } if r.head == head => {
                    per_hour * time_of(r) / 3600.0
                }
                Injected::Jump {
                    head,
                    cycle,
                    step,
                    value,
                } if r.head == head && time_of(r) >= start_of(cycle, step) => value,
                Injected::Outlier {
                    head,
                    cycle,
                    step,
                    value,
                } if (r.head, r.cycle, r.step) == (head, cycle, step) => value,
                Injected::Direction { head, value }
                    if r.head == head && r.direction == Direction::Ccw =>
                {
                    value
                }
                _ => 0.0,
            })
            .collect()
    }
}

/// The configuration of a simulated run with time (20 s per stop), σ = 0.02″, table
/// error 1″ per stop.
pub fn run_config(
    heads: Vec<f64>,
    positions: usize,
    cycles: u32,
    bidirectional: bool,
    seed: u64,
) -> SelfcalSimConfig {
    let mut config = SelfcalSimConfig::default();
    config.positions = positions;
    config.cycles = cycles;
    config.head_angles_deg = heads;
    config.bidirectional = bidirectional;
    config.step_seconds = Some(STEP_SECONDS);
    config.seed = seed;
    config
}

/// A simulated run of [`run_config`].
pub fn run(
    heads: Vec<f64>,
    positions: usize,
    cycles: u32,
    bidirectional: bool,
    seed: u64,
) -> (SelfcalSet, SelfcalTruth) {
    simulate_selfcal(&run_config(heads, positions, cycles, bidirectional, seed)).unwrap()
}

pub fn inject(set: &mut SelfcalSet, effects: &[Injected]) {
    for effect in effects {
        let column = effect.column(set);
        for (r, v) in set.readings.iter_mut().zip(column) {
            r.reading_arcsec += v;
        }
    }
}

/// `values` (one per position) with the mean and the lost harmonics removed: the part of
/// e a self-calibration can determine (a real DFT, O(P²)).
pub fn observable(values: &[f64], lost: &[usize]) -> Vec<f64> {
    let p = values.len();
    let mean = values.iter().sum::<f64>() / p as f64;
    let mut out: Vec<f64> = values.iter().map(|v| v - mean).collect();
    for &k in lost.iter().filter(|&&k| 2 * k <= p) {
        let w = 2.0 * std::f64::consts::PI * k as f64 / p as f64;
        let (mut a, mut b) = (0.0, 0.0);
        for (x, v) in out.iter().enumerate() {
            a += v * (w * x as f64).cos();
            b += v * (w * x as f64).sin();
        }
        let scale = if 2 * k == p { 1.0 } else { 2.0 } / p as f64;
        for (x, v) in out.iter_mut().enumerate() {
            *v -= scale * (a * (w * x as f64).cos() + b * (w * x as f64).sin());
        }
    }
    out
}

/// RMS errors (observable e, heads' errors) of an estimate against the truth, e without
/// its mean and the harmonics `lost` (those the head layout cannot see).
pub fn errors(
    set: &SelfcalSet,
    truth: &SelfcalTruth,
    e: &[f64],
    c: &[f64],
    lost: &[usize],
) -> (f64, f64) {
    let p = set.positions;
    let true_e: Vec<f64> = (0..p)
        .map(|x| truth.encoder_error_at_deg(x as f64 * 360.0 / p as f64))
        .collect();
    let difference: Vec<f64> = e.iter().zip(&true_e).map(|(a, b)| a - b).collect();
    let true_c: Vec<f64> = set
        .heads()
        .iter()
        .skip(1)
        .map(|h| truth.head_error_of(h.head).unwrap() - truth.head_error_of(1).unwrap())
        .collect();
    let c_difference: Vec<f64> = c.iter().zip(&true_c).map(|(a, b)| a - b).collect();
    (rms(&observable(&difference, lost)), rms(&c_difference))
}

/// The heads' errors of a solution, in head order.
pub fn head_errors(solution: &selfcal::SelfcalSolution) -> Vec<f64> {
    solution.head_error.iter().map(|h| h.value).collect()
}

pub fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len().max(1) as f64).sqrt()
}

pub fn kinds(found: &SelfcalDiagnosis) -> Vec<&Effect> {
    found.diagnosis.effects.iter().map(|f| &f.effect).collect()
}

pub fn find(found: &SelfcalDiagnosis, test: impl Fn(&Effect) -> bool) -> Option<&FoundEffect> {
    found.diagnosis.effects.iter().find(|f| test(&f.effect))
}

/// Clean runs `make(seed)` for every seed, diagnosed on two threads: (runs with some
/// effect found, runs not adequate), each checked to be at most 5 % of the runs.
pub fn check_clean_runs(
    name: &str,
    seeds: &[u64],
    make: impl Fn(u64) -> SelfcalSet + Sync,
) -> (usize, usize) {
    use polycal::diagnose::DiagnoseOptions;
    use polycal::diagnose::selfcal::diagnose_selfcal;
    use polycal::selfcal::SelfcalOptions;
    let make = &make;
    let results: Vec<(bool, bool)> = std::thread::scope(|scope| {
        let handles: Vec<_> = seeds
            .chunks(seeds.len().div_ceil(2).max(1))
            .map(|chunk| {
                scope.spawn(move || {
                    chunk
                        .iter()
                        .map(|&seed| {
                            let found = diagnose_selfcal(
                                &make(seed),
                                &DiagnoseOptions::default(),
                                &SelfcalOptions::new(),
                            )
                            .unwrap();
                            (
                                !found.diagnosis.effects.is_empty(),
                                !found.diagnosis.adequacy.adequate,
                            )
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    let runs = seeds.len();
    let effects = results.iter().filter(|r| r.0).count();
    let inadequate = results.iter().filter(|r| r.1).count();
    println!("{name}, {runs} clean runs: {effects} with an effect, {inadequate} not adequate");
    assert!(
        effects * 20 <= runs,
        "{name}: {effects} of {runs} with an effect"
    );
    assert!(
        inadequate * 20 <= runs,
        "{name}: {inadequate} of {runs} not adequate"
    );
    (effects, inadequate)
}
