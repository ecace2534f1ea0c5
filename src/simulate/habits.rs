//! Habits of real labs that nobody declares, for simulated runs: an autocollimator
//! zeroed anew at the start of every cycle (`rezero`), and a zero that wanders (a random
//! walk). Both are drawn into the truth from streams of their own, so that a run with
//! them has the very truth and noise of its clean twin (the same settings without them).

use std::fmt;
use std::str::FromStr;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::SimulationConfig;
use crate::effects::{Effect, SpecError, SpecProblem, number_from_1};

/// ChaCha stream of the `rezero` offsets (one standard normal per cycle of every setup,
/// for each `--rezero` in the order given).
pub(super) const REZERO_STREAM: u64 = 6;
/// ChaCha stream of the random walks (one standard normal per stop of the run, for each
/// `--random-walk` in the order given).
pub(super) const RANDOM_WALK_STREAM: u64 = 7;

/// An autocollimator zeroed anew at the start of every cycle: its zero in each cycle
/// (of each setup) is offset by a normal draw of standard deviation `sigma_arcsec`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RezeroSpec {
    /// Autocollimator number (≥ 1).
    pub ac: u32,
    /// Standard deviation of the offset of each cycle, arcsec, ≥ 0.
    pub sigma_arcsec: f64,
}

/// A zero that wanders: a random walk (Brownian motion) of the autocollimator's zero,
/// with standard deviation `rate_arcsec_per_sqrt_h`·√(Δt in hours) between consecutive
/// stops, 0 at the run's first stop and continuing across cycles and setups.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RandomWalkSpec {
    /// Autocollimator number (≥ 1).
    pub ac: u32,
    /// Rate, arcsec per √hour, ≥ 0.
    pub rate_arcsec_per_sqrt_h: f64,
}

/// The walk a simulated run's autocollimator zero took: its value at every stop of the
/// run, in the run's order (setup 1's stops first), arcsec.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RandomWalkTruth {
    /// Autocollimator number (≥ 1).
    pub ac: u32,
    /// The rate it was drawn with, arcsec per √hour.
    pub rate_arcsec_per_sqrt_h: f64,
    /// The walk at every stop of the run, arcsec.
    pub values_arcsec: Vec<f64>,
}

/// Parses `AC:VALUE` with AC ≥ 1 and a finite VALUE ≥ 0.
fn ac_and_value(what: &str, s: &str) -> Result<(u32, f64), SpecError> {
    let at = |problem| SpecError::part(what, s, problem, "AC:VALUE, e.g. 1:0.25");
    let parts: Vec<&str> = s.split(':').map(str::trim).collect();
    if parts.len() != 2 {
        return Err(at(SpecProblem::part_count(parts.len(), "2")));
    }
    let ac = number_from_1("AC", parts[0]).map_err(at)?;
    let value = match parts[1].parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => v,
        _ => {
            return Err(at(SpecProblem::NotNonNegative {
                text: parts[1].to_string(),
            }));
        }
    };
    Ok((ac, value))
}

impl FromStr for RezeroSpec {
    type Err = SpecError;

    /// Parses `AC:SIGMA` (arcsec), e.g. `1:0.3`.
    fn from_str(s: &str) -> Result<Self, SpecError> {
        let (ac, sigma_arcsec) = ac_and_value("rezero", s)?;
        Ok(RezeroSpec { ac, sigma_arcsec })
    }
}

impl FromStr for RandomWalkSpec {
    type Err = SpecError;

    /// Parses `AC:RATE_PER_SQRT_H` (arcsec per √hour), e.g. `1:0.25`.
    fn from_str(s: &str) -> Result<Self, SpecError> {
        let (ac, rate_arcsec_per_sqrt_h) = ac_and_value("random walk", s)?;
        Ok(RandomWalkSpec {
            ac,
            rate_arcsec_per_sqrt_h,
        })
    }
}

impl fmt::Display for RezeroSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.ac, self.sigma_arcsec)
    }
}

impl fmt::Display for RandomWalkSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}", self.ac, self.rate_arcsec_per_sqrt_h)
    }
}

/// Why a habit of a simulated run (`rezero`, `random walk`) is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum HabitError {
    /// A habit of an autocollimator the run does not have.
    #[error("{habit} {ac}:{value}: no autocollimator {ac}; the run has 1 … {acs}")]
    NoAutocollimator {
        /// The habit: `rezero` or `random walk`.
        habit: &'static str,
        /// Its autocollimator.
        ac: u32,
        /// Its value (σ, or rate).
        value: f64,
        /// The run's number of autocollimators.
        acs: usize,
    },
    /// A σ or rate that is not a finite number ≥ 0.
    #[error("{habit} {ac}:{value}: {value} is not a finite number ≥ 0")]
    NotNonNegative {
        /// The habit: `rezero` or `random walk`.
        habit: &'static str,
        /// Its autocollimator.
        ac: u32,
        /// Its value (σ, or rate).
        value: f64,
    },
}

/// Checks the habits of a configuration: autocollimators that exist, finite values ≥ 0.
pub(super) fn check(config: &SimulationConfig) -> Result<(), HabitError> {
    let acs = config.ac_count();
    let habits = config
        .rezero
        .iter()
        .map(|r| ("rezero", r.ac, r.sigma_arcsec))
        .chain(
            config
                .random_walk
                .iter()
                .map(|w| ("random walk", w.ac, w.rate_arcsec_per_sqrt_h)),
        );
    for (habit, ac, value) in habits {
        if ac == 0 || ac as usize > acs {
            return Err(HabitError::NoAutocollimator {
                habit,
                ac,
                value,
                acs,
            });
        }
        if !(value.is_finite() && value >= 0.0) {
            return Err(HabitError::NotNonNegative { habit, ac, value });
        }
    }
    Ok(())
}

/// The `rezero` effects of a configuration, drawn: one per `--rezero` (one per setup and
/// `--rezero` when the run has several setups), its offsets `sigma`·z per cycle.
pub(super) fn draw_rezero(config: &SimulationConfig) -> Vec<Effect> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    rng.set_stream(REZERO_STREAM);
    let mut effects = Vec::new();
    for spec in &config.rezero {
        for setup in 1..=config.setups {
            let offsets: Vec<f64> = (0..config.cycles)
                .map(|_| {
                    let z: f64 = StandardNormal.sample(&mut rng);
                    spec.sigma_arcsec * z
                })
                .collect();
            let setup = (config.setups > 1).then_some(setup);
            effects.push(Effect::rezero(spec.ac, setup, offsets));
        }
    }
    effects
}

/// The random walks of a configuration, drawn over its stops (`stops` of
/// `config.step_seconds` each).
pub(super) fn draw_random_walks(config: &SimulationConfig, stops: usize) -> Vec<RandomWalkTruth> {
    let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
    rng.set_stream(RANDOM_WALK_STREAM);
    let step_hours = config.step_seconds / 3600.0;
    config
        .random_walk
        .iter()
        .map(|spec| {
            let mut walk = 0.0;
            let values_arcsec = (0..stops)
                .map(|k| {
                    if k > 0 {
                        let z: f64 = StandardNormal.sample(&mut rng);
                        walk += spec.rate_arcsec_per_sqrt_h * step_hours.sqrt() * z;
                    }
                    walk
                })
                .collect();
            RandomWalkTruth {
                ac: spec.ac,
                rate_arcsec_per_sqrt_h: spec.rate_arcsec_per_sqrt_h,
                values_arcsec,
            }
        })
        .collect()
}
