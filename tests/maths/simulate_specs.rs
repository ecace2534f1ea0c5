//! Tests of the simulator against hand-derived expectations: the written forms the
//! command line takes — an effect's (`--drift 1:0.3`, `--offset-step 2:4:7:-0.5`,
//! `--outlier 2:3:0:1:-4`, …), a harmonic's (`--harmonic 2:0.35:1.3`), the temperature
//! and elevation models' (`--temperature 20:0.5:3600:0.1:1200`, `--elevation
//! 10:20:1:5:0.05`): read into their values, refused naming what they are; a harmonic or
//! a model written out reads back the same.

use polycal::effects::Effect;
use polycal::simulate::{ElevationModel, Harmonic, TemperatureModel};

use crate::simulate_support::air_conditioned_lab;

// ---------------------------------------------------------------- parsing

#[test]
fn effect_specs() {
    let good = [
        (
            "drift",
            "1:0.3",
            Effect::Drift {
                ac: 1,
                value: 0.3,
                quadratic: None,
            },
        ),
        (
            "drift",
            " 2 : -1e-2 ",
            Effect::Drift {
                ac: 2,
                value: -0.01,
                quadratic: None,
            },
        ),
        (
            "offset-step",
            "2:4:0.5",
            Effect::OffsetStep {
                ac: 2,
                cycle: 4,
                step: None,
                setup: None,
                value: 0.5,
            },
        ),
        (
            "drift",
            "1:0.3:-0.05",
            Effect::Drift {
                ac: 1,
                value: 0.3,
                quadratic: Some(-0.05),
            },
        ),
        (
            "offset-step",
            "2:4:7:-0.5",
            Effect::OffsetStep {
                ac: 2,
                cycle: 4,
                step: Some(7),
                setup: None,
                value: -0.5,
            },
        ),
        (
            "offset-step",
            "3:2:4:0:0.5",
            Effect::OffsetStep {
                ac: 2,
                cycle: 4,
                step: Some(0),
                setup: Some(3),
                value: 0.5,
            },
        ),
        (
            "temperature",
            "1:0.2",
            Effect::Temperature { ac: 1, value: 0.2 },
        ),
        (
            "temperature",
            "2:-1e-1",
            Effect::Temperature { ac: 2, value: -0.1 },
        ),
        (
            "cross-talk",
            "2:0.01",
            Effect::CrossTalk { ac: 2, value: 0.01 },
        ),
        (
            "direction",
            "0.2",
            Effect::Direction {
                ac: None,
                value: 0.2,
            },
        ),
        (
            "direction",
            "1:-0.2",
            Effect::Direction {
                ac: Some(1),
                value: -0.2,
            },
        ),
        (
            "outlier",
            "3:7:1:2.0",
            Effect::Outlier {
                cycle: 3,
                step: 7,
                ac: 1,
                setup: None,
                value: 2.0,
            },
        ),
        (
            "outlier",
            "2:3:0:1:-4",
            Effect::Outlier {
                cycle: 3,
                step: 0,
                ac: 1,
                setup: Some(2),
                value: -4.0,
            },
        ),
    ];
    for (kind, spec, want) in good {
        let got = Effect::parse_spec(kind, spec).unwrap();
        assert_eq!(got, want);
        assert_eq!(got.kind(), kind);
        assert!(!got.to_string().is_empty());
    }
    let bad = [
        ("drift", ""),
        ("drift", "1"),
        ("drift", "1:2:3:4"),
        ("drift", "1:2:nan"),
        ("drift", "0:0.3"),
        ("drift", "-1:0.3"),
        ("drift", "x:0.3"),
        ("drift", "1:abc"),
        ("drift", "1:NaN"),
        ("drift", "1:inf"),
        ("offset-step", "1:0.5"),
        ("offset-step", "1:0:0.5"),
        ("offset-step", "1:1.5:0.5"),
        ("offset-step", "1:2:-1:0.5"),
        ("offset-step", "1:2:x:0.5"),
        ("offset-step", "0:1:2:3:0.5"),
        ("offset-step", "1:0:2:3:0.5"),
        ("offset-step", "1:2:3:4:5:6"),
        ("offset-step", "1:2:3:inf"),
        ("temperature", "1"),
        ("temperature", "0:0.2"),
        ("temperature", "1:0.2:3"),
        ("temperature", "1:nan"),
        ("cross-talk", ""),
        ("cross-talk", "1:x"),
        ("cross-talk", "1:2:3"),
        ("direction", ""),
        ("direction", "1:2:3"),
        ("direction", "0:0.2"),
        ("outlier", "1:2:3"),
        ("outlier", "1:-2:1:3"),
        ("outlier", "0:2:1:3"),
        ("outlier", "1:2:1:3:4:5"),
        ("outlier", "0:1:2:1:3"),
        ("wobble", "1:2"),
        ("", ""),
        ("drift", "::::"),
        ("drift", "99999999999999999999:1"),
    ];
    for (kind, spec) in bad {
        let err = Effect::parse_spec(kind, spec).unwrap_err();
        assert!(err.message().contains(kind) || kind.is_empty(), "{err}");
    }
    assert!(
        Effect::parse_spec("wobble", "1")
            .unwrap_err()
            .message()
            .contains("offset-step")
    );
}

#[test]
fn harmonic_specs() {
    let h: Harmonic = "2:0.35:1.3".parse().unwrap();
    assert_eq!(
        h,
        Harmonic {
            order: 2,
            amplitude_arcsec: 0.35,
            phase_rad: 1.3
        }
    );
    assert_eq!(h.to_string().parse::<Harmonic>().unwrap(), h);
    let h: Harmonic = "1:0.6".parse().unwrap();
    assert_eq!(h.phase_rad, 0.0);
    let h: Harmonic = " 5 : -0.1 : -0.7 ".parse().unwrap();
    assert_eq!((h.order, h.amplitude_arcsec, h.phase_rad), (5, -0.1, -0.7));
    for bad in [
        "", "1", "0:1", "-1:1", "1.5:1", "a:1", "1:b", "1:1:c", "1:1:1:1", "1:nan", "1:1:inf",
        ":::",
    ] {
        let err = bad.parse::<Harmonic>().unwrap_err();
        assert!(err.message().contains("harmonic"), "{err}");
    }
}

// ---------------------------------------------------------------- the models' specs

#[test]
fn model_specs() {
    let t: TemperatureModel = "20:0.5:3600:0.1:1200".parse().unwrap();
    assert_eq!(t, air_conditioned_lab());
    assert_eq!(t, TemperatureModel::default());
    assert_eq!(t.to_string().parse::<TemperatureModel>().unwrap(), t);
    let t: TemperatureModel = " 18 : -0.2 : 600 : 0.05 : 900 : 1.5 : 0.01 "
        .parse()
        .unwrap();
    assert_eq!(
        t,
        TemperatureModel {
            start_celsius: 18.0,
            warmup_celsius: -0.2,
            warmup_seconds: 600.0,
            cycle_amplitude_celsius: 0.05,
            cycle_period_seconds: 900.0,
            cycle_phase_rad: 1.5,
            noise_celsius: 0.01,
        }
    );
    for bad in [
        "",
        "20",
        "20:0.5:3600:0.1",
        "20:0.5:3600:0.1:1200:0:0:0",
        "20:0.5:0:0.1:1200",
        "20:0.5:3600:0.1:-1",
        "20:0.5:3600:-0.1:1200",
        "20:0.5:3600:0.1:1200:0:-1",
        "x:0.5:3600:0.1:1200",
        "20:nan:3600:0.1:1200",
    ] {
        let err = bad.parse::<TemperatureModel>().unwrap_err();
        assert!(err.to_string().contains("temperature model"), "{err}");
    }
    let e: ElevationModel = "10:20:1:5:0.05".parse().unwrap();
    assert_eq!(e, ElevationModel::default());
    assert_eq!(e.to_string().parse::<ElevationModel>().unwrap(), e);
    let e: ElevationModel = "30:40:2:10:0.1:0.7".parse().unwrap();
    assert_eq!(
        e,
        ElevationModel {
            pyramidal_spread_arcsec: 30.0,
            mounting_tilt_arcsec: 40.0,
            wobble_arcsec: 2.0,
            wobble_phase_rad: 0.7,
            offset_spread_arcsec: 10.0,
            noise_arcsec: 0.1,
        }
    );
    for bad in [
        "",
        "10:20:1:5",
        "10:20:1:5:0.05:0:0",
        "-10:20:1:5:0.05",
        "10:20:1:5:inf",
    ] {
        let err = bad.parse::<ElevationModel>().unwrap_err();
        assert!(err.to_string().contains("elevation model"), "{err}");
    }
}
