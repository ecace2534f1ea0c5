//! Tests of the simulator against hand-derived expectations: the elevation model and the
//! mountings. reading_y is the face's pyramidal error, the mounting's tilt, the table's
//! wobble at the step and the offset of each (setup, autocollimator), plus its noise; the
//! same face read in two mountings differs by their tilts alone; switching the model on
//! changes no X reading; cross-talk adds its coefficient times reading_y.

use polycal::Reading;
use polycal::effects::Effect;
use polycal::simulate::{ElevationModel, SimulationConfig, Truth, simulate};

use crate::simulate_support::{bits, check_effect, effect_base, noise_free};

// ---------------------------------------------------------------- elevation

/// reading_y by hand from the truth's drawn geometry: the pyramidal error of the face,
/// the mounting's tilt, the table's wobble at the step and the (setup, ac) offset.
fn reading_y_by_hand(truth: &Truth, r: &Reading) -> f64 {
    let e = truth.elevation.as_ref().expect("an elevation truth");
    let n = truth.faces as f64;
    let tau = std::f64::consts::TAU;
    let tilt = e
        .mounting_tilt
        .iter()
        .find(|t| t.setup == r.setup)
        .expect("a tilt per mounting");
    let offset = e
        .offset
        .iter()
        .find(|o| o.setup == r.setup && o.ac == r.ac)
        .expect("an offset per (setup, ac)")
        .value;
    e.pyramidal_error_arcsec[r.face - 1]
        + tilt.tilt_arcsec * (tau * (r.face as f64 - 1.0) / n - tilt.azimuth_rad).cos()
        + e.wobble_arcsec * (tau * r.step as f64 / n + e.wobble_phase_rad).cos()
        + offset
}

#[test]
fn reading_y_follows_the_elevation_model() {
    let model = ElevationModel {
        pyramidal_spread_arcsec: 10.0,
        mounting_tilt_arcsec: 30.0,
        wobble_arcsec: 2.0,
        wobble_phase_rad: 0.4,
        offset_spread_arcsec: 5.0,
        noise_arcsec: 0.0,
    };
    let config = SimulationConfig {
        faces: 12,
        setups: 3,
        setup_shift_faces: 5,
        ac_faces: vec![1, 2, 7],
        cycles: 2,
        elevation: Some(model.clone()),
        ..noise_free(12)
    };
    let (set, truth) = simulate(&config).unwrap();
    let e = truth.elevation.as_ref().unwrap();
    assert_eq!(e.pyramidal_error_arcsec.len(), 12);
    assert_eq!(e.mounting_tilt.len(), 3);
    assert_eq!(e.offset.len(), 3 * 3);
    assert_eq!((e.wobble_arcsec, e.wobble_phase_rad), (2.0, 0.4));
    for t in &e.mounting_tilt {
        assert!((0.0..std::f64::consts::TAU).contains(&t.azimuth_rad));
    }
    let mut largest: f64 = 0.0;
    for r in &set.readings {
        let y = r.reading_y_arcsec.expect("a reading_y");
        assert!((y - reading_y_by_hand(&truth, r)).abs() < 1e-12, "{r:?}");
        largest = largest.max(y.abs());
    }
    assert!(largest > 10.0, "tens of arcseconds: {largest}");
    // The X readings are those of the run without an elevation model.
    let (plain, truth0) = simulate(&SimulationConfig {
        elevation: None,
        ..config.clone()
    })
    .unwrap();
    assert_eq!(bits(&plain), bits(&set));
    assert_eq!(truth0.elevation, None);
    assert_eq!(truth0.pitch_deviation, truth.pitch_deviation);

    // Noise: reading_y minus the geometry has the configured spread.
    let noisy = SimulationConfig {
        cycles: 100,
        elevation: Some(ElevationModel {
            noise_arcsec: 0.2,
            ..model
        }),
        ..config
    };
    let (set, truth) = simulate(&noisy).unwrap();
    let res: Vec<f64> = set
        .readings
        .iter()
        .map(|r| r.reading_y_arcsec.unwrap() - reading_y_by_hand(&truth, r))
        .collect();
    let n = res.len() as f64;
    let sd = (res.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
    assert!((sd / 0.2 - 1.0).abs() < 0.03, "sd {sd}");
}

#[test]
fn the_same_face_differs_between_mountings_by_the_tilt() {
    let n = 24;
    let model = ElevationModel {
        pyramidal_spread_arcsec: 10.0,
        mounting_tilt_arcsec: 30.0,
        wobble_arcsec: 0.0,
        wobble_phase_rad: 0.0,
        offset_spread_arcsec: 0.0,
        noise_arcsec: 0.0,
    };
    let config = SimulationConfig {
        faces: n,
        setups: 2,
        setup_shift_faces: 7,
        cycles: 1,
        elevation: Some(model.clone()),
        ..noise_free(n)
    };
    let (set, truth) = simulate(&config).unwrap();
    let y = |setup: u32, face: usize| {
        set.readings
            .iter()
            .find(|r| r.setup == setup && r.ac == 1 && r.face == face)
            .and_then(|r| r.reading_y_arcsec)
            .unwrap()
    };
    let tilts = &truth.elevation.as_ref().unwrap().mounting_tilt;
    let (t1, t2) = (&tilts[0], &tilts[1]);
    let theta = |f: usize| std::f64::consts::TAU * (f - 1) as f64 / n as f64;
    let d: Vec<f64> = (1..=n).map(|f| y(2, f) - y(1, f)).collect();
    for f in 1..=n {
        let tilt_term = t2.tilt_arcsec * (theta(f) - t2.azimuth_rad).cos()
            - t1.tilt_arcsec * (theta(f) - t1.azimuth_rad).cos();
        assert!((d[f - 1] - tilt_term).abs() < 1e-12, "face {f}");
    }
    // Independently of the drawn parameters: the difference is one first harmonic over
    // the faces (the pyramidal errors cancel), a·cos θ + b·sin θ.
    let a = 2.0 / n as f64 * (1..=n).map(|f| d[f - 1] * theta(f).cos()).sum::<f64>();
    let b = 2.0 / n as f64 * (1..=n).map(|f| d[f - 1] * theta(f).sin()).sum::<f64>();
    for f in 1..=n {
        let fit = a * theta(f).cos() + b * theta(f).sin();
        assert!((d[f - 1] - fit).abs() < 1e-9, "face {f}");
    }
    assert!(a.hypot(b) > 1.0, "the mountings tilt differently");

    // Without tilt the same face reads the same Y in every mounting.
    let flat = SimulationConfig {
        elevation: Some(ElevationModel {
            mounting_tilt_arcsec: 0.0,
            ..model
        }),
        ..config
    };
    let (set, _) = simulate(&flat).unwrap();
    for r in set.readings.iter().filter(|r| r.setup == 2) {
        let first = set
            .readings
            .iter()
            .find(|q| q.setup == 1 && q.ac == r.ac && q.face == r.face)
            .unwrap();
        assert_eq!(r.reading_y_arcsec, first.reading_y_arcsec);
    }
}

#[test]
fn cross_talk_adds_its_coefficient_times_reading_y() {
    let base = SimulationConfig {
        elevation: Some(ElevationModel::default()),
        ..effect_base()
    };
    check_effect(&base, Effect::CrossTalk { ac: 2, value: 0.02 }, |r| {
        if r.ac == 2 {
            0.02 * r.reading_y_arcsec.unwrap()
        } else {
            0.0
        }
    });
}
