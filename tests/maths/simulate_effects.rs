//! Tests of the simulator against hand-derived expectations: the effects. Each adds
//! exactly its contribution, reading by reading, through the settings and through a
//! truth alike — drift, straight or curved, an offset step from a cycle or from a stop
//! (in time order, in either direction, in one setup or all), a direction offset, an
//! outlier — and an effect naming what the run lacks is refused. An effect's regressor
//! and value, by hand.

use polycal::effects::{Effect, EffectContext};
use polycal::simulate::{SimulateError, SimulationConfig, Truth, simulate, simulate_with_truth};
use polycal::{Direction, MeasurementSet, Reading};

use crate::simulate_support::{check_effect, effect_base, noise_free};

// ---------------------------------------------------------------- effects

#[test]
fn drift_adds_rate_times_hours() {
    let effect = Effect::Drift {
        ac: 2,
        value: 0.3,
        quadratic: None,
    };
    check_effect(&effect_base(), effect, |r| {
        if r.ac == 2 {
            0.3 * (r.time_seconds.unwrap() / 3600.0)
        } else {
            0.0
        }
    });
}

#[test]
fn offset_step_from_its_cycle_on() {
    let effect = Effect::OffsetStep {
        ac: 1,
        cycle: 3,
        step: None,
        setup: None,
        value: 0.5,
    };
    check_effect(&effect_base(), effect, |r| {
        if r.ac == 1 && r.cycle >= 3 { 0.5 } else { 0.0 }
    });
}

#[test]
fn direction_offsets_ccw_cycles() {
    let all = Effect::Direction {
        ac: None,
        value: -0.2,
    };
    check_effect(&effect_base(), all, |r| {
        if r.cycle % 2 == 0 { -0.2 } else { 0.0 }
    });
    let one = Effect::Direction {
        ac: Some(2),
        value: 0.25,
    };
    check_effect(&effect_base(), one, |r| {
        if r.cycle % 2 == 0 && r.ac == 2 {
            0.25
        } else {
            0.0
        }
    });
}

#[test]
fn outlier_hits_exactly_one_reading() {
    let effect = Effect::Outlier {
        cycle: 3,
        step: 6,
        ac: 1,
        setup: Some(2),
        value: 2.0,
    };
    check_effect(&effect_base(), effect.clone(), |r| {
        if (r.setup, r.cycle, r.step, r.ac) == (2, 3, 6, 1) {
            2.0
        } else {
            0.0
        }
    });
    // Without a setup, in a one-setup run.
    let single = SimulationConfig {
        setups: 1,
        ..effect_base()
    };
    let effect = Effect::Outlier {
        cycle: 2,
        step: 0,
        ac: 2,
        setup: None,
        value: -1.5,
    };
    check_effect(&single, effect, |r| {
        if (r.cycle, r.step, r.ac) == (2, 0, 2) {
            -1.5
        } else {
            0.0
        }
    });
}

#[test]
fn effects_naming_what_the_run_lacks_are_refused() {
    let base = SimulationConfig {
        faces: 6,
        cycles: 3,
        closing: false,
        ..noise_free(6)
    };
    let bad = [
        Effect::Drift {
            ac: 3,
            value: 0.1,
            quadratic: None,
        },
        Effect::Drift {
            ac: 0,
            value: 0.1,
            quadratic: None,
        },
        Effect::Drift {
            ac: 1,
            value: f64::NAN,
            quadratic: None,
        },
        Effect::OffsetStep {
            ac: 1,
            cycle: 4,
            step: None,
            setup: None,
            value: 0.1,
        },
        Effect::OffsetStep {
            ac: 1,
            cycle: 0,
            step: None,
            setup: None,
            value: 0.1,
        },
        Effect::Direction {
            ac: None,
            value: 0.1,
        }, // no ccw cycle
        Effect::Outlier {
            cycle: 1,
            step: 6, // no closing reading
            ac: 1,
            setup: None,
            value: 1.0,
        },
        Effect::Outlier {
            cycle: 1,
            step: 2,
            ac: 1,
            setup: Some(2),
            value: 1.0,
        },
    ];
    for e in bad {
        let config = SimulationConfig {
            effects: vec![e.clone()],
            ..base.clone()
        };
        let err = simulate(&config).unwrap_err();
        assert!(matches!(err, SimulateError::Config(_)), "{e:?}: {err}");
        // The same effect in a truth is refused by simulate_with_truth.
        let mut truth = Truth::draw(&base).unwrap();
        truth.effects = vec![e.clone()];
        assert!(simulate_with_truth(&base, &truth).is_err(), "{e:?}");
    }
    // Step N exists with the closing reading.
    let ok = SimulationConfig {
        closing: true,
        effects: vec![Effect::Outlier {
            cycle: 3,
            step: 6,
            ac: 2,
            setup: None,
            value: 1.0,
        }],
        ..base.clone()
    };
    assert!(simulate(&ok).is_ok());
    // Several setups: an outlier must say which.
    let multi = SimulationConfig {
        setups: 2,
        effects: vec![Effect::Outlier {
            cycle: 1,
            step: 1,
            ac: 1,
            setup: None,
            value: 1.0,
        }],
        ..base.clone()
    };
    assert!(simulate(&multi).is_err());
}

// ---------------------------------------------------------------- curved drift, steps at a stop

#[test]
fn curved_drift_adds_rate_times_hours_plus_quadratic_times_hours_squared() {
    let base = SimulationConfig {
        step_seconds: 60.0,
        ..effect_base()
    };
    let effect = Effect::Drift {
        ac: 2,
        value: 0.3,
        quadratic: Some(-0.1),
    };
    check_effect(&base, effect.clone(), |r| {
        if r.ac == 2 {
            let h = r.time_seconds.unwrap() / 3600.0;
            0.3 * h - 0.1 * h * h
        } else {
            0.0
        }
    });
    // At t = 1800 s (stop 30 at 60 s a stop): 0.3 · 0.5 + (−0.1) · 0.25 = 0.125.
    let (plain, _) = simulate(&base).unwrap();
    let (drifting, _) = simulate(&SimulationConfig {
        effects: vec![effect],
        ..base.clone()
    })
    .unwrap();
    let row = 30 * 2 + 1; // stop 30, autocollimator 2
    assert_eq!(plain.readings[row].time_seconds, Some(1800.0));
    assert_eq!(plain.readings[row].ac, 2);
    let diff = drifting.readings[row].reading_arcsec - plain.readings[row].reading_arcsec;
    assert!((diff - 0.125).abs() < 1e-12, "{diff}");
}

/// The time of the reading of (setup, cycle, step, ac) in a run.
fn time_of(set: &MeasurementSet, setup: u32, cycle: u32, step: usize, ac: u32) -> f64 {
    set.readings
        .iter()
        .find(|r| (r.setup, r.cycle, r.step, r.ac) == (setup, cycle, step, ac))
        .and_then(|r| r.time_seconds)
        .expect("the reading exists")
}

#[test]
fn offset_step_at_a_stop_follows_time_order_in_both_directions() {
    let base = effect_base(); // 2 setups, 4 cycles, even cycles counter-clockwise
    let (plain, _) = simulate(&base).unwrap();
    // Cycle 2 runs steps 6, 5, 4, …, 0: from step 4 on in time order are steps 4 … 0.
    let ccw = Effect::OffsetStep {
        ac: 1,
        cycle: 2,
        step: Some(4),
        setup: None,
        value: 0.5,
    };
    let t0 = |setup| time_of(&plain, setup, 2, 4, 1);
    check_effect(&base, ccw, |r| {
        if r.ac == 1 && r.time_seconds.unwrap() >= t0(r.setup) {
            0.5
        } else {
            0.0
        }
    });
    // The same by hand from the direction: cycle 2 steps 0 … 4, cycles 3 and 4.
    for r in &plain.readings {
        let by_hand = r.ac == 1 && (r.cycle > 2 || (r.cycle == 2 && r.step <= 4));
        assert_eq!(r.ac == 1 && r.time_seconds.unwrap() >= t0(r.setup), by_hand);
    }
    // A clockwise cycle (3): steps 2 … 6 of cycle 3, and cycle 4.
    let cw = Effect::OffsetStep {
        ac: 2,
        cycle: 3,
        step: Some(2),
        setup: None,
        value: -0.7,
    };
    check_effect(&base, cw, |r| {
        if r.ac == 2 && (r.cycle == 4 || (r.cycle == 3 && r.step >= 2)) {
            -0.7
        } else {
            0.0
        }
    });
}

#[test]
fn a_setup_limited_offset_step_leaves_other_setups_alone() {
    let base = effect_base();
    let (plain, _) = simulate(&base).unwrap();
    let t0 = time_of(&plain, 2, 3, 1, 2);
    let effect = Effect::OffsetStep {
        ac: 2,
        cycle: 3,
        step: Some(1),
        setup: Some(2),
        value: -0.4,
    };
    check_effect(&base, effect, |r| {
        if r.setup == 2 && r.ac == 2 && r.time_seconds.unwrap() >= t0 {
            -0.4
        } else {
            0.0
        }
    });
    // Without a step: the whole of cycles 3 and 4 of setup 1 only.
    let whole = Effect::OffsetStep {
        ac: 1,
        cycle: 3,
        step: None,
        setup: Some(1),
        value: 0.9,
    };
    check_effect(&base, whole, |r| {
        if r.setup == 1 && r.ac == 1 && r.cycle >= 3 {
            0.9
        } else {
            0.0
        }
    });
}

// ---------------------------------------------------------------- an effect's regressor and value

#[test]
fn effect_regressor_and_value() {
    let mut r = Reading {
        setup: 2,
        cycle: 3,
        step: 5,
        ac: 1,
        face: 1,
        reading_arcsec: 0.0,
        direction: Direction::Ccw,
        time_seconds: Some(5400.0),
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line: 0,
    };
    let drift = Effect::Drift {
        ac: 1,
        value: 0.4,
        quadratic: None,
    };
    assert_eq!(drift.regressor(&r, &EffectContext::default()), 1.5);
    assert_eq!(drift.value(), 0.4);
    assert_eq!(drift.clone().with_value(0.7).value(), 0.7);
    let step = Effect::OffsetStep {
        ac: 1,
        cycle: 3,
        step: None,
        setup: None,
        value: 1.0,
    };
    assert_eq!(step.regressor(&r, &EffectContext::default()), 1.0);
    let dir = Effect::Direction {
        ac: Some(2),
        value: 1.0,
    };
    assert_eq!(dir.regressor(&r, &EffectContext::default()), 0.0);
    let out = Effect::Outlier {
        cycle: 3,
        step: 5,
        ac: 1,
        setup: Some(2),
        value: 1.0,
    };
    assert_eq!(out.regressor(&r, &EffectContext::default()), 1.0);
    r.time_seconds = None;
    assert_eq!(drift.regressor(&r, &EffectContext::default()), 0.0);
    r.cycle = 2;
    assert_eq!(step.regressor(&r, &EffectContext::default()), 0.0);
    assert_eq!(out.regressor(&r, &EffectContext::default()), 0.0);
    r.direction = Direction::Cw;
    r.ac = 2;
    assert_eq!(dir.regressor(&r, &EffectContext::default()), 0.0);
}
