//! `polycal plan`: what a design gives before it is measured (docs/FORMAT.md §5.6).

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::ValueEnum;
use polycal::input::display_name;
use polycal::measurement::{MeasurementSet, Sigma};
use polycal::output::plan::{PlanReport, write_comparison_table, write_plan_table};
use polycal::plan::{self, Design, PlanOptions};

use super::output::Output;
use super::solve::read_budget;
use super::{EXIT_OK, EXIT_VERDICT};

/// After `polycal plan --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal plan --sigma 0.05 --closing
  polycal plan --sigma 0.05 --closing --budget examples/budgets/instrument.toml --format json
  polycal plan --sigma 0.05 --closing --design 'name=A' --design 'name=B;ac-faces=1,2,5;cycles=3' --target-u 0.02
  polycal plan --sigma 0.05 --designs examples/designs.toml --plot plan-figures
  polycal plan examples/data/polygon24-2ac-6cycles.csv --sigma 0.05";

/// The design options (`simulate`'s), refused with a measurement file.
const DESIGN_OPTIONS: [&str; 10] = [
    "faces",
    "ac_faces",
    "cycles",
    "closing",
    "bidirectional",
    "setups",
    "setup_shift",
    "shift_deg",
    "step_seconds",
    "temperature",
];

/// The help of `--design`, its keys the list the parser accepts
/// ([`plan::design::DESIGN_KEYS`]), so that the two cannot drift apart.
pub static DESIGN_HELP: std::sync::LazyLock<String> = std::sync::LazyLock::new(|| {
    format!(
        "A design to plan, as changes to the design of the options: KEY=VALUE pairs joined \
         by `;` (keys {}; docs/FORMAT.md §5.6); repeatable, the designs compared side by side",
        plan::design::DESIGN_KEYS.join(", ")
    )
});

/// Arguments of `polycal plan`.
#[derive(clap::Args)]
pub struct PlanArgs {
    /// A measurement CSV whose design is planned (its readings are not used); `-` reads
    /// standard input. Without it, the design of the options below.
    #[arg(conflicts_with_all = DESIGN_OPTIONS)]
    file: Option<PathBuf>,
    /// Standard deviation of one reading, arcsec.
    #[arg(long, required = true, allow_negative_numbers = true)]
    sigma: Sigma,
    /// Number of polygon faces N.
    #[arg(long, default_value_t = 24)]
    faces: usize,
    /// Face read at step 0 by each autocollimator (the paper: 1,2).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// Cycles per mounting.
    #[arg(long, default_value_t = 6)]
    cycles: u32,
    /// Add the closing reading (step N) to every cycle.
    #[arg(long)]
    closing: bool,
    /// Run every second cycle counter-clockwise (implies --closing).
    #[arg(long)]
    bidirectional: bool,
    #[command(flatten)]
    mountings: super::simulate::MountingsArgs,
    /// Seconds per table stop.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    step_seconds: f64,
    /// The lab's temperature profile recorded with the readings (`simulate`'s
    /// --temperature; without a value 20:0.5:3600:0.1:1200): the autocollimators'
    /// temperature coefficients become detectable.
    #[arg(
        long,
        value_name = "START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS[:PHASE[:NOISE]]",
        allow_negative_numbers = true
    )]
    temperature: Option<Option<String>>,
    // the help of --design: DESIGN_HELP, its keys the parser's own
    #[arg(
        long,
        value_name = "SPEC",
        conflicts_with = "file",
        help = std::sync::LazyLock::force(&DESIGN_HELP).as_str()
    )]
    design: Vec<String>,
    /// A TOML file of designs (`[[design]]` tables with the keys of --design), each a
    /// change to the design of the options; added after the --design ones.
    #[arg(long, value_name = "FILE.toml", conflicts_with = "file")]
    designs: Option<PathBuf>,
    /// Instrument budget (TOML, docs/FORMAT.md §5): U and k of every quantity, as `solve
    /// --budget` would give for a run of the design.
    #[arg(long, value_name = "FILE.toml")]
    budget: Option<PathBuf>,
    /// Find the fewest cycles per mounting whose largest u(α) is at most this, arcsec, and
    /// the time a run of them takes (each design; the table's `target cycles` and `target
    /// time`).
    #[arg(long, value_name = "ARCSEC", allow_negative_numbers = true)]
    target_u: Option<f64>,
    /// Output format.
    #[arg(long, value_enum, default_value = "table")]
    format: PlanFormat,
    /// Write the figures (u along the circle for each design) as SVG files into DIR.
    #[arg(long, value_name = "DIR")]
    plot: Option<PathBuf>,
}

impl PlanArgs {
    /// The files this command reads, which no output may replace.
    fn inputs(&self) -> Vec<&std::path::Path> {
        let mut v: Vec<&std::path::Path> = Vec::new();
        v.extend(self.file.as_deref());
        v.extend(self.designs.as_deref());
        v.extend(self.budget.as_deref());
        v
    }
}

/// `plan --format`.
#[derive(Clone, Copy, ValueEnum)]
enum PlanFormat {
    Table,
    Json,
}

impl PlanArgs {
    /// The design of the options.
    fn base_design(&self) -> Result<Design> {
        let mut spec = format!(
            "faces={};cycles={};closing={};bidirectional={};setups={};setup-shift={};step-seconds={}",
            self.faces,
            self.cycles,
            self.closing,
            self.bidirectional,
            self.mountings.setups,
            self.mountings.setup_shift,
            self.step_seconds
        );
        let list = |v: &[String]| v.join(",");
        spec.push_str(&format!(
            ";ac-faces={}",
            list(
                &self
                    .ac_faces
                    .iter()
                    .map(usize::to_string)
                    .collect::<Vec<_>>()
            )
        ));
        match &self.temperature {
            None => spec.push_str(";temperature=none"),
            Some(None) => spec.push_str(";temperature"),
            Some(Some(profile)) => spec.push_str(&format!(";temperature={profile}")),
        }
        let mut design = Design::default()
            .with_spec(&spec)
            .map_err(|e| anyhow::anyhow!("{e}").context("the design of the options"))?;
        design.table_shift_deg = self.mountings.shift_deg.clone();
        Ok(design)
    }
}

/// `polycal plan`: returns the exit status, or an error for the `error:` line.
pub fn run(args: &PlanArgs, out: &Output) -> Result<u8> {
    super::stdin_once([
        ("the measurement file", args.file.as_deref()),
        ("--designs", args.designs.as_deref()),
        ("--budget", args.budget.as_deref()),
    ])?;
    super::check_plot(
        args.plot.as_deref(),
        polycal::figure::FigureSet::Plan,
        &args.inputs(),
    )?;
    let budget = read_budget(args.budget.as_deref(), out)?;
    let options = PlanOptions::new(args.sigma)
        .with_budget(budget)
        .with_target_encoder_u(args.target_u)
        .map_err(|e| anyhow::anyhow!("--target-u: {e}"))?;
    let mut reports = Vec::new();
    if let Some(path) = &args.file {
        let name = display_name(path);
        if args.target_u.is_some() {
            anyhow::bail!(
                "--target-u needs a design given by options, not a measurement file: the \
                 cycles of a file's design are its own"
            );
        }
        let set = MeasurementSet::read_path(path, None).map_err(super::wrong_file::measurement)?;
        let options = options.clone().with_progress(std::sync::Arc::new(
            out.progress_bar_of("Planning", "sizes"),
        ));
        let planned = plan::plan_set(&set, &options)
            .map_err(actionable)
            .with_context(|| format!("{name}: cannot plan its design"))?;
        let mut planned = planned;
        planned.name = polycal::input::shown_path(path);
        reports.push(PlanReport::new(
            &planned,
            None,
            Some(polycal::input::shown_path(path)),
        ));
    } else {
        let base = args.base_design()?;
        let mut designs = Vec::new();
        for spec in &args.design {
            designs.push(
                base.with_spec(spec)
                    .map_err(|e| anyhow::anyhow!("--design: {e}"))?,
            );
        }
        if let Some(path) = &args.designs {
            designs.extend(Design::read_designs_file(path, &base)?);
        }
        if designs.is_empty() {
            designs.push(base);
        }
        let several = designs.len() > 1;
        for (i, mut design) in designs.into_iter().enumerate() {
            if several && design.name.is_none() {
                design.name = Some(format!("design {}", i + 1));
            }
            // a bar per design, cleared when its plan is done
            let bar = out.progress_bar_of(&format!("Planning {}", design.label()), "sizes");
            let options = options.clone().with_progress(std::sync::Arc::new(bar));
            let planned = plan::plan(&design, &options)
                .map_err(actionable)
                .with_context(|| format!("design \"{}\"", design.label()))?;
            reports.push(PlanReport::new(&planned, Some(&design), None));
        }
    }
    if let Some(dir) = &args.plot {
        super::write_plot(
            dir,
            &polycal::figure::plan_figures(&reports),
            &args.inputs(),
        )?;
    }
    let stdout = super::stdout::stdout();
    let mut stdout = stdout.lock();
    match args.format {
        PlanFormat::Json => {
            for r in &reports {
                writeln!(stdout, "{}", r.to_json()?)?;
            }
        }
        PlanFormat::Table => {
            let mut text = String::new();
            if reports.len() > 1 {
                write_comparison_table(&mut text, &reports)?;
            } else if let Some(r) = reports.first() {
                write_plan_table(&mut text, r)?;
            }
            write!(stdout, "{text}")?;
        }
    }
    stdout.flush()?;
    let cannot = reports
        .iter()
        .filter(|r| r.worst.is_none() || r.target.as_ref().is_some_and(|t| t.cycles.is_none()))
        .count();
    if cannot > 0 {
        out.warning(format_args!(
            "{cannot} of {} design(s) cannot calibrate or do not reach the target u(α)",
            reports.len()
        ));
        return Ok(EXIT_VERDICT);
    }
    Ok(EXIT_OK)
}

/// A planning error with the option that gets past it, where one does.
fn actionable(error: plan::PlanError) -> anyhow::Error {
    match error {
        plan::PlanError::Budget(polycal::uncertainty::calibration::CalibrationError::NoSigma) => {
            anyhow::anyhow!("{error} (--sigma)")
        }
        plan::PlanError::Budget(
            polycal::uncertainty::calibration::CalibrationError::ShiftedMountings,
        ) => anyhow::anyhow!("{error}; plan without --budget evaluates them"),
        other => other.into(),
    }
}
