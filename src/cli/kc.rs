//! `polycal kc`: an interlaboratory (key) comparison of several laboratories' results
//! (docs/FORMAT.md §12).

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::Result;
use clap::ValueEnum;
use polycal::kc::{
    CodeKey, KcNameError, KcOptions, KeyComparison, LabResult, ReferenceMethod, anonymise,
    evaluate, lab_from_solve_json, shared_quantities,
};
use polycal::results::{Quantity, read_results_from};

use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal kc --help`.
pub const EXAMPLES: &str = "\
The contract (JSON names, the one decision at 5 %, the largest consistent subset, the
closed vector, the pilot's repeats): docs/FORMAT.md §12 (Key comparisons). Status 0
consistent (the closed vector of every laboratory passes, or a subset passes after the
stated exclusions), 1 not consistent, 2 an input refused. Without --quantity every quantity
the files share is compared (pitch_deviation, encoder_error, angle_block), status 1 when
any is not consistent.

Examples:
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv D=examples/data/kc/D.csv E=examples/data/kc/E.csv F=examples/data/kc/F.csv --format json
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv --pilot start=examples/data/kc/pilot-start.csv --pilot end=examples/data/kc/pilot-end.csv
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv F=examples/data/kc/F.csv --method dersimonian-laird --format csv
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv D=examples/data/kc/D.csv --anonymise draft-a-key.csv --plot draft-a
  polycal kc A=examples/data/kc/A.csv B=examples/data/kc/B.csv C=examples/data/kc/C.csv D=examples/data/kc/D.csv E=examples/data/kc/E.csv F=examples/data/kc/F.csv --quantity angle_block";

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
    /// The compared quantity: pitch_deviation, encoder_error or angle_block. Without it, every one of
    /// them that every result (the laboratories' and the pilot's repeats') has rows of, in
    /// that order, each with the same options and codes: --format json writes one object
    /// per quantity, one per line (JSON Lines), table each quantity's table under a heading
    /// line, csv the rows of each (column quantity); status 1 when any is not consistent.
    /// One shared quantity is written as with --quantity (docs/FORMAT.md §12).
    #[arg(long, value_parser = parse_quantity)]
    quantity: Option<Quantity>,
    /// The reference: weighted-mean (when the closed vector of every laboratory fails its
    /// test at 5 %, the largest subset that passes), or a random-effects reference with its
    /// dark uncertainty τ, nobody left out, its verdict the test of τ = 0:
    /// dersimonian-laird (τ by the method of moments) or mandel-paule (τ such that the χ²
    /// with the widened u equals n − 1).
    #[arg(long, default_value = "weighted-mean", value_parser = parse_method)]
    method: ReferenceMethod,
    /// Hold laboratory NAME in the reference whatever the tests say (the pilot's decision,
    /// stated in the notes); may be given more than once.
    #[arg(long, value_name = "NAME")]
    keep: Vec<String>,
    /// Keep laboratory NAME out of the reference but give it degrees of equivalence against
    /// it (`in_reference` false; e.g. a laboratory traceable to another in the comparison);
    /// it is not in the one test at 5 % nor in the search. May be given more than once.
    #[arg(long, value_name = "NAME")]
    not_in_reference: Vec<String>,
    /// Link this comparison to another (e.g. an RMO comparison to the CIPM one): its
    /// `polycal kc --format json` output; the laboratories in both give the offset between
    /// the references, and every degree of equivalence is also given against the linked
    /// reference (docs/FORMAT.md §12, "Linking"). Of a file of several comparisons (JSON
    /// Lines), the one of the compared quantity; without --quantity, each comparison is
    /// linked to the linked file's of its quantity (refused when none matches).
    #[arg(long, value_name = "KC.json")]
    link: Option<PathBuf>,
    /// Every U(d_i) and u_ref by M Monte Carlo draws from the fitted model (at least 1000):
    /// the reference evaluated again in each draw, τ too for the random-effects methods, so
    /// that τ's own uncertainty is in U (docs/FORMAT.md §12).
    #[arg(long, value_name = "M")]
    monte_carlo: Option<usize>,
    /// Output format (csv: the degrees of equivalence, columns
    /// lab,index,angle_deg,d,U,in_reference,quantity; docs/FORMAT.md §12).
    #[arg(long, value_enum, default_value = "table")]
    format: KcFormat,
    /// Write the figures as SVG files into DIR (created if missing; docs/FORMAT.md §10):
    /// kc-degrees-of-equivalence.svg, kc-reference.svg, kc-pairwise.svg, kc-kcdb.svg (the
    /// KCDB graphs: d_i with U(d_i) per laboratory, one graph per face, position or angle block, at
    /// most 24) and with --pilot kc-pilot-stability.svg, whatever --format is. Several
    /// quantities compared (no --quantity): the pitch deviations' figures in DIR, each other
    /// quantity's in DIR/QUANTITY/ (e.g. DIR/encoder_error/), so that none replaces another.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
    /// Draft A: every laboratory named by a code letter (A, B, …, in an order drawn at
    /// random) in every output — table, JSON, CSV, figures, and so the report and the DCC
    /// made from the JSON — and which code is which laboratory written to KEY.csv alone
    /// (columns code,lab). When KEY.csv exists it is read and its codes kept (Draft B
    /// keeps Draft A's letters). The pilot's repeats keep their names; --keep and
    /// --not-in-reference take the real names.
    #[arg(long, value_name = "KEY.csv")]
    anonymise: Option<PathBuf>,
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

/// The key of `--anonymise`: one read, or the file a new one goes to.
enum KeyFile {
    /// KEY.csv exists: its codes are kept, and it is not written.
    Read(CodeKey),
    /// KEY.csv does not exist: the key drawn is written there.
    New(PathBuf),
}

/// `--anonymise KEY.csv`, before any work: an existing key read (refused with its line
/// and column), or a new one's place checked (not `-`, a directory that can be written,
/// not one of the figures of `--plot`).
fn key_file(path: &Path, inputs: &[&Path], plot: Option<&Path>, pilot: bool) -> Result<KeyFile> {
    if polycal::input::is_stdin(path) {
        anyhow::bail!(
            "--anonymise takes the key's file (KEY.csv), not `-`: the key is written to a file \
             of its own, apart from the output"
        );
    }
    match std::fs::symlink_metadata(path) {
        Ok(_) => {
            let (bytes, source) = polycal::input::read_bytes(path)
                .map_err(|(file, source)| polycal::input::FileError::Io { file, source })?;
            Ok(KeyFile::Read(CodeKey::read(&bytes, &source)?))
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let outputs = polycal::output_file::Outputs::new(inputs.iter().copied())?;
            outputs
                .check([path])
                .map_err(|e| anyhow::anyhow!("--anonymise: cannot write the key: {e}"))?;
            if let Some(dir) = plot {
                key_apart_from_figures(path, dir, pilot)?;
            }
            Ok(KeyFile::New(path.to_path_buf()))
        }
        Err(e) => Err(anyhow::anyhow!(
            "--anonymise {}: {e}",
            polycal::input::display_name(path)
        )),
    }
}

/// `--anonymise KEY.csv` that does not exist yet, refused when it is the directory `dir`
/// the figures go into, or one of the figures there.
fn key_apart_from_figures(path: &Path, dir: &Path, pilot: bool) -> Result<()> {
    // compared as written (absolute), as the directory may not exist yet
    let key_at = std::path::absolute(path).ok();
    let dir_at = std::path::absolute(dir).ok();
    if key_at.is_some() && key_at == dir_at {
        anyhow::bail!(
            "--anonymise {}: is the directory --plot writes the figures into; give the key \
             a file of its own",
            polycal::input::display_name(path)
        );
    }
    let figures = polycal::figure::FigureSet::Kc { pilot }.file_names();
    let lexically_in_dir = key_at
        .as_deref()
        .and_then(Path::parent)
        .is_some_and(|parent| Some(parent) == dir_at.as_deref());
    let same_dir = lexically_in_dir
        || match (path.parent(), std::fs::canonicalize(dir)) {
            (Some(parent), Ok(dir)) => {
                let parent = if parent.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    parent
                };
                std::fs::canonicalize(parent).is_ok_and(|p| p == dir)
            }
            _ => false,
        };
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    if same_dir && figures.iter().any(|f| f == name) {
        anyhow::bail!(
            "--anonymise {}: is one of the figures --plot writes; give the key a file of \
             its own",
            polycal::input::display_name(path)
        );
    }
    Ok(())
}

/// `polycal kc`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &KcArgs) -> Result<u8> {
    let mut roles: Vec<(String, &std::path::Path)> = args
        .labs
        .iter()
        .chain(&args.pilot)
        .map(|n| (n.name.clone(), n.path.as_path()))
        .collect();
    if let Some(path) = &args.link {
        roles.push(("--link".to_string(), path.as_path()));
    }
    super::stdin_once(
        roles
            .iter()
            .map(|(role, path)| (role.as_str(), Some(*path))),
    )?;
    let mut inputs: Vec<&std::path::Path> = roles.iter().map(|(_, path)| *path).collect();
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Kc {
            pilot: !args.pilot.is_empty(),
        },
        &inputs,
    )?;
    let key_file = match &args.anonymise {
        Some(path) => Some(key_file(
            path,
            &inputs,
            args.plot.as_deref(),
            !args.pilot.is_empty(),
        )?),
        None => None,
    };
    if let (Some(KeyFile::Read(_)), Some(path)) = (&key_file, &args.anonymise) {
        // a key read is an input: no figure replaces it
        inputs.push(path.as_path());
    }
    let read = |list: &[Named]| -> Result<Vec<LabResult>> {
        list.iter().map(|n| read_lab(&n.name, &n.path)).collect()
    };
    let mut labs = read(&args.labs)?;
    let pilot = read(&args.pilot)?;
    let quantities = match args.quantity {
        Some(quantity) => vec![quantity],
        None => shared_quantities(&labs, &pilot)?,
    };
    check_other_plots(args, &quantities, &inputs, key_file.as_ref())?;
    let mut keep = args.keep.clone();
    let mut not_in_reference = args.not_in_reference.clone();
    let key = match &key_file {
        Some(file) => {
            let read = match file {
                KeyFile::Read(key) => Some(key),
                KeyFile::New(_) => None,
            };
            let (coded, key) = anonymise(&labs, &pilot, read, rand::random())?;
            labs = coded;
            keep = key.coded_names(keep.iter().map(String::as_str));
            not_in_reference = key.coded_names(not_in_reference.iter().map(String::as_str));
            Some(key)
        }
        None => None,
    };
    let options = KcOptions::new()
        .with_method(args.method)
        .with_keep(keep)
        .with_not_in_reference(not_in_reference);
    let options = match args.monte_carlo {
        Some(draws) => options.with_monte_carlo(draws),
        None => options,
    };
    let linked = read_linked(args, key.as_ref())?;
    let links = links_of(args, &quantities, &linked)?;
    let mut comparisons = evaluate_each(&labs, &pilot, &options, &quantities, &links)?;
    if let (Some(KeyFile::New(path)), Some(key)) = (&key_file, &key) {
        // the key before any output that uses its codes, and never over an input
        let mut outputs = polycal::output_file::Outputs::new(inputs.iter().copied())?;
        outputs
            .write_with(path, |w| {
                polycal::output::kc::write_key_csv(w, key).map_err(std::io::Error::other)
            })
            .and_then(|()| outputs.commit().map(|_| ()))
            .map_err(|e| anyhow::anyhow!("--anonymise: cannot write the key: {e}"))?;
        // the figures may not replace it
        inputs.push(path.as_path());
    }
    if key.is_some() {
        for kc in &mut comparisons {
            kc.notes.push(polycal::kc::DRAFT_A_NOTE.to_string());
        }
    }
    if let Some(dir) = &args.plot {
        super::write_plot(dir, &figures(&comparisons), &inputs)?;
    }
    write_comparisons(args.format, &comparisons)?;
    Ok(if comparisons.iter().all(|kc| kc.comparison_consistent) {
        EXIT_OK
    } else {
        EXIT_VERDICT
    })
}

/// `--plot DIR` with several quantities: the subdirectory of each whose figures do not go
/// into DIR ([`figure_subdirectories`]) checked as DIR is, before any work, and apart from
/// a new `--anonymise` key.
fn check_other_plots(
    args: &KcArgs,
    quantities: &[Quantity],
    inputs: &[&Path],
    key_file: Option<&KeyFile>,
) -> Result<()> {
    let Some(dir) = &args.plot else {
        return Ok(());
    };
    let pilot = !args.pilot.is_empty();
    for sub in figure_subdirectories(quantities) {
        let sub = dir.join(sub);
        let set = polycal::figure::FigureSet::Kc { pilot };
        super::check_plot(Some(&sub), set, inputs)?;
        if let Some(KeyFile::New(path)) = key_file {
            key_apart_from_figures(path, &sub, pilot)?;
        }
    }
    Ok(())
}

/// Each quantity's comparison with `options`, linked to its `links` entry: the first
/// refuses as one alone would (a refusal of every quantity, too few laboratories, is its
/// own); a later one's refusal says which quantity it is.
fn evaluate_each(
    labs: &[LabResult],
    pilot: &[LabResult],
    options: &KcOptions,
    quantities: &[Quantity],
    links: &[Option<&KeyComparison>],
) -> Result<Vec<KeyComparison>> {
    let mut comparisons = Vec::with_capacity(quantities.len());
    for (i, (&quantity, linked)) in quantities.iter().zip(links).enumerate() {
        let options = options.clone().with_quantity(quantity);
        let mut kc = evaluate(labs, pilot, &options)
            .map_err(with_flag)
            .map_err(|e| match i {
                0 => e,
                _ => e.context(format!("the comparison of {quantity}")),
            })?;
        match linked {
            Some(linked) => polycal::kc::link(&mut kc, linked)?,
            // --link names comparisons, none of this quantity
            None if links.iter().any(Option::is_some) => polycal::kc::note_not_linked(&mut kc),
            None => {}
        }
        comparisons.push(kc);
    }
    Ok(comparisons)
}

/// The subdirectory of `--plot DIR` of each compared quantity whose figures do not go
/// into DIR itself: with several quantities, every one but the pitch deviations (whose
/// figures keep their names in DIR), in the order compared.
fn figure_subdirectories(quantities: &[Quantity]) -> Vec<&'static str> {
    if quantities.len() < 2 {
        return Vec::new();
    }
    quantities
        .iter()
        .filter(|&&q| q != Quantity::PitchDeviation)
        .map(|q| q.name())
        .collect()
}

/// The figures of every comparison: the pitch deviations' (or a single comparison's)
/// under their names, the other quantities' in their subdirectory
/// ([`figure_subdirectories`]), so that none replaces another.
fn figures(comparisons: &[KeyComparison]) -> Vec<polycal::figure::Figure> {
    let quantities: Vec<Quantity> = comparisons.iter().map(|kc| kc.quantity).collect();
    let subdirectories = figure_subdirectories(&quantities);
    let mut figures = Vec::new();
    for kc in comparisons {
        let mut these = polycal::figure::kc_figures(kc);
        if subdirectories.contains(&kc.quantity.name()) {
            for figure in &mut these {
                figure.name = format!("{}/{}", kc.quantity.name(), figure.name);
            }
        }
        figures.extend(these);
    }
    figures
}

/// The comparison `--link` links each compared quantity to (`None`: not linked): without
/// `--quantity`, the linked file's comparison of that quantity, refused when none of the
/// compared quantities is in it; with `--quantity`, its comparison of that quantity, else
/// its first (which [`polycal::kc::link`] refuses, naming both quantities).
fn links_of<'a>(
    args: &KcArgs,
    quantities: &[Quantity],
    linked: &'a [KeyComparison],
) -> Result<Vec<Option<&'a KeyComparison>>> {
    let of = |q: Quantity| linked.iter().find(|kc| kc.quantity == q);
    let links: Vec<Option<&KeyComparison>> = match args.quantity {
        Some(q) => vec![of(q).or(linked.first())],
        None => quantities.iter().map(|&q| of(q)).collect(),
    };
    if let (Some(path), true) = (&args.link, links.iter().all(Option::is_none)) {
        let names = |list: Vec<Quantity>| {
            let names: Vec<&str> = list.iter().map(|q| q.name()).collect();
            names.join(", ")
        };
        anyhow::bail!(
            "--link {}: holds a comparison of {}, but the quantities compared here are {}: \
             a comparison is linked to one of its own quantity",
            polycal::input::display_name(path),
            names(linked.iter().map(|kc| kc.quantity).collect()),
            names(quantities.to_vec())
        );
    }
    Ok(links)
}

/// A library refusal with the flag that helps (library messages name no flags).
fn with_flag(e: polycal::kc::KcError) -> anyhow::Error {
    match e {
        // Library messages name no flags: the CLI adds the one that helps.
        polycal::kc::KcError::TooFewRepeats(_) => {
            super::with_hint(e, "--pilot", "give --pilot twice or more, or not at all")
        }
        polycal::kc::KcError::UnknownKeep(_) => super::with_hint(
            e,
            "--keep",
            "--keep takes a laboratory given as NAME=RESULT.csv",
        ),
        polycal::kc::KcError::UnknownNotInReference(_) => super::with_hint(
            e,
            "--not-in-reference",
            "--not-in-reference takes a laboratory given as NAME=RESULT.csv",
        ),
        e => e.into(),
    }
}

/// The comparison `--link` names, read back from its JSON; with `--anonymise`, its
/// laboratories named by this comparison's codes.
fn read_linked(args: &KcArgs, key: Option<&polycal::kc::CodeKey>) -> Result<Vec<KeyComparison>> {
    Ok(match &args.link {
        Some(path) => {
            let (bytes, source) = polycal::input::read_bytes(path)
                .map_err(|(file, source)| polycal::input::FileError::Io { file, source })?;
            let linked = polycal::kc::read_json_lines(&bytes, &source)?;
            // Draft A: the linked comparisons' laboratories by this comparison's codes
            match key {
                Some(key) => linked.iter().map(|kc| key.coded_comparison(kc)).collect(),
                None => linked,
            }
        }
        None => Vec::new(),
    })
}

/// The comparisons on standard output in `format`: JSON one object per line (JSON
/// Lines), the tables one after another under a heading each when several, the CSV under
/// one header.
fn write_comparisons(format: KcFormat, comparisons: &[KeyComparison]) -> Result<()> {
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match format {
        // Written as it is formed: the pairs of many laboratories are hundreds of MB.
        KcFormat::Json => {
            let mut buffered = std::io::BufWriter::with_capacity(1 << 16, &mut stdout);
            for kc in comparisons {
                polycal::output::write_json(&mut buffered, kc)?;
            }
            buffered.flush()?;
        }
        KcFormat::Table => {
            let mut text = String::new();
            polycal::output::kc::write_tables(&mut text, comparisons)?;
            write!(stdout, "{text}")?;
        }
        KcFormat::Csv => polycal::output::kc::write_csv(&mut stdout, comparisons)?,
    }
    stdout.flush()?;
    Ok(())
}
