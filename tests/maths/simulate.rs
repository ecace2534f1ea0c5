//! Tests of the simulator against hand-derived expectations.

use std::path::PathBuf;

use polycal::effects::{Effect, EffectContext};
use polycal::simulate::{
    ElevationModel, Harmonic, SimulateError, SimulationConfig, TemperatureModel, Truth, simulate,
    simulate_with_truth,
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

// ---------------------------------------------------------------- temperature

fn air_conditioned_lab() -> TemperatureModel {
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

// ---------------------------------------------------------------- Student-t noise

/// Mean, standard deviation and kurtosis (m4 / m2², 3 for the normal) of `x`.
fn moments(x: &[f64]) -> (f64, f64, f64) {
    let n = x.len() as f64;
    let mean = x.iter().sum::<f64>() / n;
    let m2 = x.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n;
    let m4 = x.iter().map(|e| (e - mean).powi(4)).sum::<f64>() / n;
    (mean, m2.sqrt(), m4 / (m2 * m2))
}

#[test]
fn student_noise_has_the_stated_spread_and_heavier_tails() {
    let normal = SimulationConfig {
        cycles: 3000,
        noise_arcsec: 0.05,
        ..SimulationConfig::default()
    };
    let student = SimulationConfig {
        noise_student_dof: Some(10.0),
        ..normal.clone()
    };
    let residuals = |config: &SimulationConfig| {
        let (set, truth) = simulate(config).unwrap();
        set.readings
            .iter()
            .map(|r| r.reading_arcsec - truth.model_reading(r))
            .collect::<Vec<f64>>()
    };
    let (z, t) = (residuals(&normal), residuals(&student));
    assert_eq!(t.len(), 3000 * 25 * 2);
    let n = t.len() as f64;
    // t with 10 dof: variance 10/8 before scaling, kurtosis 3 + 6/(10 − 4) = 4. The
    // sample kurtosis has a standard error of about 0.1 here, the sd one of 0.6 %.
    let (mean, sd, kurtosis) = moments(&t);
    assert!((sd / 0.05 - 1.0).abs() < 0.02, "sd {sd}");
    assert!(mean.abs() < 4.0 * 0.05 / n.sqrt(), "mean {mean}");
    assert!(kurtosis > 3.5 && kurtosis < 4.6, "kurtosis {kurtosis}");
    let (_, sd_normal, kurtosis_normal) = moments(&z);
    assert!((sd_normal / 0.05 - 1.0).abs() < 0.02, "sd {sd_normal}");
    assert!(
        (kurtosis_normal - 3.0).abs() < 0.1,
        "kurtosis {kurtosis_normal}"
    );
    // The truth records the noise it was made with.
    assert_eq!(Truth::draw(&student).unwrap().noise_student_dof, Some(10.0));
    // Heavier tails: more residuals beyond 4 standard deviations (normal: 6.3e-5).
    let beyond = |x: &[f64]| x.iter().filter(|e| e.abs() > 4.0 * 0.05).count();
    assert!(
        beyond(&t) > 3 * beyond(&z).max(1),
        "{} vs {}",
        beyond(&t),
        beyond(&z)
    );
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

// ---------------------------------------------------------------- the truth file and the specs

#[test]
fn truth_with_the_additions_round_trips_and_is_documented() {
    let config = SimulationConfig {
        setups: 2,
        bidirectional: true,
        temperature: Some(air_conditioned_lab()),
        elevation: Some(ElevationModel::default()),
        noise_student_dof: Some(6.0),
        effects: vec![
            Effect::Drift {
                ac: 1,
                value: 0.1,
                quadratic: Some(0.02),
            },
            Effect::OffsetStep {
                ac: 2,
                cycle: 2,
                step: Some(3),
                setup: Some(1),
                value: 0.4,
            },
            Effect::Temperature { ac: 1, value: 0.2 },
            Effect::CrossTalk { ac: 2, value: 0.01 },
        ],
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&config).unwrap();
    let json = truth.to_json_pretty();
    let path = temp_file("additions.json", &json);
    let read = Truth::read_path(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert_eq!(read, truth);
    let value: serde_json::Value = serde_json::from_str(&json).unwrap();
    assert_eq!(
        value["effects"][1],
        serde_json::json!({"kind": "offset-step", "ac": 2, "cycle": 2, "step": 3, "setup": 1, "value": 0.4})
    );
    assert_eq!(
        value["effects"][3],
        serde_json::json!({"kind": "cross-talk", "ac": 2, "value": 0.01})
    );
    // Every key of the truth file is a code span in docs/FORMAT.md.
    let doc =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/FORMAT.md")).unwrap();
    fn keys(v: &serde_json::Value, out: &mut Vec<String>) {
        match v {
            serde_json::Value::Object(map) => {
                for (k, v) in map {
                    out.push(k.clone());
                    keys(v, out);
                }
            }
            serde_json::Value::Array(list) => list.iter().for_each(|v| keys(v, out)),
            _ => {}
        }
    }
    let mut all = Vec::new();
    keys(&value, &mut all);
    let missing: Vec<&String> = all
        .iter()
        .filter(|k| !doc.contains(&format!("`{k}`")))
        .collect();
    assert!(missing.is_empty(), "not in docs/FORMAT.md: {missing:?}");
}

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

#[test]
fn temperature_at_hand_computed_times() {
    let m = air_conditioned_lab();
    assert_eq!(m.celsius_at(0.0), 20.0);
    assert!((m.celsius_at(300.0) - 20.139_977_792_685_34).abs() < 1e-12);
    assert!((m.celsius_at(3600.0) - 20.316_060_279_414_28).abs() < 1e-12);
}

// ---------------------------------------------------------------- the command line

#[cfg(feature = "cli")]
mod command_line {
    use std::process::{Command, Output};

    fn polycal(args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .stdin(std::process::Stdio::null())
            .output()
            .expect("the binary runs")
    }

    fn header(out: &Output) -> String {
        let text = String::from_utf8_lossy(&out.stdout).to_string();
        text.lines()
            .find(|l| !l.starts_with('#'))
            .unwrap_or_default()
            .to_string()
    }

    #[test]
    fn the_models_add_their_columns_only_when_on() {
        let plain = polycal(&["simulate", "--faces", "6", "--cycles", "1"]);
        assert_eq!(plain.status.code(), Some(0));
        assert_eq!(
            header(&plain),
            "cycle,step,ac,face,reading,direction,setup,time,encoder"
        );
        let both = polycal(&[
            "simulate",
            "--faces",
            "6",
            "--cycles",
            "1",
            "--temperature",
            "--elevation",
            "--noise-dof",
            "5",
        ]);
        assert_eq!(
            both.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&both.stderr)
        );
        assert_eq!(
            header(&both),
            "cycle,step,ac,face,reading,direction,setup,time,reading_y,temperature,encoder"
        );
        let warm = polycal(&[
            "simulate",
            "--faces",
            "6",
            "--cycles",
            "1",
            "--temperature",
            "18:1:600:0.2:300",
            "--temperature-effect",
            "1:0.3",
            "--drift",
            "2:0.1:-0.02",
            "--offset-step",
            "1:1:3:0.5",
        ]);
        assert_eq!(
            warm.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&warm.stderr)
        );
        assert_eq!(
            header(&warm),
            "cycle,step,ac,face,reading,direction,setup,time,temperature,encoder"
        );
        // The first data row is at 0 s: 18 °C.
        let text = String::from_utf8_lossy(&warm.stdout).to_string();
        let row = text.lines().filter(|l| !l.starts_with('#')).nth(1).unwrap();
        assert_eq!(row.split(',').nth(8), Some("18"));
    }

    #[test]
    fn bad_values_of_the_new_options_are_one_error_line_and_status_2() {
        for args in [
            &["--noise-dof", "2"][..],
            &["--noise-dof", "abc"],
            &["--temperature", "20:1"],
            &["--temperature", "20:0.5:0:0.1:1200"],
            &["--elevation", "1:2:3"],
            &["--elevation=-1:0:0:0:0"],
            &["--temperature-effect", "1:0.3"],
            &["--cross-talk", "1:0.1"],
            &["--temperature", "--temperature-effect", "3:0.3"],
            &["--elevation", "--cross-talk", "1:x"],
            &["--drift", "1:0.1:nan"],
            &["--offset-step", "1:1:9:0.5"],
            &["--offset-step", "2:1:1:3:0.5"],
        ] {
            let mut all = vec!["simulate", "--faces", "6", "--cycles", "2"];
            all.extend_from_slice(args);
            let out = polycal(&all);
            assert_eq!(out.status.code(), Some(2), "{args:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
            assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        }
    }

    #[cfg(feature = "lab")]
    #[test]
    fn sim_lab_refuses_the_models_it_does_not_simulate() {
        let help = polycal(&["sim-lab", "--help"]);
        assert_eq!(help.status.code(), Some(0));
        for args in [
            &["--temperature"][..],
            &["--elevation"],
            &["--noise-dof", "5"],
        ] {
            let mut all = vec!["sim-lab", "--time-scale", "0"];
            all.extend_from_slice(args);
            let out = polycal(&all);
            assert_eq!(out.status.code(), Some(2), "{args:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
            assert!(stderr.contains("simulated lab"), "{args:?}: {stderr}");
        }
    }
}
