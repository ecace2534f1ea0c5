//! `polycal report`: the documents of a calibration (docs/FORMAT.md §10): the
//! self-contained HTML report and the Digital Calibration Certificate (§10.3).

use std::path::PathBuf;

use anyhow::{Result, bail};
use polycal::certificate::dcc::{self, DccError};
use polycal::certificate::{CalibrationReport, ReportError, ReportInputs};
use polycal::measurement::Sigma;

use super::files::CommandOutputs;
use super::output::Output;
use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal report --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal report examples/data/polygon24-2ac-6cycles.csv --out report.html
  polycal report examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml \\
      --diagnose --reference examples/data/polygon24-shift-angle.result.csv \\
      --meta examples/report/meta.toml --out report.html
  polycal report examples/data/selfa-168.csv --budget examples/budgets/selfcal.toml --out selfcal.html
  polycal report examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml \\
      --meta examples/report/meta.toml --out report.html --dcc certificate.xml
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv \\
      --format json > kc.json
  polycal report examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml \\
      --kc kc.json --kc-lab A --out report.html
  polycal report examples/data/history/run-2026-11-03.csv --budget examples/budgets/instrument.toml \\
      --meta examples/report/meta.toml --history examples/data/history/2023.csv@2023-03-07 \\
      --history examples/data/history/2024.csv@2024-03-05 --out report.html

The report's date is now (UTC), or SOURCE_DATE_EPOCH (seconds since 1970) when it is set:
the same inputs then give the same bytes.";

/// Arguments of `polycal report`.
#[derive(clap::Args)]
pub struct ReportArgs {
    /// Measurement CSV (docs/FORMAT.md §2) or self-calibration CSV (§9.2); `-` reads
    /// standard input.
    file: PathBuf,
    /// Number of polygon faces (self-calibration: positions), when not the file's largest.
    #[arg(long)]
    faces: Option<usize>,
    /// Standard deviation of one reading, arcsec, for the uncertainties of an exactly
    /// determined fit (dof = 0, e.g. the paper's bare two-autocollimator cycle).
    #[arg(long, allow_negative_numbers = true)]
    sigma: Option<Sigma>,
    /// Instrument budget (TOML, docs/FORMAT.md §5.1): U and k of every result, and the
    /// budget section. Needed for --reference with a polygon file.
    #[arg(long, value_name = "B.toml")]
    budget: Option<PathBuf>,
    /// Cross-talk of an autocollimator stated from its calibration, AC:C or AC:C:U, as for
    /// `solve` and `diagnose`: the readings corrected, U in the budget, the stated values
    /// in the method section (docs/FORMAT.md §6, §10.2); polygon files only; repeatable.
    #[arg(
        long = "cross-talk",
        value_name = "AC:C[:U]",
        allow_negative_numbers = true
    )]
    cross_talk: Vec<polycal::measurement::cross_talk::StatedCrossTalk>,
    /// Diagnose the measurement (as `polycal diagnose`) and add the diagnosis section;
    /// status 1 when the final model is not adequate.
    #[arg(long)]
    diagnose: bool,
    /// Truth file of simulated data: the diagnosis's error before and after.
    #[arg(long, value_name = "TRUTH.json", requires = "diagnose")]
    truth: Option<PathBuf>,
    /// Reference result (docs/FORMAT.md §3), or a DCC (§13.3), to compare with by En;
    /// status 1 when some |En| > 1.
    #[arg(long, value_name = "REF.csv")]
    reference: Option<PathBuf>,
    /// Key comparison to report: the JSON of `polycal kc --format json` (docs/FORMAT.md
    /// §12); adds its section to the HTML and its result to the DCC (§10.2, §10.3).
    #[arg(long, value_name = "KC.json")]
    kc: Option<PathBuf>,
    /// The laboratory the report is for, one of the key comparison's: its d_i and U(d_i)
    /// alone; without it, every laboratory's.
    #[arg(long, value_name = "NAME", requires = "kc")]
    kc_lab: Option<String>,
    /// An earlier calibration of the standard, FILE@DATE (a result file or a DCC, and the
    /// day it was calibrated; a DCC without @DATE is dated by its endPerformanceDate), as
    /// for `polycal history`; repeatable, at least 2. Adds the section "History of the
    /// standard" (docs/FORMAT.md §10.2, §13.2), this run the newest calibration, dated by
    /// the metadata's date_of_measurement; needs --budget; status 1 when this calibration
    /// does not agree with the earlier calibrations' prediction.
    #[arg(long, value_name = "FILE@DATE", value_parser = clap::value_parser!(polycal::history::DatedPath))]
    history: Vec<polycal::history::DatedPath>,
    /// Metadata (TOML, docs/FORMAT.md §10): customer, artefact, operator, instruments,
    /// environment.
    #[arg(long, value_name = "META.toml")]
    meta: Option<PathBuf>,
    /// Run directory of `polycal run` (its manifest.json: instruments, run times).
    #[arg(long, value_name = "DIR")]
    run_dir: Option<PathBuf>,
    /// The HTML file to write (whole or not at all, never over an input: docs/FORMAT.md
    /// §8.1).
    #[arg(long, value_name = "REPORT.html", required_unless_present = "dcc")]
    out: Option<PathBuf>,
    /// The Digital Calibration Certificate to write: XML valid against DCC 3.1.2 with
    /// D-SI 2.1.0 results, the same numbers as the HTML (docs/FORMAT.md §10.3). Needs
    /// --budget for a polygon file and the metadata the schema requires (--meta);
    /// nothing is written when one is missing.
    #[arg(long, value_name = "CERTIFICATE.xml")]
    dcc: Option<PathBuf>,
}

/// `polycal report`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &ReportArgs, out: &Output) -> Result<u8> {
    super::stdin_once(
        [
            ("the measurement file", Some(args.file.as_path())),
            ("--budget", args.budget.as_deref()),
            ("--truth", args.truth.as_deref()),
            ("--reference", args.reference.as_deref()),
            ("--meta", args.meta.as_deref()),
            ("--kc", args.kc.as_deref()),
        ]
        .into_iter()
        .chain(
            args.history
                .iter()
                .map(|d| ("--history", Some(d.path.as_path()))),
        ),
    )?;
    super::solve::check_stated_cross_talk(&args.cross_talk, args.budget.is_some(), out)?;
    // refused before any work: an output that is an input, two outputs of one file, an
    // output that is not a regular file (docs/FORMAT.md §8.1)
    let manifest = args.run_dir.as_ref().map(|d| d.join("manifest.json"));
    let mut files = CommandOutputs::new(
        [
            Some(args.file.as_path()),
            args.budget.as_deref(),
            args.truth.as_deref(),
            args.reference.as_deref(),
            args.meta.as_deref(),
            args.kc.as_deref(),
            manifest.as_deref(),
        ]
        .into_iter()
        .flatten()
        .chain(args.history.iter().map(|d| d.path.as_path())),
    )?;
    files.check(
        [
            ("--out", args.out.as_deref()),
            ("--dcc", args.dcc.as_deref()),
        ]
        .into_iter()
        .filter_map(|(flag, path)| Some((flag, path?))),
    )?;
    // An argument that is not UTF-8 (a file name in another encoding) is recorded with
    // U+FFFD where its bytes are not text: `args()` would panic on it.
    let command_line = std::env::args_os()
        .skip(1)
        .map(|a| a.to_string_lossy().into_owned())
        // files by their names alone, as the documents name them: `--out=/a/b.html`
        // as `--out=b.html`, `/a/run.csv` as `run.csv`
        .map(|a| match a.split_once('=') {
            Some((flag, path)) if flag.starts_with("--") && path.contains('/') => {
                format!("{flag}={}", polycal::input::document_name(path))
            }
            _ if !a.starts_with('-') && a.contains('/') => polycal::input::document_name(&a),
            _ => a,
        })
        .map(|a| {
            if a.is_empty() || a.contains(|c: char| c.is_whitespace() || "'\"$\\".contains(c)) {
                format!("'{}'", a.replace('\'', "'\\''"))
            } else {
                a
            }
        })
        .collect::<Vec<_>>()
        .join(" ");
    let mut inputs = ReportInputs::new(&args.file);
    if let Some(stamp) = source_date()? {
        inputs = inputs.with_generated_utc(stamp);
    }
    inputs = inputs
        .with_faces(args.faces)
        .with_sigma(args.sigma)
        .with_diagnose(args.diagnose)
        .with_stated_cross_talk(args.cross_talk.clone())
        .with_command_line(format!("polycal {command_line}"));
    if let Some(p) = &args.budget {
        inputs = inputs.with_budget(p);
    }
    if let Some(p) = &args.truth {
        inputs = inputs.with_truth(p);
    }
    if let Some(p) = &args.reference {
        inputs = inputs.with_reference(p);
    }
    if let Some(p) = &args.meta {
        inputs = inputs.with_meta(p);
    }
    if let Some(p) = &args.run_dir {
        inputs = inputs.with_run_dir(p);
    }
    if let Some(p) = &args.kc {
        inputs = inputs.with_key_comparison(p, args.kc_lab.clone());
    }
    if !args.history.is_empty() {
        inputs = inputs.with_history(args.history.clone());
    }
    let report = CalibrationReport::build(&inputs).map_err(|e| match e {
        // Library messages name no flags: the CLI adds the one that helps.
        ReportError::NoExpandedUncertainty { .. } => {
            super::with_hint(e, "--budget", "give the instrument budget with --budget")
        }
        ReportError::Uncertainty {
            source: polycal::uncertainty::calibration::CalibrationError::NoSigma,
            ..
        } => anyhow::anyhow!("{e} (--sigma)"),
        ReportError::KeyComparisonLab { .. } => anyhow::anyhow!("{e} (--kc-lab)"),
        ReportError::HistoryNoExpandedUncertainty { .. } => {
            super::with_hint(e, "--budget", "give the instrument budget with --budget")
        }
        ReportError::HistoryNoDate { .. } => {
            anyhow::anyhow!("{e}; give it as date_of_measurement in the metadata file (--meta)")
        }
        ReportError::HistoryFile {
            source: polycal::history::DatedReadError::File(e),
        } => super::wrong_file::results(e),
        e => e.into(),
    })?;
    // both documents made before either is written: a refusal writes nothing
    let dcc = match &args.dcc {
        Some(path) => Some((
            path,
            report.to_dcc().map_err(|e| match e {
                DccError::NoExpandedUncertainty { .. } => {
                    super::with_hint(e, "--budget", "give the instrument budget with --budget")
                }
                DccError::MissingMetadata { .. } => anyhow::anyhow!("{e} (--meta)"),
                e => e.into(),
            })?,
        )),
        None => None,
    };
    // both written, then both put into place: all or none
    let mut written = Vec::new();
    if let Some(path) = &args.out {
        files.write("--out", path, report.to_html().as_bytes())?;
        written.push(format!(
            "{} ({} figures)",
            path.display(),
            report.figures.len()
        ));
    }
    if let Some((path, xml)) = dcc {
        files.write("--dcc", path, xml.as_bytes())?;
        written.push(format!("{} (DCC {})", path.display(), dcc::SCHEMA_VERSION));
    }
    files.commit()?;
    let verdict = report.verdict();
    out.info(format!(
        "wrote {}{}{}{}",
        written.join(" and "),
        match &report.comparison {
            Some((comparison, _)) if verdict.comparison_failed => {
                format!("; the comparison: {}", comparison.verdict_sentence())
            }
            _ => String::new(),
        },
        if verdict.not_adequate {
            "; the diagnosis: the final model is not adequate"
        } else {
            ""
        },
        match &report.history {
            Some(history) if verdict.history_disagrees => {
                format!("; the history: {}", history.agreement_statement())
            }
            _ => String::new(),
        }
    ));
    Ok(if verdict.passed() {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}

/// The report's date from `SOURCE_DATE_EPOCH` (seconds since the epoch, the
/// reproducible-builds convention), so that the same inputs give the same bytes; `None`
/// when it is not set.
pub(super) fn source_date() -> Result<Option<String>> {
    match std::env::var("SOURCE_DATE_EPOCH") {
        Err(std::env::VarError::NotPresent) => Ok(None),
        Ok(text) => match text.trim().parse::<u64>() {
            Ok(seconds) if seconds < 253_402_300_800 => {
                Ok(Some(polycal::clock::rfc3339(seconds as f64)))
            }
            _ => bail!(
                "SOURCE_DATE_EPOCH: expected whole seconds since 1970 before the year 10000, got {text:?}"
            ),
        },
        Err(std::env::VarError::NotUnicode(_)) => {
            bail!("SOURCE_DATE_EPOCH: not a number of seconds")
        }
    }
}
