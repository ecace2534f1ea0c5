//! u(α) honest beyond the band limit (issue 53, item 5): the scatter the autocollimators
//! share at a stop is measured and carried into u(α), so that 2u(α) covers the encoder
//! errors of a table that stops off its nominal angles over an interpolation error far
//! above N/2; and its test keeps its level on clean runs. The runs come from
//! tests/fault_runs, written for these tests.

use crate::fault_runs::{Fault, Run, generate};
use polycal::diagnose::stop_scatter::STOP_SCATTER_ALPHA;
use polycal::diagnose::{DiagnoseOptions, diagnose};
use rayon::prelude::*;

/// The fraction of α errors within 2u(α), over `seeds` runs, with and without the scatter.
fn coverage(run: &Run, fault: &Fault, seeds: std::ops::Range<u64>) -> (f64, f64, usize, usize) {
    let results: Vec<(usize, usize, usize, bool)> = seeds
        .into_par_iter()
        .map(|seed| {
            let pair = generate(run, fault, seed);
            let diagnosis = diagnose(&pair.faulty, &DiagnoseOptions::default()).expect("diagnoses");
            let after = &diagnosis.after;
            let u = after.encoder_error_u().expect("σ known");
            let u_fit = diagnosis.before.encoder_error_u().expect("σ known");
            let mut covered = 0;
            let mut covered_fit = 0;
            for ((a, t), (u, uf)) in after
                .encoder_error
                .iter()
                .zip(&pair.truth.encoder_error)
                .zip(u.iter().zip(&u_fit))
            {
                if (a - t).abs() <= 2.0 * u {
                    covered += 1;
                }
                if (a - t).abs() <= 2.0 * uf {
                    covered_fit += 1;
                }
            }
            let significant = diagnosis
                .stop_scatter
                .as_ref()
                .is_some_and(|s| s.significant);
            // what no position can attribute is not certified
            assert!(
                !(significant && diagnosis.adequacy.adequate),
                "adequate with a scatter"
            );
            (covered, covered_fit, u.len(), significant)
        })
        .collect();
    let total: usize = results.iter().map(|r| r.2).sum();
    let covered: usize = results.iter().map(|r| r.0).sum();
    let covered_fit: usize = results.iter().map(|r| r.1).sum();
    let found = results.iter().filter(|r| r.3).count();
    (
        covered as f64 / total as f64,
        covered_fit as f64 / total as f64,
        found,
        results.len(),
    )
}

/// A 39.6″ interpolation error of 0.3″ amplitude under a table that stops within ±6″ of
/// its nominal angles: the fit's u(α) alone covers 80 % with three autocollimators (the
/// issue's 78 %); carried into u(α), the scatter the stops share makes 2u(α) cover every
/// design at ≥ 93 %, and it is found in every run, which is then not adequate.
#[test]
fn two_u_alpha_covers_the_encoder_error_a_table_samples_off_its_angles() {
    let fault = Fault::Interpolation {
        period_arcsec: 39.6,
        amplitude: 0.3,
        stop_within_arcsec: 6.0,
    };
    for (run, seeds, fit_alone_covers) in [
        (Run::typical(4, 0.03), 0..40, true),
        (Run::typical(6, 0.05), 100..140, true),
        (
            Run {
                face_offsets: vec![0, 1, 5],
                ..Run::typical(5, 0.04)
            },
            200..240,
            false,
        ),
    ] {
        let (covered, covered_fit, found, runs) = coverage(&run, &fault, seeds);
        eprintln!(
            "{} acs, {} cycles, σ {}: scatter found in {found} of {runs}; 2u(α) covers {covered:.3} (the fit's u alone {covered_fit:.3})",
            run.face_offsets.len(),
            run.cycles,
            run.sigma
        );
        assert_eq!(found, runs);
        assert!(covered >= 0.93, "coverage {covered}");
        // the runs where the fit's u alone falls short show that the test can fail
        assert_eq!(
            covered_fit >= 0.93,
            fit_alone_covers,
            "the fit's u alone covers {covered_fit}"
        );
    }
}

#[test]
fn the_test_of_a_shared_scatter_keeps_its_level_on_clean_runs() {
    let run = Run::typical(4, 0.04);
    let runs = 1000u64;
    // (a run whose equal-noise test fails is weighted, and its scatter not evaluated: a
    // few in a thousand clean runs)
    let called: Vec<Option<bool>> = (0..runs)
        .into_par_iter()
        .map(|seed| {
            let pair = generate(&run, &Fault::None, 10_000 + seed);
            let diagnosis = diagnose(&pair.twin, &DiagnoseOptions::default()).expect("diagnoses");
            diagnosis.stop_scatter.map(|s| s.significant)
        })
        .collect();
    let evaluated = called.iter().flatten().count();
    let alarms = called.iter().flatten().filter(|&&s| s).count();
    assert!(
        evaluated as u64 >= runs - 10,
        "evaluated in {evaluated} of {runs}"
    );
    let rate = alarms as f64 / evaluated as f64;
    eprintln!(
        "a shared scatter called on {alarms} of {evaluated} clean runs evaluated ({rate:.4}, level {STOP_SCATTER_ALPHA})"
    );
    assert!((rate - STOP_SCATTER_ALPHA).abs() <= 0.015, "rate {rate}");
}
