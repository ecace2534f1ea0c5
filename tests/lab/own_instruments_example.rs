//! `examples/own_instruments.rs` (docs/FORMAT.md §7.6, the README's *Your own
//! instruments*): the example's code run here — a run driven through the session by
//! instruments of the example's own, one disturbed reply refused, and the solved pitch
//! deviations against the truth the instruments were built from (tests/sweeps/readme.rs
//! leaves out blocks that run cargo).

#![cfg(feature = "lab")]

#[allow(dead_code)]
#[path = "../../examples/own_instruments.rs"]
mod own_instruments;

#[test]
fn the_example_runs_its_instruments_through_the_session_and_solves_to_the_truth() {
    let ran = own_instruments::run().unwrap();
    // 2 cycles × 13 stops (the closing step) × 2 autocollimators.
    assert_eq!(ran.readings, 52);
    // The gust of air on one reply of autocollimator 2: refused, not stored.
    assert_eq!(ran.refused.len(), 1, "{:?}", ran.refused);
    assert!(ran.refused[0].starts_with("ac2: "), "{:?}", ran.refused);
    assert!(ran.refused[0].contains("does not agree with the readings after it"));
    // Each cycle's first stop from a pre-position, then one move a stop.
    assert_eq!(ran.moves, 2 * 13 + 2);
    // β within twice the reading noise (0.02″) of the truth on every face (the example's
    // noise is drawn from a fixed seed: the largest error is 0.023″).
    assert_eq!(ran.pitch_deviation.len(), 12);
    for (beta, truth) in ran.pitch_deviation.iter().zip(&ran.truth) {
        assert!((beta - truth).abs() < 0.04, "{beta} against {truth}");
    }
}
