//! The lab tier: the instrument layer (feature `lab`) — transports and drivers over the
//! simulated lab's in-memory streams, the run directory on a disk that fills up, the run
//! procedure's mountings, repeats and resume checks, the bundled table profiles against
//! controllers written by hand from the makers' manuals (over pseudo-terminals and TCP,
//! about two seconds), and one end-to-end run of `polycal run` against `polycal sim-lab`
//! (with `cli`, on Unix).
//!
//! Quick: run while working on `src/lab` (`cargo test --test lab`). The slow end-to-end
//! runs over pseudo-terminals (faults, designs, profiles, Ctrl-C) and the run's
//! verdict rates are in `tests/sweeps/`. One module per test file
//! (`tests/lab/NAME.rs`); run one with `cargo test --test lab NAME::`.

// The helpers the tests share with other tiers (tests/NAME/mod.rs), each gated as its
// users are.
#[cfg(all(unix, feature = "cli", feature = "lab"))]
#[path = "../instrument_support/mod.rs"]
mod instrument_support;
#[cfg(feature = "lab")]
#[path = "../lab_support/mod.rs"]
mod lab_support;
// The hand-written table controllers of `table_emulators`, served like the simulated lab.
#[cfg(all(unix, feature = "lab"))]
mod emulator_support;

// The tests: tests/lab/NAME.rs, each gated on the features it needs.
#[cfg(feature = "lab")]
mod instrument_disk;
#[cfg(feature = "lab")]
mod instrument_drivers;
#[cfg(all(feature = "cli", feature = "lab"))]
mod instrument_e2e;
#[cfg(feature = "lab")]
mod instrument_mountings;
#[cfg(feature = "lab")]
mod instrument_noise;
#[cfg(feature = "lab")]
mod instrument_resume_checks;
#[cfg(feature = "lab")]
mod instrument_run;
#[cfg(feature = "lab")]
mod instrument_wrong_stop;
#[cfg(feature = "lab")]
mod live_first_stops;
#[cfg(feature = "lab")]
mod own_instruments_example;
#[cfg(feature = "lab")]
mod replace_or_suspect;
#[cfg(feature = "lab")]
mod session_rules;
#[cfg(feature = "lab")]
mod stop_cost_readme;
#[cfg(feature = "lab")]
mod table_emulators;
#[cfg(feature = "lab")]
mod wire_rules;
