//! What a simulated run writes besides the X reading: the lab's air temperature (the
//! `temperature` column) and the autocollimators' elevation axis (the `reading_y`
//! column), docs/FORMAT.md §5.5.

use std::f64::consts::TAU;
use std::fmt;
use std::str::FromStr;

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use super::truth_file::TruthError;
use super::{SetupErrorTruth, SimulationConfig, TEMPERATURE_STREAM};
use crate::effects::{SpecError, SpecProblem};

/// Why the parameters of a [`TemperatureModel`] or an [`ElevationModel`] are refused (the
/// message leaves out the model's name).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelError {
    /// A parameter that must be finite is not.
    #[error("{parameter} is {value}; must be finite")]
    NotFinite {
        /// The parameter: `start`, `warm-up`, `cycle phase`, `wobble phase`.
        parameter: &'static str,
        /// Its value.
        value: f64,
    },
    /// A temperature that must be a finite number ≥ 0 (°C) is not.
    #[error("{parameter} is {value} °C; must be a finite number ≥ 0")]
    NotNonNegativeCelsius {
        /// The parameter: `cycle amplitude`, `noise`.
        parameter: &'static str,
        /// Its value, °C.
        value: f64,
    },
    /// A time that must be a finite number > 0 (seconds) is not.
    #[error("{parameter} is {value} s; must be a finite number > 0")]
    NotPositiveSeconds {
        /// The parameter: `warm-up time`, `cycle period`.
        parameter: &'static str,
        /// Its value, seconds.
        value: f64,
    },
    /// An angle that must be a finite number ≥ 0 (arcsec) is not.
    #[error("{parameter} is {value}″; must be a finite number ≥ 0")]
    NotNonNegativeArcsec {
        /// The parameter: `pyramidal spread`, `mounting tilt`, `wobble`, `offset spread`,
        /// `noise`.
        parameter: &'static str,
        /// Its value, arcsec.
        value: f64,
    },
}

/// The written form of a [`TemperatureModel`] or an [`ElevationModel`] that cannot be
/// read: not its numbers, or numbers that make no valid model.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ModelSpecError {
    /// Not the model's numbers separated by `:`.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// Numbers that make no valid model.
    #[error("{what} \"{spec}\": {problem} (expected {form})")]
    Invalid {
        /// The model: `temperature model`, `elevation model`.
        what: &'static str,
        /// The written form given.
        spec: String,
        /// Which parameter is wrong.
        problem: ModelError,
        /// The form expected, with an example.
        form: &'static str,
    },
}

/// The lab's air temperature during a simulated run, °C, at time t (seconds since the
/// start of the run):
///
/// ```text
/// T(t) = start_celsius
///      + warmup_celsius · (1 − exp(−t / warmup_seconds))                      slow warm-up
///      + cycle_amplitude_celsius · sin(2π·t / cycle_period_seconds + cycle_phase_rad)   air conditioning
///      + noise_celsius · z                                                     one z per stop
/// ```
///
/// The default is an air-conditioned lab: 20 °C, warming by 0.5 °C with a time constant
/// of one hour, the air conditioning cycling by ±0.1 °C every 20 minutes, no noise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct TemperatureModel {
    /// Temperature at time 0 (without the cycle and the noise), °C.
    pub start_celsius: f64,
    /// Total rise of the slow warm-up (negative: cooling), °C.
    pub warmup_celsius: f64,
    /// Time constant of the warm-up, seconds, > 0.
    pub warmup_seconds: f64,
    /// Amplitude of the air-conditioning cycle, °C, ≥ 0.
    pub cycle_amplitude_celsius: f64,
    /// Period of the air-conditioning cycle, seconds, > 0.
    pub cycle_period_seconds: f64,
    /// Phase of the air-conditioning cycle at time 0, radians.
    pub cycle_phase_rad: f64,
    /// Standard deviation of the white noise added at every stop, °C, ≥ 0.
    pub noise_celsius: f64,
}

impl Default for TemperatureModel {
    fn default() -> Self {
        TemperatureModel {
            start_celsius: 20.0,
            warmup_celsius: 0.5,
            warmup_seconds: 3600.0,
            cycle_amplitude_celsius: 0.1,
            cycle_period_seconds: 1200.0,
            cycle_phase_rad: 0.0,
            noise_celsius: 0.0,
        }
    }
}

impl TemperatureModel {
    /// The noise-free temperature at `time_seconds`, °C (the formula above without z).
    pub fn celsius_at(&self, time_seconds: f64) -> f64 {
        self.start_celsius
            + self.warmup_celsius * (1.0 - (-time_seconds / self.warmup_seconds).exp())
            + self.cycle_amplitude_celsius
                * (TAU * time_seconds / self.cycle_period_seconds + self.cycle_phase_rad).sin()
    }

    /// Checks the parameters; the error names the first bad one (without the model's name).
    pub(super) fn check(&self) -> Result<(), ModelError> {
        for (parameter, value) in [
            ("start", self.start_celsius),
            ("warm-up", self.warmup_celsius),
            ("cycle phase", self.cycle_phase_rad),
        ] {
            if !value.is_finite() {
                return Err(ModelError::NotFinite { parameter, value });
            }
        }
        for (parameter, value) in [
            ("cycle amplitude", self.cycle_amplitude_celsius),
            ("noise", self.noise_celsius),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ModelError::NotNonNegativeCelsius { parameter, value });
            }
        }
        for (parameter, value) in [
            ("warm-up time", self.warmup_seconds),
            ("cycle period", self.cycle_period_seconds),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(ModelError::NotPositiveSeconds { parameter, value });
            }
        }
        Ok(())
    }

    /// The temperature at every stop of `config`'s run, in time order (stop k at
    /// k·`step_seconds`), with the noise from stream [`TEMPERATURE_STREAM`] of the seed:
    /// one standard normal per stop, drawn even when the noise is 0.
    pub(super) fn stop_temperatures(&self, config: &SimulationConfig) -> Vec<f64> {
        let stops = (config.setups as usize)
            .saturating_mul(config.cycles as usize)
            .saturating_mul(config.stops_per_cycle());
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        rng.set_stream(TEMPERATURE_STREAM);
        (0..stops)
            .map(|k| {
                let z: f64 = StandardNormal.sample(&mut rng);
                self.celsius_at(k as f64 * config.step_seconds) + self.noise_celsius * z
            })
            .collect()
    }
}

impl FromStr for TemperatureModel {
    type Err = ModelSpecError;

    /// Parses `START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS[:PHASE[:NOISE]]`
    /// (°C, °C, s, °C, s, radians, °C), e.g. `20:0.5:3600:0.1:1200`; the phase and the
    /// noise default to 0. The numbers are checked as in [`SimulationConfig::validate`].
    fn from_str(s: &str) -> Result<TemperatureModel, ModelSpecError> {
        let form = "START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS[:PHASE[:NOISE]], \
                    e.g. 20:0.5:3600:0.1:1200";
        let v = numbers("temperature model", s, 5..=7, form)?;
        let model = TemperatureModel {
            start_celsius: v[0],
            warmup_celsius: v[1],
            warmup_seconds: v[2],
            cycle_amplitude_celsius: v[3],
            cycle_period_seconds: v[4],
            cycle_phase_rad: v.get(5).copied().unwrap_or(0.0),
            noise_celsius: v.get(6).copied().unwrap_or(0.0),
        };
        model.check().map_err(|problem| ModelSpecError::Invalid {
            what: "temperature model",
            spec: s.to_string(),
            problem,
            form,
        })?;
        Ok(model)
    }
}

impl fmt::Display for TemperatureModel {
    /// `START:WARMUP:WARMUP_SECONDS:AMPLITUDE:PERIOD_SECONDS:PHASE:NOISE`, readable back
    /// by [`TemperatureModel::from_str`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}:{}:{}:{}:{}",
            self.start_celsius,
            self.warmup_celsius,
            self.warmup_seconds,
            self.cycle_amplitude_celsius,
            self.cycle_period_seconds,
            self.cycle_phase_rad,
            self.noise_celsius
        )
    }
}

/// The elevation (Y) axis of the simulated autocollimators: what they write in
/// `reading_y`, arcsec. Autocollimator j reading face f at step p of setup s gives
///
/// ```text
/// reading_y = P[f]                                     pyramidal error of the face
///           + τ_s · cos(2π·(f − 1)/N − ψ_s)           tilt of the polygon in mounting s
///           + wobble_arcsec · cos(2π·p/N + wobble_phase_rad)   wobble of the table
///           + o[s, j]                                 zero of the Y axis in mounting s
///           + noise_arcsec · z
/// ```
///
/// with P\[f\] = `pyramidal_spread_arcsec`·z, τ_s = `mounting_tilt_arcsec`·z and ψ_s
/// uniform in \[0, 2π), o\[s, j\] = `offset_spread_arcsec`·z, all drawn once into the
/// truth ([`ElevationTruth`]), and a fresh z per reading for the noise.
///
/// The default gives tens of arcseconds: pyramidal spread 10″, mounting tilt 20″, wobble
/// 1″ at phase 0, offset spread 5″, noise 0.05″.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ElevationModel {
    /// Standard deviation of the drawn pyramidal errors of the faces, arcsec, ≥ 0.
    pub pyramidal_spread_arcsec: f64,
    /// Standard deviation of the drawn tilt amplitude τ_s of each mounting, arcsec, ≥ 0.
    pub mounting_tilt_arcsec: f64,
    /// Amplitude of the table's wobble, arcsec, ≥ 0.
    pub wobble_arcsec: f64,
    /// Phase of the table's wobble at step 0, radians.
    pub wobble_phase_rad: f64,
    /// Standard deviation of the drawn zero offsets o\[setup, ac\] of the Y axis, arcsec, ≥ 0.
    pub offset_spread_arcsec: f64,
    /// Standard deviation of the `reading_y` noise, arcsec, ≥ 0.
    pub noise_arcsec: f64,
}

impl Default for ElevationModel {
    fn default() -> Self {
        ElevationModel {
            pyramidal_spread_arcsec: 10.0,
            mounting_tilt_arcsec: 20.0,
            wobble_arcsec: 1.0,
            wobble_phase_rad: 0.0,
            offset_spread_arcsec: 5.0,
            noise_arcsec: 0.05,
        }
    }
}

impl ElevationModel {
    /// Checks the parameters; the error names the first bad one (without the model's name).
    pub(super) fn check(&self) -> Result<(), ModelError> {
        for (parameter, value) in [
            ("pyramidal spread", self.pyramidal_spread_arcsec),
            ("mounting tilt", self.mounting_tilt_arcsec),
            ("wobble", self.wobble_arcsec),
            ("offset spread", self.offset_spread_arcsec),
            ("noise", self.noise_arcsec),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(ModelError::NotNonNegativeArcsec { parameter, value });
            }
        }
        if !self.wobble_phase_rad.is_finite() {
            return Err(ModelError::NotFinite {
                parameter: "wobble phase",
                value: self.wobble_phase_rad,
            });
        }
        Ok(())
    }
}

impl FromStr for ElevationModel {
    type Err = ModelSpecError;

    /// Parses `PYRAMIDAL:TILT:WOBBLE:OFFSET:NOISE[:WOBBLE_PHASE]` (arcsec, the phase in
    /// radians, 0 when left out), e.g. `10:20:1:5:0.05`. The numbers are checked as in
    /// [`SimulationConfig::validate`].
    fn from_str(s: &str) -> Result<ElevationModel, ModelSpecError> {
        let form = "PYRAMIDAL:TILT:WOBBLE:OFFSET:NOISE[:WOBBLE_PHASE], e.g. 10:20:1:5:0.05";
        let v = numbers("elevation model", s, 5..=6, form)?;
        let model = ElevationModel {
            pyramidal_spread_arcsec: v[0],
            mounting_tilt_arcsec: v[1],
            wobble_arcsec: v[2],
            offset_spread_arcsec: v[3],
            noise_arcsec: v[4],
            wobble_phase_rad: v.get(5).copied().unwrap_or(0.0),
        };
        model.check().map_err(|problem| ModelSpecError::Invalid {
            what: "elevation model",
            spec: s.to_string(),
            problem,
            form,
        })?;
        Ok(model)
    }
}

impl fmt::Display for ElevationModel {
    /// `PYRAMIDAL:TILT:WOBBLE:OFFSET:NOISE:WOBBLE_PHASE`, readable back by
    /// [`ElevationModel::from_str`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}:{}:{}:{}:{}:{}",
            self.pyramidal_spread_arcsec,
            self.mounting_tilt_arcsec,
            self.wobble_arcsec,
            self.offset_spread_arcsec,
            self.noise_arcsec,
            self.wobble_phase_rad
        )
    }
}

/// `count` finite numbers separated by `:`, or an error naming `what`, the text, the
/// faulty part and the expected `form`.
fn numbers(
    what: &str,
    s: &str,
    count: std::ops::RangeInclusive<usize>,
    form: &'static str,
) -> Result<Vec<f64>, SpecError> {
    let at = |problem| SpecError::part(what, s, problem, form);
    let parts: Vec<&str> = s.split(':').map(str::trim).collect();
    if !count.contains(&parts.len()) {
        return Err(at(SpecProblem::part_count(
            parts.len(),
            format!("{} to {}", count.start(), count.end()),
        )));
    }
    parts
        .iter()
        .map(|text| match text.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(at(SpecProblem::NotFinite {
                part: None,
                text: text.to_string(),
            })),
        })
        .collect()
}

/// The tilt of the polygon on the table in one mounting: its face normals tip by
/// `tilt_arcsec`·cos(2π·(f − 1)/N − `azimuth_rad`) out of the measuring plane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MountingTilt {
    /// Setup (mounting) number, ≥ 1.
    pub setup: u32,
    /// Tilt amplitude τ_s, arcsec.
    pub tilt_arcsec: f64,
    /// Direction ψ_s of the tilt, radians.
    pub azimuth_rad: f64,
}

/// The true elevation-axis geometry of a simulated run (the truth's `elevation`,
/// docs/FORMAT.md §4); [`ElevationModel`] gives the formula.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ElevationTruth {
    /// Pyramidal errors P\[1\] … P\[N\] of the faces, arcsec.
    pub pyramidal_error_arcsec: Vec<f64>,
    /// The tilt of every mounting; one missing counts as no tilt.
    #[serde(default)]
    pub mounting_tilt: Vec<MountingTilt>,
    /// Amplitude of the table's wobble, arcsec.
    #[serde(default)]
    pub wobble_arcsec: f64,
    /// Phase of the table's wobble at step 0, radians.
    #[serde(default)]
    pub wobble_phase_rad: f64,
    /// Zero offsets o\[setup, ac\] of the Y axis, arcsec; one missing counts as 0.
    #[serde(default)]
    pub offset: Vec<SetupErrorTruth>,
    /// Standard deviation of the `reading_y` noise the run was made with, arcsec.
    #[serde(default)]
    pub noise_arcsec: f64,
}

impl ElevationTruth {
    /// Draws the geometry for `config` with `model`, from `rng`: N standard normals for
    /// the pyramidal errors of faces 1 … N, then for every setup one standard normal for
    /// τ_s and one uniform number u in \[0, 1) for ψ_s = 2π·u, then one standard normal per
    /// (setup, ac), setup 1's autocollimators 1, 2, … first. Draws are taken even when a
    /// spread is 0.
    pub(super) fn draw(
        config: &SimulationConfig,
        model: &ElevationModel,
        rng: &mut ChaCha8Rng,
    ) -> ElevationTruth {
        let pyramidal_error_arcsec = (0..config.faces)
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut *rng);
                model.pyramidal_spread_arcsec * z
            })
            .collect();
        let mounting_tilt = (1..=config.setups)
            .map(|setup| {
                let z: f64 = StandardNormal.sample(&mut *rng);
                let u: f64 = rng.random();
                MountingTilt {
                    setup,
                    tilt_arcsec: model.mounting_tilt_arcsec * z,
                    azimuth_rad: TAU * u,
                }
            })
            .collect();
        let mut offset = Vec::new();
        for setup in 1..=config.setups {
            for ac in 1..=config.ac_count() as u32 {
                let z: f64 = StandardNormal.sample(&mut *rng);
                offset.push(SetupErrorTruth {
                    setup,
                    ac,
                    value: model.offset_spread_arcsec * z,
                });
            }
        }
        ElevationTruth {
            pyramidal_error_arcsec,
            mounting_tilt,
            wobble_arcsec: model.wobble_arcsec,
            wobble_phase_rad: model.wobble_phase_rad,
            offset,
            noise_arcsec: model.noise_arcsec,
        }
    }

    /// The noise-free `reading_y` of autocollimator `ac` reading `face` (1 … N) at `step`
    /// of `setup`, arcsec (the formula of [`ElevationModel`] without the noise). NaN for a
    /// face outside 1 … N.
    pub fn reading_y_at(&self, setup: u32, ac: u32, step: usize, face: usize) -> f64 {
        let n = self.pyramidal_error_arcsec.len();
        let Some(&pyramidal) = face
            .checked_sub(1)
            .and_then(|i| self.pyramidal_error_arcsec.get(i))
        else {
            return f64::NAN;
        };
        let tilt = self
            .mounting_tilt
            .iter()
            .find(|t| t.setup == setup)
            .map_or(0.0, |t| {
                t.tilt_arcsec * (TAU * (face - 1) as f64 / n as f64 - t.azimuth_rad).cos()
            });
        let wobble =
            self.wobble_arcsec * (TAU * step as f64 / n as f64 + self.wobble_phase_rad).cos();
        let offset = self
            .offset
            .iter()
            .find(|o| o.setup == setup && o.ac == ac)
            .map_or(0.0, |o| o.value);
        pyramidal + tilt + wobble + offset
    }

    /// Checks the geometry for a polygon of `faces` faces; the error names the first problem.
    pub(super) fn check(&self, faces: usize) -> Result<(), TruthError> {
        if self.pyramidal_error_arcsec.len() != faces {
            return Err(TruthError::PyramidalLength {
                len: self.pyramidal_error_arcsec.len(),
                faces,
            });
        }
        if let Some(index) = self
            .pyramidal_error_arcsec
            .iter()
            .position(|v| !v.is_finite())
        {
            return Err(TruthError::PyramidalNotFinite { index });
        }
        let mut seen = std::collections::HashSet::new();
        for t in &self.mounting_tilt {
            let setup = t.setup;
            if setup == 0 {
                return Err(TruthError::TiltNumbering);
            }
            if !(t.tilt_arcsec.is_finite() && t.azimuth_rad.is_finite()) {
                return Err(TruthError::TiltNotFinite { setup });
            }
            if !seen.insert(setup) {
                return Err(TruthError::TiltTwice { setup });
            }
        }
        let mut seen = std::collections::HashSet::new();
        for &SetupErrorTruth { setup, ac, value } in &self.offset {
            if setup == 0 || ac == 0 {
                return Err(TruthError::OffsetNumbering { setup, ac });
            }
            if !value.is_finite() {
                return Err(TruthError::OffsetNotFinite { setup, ac });
            }
            if !seen.insert((setup, ac)) {
                return Err(TruthError::OffsetTwice { setup, ac });
            }
        }
        if !(self.wobble_arcsec.is_finite() && self.wobble_phase_rad.is_finite()) {
            return Err(TruthError::WobbleNotFinite);
        }
        if !(self.noise_arcsec.is_finite() && self.noise_arcsec >= 0.0) {
            return Err(TruthError::ElevationNoise {
                noise: self.noise_arcsec,
            });
        }
        Ok(())
    }
}
