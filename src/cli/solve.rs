//! `polycal solve`: measurement files to pitch deviations, encoder errors and setup
//! errors, with the uncertainty of a budget and a Monte Carlo through the solver.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::ValueEnum;
use polycal::figure::FigureSet;
use polycal::input::display_name;
use polycal::measurement::cross_talk::{StatedCrossTalk, check_distinct, correct_cross_talk};
use polycal::measurement::{MeasurementSet, Sigma};
use polycal::output::{self, SolveReport};
use polycal::results::ResultRow;
use polycal::solve::sub_pitch::{ShiftGeometry, SubPitchSolution, solve_shifted_with_progress};
use polycal::solve::{self, Method, Solution, SolveError, SolveOptions};
use polycal::uncertainty::calibration::{
    self, CalibrationMonteCarlo, CalibrationUncertainty, InstrumentBudget, KnownCorrection,
    McOptions,
};

use super::monte_carlo::McArgs;
use super::output::Output;
use super::{EXIT_ERROR, EXIT_OK, EXIT_VERDICT, with_hint};

/// After `polycal solve --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal solve examples/data/polygon24-2ac-6cycles.csv
  polycal solve examples/data/polygon24-2ac-6cycles.csv --format csv > result.csv
  polycal solve examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml
  polycal solve examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml --monte-carlo 1e5 --format json";

/// Arguments of `polycal solve`.
#[derive(clap::Args)]
pub struct SolveArgs {
    /// Measurement CSV files (docs/FORMAT.md §2); `-` reads standard input.
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
    #[arg(long, allow_negative_numbers = true)]
    sigma: Option<Sigma>,
    /// Cross-talk of an autocollimator stated from its calibration, AC:C or AC:C:U (C in
    /// arcsec of reading per arcsec of reading_y, |C| ≤ 1; U its standard uncertainty,
    /// 0 … 1): its readings are corrected to reading − C·reading_y, U enters --budget and
    /// --monte-carlo (without --budget it is not used: a warning says so), and the JSON
    /// ends with `stated_cross_talk` (docs/FORMAT.md §6); repeatable, one per
    /// autocollimator.
    #[arg(
        long = "cross-talk",
        value_name = "AC:C[:U]",
        allow_negative_numbers = true
    )]
    cross_talk: Vec<StatedCrossTalk>,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    format: SolveFormat,
    /// Instrument budget (TOML, docs/FORMAT.md §5 with `acts_on` per component): adds the
    /// expanded uncertainty U and k of every result, combining the fit's type A with
    /// the budget through the design.
    #[arg(long, value_name = "FILE.toml")]
    budget: Option<PathBuf>,
    #[command(flatten)]
    monte_carlo: McArgs,
    /// Write the figures as SVG files into DIR (created if missing), one file per figure
    /// with a stable name (docs/FORMAT.md §10), whatever --format is. Takes one input file:
    /// with several, run once per file.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Add `pitch_deviation_covariance` to the JSON: the fit's N × N covariance of the
    /// pitch deviations, arcsec² (docs/FORMAT.md §5.1), for `polycal kc`. With
    /// --format json only.
    #[arg(long)]
    covariance: bool,
}

impl SolveArgs {
    /// The files this command reads, which no output may replace.
    fn inputs(&self) -> Vec<&Path> {
        let mut v: Vec<&Path> = self.files.iter().map(PathBuf::as_path).collect();
        v.extend(self.budget.as_deref());
        v
    }
}

/// `solve --format`.
#[derive(Clone, Copy, ValueEnum)]
enum SolveFormat {
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
    /// General constrained least squares (the circulant engine where the design is
    /// regular enough, else the dense factorisation).
    Lsq,
    /// Least squares by the dense reference factorisation (a cross-check; O(N³)).
    Dense,
}

/// `polycal solve`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &SolveArgs, out: &Output) -> Result<u8> {
    super::stdin_once(
        args.files
            .iter()
            .map(|f| ("a measurement file", Some(f.as_path())))
            .chain([("--budget", args.budget.as_deref())]),
    )?;
    if args.covariance && !matches!(args.format, SolveFormat::Json) {
        anyhow::bail!("--covariance adds a member to the JSON: give --format json with it");
    }
    super::plot_one_file(args.plot.as_deref(), args.files.len())?;
    super::check_plot(
        args.plot.as_deref(),
        FigureSet::Solve {
            budget: args.budget.is_some(),
        },
        &args.inputs(),
    )?;
    check_stated_cross_talk(&args.cross_talk, args.budget.is_some(), out)?;
    let mc_options = args.monte_carlo.options(args.budget.is_some())?;
    let budget = read_budget(args.budget.as_deref(), out)?;
    let options = SolveOptions::new()
        .with_method(match args.method {
            MethodArg::Auto => Method::Auto,
            MethodArg::ClosedForm => Method::ClosedForm,
            MethodArg::Lsq => Method::LeastSquares,
            MethodArg::Dense => Method::Dense,
        })
        .with_sigma_opt(args.sigma);
    let files = &args.files;
    let several = files.len() > 1;
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    let mut failures = 0;
    let mut not_validated = 0;
    let mut csv_rows = Vec::new();
    let run = SolveRun {
        args,
        out,
        options: &options,
        budget: budget.as_ref(),
        mc_options: mc_options.as_ref(),
        several,
    };
    for path in files {
        // The name in messages (`<stdin>` for `-`); results keep the path as given.
        let name = display_name(path);
        let label = polycal::input::shown_path(path);
        let evaluated = run
            .solved(path, &name)
            .and_then(|(set, solved)| run.evaluated(&set, solved, &name));
        let (solved, gum, mc) = match evaluated {
            Ok(triple) => triple,
            Err(error) => {
                out.error(&error);
                failures += 1;
                continue;
            }
        };
        if mc.as_ref().is_some_and(|mc| !mc.validated) {
            not_validated += 1;
        }
        let incomplete = match &solved {
            Solved::Positions(solution) => &solution.incomplete_cycles,
            Solved::SubPitch(solved) => &solved.solution.incomplete_cycles,
        };
        for cycle in incomplete {
            out.warning(format_args!("{name}: {cycle}"));
        }
        let written = match solved {
            Solved::Positions(solution) => run.print_solution(
                &solution,
                (gum.as_ref(), mc.as_ref()),
                (&label, &name),
                &mut stdout,
                &mut csv_rows,
            )?,
            Solved::SubPitch(solved) => {
                run.print_sub_pitch(&solved, &label, &mut stdout, &mut csv_rows)?;
                true
            }
        };
        if !written {
            failures += 1;
        }
    }
    if matches!(args.format, SolveFormat::Csv) {
        write_result_csv(&mut stdout, several, &csv_rows)?;
    }
    stdout.flush()?;
    if failures > 0 {
        // each failed file has had its own `error:` line (docs/FORMAT.md §8); the count
        // is a summary, not another error
        if several {
            out.info(format!(
                "{failures} of {} files could not be solved",
                files.len()
            ));
        }
        return Ok(EXIT_ERROR);
    }
    if not_validated > 0 {
        out.warning(
            "Monte Carlo does not validate the GUM uncertainty of some quantities \
             (JCGM 101 §8); see the monte_carlo results",
        );
        return Ok(EXIT_VERDICT);
    }
    Ok(EXIT_OK)
}

/// What `polycal solve` of each file needs besides the file: the arguments, the solver's
/// options, the budget and the Monte Carlo's options.
struct SolveRun<'a> {
    args: &'a SolveArgs,
    out: &'a Output,
    options: &'a SolveOptions,
    budget: Option<&'a InstrumentBudget>,
    mc_options: Option<&'a McOptions<'static>>,
    several: bool,
}

/// A file solved, with the budget's GUM uncertainty and Monte Carlo where evaluated.
type Evaluated = (
    Solved,
    Option<CalibrationUncertainty>,
    Option<CalibrationMonteCarlo>,
);

/// A file's result rows (per file label) for `--format csv`, written together at the end.
type CsvRows = Vec<(String, Vec<ResultRow>)>;

impl SolveRun<'_> {
    /// The measurement file at `path` (named `name` in messages) read, corrected for the
    /// stated cross-talk, and solved: in encoder positions, or at every angle of every
    /// coset for sub-pitch mountings.
    fn solved(&self, path: &Path, name: &str) -> Result<(MeasurementSet, Solved)> {
        let (args, out, options) = (self.args, self.out, self.options);
        MeasurementSet::read_path(path, args.faces)
            .map_err(super::wrong_file::measurement)
            .and_then(|set| corrected(set, &args.cross_talk))
            .and_then(|set| {
                if self.budget.is_some()
                    && let Some(refusal) = shift_refusal(
                        &set,
                        name,
                        "--budget",
                        "polycal solve without it evaluates them",
                    )
                {
                    return Err(refusal);
                }
                // One bar per file (the dense reference's work: seconds to minutes for
                // hundreds of faces), cleared when its solution is done.
                let bar = out.progress_bar_of("Solving", "steps");
                if set.has_shifts() && ShiftGeometry::of(&set).is_sub_pitch() {
                    // docs/FORMAT.md §9.1: encoder errors at every angle of every coset
                    return solve_shifted_with_progress(&set, options, Some(&bar))
                        .map_err(actionable)
                        .with_context(|| format!("{name}: cannot solve"))
                        .map(|solved| (set, Solved::SubPitch(solved)));
                }
                solve::solve_with_progress(&set, options, Some(&bar))
                    .map_err(actionable)
                    .with_context(|| format!("{name}: cannot solve"))
                    .map(|solution| (set, Solved::Positions(solution)))
            })
    }

    /// The budget's GUM uncertainty of a solution in encoder positions, and its Monte
    /// Carlo when asked (none for sub-pitch mountings, refused with a budget).
    fn evaluated(&self, set: &MeasurementSet, solved: Solved, name: &str) -> Result<Evaluated> {
        let args = self.args;
        let solution = match solved {
            Solved::SubPitch(solved) => return Ok((Solved::SubPitch(solved), None, None)),
            Solved::Positions(solution) => solution,
        };
        let Some(budget) = self.budget else {
            return Ok((Solved::Positions(solution), None, None));
        };
        let gum = evaluate_budget(set, &solution, budget, &args.cross_talk, name)?;
        let mc = self
            .mc_options
            .map(|options| {
                // One bar per file, cleared when its Monte Carlo ends.
                let progress = self.out.progress_bar("Monte Carlo");
                let options = (*options).with_progress(&progress);
                let corrections = KnownCorrection::of_stated_cross_talk(set, &args.cross_talk);
                calibration::monte_carlo_with_corrections(
                    set,
                    &solution,
                    budget,
                    &corrections,
                    &gum,
                    &options,
                )
            })
            .transpose()
            .with_context(|| format!("{name}: Monte Carlo failed"))?;
        Ok((Solved::Positions(solution), Some(gum), mc))
    }

    /// A sub-pitch solution's figures, and its JSON, table or CSV rows.
    fn print_sub_pitch(
        &self,
        solved: &SubPitchSolution,
        label: &str,
        stdout: &mut dyn Write,
        csv_rows: &mut CsvRows,
    ) -> Result<()> {
        let args = self.args;
        if let Some(dir) = &args.plot {
            let report = SolveReport::sub_pitch(solved, None);
            super::write_plot(
                dir,
                &polycal::figure::solve_figures(&report),
                &args.inputs(),
            )?;
        }
        match args.format {
            SolveFormat::Json => {
                let report =
                    SolveReport::sub_pitch(solved, self.several.then(|| label.to_string()));
                let json = output::to_json_with_stated_cross_talk(&report, &args.cross_talk)?;
                writeln!(stdout, "{json}")?;
            }
            SolveFormat::Table => {
                if self.several {
                    writeln!(stdout)?;
                }
                let mut text = String::new();
                output::write_sub_pitch_table(&mut text, solved, label)?;
                output::write_stated_cross_talk(&mut text, &args.cross_talk)?;
                write!(stdout, "{text}")?;
            }
            SolveFormat::Csv => {
                csv_rows.push((label.to_string(), output::sub_pitch_result_rows(solved)));
            }
        }
        Ok(())
    }

    /// A solution's figures, and its JSON, table or CSV rows, with the budget's GUM
    /// uncertainty and Monte Carlo (`gum`, `mc`) where evaluated. False when its rows
    /// cannot be written (the `error:` line written, naming the file `name`).
    fn print_solution(
        &self,
        solution: &Solution,
        (gum, mc): (
            Option<&CalibrationUncertainty>,
            Option<&CalibrationMonteCarlo>,
        ),
        (label, name): (&str, &str),
        stdout: &mut dyn Write,
        csv_rows: &mut CsvRows,
    ) -> Result<bool> {
        let args = self.args;
        let json_report =
            (matches!(args.format, SolveFormat::Json) || args.plot.is_some()).then(|| {
                let mut report =
                    SolveReport::new(solution, self.several.then(|| label.to_string()));
                if let Some(gum) = gum {
                    report = report.with_uncertainty(gum);
                }
                if let Some(mc) = mc.cloned() {
                    report = report.with_monte_carlo(mc);
                }
                if args.covariance {
                    report = report.with_pitch_deviation_covariance(solution);
                }
                report
            });
        if let (Some(dir), Some(report)) = (&args.plot, &json_report) {
            super::write_plot(dir, &polycal::figure::solve_figures(report), &args.inputs())?;
        }
        match args.format {
            SolveFormat::Json => {
                if let Some(report) = &json_report {
                    let json = output::to_json_with_stated_cross_talk(report, &args.cross_talk)?;
                    writeln!(stdout, "{json}")?;
                }
            }
            SolveFormat::Table => {
                if self.several {
                    writeln!(stdout)?;
                }
                let mut text = String::new();
                output::write_table(&mut text, solution, label, gum, mc)?;
                output::write_stated_cross_talk(&mut text, &args.cross_talk)?;
                write!(stdout, "{text}")?;
            }
            SolveFormat::Csv => {
                let rows = output::result_rows_with(solution, gum);
                // checked before any row is written: a refusal names this file
                if let Err(problem) = polycal::results::check_rows(&rows) {
                    self.out
                        .error_message(format!("{name}: cannot write its results: {problem}"));
                    return Ok(false);
                }
                csv_rows.push((label.to_string(), rows));
            }
        }
        Ok(true)
    }
}

/// The instrument budget of `--budget` (`solve` and `diagnose`), read once, with a
/// `warning:` for each of its notes (a type-A component counts twice).
pub(super) fn read_budget(path: Option<&Path>, out: &Output) -> Result<Option<InstrumentBudget>> {
    let budget = path
        .map(InstrumentBudget::read_path)
        .transpose()
        .map_err(super::wrong_file::budget_option)?;
    if let Some(budget) = &budget {
        for note in budget.notes() {
            out.warning(note);
        }
    }
    Ok(budget)
}

/// The GUM uncertainty of a solved file under the budget (`solve` and `diagnose`), its
/// error naming the file and the option that helps.
pub(super) fn evaluate_budget(
    set: &MeasurementSet,
    solution: &Solution,
    budget: &InstrumentBudget,
    stated: &[StatedCrossTalk],
    name: &str,
) -> Result<CalibrationUncertainty> {
    let corrections = KnownCorrection::of_stated_cross_talk(set, stated);
    calibration::evaluate_with_corrections(set, solution, budget, &corrections)
        .map_err(|e| match e {
            // Library messages name no flags: the CLI adds the one that helps.
            calibration::CalibrationError::NoSigma => anyhow::anyhow!("{e} (--sigma)"),
            e => e.into(),
        })
        .with_context(|| format!("{name}: cannot evaluate the uncertainty"))
}

/// The set with every stated cross-talk corrected for (`--cross-talk`, `solve` and
/// `diagnose`); the error names the option.
pub(super) fn corrected(set: MeasurementSet, stated: &[StatedCrossTalk]) -> Result<MeasurementSet> {
    if stated.is_empty() {
        return Ok(set);
    }
    correct_cross_talk(&set, stated).map_err(|e| anyhow::anyhow!("{e} (--cross-talk)"))
}

/// Refuses an autocollimator stated twice; warns that a stated U is used only with a
/// budget (`solve`, `diagnose` and `report`).
pub(super) fn check_stated_cross_talk(
    stated: &[StatedCrossTalk],
    with_budget: bool,
    out: &Output,
) -> Result<()> {
    check_distinct(stated).map_err(|e| anyhow::anyhow!("--cross-talk: {e}"))?;
    if !with_budget && stated.iter().any(|s| s.u.is_some()) {
        out.warning(format_args!(
            "--cross-talk: the stated U enters the uncertainty only with --budget (the fit's type A does not see it)"
        ));
    }
    Ok(())
}

/// The result file (docs/FORMAT.md §3) of the files solved (`solve` and `diagnose`): with
/// several input files, one CSV with a leading `file` column; nothing when none was solved.
pub(super) fn write_result_csv(
    stdout: &mut impl Write,
    several: bool,
    files: &[(String, Vec<ResultRow>)],
) -> std::io::Result<()> {
    match files {
        [] => Ok(()),
        [(_, rows)] if !several => polycal::results::write_results(stdout, rows),
        _ => output::write_results_with_file(stdout, files),
    }
}

/// What `solve` solved: a set in encoder positions (no shift, or whole-face shifts), or
/// one with sub-pitch mountings.
enum Solved {
    Positions(Solution),
    SubPitch(SubPitchSolution),
}

/// The refusal of `what` (an option, or a command) for a set with shifted mountings,
/// which it does not handle yet, with the `instead` that does; `None` when every shift
/// is 0.
pub(super) fn shift_refusal(
    set: &MeasurementSet,
    name: &str,
    what: &str,
    instead: &str,
) -> Option<anyhow::Error> {
    if !set.has_shifts() {
        return None;
    }
    Some(if ShiftGeometry::of(set).is_sub_pitch() {
        anyhow::anyhow!(
            "{name}: {what} is not supported for sub-pitch mountings (a `shift` that is not a \
             whole multiple of 360°/N) yet; {instead}"
        )
    } else {
        anyhow::anyhow!(
            "{name}: {what} is not supported for shifted mountings (a `shift` other than 0) \
             yet; {instead}"
        )
    })
}

/// A solver error with the option that gets past it, where one does.
fn actionable(error: SolveError) -> anyhow::Error {
    match error {
        SolveError::ClosedFormNotApplicable(_) => {
            with_hint(error, "--method lsq", "use --method lsq")
        }
        other => other.into(),
    }
}
