//! `polycal simulate`, and the options that describe a simulated truth and its effects,
//! shared by `simulate` and `sim-lab` (flattened into both).

use std::path::PathBuf;

use anyhow::{Context, Result, anyhow, bail};
use polycal::effects::Effect;
use polycal::simulate::{
    self, ElevationModel, Harmonic, SimulationConfig, TemperatureModel, Truth,
};

use super::EXIT_OK;

/// After `polycal simulate --help`.
pub const EXAMPLES: &str = "\
Examples:
  polycal simulate --faces 24 --cycles 6 --closing --out run.csv --truth-out run.truth.json
  polycal simulate --bidirectional --direction -0.3 --drift 2:-1.5 | polycal diagnose -
  polycal simulate --faces 12 --setups 2 --setup-shift 5 --ac-faces 1,2,5 --seed 9 --out setups.csv
  polycal simulate --faces 12 --setups 3 --shift-deg 0,10,20 --out subpitch.csv --truth-out subpitch.json
  polycal simulate --temperature 20:0.5:3600:0.1:1200 --temperature-effect 1:0.3 --out warm.csv
  polycal simulate --setups 2 --elevation 10:30:1:5:0.05 --cross-talk 2:0.02 --noise-dof 5";

/// Arguments of `polycal simulate`.
#[derive(clap::Args)]
pub struct SimulateArgs {
    #[command(flatten)]
    truth: TruthArgs,
    /// Face read at step 0 by each autocollimator (the paper: 1,2).
    #[arg(long, value_delimiter = ',', default_value = "1,2")]
    ac_faces: Vec<usize>,
    /// Number of polygon mountings (shift-angle data).
    #[arg(long, default_value_t = 1)]
    setups: u32,
    /// Whole faces the polygon is turned between mountings.
    #[arg(long, default_value_t = 1)]
    setup_shift: usize,
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
    shift_deg: Vec<f64>,
    /// Seconds per table stop.
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    step_seconds: f64,
    /// Where to write the measurement CSV (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// `polycal simulate`: writes the measurement CSV and the truth.
pub fn run(args: &SimulateArgs) -> Result<u8> {
    let mut config = args.truth.config(
        args.ac_faces.clone(),
        args.setups,
        args.setup_shift,
        args.step_seconds,
    )?;
    config.table_shift_deg = args.shift_deg.clone();
    let (set, truth) = simulate::simulate(&config)?;
    let mut comment = format!(
        "polycal {} simulate: {} faces, ac faces {:?}, {} cycles, noise {} arcsec, seed {}",
        env!("CARGO_PKG_VERSION"),
        config.faces,
        config.ac_faces,
        config.cycles,
        config.noise_arcsec,
        config.seed
    );
    if !config.table_shift_deg.is_empty() {
        comment += &format!(", table shifts {:?} degrees", config.table_shift_deg);
    }
    if let Some(nu) = config.noise_student_dof {
        comment += &format!(", Student-t noise with {nu} dof");
    }
    if let Some(model) = &config.temperature {
        comment += &format!(", temperature {model}");
    }
    if let Some(model) = &config.elevation {
        comment += &format!(", elevation {model}");
    }
    let comments = vec![comment];
    match &args.out {
        Some(path) => set.write_path(path, &comments)?,
        None => {
            let stdout = std::io::stdout();
            set.write_to(stdout.lock(), &comments)
                .context("cannot write to standard output")?;
        }
    }
    args.truth.write_truth(&truth)?;
    Ok(EXIT_OK)
}

/// The truth (polygon, encoder, setup errors), the noise, the run design the effects
/// refer to, and the effects.
#[derive(clap::Args)]
pub struct TruthArgs {
    /// Number of polygon faces N.
    #[arg(long, default_value_t = 24)]
    pub faces: usize,
    /// Number of cycles.
    #[arg(long, default_value_t = 6)]
    pub cycles: u32,
    /// Add the closing reading (step N) to every cycle.
    #[arg(long)]
    pub closing: bool,
    /// Run every second cycle counter-clockwise (implies --closing).
    #[arg(long)]
    pub bidirectional: bool,
    /// Reading noise (standard deviation), arcsec.
    #[arg(long, default_value_t = 0.05, allow_negative_numbers = true)]
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
            self.harmonics
                .iter()
                .map(|spec| {
                    spec.parse::<Harmonic>()
                        .map_err(|message| anyhow!("--harmonic {spec}: {message}"))
                })
                .collect::<Result<Vec<_>>>()?
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
        })
    }

    /// Writes the truth to `--truth-out`, if given.
    pub fn write_truth(&self, truth: &Truth) -> Result<()> {
        if let Some(path) = &self.truth_out {
            std::fs::write(path, truth.to_json_pretty() + "\n")
                .with_context(|| format!("{}: cannot write the truth", path.display()))?;
        }
        Ok(())
    }
}
