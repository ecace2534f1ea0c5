//! The noise the run measures from its repeated readings (docs/FORMAT.md §7.3, *The
//! noise the run measures*; issue 47): its verdicts' rates measured on simulated runs
//! whose true noise is known, a lab whose autocollimators scatter by 0.02″ and a run
//! told the default `--reading-noise 0.1`:
//!
//! - the agreement of the readings at a stop (`RepeatNoise::agreement_at`, the loop's
//!   tolerance): its false alarms — honest pairs refused — at the nominal rate 2Φ(−z)
//!   whatever the degrees of freedom pooled (measured at z = 2.5 and 3, where a rate can
//!   be measured; the run's z = 5 refuses none of the pairs), and its power against one
//!   reading 0.5″ off at a stop (a sign flip, a digit dropped, a late reply of another
//!   stop within the old tolerance), before (the stated noise: none) and after;
//! - the live check (`to_measure_again_judged` with the loop's judged noise): the runs
//!   in which a clean run measures anything again, and the power against a stored
//!   reading 0.5″ off at one stop of a 24-face run, before (`to_measure_again`, the
//!   stated noise's floor) and after.
//!
//! Fixed seeds; each prints its figures in one stable line.

use polycal::lab::run::{
    Cell, MAX_REMEASURED_PER_CYCLE, RepeatNoise, RunSettings, to_measure_again,
    to_measure_again_judged,
};
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, simulate};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use statrs::function::erf::erfc;

/// The autocollimators' true noise, σ of one reading, arcsec.
const TRUE_SIGMA: f64 = 0.02;
/// The noise the run is told (the default `--reading-noise`), arcsec.
const STATED: f64 = 0.1;
/// The error of one reading, arcsec.
const OFF: f64 = 0.5;

// ---------------------------------------------------------------------------------------
// The agreement at a stop
// ---------------------------------------------------------------------------------------

/// Stops of each simulated run per autocollimator: 24 faces, 2 cycles with the closing
/// step.
const STOPS: usize = 50;
/// Simulated runs.
const AGREEMENT_RUNS: u64 = 4000;

/// Two readings of one autocollimator at a stop, the truth 0.
fn pair(rng: &mut Xoshiro256PlusPlus) -> [f64; 2] {
    let z1: f64 = StandardNormal.sample(rng);
    let z2: f64 = StandardNormal.sample(rng);
    [TRUE_SIGMA * z1, TRUE_SIGMA * z2]
}

/// (honest pairs refused at z, pairs in all) over every stop of [`AGREEMENT_RUNS`]
/// runs, each stop judged by the noise pooled from the stops before it.
///
/// The loop pools the agreeing readings alone (a refused one may be a wrong value):
/// at z = 5 that leaves out 2·(5φ(5) + Φ(−5)) = 1.6·10⁻⁵ of the variance, nothing; at
/// z = 2.5 it would leave out 10 % and lower s by 5 %, which is the truncation's, not
/// the construction's. So at the z where a rate can be measured every pair is pooled
/// (`pool_refused`), and at z = 5 as the loop does.
fn refused_honest_pairs(z: f64, pool_refused: bool) -> (usize, usize) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(47);
    let (mut refused, mut pairs) = (0, 0);
    for _ in 0..AGREEMENT_RUNS {
        let mut noise = RepeatNoise::default();
        for _ in 0..STOPS {
            let [a, b] = pair(&mut rng);
            pairs += 1;
            let refuse = (a - b).abs() > noise.agreement_at(STATED, z);
            refused += usize::from(refuse);
            if !refuse || pool_refused {
                noise.add_stop(&[a, b]);
            }
        }
    }
    (refused, pairs)
}

#[test]
fn honest_pairs_are_refused_at_the_nominal_rate_whatever_the_repeats_pooled() {
    let mut failed = Vec::new();
    for z in [2.5, 3.0] {
        let nominal = erfc(z / 2f64.sqrt());
        let (refused, pairs) = refused_honest_pairs(z, true);
        let rate = refused as f64 / pairs as f64;
        let se = (nominal * (1.0 - nominal) / pairs as f64).sqrt();
        println!(
            "verdict run agreement at a stop, z = {z}: honest pairs refused {rate:.5} \
             (n = {pairs}), nominal 2Φ(−z) = {nominal:.5}; true σ {TRUE_SIGMA}″, stated {STATED}″"
        );
        // Exact for every ν once the stated bound does not apply (it applies at ν = 1
        // alone here, 2 % of the pairs, and only lowers the rate): held to nominal
        // − 4 % of it … nominal + 4 standard errors.
        if rate > nominal + 4.0 * se || rate < 0.96 * nominal - 4.0 * se {
            failed.push(format!("z = {z}: {rate} against {nominal}"));
        }
    }
    // The run's own z = 5 (2Φ(−5) = 5.7e-7): none of 200 000 pairs.
    let (refused, pairs) = refused_honest_pairs(5.0, false);
    println!("verdict run agreement at a stop, z = 5: honest pairs refused {refused} of {pairs}");
    if refused > 1 {
        failed.push(format!("z = 5: {refused} of {pairs} refused"));
    }
    assert!(failed.is_empty(), "{failed:?}");
}

#[test]
fn one_reading_half_an_arcsecond_off_at_a_stop_is_refused_once_the_noise_is_measured() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(147);
    let (mut before, mut after, mut after_late, mut late) = (0, 0, 0, 0);
    for _ in 0..AGREEMENT_RUNS {
        // The reading off at a random stop of the run, of a random sign.
        let off_at = rng.random_range(0..STOPS);
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let mut noise = RepeatNoise::default();
        for stop in 0..STOPS {
            let [a, b] = pair(&mut rng);
            if stop == off_at {
                let d = (a - (b + sign * OFF)).abs();
                let stated = RunSettings::new(24, 2)
                    .with_reading_noise_arcsec(STATED)
                    .agreement_arcsec();
                before += usize::from(d > stated);
                let refused = d > noise.agreement_arcsec(STATED);
                after += usize::from(refused);
                if stop >= 10 {
                    late += 1;
                    after_late += usize::from(refused);
                }
            }
            noise.add_stop(&[a, b]);
        }
    }
    let n = AGREEMENT_RUNS as f64;
    let (before, after) = (before as f64 / n, after as f64 / n);
    let after_late = after_late as f64 / late as f64;
    println!(
        "verdict run agreement at a stop: one reading {OFF}″ off refused: before (stated \
         {STATED}″) {before:.3}, after {after:.3} at a random stop of {STOPS}, \
         {after_late:.3} from the 11th stop on (n = {AGREEMENT_RUNS}; true σ {TRUE_SIGMA}″)"
    );
    assert!(before < 0.01, "before {before}");
    // The first stops are judged by the stated noise (ν small): after ten stops all.
    assert!(after > 0.75, "after {after}");
    assert!(after_late > 0.99, "from the 11th stop on {after_late}");
}

// ---------------------------------------------------------------------------------------
// The live check
// ---------------------------------------------------------------------------------------

/// Runs of the live check: 24 faces, two autocollimators, 2 clockwise cycles with the
/// closing step (100 readings), two readings a stop.
const LIVE_FACES: usize = 24;
const LIVE_CYCLES: u32 = 2;
const LIVE_RUNS: u64 = 300;

fn live_settings() -> RunSettings {
    RunSettings::new(LIVE_FACES, LIVE_CYCLES)
        .with_closing(true)
        .with_reads_per_stop(2)
        .with_reading_noise_arcsec(STATED)
}

/// The judged noise of one reading at the check after `cycle`: the largest of the two
/// autocollimators' pooled repeats (one pair a stop, `stops_per_cycle`·`cycle` stops),
/// as the loop takes it.
fn judged_after(cycle: u32, rng: &mut Xoshiro256PlusPlus) -> f64 {
    let stops = live_settings().stops_per_cycle() * cycle as usize;
    (0..2)
        .map(|_| {
            let mut noise = RepeatNoise::default();
            for _ in 0..stops {
                noise.add_stop(&pair(rng));
            }
            noise.sigma_used_arcsec(STATED)
        })
        .fold(0.0, f64::max)
}

/// The cells the run measures again, as its loop decides them (as in
/// `verdict_rates_run_plan.rs`): with the judged noise when `judged` is given (one per
/// cycle), else with the stated one.
fn remeasured_cells(set: &MeasurementSet, judged: Option<&[f64]>) -> Vec<Cell> {
    let settings = live_settings();
    let mut handled: Vec<Cell> = Vec::new();
    for cycle in 1..=LIVE_CYCLES {
        let mut on_disk = set.clone();
        on_disk.readings.retain(|r| r.cycle <= cycle);
        for _ in 0..MAX_REMEASURED_PER_CYCLE {
            let flag = match judged {
                Some(j) => to_measure_again_judged(
                    &on_disk,
                    &settings,
                    j[cycle as usize - 1],
                    (1, cycle),
                    &handled,
                ),
                None => to_measure_again(&on_disk, &settings, 1, cycle, &handled),
            };
            let Some(flag) = flag else {
                break;
            };
            let r = &on_disk.readings[flag.index];
            handled.push((r.setup, r.step, r.ac, r.direction));
        }
    }
    handled
}

#[test]
fn the_live_check_finds_half_an_arcsecond_at_one_stop_and_keeps_its_false_alarm_rate() {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(247);
    let (mut alarms, mut found_before, mut found_after) = (0, 0, 0);
    for seed in 1..=LIVE_RUNS {
        // A stored reading is the mean of two: σ/√2.
        let config = SimulationConfig {
            faces: LIVE_FACES,
            cycles: LIVE_CYCLES,
            closing: true,
            noise_arcsec: TRUE_SIGMA / 2f64.sqrt(),
            seed,
            ..SimulationConfig::default()
        };
        let (set, _) = simulate(&config).unwrap();
        let judged: Vec<f64> = (1..=LIVE_CYCLES)
            .map(|c| judged_after(c, &mut rng))
            .collect();
        if !remeasured_cells(&set, Some(&judged)).is_empty() {
            alarms += 1;
        }
        let i = rng.random_range(0..set.readings.len());
        let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        let mut off_set = set.clone();
        off_set.readings[i].reading_arcsec += sign * OFF;
        let r = &off_set.readings[i];
        let off = (r.setup, r.step, r.ac, r.direction);
        if remeasured_cells(&off_set, None).contains(&off) {
            found_before += 1;
        }
        if remeasured_cells(&off_set, Some(&judged)).contains(&off) {
            found_after += 1;
        }
    }
    let n = LIVE_RUNS as f64;
    let (alarm, before, after) = (
        alarms as f64 / n,
        found_before as f64 / n,
        found_after as f64 / n,
    );
    println!(
        "verdict run live check with the measured noise: false alarm {alarm:.3} per run, \
         one reading {OFF}″ off measured again: before (stated {STATED}″) {before:.3}, \
         after {after:.3} (n = {LIVE_RUNS}; {LIVE_FACES} faces × {LIVE_CYCLES} cycles, \
         true σ {TRUE_SIGMA}″ a reading)"
    );
    assert!(alarm <= 0.015, "false alarm {alarm}");
    assert!(before < 0.1, "before {before}");
    assert!(after > 0.95, "after {after}");
}
