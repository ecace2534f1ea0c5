//! `polycal history`: the calibrations of one standard over time (docs/FORMAT.md §13.2).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Result, bail};
use clap::ValueEnum;
use polycal::history::{Calibration, DatedPath, DatedReadError, HistoryOptions, evaluate};
use polycal::results::Quantity;

use super::EXIT_OK;

/// After `polycal history --help`.
pub const EXAMPLES: &str = "\
The contract (JSON names, the one test of the drift vector at 5 %, the prediction and its
u): docs/FORMAT.md §13.2. Status 0 when the history is evaluated (the decision is in the
output, not the status), 2 an input refused. --at defaults to today (UTC), or to the day
of SOURCE_DATE_EPOCH (seconds since 1970) when it is set.

Examples:
  polycal history examples/data/history/2019.csv@2019-03-12 examples/data/history/2020.csv@2020-03-10 \\
      examples/data/history/2021.csv@2021-03-02 examples/data/history/2022.csv@2022-03-15 \\
      examples/data/history/2023.csv@2023-03-07 examples/data/history/2024.csv@2024-03-05 --at 2025-03-01
  polycal history examples/data/history/2019.csv@2019-03-12 examples/data/history/2024.csv@2024-03-05 \\
      --at 2025-03-01 --max-u 0.5 --format json";

/// `--at`: a day `YYYY-MM-DD`.
fn day(text: &str) -> std::result::Result<String, String> {
    match polycal::clock::days_from_date(text) {
        Some(_) => Ok(text.to_string()),
        None => Err(format!("{text:?} is not a day YYYY-MM-DD of the calendar")),
    }
}

/// `--max-u`: a positive number of arcseconds.
fn positive(text: &str) -> std::result::Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("{text:?} is not a positive number of arcseconds")),
    }
}

/// `--quantity`.
fn parse_quantity(name: &str) -> std::result::Result<Quantity, String> {
    match Quantity::from_name(name) {
        Some(q @ (Quantity::PitchDeviation | Quantity::FaceDeviation | Quantity::EncoderError)) => {
            Ok(q)
        }
        _ => Err(format!(
            "{name:?}: a history follows pitch_deviation, face_deviation or encoder_error"
        )),
    }
}

/// `history --format`.
#[derive(Clone, Copy, ValueEnum)]
enum HistoryFormat {
    Table,
    Json,
}

/// Arguments of `polycal history`.
#[derive(clap::Args)]
pub struct HistoryArgs {
    /// The standard's calibrations, FILE@DATE each: a result file (docs/FORMAT.md §3; u,
    /// or U and k, on every row of the quantity) or a DCC (§13.3), and the day it was
    /// calibrated, YYYY-MM-DD; a DCC without @DATE is dated by its endPerformanceDate;
    /// at least 2.
    #[arg(value_name = "FILE@DATE", required = true, value_parser = clap::value_parser!(DatedPath))]
    calibrations: Vec<DatedPath>,
    /// The day of the prediction, YYYY-MM-DD (default: today, UTC; SOURCE_DATE_EPOCH's
    /// day when it is set).
    #[arg(long, value_name = "DATE", value_parser = day)]
    at: Option<String>,
    /// The quantity followed: pitch_deviation, face_deviation or encoder_error.
    #[arg(long, default_value = "pitch_deviation", value_parser = parse_quantity)]
    quantity: Quantity,
    /// The largest acceptable expanded uncertainty (k = 2) of the prediction, arcsec: the
    /// date at which it is reached (a recalibration interval, ILAC-G24's method of drift).
    #[arg(long, value_name = "X", value_parser = positive)]
    max_u: Option<f64>,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    format: HistoryFormat,
    /// Write the control charts as SVG into DIR (created if missing):
    /// history-control-charts.svg, whatever --format is.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

/// Today (UTC), or the day of `SOURCE_DATE_EPOCH` when it is set.
pub fn today() -> Result<String> {
    Ok(match super::report::source_date()? {
        Some(stamp) => stamp.chars().take(10).collect(),
        None => polycal::clock::today(),
    })
}

/// One calibration read: its result file or certificate (a refusal names the file, line
/// and column, with what to do when the file is of another kind).
pub fn read(dated: &DatedPath) -> Result<Calibration> {
    let (bytes, source) = polycal::input::read_bytes(&dated.path)
        .map_err(|(file, source)| polycal::input::FileError::Io { file, source })?;
    dated.calibration(&bytes, &source).map_err(|e| match e {
        DatedReadError::File(e) => super::wrong_file::results(e),
        e => e.into(),
    })
}

/// `polycal history`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &HistoryArgs) -> Result<u8> {
    super::stdin_once(
        args.calibrations
            .iter()
            .map(|d| (d.text.as_str(), Some(d.path.as_path()))),
    )?;
    let inputs: Vec<&Path> = args.calibrations.iter().map(|d| d.path.as_path()).collect();
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::History,
        &inputs,
    )?;
    let calibrations = args
        .calibrations
        .iter()
        .map(read)
        .collect::<Result<Vec<_>>>()?;
    let at = match &args.at {
        Some(at) => at.clone(),
        None => today()?,
    };
    let mut options = HistoryOptions::new(&at)?.with_quantity(args.quantity);
    if let Some(max_u) = args.max_u {
        options = options.with_max_expanded_u(max_u);
    }
    let history = match evaluate(&calibrations, &options) {
        Ok(history) => history,
        Err(e @ polycal::history::HistoryError::TooFewCalibrations(_)) => {
            bail!("{e}; give each calibration as FILE@DATE")
        }
        Err(e) => return Err(e.into()),
    };
    if let Some(dir) = &args.plot {
        super::write_plot(dir, &polycal::figure::history_figures(&history), &inputs)?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        HistoryFormat::Json => writeln!(stdout, "{}", polycal::output::to_json(&history)?)?,
        HistoryFormat::Table => {
            let mut text = String::new();
            polycal::output::history::write_table(&mut text, &history)?;
            write!(stdout, "{text}")?;
        }
    }
    stdout.flush()?;
    Ok(EXIT_OK)
}
