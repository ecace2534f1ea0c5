//! Tests of the simulator against hand-derived expectations: reproducibility and noise.
//! One seed gives one run bit for bit and another seed another; `simulate` is a drawn
//! truth then `simulate_with_truth`, which redraws only the noise; the noise has the
//! configured spread, normal or Student-t with its heavier tails.

use polycal::MeasurementSet;
use polycal::effects::Effect;
use polycal::simulate::{SimulationConfig, Truth, simulate, simulate_with_truth};

use crate::simulate_support::{bits, noise_free};

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
