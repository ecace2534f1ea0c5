//! Tests of the self-calibration simulator (`simulate_selfcal`, `polycal simulate --selfcal`)
//! against expectations computed here, independently of the library: the cosines of the
//! encoder error are evaluated in the test.

use std::f64::consts::TAU;

use polycal::Direction;
use polycal::selfcal::SelfcalSet;
use polycal::simulate::{
    Harmonic, HarmonicError, SelfcalConfigError, SelfcalSimConfig, SelfcalTruth, SimulateError,
    SimulationConfig, Truth, equally_spaced_head_angles_deg, selfa_head_angles_deg,
    simulate_selfcal,
};

fn h(order: usize, amplitude_arcsec: f64, phase_rad: f64) -> Harmonic {
    Harmonic {
        order,
        amplitude_arcsec,
        phase_rad,
    }
}

/// Σ a·cos(k·θ + phase) at θ = `angle_deg` degrees, written out here.
fn e(harmonics: &[(usize, f64, f64)], angle_deg: f64) -> f64 {
    harmonics
        .iter()
        .map(|&(k, a, phase)| a * (k as f64 * angle_deg.to_radians() + phase).cos())
        .sum()
}

const HARMONICS: [(usize, f64, f64); 4] =
    [(1, 0.6, 0.4), (2, 0.35, 1.3), (7, 0.2, 2.2), (13, 0.1, 0.7)];

fn given_harmonics() -> Vec<Harmonic> {
    HARMONICS.iter().map(|&(k, a, p)| h(k, a, p)).collect()
}

/// A run with the given harmonics, P positions and heads, without table error and noise.
fn exact(positions: usize, heads: Vec<f64>) -> SelfcalSimConfig {
    let mut config = SelfcalSimConfig::default();
    config.positions = positions;
    config.head_angles_deg = heads;
    config.encoder_harmonics = given_harmonics();
    config.table_error_arcsec = 0.0;
    config.noise_arcsec = 0.0;
    config
}

fn bits(set: &SelfcalSet) -> Vec<u64> {
    set.readings
        .iter()
        .map(|r| r.reading_arcsec.to_bits())
        .collect()
}

// ---------------------------------------------------------------- the readings

#[test]
fn without_table_error_and_noise_a_reading_is_the_encoder_error_plus_the_head_error() {
    // SelfA on 84 positions: every head on the grid.
    let config = exact(84, selfa_head_angles_deg());
    let (set, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(set.positions, 84);
    assert_eq!(set.readings.len(), 2 * 84 * 12);
    for r in &set.readings {
        let psi = config.head_angles_deg[r.head as usize - 1];
        assert_eq!(r.head_angle_deg, psi);
        let c = truth.head_error_of(r.head).unwrap();
        let expected = e(&HARMONICS, r.step as f64 * 360.0 / 84.0 + psi) + c;
        assert!(
            (r.reading_arcsec - expected).abs() < 1e-12,
            "cycle {} step {} head {}: {} vs {expected}",
            r.cycle,
            r.step,
            r.head,
            r.reading_arcsec
        );
    }
}

#[test]
fn heads_off_the_grid_read_the_encoder_at_their_exact_angle() {
    // SelfA on 12 positions: the group of 7 is between the positions (30° apart).
    let config = exact(12, selfa_head_angles_deg());
    assert_eq!(config.heads_off_grid(), vec![7, 8, 9, 10, 11, 12]);
    let (set, truth) = simulate_selfcal(&config).unwrap();
    let head7: Vec<_> = set.readings.iter().filter(|r| r.head == 7).collect();
    assert_eq!(head7.len(), 2 * 12);
    for r in head7 {
        let angle = r.step as f64 * 30.0 + 360.0 / 7.0;
        let expected = e(&HARMONICS, angle) + truth.head_error_of(7).unwrap();
        assert!((r.reading_arcsec - expected).abs() < 1e-12);
    }
}

#[test]
fn the_table_error_is_shared_by_the_heads_of_a_stop_and_redrawn_at_every_stop() {
    let mut config = exact(12, equally_spaced_head_angles_deg(4));
    config.table_error_arcsec = 1.0;
    config.cycles = 3;
    let (set, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(truth.table_error.len(), 3);
    for r in &set.readings {
        let t = truth.table_error_at(r.cycle, r.step).unwrap();
        let expected = t
            + e(&HARMONICS, r.step as f64 * 30.0 + r.head_angle_deg)
            + truth.head_error_of(r.head).unwrap();
        assert!((r.reading_arcsec - expected).abs() < 1e-12);
    }
    // The table is not repeatable: the same step of two cycles has different errors.
    let t: Vec<f64> = truth.table_error.iter().flatten().copied().collect();
    let rms = (t.iter().map(|x| x * x).sum::<f64>() / t.len() as f64).sqrt();
    assert!(rms > 0.5 && rms < 1.5, "rms {rms}");
    assert_ne!(truth.table_error[0][5], truth.table_error[1][5]);
}

#[test]
fn the_noise_has_the_asked_standard_deviation() {
    let mut config = exact(168, selfa_head_angles_deg());
    config.noise_arcsec = 0.02;
    config.cycles = 4;
    let (noisy, truth) = simulate_selfcal(&config).unwrap();
    config.noise_arcsec = 0.0;
    let (clean, truth0) = simulate_selfcal(&config).unwrap();
    assert_eq!(truth.encoder_error, truth0.encoder_error);
    let d: Vec<f64> = noisy
        .readings
        .iter()
        .zip(&clean.readings)
        .map(|(a, b)| a.reading_arcsec - b.reading_arcsec)
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let sd = (d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0)).sqrt();
    assert!((sd - 0.02).abs() < 0.001, "sd {sd}");
    assert!(mean.abs() < 0.001, "mean {mean}");
}

#[test]
fn the_run_visits_every_step_with_every_head_in_time_order() {
    let mut config = exact(6, vec![0.0, 120.0, 240.0]);
    config.cycles = 3;
    config.bidirectional = true;
    config.step_seconds = Some(5.0);
    let (set, _) = simulate_selfcal(&config).unwrap();
    assert_eq!(set.readings.len(), 3 * 6 * 3);
    let mut stop = 0;
    for cycle in 1..=3u32 {
        let ccw = cycle == 2;
        for i in 0..6 {
            let step = if ccw { 5 - i } else { i };
            for head in 1..=3u32 {
                let r = &set.readings[stop * 3 + head as usize - 1];
                assert_eq!((r.cycle, r.step, r.head), (cycle, step, head));
                let direction = if ccw { Direction::Ccw } else { Direction::Cw };
                assert_eq!(r.direction, direction);
                assert_eq!(r.time_seconds, Some(stop as f64 * 5.0));
                assert_eq!(r.line, 0);
            }
            stop += 1;
        }
    }
    // Without a step time there is no time; without bidirectional every cycle is clockwise.
    let (plain, _) = simulate_selfcal(&exact(6, vec![0.0, 120.0, 240.0])).unwrap();
    assert!(plain.readings.iter().all(|r| r.time_seconds.is_none()));
    assert!(plain.readings.iter().all(|r| r.direction == Direction::Cw));
}

// ---------------------------------------------------------------- the design

#[test]
fn the_default_is_selfa_with_twelve_heads_in_groups_of_three_four_and_seven() {
    let config = SelfcalSimConfig::default();
    assert_eq!(config.positions, 168);
    assert_eq!(config.cycles, 2);
    let mut expected = vec![0.0, 120.0, 240.0, 90.0, 180.0, 270.0];
    for k in 1..7 {
        expected.push(k as f64 * 360.0 / 7.0);
    }
    assert_eq!(config.head_angles_deg, expected);
    assert_eq!(selfa_head_angles_deg(), expected);
    assert!(config.heads_off_grid().is_empty());

    let (set, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(set.readings.len(), 2 * 168 * 12);
    let heads = set.heads();
    assert_eq!(heads.len(), 12);
    for (j, head) in heads.iter().enumerate() {
        assert_eq!(head.head, j as u32 + 1);
        assert_eq!(head.angle_deg, expected[j]);
    }
    assert_eq!(set.cycles(), vec![1, 2]);
    // Heads 2 … 12 in the truth, each with its angle; head 1 is the reference.
    let listed: Vec<(u32, f64)> = truth
        .head_error
        .iter()
        .map(|c| (c.head, c.angle_deg))
        .collect();
    let want: Vec<(u32, f64)> = (2..=12).map(|j| (j, expected[j as usize - 1])).collect();
    assert_eq!(listed, want);
}

#[test]
fn equally_spaced_heads() {
    assert_eq!(equally_spaced_head_angles_deg(3), vec![0.0, 120.0, 240.0]);
    assert_eq!(
        equally_spaced_head_angles_deg(7)[1..],
        (1..7).map(|k| k as f64 * 360.0 / 7.0).collect::<Vec<_>>()[..]
    );
    assert!(equally_spaced_head_angles_deg(0).is_empty());
}

// ---------------------------------------------------------------- the truth

#[test]
fn the_encoder_error_sums_to_zero_and_is_the_harmonics_minus_their_mean() {
    // Order 12 on 12 positions has a mean over the positions: it must be removed.
    let mut config = exact(12, equally_spaced_head_angles_deg(4));
    config.encoder_harmonics.push(h(12, 0.25, 0.5));
    let mut all = HARMONICS.to_vec();
    all.push((12, 0.25, 0.5));
    let (_, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(truth.positions, 12);
    assert_eq!(truth.encoder_error.len(), 12);
    assert_eq!(truth.encoder_error.iter().sum::<f64>(), 0.0);
    let raw: Vec<f64> = (0..12).map(|k| e(&all, k as f64 * 30.0)).collect();
    let mean = raw.iter().sum::<f64>() / 12.0;
    assert!((mean - 0.25 * 0.5f64.cos()).abs() < 1e-12);
    for (k, &raw_k) in raw.iter().enumerate() {
        let angle = k as f64 * 30.0;
        assert_eq!(truth.encoder_angle_deg[k], angle);
        assert!((truth.encoder_error[k] - (raw_k - mean)).abs() < 1e-12);
        // The continuous error is not mean-removed.
        assert!((truth.encoder_error_at_deg(angle) - raw_k).abs() < 1e-12);
    }
    // Between the positions, and beyond a turn.
    assert!((truth.encoder_error_at_deg(17.5) - e(&all, 17.5)).abs() < 1e-12);
    assert!((truth.encoder_error_at_deg(377.5) - e(&all, 17.5)).abs() < 1e-12);
    assert!((truth.encoder_error_at_deg(-342.5) - e(&all, 17.5)).abs() < 1e-12);
    assert_eq!(truth.encoder_harmonics, config.encoder_harmonics);
    assert_eq!(truth.noise_arcsec, Some(0.0));
}

#[test]
fn head_one_is_the_reference_and_the_others_are_in_the_range() {
    let mut config = SelfcalSimConfig::default();
    config.head_error_arcsec = 1.5;
    let (set, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(truth.head_error_of(1), Some(0.0));
    assert_eq!(truth.head_error_of(13), None);
    assert!(truth.head_error.iter().all(|c| c.head >= 2));
    assert!(truth.head_error.iter().all(|c| c.value.abs() <= 1.5));
    assert!(truth.head_error.iter().any(|c| c.value.abs() > 0.1));
    // Head 1's readings carry no head error: without table error and noise they are e.
    let mut exact_config = config.clone();
    exact_config.table_error_arcsec = 0.0;
    exact_config.noise_arcsec = 0.0;
    let (exact_set, exact_truth) = simulate_selfcal(&exact_config).unwrap();
    for r in exact_set.readings.iter().filter(|r| r.head == 1) {
        let angle = r.step as f64 * 360.0 / 168.0;
        assert!((r.reading_arcsec - exact_truth.encoder_error_at_deg(angle)).abs() < 1e-12);
    }
    assert_eq!(set.readings.len(), exact_set.readings.len());
}

#[test]
fn a_drawn_encoder_error_has_the_asked_orders_and_amplitudes() {
    let mut config = SelfcalSimConfig::default();
    config.max_order = 20;
    let (_, truth) = simulate_selfcal(&config).unwrap();
    assert_eq!(truth.encoder_harmonics.len(), 20);
    for (i, harmonic) in truth.encoder_harmonics.iter().enumerate() {
        assert_eq!(harmonic.order, i + 1);
        assert!((harmonic.amplitude_arcsec - 0.3 / ((i + 1) as f64).sqrt()).abs() < 1e-15);
        assert!((0.0..TAU).contains(&harmonic.phase_rad));
    }
    let phases: Vec<f64> = truth
        .encoder_harmonics
        .iter()
        .map(|h| h.phase_rad)
        .collect();
    assert!(phases.windows(2).all(|w| w[0] != w[1]));
}

#[test]
fn the_same_encoder_in_a_polygon_run() {
    // The self-calibration truth's harmonics, given to a 24-faced polygon run, give that
    // encoder's errors at 0°, 15°, …, 345° (mean removed over the 24).
    let (_, selfcal_truth) = simulate_selfcal(&SelfcalSimConfig::default()).unwrap();
    let polygon = SimulationConfig {
        encoder_harmonics: selfcal_truth.encoder_harmonics.clone(),
        ..SimulationConfig::default()
    };
    let truth = Truth::draw(&polygon).unwrap();
    let at: Vec<f64> = (0..24)
        .map(|p| selfcal_truth.encoder_error_at_deg(p as f64 * 15.0))
        .collect();
    let mean = at.iter().sum::<f64>() / 24.0;
    for (alpha, at_p) in truth.encoder_error.iter().zip(&at) {
        assert!((alpha - (at_p - mean)).abs() < 1e-12);
    }
    assert_eq!(truth.encoder_error.len(), 24);
}

#[test]
fn the_truth_reads_back_from_its_json() {
    let mut config = SelfcalSimConfig::default();
    config.positions = 84;
    let (_, truth) = simulate_selfcal(&config).unwrap();
    let dir = std::env::temp_dir().join(format!("polycal-selfcal-truth-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("truth.json");
    std::fs::write(&path, truth.to_json_pretty()).unwrap();
    assert_eq!(SelfcalTruth::read_path(&path).unwrap(), truth);

    // A hand-written file needs only positions and encoder_error.
    std::fs::write(
        &path,
        r#"{"positions": 4, "encoder_error": [1, -1, 0.5, -0.5]}"#,
    )
    .unwrap();
    let small = SelfcalTruth::read_path(&path).unwrap();
    assert_eq!(small.encoder_angle_deg, vec![0.0, 90.0, 180.0, 270.0]);
    assert!(small.encoder_error_at_deg(0.0).is_nan());
    assert_eq!(small.head_error_of(1), Some(0.0));

    for (text, what) in [
        (
            r#"{"positions": 4, "encoder_error": [1, -1, 0.5]}"#,
            "3 values",
        ),
        (
            r#"{"positions": 2, "encoder_error": [1, -1]}"#,
            "positions is 2",
        ),
        (
            r#"{"positions": 3, "encoder_error": [1, -1, 0], "head_error": [{"head": 1, "angle_deg": 0, "value": 0}]}"#,
            "head 1",
        ),
        (
            r#"{"positions": 3, "encoder_error": [1, -1, 0], "table_error": [[0, 0]]}"#,
            "table_error of cycle 1",
        ),
    ] {
        std::fs::write(&path, text).unwrap();
        match SelfcalTruth::read_path(&path) {
            Err(SimulateError::Truth { origin, problem }) => {
                assert!(origin.ends_with("truth.json"), "{origin}");
                let message = problem.to_string();
                assert!(message.contains(what), "{text}: {message}");
            }
            other => panic!("{text}: {other:?}"),
        }
    }
    std::fs::write(&path, "{\"positions\": 3,\n \"encoder_error\": [1, -1, x]}").unwrap();
    assert!(matches!(
        SelfcalTruth::read_path(&path),
        Err(SimulateError::Json { .. })
    ));
    let _ = std::fs::remove_dir_all(&dir);
}

// ---------------------------------------------------------------- reproducibility

#[test]
fn the_same_seed_gives_the_same_run_and_each_part_has_its_own_stream() {
    let config = SelfcalSimConfig::default();
    let (a, truth_a) = simulate_selfcal(&config).unwrap();
    let (b, truth_b) = simulate_selfcal(&config).unwrap();
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(a, b);
    assert_eq!(truth_a, truth_b);

    let mut other = config.clone();
    other.seed = 2;
    let (c, truth_c) = simulate_selfcal(&other).unwrap();
    assert_ne!(bits(&a), bits(&c));
    assert_ne!(truth_a.encoder_error, truth_c.encoder_error);

    // Changing the noise, the table error or the head error range changes nothing else.
    let mut quiet = config.clone();
    quiet.noise_arcsec = 0.05;
    quiet.table_error_arcsec = 0.3;
    quiet.head_error_arcsec = 1.0;
    let (_, truth_q) = simulate_selfcal(&quiet).unwrap();
    assert_eq!(truth_q.encoder_harmonics, truth_a.encoder_harmonics);
    assert_eq!(truth_q.encoder_error, truth_a.encoder_error);
    for (q, a) in truth_q.head_error.iter().zip(&truth_a.head_error) {
        assert!((q.value - a.value / 2.0).abs() < 1e-15);
    }
    for (q, a) in truth_q
        .table_error
        .iter()
        .flatten()
        .zip(truth_a.table_error.iter().flatten())
    {
        assert!((q - a * 0.3).abs() < 1e-15);
    }
}

// ---------------------------------------------------------------- refused settings

#[test]
fn invalid_settings_are_refused_with_typed_errors() {
    use SelfcalConfigError as E;
    let refused = |change: &dyn Fn(&mut SelfcalSimConfig)| -> SelfcalConfigError {
        let mut config = SelfcalSimConfig::default();
        change(&mut config);
        match simulate_selfcal(&config) {
            Err(SimulateError::SelfcalConfig(reason)) => {
                assert_eq!(
                    config.validate().unwrap_err().to_string(),
                    SimulateError::SelfcalConfig(reason.clone()).to_string()
                );
                reason
            }
            other => panic!("{config:?}: {other:?}"),
        }
    };
    assert_eq!(
        refused(&|c| c.positions = 2),
        E::TooFewPositions { positions: 2 }
    );
    assert_eq!(refused(&|c| c.cycles = 0), E::NoCycles);
    assert_eq!(
        refused(&|c| c.head_angles_deg = vec![0.0]),
        E::TooFewHeads { heads: 1 }
    );
    assert_eq!(
        refused(&|c| c.head_angles_deg = vec![10.0, 100.0]),
        E::FirstHeadNotAtZero { angle_deg: 10.0 }
    );
    assert_eq!(
        refused(&|c| c.head_angles_deg = vec![0.0, 360.0]),
        E::HeadAngleOutOfRange {
            head: 2,
            angle_deg: 360.0
        }
    );
    assert!(matches!(
        refused(&|c| c.head_angles_deg = vec![0.0, f64::NAN]),
        E::HeadAngleOutOfRange { head: 2, .. }
    ));
    assert_eq!(
        refused(&|c| c.head_angles_deg = vec![0.0, 90.0, 180.0, 90.0]),
        E::SameHeadAngle {
            first: 2,
            head: 4,
            angle_deg: 90.0
        }
    );
    assert_eq!(
        refused(&|c| c.noise_arcsec = -0.1),
        E::NotNonNegative {
            what: "noise",
            value: -0.1
        }
    );
    assert!(matches!(
        refused(&|c| c.table_error_arcsec = f64::INFINITY),
        E::NotNonNegative {
            what: "table error",
            ..
        }
    ));
    assert!(matches!(
        refused(&|c| c.head_error_arcsec = -1.0),
        E::NotNonNegative {
            what: "head error range",
            ..
        }
    ));
    assert_eq!(
        refused(&|c| c.step_seconds = Some(0.0)),
        E::StepSeconds { seconds: 0.0 }
    );
    assert_eq!(
        refused(&|c| c.encoder_harmonics = vec![h(0, 1.0, 0.0)]),
        E::Harmonic(HarmonicError::OrderZero(h(0, 1.0, 0.0)))
    );
    assert!(matches!(
        refused(&|c| c.encoder_harmonics = vec![h(2, f64::NAN, 0.0)]),
        E::Harmonic(HarmonicError::NotFinite(_))
    ));
    assert_eq!(refused(&|c| c.max_order = 0), E::MaxOrder { max_order: 0 });
    assert!(matches!(
        refused(&|c| c.positions = 10_000_000),
        E::TooManyReadings {
            readings: 240_000_000
        }
    ));
    assert!(matches!(
        refused(&|c| c.max_order = 1_000_000),
        E::TooManyHarmonicTerms { .. }
    ));
    // max_order is not looked at when harmonics are given.
    let mut given = exact(12, equally_spaced_head_angles_deg(3));
    given.max_order = 0;
    assert!(simulate_selfcal(&given).is_ok());
    // An error names the problem in words.
    let text = SimulateError::SelfcalConfig(E::TooFewHeads { heads: 1 }).to_string();
    assert!(text.contains("at least 2"), "{text}");
}

// ---------------------------------------------------------------- the command line

#[cfg(feature = "cli")]
mod command_line {
    use std::path::PathBuf;
    use std::process::{Command, Output};

    fn polycal(args: &[&str]) -> Output {
        Command::new(env!("CARGO_BIN_EXE_polycal"))
            .args(args)
            .stdin(std::process::Stdio::null())
            .output()
            .expect("the binary runs")
    }

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "polycal-simulate-selfcal-{}-{name}",
            std::process::id()
        ));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn writes_the_self_calibration_file_and_its_truth() {
        let dir = scratch("files");
        let (csv, json) = (dir.join("run.csv"), dir.join("run.json"));
        let out = polycal(&[
            "simulate",
            "--selfcal",
            "--positions",
            "12",
            "--heads",
            "0,90,180,270",
            "--seed",
            "4",
            "--out",
            csv.to_str().unwrap(),
            "--truth-out",
            json.to_str().unwrap(),
        ]);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(out.stdout.is_empty());
        assert!(
            out.stderr.is_empty(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = std::fs::read_to_string(&csv).unwrap();
        let mut lines = text.lines();
        let comment = lines.next().unwrap();
        assert!(comment.starts_with("# polycal "), "{comment}");
        assert!(comment.contains(" simulate --selfcal"), "{comment}");
        assert_eq!(
            lines.next(),
            Some("cycle,step,head,head_angle,reading,time")
        );
        let rows: Vec<&str> = lines.collect();
        // The defaults with --selfcal: 2 cycles.
        assert_eq!(rows.len(), 2 * 12 * 4);
        assert!(rows[0].starts_with("1,0,1,0,"), "{}", rows[0]);
        assert!(rows[1].starts_with("1,0,2,90,"), "{}", rows[1]);
        assert!(rows[4].ends_with(",20"), "{}", rows[4]);
        let truth = polycal::simulate::SelfcalTruth::read_path(&json).unwrap();
        assert_eq!(truth.positions, 12);
        assert_eq!(truth.head_error.len(), 3);
        assert_eq!(truth.noise_arcsec, Some(0.02));
        // The numbers are the library's, at full precision.
        let mut config = polycal::simulate::SelfcalSimConfig::default();
        config.positions = 12;
        config.head_angles_deg = vec![0.0, 90.0, 180.0, 270.0];
        config.seed = 4;
        config.step_seconds = Some(20.0);
        let (set, library_truth) = polycal::simulate::simulate_selfcal(&config).unwrap();
        assert_eq!(truth, library_truth);
        for (row, r) in rows.iter().zip(&set.readings) {
            let reading: f64 = row.split(',').nth(4).unwrap().parse().unwrap();
            assert_eq!(reading.to_bits(), r.reading_arcsec.to_bits());
        }
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bidirectional_runs_write_the_direction_and_stdout_is_the_default() {
        let out = polycal(&[
            "simulate",
            "--selfcal",
            "--positions",
            "6",
            "--heads",
            "0,120,240",
            "--cycles",
            "2",
            "--bidirectional",
            "--harmonic",
            "1:0.5:0.2",
            "--harmonic",
            "3:0.1",
        ]);
        assert_eq!(out.status.code(), Some(0));
        let text = String::from_utf8(out.stdout).unwrap();
        let lines: Vec<&str> = text.lines().collect();
        assert!(
            lines[0].contains("encoder harmonics 1:0.5:0.2 3:0.1"),
            "{}",
            lines[0]
        );
        assert_eq!(
            lines[1],
            "cycle,step,head,head_angle,reading,direction,time"
        );
        assert_eq!(lines.len(), 2 + 2 * 6 * 3);
        assert!(lines[2 + 6 * 3].starts_with("2,5,1,0,"), "{}", lines[20]);
        assert!(lines[2 + 6 * 3].contains(",ccw,"));
    }

    #[test]
    fn heads_between_the_positions_are_warned_about() {
        let out = polycal(&[
            "simulate",
            "--selfcal",
            "--positions",
            "12",
            "--cycles",
            "1",
        ]);
        assert_eq!(out.status.code(), Some(0));
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.starts_with("warning: "), "{stderr}");
        assert!(stderr.contains("7, 8, 9, 10, 11, 12"), "{stderr}");
        let quiet = polycal(&["simulate", "--selfcal", "--positions", "12", "-q"]);
        assert!(quiet.stderr.is_empty());
    }

    fn refused(args: &[&str]) -> String {
        let out = polycal(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        assert!(out.stdout.is_empty(), "{args:?}");
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        assert_eq!(stderr.lines().count(), 1, "{args:?}: {stderr}");
        assert!(stderr.starts_with("error: "), "{args:?}: {stderr}");
        stderr
    }

    #[test]
    fn the_polygon_options_are_refused_with_selfcal() {
        for args in [
            &["--faces", "12"][..],
            &["--closing"],
            &["--ac-faces", "1,3"],
            &["--setups", "2"],
            &["--setup-shift", "2"],
            &["--pitch-spread", "0.1"],
            &["--setup-spread", "0.1"],
            &["--noise-dof", "5"],
            &["--temperature"],
            &["--elevation"],
            &["--drift", "1:0.5"],
            &["--offset-step", "1:1:0.3"],
            &["--direction", "0.2"],
            &["--outlier", "1:2:1:3"],
            &["--temperature-effect", "1:0.3"],
            &["--cross-talk", "1:0.1"],
        ] {
            let mut all = vec!["simulate", "--selfcal", "--positions", "12"];
            all.extend_from_slice(args);
            let stderr = refused(&all);
            assert!(stderr.contains("--selfcal"), "{args:?}: {stderr}");
            assert!(stderr.contains(args[0]), "{args:?}: {stderr}");
        }
    }

    #[test]
    fn the_selfcal_options_need_selfcal() {
        for args in [
            &["--positions", "12"][..],
            &["--heads", "selfa"],
            &["--table-error", "0.5"],
            &["--head-error", "1"],
            &["--max-order", "10"],
        ] {
            let mut all = vec!["simulate"];
            all.extend_from_slice(args);
            let stderr = refused(&all);
            assert!(stderr.contains("--selfcal"), "{args:?}: {stderr}");
        }
        let stderr = refused(&[
            "simulate",
            "--selfcal",
            "--harmonic",
            "1:0.5",
            "--max-order",
            "10",
        ]);
        assert!(stderr.contains("--max-order"), "{stderr}");
    }

    #[test]
    fn bad_values_are_one_error_line_naming_the_option() {
        for (args, flag) in [
            (&["--positions", "2"][..], "--positions"),
            (&["--heads", "10,100"], "--heads"),
            (&["--heads", "0,90,90"], "--heads"),
            (&["--heads", "0,abc"], "--heads"),
            (&["--heads", "0"], "--heads"),
            (&["--noise", "-1"], "--noise"),
            (&["--table-error", "-0.5"], "--table-error"),
            (&["--head-error", "nan"], "--head-error"),
            (&["--cycles", "0"], "--cycles"),
            (&["--step-seconds", "0"], "--step-seconds"),
            (&["--max-order", "0"], "--max-order"),
            (&["--harmonic", "0:1"], "--harmonic"),
        ] {
            let mut all = vec!["simulate", "--selfcal", "--positions", "12"];
            if args[0] == "--positions" {
                all.truncate(2);
            }
            all.extend_from_slice(args);
            let stderr = refused(&all);
            assert!(stderr.contains(flag), "{args:?}: {stderr}");
        }
    }
}
