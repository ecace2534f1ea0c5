//! Tests of the simulator against hand-derived expectations.

use std::path::PathBuf;

use polycal::effects::{Effect, EffectContext};
use polycal::simulate::{
    Harmonic, SimulateError, SimulationConfig, Truth, simulate, simulate_with_truth,
};
use polycal::{Direction, MeasurementSet, Reading};

/// φ[f] = β[1] + … + β[f], summed by hand from the truth's β.
fn phi(truth: &Truth, f: usize) -> f64 {
    let mut s = 0.0;
    for k in 1..=f {
        s += truth.pitch_deviation[k - 1];
    }
    s
}

fn u(truth: &Truth, setup: u32, ac: u32) -> f64 {
    truth
        .setup_error
        .iter()
        .find(|e| e.setup == setup && e.ac == ac)
        .expect("setup error present")
        .value
}

fn noise_free(faces: usize) -> SimulationConfig {
    SimulationConfig {
        faces,
        noise_arcsec: 0.0,
        ..SimulationConfig::default()
    }
}

fn temp_file(name: &str, contents: &str) -> PathBuf {
    let path = std::env::temp_dir().join(format!(
        "polycal-test-simulate-{}-{name}",
        std::process::id()
    ));
    std::fs::write(&path, contents).unwrap();
    path
}

fn bits(set: &MeasurementSet) -> Vec<u64> {
    set.readings
        .iter()
        .map(|r| r.reading_arcsec.to_bits())
        .collect()
}

// ---------------------------------------------------------------- the paper's equations

#[test]
fn paper_design_four_faces_matches_equations_4_and_5_exactly() {
    let config = noise_free(4);
    let (set, truth) = simulate(&config).unwrap();
    let n = 4;
    assert_eq!(set.faces, n);
    assert_eq!(set.source, "simulated");
    assert_eq!(set.readings.len(), 6 * (n + 1) * 2);
    let (u1, u2) = (u(&truth, 1, 1), u(&truth, 1, 2));
    let a = &truth.encoder_error;

    let mut rows = set.readings.iter();
    for cycle in 1..=6 {
        for p in 0..=n {
            // ac 1 reads face p+1 (wrapping): α[p] + φ[p+1] + U1, eq. (4).
            let r = rows.next().unwrap();
            assert_eq!((r.setup, r.cycle, r.step, r.ac), (1, cycle, p, 1));
            assert_eq!(r.face, p % n + 1);
            assert_eq!(r.reading_arcsec, a[p % n] + phi(&truth, p % n + 1) + u1);
            // ac 2 reads face p+2 (wrapping): α[p] + φ[(p+1) mod N + 1] + U2, eq. (5).
            let r = rows.next().unwrap();
            assert_eq!((r.setup, r.cycle, r.step, r.ac), (1, cycle, p, 2));
            let f2 = (p + 1) % n + 1;
            assert_eq!(r.face, f2);
            assert_eq!(r.reading_arcsec, a[p % n] + phi(&truth, f2) + u2);
        }
    }
    assert!(rows.next().is_none());

    // Equation (5) in the paper's own gauge, U2(paper) = U2 + β1:
    // ε(i,2) = α + β2 + … + β(i+1) + U2(paper) for i < N, and α(last) + Σβ + U2(paper).
    let b = &truth.pitch_deviation;
    let u2_paper = u2 + b[0];
    for r in set.readings.iter().filter(|r| r.ac == 2 && r.step < n) {
        let p = r.step;
        let sum: f64 = if p < n - 1 {
            b[1..=p + 1].iter().sum()
        } else {
            b.iter().sum()
        };
        assert!((r.reading_arcsec - (a[p] + sum + u2_paper)).abs() < 1e-12);
    }
    // Equation (6): the last difference is U2(paper) − U1.
    let last = |ac| {
        set.readings
            .iter()
            .find(|r| r.cycle == 1 && r.step == n - 1 && r.ac == ac)
            .unwrap()
            .reading_arcsec
    };
    assert!((last(2) - last(1) - (u2_paper - u1)).abs() < 1e-12);
}

#[test]
fn truth_closures_lengths_and_harmonics() {
    for faces in [3, 4, 7, 24, 36] {
        let config = SimulationConfig {
            faces,
            setups: 2,
            ..SimulationConfig::default()
        };
        let truth = Truth::draw(&config).unwrap();
        assert_eq!(truth.faces, faces);
        assert_eq!(truth.pitch_deviation.len(), faces);
        assert_eq!(truth.encoder_error.len(), faces);
        assert_eq!(truth.face_deviation.len(), faces);
        assert_eq!(truth.setup_error.len(), 2 * 2);
        assert!(truth.pitch_deviation.iter().sum::<f64>().abs() < 1e-12);
        assert!(truth.encoder_error.iter().sum::<f64>().abs() < 1e-12);
        assert!(truth.face_deviation[faces - 1].abs() < 1e-12);
        for f in 1..=faces {
            assert!((truth.face_deviation[f - 1] - phi(&truth, f)).abs() < 1e-12);
        }
        // α from the harmonics by hand, minus the mean.
        let raw: Vec<f64> = (0..faces)
            .map(|p| {
                config
                    .encoder_harmonics
                    .iter()
                    .map(|h| {
                        h.amplitude_arcsec
                            * (2.0 * std::f64::consts::PI * h.order as f64 * p as f64
                                / faces as f64
                                + h.phase_rad)
                                .cos()
                    })
                    .sum()
            })
            .collect();
        let mean = raw.iter().sum::<f64>() / faces as f64;
        for (alpha, raw) in truth.encoder_error.iter().zip(&raw) {
            assert!((alpha - (raw - mean)).abs() < 1e-12);
        }
        assert_eq!(truth.noise_arcsec, Some(config.noise_arcsec));
        let pairs: Vec<(u32, u32)> = truth.setup_error.iter().map(|e| (e.setup, e.ac)).collect();
        assert_eq!(pairs, vec![(1, 1), (1, 2), (2, 1), (2, 2)]);
    }
}

#[test]
fn default_is_the_papers_design() {
    let c = SimulationConfig::default();
    assert_eq!(c.faces, 24);
    assert_eq!(c.ac_faces, vec![1, 2]);
    assert_eq!((c.setups, c.setup_shift_faces, c.cycles), (1, 1, 6));
    assert!(c.closing && !c.bidirectional);
    assert_eq!(c.noise_arcsec, 0.05);
    assert_eq!(c.step_seconds, 20.0);
    assert!(c.effects.is_empty());
    assert_eq!(c.seed, 1);
    let truth = Truth::draw(&c).unwrap();
    let max = truth
        .encoder_error
        .iter()
        .fold(0.0f64, |m, a| m.max(a.abs()));
    assert!((0.5..1.5).contains(&max), "encoder error peak {max}");
    assert_eq!(simulate(&c).unwrap().0.readings.len(), 6 * 25 * 2);
}

// ---------------------------------------------------------------- run structure

#[test]
fn faces_per_setup_follow_the_shift() {
    let config = SimulationConfig {
        faces: 24,
        ac_faces: vec![1, 2, 9],
        setups: 3,
        setup_shift_faces: 5,
        cycles: 2,
        ..noise_free(24)
    };
    let (set, _) = simulate(&config).unwrap();
    assert_eq!(set.readings.len(), 3 * 2 * 25 * 3);
    for r in &set.readings {
        let f0 = [1, 2, 9][r.ac as usize - 1];
        let expected = ((f0 - 1) + (r.setup as usize - 1) * 5 + r.step) % 24 + 1;
        assert_eq!(r.face, expected, "{r:?}");
    }
    let face = |setup, ac, step| {
        set.readings
            .iter()
            .find(|r| r.setup == setup && r.ac == ac && r.step == step)
            .unwrap()
            .face
    };
    assert_eq!(face(1, 1, 0), 1);
    assert_eq!(face(1, 2, 23), 1);
    assert_eq!(face(2, 1, 0), 6);
    assert_eq!(face(3, 2, 23), 11);
    assert_eq!(face(3, 3, 24), 19); // closing step reads the same face as step 0
    assert_eq!(face(3, 3, 0), 19);
    // Setups are measured one after the other.
    let setups: Vec<u32> = set.readings.iter().map(|r| r.setup).collect();
    assert!(setups.windows(2).all(|w| w[0] <= w[1]));
}

#[test]
fn bidirectional_cycles_run_counter_clockwise_and_times_increase() {
    let n = 5;
    let config = SimulationConfig {
        faces: n,
        setups: 2,
        cycles: 4,
        closing: false, // implied by bidirectional
        bidirectional: true,
        step_seconds: 7.5,
        ..noise_free(n)
    };
    let (set, _) = simulate(&config).unwrap();
    assert_eq!(set.readings.len(), 2 * 4 * (n + 1) * 2);
    for setup in 1..=2 {
        for cycle in 1..=4u32 {
            let rows: Vec<&Reading> = set
                .readings
                .iter()
                .filter(|r| r.setup == setup && r.cycle == cycle && r.ac == 1)
                .collect();
            let steps: Vec<usize> = rows.iter().map(|r| r.step).collect();
            let (want_steps, want_dir): (Vec<usize>, _) = if cycle % 2 == 0 {
                ((0..=n).rev().collect(), Direction::Ccw)
            } else {
                ((0..=n).collect(), Direction::Cw)
            };
            assert_eq!(steps, want_steps);
            assert!(rows.iter().all(|r| r.direction == want_dir));
        }
    }
    // Stop k is at k · step_seconds, both autocollimators at one stop share it, rows by
    // time then ac.
    for (i, pair) in set.readings.chunks(2).enumerate() {
        assert_eq!(pair[0].ac, 1);
        assert_eq!(pair[1].ac, 2);
        assert_eq!(pair[0].step, pair[1].step);
        assert_eq!(pair[0].time_seconds, Some(i as f64 * 7.5));
        assert_eq!(pair[1].time_seconds, Some(i as f64 * 7.5));
    }
    let times: Vec<f64> = set
        .readings
        .iter()
        .map(|r| r.time_seconds.unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]));
    for r in &set.readings {
        assert_eq!(r.encoder_degrees, Some(r.step as f64 * 360.0 / n as f64));
        assert_eq!(r.reading_y_arcsec, None);
        assert_eq!(r.temperature_celsius, None);
        assert_eq!(r.line, 0);
    }
}

#[test]
fn row_counts() {
    let cases = [
        (24, vec![1, 2], 1, 6, true, false, 6 * 25 * 2),
        (24, vec![1, 2], 1, 6, false, false, 6 * 24 * 2),
        (12, vec![1, 2, 3], 2, 3, false, false, 2 * 3 * 12 * 3),
        (12, vec![1, 7], 3, 4, false, true, 3 * 4 * 13 * 2),
        (8, vec![3], 1, 1, true, true, 9),
    ];
    for (faces, ac_faces, setups, cycles, closing, bidirectional, want) in cases {
        let config = SimulationConfig {
            faces,
            ac_faces,
            setups,
            cycles,
            closing,
            bidirectional,
            ..SimulationConfig::default()
        };
        assert_eq!(config.reading_count(), want);
        let (set, _) = simulate(&config).unwrap();
        assert_eq!(set.readings.len(), want);
        // Every face and every step 0 … N−1 is present.
        for f in 1..=faces {
            assert!(set.readings.iter().any(|r| r.face == f));
        }
        for p in 0..faces {
            assert!(set.readings.iter().any(|r| r.step == p));
        }
        let has_closing = set.readings.iter().any(|r| r.step == faces);
        assert_eq!(has_closing, closing || bidirectional);
    }
}

// ---------------------------------------------------------------- effects

/// Simulates `base` noise-free with and without `effect` (both via the config and via a
/// truth), and checks reading by reading that the difference is `expected(reading)`:
/// bit-identical where it is 0.
fn check_effect(base: &SimulationConfig, effect: Effect, expected: impl Fn(&Reading) -> f64) {
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
        assert_eq!(
            effect.regressor(a, &EffectContext::default()) * effect.value(),
            want,
            "{effect:?} {a:?}"
        );
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

fn effect_base() -> SimulationConfig {
    SimulationConfig {
        faces: 6,
        setups: 2,
        cycles: 4,
        bidirectional: true,
        step_seconds: 30.0,
        ..noise_free(6)
    }
}

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

// ---------------------------------------------------------------- reproducibility and noise

#[test]
fn same_seed_same_output_different_seed_different_output() {
    let config = SimulationConfig {
        setups: 2,
        bidirectional: true,
        effects: vec![Effect::Drift {
            ac: 1,
            value: 0.1,
            quadratic: None,
        }],
        ..SimulationConfig::default()
    };
    let (a, ta) = simulate(&config).unwrap();
    let (b, tb) = simulate(&config).unwrap();
    assert_eq!(a, b);
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(ta.to_json_pretty(), tb.to_json_pretty());

    let other = SimulationConfig {
        seed: 2,
        ..config.clone()
    };
    let (c, tc) = simulate(&other).unwrap();
    assert_ne!(bits(&a), bits(&c));
    assert_ne!(ta.to_json_pretty(), tc.to_json_pretty());
    assert_ne!(ta.pitch_deviation, tc.pitch_deviation);

    // simulate = draw + simulate_with_truth.
    let truth = Truth::draw(&config).unwrap();
    assert_eq!(truth, ta);
    assert_eq!(simulate_with_truth(&config, &truth).unwrap(), a);
}

#[test]
fn noise_has_the_configured_spread() {
    let config = SimulationConfig {
        cycles: 300,
        noise_arcsec: 0.05,
        ..SimulationConfig::default()
    };
    let (set, truth) = simulate(&config).unwrap();
    let res: Vec<f64> = set
        .readings
        .iter()
        .map(|r| r.reading_arcsec - truth.model_reading(r))
        .collect();
    let n = res.len() as f64;
    assert_eq!(res.len(), 300 * 25 * 2);
    let mean = res.iter().sum::<f64>() / n;
    let sd = (res.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    assert!((sd / 0.05 - 1.0).abs() < 0.03, "sd {sd}");
    assert!(mean.abs() < 4.0 * 0.05 / n.sqrt(), "mean {mean}");

    // Redrawing the noise with one truth: same model, different noise.
    let small = SimulationConfig {
        noise_arcsec: 0.05,
        ..noise_free(24)
    };
    let truth = Truth::draw(&small).unwrap();
    let runs: Vec<MeasurementSet> = (10..13)
        .map(|seed| {
            simulate_with_truth(
                &SimulationConfig {
                    seed,
                    ..small.clone()
                },
                &truth,
            )
            .unwrap()
        })
        .collect();
    assert_ne!(bits(&runs[0]), bits(&runs[1]));
    assert_ne!(bits(&runs[1]), bits(&runs[2]));
    for run in &runs {
        for r in &run.readings {
            assert!((r.reading_arcsec - truth.model_reading(r)).abs() < 0.05 * 6.0);
        }
    }
}

// ---------------------------------------------------------------- truth file

#[test]
fn truth_json_round_trip() {
    let config = SimulationConfig {
        setups: 2,
        bidirectional: true,
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.1,
                quadratic: None,
            },
            Effect::Direction {
                ac: None,
                value: 0.2,
            },
            Effect::Outlier {
                cycle: 2,
                step: 3,
                ac: 2,
                setup: Some(1),
                value: 1.5,
            },
        ],
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&config).unwrap();
    let json = truth.to_json_pretty();
    let back: Truth = serde_json::from_str(&json).unwrap();
    assert_eq!(back, truth);
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(value["faces"], 24);
    assert_eq!(value["pitch_deviation"].as_array().unwrap().len(), 24);
    assert_eq!(value["encoder_error"].as_array().unwrap().len(), 24);
    assert_eq!(
        value["effects"][1],
        serde_json::json!({"kind": "direction", "value": 0.2})
    );

    let path = temp_file("roundtrip.json", &json);
    let read = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(read, truth);
}

#[test]
fn minimal_truth_file_and_effect_json() {
    let path = temp_file(
        "minimal.json",
        r#"{"faces": 3, "pitch_deviation": [0.5, -0.25, -0.25], "encoder_error": [0.1, 0.2, -0.3],
            "effects": [{"kind": "offset-step", "ac": 2, "cycle": 4, "value": 0.5, "u": 0.01}],
            "comment": "extra fields are fine"}"#,
    );
    let truth = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(truth.face_deviation, vec![0.5, 0.25, 0.0]);
    assert!(truth.setup_error.is_empty());
    assert_eq!(truth.noise_arcsec, None);
    assert_eq!(
        truth.effects,
        vec![Effect::OffsetStep {
            ac: 2,
            cycle: 4,
            step: None,
            setup: None,
            value: 0.5
        }]
    );
    assert_eq!(
        serde_json::to_string(&truth.effects[0]).unwrap(),
        r#"{"kind":"offset-step","ac":2,"cycle":4,"value":0.5}"#
    );
    let outlier = Effect::Outlier {
        cycle: 1,
        step: 2,
        ac: 1,
        setup: None,
        value: 3.0,
    };
    assert_eq!(
        serde_json::to_string(&outlier).unwrap(),
        r#"{"kind":"outlier","cycle":1,"step":2,"ac":1,"value":3.0}"#
    );

    // model_reading with no setup errors: α + φ; a face outside 1 … N gives NaN.
    let mut r = Reading {
        setup: 1,
        cycle: 1,
        step: 4,
        ac: 1,
        face: 2,
        reading_arcsec: 0.0,
        direction: Direction::Cw,
        time_seconds: None,
        reading_y_arcsec: None,
        temperature_celsius: None,
        encoder_degrees: None,
        line: 0,
    };
    assert_eq!(truth.model_reading(&r), 0.2 + 0.25);
    r.face = 4;
    assert!(truth.model_reading(&r).is_nan());
}

#[test]
fn bad_truth_files_are_refused_naming_the_file() {
    let missing = std::env::temp_dir().join("polycal-test-simulate-does-not-exist.json");
    let err = Truth::read_path(&missing).unwrap_err();
    assert!(matches!(err, SimulateError::Io { .. }));
    assert!(err.to_string().contains("does-not-exist.json"), "{err}");

    let cases = [
        (
            "syntax.json",
            "{\"faces\": 3,\n \"pitch_deviation\": [1, 2,,]}",
            "syntax.json:2:27:",
        ),
        (
            "missing.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0]}"#,
            "encoder_error",
        ),
        (
            "null.json",
            r#"{"faces": 3, "pitch_deviation": [0, null, 0], "encoder_error": [0, 0, 0]}"#,
            "null.json:1:",
        ),
        (
            "length.json",
            r#"{"faces": 4, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0, 0]}"#,
            "pitch_deviation has 3 values",
        ),
        (
            "facelen.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0], "face_deviation": [0]}"#,
            "face_deviation",
        ),
        (
            "faces.json",
            r#"{"faces": 2, "pitch_deviation": [0, 0], "encoder_error": [0, 0]}"#,
            "faces",
        ),
        (
            "huge.json",
            r#"{"faces": 3, "pitch_deviation": [0, 1e999, 0], "encoder_error": [0, 0, 0]}"#,
            "",
        ),
        (
            "setup.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0],
                "setup_error": [{"setup": 1, "ac": 1, "value": 0}, {"setup": 1, "ac": 1, "value": 1}]}"#,
            "twice",
        ),
        (
            "effect.json",
            r#"{"faces": 3, "pitch_deviation": [0, 0, 0], "encoder_error": [0, 0, 0],
                "effects": [{"kind": "wobble", "value": 1}]}"#,
            "wobble",
        ),
        ("empty.json", "", "empty.json:1"),
    ];
    for (name, text, needle) in cases {
        let path = temp_file(name, text);
        let err = Truth::read_path(&path).unwrap_err();
        std::fs::remove_file(&path).ok();
        let msg = err.to_string();
        assert!(msg.contains(name), "{msg:?} lacks the file name");
        assert!(msg.contains(needle), "{msg:?} lacks {needle:?}");
    }
}

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
        ("drift", "1:2:3"),
        ("drift", "0:0.3"),
        ("drift", "-1:0.3"),
        ("drift", "x:0.3"),
        ("drift", "1:abc"),
        ("drift", "1:NaN"),
        ("drift", "1:inf"),
        ("offset-step", "1:0.5"),
        ("offset-step", "1:0:0.5"),
        ("offset-step", "1:1.5:0.5"),
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

/// A truth file that is not JSON is refused with its file, line and column.
#[test]
fn a_bad_truth_file_is_refused_with_line_and_column() {
    let path = std::env::temp_dir().join(format!("polycal-bad-truth-{}.json", std::process::id()));
    std::fs::write(&path, "{\"faces\": 24,\n \"pitch_deviation\": [1,2,}").unwrap();
    let err = polycal::simulate::Truth::read_path(&path).unwrap_err();
    let _ = std::fs::remove_file(&path);
    assert_eq!(
        err.to_string(),
        format!(
            "{}:2:26: not a valid truth file: expected value",
            path.display()
        )
    );
}
