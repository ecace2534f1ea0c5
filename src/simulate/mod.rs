//! Simulated measurement runs with a known truth.
//!
//! Two kinds of run: the polygon calibration ([`simulate`], below), and the
//! self-calibration of an encoder with several read heads ([`simulate_selfcal`], with its
//! own settings [`SelfcalSimConfig`] and truth [`SelfcalTruth`]; its documentation gives
//! the model, the run and the random draws). The same encoder can be put into both: the
//! self-calibration truth's `encoder_harmonics` are a continuous function of the angle, and
//! as a polygon run's [`SimulationConfig::encoder_harmonics`] they give that encoder's
//! errors at the polygon's N positions. [`crate::verification`] puts one truth into three runs
//! (two autocollimators, the shift-angle method, self-calibration) and compares their
//! results as the paper's section 3.1 does.
//!
//! [`simulate`] draws the true values ([`Truth`]) for a [`SimulationConfig`] and the
//! readings a run of that design would give, following the model of docs/FORMAT.md §1:
//!
//! ```text
//! reading = α[step mod N] + φ[face] + U[setup, ac] + Σ effect.value · effect.regressor + noise
//! ```
//!
//! # The run
//!
//! Setups are measured one after the other (setup 1 first); each has cycles 1 … R in
//! time order. A clockwise cycle visits steps 0, 1, …, N−1, then N when `closing`; with
//! `bidirectional`, cycles 2, 4, … are counter-clockwise and visit steps N, N−1, …, 0
//! (every cycle then has the closing reading). At every stop every autocollimator gives
//! one reading: autocollimator j reads face
//! `((ac_faces[j-1] − 1) + (setup − 1)·setup_shift_faces + step) mod N + 1`.
//!
//! Readings are ordered by time, then autocollimator. `time_seconds` is the number of
//! stops before this one (over the whole run, across cycles and setups) times
//! `step_seconds`, shared by the autocollimators of one stop, starting at 0.
//! `encoder_degrees` is the commanded position step·360/N (360 at the closing step)
//! plus the setup's table shift; `line` is 0.
//!
//! # Shifted mountings
//!
//! With `table_shift_deg`, setup s stops at `table_shift_deg[s-1]` + step·360°/N; the set
//! keeps the shifts ([`MeasurementSet::setup_shift_deg`], written as the `shift` column)
//! and each reading's α is the truth's encoder error at its table angle
//! ([`Truth::model_reading_shifted`]). Shifts that are not whole multiples of 360°/N give
//! the truth an encoder error at every table angle of every coset (`encoder_angle_deg`,
//! [`Truth::draw`]); whole-face shifts keep the N positions.
//!
//! `temperature_celsius` is `None` unless the configuration has a [`TemperatureModel`];
//! then every reading of a stop has the model's temperature at the stop's time, and the
//! truth's `reference_temperature_celsius` is the mean of that column over all readings
//! (the reference a `temperature` effect acts against). `reading_y_arcsec` is `None`
//! unless the configuration has an [`ElevationModel`]; then it is the truth's
//! [`ElevationTruth`] value of that reading plus noise, and a `cross-talk` effect acts
//! on that written value.
//!
//! # Noise
//!
//! The reading noise has standard deviation `noise_arcsec`: `noise_arcsec`·z with z
//! standard normal, or, with `noise_student_dof` = ν, `noise_arcsec`·z·√((ν − 2)/w) with
//! w chi-squared with ν degrees of freedom: a Student-t variate (z/√(w/ν)) scaled to unit
//! variance, with the same z as the normal noise and heavier tails (kurtosis
//! 3 + 6/(ν − 4) for ν > 4).
//!
//! # Reproducibility
//!
//! Everything random comes from `ChaCha8Rng::seed_from_u64(config.seed)`: the truth from
//! its stream 0 ([`Truth::draw`] documents the order), the noise from its stream 1, one
//! standard normal per reading in row order, drawn even when the noise is 0. The same
//! configuration therefore gives the same readings and truth bit for bit (with the same
//! versions of `rand_chacha` and `rand_distr`), and `simulate(c)` equals
//! `Truth::draw(c)` followed by `simulate_with_truth(c, &truth)`. Because the noise has
//! its own stream, a different spread or harmonic changes the truth but not the noise.
//!
//! The additions have streams of their own, so that a run without them is the same bit
//! for bit as before they existed, and switching one on changes nothing else: stream 2
//! the temperature noise (one standard normal per stop, in time order), stream 3 the
//! elevation geometry ([`ElevationTruth`] documents the order), stream 4 the `reading_y`
//! noise (one standard normal per reading, row order), stream 5 the chi-squared variates
//! of Student-t noise (one per reading, row order). Each is drawn only when its model is
//! on, and then even when its spread or noise is 0.

mod config;
mod habits;
mod harmonic;
mod models;
mod run_effect;
mod selfcal;
mod truth;
mod truth_file;

use std::path::PathBuf;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{ChiSquared, Distribution, StandardNormal};

pub use config::{Harmonic, HarmonicError, MAX_READINGS, SimulationConfig, SimulationConfigError};
pub use habits::{HabitError, RandomWalkSpec, RandomWalkTruth, RezeroSpec};
pub use models::{
    ElevationModel, ElevationTruth, ModelError, ModelSpecError, MountingTilt, TemperatureModel,
};
pub use run_effect::RunEffectError;
pub use selfcal::{
    HeadErrorTruth, MAX_DRAWN_ORDER, MAX_HARMONIC_TERMS, MIN_POSITIONS, SelfcalConfigError,
    SelfcalSimConfig, SelfcalTruth, equally_spaced_head_angles_deg, selfa_head_angles_deg,
    simulate_selfcal,
};
pub use truth::{SetupErrorTruth, Truth};
pub use truth_file::{TruthError, TruthFile};

use crate::effects::Effect;
use crate::measurement::{MeasurementSet, Reading, Stop, run_stops};

/// ChaCha stream of the true values.
const TRUTH_STREAM: u64 = 0;
/// ChaCha stream of the reading noise.
const NOISE_STREAM: u64 = 1;
/// ChaCha stream of the temperature noise (one standard normal per stop).
const TEMPERATURE_STREAM: u64 = 2;
/// ChaCha stream of the true elevation geometry ([`ElevationTruth`]).
const ELEVATION_TRUTH_STREAM: u64 = 3;
/// ChaCha stream of the `reading_y` noise (one standard normal per reading).
const ELEVATION_NOISE_STREAM: u64 = 4;
/// ChaCha stream of the chi-squared variates of Student-t noise (one per reading).
const STUDENT_STREAM: u64 = 5;

/// Why a simulation or a truth file was refused.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum SimulateError {
    /// The simulation settings are invalid ([`SimulationConfig::validate`]).
    #[error("invalid simulation settings: {0}")]
    Config(SimulationConfigError),
    /// A file could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A truth file is not valid JSON of the truth format.
    #[error("{location}: not a valid truth file: {message}")]
    Json {
        /// The file, and the line and column where the JSON went wrong.
        location: crate::input::Location,
        /// What is wrong (serde_json's message without its position).
        message: String,
    },
    /// A truth is inconsistent, or does not fit the simulation settings.
    #[error("{origin}: invalid truth: {problem}")]
    Truth {
        /// Where the truth came from: a file name, or `truth` for one given in memory.
        origin: String,
        /// What is wrong.
        problem: TruthError,
    },
    /// The settings of a simulated self-calibration are invalid
    /// ([`SelfcalSimConfig::validate`]).
    #[error("invalid self-calibration simulation settings: {0}")]
    SelfcalConfig(#[from] SelfcalConfigError),
    /// The simulated readings break a rule of the measurement file (docs/FORMAT.md §2),
    /// such as a reading beyond its limits for a noise or a truth that large.
    #[error("the simulated readings: {0}")]
    Readings(crate::input::FileError),
    /// The simulated self-calibration readings break a rule of the self-calibration file
    /// (docs/FORMAT.md §9); not expected of a valid configuration.
    #[error("the simulated self-calibration readings: {0}")]
    Selfcal(crate::input::FileError),
}

/// Simulates a run: draws the truth for `config`, then the readings.
///
/// Equivalent to [`Truth::draw`] followed by [`simulate_with_truth`]; see the
/// [module documentation](self) for the run's structure and the order of the random
/// draws. The measurement set's `source` is `"simulated"`.
///
/// ```
/// use polycal::simulate::{SimulationConfig, simulate};
///
/// // The paper's design on a 4-faced polygon, without noise.
/// let config = SimulationConfig { faces: 4, noise_arcsec: 0.0, ..SimulationConfig::default() };
/// let (set, truth) = simulate(&config)?;
/// assert_eq!(set.readings.len(), 6 * 5 * 2); // cycles · (N + closing) · autocollimators
/// let first = &set.readings[0]; // step 0, autocollimator 1, face 1
/// assert_eq!((first.step, first.ac, first.face), (0, 1, 1));
/// let u1 = truth.setup_error_of(1, 1).unwrap();
/// let expected = truth.encoder_error[0] + truth.pitch_deviation[0] + u1;
/// assert!((first.reading_arcsec - expected).abs() < 1e-12);
/// # Ok::<(), polycal::simulate::SimulateError>(())
/// ```
pub fn simulate(config: &SimulationConfig) -> Result<(MeasurementSet, Truth), SimulateError> {
    let truth = Truth::draw(config)?;
    let set = simulate_with_truth(config, &truth)?;
    Ok((set, truth))
}

/// Simulates the readings of a run of `config`'s design for the given `truth`.
///
/// The true values and the effects come from `truth` (each reading is
/// [`Truth::model_reading`] plus noise); from `config` only the design (faces,
/// autocollimators, setups, shift, cycles, closing, bidirectional), `step_seconds`,
/// `noise_arcsec`, `noise_student_dof`, the temperature model, the elevation model's
/// noise and `seed` are used — its spreads, harmonics and effects are ignored. This lets
/// a test redraw the noise over many seeds with one truth. The `reading_y` column is
/// written when `config` has an elevation model, from the truth's `elevation`; the
/// temperature column when it has a temperature model (its noise follows `seed`, so with
/// another seed than the truth was drawn with, the column's mean differs slightly from
/// the truth's `reference_temperature_celsius`, which a temperature effect keeps using).
///
/// Refused when `config` is invalid, the truth is invalid ([`Truth::validate`]), the
/// numbers of faces differ, an effect of the truth names something the run does not
/// have (or needs a model `config` lacks), `config` has an elevation model and the truth
/// no `elevation`, or the truth has a temperature effect and no
/// `reference_temperature_celsius`.
pub fn simulate_with_truth(
    config: &SimulationConfig,
    truth: &Truth,
) -> Result<MeasurementSet, SimulateError> {
    config.validate()?;
    let mismatch = |problem: TruthError| SimulateError::Truth {
        origin: "truth".into(),
        problem,
    };
    truth.validate()?;
    if truth.faces != config.faces {
        return Err(mismatch(TruthError::FacesDiffer {
            truth_faces: truth.faces,
            run: "the simulation settings",
            run_faces: config.faces,
        }));
    }
    for e in &truth.effects {
        config.check_effect(e).map_err(|problem| {
            mismatch(TruthError::EffectNotInRun {
                effect: e.clone(),
                problem,
            })
        })?;
    }

    if truth.reference_temperature_celsius.is_none()
        && truth
            .effects
            .iter()
            .any(|e| matches!(e, Effect::Temperature { .. }))
    {
        return Err(mismatch(TruthError::NoReferenceTemperature));
    }
    for setup in 1..=config.setups {
        let shift = config.table_shift_of(setup);
        for step in 0..config.faces {
            let angle_deg = shift + step as f64 * 360.0 / config.faces as f64;
            if truth.encoder_error_at_deg(angle_deg).is_none() {
                return Err(mismatch(TruthError::NoEncoderErrorAt {
                    angle_deg,
                    setup,
                    step,
                }));
            }
        }
    }
    let elevation = match (&config.elevation, &truth.elevation) {
        (Some(model), Some(geometry)) => Some((model, geometry)),
        (Some(_), None) => return Err(mismatch(TruthError::NoElevation)),
        (None, _) => None,
    };
    let temperatures = config
        .temperature
        .as_ref()
        .map(|model| model.stop_temperatures(config));
    let mut student = match config.noise_student_dof {
        Some(nu) => {
            let chi_squared = ChiSquared::new(nu).map_err(|error| {
                SimulateError::Config(SimulationConfigError::StudentNoise { dof: nu, error })
            })?;
            let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
            rng.set_stream(STUDENT_STREAM);
            Some((nu, chi_squared, rng))
        }
        None => None,
    };
    let mut y_rng = ChaCha8Rng::seed_from_u64(config.seed);
    y_rng.set_stream(ELEVATION_NOISE_STREAM);

    let n = config.faces;
    let n_ac = config.ac_count() as u32;
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    rng.set_stream(NOISE_STREAM);
    let mut readings = Vec::with_capacity(config.reading_count());
    let stops_total = config.reading_count() / config.ac_count().max(1);
    for walk in &truth.random_walk {
        if walk.values_arcsec.len() != stops_total {
            return Err(mismatch(TruthError::RandomWalkLength {
                ac: walk.ac,
                len: walk.values_arcsec.len(),
                stops: stops_total,
            }));
        }
        if walk.ac == 0 || walk.ac > n_ac {
            return Err(mismatch(TruthError::RandomWalkAc {
                ac: walk.ac,
                acs: n_ac,
            }));
        }
    }
    let mut stop: usize = 0;
    for setup in 1..=config.setups {
        let shift = config.table_shift_of(setup);
        for Stop {
            cycle,
            step,
            direction,
        } in run_stops(n, config.cycles, config.closing, config.bidirectional)
        {
            let time = stop as f64 * config.step_seconds;
            let encoder = step as f64 * 360.0 / n as f64 + shift;
            let temperature = temperatures.as_ref().and_then(|t| t.get(stop).copied());
            for ac in 1..=n_ac {
                let face = config.face_at(setup, ac, step);
                let reading_y = elevation.map(|(model, geometry)| {
                    let z: f64 = StandardNormal.sample(&mut y_rng);
                    geometry.reading_y_at(setup, ac, step, face) + model.noise_arcsec * z
                });
                let mut reading = Reading {
                    setup,
                    cycle,
                    step,
                    ac,
                    face,
                    reading_arcsec: 0.0,
                    direction,
                    time_seconds: Some(time),
                    reading_y_arcsec: reading_y,
                    temperature_celsius: temperature,
                    encoder_degrees: Some(encoder),
                    line: 0,
                };
                let z: f64 = StandardNormal.sample(&mut rng);
                reading.reading_arcsec = match &mut student {
                    None => truth.model_reading_shifted(&reading, shift) + config.noise_arcsec * z,
                    Some((nu, chi_squared, chi_rng)) => {
                        let w: f64 = chi_squared.sample(chi_rng);
                        truth.model_reading_shifted(&reading, shift)
                            + config.noise_arcsec * z * ((*nu - 2.0) / w).sqrt()
                    }
                };
                reading.reading_arcsec += truth.random_walk_at(ac, stop);
                if config.no_time {
                    // the effects acted on the true time; the file has none
                    reading.time_seconds = None;
                }
                readings.push(reading);
            }
            stop += 1;
        }
    }
    // Every simulated reading obeys the rules of the file it will be written to (its
    // limits above all: a noise of 1e300″ is a valid setting with no valid reading).
    let mut set = MeasurementSet::from_readings(readings, Some(n), "simulated")
        .map_err(SimulateError::Readings)?;
    set.setup_shift_deg = (1..=config.setups)
        .map(|s| (s, config.table_shift_of(s)))
        .filter(|&(_, shift)| shift != 0.0)
        .collect();
    Ok(set)
}
