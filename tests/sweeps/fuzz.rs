//! Mutation fuzzing of every file reader and of the instruments' reply parsers, at the
//! library level (issue 13, "Hardening"); the binary level is `tests/sweeps/fuzz_cli.rs`.
//!
//! Each target takes valid seed files (the bundled examples and test files), mutates
//! them (`fuzz/mutate.rs`) and reads the result inside `catch_unwind`:
//!
//! - the reader must not panic;
//! - when it refuses the input, its message must name the file (the name it was given),
//!   and for bytes that are not UTF-8 the line and column (docs/FORMAT.md §2.1, §3.2,
//!   §4, §5.3, §9.2.1);
//! - when it accepts the input, the value goes through the computation it feeds (solve a
//!   measurement set and evaluate an instrument budget on it, solve a self-calibration,
//!   compare two results, evaluate a budget, compare a diagnosis with a truth, plan a
//!   design, write the example's HTML report and DCC with fuzzed metadata — a DCC must be
//!   well-formed XML), which must not panic either.
//!
//! `POLYCAL_FUZZ_CASES`, `POLYCAL_FUZZ_SEED` and `POLYCAL_FUZZ_SURVEY` scale and steer
//! it (`fuzz/harness.rs`); a failure prints the mutated input and saves it under
//! `target/tmp/fuzz-failures/`.

// The runner and the mutations, shared with `fuzz_cli`.
pub(crate) mod harness;
mod library;
pub(crate) mod mutate;
#[cfg(feature = "lab")]
mod replies;

use harness::{library_cases, run};
use mutate::{case, seed, seeds};

/// Proptest's shrinking steps at most, per failure.
const SHRINK: u32 = 512;

#[test]
fn measurement_file() {
    let strategy = case(seeds(seed::MEASUREMENT));
    run(
        "measurement",
        library_cases(),
        SHRINK,
        strategy,
        library::measurement,
    );
}

#[test]
fn selfcal_file() {
    let strategy = case(seeds(seed::SELFCAL));
    run(
        "selfcal",
        library_cases(),
        SHRINK,
        strategy,
        library::selfcal,
    );
}

#[test]
fn result_file() {
    let strategy = case(seeds(seed::RESULTS));
    run(
        "results",
        library_cases(),
        SHRINK,
        strategy,
        library::results,
    );
}

#[test]
fn budget_file() {
    let strategy = case(seeds(seed::BUDGET));
    run("budget", library_cases(), SHRINK, strategy, library::budget);
}

#[test]
fn instrument_budget_file() {
    let strategy = case(seeds(seed::BUDGET));
    run(
        "instrument-budget",
        library_cases(),
        SHRINK,
        strategy,
        library::instrument_budget,
    );
}

#[test]
fn designs_file() {
    let strategy = case(seeds(seed::DESIGNS));
    run(
        "designs",
        library_cases(),
        SHRINK,
        strategy,
        library::designs,
    );
}

#[test]
fn truth_file() {
    let strategy = case(seeds(seed::TRUTH));
    run("truth", library_cases(), SHRINK, strategy, library::truth);
}

#[test]
fn selfcal_truth_file() {
    let strategy = case(seeds(seed::SELFCAL_TRUTH));
    run(
        "selfcal-truth",
        library_cases(),
        SHRINK,
        strategy,
        library::selfcal_truth,
    );
}

#[test]
fn report_metadata_file() {
    let strategy = case(seeds(seed::META));
    run("meta", library_cases(), SHRINK, strategy, library::meta);
}

#[cfg(feature = "lab")]
#[test]
fn instrument_replies() {
    // Reply lines are short and the parsers fast: many more cases.
    let cases = library_cases().saturating_mul(8);
    run("replies", cases, SHRINK, replies::case(), replies::check);
}
