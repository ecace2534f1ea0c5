//! `diagnose` on simulated runs with effects beyond a zero jump at a cycle boundary, all
//! injected and undeclared: a jump in the middle of a cycle (small, and large enough to
//! tempt a string of outliers), a jump in one mounting of two, an accelerating drift, each
//! also with alternating clockwise and counter-clockwise cycles. Each must be found at the
//! right autocollimator / mounting / cycle / step, with its value within 3 u, and the
//! error against the truth must come within 1.3× of what a fit that knows the true effect
//! shape achieves ("oracle"). Structure no term expresses must give `adequate: false`;
//! a bad reading whose twin the data cannot tell from it is named with its twin and not
//! silently dropped; noise-free and constant data are adequate without effects.

use polycal::diagnose::{DiagnoseOptions, Diagnosis, diagnose};
use polycal::effects::{Effect, EffectContext};
use polycal::measurement::{Direction, MeasurementSet};
use polycal::output::diagnose::ErrorSummary;
use polycal::simulate::{SimulationConfig, Truth, simulate};
use polycal::solve::least_squares_with_regressors;

fn config(effects: Vec<Effect>, seed: u64, bidirectional: bool) -> SimulationConfig {
    SimulationConfig {
        faces: 24,
        cycles: 6,
        closing: true,
        bidirectional,
        noise_arcsec: 0.05,
        effects,
        seed,
        ..SimulationConfig::default()
    }
}

/// The columns of the true effects (a curved drift gives two).
fn true_columns(set: &MeasurementSet, effects: &[Effect]) -> Vec<Vec<f64>> {
    let context = EffectContext::of(&set.readings);
    let mut columns = Vec::new();
    for e in effects {
        columns.push(
            set.readings
                .iter()
                .map(|r| e.regressor(r, &context))
                .collect(),
        );
        if let Effect::Drift {
            quadratic: Some(_), ..
        } = e
        {
            columns.push(
                set.readings
                    .iter()
                    .map(|r| e.quadratic_regressor(r))
                    .collect(),
            );
        }
    }
    columns
}

/// The error of a fit that is told the true effect shapes (not their values).
fn oracle_error(set: &MeasurementSet, truth: &Truth, effects: &[Effect]) -> ErrorSummary {
    let fit = least_squares_with_regressors(set, &true_columns(set, effects), None).unwrap();
    ErrorSummary::new(&fit, truth).unwrap()
}

/// Checks the diagnosis against the oracle: within 1.3× in RMS of β and of α (plus a
/// floor of 0.002″ for errors that are already at the rounding of the noise).
fn assert_near_oracle(d: &Diagnosis, set: &MeasurementSet, truth: &Truth, effects: &[Effect]) {
    let oracle = oracle_error(set, truth, effects);
    let after = ErrorSummary::new(&d.after, truth).unwrap();
    assert!(
        after.pitch_rms <= 1.3 * oracle.pitch_rms + 0.002
            && after.encoder_rms <= 1.3 * oracle.encoder_rms + 0.002,
        "after {after:?}, oracle {oracle:?}, effects {:#?}",
        d.effects
    );
}

fn value_within_3u(d: &Diagnosis, index: usize, injected: f64) {
    let found = &d.effects[index];
    let u = found.u.unwrap();
    assert!(
        (found.effect.value() - injected).abs() <= 3.0 * u,
        "{:?}: injected {injected}, u {u}",
        found.effect
    );
}

fn outliers(d: &Diagnosis) -> usize {
    d.effects
        .iter()
        .filter(|f| matches!(f.effect, Effect::Outlier { .. }))
        .count()
}

/// A jump of autocollimator 2 from step 13 of cycle 3 on, small (0.25″ = 5σ) and large
/// (3″ = 60σ), clockwise only and with alternating directions.
#[test]
fn a_jump_in_the_middle_of_a_cycle_is_found_at_its_step() {
    for bidirectional in [false, true] {
        for (size, seed) in [(0.25, 21), (3.0, 22)] {
            let effect = Effect::OffsetStep {
                ac: 2,
                cycle: 3,
                step: Some(13),
                setup: None,
                value: size,
            };
            let (set, truth) =
                simulate(&config(vec![effect.clone()], seed, bidirectional)).unwrap();
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            let index = d
                .effects
                .iter()
                .position(|f| {
                    matches!(
                        f.effect,
                        Effect::OffsetStep {
                            ac: 2,
                            cycle: 3,
                            step: Some(13),
                            ..
                        }
                    )
                })
                .unwrap_or_else(|| {
                    panic!(
                        "size {size} bidirectional {bidirectional}: {:#?}",
                        d.effects
                    )
                });
            value_within_3u(&d, index, size);
            assert!(
                outliers(&d) <= 1,
                "a jump found as outliers: {:#?}",
                d.effects
            );
            let before = ErrorSummary::new(&d.before, &truth).unwrap();
            assert!(
                before.encoder_max > 0.05 || size < 1.0,
                "the jump biases the base fit: {before:?}"
            );
            assert_near_oracle(&d, &set, &truth, &[effect]);
            assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);
        }
    }
}

/// Two mountings (shifted by 5 faces); autocollimator 1 jumps by 0.4″ in the middle of
/// cycle 2 of mounting 2 only. Found in that mounting, not smeared across both.
#[test]
fn a_jump_in_one_mounting_is_found_in_that_mounting() {
    for bidirectional in [false, true] {
        let effect = Effect::OffsetStep {
            ac: 1,
            cycle: 2,
            step: Some(8),
            setup: Some(2),
            value: 0.4,
        };
        let mut c = config(vec![effect.clone()], 31, bidirectional);
        c.setups = 2;
        c.setup_shift_faces = 5;
        c.cycles = 4;
        let (set, truth) = simulate(&c).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let index = d
            .effects
            .iter()
            .position(|f| {
                matches!(
                    f.effect,
                    Effect::OffsetStep {
                        ac: 1,
                        cycle: 2,
                        step: Some(8),
                        setup: Some(2),
                        ..
                    }
                )
            })
            .unwrap_or_else(|| panic!("{:#?}", d.effects));
        value_within_3u(&d, index, 0.4);
        assert_near_oracle(&d, &set, &truth, &[effect]);
        assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);
    }
}

/// A zero drift that accelerates: 0.5″/h plus 1.5″/h² (over the 1.4 h run: 0.7″ linear,
/// 3″ curved). Found as a drift with a quadratic, both within 3 u.
#[test]
fn an_accelerating_drift_is_found_with_its_curvature() {
    for bidirectional in [false, true] {
        let effect = Effect::Drift {
            ac: 1,
            value: 0.5,
            quadratic: Some(1.5),
        };
        let (set, truth) = simulate(&config(vec![effect.clone()], 41, bidirectional)).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        assert_eq!(d.effects.len(), 1, "{:#?}", d.effects);
        let found = &d.effects[0];
        let Effect::Drift {
            ac: 1,
            value,
            quadratic: Some(q),
        } = found.effect
        else {
            panic!("{:#?}", d.effects);
        };
        assert!((value - 0.5).abs() <= 3.0 * found.u.unwrap(), "{found:?}");
        assert!(
            (q - 1.5).abs() <= 3.0 * found.quadratic_u.unwrap(),
            "{found:?}"
        );
        assert_near_oracle(&d, &set, &truth, &[effect]);
        assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);
    }
}

/// The reading table of a direction-dependent periodic table error: counter-clockwise
/// positions read 0.4″·sin(3·2πp/N) more than clockwise ones. No term expresses it.
#[test]
fn a_periodic_direction_dependent_error_is_not_adequate() {
    let (mut set, _) = simulate(&config(Vec::new(), 51, true)).unwrap();
    for r in &mut set.readings {
        if r.direction == Direction::Ccw {
            let p = (r.step % 24) as f64;
            r.reading_arcsec += 0.4 * (3.0 * std::f64::consts::TAU * p / 24.0).sin();
        }
    }
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert!(!d.adequacy.adequate, "{:#?}", d.effects);
    let lof = d.lack_of_fit.as_ref().unwrap();
    assert!(!lof.passed(), "{lof:?}");
}

/// Two cycles (each cell read twice) and one bad reading: the bad reading and its twin
/// have equal residuals. Diagnosis names both, drops neither and is not adequate.
#[test]
fn an_outlier_with_an_indistinguishable_twin_is_named_with_it() {
    let effect = Effect::Outlier {
        cycle: 2,
        step: 7,
        ac: 1,
        setup: None,
        value: 1.5,
    };
    let mut c = config(vec![effect], 61, false);
    c.cycles = 2;
    let (set, _) = simulate(&c).unwrap();
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert_eq!(outliers(&d), 0, "picked one: {:#?}", d.effects);
    assert_eq!(d.unattributed.len(), 1, "{:#?}", d.unattributed);
    let mut named: Vec<(u32, usize, u32)> = d.unattributed[0]
        .iter()
        .map(|s| (s.cycle, s.step, s.ac))
        .collect();
    named.sort_unstable();
    assert_eq!(named, vec![(1, 7, 1), (2, 7, 1)]);
    assert!(!d.adequacy.adequate);
    assert!(d.notes.iter().any(|n| n.contains("cannot tell which")));
}

/// Noise-free data: residuals at rounding level, adequate, no effect; constant readings
/// likewise.
#[test]
fn noise_free_and_constant_data_are_adequate_without_effects() {
    let mut c = config(Vec::new(), 71, true);
    c.noise_arcsec = 0.0;
    let (set, _) = simulate(&c).unwrap();
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert!(d.effects.is_empty(), "{:#?}", d.effects);
    assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);

    let mut constant = set.clone();
    for r in &mut constant.readings {
        r.reading_arcsec = 12.5;
    }
    let d = diagnose(&constant, &DiagnoseOptions::default()).unwrap();
    assert!(d.effects.is_empty(), "{:#?}", d.effects);
    assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);
}

/// Clean data with alternating directions over 100 seeds: a systematic effect (anything
/// but an outlier) is added in at most 5 runs, and the verdict is "not adequate" in at most
/// 5; wherever the lack-of-fit test applies and the verdict is adequate, the error is
/// within twice what the clean fit's own uncertainty gives.
#[test]
fn clean_runs_rarely_get_a_systematic_effect() {
    let (mut systematic, mut inadequate) = (0, 0);
    for seed in 0..100 {
        let (set, _) = simulate(&config(Vec::new(), 5000 + seed, seed % 2 == 0)).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        if d.effects
            .iter()
            .any(|f| !matches!(f.effect, Effect::Outlier { .. }))
        {
            systematic += 1;
        }
        if !d.adequacy.adequate {
            inadequate += 1;
        }
    }
    eprintln!("clean: {systematic} of 100 got a systematic effect, {inadequate} inadequate");
    assert!(systematic <= 5, "{systematic} of 100");
    assert!(inadequate <= 5, "{inadequate} of 100");
}

/// Structures no term expresses, at amplitudes from invisible to obvious, in runs where the
/// lack-of-fit test applies (alternating directions): whenever the verdict is adequate,
/// the error of β and of α is at most twice what the same run without the structure
/// gives.
#[test]
fn an_adequate_verdict_never_hides_a_doubled_error() {
    type Structure = fn(&mut MeasurementSet, f64);
    let structures: [(&str, Structure); 4] = [
        ("direction-dependent periodic table error", |set, a| {
            for r in &mut set.readings {
                if r.direction == Direction::Ccw {
                    let p = (r.step % set.faces) as f64;
                    r.reading_arcsec +=
                        a * (3.0 * std::f64::consts::TAU * p / set.faces as f64).sin();
                }
            }
        }),
        ("slow sinusoidal zero variation of ac 2", |set, a| {
            for r in &mut set.readings {
                if r.ac == 2 {
                    let t = r.time_seconds.unwrap_or(0.0);
                    r.reading_arcsec += a * (std::f64::consts::TAU * t / 1700.0).sin();
                }
            }
        }),
        // (A face-dependent error of one autocollimator in both directions of a single
        // mounting lies in the span of φ and α: no test on these data can see it.)
        (
            "face-dependent error of ac 2 in counter-clockwise cycles",
            |set, a| {
                for r in &mut set.readings {
                    if r.ac == 2 && r.direction == Direction::Ccw {
                        r.reading_arcsec += a * ((r.face * 7 % 5) as f64 - 2.0) / 2.0;
                    }
                }
            },
        ),
        (
            "direction-dependent zero of ac 1 that grows with time",
            |set, a| {
                for r in &mut set.readings {
                    if r.ac == 1 && r.direction == Direction::Ccw {
                        r.reading_arcsec += a * r.time_seconds.unwrap_or(0.0) / 3000.0;
                    }
                }
            },
        ),
    ];
    let mut adequate_runs = 0;
    for (name, structure) in structures {
        for (k, amplitude) in [0.01, 0.03, 0.1, 0.3, 1.0].into_iter().enumerate() {
            let seed = 7000 + k as u64;
            let (clean, truth) = simulate(&config(Vec::new(), seed, true)).unwrap();
            let clean_fit = least_squares_with_regressors(&clean, &[], None).unwrap();
            let clean_error = ErrorSummary::new(&clean_fit, &truth).unwrap();
            let mut set = clean.clone();
            structure(&mut set, amplitude);
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            assert!(d.lack_of_fit.is_some(), "{name}: the test applies");
            if d.adequacy.adequate {
                adequate_runs += 1;
                let after = ErrorSummary::new(&d.after, &truth).unwrap();
                assert!(
                    after.pitch_rms <= 2.0 * clean_error.pitch_rms
                        && after.encoder_rms <= 2.0 * clean_error.encoder_rms,
                    "{name} at {amplitude}″: adequate with error {after:?}, clean {clean_error:?}, effects {:#?}",
                    d.effects
                );
            }
        }
    }
    // The smallest amplitudes are invisible and harmless: some runs must be adequate.
    assert!(adequate_runs >= 4, "{adequate_runs}");
}

/// An air-conditioned lab: the temperature warms up by 0.5 °C over an hour and cycles by
/// ±0.1 °C every 20 minutes; autocollimator 1 reads 1.5″ per °C. Time and temperature are
/// correlated but not equal: the temperature term must be chosen, not a drift.
#[test]
fn a_temperature_coefficient_is_told_from_a_drift() {
    use polycal::simulate::TemperatureModel;
    for bidirectional in [false, true] {
        let effect = Effect::Temperature { ac: 1, value: 1.5 };
        let mut c = config(vec![effect.clone()], 81, bidirectional);
        c.temperature = Some(TemperatureModel {
            noise_celsius: 0.002,
            ..TemperatureModel::default()
        });
        let (set, truth) = simulate(&c).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let index = d
            .effects
            .iter()
            .position(|f| matches!(f.effect, Effect::Temperature { ac: 1, .. }))
            .unwrap_or_else(|| panic!("{:#?}", d.effects));
        value_within_3u(&d, index, 1.5);
        assert!(
            !d.effects
                .iter()
                .any(|f| matches!(f.effect, Effect::Drift { .. })),
            "a drift stands in for the temperature: {:#?}",
            d.effects
        );
        assert_near_oracle(&d, &set, &truth, &[effect]);
        assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);
    }
}

/// Cross-talk of 1 % of the elevation axis into autocollimator 2, with elevation readings
/// of tens of arcseconds (pyramidal errors, a tilted mounting) in a two-mounting run:
/// found with its value. In one mounting it cannot be told apart from the polygon, and the
/// notes say so.
#[test]
fn cross_talk_is_found_in_two_mountings_and_named_untestable_in_one() {
    use polycal::simulate::ElevationModel;
    for bidirectional in [false, true] {
        let effect = Effect::CrossTalk { ac: 2, value: 0.01 };
        let mut c = config(vec![effect.clone()], 91, bidirectional);
        c.setups = 2;
        c.setup_shift_faces = 5;
        c.cycles = 4;
        c.elevation = Some(ElevationModel::default());
        let (set, truth) = simulate(&c).unwrap();
        let spread = set
            .readings
            .iter()
            .filter_map(|r| r.reading_y_arcsec)
            .fold(0.0_f64, |m, y| m.max(y.abs()));
        assert!(spread > 20.0, "elevations of tens of arcseconds: {spread}");
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let index = d
            .effects
            .iter()
            .position(|f| matches!(f.effect, Effect::CrossTalk { ac: 2, .. }))
            .unwrap_or_else(|| panic!("{:#?}", d.effects));
        value_within_3u(&d, index, 0.01);
        assert_near_oracle(&d, &set, &truth, std::slice::from_ref(&effect));
        assert!(d.adequacy.adequate, "{:?}", d.adequacy.checks);

        let mut one = config(vec![effect.clone()], 92, bidirectional);
        one.elevation = Some(ElevationModel::default());
        let (set, _) = simulate(&one).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        assert!(
            !d.effects
                .iter()
                .any(|f| matches!(f.effect, Effect::CrossTalk { .. })),
            "{:#?}",
            d.effects
        );
        assert!(
            d.notes.iter().any(|n| n.contains("Cross-talk")),
            "{:?}",
            d.notes
        );
    }
}

/// Heavy-tailed noise (Student t, 3 degrees of freedom) over 50 seeds: outliers may be
/// flagged, but a systematic effect is added in at most 5 % of runs.
#[test]
fn heavy_tailed_noise_rarely_gets_a_systematic_effect() {
    let mut systematic = 0;
    for seed in 0..50 {
        let mut c = config(Vec::new(), 9000 + seed, seed % 2 == 1);
        c.noise_student_dof = Some(3.0);
        let (set, _) = simulate(&c).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        if d.effects
            .iter()
            .any(|f| !matches!(f.effect, Effect::Outlier { .. }))
        {
            systematic += 1;
            eprintln!(
                "seed {seed}: {:?}",
                d.effects.iter().map(|f| &f.effect).collect::<Vec<_>>()
            );
        }
    }
    eprintln!("heavy tails: {systematic} of 50 got a systematic effect");
    assert!(systematic * 20 <= 50, "{systematic} of 50");
}

/// A `temperature` column with gaps: no temperature term is tried (nothing is guessed for
/// the missing values), and the notes say how many readings have one.
#[test]
fn a_temperature_column_with_gaps_is_named_not_guessed() {
    use polycal::simulate::TemperatureModel;
    let mut c = config(vec![Effect::Temperature { ac: 1, value: 1.5 }], 82, false);
    c.temperature = Some(TemperatureModel::default());
    let (mut set, _) = simulate(&c).unwrap();
    set.readings[10].temperature_celsius = None;
    let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
    assert!(
        !d.effects
            .iter()
            .any(|f| matches!(f.effect, Effect::Temperature { .. })),
        "{:#?}",
        d.effects
    );
    let total = set.readings.len();
    let expected = format!("only {} of {total} readings", total - 1);
    assert!(
        d.notes.iter().any(|n| n.contains(&expected)),
        "{:?}",
        d.notes
    );
}

/// A gross error is never left in the fit (issue 35): one reading 10σ … 29σ off (σ =
/// 0.05″, either sign), in a plain run and in a run of two mountings between the stops (24
/// faces, shifts 0° and 7.5°, 3 cycles without the closing step: the run where a 20σ
/// reading was left in for not reducing the lack of fit), is found as an outlier at its
/// place in every one of 20 seeds.
#[test]
fn a_reading_ten_to_thirty_sigma_off_is_found_in_every_run() {
    let mut missed = Vec::new();
    // The run first (`simulate --faces 24 --setups 2 --shift-deg 0,7.5 --cycles 3
    // --outlier 2:2:12:1:1.0 --seed 2`: 1″ at setup 2, cycle 2, step 12, autocollimator 1),
    // then 20 seeds of each design with the reading moved around.
    let cases = std::iter::once((true, 1u64, 1.0, 12usize, 1u32)).chain(
        [false, true].into_iter().flat_map(|shifted| {
            (0..20u64).map(move |seed| {
                let sign = if seed % 2 == 0 { 1.0 } else { -1.0 };
                let value = sign * (10.0 + seed as f64) * 0.05;
                (
                    shifted,
                    seed,
                    value,
                    (5 * seed as usize) % 24,
                    1 + (seed % 2) as u32,
                )
            })
        }),
    );
    for (shifted, seed, value, step, ac) in cases {
        let cycle = 2;
        let effects = vec![Effect::Outlier {
            cycle,
            step,
            ac,
            setup: shifted.then_some(2),
            value,
        }];
        let mut config = SimulationConfig {
            cycles: 3,
            closing: false,
            seed: seed + 1,
            ..config(effects, 0, false)
        };
        if shifted {
            config.setups = 2;
            config.table_shift_deg = vec![0.0, 7.5];
        }
        let (set, _) = simulate(&config).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let found = d.effects.iter().any(|f| {
            matches!(
                f.effect,
                Effect::Outlier { cycle: c, step: s, ac: a, .. } if (c, s, a) == (cycle, step, ac)
            )
        });
        if !found {
            missed.push((shifted, seed, value));
        }
    }
    assert!(missed.is_empty(), "not found: {missed:?}");
}
