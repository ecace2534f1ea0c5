//! The `polycal` command line: the [`Cli`] struct, the options every command has, the
//! exit statuses, and the dispatch to one module per command group. All calibration
//! logic lives in the library; these modules parse, call it and print.

mod budget;
mod compare;
mod diagnose;
mod docs;
mod files;
mod history;
#[cfg(feature = "lab")]
mod interrupt;
mod kc;
mod monte_carlo;
pub mod output;
mod plan;
mod report;
#[cfg(feature = "lab")]
mod run;
mod selfcal;
#[cfg(feature = "lab")]
mod sim_lab;
mod simulate;
mod solve;
pub mod stdout;
mod validate;
mod wrong_file;

use anyhow::Result;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
pub use files::wait_if_interrupted;
use output::Output;

/// Exit status: done, every check passed.
pub const EXIT_OK: u8 = 0;
/// Exit status: done, but a verdict is negative.
pub const EXIT_VERDICT: u8 = 1;
/// Exit status: an error (usage, refused input, instrument or file failure).
pub const EXIT_ERROR: u8 = 2;

/// After the list of commands in `polycal --help`.
const EXIT_STATUS_HELP: &str = "\
Exit status: 0 done and every check passed; 1 done, but a verdict is negative (compare:
the differences fail their χ² test as one vector, or some |En| > 1 with --verdict en; kc: not consistent after the stated exclusions; diagnose: a model not adequate; solve: Monte Carlo does not validate GUM;
plan: a design cannot calibrate or misses --target-u);
2 an error (usage, refused input, instrument or file failure); 130 `run` stopped at once by
a second Ctrl-C; 141 standard output closed by its reader (`| head`), quietly (docs/FORMAT.md §8).

The data and command contract: docs/FORMAT.md. Completions: `polycal completions SHELL`;
manual page: `polycal man`.";

#[derive(Parser)]
#[command(
    name = "polycal",
    version,
    about = "Calibrate an optical polygon and a rotary encoder at once (two-autocollimator method)",
    long_about = None,
    after_help = EXIT_STATUS_HELP
)]
pub struct Cli {
    #[command(flatten)]
    pub global: GlobalArgs,
    #[command(subcommand)]
    pub command: Command,
}

/// The options every command has.
#[derive(clap::Args)]
pub struct GlobalArgs {
    /// No warnings, progress bars or summaries on standard error (errors and results
    /// are always written).
    #[arg(short, long, global = true)]
    pub quiet: bool,
    /// When to colour polycal's `warning:` and `error:` lines: `auto` when standard
    /// error is a terminal and NO_COLOR is not set.
    #[arg(
        long,
        global = true,
        value_enum,
        value_name = "WHEN",
        default_value_t = ColorWhen::Auto
    )]
    pub color: ColorWhen,
}

/// `--color`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ColorWhen {
    // No doc comments here: they would turn every command's `--help` into the long form.
    Auto,
    Always,
    Never,
}

#[derive(Subcommand)]
// Parsed once per process: the size of the simulate variant does not matter.
#[allow(clippy::large_enum_variant)]
pub enum Command {
    /// Solve measurement files: pitch deviations, encoder errors, setup errors.
    #[command(after_help = solve::EXAMPLES)]
    Solve(solve::SolveArgs),
    /// Find the effects the base model lacks (drift, zero jumps, direction, outliers),
    /// add them, and report the calibration before and after.
    #[command(after_help = diagnose::EXAMPLES)]
    Diagnose(diagnose::DiagnoseArgs),
    /// Evaluate a GUM uncertainty budget (TOML, docs/FORMAT.md §5).
    #[command(after_help = budget::EXAMPLES)]
    Budget(budget::BudgetArgs),
    /// Compare two results quantity by quantity with En (ISO 13528) and give one verdict for
    /// the whole comparison, docs/FORMAT.md §5.4: status 1 when the closed quantities'
    /// differences fail their χ² test as one vector at 5 % (--verdict en: some |En| > 1).
    #[command(after_help = compare::EXAMPLES)]
    Compare(compare::CompareArgs),
    /// Evaluate an interlaboratory (key) comparison of a polygon or an encoder: reference
    /// per face with χ², exclusions, degrees of equivalence, the closed vector
    /// (docs/FORMAT.md §12); status 1 when not consistent after the stated exclusions.
    #[command(after_help = kc::EXAMPLES)]
    Kc(kc::KcArgs),
    /// Follow one standard's calibrations over time: per face or position the drift per
    /// year with its u, one test of the whole drift vector at 5 % (constant or linear),
    /// the value predicted at a date with its u, control charts (docs/FORMAT.md §13.2).
    #[command(after_help = history::EXAMPLES)]
    History(history::HistoryArgs),
    /// Self-calibrate a rotary encoder with several read heads (SelfA): the disc's
    /// graduation error and the heads' errors (docs/FORMAT.md §9).
    #[command(after_help = selfcal::EXAMPLES)]
    Selfcal(selfcal::SelfcalArgs),
    /// Plan a design before measuring: predicted u (and U with a budget) of every β, φ,
    /// α, the lost harmonics, the smallest drift and jump a diagnosis finds, designs
    /// side by side (docs/FORMAT.md §5.6).
    #[command(after_help = plan::EXAMPLES)]
    Plan(plan::PlanArgs),
    /// Write a self-contained HTML calibration report (inline figures, A4 print): details,
    /// method, results with u, U and k, budget, diagnosis, comparison, provenance
    /// (docs/FORMAT.md §10).
    #[command(after_help = report::EXAMPLES)]
    Report(report::ReportArgs),
    /// Simulate a measurement run (or with --selfcal a self-calibration run) with a known
    /// truth.
    #[command(after_help = simulate::EXAMPLES)]
    Simulate(simulate::SimulateArgs),
    /// Validate this build against reference results computed without polycal
    /// (ISO/IEC 17025 7.11.2): every bundled case, its deviation against its tolerance, the
    /// build and platform; status 1 when a case fails (docs/FORMAT.md §13.1).
    #[command(after_help = validate::EXAMPLES)]
    Validate(validate::ValidateArgs),
    /// Drive the instruments through a calibration run (docs/FORMAT.md §7).
    #[cfg(feature = "lab")]
    #[command(after_help = run::RUN_EXAMPLES)]
    Run(run::RunArgs),
    /// Serve simulated instruments on pseudo-terminals, to try `run` without hardware.
    #[cfg(feature = "lab")]
    #[command(after_help = sim_lab::SIM_LAB_EXAMPLES)]
    SimLab(sim_lab::SimLabArgs),
    /// Print a shell completion script on standard output.
    #[command(after_help = docs::COMPLETIONS_EXAMPLES)]
    Completions(docs::CompletionsArgs),
    /// Print the manual page (roff) on standard output.
    #[command(after_help = docs::MAN_EXAMPLES)]
    Man(docs::ManArgs),
}

impl Cli {
    /// Parses the command line. `--help` and `--version` are printed by clap (status 0),
    /// in colour as `--color` says. A usage error is one `error:` line on standard error
    /// (docs/FORMAT.md §8: clap's message, its tips joined on the line) and status 2.
    pub fn parse_args() -> Cli {
        let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
        let choice = color_in_args(&args);
        let mut command = negative_numbers_are_values(Cli::command());
        if let Some(choice) = choice {
            command = command.color(match choice {
                ColorWhen::Auto => clap::ColorChoice::Auto,
                ColorWhen::Always => clap::ColorChoice::Always,
                ColorWhen::Never => clap::ColorChoice::Never,
            });
        }
        let parsed = command
            .try_get_matches_from(args)
            .and_then(|matches| Cli::from_arg_matches(&matches));
        match parsed {
            Ok(cli) => cli,
            Err(error) => {
                use clap::error::ErrorKind;
                if matches!(
                    error.kind(),
                    ErrorKind::DisplayHelp | ErrorKind::DisplayVersion
                ) {
                    error.exit();
                }
                let out = output::Output::new(choice.unwrap_or(ColorWhen::Auto), false);
                if error.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand {
                    // `polycal` alone: a usage error, one line like every other
                    out.error_message(format!(
                        "no command given; the commands are {} (see --help)",
                        command_names().join(", ")
                    ));
                } else if let Some(line) = negative_out_of_range(&error) {
                    out.error_message(line);
                } else {
                    out.error_message(usage_error_line(&error.render().to_string()));
                }
                std::process::exit(i32::from(EXIT_ERROR));
            }
        }
    }
}

/// Every option that takes a value takes a negative number as its value (`--faces -5`), so
/// that the value is judged by the option's own parser ([`negative_out_of_range`]) rather
/// than taken for an unknown option `-5`.
fn negative_numbers_are_values(command: clap::Command) -> clap::Command {
    fn option(arg: clap::Arg) -> clap::Arg {
        if arg.get_long().is_some() && arg.get_action().takes_values() {
            arg.allow_negative_numbers(true)
        } else {
            arg
        }
    }
    command
        .mut_args(option)
        .mut_subcommands(|sub| sub.mut_args(option))
}

/// A negative number refused by an option's parser (a count, a seed: `--faces -5`), as
/// one line saying it is out of range; `None` for any other usage error.
fn negative_out_of_range(error: &clap::Error) -> Option<String> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if error.kind() != ErrorKind::ValueValidation {
        return None;
    }
    let (Some(ContextValue::String(arg)), Some(ContextValue::String(value))) = (
        error.get(ContextKind::InvalidArg),
        error.get(ContextKind::InvalidValue),
    ) else {
        return None;
    };
    // an integer option's parser: clap's for usize/u64 (a `ParseIntError`) or for the
    // narrower types (`-1 is not in 0..=4294967295`); a parser of its own keeps its message
    let integer = std::error::Error::source(error).is_some_and(|cause| {
        cause.is::<std::num::ParseIntError>()
            || cause
                .to_string()
                .starts_with(&format!("{value} is not in "))
    });
    if !integer || !value.parse::<f64>().is_ok_and(|v| v < 0.0) {
        return None;
    }
    let option = arg.split_whitespace().next().unwrap_or(arg);
    Some(format!(
        "{option} {value}: out of range: {option} takes a whole number, not a negative one (see --help)"
    ))
}

/// The names of polycal's commands, in the order of `--help` (without `help`).
pub fn command_names() -> Vec<String> {
    Cli::command()
        .get_subcommands()
        .map(|c| c.get_name().to_string())
        .filter(|n| n != "help")
        .collect()
}

/// clap's usage error on one line: its message and tips, without the `error:` prefix,
/// the usage synopsis and the pointer to `--help`.
fn usage_error_line(rendered: &str) -> String {
    let mut parts: Vec<String> = Vec::new();
    for line in rendered.lines() {
        let line = line.trim();
        if line.starts_with("Usage:") || line.starts_with("For more information") {
            break;
        }
        if line.is_empty() {
            continue;
        }
        parts.push(line.strip_prefix("error: ").unwrap_or(line).to_string());
    }
    let mut text = String::new();
    for part in parts {
        if !text.is_empty() {
            text.push_str(if text.ends_with(':') { " " } else { "; " });
        }
        text.push_str(&part);
    }
    if text.is_empty() {
        text = "invalid command line".to_string();
    }
    text.push_str(" (see --help)");
    text
}

/// The last valid `--color WHEN` or `--color=WHEN` before `--`, read before clap parses,
/// so that clap's own help and usage errors are coloured as asked.
fn color_in_args(args: &[std::ffi::OsString]) -> Option<ColorWhen> {
    let mut choice = None;
    let mut args = args.iter().skip(1).map(|a| a.to_str());
    while let Some(arg) = args.next() {
        let value = match arg {
            Some("--") => break,
            Some("--color") => args.next().flatten(),
            Some(arg) => arg.strip_prefix("--color="),
            None => None,
        };
        if let Some(found) = value.and_then(|v| ColorWhen::from_str(v, false).ok()) {
            choice = Some(found);
        }
    }
    choice
}

/// Runs a parsed command: returns its exit status, or the error for the final `error:`
/// line.
pub fn dispatch(command: Command, out: &Output) -> Result<u8> {
    #[cfg(feature = "lab")]
    let handles_signals = matches!(command, Command::Run(_) | Command::SimLab(_));
    #[cfg(not(feature = "lab"))]
    let handles_signals = false;
    if !handles_signals {
        files::clean_up_on_interrupt();
    }
    match command {
        Command::Solve(args) => solve::run(&args, out),
        Command::Diagnose(args) => diagnose::run(&args, out),
        Command::Budget(args) => budget::run(&args),
        Command::Compare(args) => compare::run(&args),
        Command::Kc(args) => kc::run(&args),
        Command::History(args) => history::run(&args),
        Command::Selfcal(args) => selfcal::run(&args, out),
        Command::Plan(args) => plan::run(&args, out),
        Command::Report(args) => report::run(&args, out),
        Command::Simulate(args) => simulate::run(&args, out),
        Command::Validate(args) => validate::run(&args),
        #[cfg(feature = "lab")]
        Command::Run(args) => run::run(&args, out),
        #[cfg(feature = "lab")]
        Command::SimLab(args) => sim_lab::sim_lab(&args, out),
        Command::Completions(args) => docs::completions(&args),
        Command::Man(args) => docs::man(&args),
    }
}

/// A library error with the command-line way out added: `"{error}; {hint}"`, unless its
/// message already names `flag` (the library's messages name no flags; older ones did).
pub fn with_hint(error: impl std::fmt::Display, flag: &str, hint: &str) -> anyhow::Error {
    let message = error.to_string();
    if message.contains(flag) {
        anyhow::Error::msg(message)
    } else {
        anyhow::anyhow!("{message}; {hint}")
    }
}

#[cfg(test)]
mod usage_tests {
    use super::usage_error_line;

    #[test]
    fn a_usage_error_is_one_line_with_its_tips() {
        let rendered = "error: unexpected argument '--fces' found\n\n  tip: a similar argument exists: '--faces'\n\nUsage: polycal solve <FILES>...\n\nFor more information, try '--help'.\n";
        assert_eq!(
            usage_error_line(rendered),
            "unexpected argument '--fces' found; tip: a similar argument exists: '--faces' (see --help)"
        );
        let missing = "error: the following required arguments were not provided:\n  <FILES>...\n\nUsage: polycal solve <FILES>...\n";
        assert_eq!(
            usage_error_line(missing),
            "the following required arguments were not provided: <FILES>... (see --help)"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }

    #[test]
    fn color_is_read_before_parsing() {
        let args = |list: &[&str]| list.iter().map(Into::into).collect::<Vec<_>>();
        assert_eq!(color_in_args(&args(&["polycal", "solve", "x"])), None);
        assert_eq!(
            color_in_args(&args(&["polycal", "--color", "never", "solve"])),
            Some(ColorWhen::Never)
        );
        assert_eq!(
            color_in_args(&args(&["polycal", "solve", "--color=always"])),
            Some(ColorWhen::Always)
        );
        assert_eq!(
            color_in_args(&args(&["polycal", "--color=bad", "solve"])),
            None
        );
        assert_eq!(
            color_in_args(&args(&["polycal", "solve", "--", "--color=always"])),
            None
        );
    }

    #[test]
    fn a_hint_is_added_once() {
        assert_eq!(
            with_hint("does not apply", "--method", "use --method lsq").to_string(),
            "does not apply; use --method lsq"
        );
        assert_eq!(
            with_hint(
                "does not apply; use --method lsq",
                "--method",
                "use --method lsq"
            )
            .to_string(),
            "does not apply; use --method lsq"
        );
    }
}

/// Writes the figures of `--plot DIR` (docs/FORMAT.md §10, §8.1), all or none, none of
/// them one of `inputs`; a write failure is an error naming the path.
pub fn write_plot(
    dir: &std::path::Path,
    figures: &[polycal::figure::Figure],
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    polycal::figure::write_figures(dir, figures, inputs)
        .map(|_| ())
        .map_err(|e| anyhow::anyhow!("--plot: cannot write the figures: {e}"))
}

/// Refuses `--plot DIR`, before any work, when its figures cannot be written there
/// ([`polycal::figure::check_figures`]: DIR not a directory nor creatable, not
/// writable, or a figure that would replace one of `inputs`); one `error:` line naming
/// `--plot`. The residual figures of `diagnose`, named after the file's autocollimators,
/// are checked again as they are written ([`write_plot`]).
pub fn check_plot(
    dir: Option<&std::path::Path>,
    set: polycal::figure::FigureSet,
    inputs: &[&std::path::Path],
) -> anyhow::Result<()> {
    match dir {
        Some(dir) => polycal::figure::check_figures(dir, set, inputs)
            .map_err(|e| anyhow::anyhow!("--plot {e}")),
        None => Ok(()),
    }
}

/// The refusal of `--plot` with several input files (their figures would share names).
pub fn plot_one_file(plot: Option<&std::path::Path>, files: usize) -> anyhow::Result<()> {
    if plot.is_some() && files > 1 {
        anyhow::bail!(
            "--plot takes one input file ({files} given): the figures of several files would share names; run once per file"
        );
    }
    Ok(())
}

/// The refusal of standard input given twice (`-` for two inputs): it can be read once,
/// and the second reader would see it empty. `inputs` are each input's role (`the
/// measurement file`, `--truth`) and path.
pub fn stdin_once<'a>(
    inputs: impl IntoIterator<Item = (&'a str, Option<&'a std::path::Path>)>,
) -> anyhow::Result<()> {
    let roles: Vec<&str> = inputs
        .into_iter()
        .filter(|(_, path)| path.is_some_and(polycal::input::is_stdin))
        .map(|(role, _)| role)
        .collect();
    if roles.len() > 1 {
        anyhow::bail!(
            "standard input (`-`) is given for {}: it can be read only once; give the others as files",
            roles.join(" and ")
        );
    }
    Ok(())
}
