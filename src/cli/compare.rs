//! `polycal compare`: two results quantity by quantity with En, and one verdict for the
//! whole comparison (docs/FORMAT.md §5.4).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::ValueEnum;
use polycal::compare::{CompareError, CompareOptions, VerdictRule, compare_files};
use polycal::input::display_name;
use polycal::results::read_result_file;

use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal compare --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal solve examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml --format csv > a.csv
  polycal simulate --closing --seed 2 | polycal solve - --budget examples/budgets/instrument.toml --format csv > b.csv
  polycal compare a.csv b.csv
  polycal compare a.csv b.csv --include-setup --format json
  polycal compare a.csv b.csv --correlation 0.3 --format csv
  polycal compare a.csv b.csv --verdict en";

/// Arguments of `polycal compare`.
#[derive(clap::Args)]
pub struct CompareArgs {
    /// First result file (docs/FORMAT.md §3), or a DCC written by `report --dcc` (read by
    /// its content, §13.3); `-` reads standard input.
    a: PathBuf,
    /// Second result file or DCC.
    b: PathBuf,
    /// Correlation coefficient r between the two results (shared inputs), −1 … 1.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    correlation: f64,
    /// Count the setup errors in the verdict and in the largest |En|; without it they are
    /// listed but left out, since they depend on the mounting (docs/FORMAT.md §5.4).
    /// Encoder errors are matched by angle_deg when both files carry it, by index otherwise.
    #[arg(long)]
    include_setup: bool,
    /// The rule of the verdict and the exit status (docs/FORMAT.md §5.4): vector, one test
    /// at 5 % of the differences of the closed quantities as one vector (status 1 when
    /// χ² > χ²_0.95(ν); needs u, or k for u = U/k, on every row); en, the per-row rule for
    /// schemes that prescribe it (status 1 when some |En| > 1; with 24 rows some |En| > 1 in
    /// about two consistent comparisons of three).
    #[arg(long, value_enum, default_value = "vector")]
    verdict: VerdictArg,
    /// Output format (csv: one row per compared quantity, columns
    /// quantity,index,a,b,difference,U_a,U_b,en,index_b,angle_deg,in_verdict;
    /// docs/FORMAT.md §5.4).
    #[arg(long, value_enum, default_value = "table")]
    format: CompareFormat,
    /// Write the figures as SVG files into DIR (created if missing), one file per figure
    /// with a stable name (docs/FORMAT.md §10), whatever --format is.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

impl CompareArgs {
    /// The files this command reads, which no output may replace.
    fn inputs(&self) -> Vec<&std::path::Path> {
        vec![self.a.as_path(), self.b.as_path()]
    }
}

/// `compare --verdict`.
#[derive(Clone, Copy, ValueEnum)]
enum VerdictArg {
    Vector,
    En,
}

impl From<VerdictArg> for VerdictRule {
    fn from(arg: VerdictArg) -> Self {
        match arg {
            VerdictArg::Vector => VerdictRule::Vector,
            VerdictArg::En => VerdictRule::En,
        }
    }
}

/// `compare --format`.
#[derive(Clone, Copy, ValueEnum)]
enum CompareFormat {
    Table,
    Json,
    Csv,
}

/// `polycal compare`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &CompareArgs) -> Result<u8> {
    super::stdin_once([("A", Some(args.a.as_path())), ("B", Some(args.b.as_path()))])?;
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Compare,
        &args.inputs(),
    )?;
    let file_a = read_result_file(&args.a).map_err(super::wrong_file::results)?;
    let file_b = read_result_file(&args.b).map_err(super::wrong_file::results)?;
    let options = CompareOptions::new()
        .with_correlation(args.correlation)
        .with_include_setup(args.include_setup)
        .with_verdict(args.verdict.into())
        .with_labels(display_name(&args.a), display_name(&args.b));
    let comparison = compare_files(&file_a, &file_b, &options).map_err(|e| match e {
        // Library messages name no flags: the CLI adds the one that helps.
        CompareError::OnlySetupInCommon { .. } => super::with_hint(
            e,
            "--include-setup",
            "--include-setup counts them in the verdict",
        ),
        CompareError::NoStandardU { .. } | CompareError::NoVector { .. } => super::with_hint(
            e,
            "--verdict en",
            "--verdict en judges row by row with U alone",
        ),
        e => e.into(),
    })?;
    if let Some(dir) = &args.plot {
        let figures = polycal::figure::compare_figures_labelled(
            &comparison,
            // figures are documents: the files by their names alone
            &polycal::input::document_name(&display_name(&args.a)),
            &polycal::input::document_name(&display_name(&args.b)),
        );
        super::write_plot(dir, &figures, &args.inputs())?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        CompareFormat::Json => writeln!(stdout, "{}", polycal::output::to_json(&comparison)?)?,
        CompareFormat::Table => {
            let mut text = String::new();
            polycal::output::compare::write_table(&mut text, &comparison)?;
            write!(stdout, "{text}")?;
        }
        CompareFormat::Csv => polycal::output::compare::write_csv(&mut stdout, &comparison)?,
    }
    stdout.flush()?;
    Ok(if comparison.verdict_ok() {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}
