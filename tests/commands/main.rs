//! The commands tier: the `polycal` binary run as a user runs it (feature `cli`; the
//! commands of the instrument layer with `lab` too) — every command's output, files,
//! refusals and exit status, the reports and the DCC, the fixtures compared byte for
//! byte, the JSON fields against docs/FORMAT.md.
//!
//! Quick: part of the inner loop, `cargo test --lib --test maths --test commands`, run
//! while working on the binary or the library. The README's shell blocks and the
//! binary's fuzzer are in `tests/sweeps/`. One module per test file
//! (`tests/commands/NAME.rs`); run one with `cargo test --test commands NAME::`.

// The helpers the tests share: those of this tier in tests/commands/NAME/, those of
// several tiers in tests/NAME/mod.rs, each gated as its users are.
#[cfg(feature = "cli")]
mod calibration_uncertainty_support;
#[cfg(feature = "cli")]
mod cli_support;
#[cfg(feature = "cli")]
#[path = "../common/mod.rs"]
mod common;
#[cfg(feature = "cli")]
mod dcc_schema;
#[cfg(feature = "cli")]
mod document_support;
#[cfg(feature = "cli")]
#[path = "../fault_runs/mod.rs"]
mod fault_runs;
#[cfg(feature = "cli")]
mod files_support;
#[cfg(feature = "cli")]
mod hardening_support;
#[cfg(feature = "cli")]
mod report_support;
#[cfg(feature = "cli")]
mod skip_support;
#[cfg(feature = "cli")]
#[path = "../undeclared/mod.rs"]
mod undeclared;

// The tests: tests/commands/NAME.rs, each gated on the features it needs.
mod architecture;
#[cfg(feature = "cli")]
mod calibration_uncertainty_cli;
#[cfg(feature = "cli")]
mod calibration_uncertainty_effects;
#[cfg(feature = "cli")]
mod calibration_uncertainty_monte_carlo;
#[cfg(feature = "cli")]
mod calibration_uncertainty_propagation;
#[cfg(feature = "cli")]
mod certificate_dcc;
#[cfg(feature = "cli")]
mod certificate_read_back;
#[cfg(feature = "cli")]
mod cli_budget;
#[cfg(feature = "cli")]
mod cli_compare;
#[cfg(feature = "cli")]
mod cli_diagnose;
#[cfg(feature = "cli")]
mod cli_help;
#[cfg(feature = "cli")]
mod cli_messages;
#[cfg(all(feature = "cli", feature = "lab"))]
mod cli_newcomer;
#[cfg(feature = "cli")]
mod cli_simulate;
#[cfg(feature = "cli")]
mod cli_solve;
#[cfg(feature = "cli")]
mod cross_talk_stated;
#[cfg(feature = "cli")]
mod diagnose_cli_identify;
#[cfg(feature = "cli")]
mod diagnose_noise_cli;
#[cfg(feature = "cli")]
mod diagnose_selfcal_cli;
#[cfg(feature = "cli")]
mod diagnose_shifted_cli;
#[cfg(feature = "cli")]
mod figures;
#[cfg(all(feature = "cli", feature = "lab"))]
mod fixtures;
#[cfg(all(feature = "cli", feature = "lab"))]
mod format_doc;
#[cfg(feature = "cli")]
mod hardening_errors;
#[cfg(feature = "cli")]
mod hardening_limits;
#[cfg(feature = "cli")]
mod hardening_not_utf8;
#[cfg(feature = "cli")]
mod hardening_numbers;
#[cfg(feature = "cli")]
mod history_cli;
#[cfg(feature = "cli")]
mod kc_blocks;
#[cfg(feature = "cli")]
mod kc_cli;
#[cfg(feature = "cli")]
mod kc_draft;
#[cfg(feature = "cli")]
mod kc_encoder_subsets;
mod kc_input;
#[cfg(feature = "cli")]
mod kc_labs_apart;
#[cfg(feature = "cli")]
mod kc_shared;
#[cfg(feature = "cli")]
mod output_files;
#[cfg(feature = "cli")]
mod output_files_plot;
#[cfg(feature = "cli")]
mod progress_cli;
#[cfg(feature = "cli")]
mod report_17025;
#[cfg(feature = "cli")]
mod report_history;
#[cfg(feature = "cli")]
mod report_kc;
#[cfg(feature = "cli")]
mod report_metadata;
#[cfg(feature = "cli")]
mod report_numbers;
#[cfg(feature = "cli")]
mod report_printed;
#[cfg(feature = "cli")]
mod report_reproducible;
#[cfg(feature = "cli")]
mod report_status;

#[cfg(feature = "cli")]
mod validate;
