//! `polycal budget`: a GUM uncertainty budget evaluated.

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::ValueEnum;
use polycal::uncertainty::BudgetFile;

use super::EXIT_OK;

/// After `polycal budget --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal budget examples/budgets/paper-table1.toml
  polycal budget examples/budgets/gum-h1-end-gauge.toml --format json
  polycal budget - < examples/budgets/paper-table1.toml";

/// Arguments of `polycal budget`.
#[derive(clap::Args)]
pub struct BudgetArgs {
    /// Budget file; `-` reads standard input.
    file: PathBuf,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    format: ReportFormat,
}

/// `budget --format`.
#[derive(Clone, Copy, ValueEnum)]
enum ReportFormat {
    Table,
    Json,
}

/// `polycal budget`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &BudgetArgs) -> Result<u8> {
    let budget = BudgetFile::read_path(&args.file).map_err(super::wrong_file::budget)?;
    // the evaluation's errors name the file already
    let result = budget.evaluate()?;
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        ReportFormat::Json => writeln!(stdout, "{}", polycal::output::to_json(&result)?)?,
        ReportFormat::Table => {
            write!(stdout, "{}", polycal::uncertainty::budget_table(&result))?;
        }
    }
    stdout.flush()?;
    Ok(EXIT_OK)
}
