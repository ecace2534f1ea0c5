//! What the tests of the simulator (`tests/maths/simulate_*.rs`) share: noise-free
//! settings, a run's readings as bits, the check of one effect against the contribution
//! derived by hand and the run it is checked on, and an air-conditioned lab's temperature.

use polycal::effects::{Effect, EffectContext};
use polycal::simulate::{SimulationConfig, TemperatureModel, simulate, simulate_with_truth};
use polycal::{MeasurementSet, Reading};

/// The default settings with `faces` faces and no noise.
pub fn noise_free(faces: usize) -> SimulationConfig {
    SimulationConfig {
        faces,
        noise_arcsec: 0.0,
        ..SimulationConfig::default()
    }
}

/// The readings of a run, bit for bit.
pub fn bits(set: &MeasurementSet) -> Vec<u64> {
    set.readings
        .iter()
        .map(|r| r.reading_arcsec.to_bits())
        .collect()
}

/// Simulates `base` noise-free with and without `effect` (both via the config and via a
/// truth), and checks reading by reading that the difference is `expected(reading)`:
/// bit-identical where it is 0.
pub fn check_effect(base: &SimulationConfig, effect: Effect, expected: impl Fn(&Reading) -> f64) {
    let (plain, truth0) = simulate(base).unwrap();
    let with_cfg = SimulationConfig {
        effects: vec![effect.clone()],
        ..base.clone()
    };
    let (affected, truth1) = simulate(&with_cfg).unwrap();
    assert_eq!(truth1.effects, vec![effect.clone()]);
    assert_eq!(truth1.pitch_deviation, truth0.pitch_deviation);
    assert_eq!(truth1.encoder_error, truth0.encoder_error);
    assert_eq!(truth1.setup_error, truth0.setup_error);
    // The same through simulate_with_truth.
    let again = simulate_with_truth(base, &truth1).unwrap();
    assert_eq!(bits(&again), bits(&affected));

    let mut touched = 0;
    for (a, b) in plain.readings.iter().zip(&affected.readings) {
        assert_eq!(
            (a.setup, a.cycle, a.step, a.ac),
            (b.setup, b.cycle, b.step, b.ac)
        );
        let want = expected(a);
        let context = EffectContext::with_mean_temperature(
            truth1.reference_temperature_celsius.unwrap_or(0.0),
        );
        let code = effect.contribution(a, &context);
        assert!(
            (code - want).abs() < 1e-12,
            "{effect:?} {a:?}: {code} vs {want}"
        );
        // The columns an effect acts through are the same with and without it.
        assert_eq!(a.temperature_celsius, b.temperature_celsius);
        assert_eq!(a.reading_y_arcsec, b.reading_y_arcsec);
        if want == 0.0 {
            assert_eq!(a.reading_arcsec.to_bits(), b.reading_arcsec.to_bits());
        } else {
            touched += 1;
            let diff = b.reading_arcsec - a.reading_arcsec;
            assert!((diff - want).abs() < 1e-12, "{effect:?}: {diff} vs {want}");
        }
        assert!((b.reading_arcsec - truth1.model_reading(b)).abs() < 1e-12);
    }
    assert!(touched > 0);
}

/// The run the effects are checked on: 6 faces, 2 setups, 4 cycles in alternating
/// directions, 30 s a stop, no noise.
pub fn effect_base() -> SimulationConfig {
    SimulationConfig {
        faces: 6,
        setups: 2,
        cycles: 4,
        bidirectional: true,
        step_seconds: 30.0,
        ..noise_free(6)
    }
}

/// A lab at 20 °C warming towards 20.5 °C (time constant an hour), cycling by ±0.1 °C every
/// 20 minutes, without noise: `TemperatureModel::default()`.
pub fn air_conditioned_lab() -> TemperatureModel {
    TemperatureModel {
        start_celsius: 20.0,
        warmup_celsius: 0.5,
        warmup_seconds: 3600.0,
        cycle_amplitude_celsius: 0.1,
        cycle_period_seconds: 1200.0,
        cycle_phase_rad: 0.0,
        noise_celsius: 0.0,
    }
}
