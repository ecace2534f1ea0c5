//! The maths tier: the library's calibration maths — solve, uncertainty, Monte Carlo,
//! diagnose, self-calibration, compare, key comparisons, simulate, the readers of every
//! file — through its public API, without the `polycal` binary and without the instrument
//! layer (it builds and runs with `--no-default-features`; `simulate_command_line`
//! and `simulate_selfcal` run their command-line checks only with `cli`).
//!
//! Quick: part of the inner loop, `cargo test --lib --test maths --test commands`, run
//! while working on the library. Its slow statistical sweeps are in `tests/sweeps/`.
//! One module per test file (`tests/maths/NAME.rs`); run one with
//! `cargo test --test maths NAME::`.

// The helpers the tests share: those of this tier in tests/maths/NAME/, those of several
// tiers in tests/NAME/mod.rs, each gated as its users are.
#[path = "../common/mod.rs"]
mod common;
mod compare_support;
mod file_error_support;
#[path = "../kc_support/mod.rs"]
mod kc_support;
mod measurement_file_support;
mod selfcal_file_support;
#[path = "../selfcal_support/mod.rs"]
mod selfcal_support;
mod simulate_support;
#[path = "../undeclared/mod.rs"]
mod undeclared;

// The tests: tests/maths/NAME.rs, each gated on the features it needs.
mod compare_angles;
mod compare_en;
mod compare_verdict;
mod diagnose;
mod diagnose_effects;
mod diagnose_geometry;
mod diagnose_identify;
mod diagnose_monte_carlo;
mod diagnose_selfcal;
mod diagnose_selfcal_off_grid;
mod diagnose_selfcal_within_cells;
mod diagnose_shifted;
mod engine;
mod history;
mod kc;
mod kc_blocks;
mod kc_blocks_uncertainty;
mod kc_covariance;
mod kc_encoder_subsets;
mod kc_link_positions;
mod measurement_file_good;
mod measurement_file_in_memory;
mod measurement_file_refusals;
mod measurement_file_round_trips;
mod measurement_file_shifts;
mod result_file;
mod selfcal;
mod selfcal_file_good;
mod selfcal_file_in_memory;
mod selfcal_file_refusals;
mod selfcal_file_round_trips;
mod selfcal_monte_carlo;
mod simulate_command_line;
mod simulate_effects;
mod simulate_elevation;
mod simulate_equations;
mod simulate_habits;
mod simulate_noise;
mod simulate_refusals;
mod simulate_selfcal;
mod simulate_specs;
mod simulate_temperature;
mod simulate_truth_file;
mod solve_properties;
mod solve_uncertainty;
mod sub_pitch;
mod sub_pitch_structured;
mod table_rules;
mod uncertainty;
mod verification;
