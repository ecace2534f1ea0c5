//! Mutation fuzzing of the `polycal` binary (issue 13, "Hardening"): each command run on
//! mutated copies of the bundled example and test files, judged by docs/FORMAT.md §8
//! (`fuzz/cli.rs` lists the assertions). The library level is `tests/sweeps/fuzz.rs`.
//!
//! Spawning the binary is slow, so each target runs `POLYCAL_FUZZ_CASES / 8` cases
//! (`fuzz/harness.rs`). A failure prints the command, its output and the mutated input,
//! saved under `target/tmp/fuzz-failures/`.

#[path = "fuzz/cli.rs"]
mod cli;

use crate::fuzz::{harness, mutate};
use cli::{Format, Run, repo};
use harness::{binary_cases, run};
use mutate::{Case, case, seed, seeds};
use proptest::prelude::*;

/// Proptest's shrinking steps at most, per failure (each one runs the binary).
const SHRINK: u32 = 96;

/// The 24-faced example measurement.
const EXAMPLE: &str = "examples/data/polygon24-2ac-6cycles.csv";
/// A small self-calibration (12 positions, 4 heads).
const SELFCAL: &str = "tests/fixtures/expected/sim-selfcal.file.selfcal.csv";

/// Cases of `seeds` with a format from `formats`, a variant below `variants` (which
/// options the command is given; shrinking keeps it) and whether to add `--plot DIR`.
fn with_format(
    seeds: &[&'static str],
    formats: &'static [Format],
    variants: u8,
) -> impl Strategy<Value = (Case, Format, u8, bool)> {
    (
        case(mutate::seeds(seeds)),
        prop::sample::select(formats),
        0..variants,
        prop::bool::weighted(0.25),
    )
}

/// Runs a target: `args` builds the command line (`{}` is the mutated file) of a case
/// and its variant; `--plot DIR` is added to a quarter of the cases when `plot`.
fn fuzz_command(
    target: &str,
    seeds: &[&'static str],
    ext: &'static str,
    (formats, plot): (&'static [Format], bool),
    variants: u8,
    args: impl Fn(&Case, u8) -> Vec<String>,
) {
    run(
        target,
        binary_cases(),
        SHRINK,
        with_format(seeds, formats, variants),
        |(case, format, variant, with_plot)| {
            let mut args = args(case, *variant);
            if plot && *with_plot {
                args.extend(["--plot".into(), "{dir}/plot".into()]);
            }
            Run {
                target,
                case,
                ext,
                args,
                format: *format,
            }
            .check()
        },
    );
}

fn words(text: &str) -> Vec<String> {
    text.split_whitespace().map(str::to_string).collect()
}

fn path(p: &str) -> String {
    repo(p).display().to_string()
}

const ALL: &[Format] = &[Format::Table, Format::Json, Format::Csv];
/// Every format, and `--plot` in a quarter of the cases.
const PLOT: (&[Format], bool) = (ALL, true);
/// Every format.
const NO_PLOT: (&[Format], bool) = (ALL, false);

/// Options given with a mutated measurement file, by variant: none, a budget, a stated
/// σ, the dense solver (`solve` only).
fn measurement_options(variant: u8) -> Vec<String> {
    match variant {
        0 => vec![],
        1 => vec!["--budget".into(), path("examples/budgets/instrument.toml")],
        2 => words("--sigma 0.05"),
        _ => words("--method dense"),
    }
}

#[test]
fn cli_solve() {
    fuzz_command(
        "cli-solve",
        seed::MEASUREMENT,
        "csv",
        PLOT,
        4,
        |_, variant| [words("solve {}"), measurement_options(variant)].concat(),
    );
}

#[test]
fn cli_solve_budget() {
    fuzz_command(
        "cli-solve-budget",
        seed::BUDGET,
        "toml",
        PLOT,
        4,
        |_, variant| {
            let mut args = vec![
                "solve".into(),
                path(EXAMPLE),
                "--budget".into(),
                "{}".into(),
            ];
            if variant == 3 {
                // A short Monte Carlo too.
                args.extend(words("--monte-carlo 2000 --seed 1"));
            }
            args
        },
    );
}

#[test]
fn cli_diagnose() {
    // diagnose has no --method: variants 0 to 2 only.
    fuzz_command(
        "cli-diagnose",
        seed::MEASUREMENT,
        "csv",
        PLOT,
        3,
        |_, variant| [words("diagnose {}"), measurement_options(variant)].concat(),
    );
}

/// The truths of sets `diagnose` takes (not the sub-pitch one: `diagnose` refuses its
/// measurement, whatever the truth).
const DIAGNOSE_TRUTH: &[&str] = &[
    "examples/data/polygon24-2ac-6cycles.truth.json",
    "tests/fixtures/expected/sim-bare.file.bare.json",
    "tests/fixtures/expected/sim-drift.file.drift.json",
];

/// The measurement file each truth seed belongs to.
fn measurement_of_truth(truth: &str) -> &'static str {
    match truth {
        "tests/fixtures/expected/sim-bare.file.bare.json" => {
            "tests/fixtures/expected/sim-bare.file.bare.csv"
        }
        "tests/fixtures/expected/sim-drift.file.drift.json" => {
            "tests/fixtures/expected/sim-drift.file.drift.csv"
        }
        _ => EXAMPLE,
    }
}

#[test]
fn cli_diagnose_truth() {
    fuzz_command(
        "cli-diagnose-truth",
        DIAGNOSE_TRUTH,
        "json",
        NO_PLOT,
        1,
        |case, _| {
            let measurement = path(measurement_of_truth(case.seed.path));
            vec![
                "diagnose".into(),
                measurement,
                "--truth".into(),
                "{}".into(),
            ]
        },
    );
}

#[test]
fn cli_selfcal() {
    fuzz_command(
        "cli-selfcal",
        seed::SELFCAL,
        "csv",
        PLOT,
        4,
        |_, variant| {
            let options = match variant {
                0 => vec![],
                1 => vec!["--budget".into(), path("examples/budgets/selfcal.toml")],
                2 => words("--sigma 0.05"),
                _ => words("--lost-harmonic-bound 0.01 --gauge-positions 24 --head-angle-u 0.5"),
            };
            [words("selfcal {}"), options].concat()
        },
    );
}

#[test]
fn cli_selfcal_budget() {
    fuzz_command(
        "cli-selfcal-budget",
        seed::BUDGET,
        "toml",
        PLOT,
        1,
        |_, _| {
            vec![
                "selfcal".into(),
                path(SELFCAL),
                "--budget".into(),
                "{}".into(),
            ]
        },
    );
}

#[test]
fn cli_compare() {
    // The mutated file against its own seed, as A or as B.
    fuzz_command(
        "cli-compare",
        seed::RESULTS,
        "csv",
        PLOT,
        2,
        |case, variant| {
            // a seed with U but neither u nor k is refused by the vector verdict at its own
            // first row, naming the seed: compare it by the per-row rule, which takes U alone
            let per_row = case.seed.path.ends_with("no-angle.csv");
            let seed = path(case.seed.path);
            let mut words = if variant == 0 {
                vec!["compare".into(), "{}".into(), seed]
            } else {
                vec!["compare".into(), seed, "{}".into()]
            };
            if per_row {
                words.extend(["--verdict".into(), "en".into()]);
            }
            words
        },
    );
}

#[test]
fn cli_budget() {
    fuzz_command(
        "cli-budget",
        seed::BUDGET,
        "toml",
        (&[Format::Table, Format::Json], false),
        1,
        |_, _| words("budget {}"),
    );
}

/// Which input of `report` is mutated.
#[derive(Clone, Copy, Debug)]
enum Role {
    Measurement,
    Selfcal,
    Meta,
    Budget,
    Reference,
    Truth,
}

#[test]
fn cli_report() {
    let role = |role: Role, list: &[&'static str]| case(seeds(list)).prop_map(move |c| (c, role));
    let strategy = prop_oneof![
        2 => role(Role::Measurement, seed::MEASUREMENT),
        1 => role(Role::Selfcal, seed::SELFCAL),
        2 => role(Role::Meta, seed::META),
        1 => role(Role::Budget, &["examples/budgets/instrument.toml"]),
        1 => role(Role::Reference, seed::RESULTS),
        1 => role(Role::Truth, DIAGNOSE_TRUTH),
    ];
    let target = "cli-report";
    run(target, binary_cases(), SHRINK, strategy, |(case, role)| {
        let (example, budget) = (path(EXAMPLE), path("examples/budgets/instrument.toml"));
        let mut args: Vec<String> = vec!["report".into()];
        let ext = match role {
            Role::Measurement | Role::Selfcal => {
                args.push("{}".into());
                "csv"
            }
            Role::Meta => {
                args.extend([example, "--meta".into(), "{}".into()]);
                "toml"
            }
            Role::Budget => {
                args.extend([example, "--budget".into(), "{}".into()]);
                "toml"
            }
            Role::Reference => {
                args.extend([example, "--budget".into(), budget]);
                args.extend(["--reference".into(), "{}".into()]);
                "csv"
            }
            Role::Truth => {
                let measurement = path(measurement_of_truth(case.seed.path));
                args.extend([measurement, "--diagnose".into(), "--truth".into()]);
                args.push("{}".into());
                "json"
            }
        };
        args.extend(["--out".into(), "{dir}/report.html".into()]);
        Run {
            target,
            case,
            ext,
            args,
            format: Format::None,
        }
        .check()
    });
}
