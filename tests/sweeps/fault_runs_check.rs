//! The generator of tests/fault_runs (issue 53) checked against its own truth: the clean
//! twin solves to the truth within its uncertainties, and each logging fault moves the
//! calibration, so that the tests built on it can fail.

use crate::fault_runs::{Fault, Run, error, generate};
use polycal::solve::{SolveOptions, solve};

/// The twin's errors are of the size its uncertainties say (RMS error below 2.5 × RMS u).
fn within_u(fit: &polycal::solve::Solution, pitch_rms: f64, encoder_rms: f64, fault: &Fault) {
    let rms = |v: Vec<f64>| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let pitch_u = rms(fit.pitch_deviation_u().expect("dof > 0"));
    let encoder_u = rms(fit.encoder_error_u().expect("dof > 0"));
    assert!(
        pitch_rms < 2.5 * pitch_u && encoder_rms < 2.5 * encoder_u,
        "{fault:?}: β error {pitch_rms} (u {pitch_u}), α error {encoder_rms} (u {encoder_u})"
    );
}

#[test]
fn the_twin_solves_to_the_truth_and_each_fault_moves_it() {
    let run = Run::typical(5, 0.04);
    let faults = [
        Fault::SwappedAcs {
            cycle: 3,
            a: 1,
            b: 2,
        },
        Fault::OneStopLate { cycle: 3 },
        Fault::OneStopEarly { cycle: 2 },
        Fault::FacesShifted { cycle: 4, by: 1 },
        Fault::Reversed { cycle: 3 },
    ];
    for (seed, fault) in faults.iter().enumerate() {
        let pair = generate(&run, fault, 100 + seed as u64);
        let twin = solve(&pair.twin, &SolveOptions::new()).expect("the twin solves");
        let (pitch_rms, _) = error(&twin.pitch_deviation, &pair.truth.pitch_deviation);
        let (encoder_rms, _) = error(&twin.encoder_error, &pair.truth.encoder_error);
        within_u(&twin, pitch_rms, encoder_rms, fault);
        let rms = twin.residual_rms().expect("dof > 0");
        assert!((rms - 0.04).abs() < 0.01, "{fault:?}: residual RMS {rms}");
        let faulty = solve(&pair.faulty, &SolveOptions::new()).expect("the faulty run solves");
        let faulty_rms = faulty.residual_rms().expect("dof > 0");
        assert!(
            faulty_rms > 2.0 * rms,
            "{fault:?}: the fault leaves {faulty_rms} against {rms}"
        );
    }
}

#[test]
fn instrument_faults_leave_the_twin_clean() {
    let run = Run::typical(6, 0.04);
    for fault in [
        Fault::NoiseRise {
            ac: 2,
            from_cycle: 4,
            factor: 3.0,
        },
        Fault::KinkedDrift {
            ac: 1,
            rate_before: 1.2,
            rate_after: -0.4,
            kink_seconds: 2100.0,
        },
        Fault::Interpolation {
            period_arcsec: 39.6,
            amplitude: 0.2,
            stop_within_arcsec: 6.0,
        },
    ] {
        let pair = generate(&run, &fault, 7);
        let twin = solve(&pair.twin, &SolveOptions::new()).expect("the twin solves");
        let (pitch_rms, _) = error(&twin.pitch_deviation, &pair.truth.pitch_deviation);
        let (encoder_rms, _) = error(&twin.encoder_error, &pair.truth.encoder_error);
        within_u(&twin, pitch_rms, encoder_rms, &fault);
        let faulty = solve(&pair.faulty, &SolveOptions::new()).expect("the faulty run solves");
        let rms = twin.residual_rms().expect("dof > 0");
        let faulty_rms = faulty.residual_rms().expect("dof > 0");
        assert!(
            faulty_rms > 1.2 * rms,
            "{fault:?}: the fault leaves {faulty_rms} against {rms}"
        );
    }
}
