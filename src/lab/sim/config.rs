//! The settings of a simulated lab.

use super::{DeviceId, Fault, PYRAMIDAL_SPREAD_ARCSEC};
use crate::lab::profile::Profile;
use crate::simulate::{SimulateError, SimulationConfig};

/// Settings of a simulated lab.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub struct LabConfig {
    /// The truth, noise, seed and run design (its `ac_faces` must have two entries).
    pub simulation: SimulationConfig,
    /// Table speed, degrees per second.
    pub speed_deg_per_s: f64,
    /// Extra time of a home search, seconds.
    pub home_seconds: f64,
    /// Factor on every simulated duration (0: instantaneous motion).
    pub time_scale: f64,
    /// Injected faults.
    pub faults: Vec<Fault>,
    /// The autocollimators' profile (`None`: the ELCOMAT 3000's own simulation).
    pub ac_profile: Option<Profile>,
    /// The table's profile (`None`: the SMC100's own simulation).
    pub table_profile: Option<Profile>,
}

impl Default for LabConfig {
    /// The simulator's defaults, 20°/s, 2 s home search, real time, no faults.
    fn default() -> Self {
        LabConfig::new(SimulationConfig::default())
    }
}

impl LabConfig {
    /// A lab measuring `simulation`'s truth (its `ac_faces` must have two entries), with a
    /// table of 20°/s, a 2 s home search, real time and no faults.
    pub fn new(simulation: SimulationConfig) -> LabConfig {
        LabConfig {
            simulation,
            speed_deg_per_s: 20.0,
            home_seconds: 2.0,
            time_scale: 1.0,
            faults: Vec::new(),
            ac_profile: None,
            table_profile: None,
        }
    }

    /// The autocollimators speak `profile` (an autocollimator's). The bundled
    /// `elcomat3000` keeps the ELCOMAT 3000's own simulation, written from its manual
    /// apart from the profile; any other is served from its profile.
    pub fn with_ac_profile(mut self, profile: Profile) -> LabConfig {
        self.ac_profile =
            (profile.name != "elcomat3000" || profile.autocollimator().is_err()).then_some(profile);
        self
    }

    /// The table speaks `profile` (a table's). The bundled `smc100` keeps the SMC100's
    /// own simulation; any other is served from its profile.
    pub fn with_table_profile(mut self, profile: Profile) -> LabConfig {
        self.table_profile =
            (profile.name != "smc100" || profile.table().is_err()).then_some(profile);
        self
    }

    /// Sets the table speed, degrees per second.
    pub fn with_speed_deg_per_s(mut self, speed_deg_per_s: f64) -> LabConfig {
        self.speed_deg_per_s = speed_deg_per_s;
        self
    }

    /// Sets the extra time of a home search, seconds.
    pub fn with_home_seconds(mut self, home_seconds: f64) -> LabConfig {
        self.home_seconds = home_seconds;
        self
    }

    /// Sets the factor on every simulated duration (0: instantaneous motion).
    pub fn with_time_scale(mut self, time_scale: f64) -> LabConfig {
        self.time_scale = time_scale;
        self
    }

    /// Sets the injected faults.
    pub fn with_faults(mut self, faults: Vec<Fault>) -> LabConfig {
        self.faults = faults;
        self
    }

    /// Checks the settings: the simulation's ([`SimulationConfig::validate`]), 2 … 16
    /// autocollimators, faults only on devices the lab has, a speed > 0, home time and time scale ≥ 0, and none
    /// of the run simulator's temperature model, elevation model or Student-t noise, which
    /// the lab does not simulate.
    ///
    /// # Errors
    ///
    /// [`LabSimError::Simulation`] for the simulation's settings, [`LabSimError::Config`]
    /// with the [`LabConfigError`] of the first problem of the lab's.
    pub fn validate(&self) -> Result<(), LabSimError> {
        self.simulation.validate()?;
        Ok(self.check()?)
    }

    fn check(&self) -> Result<(), LabConfigError> {
        let acs = self.simulation.ac_faces.len();
        if !(2..=16).contains(&acs) {
            return Err(LabConfigError::AutocollimatorCount {
                ac_faces: self.simulation.ac_faces.clone(),
            });
        }
        for &fault in &self.faults {
            if let DeviceId::Ac(ac) = fault.device
                && ac as usize > acs
            {
                return Err(LabConfigError::FaultOfMissingAc { fault, acs, ac });
            }
        }
        // The lab's instruments have no thermometer, their Y axis has its own model, and
        // their noise is normal: refuse what the run simulator has beyond that rather
        // than ignore it.
        if self.simulation.temperature.is_some() {
            return Err(LabConfigError::TemperatureModel);
        }
        if self.simulation.elevation.is_some() {
            return Err(LabConfigError::ElevationModel);
        }
        if self.simulation.noise_student_dof.is_some() {
            return Err(LabConfigError::StudentNoise);
        }
        if !self.simulation.rezero.is_empty() || !self.simulation.random_walk.is_empty() {
            return Err(LabConfigError::Habits);
        }
        if self.simulation.no_time {
            return Err(LabConfigError::NoTime);
        }
        if !(self.speed_deg_per_s.is_finite() && self.speed_deg_per_s > 0.0) {
            return Err(LabConfigError::Speed {
                deg_per_s: self.speed_deg_per_s,
            });
        }
        for (what, value) in [
            ("home time", self.home_seconds),
            ("time scale", self.time_scale),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(LabConfigError::NotNonNegative { what, value });
            }
        }
        Ok(())
    }

    pub(super) fn faults_of(&self, device: DeviceId) -> Vec<Fault> {
        self.faults
            .iter()
            .copied()
            .filter(|f| f.device == device)
            .collect()
    }
}

/// Why a simulated lab cannot be set up: its simulation's settings or truth, or its own
/// settings.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum LabSimError {
    /// The simulation's settings ([`SimulationConfig::validate`]) or truth are refused.
    #[error(transparent)]
    Simulation(#[from] SimulateError),
    /// The lab's own settings are refused.
    #[error("invalid simulation settings: {0}")]
    Config(#[from] LabConfigError),
}

/// Why the settings of a simulated lab ([`LabConfig`]) are refused, beyond those of its
/// simulation ([`SimulationConfig::validate`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LabConfigError {
    /// Not 2 to 16 autocollimators.
    #[error("the lab has 2 to 16 autocollimators; ac faces {ac_faces:?} name {}", ac_faces.len())]
    AutocollimatorCount {
        /// The faces the autocollimators read at step 0, one per autocollimator.
        ac_faces: Vec<usize>,
    },
    /// A fault of an autocollimator the lab does not have.
    #[error("fault {fault}: the lab has {acs} autocollimators, not an ac{ac}")]
    FaultOfMissingAc {
        /// The fault.
        fault: Fault,
        /// The lab's number of autocollimators.
        acs: usize,
        /// The autocollimator the fault names.
        ac: u32,
    },
    /// A temperature model: the lab's instruments report no temperature.
    #[error("the simulated lab has no temperature model (its instruments report no temperature)")]
    TemperatureModel,
    /// An elevation model: the lab's Y axis has its own.
    #[error(
        "the simulated lab has no elevation model (its Y axis is a pyramidal error of spread \
         {PYRAMIDAL_SPREAD_ARCSEC}″ plus noise)"
    )]
    ElevationModel,
    /// Student-t noise: the lab's noise is normal.
    #[error("the simulated lab's noise is normal (no Student-t noise)")]
    StudentNoise,
    /// Re-zeroing or wandering zeros.
    #[error(
        "the simulated lab's zeros neither re-zero every cycle nor wander (simulate a run \
         with them instead)"
    )]
    Habits,
    /// A run without the time of its readings.
    #[error("a run in the simulated lab always records the time of every reading")]
    NoTime,
    /// A table speed that is not a finite number > 0.
    #[error("speed {deg_per_s} °/s must be a finite number > 0")]
    Speed {
        /// The speed, degrees per second.
        deg_per_s: f64,
    },
    /// A home time or time scale that is not a finite number ≥ 0.
    #[error("{what} {value} must be a finite number ≥ 0")]
    NotNonNegative {
        /// Which: `home time`, `time scale`.
        what: &'static str,
        /// Its value.
        value: f64,
    },
}
