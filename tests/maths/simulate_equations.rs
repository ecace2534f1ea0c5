//! Tests of the simulator against hand-derived expectations: the paper's design and the
//! run's structure. Noise-free readings of four faces are the paper's equations (4)–(6)
//! exactly; the drawn truth closes and follows its encoder harmonics; the default is the
//! paper's design; the faces each mounting reads follow the shift, counter-clockwise
//! cycles run backwards at increasing times, and the rows are as many as configured.

use polycal::simulate::{SimulationConfig, Truth, simulate};
use polycal::{Direction, Reading};

use crate::simulate_support::noise_free;

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
