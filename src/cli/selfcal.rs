//! `polycal selfcal`: a multi-head self-calibration of a rotary encoder (docs/FORMAT.md §9).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::ValueEnum;
use polycal::input::display_name;
use polycal::measurement::Sigma;
use polycal::output::selfcal::{SelfcalReport, result_rows, write_monte_carlo, write_table};
use polycal::selfcal::{self, SelfcalOptions, SelfcalSet, SelfcalSolveError};
use polycal::uncertainty::calibration::CalibrationError;

use super::monte_carlo::McArgs;
use super::output::Output;
use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal selfcal --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal selfcal examples/data/selfa-168.csv
  polycal selfcal examples/data/selfa-168.csv --format csv > selfcal.csv
  polycal selfcal examples/data/selfa-168.csv --gauge-positions 24 --format csv > selfcal-24.csv
  polycal selfcal examples/data/selfa-168.csv --lost-harmonic-bound 0.01 --format json
  polycal selfcal examples/data/selfa-168.csv --budget examples/budgets/selfcal.toml
  polycal simulate --selfcal --positions 168 | polycal selfcal -";

/// Arguments of `polycal selfcal`.
#[derive(clap::Args)]
pub struct SelfcalArgs {
    /// Self-calibration CSV (docs/FORMAT.md §9: cycle, step, head, head_angle, reading);
    /// `-` reads standard input.
    file: PathBuf,
    /// Number of table positions P (default: the largest step + 1).
    #[arg(long)]
    positions: Option<usize>,
    /// Standard deviation of one reading, arcsec, for the uncertainties of a fit without
    /// residual degrees of freedom.
    #[arg(long, allow_negative_numbers = true)]
    sigma: Option<Sigma>,
    /// A bound on the amplitude of every harmonic the head layout cannot see, arcsec:
    /// each is taken as a sinusoid of that amplitude with unknown phase (u = A/√2) and
    /// added to u(e).
    #[arg(long, value_name = "ARCSEC", allow_negative_numbers = true)]
    lost_harmonic_bound: Option<f64>,
    /// Standard uncertainty of every head's nominal angle (heads 2 … M, relative to head
    /// 1), arcsec: propagated through the slope of the disc's error into u(e) and u(c).
    #[arg(long, value_name = "ARCSEC", allow_negative_numbers = true)]
    head_angle_u: Option<f64>,
    /// The gauge of e: Σe = 0 over the N angles k·360°/N (N divides P) instead of over
    /// all P positions — that of an N-faced polygon's encoder errors, to compare with
    /// them by angle (docs/FORMAT.md §9.3).
    #[arg(long, value_name = "N")]
    gauge_positions: Option<usize>,
    /// Instrument budget (TOML, docs/FORMAT.md §5 with `acts_on` per component; in a
    /// self-calibration `each-autocollimator` means each read head): adds u_c, k and U
    /// of every result, combining the fit's type A with the budget through the design.
    #[arg(long, value_name = "FILE.toml")]
    budget: Option<PathBuf>,
    /// Output format (csv: the result file of docs/FORMAT.md §3 with angle_deg).
    #[command(flatten)]
    monte_carlo: McArgs,
    #[arg(long, value_enum, default_value = "table")]
    format: SelfcalFormat,
    /// Write the figures as SVG files into DIR (created if missing), one file per figure
    /// with a stable name (docs/FORMAT.md §10), whatever --format is.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

impl SelfcalArgs {
    /// The files this command reads, which no output may replace.
    fn inputs(&self) -> Vec<&std::path::Path> {
        let mut v: Vec<&std::path::Path> = vec![self.file.as_path()];
        v.extend(self.budget.as_deref());
        v
    }
}

/// `selfcal --format`.
#[derive(Clone, Copy, ValueEnum)]
enum SelfcalFormat {
    Table,
    Json,
    Csv,
}

/// `polycal selfcal`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &SelfcalArgs, out: &Output) -> Result<u8> {
    super::stdin_once([
        ("the self-calibration file", Some(args.file.as_path())),
        ("--budget", args.budget.as_deref()),
    ])?;
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Selfcal,
        &args.inputs(),
    )?;
    let name = display_name(&args.file);
    let set =
        SelfcalSet::read_path(&args.file, args.positions).map_err(super::wrong_file::selfcal)?;
    let mut options = SelfcalOptions::new().with_sigma_opt(args.sigma);
    if let Some(u) = args.head_angle_u {
        options = options.with_head_angle_u(u).context("--head-angle-u")?;
    }
    if let Some(n) = args.gauge_positions {
        options = options.with_gauge_positions(n);
    }
    if let Some(bound) = args.lost_harmonic_bound {
        options = options
            .with_lost_harmonic_bound(bound)
            .context("--lost-harmonic-bound")?;
    }
    let mc_options = args.monte_carlo.options(args.budget.is_some())?;
    let budget = super::solve::read_budget(args.budget.as_deref(), out)?;
    let solution = selfcal::solve(&set, &options)
        .map_err(|e| match e {
            SelfcalSolveError::InvalidGauge { .. } => anyhow::anyhow!("--gauge-positions: {e}"),
            e => e.into(),
        })
        .with_context(|| format!("{name}: cannot solve"))?;
    if solution.sigma.is_none() {
        out.warning(format!(
            "{name}: no residual degrees of freedom: uncertainties need --sigma"
        ));
    }
    let uncertainty = budget
        .as_ref()
        .map(|budget| {
            selfcal::evaluate_budget(&solution, budget).map_err(|e| match e {
                CalibrationError::NoSigma => anyhow::anyhow!("{e} (--sigma)"),
                e => e.into(),
            })
        })
        .transpose()
        .with_context(|| format!("{name}: cannot evaluate the uncertainty"))?;
    // The Monte Carlo of the budget (JCGM 101), with the validation of its GUM intervals.
    let mc = match (&budget, &uncertainty, &mc_options) {
        (Some(budget), Some(gum), Some(options)) => {
            let progress = out.progress_bar("Monte Carlo");
            let options = (*options).with_progress(&progress);
            Some(
                selfcal::monte_carlo(&set, &solution, budget, gum, &options)
                    .with_context(|| format!("{name}: Monte Carlo failed"))?,
            )
        }
        _ => None,
    };
    let report_of = || {
        let mut report = SelfcalReport::new(&solution, &name);
        if let Some(uncertainty) = &uncertainty {
            report = report.with_uncertainty(uncertainty);
        }
        if let Some(mc) = &mc {
            report = report.with_monte_carlo(mc.clone());
        }
        report
    };
    if let Some(dir) = &args.plot {
        let report = report_of();
        super::write_plot(
            dir,
            &polycal::figure::selfcal_figures(&report),
            &args.inputs(),
        )?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        SelfcalFormat::Json => {
            writeln!(stdout, "{}", report_of().to_json()?)?;
        }
        SelfcalFormat::Table => {
            let mut text = String::new();
            write_table(
                &mut text,
                &solution,
                &polycal::input::shown_path(&args.file),
                uncertainty.as_ref(),
            )?;
            if let (Some(gum), Some(mc)) = (&uncertainty, &mc) {
                write_monte_carlo(&mut text, &solution, gum, mc)?;
            }
            write!(stdout, "{text}")?;
        }
        SelfcalFormat::Csv => {
            let rows = result_rows(&solution, uncertainty.as_ref());
            polycal::results::check_rows(&rows).map_err(|problem| {
                anyhow::anyhow!("{name}: cannot write its results: {problem}")
            })?;
            polycal::results::write_results(&mut stdout, &rows)?;
        }
    }
    stdout.flush()?;
    if mc.as_ref().is_some_and(|mc| !mc.validated) {
        out.warning(
            "Monte Carlo does not validate the GUM uncertainty of some results (JCGM 101 §8); \
             see the monte_carlo results",
        );
        return Ok(EXIT_VERDICT);
    }
    Ok(EXIT_OK)
}
