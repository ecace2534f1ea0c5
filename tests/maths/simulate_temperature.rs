//! Tests of the simulator against hand-derived expectations: the temperature model. The
//! column it writes follows the model at every stop (at hand-computed times too), its
//! noise is white and shared by the autocollimators of a stop, switching it on changes
//! no reading, and a temperature effect acts against the run's mean temperature.

use polycal::effects::Effect;
use polycal::simulate::{SimulationConfig, TemperatureModel, simulate};

use crate::simulate_support::{air_conditioned_lab, bits, check_effect, effect_base, noise_free};

// ---------------------------------------------------------------- temperature

#[test]
fn the_temperature_column_follows_the_model() {
    let config = SimulationConfig {
        faces: 6,
        cycles: 30, // 30 · 7 stops of 60 s: 3.5 hours
        step_seconds: 60.0,
        temperature: Some(air_conditioned_lab()),
        ..noise_free(6)
    };
    let (set, truth) = simulate(&config).unwrap();
    // Both autocollimators of a stop share the stop's temperature; stop k is at 60 k s.
    for (k, pair) in set.readings.chunks(2).enumerate() {
        let t = 60.0 * k as f64;
        let by_hand = 20.0
            + 0.5 * (1.0 - (-t / 3600.0).exp())
            + 0.1 * (2.0 * std::f64::consts::PI * t / 1200.0).sin();
        for r in pair {
            assert_eq!(r.time_seconds, Some(t));
            let temperature = r.temperature_celsius.expect("a temperature");
            assert!(
                (temperature - by_hand).abs() < 1e-12,
                "{t} s: {temperature}"
            );
        }
    }
    // Hand-computed values: 20 °C at 0 s; at 300 s the cycle's crest, 20 + 0.5·(1 − e^(−1/12))
    // + 0.1; at 900 s its trough; at 3600 s (three whole periods) 20 + 0.5·(1 − 1/e).
    let at = |t: f64| {
        set.readings[(t / 60.0) as usize * 2]
            .temperature_celsius
            .unwrap()
    };
    assert_eq!(at(0.0), 20.0);
    assert!((at(300.0) - 20.139_977_792_685_34).abs() < 1e-12);
    assert!((at(900.0) - 20.010_599_608_464_297).abs() < 1e-12);
    assert!((at(3600.0) - 20.316_060_279_414_28).abs() < 1e-12);
    // The truth's reference temperature is the mean of the column over every reading.
    let column: Vec<f64> = set
        .readings
        .iter()
        .map(|r| r.temperature_celsius.unwrap())
        .collect();
    let mean = column.iter().sum::<f64>() / column.len() as f64;
    let reference = truth.reference_temperature_celsius.expect("a reference");
    assert!((reference - mean).abs() < 1e-12, "{reference} vs {mean}");
    assert!(reference > 20.1 && reference < 20.5, "{reference}");

    // Switching the model on changes neither the truth's other values nor the readings.
    let (without, truth0) = simulate(&SimulationConfig {
        temperature: None,
        ..config.clone()
    })
    .unwrap();
    assert_eq!(bits(&without), bits(&set));
    assert_eq!(truth0.reference_temperature_celsius, None);
    assert_eq!(truth0.pitch_deviation, truth.pitch_deviation);
    assert_eq!(truth0.setup_error, truth.setup_error);
}

#[test]
fn temperature_noise_is_white_and_shared_by_a_stop() {
    let model = TemperatureModel {
        noise_celsius: 0.01,
        ..air_conditioned_lab()
    };
    let config = SimulationConfig {
        cycles: 200,
        temperature: Some(model.clone()),
        ..SimulationConfig::default()
    };
    let (set, truth) = simulate(&config).unwrap();
    let residuals: Vec<f64> = set
        .readings
        .chunks(2)
        .map(|pair| {
            assert_eq!(pair[0].temperature_celsius, pair[1].temperature_celsius);
            let t = pair[0].time_seconds.unwrap();
            pair[0].temperature_celsius.unwrap() - model.celsius_at(t)
        })
        .collect();
    let n = residuals.len() as f64;
    assert_eq!(residuals.len(), 200 * 25);
    let mean = residuals.iter().sum::<f64>() / n;
    let sd = (residuals.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    assert!((sd / 0.01 - 1.0).abs() < 0.05, "sd {sd}");
    assert!(mean.abs() < 4.0 * 0.01 / n.sqrt(), "mean {mean}");
    // The reference is still the column mean, noise included.
    let column_mean = set
        .readings
        .iter()
        .map(|r| r.temperature_celsius.unwrap())
        .sum::<f64>()
        / set.readings.len() as f64;
    assert!((truth.reference_temperature_celsius.unwrap() - column_mean).abs() < 1e-12);
    // The X readings are those of the run without a temperature model.
    let (plain, _) = simulate(&SimulationConfig {
        temperature: None,
        ..config
    })
    .unwrap();
    assert_eq!(bits(&plain), bits(&set));
}

#[test]
fn a_temperature_effect_acts_against_the_mean_temperature() {
    let base = SimulationConfig {
        step_seconds: 120.0,
        temperature: Some(air_conditioned_lab()),
        ..effect_base()
    };
    let (plain, _) = simulate(&base).unwrap();
    let temperatures: Vec<f64> = plain
        .readings
        .iter()
        .map(|r| r.temperature_celsius.unwrap())
        .collect();
    let mean = temperatures.iter().sum::<f64>() / temperatures.len() as f64;
    let effect = Effect::Temperature { ac: 1, value: 0.3 };
    check_effect(&base, effect, |r| {
        if r.ac == 1 {
            0.3 * (r.temperature_celsius.unwrap() - mean)
        } else {
            0.0
        }
    });
    // At time 0 (20 °C) the effect is 0.3 · (20 − mean).
    let (warm, _) = simulate(&SimulationConfig {
        effects: vec![Effect::Temperature { ac: 1, value: 0.3 }],
        ..base
    })
    .unwrap();
    let diff = warm.readings[0].reading_arcsec - plain.readings[0].reading_arcsec;
    assert!((diff - 0.3 * (20.0 - mean)).abs() < 1e-12);
    assert!(diff < 0.0, "the lab warms, so the start is below the mean");
}

#[test]
fn temperature_at_hand_computed_times() {
    let m = air_conditioned_lab();
    assert_eq!(m.celsius_at(0.0), 20.0);
    assert!((m.celsius_at(300.0) - 20.139_977_792_685_34).abs() < 1e-12);
    assert!((m.celsius_at(3600.0) - 20.316_060_279_414_28).abs() < 1e-12);
}
