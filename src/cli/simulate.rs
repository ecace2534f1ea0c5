//! `polycal simulate`, and the options that describe a simulated truth and its effects,
//! shared by `simulate` and `sim-lab` (flattened into both).

use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use clap::builder::ArgPredicate;
use polycal::effects::Effect;
use polycal::simulate::{
    self, ElevationModel, Harmonic, RandomWalkSpec, RezeroSpec, SelfcalConfigError,
    SelfcalSimConfig, SimulateError, SimulationConfig, TemperatureModel, Truth,
};

use super::files::CommandOutputs;
use super::output::Output;
use super::{EXIT_OK, with_hint};

/// After `polycal simulate --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal simulate --faces 24 --cycles 6 --closing --out run.csv --truth-out run.truth.json
  polycal simulate --bidirectional --direction -0.3 --drift 2:-1.5 | polycal diagnose -
  polycal simulate --faces 12 --setups 2 --setup-shift 5 --ac-faces 1,2,5 --seed 9 --out setups.csv
  polycal simulate --faces 12 --setups 3 --shift-deg 0,10,20 --out subpitch.csv --truth-out subpitch.json
  polycal simulate --temperature 20:0.5:3600:0.1:1200 --temperature-effect 1:0.3 --out warm.csv
  polycal simulate --setups 2 --elevation 10:30:1:5:0.05 --cross-talk 2:0.02 --noise-dof 5
  polycal simulate --selfcal --out selfa.csv --truth-out selfa.truth.json
  polycal simulate --selfcal --positions 12 --heads 0,90,180,270 --cycles 3 --bidirectional
  polycal simulate --selfcal --positions 84 --harmonic 1:0.8:0.3 --harmonic 7:0.2 --table-error 0 --noise 0";

/// The options of the polygon run, refused with `--selfcal` (clap's ids).
const POLYGON_ONLY: [&str; 19] = [
    "faces",
    "closing",
    "pitch_spread",
    "setup_spread",
    "noise_dof",
    "temperature",
    "elevation",
    "drift",
    "offset_step",
    "temperature_effect",
    "cross_talk",
    "direction",
    "outlier",
    "ac_faces",
    "setups",
    "setup_shift",
    "rezero",
    "random_walk",
    "no_time",
];

/// Arguments of `polycal simulate`.
#[derive(clap::Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    truth: TruthArgs,
    /// Face read at step 0 by each autocollimator (the paper: 1,2).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    #[command(flatten)]
    mountings: MountingsArgs,
    /// Seconds per table stop.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    step_seconds: f64,
    /// Where to write the measurement CSV (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Simulate a self-calibration run instead: read heads on one graduated disc
    /// (docs/FORMAT.md §9), written as the self-calibration CSV.
    ///
    /// Reading = t[cycle, step] + e(step·360°/P + head angle) + c[head] + noise, with the
    /// table error t (--table-error), the disc's graduation error e (--harmonic, or drawn
    /// up to --max-order), the head errors c (--head-error, c[1] = 0) and --noise. Shared
    /// with the polygon run: --cycles (default 2 here), --bidirectional (cycles 2, 4, …
    /// visit steps P−1 … 0), --noise (default 0.02 here), --harmonic (ORDER:AMPLITUDE[:PHASE]
    /// is A·cos(ORDER·θ + PHASE) at the disc angle θ, in radians), --step-seconds, --seed, --out,
    /// --truth-out. The polygon's options (--faces, --ac-faces, --closing, the spreads,
    /// the models and the effects) are refused.
    #[arg(long, conflicts_with_all = POLYGON_ONLY)]
    selfcal: bool,
    #[command(flatten)]
    selfcal_args: SelfcalArgs,
}

/// The options of `simulate --selfcal` only (each needs `--selfcal`).
#[derive(clap::Args)]
struct SelfcalArgs {
    /// With --selfcal: number of table positions P per turn (step p at p·360°/P).
    #[arg(long, default_value_t = 168, requires = "selfcal")]
    positions: usize,
    /// With --selfcal: the read heads, `selfa` (12 heads: 0, 120, 240, 90, 180, 270 and
    /// k·360/7 for k = 1 … 6) or their angles from head 1 in degrees, head 1 first at 0
    /// (e.g. 0,90,180,270).
    #[arg(
        long,
        value_name = "selfa|A1,A2,...",
        default_value = "selfa",
        requires = "selfcal"
    )]
    heads: String,
    /// With --selfcal: standard deviation of the table's position error at every stop,
    /// arcsec (the table does not return to the same angle).
    #[arg(
        long,
        default_value_t = 1.0,
        allow_negative_numbers = true,
        requires = "selfcal"
    )]
    table_error: f64,
    /// With --selfcal: the head errors c are drawn uniformly in ±this, arcsec (c[1] = 0).
    #[arg(
        long,
        default_value_t = 2.0,
        allow_negative_numbers = true,
        requires = "selfcal"
    )]
    head_error: f64,
    /// With --selfcal and no --harmonic: the drawn graduation error has the orders
    /// 1 … K, amplitudes 0.3″/√order and random phases.
    #[arg(
        long,
        value_name = "K",
        default_value_t = 60,
        requires = "selfcal",
        conflicts_with = "harmonics"
    )]
    max_order: usize,
}

/// The polygon's mountings of a simulated or planned run (`simulate`, `sim-lab`, `plan`):
/// how many, the faces the polygon is turned between them, the table's angle at step 0
/// of each.
#[derive(clap::Args, Clone)]
pub struct MountingsArgs {
    /// Number of polygon mountings (shift-angle data).
    #[arg(long, default_value_t = 1)]
    pub setups: u32,
    /// Whole faces the polygon is turned between mountings.
    #[arg(long, default_value_t = 1)]
    pub setup_shift: usize,
    /// The table's angle at step 0 of each mounting, degrees (the `shift` column), one per
    /// setup (e.g. 0,10,20 with --setups 3); default: every mounting at 0. A shift that is
    /// not a whole multiple of 360/N puts the mounting's stops between the encoder
    /// positions (sub-pitch).
    #[arg(
        long,
        value_delimiter = ',',
        value_name = "DEG,...",
        allow_negative_numbers = true
    )]
    pub shift_deg: Vec<f64>,
}

impl SimulateArgs {
    /// The files `simulate` writes, checked before anything is simulated: `--out` and
    /// `--truth-out` neither one file nor anything but a regular file (docs/FORMAT.md
    /// §8.1); both are put into place together.
    fn outputs(&self) -> Result<CommandOutputs> {
        let files = CommandOutputs::new([])?;
        files.check(
            [
                ("--out", self.out.as_deref()),
                ("--truth-out", self.truth.truth_out.as_deref()),
            ]
            .into_iter()
            .filter_map(|(flag, path)| Some((flag, path?))),
        )?;
        Ok(files)
    }
}

/// `polycal simulate`: writes the measurement CSV (or with `--selfcal` the
/// self-calibration CSV) and the truth.
pub fn run(args: &SimulateArgs, out: &Output) -> Result<u8> {
    args.outputs()?;
    if args.selfcal {
        return run_selfcal(args, out);
    }
    let mut config = args.truth.config(
        args.ac_faces.clone(),
        args.mountings.setups,
        args.mountings.setup_shift,
        args.step_seconds,
    )?;
    config.table_shift_deg = args.mountings.shift_deg.clone();
    let (set, truth) = simulate::simulate(&config)?;
    let comments = vec![config.comment()];
    let mut files = args.outputs()?;
    match &args.out {
        Some(path) => files.write_with("--out", path, |w| set.write_to(w, &comments))?,
        None => {
            let stdout = super::stdout::stdout();
            set.write_to(stdout.lock(), &comments)
                .context("cannot write to standard output")?;
        }
    }
    args.truth.stage_json(&mut files, &truth.to_json_pretty())?;
    files.commit()?;
    Ok(EXIT_OK)
}

/// `polycal simulate --selfcal`: writes the self-calibration CSV and its truth.
fn run_selfcal(args: &SimulateArgs, out: &Output) -> Result<u8> {
    let options = &args.selfcal_args;
    let mut config = SelfcalSimConfig::default();
    config.positions = options.positions;
    config.cycles = args.truth.cycles;
    config.head_angles_deg = parse_heads(&options.heads)?;
    config.encoder_harmonics = args.truth.parsed_harmonics()?;
    config.max_order = options.max_order;
    config.head_error_arcsec = options.head_error;
    config.table_error_arcsec = options.table_error;
    config.noise_arcsec = args.truth.noise;
    config.bidirectional = args.truth.bidirectional;
    config.step_seconds = Some(args.step_seconds);
    config.seed = args.truth.seed;
    let (set, truth) = simulate::simulate_selfcal(&config).map_err(selfcal_hint)?;

    let off_grid = config.heads_off_grid();
    if !off_grid.is_empty() {
        let heads: Vec<String> = off_grid.iter().map(u32::to_string).collect();
        let which = match heads.as_slice() {
            [one] => format!("head {one} is"),
            many => format!("heads {} are", many.join(", ")),
        };
        let p = config.positions;
        out.warning(format!(
            "{which} not at a multiple of 360°/{p} = {}°: they read the disc between the {p} \
             positions, where the truth's encoder_error has no value",
            360.0 / p as f64
        ));
    }

    let comments = [config.comment(&args.truth.harmonics)];
    let mut files = args.outputs()?;
    match &args.out {
        Some(path) => files.write_with("--out", path, |w| {
            set.write_with_comments(w, &comments)
                .map_err(|e| std::io::Error::other(e.to_string()))
        })?,
        None => {
            let stdout = super::stdout::stdout();
            set.write_with_comments(stdout.lock(), &comments)
                .context("cannot write to standard output")?;
        }
    }
    args.truth.stage_json(&mut files, &truth.to_json_pretty())?;
    files.commit()?;
    Ok(EXIT_OK)
}

/// `--heads`: `selfa`, or the head angles in degrees separated by commas.
fn parse_heads(spec: &str) -> Result<Vec<f64>> {
    if spec.trim().eq_ignore_ascii_case("selfa") {
        return Ok(simulate::selfa_head_angles_deg());
    }
    spec.split(',')
        .map(str::trim)
        .map(|text| match text.parse::<f64>() {
            Ok(angle) if angle.is_finite() => Ok(angle),
            _ => Err(anyhow!(
                "--heads {spec}: \"{text}\" is not a number of degrees (expected selfa, or the \
                 head angles from head 1 in degrees, head 1 first at 0, e.g. 0,90,180,270)"
            )),
        })
        .collect()
}

/// A refused self-calibration simulation, with the option that helps.
fn selfcal_hint(error: SimulateError) -> anyhow::Error {
    use SelfcalConfigError as E;
    let SimulateError::SelfcalConfig(reason) = &error else {
        return error.into();
    };
    let (flag, hint) = match reason {
        E::TooFewPositions { .. } => ("--positions", "give --positions 3 or more"),
        E::NoCycles => ("--cycles", "give --cycles 1 or more"),
        E::TooFewHeads { .. }
        | E::FirstHeadNotAtZero { .. }
        | E::HeadAngleOutOfRange { .. }
        | E::SameHeadAngle { .. } => (
            "--heads",
            "--heads lists distinct angles in [0, 360) degrees, head 1 first at 0",
        ),
        E::NotNonNegative { what, .. } => match *what {
            "noise" => ("--noise", "give --noise 0 or more"),
            "table error" => ("--table-error", "give --table-error 0 or more"),
            "head error range" => ("--head-error", "give --head-error 0 or more"),
            _ => return error.into(),
        },
        E::StepSeconds { .. } => ("--step-seconds", "give --step-seconds above 0"),
        E::Harmonic(_) => ("--harmonic", "see --harmonic"),
        E::MaxOrder { .. } => ("--max-order", "give --max-order 1 or more"),
        E::TooManyReadings { .. } | E::TooManyHarmonicTerms { .. } => (
            "--positions",
            "give fewer --positions, heads, --cycles or harmonics",
        ),
        _ => return error.into(),
    };
    with_hint(&error, flag, hint)
}

/// The truth (polygon, encoder, setup errors), the noise, the run design the effects
/// refer to, and the effects.
#[derive(clap::Args)]
pub struct TruthArgs {
    /// Number of polygon faces N.
    #[arg(long, default_value_t = 24)]
    pub faces: usize,
    /// Number of cycles.
    #[arg(
        long,
        default_value_t = 6,
        default_value_if("selfcal", ArgPredicate::IsPresent, "2")
    )]
    pub cycles: u32,
    /// Add the closing reading (step N) to every cycle.
    #[arg(long)]
    pub closing: bool,
    /// Run every second cycle counter-clockwise (implies --closing).
    #[arg(long)]
    pub bidirectional: bool,
    /// Reading noise (standard deviation), arcsec.
    #[arg(
        long,
        default_value_t = 0.05,
        default_value_if("selfcal", ArgPredicate::IsPresent, "0.02"),
        allow_negative_numbers = true
    )]
    pub noise: f64,
    /// Spread (standard deviation) of the pitch deviations, arcsec.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub pitch_spread: f64,
    /// Encoder error harmonic ORDER:AMPLITUDE[:PHASE] (arcsec, radians); repeatable.
    /// Default: 1:0.6:0.4 2:0.35:1.3 3:0.2:2.2 5:0.1:0.7.
    #[arg(
        long = "harmonic",
        value_name = "ORDER:AMPLITUDE[:PHASE]",
        allow_negative_numbers = true
    )]
    pub harmonics: Vec<String>,
    /// Spread of the setup errors, arcsec.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub setup_spread: f64,
    /// Random seed (same seed, same truth and noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Reading noise from Student's t with NU (> 2) degrees of freedom instead of the
    /// normal, with the same standard deviation --noise (heavy tails).
    #[arg(long, value_name = "NU", allow_negative_numbers = true)]
    pub noise_dof: Option<f64>,
    /// Write the lab's air temperature (the `temperature` column), °C at t seconds:
    /// START + WARMUP·(1 − exp(−t/WARMUP_SECONDS)) + AMPLITUDE·sin(2π·t/PERIOD_SECONDS +
    /// PHASE) + NOISE·z. Without a value: 20:0.5:3600:0.1:1200 (an air-conditioned lab).
    #[arg(
        long,
        value_name = "START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS[:PHASE[:NOISE]]",
        allow_negative_numbers = true
    )]
    pub temperature: Option<Option<String>>,
    /// Write the elevation axis (the `reading_y` column), arcsec: drawn pyramidal errors
    /// (spread PYRAMIDAL), a drawn tilt of each mounting (spread TILT), the table's
    /// wobble (amplitude WOBBLE), drawn zeros per mounting and autocollimator (spread
    /// OFFSET) and NOISE. Without a value: 10:20:1:5:0.05.
    #[arg(
        long,
        value_name = "PYRAMIDAL:TILT:WOBBLE:OFFSET:NOISE[:WOBBLE_PHASE]",
        allow_negative_numbers = true
    )]
    pub elevation: Option<Option<String>>,
    /// Zero drift AC:RATE[:QUADRATIC] (arcsec per hour, and per hour² for a curved
    /// drift); repeatable.
    #[arg(
        long,
        value_name = "AC:RATE[:QUADRATIC]",
        allow_negative_numbers = true
    )]
    pub drift: Vec<String>,
    /// Zero jump AC:CYCLE:VALUE from that cycle on, AC:CYCLE:STEP:VALUE from that stop of
    /// the cycle on (in time order), or SETUP:AC:CYCLE:STEP:VALUE in that mounting only;
    /// repeatable.
    #[arg(
        long,
        value_name = "[SETUP:AC:CYCLE:STEP|AC:CYCLE[:STEP]]:VALUE",
        allow_negative_numbers = true
    )]
    pub offset_step: Vec<String>,
    /// Temperature coefficient AC:COEFF of an autocollimator, arcsec per °C against the
    /// run's mean temperature (needs --temperature); repeatable.
    #[arg(long, value_name = "AC:COEFF", allow_negative_numbers = true)]
    pub temperature_effect: Vec<String>,
    /// Cross-talk AC:COEFF: the reading changes by COEFF times its reading_y (needs
    /// --elevation); repeatable.
    #[arg(long, value_name = "AC:COEFF", allow_negative_numbers = true)]
    pub cross_talk: Vec<String>,
    /// Counter-clockwise offset [AC:]VALUE (`-0.3` or `2:-0.3`); repeatable.
    #[arg(long, value_name = "[AC:]VALUE", allow_negative_numbers = true)]
    pub direction: Vec<String>,
    /// One bad reading CYCLE:STEP:AC:VALUE, or SETUP:CYCLE:STEP:AC:VALUE; repeatable.
    #[arg(
        long,
        value_name = "[SETUP:]CYCLE:STEP:AC:VALUE",
        allow_negative_numbers = true
    )]
    pub outlier: Vec<String>,
    /// An autocollimator zeroed anew at the start of every cycle AC:SIGMA: each cycle's
    /// zero offset drawn normal with standard deviation SIGMA arcsec (into the truth as a
    /// `rezero` effect); repeatable.
    #[arg(long, value_name = "AC:SIGMA", allow_negative_numbers = true)]
    pub rezero: Vec<String>,
    /// A wandering zero AC:RATE: a random walk of RATE arcsec per √hour between stops,
    /// continuing over the whole run (into the truth's `random_walk`); repeatable.
    #[arg(long, value_name = "AC:RATE_PER_SQRT_H", allow_negative_numbers = true)]
    pub random_walk: Vec<String>,
    /// Write no `time` column (as the reference paper's data); drift and random walks
    /// still act on the true time.
    #[arg(long)]
    pub no_time: bool,
    /// Where to write the truth JSON (docs/FORMAT.md §4).
    #[arg(long)]
    pub truth_out: Option<PathBuf>,
}

impl TruthArgs {
    /// The simulation configuration for the given design details.
    pub fn config(
        &self,
        ac_faces: Vec<usize>,
        setups: u32,
        setup_shift_faces: usize,
        step_seconds: f64,
    ) -> Result<SimulationConfig> {
        let mut effects = Vec::new();
        for (kind, flag, specs) in [
            ("drift", "drift", &self.drift),
            ("offset-step", "offset-step", &self.offset_step),
            ("direction", "direction", &self.direction),
            ("outlier", "outlier", &self.outlier),
            (
                "temperature",
                "temperature-effect",
                &self.temperature_effect,
            ),
            ("cross-talk", "cross-talk", &self.cross_talk),
        ] {
            for spec in specs {
                effects.push(
                    Effect::parse_spec(kind, spec)
                        .map_err(|message| anyhow!("--{flag} {spec}: {message}"))?,
                );
            }
        }
        if let (Some(spec), None) = (self.temperature_effect.first(), &self.temperature) {
            bail!(
                "--temperature-effect {spec}: a temperature effect needs the lab's temperature; \
                 add --temperature"
            );
        }
        if let (Some(spec), None) = (self.cross_talk.first(), &self.elevation) {
            bail!("--cross-talk {spec}: cross-talk needs the elevation axis; add --elevation");
        }
        let temperature = match &self.temperature {
            None => None,
            Some(None) => Some(TemperatureModel::default()),
            Some(Some(spec)) => Some(
                spec.parse::<TemperatureModel>()
                    .map_err(|message| anyhow!("--temperature {spec}: {message}"))?,
            ),
        };
        let elevation = match &self.elevation {
            None => None,
            Some(None) => Some(ElevationModel::default()),
            Some(Some(spec)) => Some(
                spec.parse::<ElevationModel>()
                    .map_err(|message| anyhow!("--elevation {spec}: {message}"))?,
            ),
        };
        let encoder_harmonics = if self.harmonics.is_empty() {
            SimulationConfig::default().encoder_harmonics
        } else {
            self.parsed_harmonics()?
        };
        Ok(SimulationConfig {
            faces: self.faces,
            ac_faces,
            setups,
            setup_shift_faces,
            table_shift_deg: Vec::new(),
            cycles: self.cycles,
            closing: self.closing || self.bidirectional,
            bidirectional: self.bidirectional,
            noise_arcsec: self.noise,
            pitch_spread_arcsec: self.pitch_spread,
            encoder_harmonics,
            setup_error_spread_arcsec: self.setup_spread,
            step_seconds,
            effects,
            seed: self.seed,
            temperature,
            elevation,
            noise_student_dof: self.noise_dof,
            rezero: self
                .rezero
                .iter()
                .map(|spec| {
                    spec.parse::<RezeroSpec>()
                        .map_err(|message| anyhow!("--rezero {spec}: {message}"))
                })
                .collect::<Result<_>>()?,
            random_walk: self
                .random_walk
                .iter()
                .map(|spec| {
                    spec.parse::<RandomWalkSpec>()
                        .map_err(|message| anyhow!("--random-walk {spec}: {message}"))
                })
                .collect::<Result<_>>()?,
            no_time: self.no_time,
        })
    }

    /// The `--harmonic` options, parsed (empty when none is given).
    pub fn parsed_harmonics(&self) -> Result<Vec<Harmonic>> {
        self.harmonics
            .iter()
            .map(|spec| {
                spec.parse::<Harmonic>()
                    .map_err(|message| anyhow!("--harmonic {spec}: {message}"))
            })
            .collect()
    }

    /// Writes the truth to `--truth-out`, if given, whole or not at all.
    pub fn write_truth(&self, truth: &Truth) -> Result<()> {
        let mut files = CommandOutputs::new([])?;
        self.stage_json(&mut files, &truth.to_json_pretty())?;
        files.commit().map(|_| ())
    }

    /// Writes a truth's JSON text (and a line feed) to `--truth-out` among `files`, if
    /// given.
    fn stage_json(&self, files: &mut CommandOutputs, json: &str) -> Result<()> {
        if let Some(path) = &self.truth_out {
            files.write("--truth-out", path, format!("{json}\n").as_bytes())?;
        }
        Ok(())
    }
}
