//! The sweeps tier: the slow tests — the statistical sweeps that measure each verdict's
//! false-alarm rate and power on thousands of simulated runs (docs/verdicts.md), the
//! fault runs of issue 53 (`tests/fault_runs`), the mutation fuzzers of every reader and
//! every command (`tests/sweeps/fuzz/`), the Monte Carlo engine's checks over many
//! trials, the planner's 90 % sizes, the end-to-end instrument runs over pseudo-terminals
//! with their faults and waits, and the README's and guides' shell blocks run as written.
//!
//! Minutes, not seconds: CI runs it (`cargo test` runs every tier); run it before a
//! commit that touches what it measures, or one module with
//! `cargo test --test sweeps NAME::` (`tests/sweeps/NAME.rs`).

// The helpers the tests share: those of this tier in tests/sweeps/NAME/, those of several
// tiers in tests/NAME/mod.rs, each gated as its users are.
#[path = "../fault_runs/mod.rs"]
mod fault_runs;
#[cfg(all(unix, feature = "cli", feature = "lab"))]
#[path = "../instrument_support/mod.rs"]
mod instrument_support;
#[path = "../kc_support/mod.rs"]
mod kc_support;
#[cfg(feature = "lab")]
#[path = "../lab_support/mod.rs"]
mod lab_support;
#[cfg(feature = "cli")]
mod plan_cli_support;
#[path = "../selfcal_support/mod.rs"]
mod selfcal_support;

// The tests: tests/sweeps/NAME.rs, each gated on the features it needs.
mod diagnose_cycles;
mod diagnose_mountings;
mod diagnose_noise;
mod diagnose_search_end;
mod diagnose_stop_scatter;
mod fault_runs_check;
mod fuzz;
#[cfg(feature = "cli")]
mod fuzz_cli;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_designs_cli;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_faults;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_live_cli;
#[cfg(feature = "lab")]
mod instrument_profiles;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_profiles_cli;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_resume;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_wrong_stop_cli;
mod kc_blocks_rates;
mod kc_encoder_subsets_rates;
mod kc_link_rates;
mod kc_pairs_motion;
mod kc_rates;
mod kc_understated_rates;
mod monte_carlo;
mod plan;
#[cfg(feature = "cli")]
mod plan_cli_comparison;
#[cfg(feature = "cli")]
mod plan_cli_design;
#[cfg(feature = "cli")]
mod plan_cli_plot;
#[cfg(feature = "cli")]
mod plan_cli_usage;
#[cfg(all(feature = "cli", feature = "lab"))]
mod readme;
mod verdict_rates_diagnose;
#[cfg(feature = "lab")]
mod verdict_rates_repeat_noise;
#[cfg(feature = "lab")]
mod verdict_rates_resume_checks;
#[cfg(feature = "lab")]
mod verdict_rates_run_plan;
