//! The habits of real labs in `simulate` (issue 21): `--rezero AC:SIGMA`,
//! `--random-walk AC:RATE`, `--no-time`. Each keeps the truth and the noise of the clean
//! twin (the same settings without it) bit for bit, so that a test can put the effect's
//! error next to the clean run's; the drawn values follow their distributions.

use polycal::effects::Effect;
use polycal::simulate::{RandomWalkSpec, RezeroSpec, SimulationConfig, simulate};

fn base(seed: u64) -> SimulationConfig {
    SimulationConfig {
        seed,
        ..SimulationConfig::default()
    }
}

/// A rezeroed run differs from its clean twin by exactly the drawn offset of each
/// reading's cycle, on that autocollimator only; truth values are the twin's.
#[test]
fn rezero_adds_exactly_its_drawn_offsets_to_the_clean_twin() {
    let config = SimulationConfig {
        rezero: vec![RezeroSpec {
            ac: 2,
            sigma_arcsec: 0.3,
        }],
        ..base(5)
    };
    let (set, truth) = simulate(&config).unwrap();
    let (clean, clean_truth) = simulate(&base(5)).unwrap();
    assert_eq!(truth.pitch_deviation, clean_truth.pitch_deviation);
    assert_eq!(truth.encoder_error, clean_truth.encoder_error);
    assert_eq!(truth.setup_error, clean_truth.setup_error);
    let [Effect::Rezero { ac: 2, offsets, .. }] = truth.effects.as_slice() else {
        panic!("{:?}", truth.effects);
    };
    assert_eq!(offsets.len(), 6);
    for (r, c) in set.readings.iter().zip(&clean.readings) {
        let expected = if r.ac == 2 {
            offsets[r.cycle as usize - 1]
        } else {
            0.0
        };
        assert!((r.reading_arcsec - c.reading_arcsec - expected).abs() < 1e-12);
    }
}

/// The offsets are normal with the stated σ: over 200 seeds × 6 cycles the sample
/// standard deviation is within 10 % of 0.3″ (its relative standard error is 2 %).
#[test]
fn rezero_offsets_have_the_stated_spread() {
    let mut all = Vec::new();
    for seed in 0..200 {
        let config = SimulationConfig {
            rezero: vec![RezeroSpec {
                ac: 1,
                sigma_arcsec: 0.3,
            }],
            ..base(seed)
        };
        let (_, truth) = simulate(&config).unwrap();
        if let Some(Effect::Rezero { offsets, .. }) = truth.effects.first() {
            all.extend(offsets.iter().copied());
        }
    }
    assert_eq!(all.len(), 1200);
    let sd = (all.iter().map(|o| o * o).sum::<f64>() / all.len() as f64).sqrt();
    assert!((sd - 0.3).abs() < 0.03, "{sd}");
}

/// A random walk adds to every reading of its autocollimator the walk at its stop (0 at
/// the first stop); the increments have variance rate²·Δt (Δt = 20 s in hours): over
/// 40 seeds × 149 increments the sample variance is within 10 % of it.
#[test]
fn a_random_walk_adds_its_recorded_values_with_the_stated_rate() {
    let mut squares = (0.0, 0usize);
    for seed in 0..40 {
        let config = SimulationConfig {
            random_walk: vec![RandomWalkSpec {
                ac: 1,
                rate_arcsec_per_sqrt_h: 0.25,
            }],
            ..base(seed)
        };
        let (set, truth) = simulate(&config).unwrap();
        let (clean, clean_truth) = simulate(&base(seed)).unwrap();
        assert_eq!(truth.encoder_error, clean_truth.encoder_error);
        let walk = &truth.random_walk[0];
        assert_eq!(walk.values_arcsec.len(), 150);
        assert_eq!(walk.values_arcsec[0], 0.0);
        for (k, pair) in set
            .readings
            .chunks(2)
            .zip(clean.readings.chunks(2))
            .enumerate()
        {
            let (r, c) = pair;
            assert!(
                (r[0].reading_arcsec - c[0].reading_arcsec - walk.values_arcsec[k]).abs() < 1e-12
            );
            assert_eq!(r[1].reading_arcsec, c[1].reading_arcsec);
        }
        for w in walk.values_arcsec.windows(2) {
            squares.0 += (w[1] - w[0]).powi(2);
            squares.1 += 1;
        }
    }
    let variance = squares.0 / squares.1 as f64;
    let expected = 0.25_f64.powi(2) * 20.0 / 3600.0;
    assert!(
        (variance / expected - 1.0).abs() < 0.1,
        "{variance} vs {expected}"
    );
}

/// `no_time`: the readings are the timed run's (a drift acting on the true time), without
/// a time.
#[test]
fn no_time_keeps_the_readings_and_drops_the_time() {
    let config = SimulationConfig {
        effects: vec![Effect::Drift {
            ac: 2,
            value: 2.0,
            quadratic: None,
        }],
        ..base(3)
    };
    let (timed, _) = simulate(&config).unwrap();
    let (untimed, _) = simulate(&SimulationConfig {
        no_time: true,
        ..config
    })
    .unwrap();
    for (a, b) in timed.readings.iter().zip(&untimed.readings) {
        assert_eq!(a.reading_arcsec, b.reading_arcsec);
        assert!(a.time_seconds.is_some() && b.time_seconds.is_none());
    }
}

/// Bad settings are refused: an autocollimator the run does not have, a negative σ.
#[test]
fn bad_habits_are_refused() {
    let config = SimulationConfig {
        rezero: vec![RezeroSpec {
            ac: 3,
            sigma_arcsec: 0.1,
        }],
        ..base(1)
    };
    let message = simulate(&config).unwrap_err().to_string();
    assert!(message.contains("no autocollimator 3"), "{message}");
    assert!("1:-0.1".parse::<RandomWalkSpec>().is_err());
    assert!("0:0.1".parse::<RezeroSpec>().is_err());
    assert!("1:0.1:2".parse::<RezeroSpec>().is_err());
}
