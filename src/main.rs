//! `polycal`: the command line over the polycal library. It parses arguments, calls the
//! library and prints; all logic lives in the library's modules.

mod cli_instrument;
mod cli_truth;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand, ValueEnum};
use polycal::compare::{CompareOptions, compare_files};
use polycal::diagnose::{self, DiagnoseOptions};
use polycal::measurement::{MeasurementSet, Sigma};
use polycal::report::diagnose::DiagnoseReport;
use polycal::report::{self, SolveReport};
use polycal::results::read_result_file;
use polycal::simulate::{self, Truth};
use polycal::solve::{self, Method, SolveOptions};
use polycal::uncertainty::BudgetFile;
use polycal::uncertainty::calibration::{self, InstrumentBudget, McOptions, McSolver};
use polycal::uncertainty::monte_carlo::Trials;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// Exit status: done, every check passed.
const EXIT_OK: u8 = 0;
/// Exit status: done, but a verdict is negative.
const EXIT_VERDICT: u8 = 1;
/// Exit status: an error (usage, refused input, instrument or file failure).
const EXIT_ERROR: u8 = 2;

#[derive(Parser)]
#[command(
    name = "polycal",
    version,
    about = "Calibrate an optical polygon and a rotary encoder at once (two-autocollimator method)",
    long_about = None
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Clone, Copy, ValueEnum)]
enum FormatArg {
    Table,
    Json,
    Csv,
}

#[derive(Clone, Copy, ValueEnum)]
enum MethodArg {
    /// The closed form where it applies, else least squares.
    Auto,
    /// The paper's closed form, eqs. (6)-(10).
    ClosedForm,
    /// General constrained least squares.
    Lsq,
}

#[derive(Subcommand)]
// Parsed once per process: the size of the simulate variant does not matter.
#[allow(clippy::large_enum_variant)]
enum Command {
    /// Solve measurement files: pitch deviations, encoder errors, setup errors.
    Solve {
        /// Measurement CSV files (FORMAT.md §2); `-` reads standard input.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Number of polygon faces (default: the largest face in the file).
        #[arg(long)]
        faces: Option<usize>,
        /// Solver.
        #[arg(long, value_enum, default_value = "auto")]
        method: MethodArg,
        /// Standard deviation of one reading, arcsec, for the uncertainties of an
        /// exactly determined fit (dof = 0).
        #[arg(long)]
        sigma: Option<Sigma>,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: FormatArg,
        /// Instrument budget (TOML, FORMAT.md §5 with `acts_on` per component): adds the
        /// expanded uncertainty U and k of every result, combining the fit's type A with
        /// the budget through the design.
        #[arg(long, value_name = "FILE.toml")]
        budget: Option<PathBuf>,
        /// Monte Carlo through the solver (JCGM 101): a number of trials (e.g. 1000000 or
        /// 1e6) or `adaptive` (JCGM 101 §7.9). Needs --budget.
        #[arg(long, value_name = "N|adaptive", value_parser = parse_trials)]
        monte_carlo: Option<McTrials>,
        /// Seed of the Monte Carlo (same seed, same numbers, whatever the threads).
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Significant digits of u_c for the Monte Carlo validation of the GUM result and
        /// for the adaptive procedure.
        #[arg(long, default_value_t = 2, value_parser = clap::value_parser!(u32).range(1..=6))]
        mc_digits: u32,
        /// Largest number of trials of the adaptive procedure.
        #[arg(long, default_value_t = 10_000_000)]
        mc_max_trials: usize,
    },
    /// Find the effects the base model lacks (drift, zero jumps, direction, outliers),
    /// add them, and report the calibration before and after.
    Diagnose {
        /// Measurement CSV files (FORMAT.md §2); `-` reads standard input.
        #[arg(required = true)]
        files: Vec<PathBuf>,
        /// Truth JSON of simulated data (FORMAT.md §4): adds the errors before and after.
        #[arg(long)]
        truth: Option<PathBuf>,
        /// Number of polygon faces (default: the largest face in the file).
        #[arg(long)]
        faces: Option<usize>,
        /// Standard deviation of one reading, arcsec, if known: adds a χ² check.
        #[arg(long)]
        sigma: Option<Sigma>,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: FormatArg,
    },
    /// Evaluate a GUM uncertainty budget (TOML, FORMAT.md §5).
    Budget {
        /// Budget file; `-` reads standard input.
        file: PathBuf,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: FormatArg,
    },
    /// Compare two results quantity by quantity with En (ISO 13528); status 1 when some |En| > 1.
    Compare {
        /// First result file (FORMAT.md §3).
        a: PathBuf,
        /// Second result file.
        b: PathBuf,
        /// Correlation coefficient r between the two results (shared inputs), −1 … 1.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        correlation: f64,
        /// Output format.
        #[arg(long, value_enum, default_value = "table")]
        format: FormatArg,
    },
    /// Simulate a measurement run with a known truth.
    Simulate(SimulateArgs),
    /// Drive the instruments through a calibration run (FORMAT.md §7).
    Run(cli_instrument::RunArgs),
    /// Serve simulated instruments on pseudo-terminals, to try `run` without hardware.
    SimLab(cli_instrument::SimLabArgs),
}

#[derive(clap::Args)]
struct SimulateArgs {
    #[command(flatten)]
    truth: cli_truth::TruthArgs,
    /// Face read at step 0 by each autocollimator (the paper: 1,2).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// Number of polygon mountings (shift-angle data).
    #[arg(long, default_value_t = 1)]
    setups: u32,
    /// Whole faces the polygon is turned between mountings.
    #[arg(long, default_value_t = 1)]
    setup_shift: usize,
    /// Seconds per table stop.
    #[arg(long, default_value_t = 20.0)]
    step_seconds: f64,
    /// Where to write the measurement CSV (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `--monte-carlo`: a number of trials or the adaptive procedure.
#[derive(Debug, Clone, Copy)]
enum McTrials {
    Fixed(usize),
    Adaptive,
}

fn parse_trials(text: &str) -> Result<McTrials, String> {
    if text == "adaptive" {
        return Ok(McTrials::Adaptive);
    }
    let trials = text
        .parse::<usize>()
        .ok()
        .or_else(|| {
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && *v >= 1.0 && v.fract() == 0.0 && *v <= 1e12)
                .map(|v| v as usize)
        })
        .ok_or_else(|| {
            format!("expected a number of trials (e.g. 1000000 or 1e6) or `adaptive`, got {text:?}")
        })?;
    Ok(McTrials::Fixed(trials))
}

/// The uncertainty options of `polycal solve`.
struct UncertaintyArgs {
    budget: Option<PathBuf>,
    monte_carlo: Option<McTrials>,
    seed: u64,
    mc_digits: u32,
    mc_max_trials: usize,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let outcome = match cli.command {
        Command::Solve {
            files,
            faces,
            method,
            sigma,
            format,
            budget,
            monte_carlo,
            seed,
            mc_digits,
            mc_max_trials,
        } => run_solve(
            &files,
            faces,
            method,
            sigma,
            format,
            &UncertaintyArgs {
                budget,
                monte_carlo,
                seed,
                mc_digits,
                mc_max_trials,
            },
        ),
        Command::Diagnose {
            files,
            truth,
            faces,
            sigma,
            format,
        } => run_diagnose(&files, truth.as_deref(), faces, sigma, format),
        Command::Budget { file, format } => run_budget(&file, format),
        Command::Compare {
            a,
            b,
            correlation,
            format,
        } => run_compare(&a, &b, correlation, format),
        Command::Simulate(args) => run_simulate(&args).map(|()| EXIT_OK),
        Command::Run(args) => cli_instrument::run(&args),
        Command::SimLab(args) => cli_instrument::sim_lab(&args),
    };
    match outcome {
        Ok(code) => ExitCode::from(code),
        Err(error) => {
            eprintln!("error: {}", one_line(&error));
            ExitCode::from(EXIT_ERROR)
        }
    }
}

/// The error and its causes on one line.
fn one_line(error: &anyhow::Error) -> String {
    error
        .chain()
        .map(|e| e.to_string())
        .collect::<Vec<_>>()
        .join(": ")
}

fn display_name(path: &Path) -> String {
    path.display().to_string()
}

fn run_solve(
    files: &[PathBuf],
    faces: Option<usize>,
    method: MethodArg,
    sigma: Option<Sigma>,
    format: FormatArg,
    uncertainty: &UncertaintyArgs,
) -> Result<u8> {
    let budget = uncertainty
        .budget
        .as_deref()
        .map(InstrumentBudget::read_path)
        .transpose()?;
    if uncertainty.monte_carlo.is_some() && budget.is_none() {
        bail!(
            "--monte-carlo needs --budget: the Monte Carlo propagates the instrument budget \
             with the reading noise (see examples/budgets/instrument.toml)"
        );
    }
    if let Some(budget) = &budget {
        for note in budget.notes() {
            eprintln!("warning: {note}");
        }
    }
    let mc_options = uncertainty.monte_carlo.map(|trials| {
        McOptions::new(match trials {
            McTrials::Fixed(m) => Trials::Fixed(m),
            McTrials::Adaptive => Trials::Adaptive {
                significant_digits: uncertainty.mc_digits,
                max_trials: uncertainty.mc_max_trials,
            },
        })
        .with_seed(uncertainty.seed)
        .with_significant_digits(uncertainty.mc_digits)
        .with_solver(McSolver::Auto)
    });
    let options = SolveOptions::new()
        .with_method(match method {
            MethodArg::Auto => Method::Auto,
            MethodArg::ClosedForm => Method::ClosedForm,
            MethodArg::Lsq => Method::LeastSquares,
        })
        .with_sigma_opt(sigma);
    let several = files.len() > 1;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut failures = 0;
    let mut not_validated = 0;
    let mut csv_rows = Vec::new();
    for path in files {
        let name = display_name(path);
        let solved = MeasurementSet::read_path(path, faces)
            .map_err(anyhow::Error::from)
            .and_then(|set| {
                solve::solve(&set, &options)
                    .with_context(|| format!("{name}: cannot solve"))
                    .map(|solution| (set, solution))
            });
        let evaluated = solved.and_then(|(set, solution)| {
            let Some(budget) = &budget else {
                return Ok((solution, None, None));
            };
            let gum = calibration::evaluate(&set, &solution, budget)
                .map_err(|e| match e {
                    // Library messages name no flags: the CLI adds the one that helps.
                    calibration::CalibrationError::NoSigma => anyhow::anyhow!("{e} (--sigma)"),
                    e => e.into(),
                })
                .with_context(|| format!("{name}: cannot evaluate the uncertainty"))?;
            let mc = mc_options
                .as_ref()
                .map(|options| calibration::monte_carlo(&set, &solution, budget, &gum, options))
                .transpose()
                .with_context(|| format!("{name}: Monte Carlo failed"))?;
            Ok((solution, Some(gum), mc))
        });
        let (solution, gum, mc) = match evaluated {
            Ok(triple) => triple,
            Err(error) => {
                eprintln!("error: {}", one_line(&error));
                failures += 1;
                continue;
            }
        };
        if mc.as_ref().is_some_and(|mc| !mc.validated) {
            not_validated += 1;
        }
        match format {
            FormatArg::Json => {
                let mut report = SolveReport::new(&solution, several.then(|| name.clone()));
                if let Some(gum) = &gum {
                    report = report.with_uncertainty(gum);
                }
                if let Some(mc) = mc {
                    report = report.with_monte_carlo(mc);
                }
                writeln!(out, "{}", report.to_json()?)?;
            }
            FormatArg::Table => {
                if several {
                    writeln!(out)?;
                }
                let mut text = String::new();
                report::write_table(&mut text, &solution, &name, gum.as_ref(), mc.as_ref())?;
                write!(out, "{text}")?;
            }
            FormatArg::Csv => {
                let rows = report::result_rows_with(&solution, gum.as_ref());
                csv_rows.push((name, rows));
            }
        }
    }
    if matches!(format, FormatArg::Csv) && !csv_rows.is_empty() {
        if several {
            report::write_results_with_file(&mut out, &csv_rows)?;
        } else {
            polycal::results::write_results(&mut out, &csv_rows[0].1)?;
        }
    }
    out.flush()?;
    if failures > 0 {
        if several {
            bail!("{failures} of {} files could not be solved", files.len());
        }
        return Ok(EXIT_ERROR);
    }
    if not_validated > 0 {
        eprintln!(
            "warning: Monte Carlo does not validate the GUM uncertainty of some quantities \
             (JCGM 101 §8); see the monte_carlo results"
        );
        return Ok(EXIT_VERDICT);
    }
    Ok(EXIT_OK)
}

fn run_diagnose(
    files: &[PathBuf],
    truth: Option<&Path>,
    faces: Option<usize>,
    sigma: Option<Sigma>,
    format: FormatArg,
) -> Result<u8> {
    if matches!(format, FormatArg::Csv) {
        bail!("diagnose reports as table or json, not csv");
    }
    let truth = truth.map(Truth::read_path).transpose()?;
    let options = DiagnoseOptions::new().with_sigma_opt(sigma);
    let several = files.len() > 1;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let (mut failures, mut inadequate) = (0, 0);
    for path in files {
        let name = display_name(path);
        let diagnosed = MeasurementSet::read_path(path, faces)
            .map_err(anyhow::Error::from)
            .and_then(|set| {
                diagnose::diagnose(&set, &options).with_context(|| format!("{name}: cannot solve"))
            });
        let diagnosis = match diagnosed {
            Ok(d) => d,
            Err(error) => {
                eprintln!("error: {}", one_line(&error));
                failures += 1;
                continue;
            }
        };
        if let Some(t) = &truth
            && t.faces != diagnosis.before.faces
        {
            eprintln!(
                "error: {name}: the truth has {} faces, the measurement {}",
                t.faces, diagnosis.before.faces
            );
            failures += 1;
            continue;
        }
        if !diagnosis.adequacy.adequate {
            inadequate += 1;
        }
        match format {
            FormatArg::Json => {
                let report =
                    DiagnoseReport::new(&diagnosis, truth.as_ref(), several.then(|| name.clone()));
                writeln!(out, "{}", report.to_json()?)?;
            }
            _ => {
                if several {
                    writeln!(out)?;
                }
                let mut text = String::new();
                polycal::report::diagnose::write_table(
                    &mut text,
                    &diagnosis,
                    truth.as_ref(),
                    &name,
                )?;
                write!(out, "{text}")?;
            }
        }
    }
    out.flush()?;
    if failures > 0 {
        return Ok(EXIT_ERROR);
    }
    Ok(if inadequate > 0 {
        EXIT_VERDICT
    } else {
        EXIT_OK
    })
}

fn run_budget(file: &Path, format: FormatArg) -> Result<u8> {
    let budget = BudgetFile::read_path(file)?;
    let result = budget.evaluate().with_context(|| display_name(file))?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match format {
        FormatArg::Json => writeln!(out, "{}", report::to_json(&result)?)?,
        FormatArg::Table => write!(out, "{}", polycal::uncertainty::budget_table(&result))?,
        FormatArg::Csv => bail!("budget reports as table or json, not csv"),
    }
    out.flush()?;
    Ok(EXIT_OK)
}

fn run_compare(a: &Path, b: &Path, correlation: f64, format: FormatArg) -> Result<u8> {
    let file_a = read_result_file(a)?;
    let file_b = read_result_file(b)?;
    let options = CompareOptions {
        correlation,
        label_a: display_name(a),
        label_b: display_name(b),
    };
    let comparison = compare_files(&file_a, &file_b, &options)?;
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    match format {
        FormatArg::Json => writeln!(out, "{}", report::to_json(&comparison)?)?,
        FormatArg::Table => {
            let mut text = String::new();
            polycal::report::compare::write_table(&mut text, &comparison)?;
            write!(out, "{text}")?;
        }
        FormatArg::Csv => bail!("compare reports as table or json, not csv"),
    }
    out.flush()?;
    Ok(if comparison.verdict_ok() {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}

fn run_simulate(args: &SimulateArgs) -> Result<()> {
    let config = args.truth.config(
        args.ac_faces.clone(),
        args.setups,
        args.setup_shift,
        args.step_seconds,
    )?;
    let (set, truth) = simulate::simulate(&config)?;
    let comments = vec![format!(
        "polycal {} simulate: {} faces, ac faces {:?}, {} cycles, noise {} arcsec, seed {}",
        env!("CARGO_PKG_VERSION"),
        config.faces,
        config.ac_faces,
        config.cycles,
        config.noise_arcsec,
        config.seed
    )];
    match &args.out {
        Some(path) => set.write_path(path, &comments)?,
        None => {
            let stdout = std::io::stdout();
            set.write_to(stdout.lock(), &comments)
                .context("cannot write to standard output")?;
        }
    }
    args.truth.write_truth(&truth)
}
