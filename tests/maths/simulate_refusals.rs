//! Tests of the simulator against hand-derived expectations: the settings it refuses,
//! naming what is wrong — faces, autocollimators, setups and their shift, cycles, noise
//! and spreads, step time, harmonic orders, the number of readings; the additions (the
//! models, the effects acting through them, curved drift, offset steps at a stop or in
//! one setup, Student-t noise) that do not fit the run — and the truths
//! `simulate_with_truth` refuses: one of another polygon, one without what its effects
//! act through.

use polycal::effects::Effect;
use polycal::simulate::{
    ElevationModel, Harmonic, SimulateError, SimulationConfig, TemperatureModel, Truth, simulate,
    simulate_with_truth,
};

use crate::simulate_support::{air_conditioned_lab, noise_free};

// ---------------------------------------------------------------- configuration

#[test]
fn invalid_configurations_are_refused() {
    let d = SimulationConfig::default;
    let cases: Vec<(SimulationConfig, &str)> = vec![
        (SimulationConfig { faces: 2, ..d() }, "faces"),
        (SimulationConfig { faces: 0, ..d() }, "faces"),
        (
            SimulationConfig {
                ac_faces: vec![],
                ..d()
            },
            "autocollimator",
        ),
        (
            SimulationConfig {
                ac_faces: vec![0, 1],
                ..d()
            },
            "face 0",
        ),
        (
            SimulationConfig {
                ac_faces: vec![1, 25],
                ..d()
            },
            "face 25",
        ),
        (
            SimulationConfig {
                ac_faces: vec![2, 2],
                ..d()
            },
            "face 2",
        ),
        (SimulationConfig { setups: 0, ..d() }, "setups"),
        (
            SimulationConfig {
                setup_shift_faces: 24,
                ..d()
            },
            "shift",
        ),
        (SimulationConfig { cycles: 0, ..d() }, "cycles"),
        (
            SimulationConfig {
                noise_arcsec: -0.1,
                ..d()
            },
            "noise",
        ),
        (
            SimulationConfig {
                noise_arcsec: f64::NAN,
                ..d()
            },
            "noise",
        ),
        (
            SimulationConfig {
                pitch_spread_arcsec: f64::INFINITY,
                ..d()
            },
            "pitch",
        ),
        (
            SimulationConfig {
                setup_error_spread_arcsec: -1.0,
                ..d()
            },
            "setup error",
        ),
        (
            SimulationConfig {
                step_seconds: 0.0,
                ..d()
            },
            "step time",
        ),
        (
            SimulationConfig {
                encoder_harmonics: vec![Harmonic {
                    order: 0,
                    amplitude_arcsec: 1.0,
                    phase_rad: 0.0,
                }],
                ..d()
            },
            "order 0",
        ),
        (
            SimulationConfig {
                cycles: u32::MAX,
                ..d()
            },
            "readings",
        ),
    ];
    for (config, needle) in cases {
        let err = simulate(&config).unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, SimulateError::Config(_)), "{text}");
        assert!(text.contains(needle), "{text:?} lacks {needle:?}");
        assert!(Truth::draw(&config).is_err());
    }
}

#[test]
fn simulate_with_truth_refuses_a_truth_of_another_polygon() {
    let truth = Truth::draw(&noise_free(6)).unwrap();
    let err = simulate_with_truth(&noise_free(8), &truth).unwrap_err();
    assert!(err.to_string().contains("6 faces"), "{err}");
    let mut broken = truth.clone();
    broken.encoder_error.pop();
    assert!(simulate_with_truth(&noise_free(6), &broken).is_err());
}

// ---------------------------------------------------------------- validation of the additions

#[test]
fn additions_that_do_not_fit_the_run_are_refused() {
    let base = SimulationConfig {
        faces: 6,
        cycles: 3,
        closing: false,
        setups: 2,
        ..noise_free(6)
    };
    let with = |effect: Effect| SimulationConfig {
        effects: vec![effect],
        ..base.clone()
    };
    let cases: Vec<(SimulationConfig, &str)> = vec![
        (
            with(Effect::Temperature { ac: 1, value: 0.1 }),
            "temperature model",
        ),
        (
            with(Effect::CrossTalk { ac: 1, value: 0.1 }),
            "elevation model",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel::default()),
                ..with(Effect::Temperature { ac: 3, value: 0.1 })
            },
            "autocollimator 3",
        ),
        (
            with(Effect::Drift {
                ac: 1,
                value: 0.1,
                quadratic: Some(f64::INFINITY),
            }),
            "quadratic",
        ),
        (
            with(Effect::OffsetStep {
                ac: 1,
                cycle: 2,
                step: Some(6), // no closing reading: steps 0 … 5
                setup: None,
                value: 0.1,
            }),
            "no step 6",
        ),
        (
            with(Effect::OffsetStep {
                ac: 1,
                cycle: 2,
                step: Some(1),
                setup: Some(3),
                value: 0.1,
            }),
            "no setup 3",
        ),
        (
            with(Effect::OffsetStep {
                ac: 1,
                cycle: 2,
                step: None,
                setup: Some(0),
                value: 0.1,
            }),
            "no setup 0",
        ),
        (
            SimulationConfig {
                noise_student_dof: Some(2.0),
                ..base.clone()
            },
            "Student",
        ),
        (
            SimulationConfig {
                noise_student_dof: Some(f64::NAN),
                ..base.clone()
            },
            "Student",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel {
                    warmup_seconds: 0.0,
                    ..TemperatureModel::default()
                }),
                ..base.clone()
            },
            "warm-up time",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel {
                    cycle_period_seconds: -60.0,
                    ..TemperatureModel::default()
                }),
                ..base.clone()
            },
            "cycle period",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel {
                    cycle_amplitude_celsius: -0.1,
                    ..TemperatureModel::default()
                }),
                ..base.clone()
            },
            "cycle amplitude",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel {
                    start_celsius: f64::NAN,
                    ..TemperatureModel::default()
                }),
                ..base.clone()
            },
            "start",
        ),
        (
            SimulationConfig {
                temperature: Some(TemperatureModel {
                    noise_celsius: -0.01,
                    ..TemperatureModel::default()
                }),
                ..base.clone()
            },
            "noise",
        ),
        (
            SimulationConfig {
                elevation: Some(ElevationModel {
                    mounting_tilt_arcsec: -1.0,
                    ..ElevationModel::default()
                }),
                ..base.clone()
            },
            "mounting tilt",
        ),
        (
            SimulationConfig {
                elevation: Some(ElevationModel {
                    wobble_phase_rad: f64::INFINITY,
                    ..ElevationModel::default()
                }),
                ..base.clone()
            },
            "wobble phase",
        ),
        (
            SimulationConfig {
                elevation: Some(ElevationModel {
                    pyramidal_spread_arcsec: f64::NAN,
                    ..ElevationModel::default()
                }),
                ..base.clone()
            },
            "pyramidal",
        ),
    ];
    for (config, needle) in cases {
        let err = simulate(&config).unwrap_err();
        let text = err.to_string();
        assert!(matches!(err, SimulateError::Config(_)), "{text}");
        assert!(text.contains(needle), "{text:?} lacks {needle:?}");
    }
    // The step N exists with the closing reading, and a step in setup 2 is fine.
    let ok = SimulationConfig {
        closing: true,
        ..with(Effect::OffsetStep {
            ac: 2,
            cycle: 3,
            step: Some(6),
            setup: Some(2),
            value: 0.1,
        })
    };
    assert!(simulate(&ok).is_ok());
}

#[test]
fn simulate_with_truth_needs_what_its_effects_act_through() {
    let config = SimulationConfig {
        temperature: Some(air_conditioned_lab()),
        elevation: Some(ElevationModel::default()),
        effects: vec![
            Effect::Temperature { ac: 1, value: 0.2 },
            Effect::CrossTalk { ac: 2, value: 0.01 },
        ],
        ..noise_free(6)
    };
    let truth = Truth::draw(&config).unwrap();
    assert!(simulate_with_truth(&config, &truth).is_ok());
    // A temperature effect without the reference it acts against.
    let mut no_reference = truth.clone();
    no_reference.reference_temperature_celsius = None;
    let err = simulate_with_truth(&config, &no_reference).unwrap_err();
    assert!(
        err.to_string().contains("reference_temperature_celsius"),
        "{err}"
    );
    // An elevation model, but a truth without the geometry.
    let mut flat = truth.clone();
    flat.elevation = None;
    let err = simulate_with_truth(&config, &flat).unwrap_err();
    assert!(err.to_string().contains("elevation"), "{err}");
    // Settings without the models refuse the truth's effects.
    let bare = SimulationConfig {
        temperature: None,
        elevation: None,
        effects: Vec::new(),
        ..config.clone()
    };
    assert!(simulate_with_truth(&bare, &truth).is_err());
    // A broken geometry is refused by the truth's own check.
    let mut short = truth.clone();
    short
        .elevation
        .as_mut()
        .unwrap()
        .pyramidal_error_arcsec
        .pop();
    assert!(short.validate().is_err());
    let mut dof = truth;
    dof.noise_student_dof = Some(1.0);
    assert!(dof.validate().is_err());
}
