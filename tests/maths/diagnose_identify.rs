//! Closing the loop, third generation (issue 21): findings the data cannot tell from
//! another explanation, and the habits of real labs, each over many seeds against the
//! simulated truth and the clean twin (the same truth and noise without the effect).
//!
//! - cross-talk on one or both autocollimators in two mountings, with an elevation axis
//!   `reading_y = Y[face] + W[step] + offsets` (no tilt of the mountings): closure data
//!   determine only the difference of the cross-talk coefficients, so the finding must
//!   carry `alternatives` and the verdict must be "not adequate"; stating one
//!   autocollimator's cross-talk resolves it;
//! - a zero set anew every cycle (`rezero`), found as one term, adequate, errors as the
//!   clean twin's;
//! - a drift in a file without `time`, found on the stop clock, errors as a fit with the
//!   true drift shape;
//! - a wandering zero (random walk): the final model is not worse than the base model;
//! - false alarms on clean data of four designs.

use polycal::diagnose::{Clock, DiagnoseOptions, Diagnosis, diagnose};
use polycal::effects::Effect;
use polycal::output::diagnose::ErrorSummary;
use polycal::simulate::{RandomWalkSpec, RezeroSpec, SimulationConfig, Truth, simulate};
use polycal::solve::least_squares_with_regressors;

fn base(seed: u64) -> SimulationConfig {
    SimulationConfig {
        seed,
        ..SimulationConfig::default()
    }
}

use crate::undeclared::two_mountings_with_y;

fn errors(d: &Diagnosis, truth: &Truth) -> ErrorSummary {
    ErrorSummary::new(&d.after, truth).unwrap()
}

/// The clean twin's errors: the same configuration without effects, diagnosed.
fn clean_twin(config: &SimulationConfig) -> ErrorSummary {
    let clean = SimulationConfig {
        effects: Vec::new(),
        ..config.clone()
    };
    let (set, truth) = simulate(&clean).unwrap();
    errors(
        &diagnose(&set, &DiagnoseOptions::default()).unwrap(),
        &truth,
    )
}

fn within(after: &ErrorSummary, reference: &ErrorSummary, factor: f64) -> bool {
    after.pitch_rms <= factor * reference.pitch_rms + 0.002
        && after.encoder_rms <= factor * reference.encoder_rms + 0.002
}

fn cross_talk_effects(both: bool) -> Vec<Effect> {
    let mut effects = vec![Effect::CrossTalk { ac: 1, value: 0.01 }];
    if both {
        effects.push(Effect::CrossTalk {
            ac: 2,
            value: -0.006,
        });
    }
    effects
}

/// Cross-talk on one and on both autocollimators: status 1 with `alternatives` in at
/// least 95 % of 20 seeds; the alternative moves β by more than its expanded
/// uncertainty (by c·Y, tenths of an arcsecond here).
#[test]
fn cross_talk_the_data_cannot_place_is_not_certified() {
    for both in [false, true] {
        let mut flagged = 0;
        for seed in 0..20 {
            let config = two_mountings_with_y(300 + seed, cross_talk_effects(both));
            let (set, _) = simulate(&config).unwrap();
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            let finding = d
                .effects
                .iter()
                .find(|f| matches!(f.effect, Effect::CrossTalk { .. }));
            if let Some(f) = finding
                && !d.adequacy.adequate
                && f.ambiguous()
            {
                let alternative = &f.alternatives[0];
                assert!(
                    matches!(alternative.effects[0], Effect::CrossTalk { .. }),
                    "{alternative:?}"
                );
                assert!(alternative.pitch_change_max > 0.03, "{alternative:?}");
                assert!(
                    d.notes.iter().any(|n| n.contains("cannot tell")),
                    "{:?}",
                    d.notes
                );
                flagged += 1;
            }
        }
        eprintln!("cross-talk (both: {both}): {flagged} of 20 not certified");
        assert!(flagged >= 19, "both: {both}: {flagged} of 20");
    }
}

/// With autocollimator 2's cross-talk stated (0 when only 1 has cross-talk; −0.006 when
/// both have, its readings corrected by it): adequate and errors within 2× the clean
/// twin's in at least 95 % of 20 seeds.
#[test]
fn stated_cross_talk_decides_it() {
    for both in [false, true] {
        let mut good = 0;
        for seed in 0..20 {
            let config = two_mountings_with_y(300 + seed, cross_talk_effects(both));
            let (mut set, truth) = simulate(&config).unwrap();
            let stated = if both { -0.006 } else { 0.0 };
            for r in set.readings.iter_mut().filter(|r| r.ac == 2) {
                r.reading_arcsec -= stated * r.reading_y_arcsec.unwrap();
            }
            let options = DiagnoseOptions::default().with_stated_cross_talk(vec![2]);
            let d = diagnose(&set, &options).unwrap();
            let found = d
                .effects
                .iter()
                .any(|f| matches!(f.effect, Effect::CrossTalk { ac: 1, .. }));
            assert!(
                !found || d.notes.iter().any(|n| n.contains("follows from the data")),
                "{:?}",
                d.notes
            );
            if found
                && d.adequacy.adequate
                && within(&errors(&d, &truth), &clean_twin(&config), 2.0)
            {
                good += 1;
            }
        }
        eprintln!(
            "stated cross-talk (both: {both}): {good} of 20 adequate and near the clean twin"
        );
        assert!(good >= 19, "both: {both}: {good} of 20");
    }
}

/// Autocollimator 1 re-zeroed at the start of every cycle (`simulate --rezero 1:0.3`):
/// found as one `rezero` term whose offsets against the first cycle are each within 4 u
/// of the drawn ones, adequate, errors within 1.3× the clean twin's, in at least 95 % of
/// 20 seeds.
#[test]
fn a_zero_set_anew_every_cycle_is_one_term() {
    let mut good = 0;
    for seed in 0..20 {
        let config = SimulationConfig {
            rezero: vec![RezeroSpec {
                ac: 1,
                sigma_arcsec: 0.3,
            }],
            ..base(400 + seed)
        };
        let (set, truth) = simulate(&config).unwrap();
        let Some(Effect::Rezero { offsets, .. }) = truth.effects.first() else {
            panic!("the truth carries the drawn offsets: {:?}", truth.effects);
        };
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let Some(found) = d
            .effects
            .iter()
            .find(|f| matches!(f.effect, Effect::Rezero { ac: 1, .. }))
        else {
            continue;
        };
        if let Effect::Rezero {
            offsets: fitted,
            offsets_u: Some(u),
            ..
        } = &found.effect
        {
            for c in 1..6 {
                let truth_offset = offsets[c] - offsets[0];
                assert!(
                    (fitted[c] - truth_offset).abs() <= 4.0 * u[c],
                    "cycle {}: {} vs {truth_offset} (u {})",
                    c + 1,
                    fitted[c],
                    u[c]
                );
            }
        }
        let clean = SimulationConfig {
            rezero: Vec::new(),
            ..config.clone()
        };
        if d.adequacy.adequate && within(&errors(&d, &truth), &clean_twin(&clean), 1.3) {
            good += 1;
        }
    }
    eprintln!("rezero: {good} of 20 found, adequate and near the clean twin");
    assert!(good >= 19, "{good} of 20");
}

/// A 2″/h drift of autocollimator 2 in a file without `time`: found on the stop clock
/// (its value 2″/h × 20 s per stop = 0.0111″/stop within 3 u), errors within 1.3× a fit
/// told the true drift shape, in at least 95 % of 20 seeds.
#[test]
fn a_drift_without_a_clock_runs_on_the_stop_order() {
    let mut good = 0;
    for seed in 0..20 {
        let drift = Effect::Drift {
            ac: 2,
            value: 2.0,
            quadratic: None,
        };
        let config = SimulationConfig {
            effects: vec![drift.clone()],
            ..base(500 + seed)
        };
        let (timed, truth) = simulate(&config).unwrap();
        let (set, _) = simulate(&SimulationConfig {
            no_time: true,
            ..config.clone()
        })
        .unwrap();
        assert!(set.readings.iter().all(|r| r.time_seconds.is_none()));
        let column: Vec<f64> = timed
            .readings
            .iter()
            .map(|r| {
                if r.ac == 2 {
                    r.time_seconds.unwrap()
                } else {
                    0.0
                }
            })
            .collect();
        let oracle = ErrorSummary::new(
            &least_squares_with_regressors(&timed, &[column], None).unwrap(),
            &truth,
        )
        .unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        assert_eq!(d.clock, Clock::StopOrder);
        let Some(found) = d
            .effects
            .iter()
            .find(|f| matches!(f.effect, Effect::Drift { ac: 2, .. }))
        else {
            continue;
        };
        let per_stop = 2.0 * 20.0 / 3600.0;
        let u = found.u.unwrap();
        assert!(
            (found.effect.value() - per_stop).abs() <= 3.0 * u,
            "{} vs {per_stop} (u {u})",
            found.effect.value()
        );
        if within(&errors(&d, &truth), &oracle, 1.3) {
            good += 1;
        }
    }
    eprintln!("drift without time: {good} of 20 found and near the true shape's fit");
    assert!(good >= 19, "{good} of 20");
}

/// A wandering zero (0.25″/√h on both autocollimators) over 40 seeds: the final
/// encoder error is not worse than the base model's by more than 10 % + 3 mas in at least
/// 90 % of them.
#[test]
fn a_wandering_zero_does_no_harm() {
    let mut not_worse = 0;
    for seed in 0..40 {
        let walk = |ac| RandomWalkSpec {
            ac,
            rate_arcsec_per_sqrt_h: 0.25,
        };
        let config = SimulationConfig {
            random_walk: vec![walk(1), walk(2)],
            ..base(100 + seed)
        };
        let (set, truth) = simulate(&config).unwrap();
        let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
        let before = ErrorSummary::new(&d.before, &truth).unwrap();
        let after = errors(&d, &truth);
        if after.encoder_rms <= 1.1 * before.encoder_rms + 0.003 {
            not_worse += 1;
        }
    }
    eprintln!("random walk: {not_worse} of 40 not worse than the base model");
    assert!(not_worse >= 36, "{not_worse} of 40");
}

/// False alarms over 100 clean seeds of each design: with and without `time`, with
/// `reading_y` in two mountings, and three autocollimators. A false alarm is any
/// effect other than an outlier, or an ambiguous finding; a verdict "not adequate" is
/// counted apart, also at most 5 %.
#[test]
fn clean_runs_of_four_designs_rarely_get_a_false_effect() {
    type Design = (&'static str, fn(u64) -> SimulationConfig, bool);
    let designs: [Design; 4] = [
        ("with time", base, false),
        ("without time", base, true),
        (
            "reading_y in two mountings",
            |s| two_mountings_with_y(s, Vec::new()),
            false,
        ),
        (
            "three autocollimators",
            |s| SimulationConfig {
                ac_faces: vec![1, 2, 4],
                ..base(s)
            },
            false,
        ),
    ];
    for (name, config, strip_time) in designs {
        let (mut alarms, mut inadequate) = (0, 0);
        for seed in 0..100 {
            let c = SimulationConfig {
                no_time: strip_time,
                ..config(2000 + seed)
            };
            let (set, _) = simulate(&c).unwrap();
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            if d.effects
                .iter()
                .any(|f| !matches!(f.effect, Effect::Outlier { .. }) || f.ambiguous())
            {
                alarms += 1;
            }
            inadequate += usize::from(!d.adequacy.adequate);
        }
        eprintln!(
            "clean, {name}: {alarms} of 100 with a false effect, {inadequate} called inadequate"
        );
        assert!(alarms <= 5, "{name}: {alarms} of 100");
        assert!(inadequate <= 5, "{name}: {inadequate} of 100 inadequate");
    }
}

/// With one clockwise and one counter-clockwise cycle, a direction offset of
/// autocollimator 2 and a jump of its zero from the start of cycle 2 are the same column
/// (issue 35): whichever is found carries the other as an exact equivalent — fitted as
/// well, the calibration unchanged — and the verdict stays adequate. Injected both ways,
/// five seeds each.
#[test]
fn a_direction_offset_and_a_jump_at_the_ccw_cycle_name_each_other_as_equivalent() {
    let direction = |e: &Effect| matches!(e, Effect::Direction { ac: Some(2), .. });
    let jump = |e: &Effect| {
        matches!(
            e,
            Effect::OffsetStep {
                ac: 2,
                cycle: 2,
                step: None,
                ..
            }
        )
    };
    let injected = [
        Effect::Direction {
            ac: Some(2),
            value: 0.4,
        },
        Effect::OffsetStep {
            ac: 2,
            cycle: 2,
            step: None,
            setup: None,
            value: 0.4,
        },
    ];
    for effect in injected {
        for seed in 1..=5u64 {
            let config = SimulationConfig {
                faces: 12,
                cycles: 2,
                closing: true,
                bidirectional: true,
                noise_arcsec: 0.05,
                effects: vec![effect.clone()],
                ..base(seed)
            };
            let (set, _) = simulate(&config).unwrap();
            let d = diagnose(&set, &DiagnoseOptions::default()).unwrap();
            let found = d
                .effects
                .iter()
                .find(|f| direction(&f.effect) || jump(&f.effect))
                .unwrap_or_else(|| panic!("{effect:?}, seed {seed}: {:#?}", d.effects));
            let other: &dyn Fn(&Effect) -> bool = if direction(&found.effect) {
                &jump
            } else {
                &direction
            };
            let equivalent = found
                .alternatives
                .iter()
                .find(|a| a.effects.len() == 1 && other(&a.effects[0]))
                .unwrap_or_else(|| {
                    panic!(
                        "{effect:?}, seed {seed}: no equivalent: {:#?}",
                        found.alternatives
                    )
                });
            assert!(equivalent.equivalent, "{equivalent:?}");
            assert!(equivalent.change_over_expanded_u < 1e-6, "{equivalent:?}");
            assert!(
                (equivalent.effects[0].value() - found.effect.value()).abs() < 1e-9,
                "{equivalent:?} vs {:?}",
                found.effect
            );
            assert!(!found.ambiguous());
            assert!(d.adequacy.adequate, "{effect:?}, seed {seed}");
        }
    }
}
