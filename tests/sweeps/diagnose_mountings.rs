//! A whole mounting against the others (issue 53, "the same for a whole mounting"): a
//! mounting whose every cycle was logged wrongly alike — its autocollimators' columns
//! exchanged, its face labels one round, every reading one stop late — agrees with
//! itself, so only the other mountings can show it. In runs of three mountings (24
//! faces, 2–3 autocollimators, 3 cycles, closing readings, noise 0.03–0.06″; the polygon
//! turned 8 faces between mountings) generated here from the paper's model with a known
//! truth, apart from polycal's `simulate`: the fault is named and undone, the run then
//! ends within 2× its clean twin's error, and no run is adequate while worse than that;
//! the clean twins keep the mounting test's stated false-alarm rate.

use crate::fault_runs::{Run, Truth, error, face_deviation, truth};
use polycal::diagnose::cycles::mountings::{MOUNTING_ALPHA, disagreeing_mountings};
use polycal::diagnose::cycles::{CycleAction, CycleCause};
use polycal::diagnose::{DiagnoseOptions, Diagnosis, diagnose};
use polycal::measurement::{Direction, MeasurementSet, Reading, face_at};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;

/// A logging error of a whole mounting (the second or the third).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Fault {
    None,
    /// Autocollimators 1 and 2 exchanged in every cycle of mounting 2.
    SwappedAcs,
    /// Mounting 3's face labels one face round (the file names the face after the one read).
    FacesLabelledOneOn,
    /// Every reading of mounting 2 stored against the stop after the one it was read at.
    OneStopLate,
    /// Mounting 2 read through something no logging error explains: autocollimator 1's
    /// readings carry a pattern over the faces (0.5″, two periods a round) the others lack.
    Unexplained,
}

/// Mountings, the polygon's turn between them (faces), cycles per mounting.
const MOUNTINGS: u32 = 3;
const TURN_FACES: usize = 8;
const CYCLES: u32 = 3;

/// A run of three mountings with `fault`, and its clean twin (the same truth and noise).
fn generate(run: &Run, fault: Fault, seed: u64) -> (MeasurementSet, MeasurementSet, Truth) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let truth = truth(run, &mut rng);
    let n = run.faces;
    let acs = run.face_offsets.len();
    let unit = Normal::new(0.0, 1.0).expect("σ > 0");
    // each mounting's setup errors (the polygon sits anew on the table)
    let setup_error: Vec<Vec<f64>> = (0..MOUNTINGS)
        .map(|_| (0..acs).map(|_| rng.random_range(-2.0..2.0)).collect())
        .collect();
    let mut twin = Vec::new();
    let mut faulty = Vec::new();
    let mut time = 0.0;
    for m in 0..MOUNTINGS {
        let turn = m as usize * TURN_FACES;
        for cycle in 1..=CYCLES {
            let steps: Vec<usize> = (0..=n).collect();
            // the values of this cycle, per stop and autocollimator
            let values: Vec<Vec<f64>> = steps
                .iter()
                .map(|&step| {
                    (0..acs)
                        .map(|j| {
                            let face = face_at(step, run.face_offsets[j] + turn, n);
                            truth.encoder_error[step % n]
                                + face_deviation(&truth, face)
                                + setup_error[m as usize][j]
                                + run.sigma * unit.sample(&mut rng)
                        })
                        .collect()
                })
                .collect();
            for (k, &step) in steps.iter().enumerate() {
                for j in 0..acs {
                    let face = face_at(step, run.face_offsets[j] + turn, n);
                    let line = 2 + twin.len() as u64;
                    let reading = |value: f64, face: usize| Reading {
                        setup: m + 1,
                        cycle,
                        step,
                        ac: j as u32 + 1,
                        face,
                        reading_arcsec: value,
                        direction: Direction::Cw,
                        time_seconds: Some(time),
                        reading_y_arcsec: None,
                        temperature_celsius: None,
                        encoder_degrees: None,
                        line,
                    };
                    twin.push(reading(values[k][j], face));
                    let stored = match fault {
                        Fault::SwappedAcs if m == 1 && j < 2 => Some((values[k][1 - j], face)),
                        Fault::FacesLabelledOneOn if m == 2 => Some((
                            values[k][j],
                            face_at(step, run.face_offsets[j] + turn + 1, n),
                        )),
                        // the first stop stores a stray value (the table not yet at it)
                        Fault::OneStopLate if m == 1 && k == 0 => Some((values[0][j] + 3.0, face)),
                        Fault::OneStopLate if m == 1 => Some((values[k - 1][j], face)),
                        Fault::Unexplained if m == 1 && j == 0 => Some((
                            values[k][j]
                                + 0.5
                                    * (std::f64::consts::TAU * 2.0 * face as f64 / n as f64).sin(),
                            face,
                        )),
                        _ => Some((values[k][j], face)),
                    };
                    if let Some((value, face)) = stored {
                        faulty.push(reading(value, face));
                    }
                }
                time += run.seconds_per_stop;
            }
        }
    }
    let set = |readings, name| {
        MeasurementSet::from_readings(readings, Some(n), name).expect("a valid set")
    };
    (set(faulty, "faulty.csv"), set(twin, "twin.csv"), truth)
}

/// The runs: 2 or 3 autocollimators, noise 0.03–0.06″.
fn run(k: u64) -> Run {
    let mut run = Run::typical(CYCLES, [0.03, 0.045, 0.06][(k % 3) as usize]);
    if k % 2 == 1 {
        run.face_offsets = vec![0, 1, 5];
    }
    run
}

/// The errors (RMS) of β and α of a fit against the truth.
fn errors(d: &Diagnosis, truth: &Truth, after: bool) -> (f64, f64) {
    let fit = if after { &d.after } else { &d.before };
    (
        error(&fit.pitch_deviation, &truth.pitch_deviation).0,
        error(&fit.encoder_error, &truth.encoder_error).0,
    )
}

/// Over 12 seeds of `fault`: how many runs name `cause` and repair the mounting and end
/// within 2× the twin (+ 0.01″); panics when a run is adequate while worse than that.
fn check(fault: Fault, setup: u32, is_cause: impl Fn(CycleCause) -> bool + Sync) {
    let outcomes: Vec<(bool, bool)> = (0..12u64)
        .into_par_iter()
        .map(|k| {
            let (faulty, twin, truth) = generate(&run(k), fault, 7100 + k);
            let options = DiagnoseOptions::default();
            let d = diagnose(&faulty, &options).expect("a diagnosis");
            let t = diagnose(&twin, &options).expect("a diagnosis of the twin");
            let (after, twin_error) = (errors(&d, &truth, true), errors(&t, &truth, true));
            let before = errors(&d, &truth, false);
            let within = after.0 <= 2.0 * twin_error.0 + 0.01 && after.1 <= 2.0 * twin_error.1 + 0.01;
            let named = d.mountings.len() == 1
                && d.mountings[0].setup == setup
                && is_cause(d.mountings[0].cause)
                && d.mountings[0].action == CycleAction::Repaired;
            println!(
                "{fault:?} seed {}: named {named} adequate {} β {:.4}/{:.4} (twin {:.4}) α {:.4}/{:.4} (twin {:.4}) mountings {:?} cycles {}",
                7100 + k,
                d.adequacy.adequate,
                before.0,
                after.0,
                twin_error.0,
                before.1,
                after.1,
                twin_error.1,
                d.mountings.iter().map(|m| (m.setup, m.cause.as_str(), m.action.as_str(), m.f_statistic)).collect::<Vec<_>>(),
                d.cycles.len(),
            );
            assert!(
                !d.adequacy.adequate || within,
                "adequate while β or α is beyond 2× the twin's error + 0.01″ (seed {})",
                7100 + k
            );
            (named, within)
        })
        .collect();
    let repaired = outcomes.iter().filter(|o| o.0 && o.1).count();
    println!("{fault:?}: named, repaired and within 2× the twin in {repaired} of 12");
    assert!(repaired >= 11, "{fault:?}: {repaired} of 12");
}

#[test]
fn a_mounting_with_its_autocollimators_exchanged_is_named_and_undone() {
    check(Fault::SwappedAcs, 2, |c| {
        matches!(c, CycleCause::SwappedAcs { a: 1, b: 2 })
    });
}

#[test]
fn a_mounting_with_its_face_labels_one_round_is_named_and_undone() {
    check(Fault::FacesLabelledOneOn, 3, |c| {
        c == CycleCause::FacesShifted { by: -1 }
    });
}

#[test]
fn a_mounting_logged_one_stop_late_is_named_and_undone() {
    check(Fault::OneStopLate, 2, |c| c == CycleCause::OneStopLate);
}

#[test]
fn an_unexplained_mounting_alone_is_set_aside_and_the_others_kept() {
    // one mounting set aside at a time: the one that disagrees pulls the fit of the
    // others, which must not be set aside beside it
    let outcomes: Vec<bool> = (0..12u64)
        .into_par_iter()
        .map(|k| {
            let (faulty, _, _) = generate(&run(k), Fault::Unexplained, 7300 + k);
            let d = diagnose(&faulty, &DiagnoseOptions::default()).expect("a diagnosis");
            let listed: Vec<(u32, &str)> = d
                .mountings
                .iter()
                .map(|m| (m.setup, m.action.as_str()))
                .collect();
            println!(
                "Unexplained seed {}: mountings {listed:?} adequate {}",
                7300 + k,
                d.adequacy.adequate
            );
            assert!(!d.adequacy.adequate, "seed {}: adequate", 7300 + k);
            // the failed check states the F its level allows (a number, never NaN)
            assert!(
                d.adequacy.checks.iter().all(|c| c.limit.is_finite()),
                "seed {}: a check without a limit: {:?}",
                7300 + k,
                d.adequacy
                    .checks
                    .iter()
                    .map(|c| (c.name.clone(), c.limit))
                    .collect::<Vec<_>>()
            );
            assert!(
                d.mountings.iter().all(|m| m.setup == 2),
                "seed {}: a consistent mounting listed: {listed:?}",
                7300 + k
            );
            listed == [(2, "set-aside")]
        })
        .collect();
    let alone = outcomes.iter().filter(|&&o| o).count();
    println!("Unexplained: mounting 2 alone set aside in {alone} of 12");
    assert!(alone >= 11, "{alone} of 12");
}

#[test]
fn clean_runs_keep_the_mounting_tests_false_alarm_rate() {
    // the raw decision on 1 000 clean runs, and what the diagnosis does on 200 of them
    let runs = 1000u64;
    let fired = (0..runs)
        .into_par_iter()
        .filter(|&k| {
            let (_, twin, _) = generate(&run(k), Fault::None, 9000 + k);
            !disagreeing_mountings(&twin).is_empty()
        })
        .count();
    let rate = fired as f64 / runs as f64;
    let listed = (0..200u64)
        .into_par_iter()
        .filter(|&k| {
            let (_, twin, _) = generate(&run(k), Fault::None, 9000 + k);
            let d = diagnose(&twin, &DiagnoseOptions::default()).expect("a diagnosis");
            !d.mountings.is_empty()
        })
        .count();
    println!(
        "mounting test on {runs} clean runs: a mounting disagrees in {rate:.4} (level {MOUNTING_ALPHA}); listed by the diagnosis in {listed} of 200"
    );
    // within the level ± 1.5 % (docs/verdicts.md)
    assert!(rate <= MOUNTING_ALPHA + 0.015, "{rate}");
    assert!(listed <= 5, "{listed} of 200");
}

#[test]
fn two_mountings_are_not_tested() {
    let (_, twin, _) = generate(&run(0), Fault::None, 1);
    let two: Vec<Reading> = twin
        .readings
        .iter()
        .filter(|r| r.setup <= 2)
        .cloned()
        .collect();
    let two = MeasurementSet::from_readings(two, Some(24), "two.csv").expect("a valid set");
    let d = diagnose(&two, &DiagnoseOptions::default()).expect("a diagnosis");
    assert!(d.mountings.is_empty());
    assert!(disagreeing_mountings(&two).is_empty());
}
