//! `polycal diagnose`: the effects the base model lacks, found, added and reported, and
//! the final model's calibration with the uncertainty of an instrument budget.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;

use anyhow::{Context, Result};
use clap::ValueEnum;
use polycal::diagnose::{self, DiagnoseOptions, Diagnosis};
use polycal::input::FileError;
use polycal::input::display_name;
use polycal::measurement::cross_talk::StatedCrossTalk;
use polycal::measurement::{MeasurementSet, Sigma};
use polycal::output::diagnose_selfcal::{self, SelfcalDiagnoseReport};
use polycal::output::{self, diagnose::DiagnoseReport};
use polycal::results::ResultRow;
use polycal::selfcal::{SelfcalOptions, SelfcalSet};
use polycal::simulate::TruthFile;
use polycal::uncertainty::calibration::{
    self, CalibrationError, CalibrationMonteCarlo, CalibrationUncertainty, InstrumentBudget,
    KnownCorrection, McOptions,
};

use super::monte_carlo::McArgs;
use super::output::Output;
use super::solve::{
    check_stated_cross_talk, corrected, evaluate_budget, read_budget, shift_refusal,
    write_result_csv,
};
use super::{EXIT_ERROR, EXIT_OK, EXIT_VERDICT};

/// After `polycal diagnose --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal diagnose examples/data/polygon24-2ac-6cycles.csv
  polycal diagnose examples/data/polygon24-2ac-6cycles.csv --truth examples/data/polygon24-2ac-6cycles.truth.json
  polycal diagnose examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml
  polycal diagnose examples/data/polygon24-2ac-6cycles.csv --budget examples/budgets/instrument.toml --format csv > result.csv
  polycal simulate --closing --drift 2:1.5 | polycal diagnose - --format json
  polycal diagnose examples/data/selfa-168.csv";

/// Arguments of `polycal diagnose`.
#[derive(clap::Args)]
pub struct DiagnoseArgs {
    /// Measurement CSV files (docs/FORMAT.md §2) or self-calibration files (§9.2, told by
    /// their `head` and `head_angle` columns; diagnosed as docs/FORMAT.md §5.2 says);
    /// `-` reads standard input.
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Truth JSON of simulated data (docs/FORMAT.md §4, or the self-calibration truth of
    /// `simulate --selfcal --truth-out`): adds the errors before and after.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Number of polygon faces (default: the largest face in the file); for a
    /// self-calibration file, the number of positions P (default: the largest step + 1).
    #[arg(long)]
    faces: Option<usize>,
    /// Standard deviation of one reading, arcsec, if known: adds a χ² check.
    #[arg(long, allow_negative_numbers = true)]
    sigma: Option<Sigma>,
    /// Cross-talk of an autocollimator stated from its calibration, AC:C or AC:C:U, as for
    /// `solve`: its readings are corrected to reading − C·reading_y, U enters --budget, no
    /// cross-talk term is tried for it, the others' cross-talk follows from the data, and
    /// the JSON ends with `stated_cross_talk` (docs/FORMAT.md §6); repeatable.
    #[arg(
        long = "cross-talk",
        value_name = "AC:C[:U]",
        allow_negative_numbers = true
    )]
    cross_talk: Vec<StatedCrossTalk>,
    /// Instrument budget (TOML, as for `solve --budget`): adds the expanded uncertainty U
    /// and k of every result of the final model (base model + the effects found).
    #[arg(long, value_name = "FILE.toml")]
    budget: Option<PathBuf>,
    #[command(flatten)]
    monte_carlo: McArgs,
    /// Output format: `csv` writes the final model's result file (docs/FORMAT.md §3),
    /// as `solve --format csv` does.
    #[arg(long, value_enum, default_value = "table")]
    format: DiagnoseFormat,
    /// Write the figures as SVG files into DIR (created if missing), one file per figure
    /// with a stable name (docs/FORMAT.md §10), whatever --format is. Takes one input file:
    /// with several, run once per file.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

impl DiagnoseArgs {
    /// The files this command reads, which no output may replace.
    fn inputs(&self) -> Vec<&std::path::Path> {
        let mut v: Vec<&std::path::Path> = self.files.iter().map(PathBuf::as_path).collect();
        v.extend(self.truth.as_deref());
        v.extend(self.budget.as_deref());
        v
    }
}

/// `diagnose --format`.
#[derive(Clone, Copy, ValueEnum)]
enum DiagnoseFormat {
    Table,
    Json,
    Csv,
}

/// `polycal diagnose`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &DiagnoseArgs, out: &Output) -> Result<u8> {
    super::stdin_once(
        args.files
            .iter()
            .map(|f| ("a measurement file", Some(f.as_path())))
            .chain([
                ("--truth", args.truth.as_deref()),
                ("--budget", args.budget.as_deref()),
            ]),
    )?;
    super::plot_one_file(args.plot.as_deref(), args.files.len())?;
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Diagnose {
            budget: args.budget.is_some(),
        },
        &args.inputs(),
    )?;
    let truth = args
        .truth
        .as_deref()
        .map(TruthFile::read_path)
        .transpose()?;
    let mc_options = args.monte_carlo.options(args.budget.is_some())?;
    let budget = read_budget(args.budget.as_deref(), out)?;
    check_stated_cross_talk(&args.cross_talk, args.budget.is_some(), out)?;
    let options = DiagnoseOptions::new()
        .with_sigma_opt(args.sigma)
        .with_stated_cross_talk(args.cross_talk.iter().map(|s| s.ac).collect());
    let several = args.files.len() > 1;
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    let (mut failures, mut inadequate, mut not_validated) = (0, 0, 0);
    let mut csv_rows = Vec::new();
    let polygon = PolygonRun {
        args,
        out,
        options: &options,
        budget: budget.as_ref(),
        mc_options: mc_options.as_ref(),
        several,
    };
    for path in &args.files {
        // The name in messages (`<stdin>` for `-`); reports keep the path as given.
        let name = display_name(path);
        let label = polycal::input::shown_path(path);
        let bytes = match polycal::input::read_bytes(path) {
            Ok((bytes, _)) => bytes,
            Err((file, source)) => {
                out.error(&anyhow::Error::from(FileError::Io { file, source }));
                failures += 1;
                continue;
            }
        };
        if SelfcalSet::is_selfcal_file(&bytes) {
            let file = FileRead {
                bytes: &bytes,
                name: &name,
                label: &label,
            };
            let evaluation = SelfcalEvaluation {
                budget: budget.as_ref(),
                monte_carlo: mc_options.as_ref(),
            };
            match selfcal_file(args, file, truth.as_ref(), evaluation, several, out) {
                Ok(done) => {
                    inadequate += usize::from(!done.adequate);
                    not_validated += usize::from(!done.validated);
                    match (args.format, done.output) {
                        (DiagnoseFormat::Csv, Printed::Rows(rows)) => csv_rows.push((label, rows)),
                        (_, Printed::Text(text)) => write!(stdout, "{text}")?,
                        _ => {}
                    }
                }
                Err(error) => {
                    out.error(&error);
                    failures += 1;
                }
            }
            continue;
        }
        let file = FileRead {
            bytes: &bytes,
            name: &name,
            label: &label,
        };
        match polygon.file(file, truth.as_ref(), &mut stdout, &mut csv_rows)? {
            Some(done) => {
                inadequate += usize::from(!done.adequate);
                not_validated += usize::from(!done.validated);
            }
            None => failures += 1,
        }
    }
    if matches!(args.format, DiagnoseFormat::Csv) {
        write_result_csv(&mut stdout, several, &csv_rows)?;
    }
    stdout.flush()?;
    if failures > 0 {
        return Ok(EXIT_ERROR);
    }
    if not_validated > 0 {
        out.warning(
            "Monte Carlo does not validate the GUM uncertainty of some quantities of the \
             final model (JCGM 101 §8); see the monte_carlo results",
        );
    }
    Ok(if inadequate > 0 || not_validated > 0 {
        EXIT_VERDICT
    } else {
        EXIT_OK
    })
}

/// What `polycal diagnose` of a polygon measurement file needs besides the file: the
/// arguments, the options, the budget and the Monte Carlo's options.
struct PolygonRun<'a> {
    args: &'a DiagnoseArgs,
    out: &'a Output,
    options: &'a DiagnoseOptions,
    budget: Option<&'a InstrumentBudget>,
    mc_options: Option<&'a McOptions<'static>>,
    several: bool,
}

/// The verdicts of a file diagnosed.
struct Verdicts {
    adequate: bool,
    /// False when a Monte Carlo does not validate the GUM budget.
    validated: bool,
}

impl PolygonRun<'_> {
    /// `polycal diagnose` of a polygon measurement file (`file`, read): its table or
    /// JSON written to `stdout`, its CSV rows added to `csv_rows`, its figures written.
    /// `None`: the file failed (the `error:` line written); an error: the whole command
    /// fails.
    fn file(
        &self,
        file: FileRead<'_>,
        truth: Option<&TruthFile>,
        stdout: &mut dyn Write,
        csv_rows: &mut Vec<(String, Vec<ResultRow>)>,
    ) -> Result<Option<Verdicts>> {
        let (args, out) = (self.args, self.out);
        let FileRead { bytes, name, label } = file;
        let polygon_truth = match truth {
            Some(TruthFile::Selfcal(_)) => {
                out.error_message(format_args!(
                    "{name}: the truth is a self-calibration's (positions and heads), the file a measurement file"
                ));
                return Ok(None);
            }
            Some(TruthFile::Polygon(t)) => Some(t),
            None => None,
        };
        let (set, diagnosis) = match self.diagnosed(bytes, name) {
            Ok(d) => d,
            Err(error) => {
                out.error(&error);
                return Ok(None);
            }
        };
        if let Some(t) = polygon_truth
            && t.faces != diagnosis.before.faces
        {
            out.error_message(format_args!(
                "{name}: the truth has {} faces, the measurement {}",
                t.faces, diagnosis.before.faces
            ));
            return Ok(None);
        }
        let Some((gum, mc)) = self.final_model_uncertainty(&set, &diagnosis, name) else {
            return Ok(None);
        };
        let verdicts = Verdicts {
            adequate: diagnosis.adequacy.adequate,
            validated: mc.as_ref().is_none_or(|mc| mc.validated),
        };
        let json_report = (matches!(args.format, DiagnoseFormat::Json) || args.plot.is_some())
            .then(|| {
                let mut report = DiagnoseReport::new(
                    &diagnosis,
                    polygon_truth,
                    self.several.then(|| label.to_string()),
                )
                .with_residuals(&diagnosis, &set);
                if let Some(gum) = &gum {
                    report.after = report.after.with_uncertainty(gum);
                }
                if let Some(mc) = mc.clone() {
                    report.after = report.after.with_monte_carlo(mc);
                }
                report
            });
        if let (Some(dir), Some(report)) = (&args.plot, &json_report) {
            let mut figures = polycal::figure::diagnose_figures(report);
            if let Some(gum) = &gum {
                figures.extend(polycal::figure::budget_figures(gum));
            }
            super::write_plot(dir, &figures, &args.inputs())?;
        }
        match args.format {
            DiagnoseFormat::Json => {
                if let Some(report) = &json_report {
                    let json = output::to_json_with_stated_cross_talk(report, &args.cross_talk)?;
                    writeln!(stdout, "{json}")?;
                }
            }
            DiagnoseFormat::Table => {
                if self.several {
                    writeln!(stdout)?;
                }
                let mut text = String::new();
                output::diagnose_table::write_table(&mut text, &diagnosis, polygon_truth, label)?;
                output::write_final_model_results(
                    &mut text,
                    &diagnosis.after,
                    gum.as_ref(),
                    diagnosis.after_sub_pitch.as_ref(),
                    mc.as_ref(),
                )?;
                output::write_stated_cross_talk(&mut text, &args.cross_talk)?;
                write!(stdout, "{text}")?;
            }
            DiagnoseFormat::Csv => {
                let rows = match &diagnosis.after_sub_pitch {
                    Some(solved) => output::sub_pitch_result_rows(solved),
                    None => output::result_rows_with(&diagnosis.after, gum.as_ref()),
                };
                // checked before any row is written: a refusal names this file
                if let Err(problem) = polycal::results::check_rows(&rows) {
                    out.error_message(format!("{name}: cannot write its results: {problem}"));
                    return Ok(None);
                }
                csv_rows.push((label.to_string(), rows));
            }
        }
        Ok(Some(verdicts))
    }

    /// The measurement file `bytes` (named `name`) read, corrected for the stated
    /// cross-talk, and diagnosed (with a spinner over the forward selection's rounds).
    fn diagnosed(&self, bytes: &[u8], name: &str) -> Result<(MeasurementSet, Diagnosis)> {
        let (args, out) = (self.args, self.out);
        MeasurementSet::read_from(bytes, name, args.faces)
            .map_err(super::wrong_file::measurement)
            .inspect(|set| {
                // docs/FORMAT.md §2.1: named as `solve` names them
                for cycle in set.incomplete_cycles() {
                    out.warning(format_args!("{name}: {cycle}"));
                }
            })
            .and_then(|set| corrected(set, &args.cross_talk))
            .and_then(|set| {
                if args.budget.is_some()
                    && let Some(refusal) = shift_refusal(
                        &set,
                        name,
                        "--budget",
                        "polycal diagnose without it evaluates them",
                    )
                {
                    return Err(refusal);
                }
                // the forward selection's rounds, a spinner: how many it takes is the data's
                let progress = Arc::new(out.progress_bar_of("Diagnosing", "rounds"));
                diagnose::diagnose(&set, &self.options.clone().with_progress(progress))
                    .with_context(|| format!("{name}: cannot solve"))
                    .map(|diagnosis| (set, diagnosis))
            })
    }

    /// The budget's GUM uncertainty of the final model, and its Monte Carlo (effect
    /// columns included, as `solve`'s), when asked. `None`: refused or failed (the
    /// `error:` line written).
    fn final_model_uncertainty(
        &self,
        set: &MeasurementSet,
        diagnosis: &Diagnosis,
        name: &str,
    ) -> Option<(
        Option<CalibrationUncertainty>,
        Option<CalibrationMonteCarlo>,
    )> {
        let (args, out) = (self.args, self.out);
        // A budget is propagated through an equally weighted fit only: a final model
        // weighted by the noise of each cycle (docs/FORMAT.md §5.2 `noise`) is refused
        // with it rather than given another fit's U.
        if self.budget.is_some()
            && let Some(noise) = diagnosis.noise.as_ref().filter(|n| n.weighted)
        {
            out.error_message(format_args!(
                "{name}: --budget: the noise differs between the cycles (equal-noise test p = {:.1e}), so the final model weights each group by its own σ, and a budget is propagated through equally weighted fits only; run `polycal diagnose` without --budget for the weighted result and its u, or `polycal solve --budget` for the equally weighted calibration",
                noise.p_value
            ));
            return None;
        }
        // The budget acts on the final model: its results are the ones reported.
        let gum = match self
            .budget
            .map(|budget| evaluate_budget(set, &diagnosis.after, budget, &args.cross_talk, name))
            .transpose()
        {
            Ok(gum) => gum,
            Err(error) => {
                out.error(&error);
                return None;
            }
        };
        // The Monte Carlo of the final model, effect columns included, as `solve`'s.
        let mc = match (self.budget, &gum, self.mc_options) {
            (Some(budget), Some(gum), Some(options)) => {
                let progress = out.progress_bar("Monte Carlo");
                let options = (*options).with_progress(&progress);
                let corrections = KnownCorrection::of_stated_cross_talk(set, &args.cross_talk);
                match calibration::monte_carlo_with_corrections(
                    set,
                    &diagnosis.after,
                    budget,
                    &corrections,
                    gum,
                    &options,
                )
                .with_context(|| format!("{name}: Monte Carlo failed"))
                {
                    Ok(mc) => Some(mc),
                    Err(error) => {
                        out.error(&error);
                        return None;
                    }
                }
            }
            _ => None,
        };
        Some((gum, mc))
    }
}

/// A file read: its bytes and its names.
#[derive(Clone, Copy)]
struct FileRead<'a> {
    bytes: &'a [u8],
    /// The name in messages.
    name: &'a str,
    /// The path as given, in reports.
    label: &'a str,
}

/// What a self-calibration file's diagnosis prints: text (table, JSON) or result rows.
enum Printed {
    Text(String),
    Rows(Vec<ResultRow>),
}

/// A self-calibration file diagnosed.
struct SelfcalDone {
    adequate: bool,
    /// False when a Monte Carlo does not validate the GUM budget.
    validated: bool,
    output: Printed,
}

/// The budget of `--budget` and the options of `--monte-carlo`, when given.
struct SelfcalEvaluation<'a> {
    budget: Option<&'a InstrumentBudget>,
    monte_carlo: Option<&'a McOptions<'static>>,
}

/// `polycal diagnose` of a self-calibration file (docs/FORMAT.md §5.2).
fn selfcal_file(
    args: &DiagnoseArgs,
    file: FileRead<'_>,
    truth: Option<&TruthFile>,
    evaluation: SelfcalEvaluation<'_>,
    several: bool,
    out: &Output,
) -> Result<SelfcalDone> {
    let budget = evaluation.budget;
    let FileRead { bytes, name, label } = file;
    if !args.cross_talk.is_empty() {
        anyhow::bail!(
            "{name}: a self-calibration file has no reading_y: --cross-talk does not apply to it"
        );
    }
    let set = SelfcalSet::read_from(bytes, name, args.faces).map_err(super::wrong_file::selfcal)?;
    let truth = match truth {
        Some(TruthFile::Polygon(_)) => anyhow::bail!(
            "{name}: the truth is a polygon run's (faces), the file a self-calibration file"
        ),
        Some(TruthFile::Selfcal(t)) if t.positions != set.positions => anyhow::bail!(
            "{name}: the truth has {} positions, the self-calibration file {}",
            t.positions,
            set.positions
        ),
        Some(TruthFile::Selfcal(t)) => Some(t),
        None => None,
    };
    let options = DiagnoseOptions::new()
        .with_sigma_opt(args.sigma)
        .with_progress(Arc::new(out.progress_bar_of("Diagnosing", "rounds")));
    let selfcal_options = SelfcalOptions::new().with_sigma_opt(args.sigma);
    let diagnosis = polycal::diagnose::selfcal::diagnose_selfcal(&set, &options, &selfcal_options)
        .with_context(|| format!("{name}: cannot solve"))?;
    // the bar is cleared before anything else is written
    drop(options);
    let uncertainty = budget
        .map(|budget| {
            polycal::selfcal::evaluate_budget(&diagnosis.after, budget).map_err(|e| match e {
                CalibrationError::NoSigma => anyhow::anyhow!("{e} (--sigma)"),
                e => e.into(),
            })
        })
        .transpose()
        .with_context(|| format!("{name}: cannot evaluate the uncertainty"))?;
    // The Monte Carlo of the final model, effect columns included, as a polygon run's.
    let mc = match (budget, &uncertainty, evaluation.monte_carlo) {
        (Some(budget), Some(gum), Some(options)) => {
            let progress = out.progress_bar("Monte Carlo");
            let options = (*options).with_progress(&progress);
            Some(
                polycal::diagnose::selfcal::monte_carlo(&set, &diagnosis, budget, gum, &options)
                    .with_context(|| format!("{name}: Monte Carlo failed"))?,
            )
        }
        _ => None,
    };
    let report = || {
        let mut report = SelfcalDiagnoseReport::new(&diagnosis, truth, label);
        if let Some(u) = &uncertainty {
            report = report.with_uncertainty(u);
        }
        if let Some(mc) = &mc {
            report = report.with_monte_carlo(mc.clone());
        }
        report
    };
    if let Some(dir) = &args.plot {
        super::write_plot(
            dir,
            &polycal::figure::selfcal_figures(&report().after),
            &args.inputs(),
        )?;
    }
    let output = match args.format {
        DiagnoseFormat::Json => Printed::Text(format!("{}\n", report().to_json()?)),
        DiagnoseFormat::Table => {
            let mut text = String::new();
            if several {
                text.push('\n');
            }
            diagnose_selfcal::write_table(
                &mut text,
                &diagnosis,
                truth,
                label,
                uncertainty.as_ref(),
            )?;
            if let (Some(gum), Some(mc)) = (&uncertainty, &mc) {
                polycal::output::selfcal::write_monte_carlo(&mut text, &diagnosis.after, gum, mc)?;
            }
            Printed::Text(text)
        }
        DiagnoseFormat::Csv => {
            let rows = output::selfcal::result_rows(&diagnosis.after, uncertainty.as_ref());
            polycal::results::check_rows(&rows).map_err(|problem| {
                anyhow::anyhow!("{name}: cannot write its results: {problem}")
            })?;
            Printed::Rows(rows)
        }
    };
    Ok(SelfcalDone {
        adequate: diagnosis.diagnosis.adequacy.adequate,
        validated: mc.as_ref().is_none_or(|mc| mc.validated),
        output,
    })
}
