//! A cycle against the others (issue 53, items 1–2): a cycle logged wrongly in a realistic
//! run (tests/fault_runs, a generator written for issue 53 apart from polycal's
//! `simulate`) is named and undone, and then ends within 2× its clean twin's error; a
//! diagnosis never says adequate while β or α is far from the truth; the clean twins keep
//! the cycle test's stated false-alarm rate.

use crate::fault_runs;

use crate::fault_runs::{Fault, Pair, Run, error, generate};
use polycal::diagnose::cycles::{CYCLE_ALPHA, CycleAction, CycleCause, disagreeing_cycles};
use polycal::diagnose::{DiagnoseOptions, Diagnosis, diagnose};
use rayon::prelude::*;

/// The errors (RMS) of β and α of a fit against the truth.
fn errors(d: &Diagnosis, pair: &Pair, after: bool) -> (f64, f64) {
    let fit = if after { &d.after } else { &d.before };
    (
        error(&fit.pitch_deviation, &pair.truth.pitch_deviation).0,
        error(&fit.encoder_error, &pair.truth.encoder_error).0,
    )
}

/// The runs of a kind: 24 faces, 2 or 3 autocollimators, 4–6 cycles with closing
/// readings, noise 0.03–0.06″, the fault in cycle 3 (or 2).
fn runs(seeds: u64) -> Vec<(Run, u64)> {
    (0..seeds)
        .map(|k| {
            let mut run = Run::typical(
                4 + (k % 3) as u32,
                [0.03, 0.045, 0.06][(k / 3 % 3) as usize],
            );
            if k % 2 == 1 {
                run.face_offsets = vec![0, 1, 5];
            }
            (run, 5300 + k)
        })
        .collect()
}

/// One run's outcome.
#[derive(Debug)]
struct Outcome {
    named: bool,
    adequate: bool,
    after: (f64, f64),
    before: (f64, f64),
    twin: (f64, f64),
    line: String,
}

fn outcome(run: &Run, seed: u64, fault: &Fault, is_cause: impl Fn(CycleCause) -> bool) -> Outcome {
    let cycle = fault_runs::fault_cycle(fault).expect("a logging fault");
    let pair = generate(run, fault, seed);
    let options = DiagnoseOptions::default();
    let d = diagnose(&pair.faulty, &options).expect("a diagnosis");
    let t = diagnose(&pair.twin, &options).expect("a diagnosis of the twin");
    let named = d
        .cycles
        .iter()
        .any(|c| c.cycle == cycle && is_cause(c.cause) && c.action == CycleAction::Repaired)
        && d.cycles.len() == 1;
    let o = Outcome {
        named,
        adequate: d.adequacy.adequate,
        after: errors(&d, &pair, true),
        before: errors(&d, &pair, false),
        twin: errors(&t, &pair, true),
        line: String::new(),
    };
    let line = format!(
        "seed {seed} acs {} cycles {} σ {}: named {} adequate {} β {:.4}/{:.4} (twin {:.4}) α {:.4}/{:.4} (twin {:.4}) cycles {:?} effects {:?}",
        run.face_offsets.len(),
        run.cycles,
        run.sigma,
        o.named,
        o.adequate,
        o.before.0,
        o.after.0,
        o.twin.0,
        o.before.1,
        o.after.1,
        o.twin.1,
        d.cycles
            .iter()
            .map(|c| (
                c.cycle,
                c.cause.as_str(),
                c.action.as_str(),
                c.f_statistic as i64
            ))
            .collect::<Vec<_>>(),
        d.effects
            .iter()
            .map(|e| e.effect.label())
            .collect::<Vec<_>>()
    );
    Outcome { line, ..o }
}

fn far(e: (f64, f64), twin: (f64, f64)) -> bool {
    e.0 > 2.0 * twin.0 + 0.01 || e.1 > 2.0 * twin.1 + 0.01
}

/// The acceptance of one kind of logging error over `seeds` runs.
fn kind(
    name: &str,
    fault: impl Fn(u32) -> Fault + Sync,
    is_cause: impl Fn(CycleCause) -> bool + Sync,
) {
    let runs = runs(12);
    let outcomes: Vec<Outcome> = runs
        .par_iter()
        .enumerate()
        .map(|(k, (run, seed))| outcome(run, *seed, &fault(2 + (k % 2) as u32), &is_cause))
        .collect();
    for o in &outcomes {
        println!("{name}: {}", o.line);
    }
    let n = outcomes.len();
    let named = outcomes.iter().filter(|o| o.named).count();
    let named_and_close = outcomes
        .iter()
        .filter(|o| o.named && !far(o.after, o.twin))
        .count();
    println!(
        "{name}: named and repaired in {named} of {n}, then within 2× the twin in {named_and_close}"
    );
    assert!(
        named_and_close as f64 >= 0.9 * n as f64,
        "{name}: named, repaired and within 2× the twin's error + 0.01″ in {named_and_close} of {n}"
    );
    for o in &outcomes {
        assert!(
            !(o.adequate && far(o.after, o.twin)),
            "{name}: adequate while far from the truth: {}",
            o.line
        );
    }
    let worse = outcomes
        .iter()
        .filter(|o| o.after.0 > 1.1 * o.before.0 || o.after.1 > 1.1 * o.before.1)
        .count();
    assert!(
        worse * 10 <= n,
        "{name}: after worse than before by more than 10 % in {worse} of {n}"
    );
}

#[test]
fn swapped_autocollimators_are_named_and_undone() {
    kind(
        "swapped-acs",
        |cycle| Fault::SwappedAcs { cycle, a: 1, b: 2 },
        |c| c == CycleCause::SwappedAcs { a: 1, b: 2 },
    );
}

#[test]
fn a_cycle_logged_one_stop_late_is_named_and_undone() {
    kind(
        "one-stop-late",
        |cycle| Fault::OneStopLate { cycle },
        |c| c == CycleCause::OneStopLate,
    );
}

#[test]
fn a_cycle_logged_one_stop_early_is_named_and_undone() {
    kind(
        "one-stop-early",
        |cycle| Fault::OneStopEarly { cycle },
        |c| c == CycleCause::OneStopEarly,
    );
}

#[test]
fn a_cycle_on_shifted_faces_is_named_and_undone() {
    kind(
        "faces-shifted +1",
        |cycle| Fault::FacesShifted { cycle, by: 1 },
        |c| c == CycleCause::FacesShifted { by: 1 },
    );
    kind(
        "faces-shifted −1",
        |cycle| Fault::FacesShifted { cycle, by: -1 },
        |c| c == CycleCause::FacesShifted { by: -1 },
    );
}

#[test]
fn a_reversed_cycle_is_named_and_undone() {
    kind(
        "reversed",
        |cycle| Fault::Reversed { cycle },
        |c| c == CycleCause::Reversed,
    );
}

/// The clean twins: the share of runs in which some cycle is said to disagree, against
/// the stated level [`CYCLE_ALPHA`] for the run (± 1.5 % with 1 200 runs).
#[test]
fn clean_runs_keep_the_cycle_tests_false_alarm_rate() {
    let runs = runs(1200);
    let flagged: Vec<(bool, bool)> = runs
        .par_iter()
        .map(|(run, seed)| {
            let pair = generate(run, &Fault::None, seed + 1_000_000);
            let d = diagnose(&pair.twin, &DiagnoseOptions::default()).expect("a diagnosis");
            (
                !disagreeing_cycles(&pair.twin).is_empty(),
                !d.cycles.is_empty(),
            )
        })
        .collect();
    let n = flagged.len() as f64;
    let rate = flagged.iter().filter(|f| f.0).count() as f64 / n;
    let listed = flagged.iter().filter(|f| f.1).count() as f64 / n;
    println!(
        "cycle test on {} clean runs: a cycle disagrees in {rate:.4} (level {CYCLE_ALPHA}); listed (repaired or set aside) in {listed:.4}",
        flagged.len()
    );
    assert!(listed <= rate, "listed {listed} beyond the test's {rate}");
    assert!(
        (rate - CYCLE_ALPHA).abs() <= 0.015,
        "false-alarm rate {rate:.4} against the level {CYCLE_ALPHA}"
    );
}

/// A cycle whose first autocollimator read nonsense (0.5″ RMS of extra scatter) is no
/// usual logging error: it is set aside as unexplained, every one of its readings
/// accounted for, the verdict is not adequate, and the result ends near the twin's.
#[test]
fn a_cycle_no_cause_explains_is_set_aside() {
    for (k, (run, seed)) in runs(6).into_iter().enumerate() {
        let pair = generate(&run, &Fault::None, seed + 77);
        let mut faulty = pair.twin.clone();
        let mut in_cycle = 0;
        for (i, r) in faulty.readings.iter_mut().enumerate() {
            if r.cycle == 3 && r.ac == 1 {
                // a deterministic scatter of about 0.5″ RMS
                r.reading_arcsec += 0.7 * (((i * 7919 + k * 31) % 97) as f64 / 48.0 - 1.0);
            }
            if r.cycle == 3 {
                in_cycle += 1;
            }
        }
        let d = diagnose(&faulty, &DiagnoseOptions::default()).expect("a diagnosis");
        let t = diagnose(&pair.twin, &DiagnoseOptions::default()).expect("a diagnosis");
        assert_eq!(d.cycles.len(), 1, "{:?}", d.cycles);
        let c = &d.cycles[0];
        assert_eq!(
            (c.cycle, c.cause, c.action),
            (3, CycleCause::Unexplained, CycleAction::SetAside)
        );
        assert_eq!(c.set_aside.len(), in_cycle);
        assert!(!d.adequacy.adequate);
        let e = errors(&d, &pair, true);
        let et = errors(&t, &pair, true);
        assert!(!far(e, et), "β, α {e:?} against the twin's {et:?}");
    }
}

/// The JSON and the table say which cycle was repaired, why, and what left the fit; a
/// clean run's JSON has an empty `cycles`.
#[test]
fn the_report_names_the_cycle_its_cause_and_the_reading_set_aside() {
    let (run, seed) = runs(1)[0].clone();
    let pair = generate(&run, &Fault::OneStopLate { cycle: 3 }, seed);
    let d = diagnose(&pair.faulty, &DiagnoseOptions::default()).expect("a diagnosis");
    let json = polycal::output::diagnose::DiagnoseReport::new(&d, None, None)
        .to_json()
        .expect("JSON");
    let value: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    let cycles = value["cycles"].as_array().expect("cycles");
    assert_eq!(cycles.len(), 1);
    let c = &cycles[0];
    assert_eq!(c["setup"], 1);
    assert_eq!(c["cycle"], 3);
    assert_eq!(c["cause"], "one-stop-late");
    assert_eq!(c["action"], "repaired");
    assert_eq!(c["consistent"], false);
    assert!(c["statistic"].as_f64().expect("F") > 10.0);
    assert!(c["p"].as_f64().expect("p") < 1e-6);
    // the first stop's values (one per autocollimator) belong to the stop before the cycle
    let aside = c["set_aside"].as_array().expect("set_aside");
    assert_eq!(aside.len(), run.face_offsets.len());
    assert!(aside.iter().all(|r| r["step"] == 0 && r["cycle"] == 3));
    let mut table = String::new();
    polycal::output::diagnose_table::write_table(&mut table, &d, None, "late.csv")
        .expect("a table");
    assert!(table.contains("setup 1 cycle 3"), "{table}");
    assert!(table.contains("one-stop-late; repaired"), "{table}");

    let clean = diagnose(&pair.twin, &DiagnoseOptions::default()).expect("a diagnosis");
    let json = polycal::output::diagnose::DiagnoseReport::new(&clean, None, None)
        .to_json()
        .expect("JSON");
    let value: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    assert_eq!(value["cycles"], serde_json::json!([]));
}
