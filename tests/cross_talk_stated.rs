//! Cross-talk stated from an autocollimator's calibration (`--cross-talk AC:C[:U]`,
//! docs/FORMAT.md §6): the correction is exact, and its U enters the budget as the
//! propagation through the design says (checked by finite differences of the solver).
//! That it decides a cross-talk the closure alone cannot place is tested on the command
//! line in `diagnose_cli_identify.rs`.

use polycal::effects::Effect;
use polycal::measurement::cross_talk::{StatedCrossTalk, correct_cross_talk};
use polycal::simulate::{SimulationConfig, simulate};
use polycal::solve::{SolveOptions, solve};
use polycal::uncertainty::calibration::{
    InstrumentBudget, KnownCorrection, evaluate, evaluate_with_corrections,
};

mod undeclared;

fn config(effects: Vec<Effect>) -> SimulationConfig {
    undeclared::two_mountings_with_y(11, effects)
}

/// Corrected with the true coefficient, the readings are the clean twin's (the simulator
/// adds C·reading_y as written), and so is the solution.
#[test]
fn the_correction_with_the_true_coefficient_gives_the_clean_twin() {
    let (set, _) = simulate(&config(vec![Effect::CrossTalk { ac: 1, value: 0.01 }])).unwrap();
    let (clean, _) = simulate(&config(Vec::new())).unwrap();
    let stated = StatedCrossTalk::new(1, 0.01, None).unwrap();
    let corrected = correct_cross_talk(&set, &[stated]).unwrap();
    for (c, k) in corrected.readings.iter().zip(&clean.readings) {
        assert!((c.reading_arcsec - k.reading_arcsec).abs() < 1e-12);
    }
    let a = solve(&corrected, &SolveOptions::default()).unwrap();
    let b = solve(&clean, &SolveOptions::default()).unwrap();
    for (x, y) in a.encoder_error.iter().zip(&b.encoder_error) {
        assert!((x - y).abs() < 1e-9);
    }
}

/// u_j = U·|∂θ_j/∂C|: the component of a stated U equals U times the change of every β
/// and α per unit of C, taken by finite differences of the solver on the corrected
/// readings; the other components are those of the budget without it.
#[test]
fn a_stated_u_enters_the_budget_through_the_design() {
    let (set, _) = simulate(&config(vec![Effect::CrossTalk { ac: 1, value: 0.01 }])).unwrap();
    let budget = InstrumentBudget::read_path("examples/budgets/instrument.toml").unwrap();
    let (c, u, delta) = (0.01, 0.001, 1e-4);
    let stated = StatedCrossTalk::new(1, c, Some(u)).unwrap();
    let corrected = correct_cross_talk(&set, &[stated]).unwrap();
    let moved =
        correct_cross_talk(&set, &[StatedCrossTalk::new(1, c + delta, None).unwrap()]).unwrap();
    let base = solve(&corrected, &SolveOptions::default()).unwrap();
    let shifted = solve(&moved, &SolveOptions::default()).unwrap();
    let correction = KnownCorrection::new("stated", u, stated.column(&corrected));
    let with = evaluate_with_corrections(&corrected, &base, &budget, &[correction]).unwrap();
    let without = evaluate(&corrected, &base, &budget).unwrap();
    assert_eq!(with.components.len(), without.components.len() + 1);
    let component = with.components.last().unwrap();
    for (j, contribution) in component.pitch_deviation.iter().enumerate() {
        let expected = u * (shifted.pitch_deviation[j] - base.pitch_deviation[j]).abs() / delta;
        assert!(
            (contribution - expected).abs() < 1e-7,
            "β{j}: {contribution} vs {expected}"
        );
    }
    for (j, contribution) in component.encoder_error.iter().enumerate() {
        let expected = u * (shifted.encoder_error[j] - base.encoder_error[j]).abs() / delta;
        assert!(
            (contribution - expected).abs() < 1e-7,
            "α{j}: {contribution} vs {expected}"
        );
    }
    // combined in quadrature with the rest
    for j in 0..base.faces {
        let (w, o, c) = (
            with.encoder_error.u[j],
            without.encoder_error.u[j],
            component.encoder_error[j],
        );
        assert!((w * w - o * o - c * c).abs() < 1e-12, "{w} {o} {c}");
    }
}

/// Specs and refusals.
#[test]
fn stated_cross_talk_is_read_and_checked() {
    let s: StatedCrossTalk = "2:0.004:0.0005".parse().unwrap();
    assert_eq!((s.ac, s.coefficient, s.u), (2, 0.004, Some(0.0005)));
    for bad in ["0:0.1", "1", "1:x", "1:2", "1:0.1:-1", "1:0.1:0.1:0.1"] {
        assert!(bad.parse::<StatedCrossTalk>().is_err(), "{bad}");
    }
    let (set, _) = simulate(&SimulationConfig::default()).unwrap();
    let message = correct_cross_talk(&set, &[StatedCrossTalk::new(1, 0.0, None).unwrap()])
        .unwrap_err()
        .to_string();
    assert!(message.contains("no reading_y"), "{message}");
}
