//! `diagnose` on shifted mountings (issue 22, part 1): whole-face and sub-pitch shifts are
//! fitted in encoder positions, and every effect names the mounting, cycle and step of the
//! file. Checked against simulated truth: the effects injected are found where they were
//! put, the calibration after the diagnosis is as close to the truth as a fit that is
//! told the true effects (within 1.3×), and clean runs rarely get a false effect.

use polycal::diagnose::base::Base;
use polycal::diagnose::{DiagnoseOptions, diagnose};
use polycal::effects::{Effect, EffectContext};
use polycal::measurement::MeasurementSet;
use polycal::simulate::{SimulationConfig, Truth, simulate};
use polycal::solve::SolveOptions;
use polycal::solve::sub_pitch::solve_shifted;

/// 24 faces, 4 cycles with closing readings, one mounting per shift (the polygon turned 5
/// faces between mountings), noise 0.05″.
fn config(shifts: &[f64], effects: Vec<Effect>, seed: u64) -> SimulationConfig {
    SimulationConfig {
        faces: 24,
        setups: shifts.len() as u32,
        setup_shift_faces: 5,
        table_shift_deg: shifts.to_vec(),
        cycles: 4,
        closing: true,
        effects,
        noise_arcsec: 0.05,
        seed,
        ..SimulationConfig::default()
    }
}

/// A drift of autocollimator 1, a jump of autocollimator 2's zero inside mounting 2
/// (cycle 2, from step 9 on), and one bad reading in mounting 1.
fn injected() -> Vec<Effect> {
    vec![
        Effect::Drift {
            ac: 1,
            value: 0.5,
            quadratic: None,
        },
        Effect::OffsetStep {
            ac: 2,
            cycle: 2,
            step: Some(9),
            setup: Some(2),
            value: 0.4,
        },
        Effect::Outlier {
            cycle: 3,
            step: 5,
            ac: 1,
            setup: Some(1),
            value: 1.0,
        },
    ]
}

/// RMS errors of β and α against the truth; α at every table angle, each coset's
/// differences after removing their mean (a coset's constant is not determined).
fn errors(set: &MeasurementSet, truth: &Truth, fit_terms: &[Vec<f64>]) -> (f64, f64) {
    let base = Base::of(set);
    let fit = base.fit(fit_terms, None).unwrap();
    let rms = |d: &[f64]| (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt();
    let beta: Vec<f64> = fit
        .pitch_deviation
        .iter()
        .zip(&truth.pitch_deviation)
        .map(|(a, b)| a - b)
        .collect();
    let (alpha, angles, cosets) = match base.sub_pitch_solution(&fit) {
        Some(s) => (s.encoder_error, s.encoder_angle_deg, s.cosets.len()),
        None => {
            let n = fit.faces;
            let angles = (0..n).map(|p| p as f64 * 360.0 / n as f64).collect();
            (fit.encoder_error.clone(), angles, 1)
        }
    };
    let mut by_coset = vec![Vec::new(); cosets];
    for (j, (a, angle)) in alpha.iter().zip(&angles).enumerate() {
        by_coset[j % cosets].push(a - truth.encoder_error_at_deg(*angle).unwrap());
    }
    let mut alpha_errors = Vec::new();
    for d in by_coset {
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        alpha_errors.extend(d.iter().map(|x| x - mean));
    }
    (rms(&beta), rms(&alpha_errors))
}

fn columns(set: &MeasurementSet, effects: &[Effect]) -> Vec<Vec<f64>> {
    let context = EffectContext::of(&set.readings);
    effects
        .iter()
        .map(|e| {
            set.readings
                .iter()
                .map(|r| e.regressor(r, &context))
                .collect()
        })
        .collect()
}

fn found_where_put(shifts: &[f64]) {
    let runs = 40;
    let (mut all_found, mut diagnosed_sq, mut oracle_sq) = (0, [0.0; 2], [0.0; 2]);
    for seed in 1..=runs {
        let (set, truth) = simulate(&config(shifts, injected(), seed)).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let has = |want: &dyn Fn(&Effect) -> bool| d.effects.iter().any(|f| want(&f.effect));
        let drift = has(&|e| matches!(e, Effect::Drift { ac: 1, .. }));
        let jump = has(&|e| {
            matches!(
                e,
                Effect::OffsetStep {
                    ac: 2,
                    cycle: 2,
                    step: Some(9),
                    setup: Some(2),
                    ..
                }
            )
        });
        let outlier = has(&|e| {
            matches!(
                e,
                Effect::Outlier {
                    cycle: 3,
                    step: 5,
                    ac: 1,
                    setup: Some(1),
                    ..
                }
            )
        });
        if drift && jump && outlier {
            all_found += 1;
        }
        // the diagnosis's final model against the fit told the true effects
        let found: Vec<Effect> = d.effects.iter().map(|f| f.effect.clone()).collect();
        let mut terms = columns(&set, &found);
        // a curved drift's curvature is a column of its own
        for f in &found {
            if let Effect::Drift {
                ac,
                quadratic: Some(_),
                ..
            } = f
            {
                let drift = Effect::Drift {
                    ac: *ac,
                    value: 0.0,
                    quadratic: None,
                };
                terms.push(
                    set.readings
                        .iter()
                        .map(|r| drift.quadratic_regressor(r))
                        .collect(),
                );
            }
        }
        let (b, a) = errors(&set, &truth, &terms);
        let (ob, oa) = errors(&set, &truth, &columns(&set, &injected()));
        diagnosed_sq[0] += b * b;
        diagnosed_sq[1] += a * a;
        oracle_sq[0] += ob * ob;
        oracle_sq[1] += oa * oa;
    }
    assert!(
        all_found >= 36,
        "{shifts:?}: drift, jump and outlier all found where put in {all_found} of {runs}"
    );
    for (k, name) in ["β", "α"].iter().enumerate() {
        let ratio = (diagnosed_sq[k] / oracle_sq[k]).sqrt();
        assert!(
            ratio <= 1.3,
            "{shifts:?}: RMS error of {name} {ratio:.3}× that of the fit told the true effects"
        );
    }
}

#[test]
fn effects_in_whole_face_mountings_are_found_where_they_were_put() {
    // the second mounting's table turned 3 positions (45° of 15°)
    found_where_put(&[0.0, 45.0]);
}

#[test]
fn effects_in_sub_pitch_mountings_are_found_where_they_were_put() {
    found_where_put(&[0.0, 7.5]);
    found_where_put(&[0.0, 30.0, 97.5]);
}

fn false_alarms(shifts: &[f64]) -> usize {
    (1..=100u64)
        .filter(|&seed| {
            let (set, _) = simulate(&config(shifts, Vec::new(), 1000 + seed)).unwrap();
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            d.effects
                .iter()
                .any(|f| !matches!(f.effect, Effect::Outlier { .. }))
        })
        .count()
}

#[test]
fn clean_shifted_runs_rarely_get_a_false_systematic_effect() {
    for shifts in [&[0.0, 45.0][..], &[0.0, 7.5][..]] {
        let false_alarms = false_alarms(shifts);
        assert!(
            false_alarms <= 5,
            "{shifts:?}: a false systematic effect in {false_alarms} of 100 clean runs"
        );
    }
}

#[test]
fn a_clean_sub_pitch_diagnosis_reports_what_solve_shifted_reports() {
    let (set, _) = simulate(&config(&[0.0, 7.5], Vec::new(), 5)).unwrap();
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert!(d.effects.is_empty(), "{:?}", d.effects);
    let solved = solve_shifted(&set, &SolveOptions::default()).unwrap();
    let after = d.after_sub_pitch.unwrap();
    assert_eq!(after.encoder_angle_deg, solved.encoder_angle_deg);
    for (a, b) in after.encoder_error.iter().zip(&solved.encoder_error) {
        assert!((a - b).abs() < 1e-12);
    }
    for (a, b) in after
        .encoder_error_u
        .unwrap()
        .iter()
        .zip(&solved.encoder_error_u.unwrap())
    {
        assert!((a - b).abs() < 1e-12);
    }
    for (a, b) in d
        .after
        .pitch_deviation
        .iter()
        .zip(&solved.solution.pitch_deviation)
    {
        assert!((a - b).abs() < 1e-12);
    }
}
