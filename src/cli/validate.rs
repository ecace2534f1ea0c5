//! `polycal validate`: the software against reference results computed without it
//! (docs/FORMAT.md §13.1), the validation record a laboratory files.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::ValueEnum;
use polycal::validation;

use super::files::CommandOutputs;
use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal validate --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal validate
  polycal validate --format json
  polycal validate --out validation.html
  polycal validate --cases examples/validation";

/// Arguments of `polycal validate`.
#[derive(clap::Args)]
pub struct ValidateArgs {
    /// Write the validation record as one self-contained HTML file.
    #[arg(long, value_name = "REPORT.html")]
    out: Option<PathBuf>,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    format: ValidateFormat,
    /// Run the cases of DIR (one sub-directory per case, each with a case.toml and a
    /// reference.json, docs/FORMAT.md §13.1) instead of the bundled ones.
    #[arg(long, value_name = "DIR")]
    cases: Option<PathBuf>,
}

/// `validate --format`.
#[derive(Clone, Copy, ValueEnum)]
enum ValidateFormat {
    Table,
    Json,
}

/// `polycal validate`: 0 when every case passes, 1 when one fails, or an error (status 2)
/// for a case that cannot be read.
pub fn run(args: &ValidateArgs) -> Result<u8> {
    let mut files = CommandOutputs::new([])?;
    if let Some(out) = &args.out {
        files.check([("--out", out.as_path())])?;
    }
    let cases = match &args.cases {
        Some(dir) => validation::read_cases(dir).context("--cases")?,
        None => validation::bundled(),
    };
    let date = super::report::source_date()?
        .unwrap_or_else(|| polycal::clock::rfc3339(polycal::clock::unix_now()));
    let record = validation::validate_dated(&cases, date)?;
    if let Some(out) = &args.out {
        let mut html = String::new();
        validation::write_html(&mut html, &record)?;
        files.write("--out", out, html.as_bytes())?;
        files.commit()?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        ValidateFormat::Json => writeln!(stdout, "{}", polycal::output::to_json(&record)?)?,
        ValidateFormat::Table => {
            let mut text = String::new();
            validation::write_table(&mut text, &record)?;
            write!(stdout, "{text}")?;
        }
    }
    stdout.flush()?;
    Ok(if record.failed == 0 {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}
