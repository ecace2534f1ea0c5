//! `polycal kc`: an interlaboratory (key) comparison of several laboratories' results
//! (docs/FORMAT.md §12).

use std::io::Write;
use std::path::PathBuf;

use anyhow::Result;
use clap::ValueEnum;
use polycal::kc::{
    KcNameError, KcOptions, LabResult, ReferenceMethod, evaluate, lab_from_solve_json,
};
use polycal::results::{Quantity, read_results_from};

use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal kc --help`.
pub const EXAMPLES: &str = "\
The contract (JSON names, the one decision at 5 %, the largest consistent subset, the
closed vector, the pilot's repeats): docs/FORMAT.md §12 (Key comparisons). Status 0
consistent (the closed vector of every laboratory passes, or a subset passes after the
stated exclusions), 1 not consistent, 2 an input refused.

Examples:
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv D=examples/data/kc/D.csv E=examples/data/kc/E.csv F=examples/data/kc/F.csv --format json
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv --pilot start=examples/data/kc/pilot-start.csv --pilot end=examples/data/kc/pilot-end.csv
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv F=examples/data/kc/F.csv --method dersimonian-laird --format csv";

/// One `NAME=RESULT.csv` argument.
#[derive(Clone, Debug)]
pub struct Named {
    name: String,
    path: PathBuf,
}

/// Parses `NAME=PATH` (a name not empty; the path may contain `=`).
fn named(text: &str) -> std::result::Result<Named, NotNamed> {
    match text.split_once('=') {
        Some((name, path)) if !name.is_empty() && !path.is_empty() => Ok(Named {
            name: name.to_string(),
            path: PathBuf::from(path),
        }),
        _ => Err(NotNamed {
            text: text.to_string(),
        }),
    }
}

/// An argument that is not `NAME=RESULT.csv`.
#[derive(Debug, thiserror::Error)]
#[error("expected NAME=RESULT.csv (a laboratory's name, `=`, its result file), got {text:?}")]
struct NotNamed {
    /// The argument given.
    text: String,
}

/// Arguments of `polycal kc`.
#[derive(clap::Args)]
pub struct KcArgs {
    /// The laboratories' results, NAME=RESULT.csv each (docs/FORMAT.md §3: U and k, or u,
    /// on every row of the quantity), NAME=CERT.xml (a DCC, read by its content, §13.3),
    /// or NAME=SOLVE.json (`solve --format json [--covariance]`, whose covariance the
    /// closed vector then uses); at least 2.
    #[arg(value_name = "NAME=RESULT.csv", required = true, value_parser = named)]
    labs: Vec<Named>,
    /// The pilot's repeated result of the artefact (start, middle, end of the
    /// circulation), NAME=RESULT.csv; give it at least twice.
    #[arg(long, value_name = "NAME=RESULT.csv", value_parser = named)]
    pilot: Vec<Named>,
    /// The compared quantity: pitch_deviation or encoder_error.
    #[arg(long, default_value = "pitch_deviation", value_parser = parse_quantity)]
    quantity: Quantity,
    /// The reference: weighted-mean (when the closed vector of every laboratory fails its
    /// test at 5 %, the largest subset that passes), or dersimonian-laird (the
    /// random-effects reference with its dark uncertainty τ, nobody left out; its verdict
    /// is the test of τ = 0).
    #[arg(long, default_value = "weighted-mean", value_parser = parse_method)]
    method: ReferenceMethod,
    /// Hold laboratory NAME in the reference whatever the tests say (the pilot's decision,
    /// stated in the notes); may be given more than once.
    #[arg(long, value_name = "NAME")]
    keep: Vec<String>,
    /// Output format (csv: the degrees of equivalence, columns
    /// lab,index,angle_deg,d,U,in_reference; docs/FORMAT.md §12).
    #[arg(long, value_enum, default_value = "table")]
    format: KcFormat,
    /// Write the figures as SVG files into DIR (created if missing; docs/FORMAT.md §10):
    /// kc-degrees-of-equivalence.svg, kc-reference.svg and with --pilot
    /// kc-pilot-stability.svg, whatever --format is.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

/// `kc --quantity`: the library's parsing, so that Python accepts the same words.
fn parse_quantity(name: &str) -> std::result::Result<Quantity, KcNameError> {
    polycal::kc::compared_quantity(name)
}

/// `kc --method`: the library's `FromStr`.
fn parse_method(name: &str) -> std::result::Result<ReferenceMethod, KcNameError> {
    name.parse::<ReferenceMethod>()
}

/// `kc --format`.
#[derive(Clone, Copy, ValueEnum)]
enum KcFormat {
    Table,
    Json,
    Csv,
}

/// One laboratory's result: a solve result in JSON (docs/FORMAT.md §5.1, its first
/// character other than white space `{`), else a result file (§3).
fn read_lab(name: &str, path: &std::path::Path) -> Result<LabResult> {
    let (bytes, source) = polycal::input::read_bytes(path)
        .map_err(|(file, source)| polycal::input::FileError::Io { file, source })?;
    if bytes.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        return Ok(lab_from_solve_json(name, &bytes, &source)?);
    }
    Ok(LabResult::from_file(
        name,
        read_results_from(&bytes[..], &source).map_err(super::wrong_file::results)?,
    ))
}

/// `polycal kc`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &KcArgs) -> Result<u8> {
    let roles: Vec<(String, &std::path::Path)> = args
        .labs
        .iter()
        .chain(&args.pilot)
        .map(|n| (n.name.clone(), n.path.as_path()))
        .collect();
    super::stdin_once(
        roles
            .iter()
            .map(|(role, path)| (role.as_str(), Some(*path))),
    )?;
    let inputs: Vec<&std::path::Path> = roles.iter().map(|(_, path)| *path).collect();
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Kc {
            pilot: !args.pilot.is_empty(),
        },
        &inputs,
    )?;
    let read = |list: &[Named]| -> Result<Vec<LabResult>> {
        list.iter().map(|n| read_lab(&n.name, &n.path)).collect()
    };
    let labs = read(&args.labs)?;
    let pilot = read(&args.pilot)?;
    let options = KcOptions::new()
        .with_quantity(args.quantity)
        .with_method(args.method)
        .with_keep(args.keep.iter().cloned());
    let kc = evaluate(&labs, &pilot, &options).map_err(|e| match e {
        // Library messages name no flags: the CLI adds the one that helps.
        polycal::kc::KcError::TooFewRepeats(_) => {
            super::with_hint(e, "--pilot", "give --pilot twice or more, or not at all")
        }
        polycal::kc::KcError::UnknownKeep(_) => super::with_hint(
            e,
            "--keep",
            "--keep takes a laboratory given as NAME=RESULT.csv",
        ),
        e => e.into(),
    })?;
    if let Some(dir) = &args.plot {
        super::write_plot(dir, &polycal::figure::kc_figures(&kc), &inputs)?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        // Written as it is formed: the pairs of many laboratories are hundreds of MB.
        KcFormat::Json => {
            let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut stdout);
            polycal::output::write_json(&mut buffered, &kc)?;
            buffered.flush()?;
        }
        KcFormat::Table => {
            let mut text = String::new();
            polycal::output::kc::write_table(&mut text, &kc)?;
            write!(stdout, "{text}")?;
        }
        KcFormat::Csv => polycal::output::kc::write_csv(&mut stdout, &kc)?,
    }
    stdout.flush()?;
    Ok(if kc.comparison_consistent {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}
