//! The settings of a simulated run: design, true-value spreads, noise, effects and seed.

use std::collections::HashSet;

use serde::{Deserialize, Serialize};

use super::SimulateError;
use super::habits::HabitError;
pub use super::harmonic::{Harmonic, HarmonicError};
use super::models::{ElevationModel, ModelError, TemperatureModel};
use super::run_effect::{RunEffectError, effect_json};
use crate::effects::Effect;

/// Largest number of readings a simulated run may have (a guard against absurd settings).
pub const MAX_READINGS: usize = 50_000_000;

/// Settings of a simulated run.
///
/// The design: `faces` N, the autocollimators (`ac_faces[j-1]` is the face autocollimator
/// j reads at step 0 of setup 1), `setups` mountings of the polygon, each turned by
/// `setup_shift_faces` faces against the previous one, `cycles` repeats per setup, with
/// or without the `closing` reading at step N, and optionally `bidirectional`.
///
/// The truth: pitch deviations drawn with spread `pitch_spread_arcsec`, the encoder error
/// made of `encoder_harmonics`, setup errors drawn with spread
/// `setup_error_spread_arcsec`, and `effects`. The readings: noise of standard deviation
/// `noise_arcsec` (normal, or Student's t with `noise_student_dof` degrees of freedom),
/// one stop every `step_seconds`, with the lab's air temperature when there is a
/// `temperature` model and the elevation axis when there is an `elevation` model.
/// Everything random comes from `seed`.
///
/// At step p of setup s, autocollimator j reads face
/// `((ac_faces[j-1] − 1) + (s − 1)·setup_shift_faces + p) mod N + 1`, and the table
/// stands at `table_shift_deg[s-1]` + p·360°/N (at p·360°/N when `table_shift_deg` is
/// empty).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct SimulationConfig {
    /// Number of polygon faces N (= encoder positions), ≥ 3.
    pub faces: usize,
    /// Face read by each autocollimator at step 0 of setup 1 (1 … N, distinct); its
    /// length is the number of autocollimators. The paper's design is `[1, 2]`.
    pub ac_faces: Vec<usize>,
    /// Number of mountings of the polygon, ≥ 1, measured one after the other.
    pub setups: u32,
    /// Whole-face shift of the polygon between consecutive setups, 0 … N−1.
    pub setup_shift_faces: usize,
    /// The table's angle at step 0 of each setup, degrees, 0 ≤ shift < 360 (the `shift`
    /// column, docs/FORMAT.md §2, §9.1): empty, every setup at 0; else one per setup,
    /// setup 1 first. A shift that is not a whole multiple of 360°/N puts the mounting's
    /// stops, and the encoder errors it reads, between the N positions.
    pub table_shift_deg: Vec<f64>,
    /// Number of cycles per setup, ≥ 1.
    pub cycles: u32,
    /// Whether clockwise cycles end with the closing reading at step N.
    pub closing: bool,
    /// Whether every second cycle (2, 4, …) runs counter-clockwise, steps N … 0 (the
    /// closing reading is then taken in every cycle).
    pub bidirectional: bool,
    /// Standard deviation of the reading noise, arcsec, ≥ 0.
    pub noise_arcsec: f64,
    /// Standard deviation of the drawn pitch deviations, arcsec, ≥ 0.
    pub pitch_spread_arcsec: f64,
    /// Harmonics making up the true encoder error (its mean is removed).
    pub encoder_harmonics: Vec<Harmonic>,
    /// Standard deviation of the drawn setup errors, arcsec, ≥ 0.
    pub setup_error_spread_arcsec: f64,
    /// Time between consecutive stops, seconds, > 0.
    pub step_seconds: f64,
    /// Effects added to the readings (docs/FORMAT.md §6).
    pub effects: Vec<Effect>,
    /// Seed of the random draws.
    pub seed: u64,
    /// The lab's air temperature, written to the `temperature` column of every reading;
    /// `None`: no temperature column. A `temperature` effect needs it.
    pub temperature: Option<TemperatureModel>,
    /// The elevation axis, written to the `reading_y` column of every reading; `None`: no
    /// `reading_y` column. A `cross-talk` effect needs it.
    pub elevation: Option<ElevationModel>,
    /// Degrees of freedom ν (> 2) of Student-t reading noise; `None`: normal noise. The
    /// noise keeps the standard deviation `noise_arcsec`: a t variate scaled by
    /// `noise_arcsec`·√((ν − 2)/ν).
    pub noise_student_dof: Option<f64>,
    /// Autocollimators zeroed anew at the start of every cycle (`simulate --rezero`): the
    /// offsets are drawn into the truth's effects as `rezero` effects.
    pub rezero: Vec<super::RezeroSpec>,
    /// Autocollimator zeros that wander (`simulate --random-walk`): the walks are drawn
    /// into the truth's `random_walk`.
    pub random_walk: Vec<super::RandomWalkSpec>,
    /// Whether the written readings leave out `time` (`simulate --no-time`; effects
    /// still act on the true time).
    pub no_time: bool,
}

impl Default for SimulationConfig {
    /// The paper's design: 24 faces, autocollimators on faces 1 and 2, one setup, 6
    /// clockwise cycles with closing reading, noise 0.05″, pitch spread 0.5″, an encoder
    /// error of about ±1″ (harmonics 1:0.6:0.4, 2:0.35:1.3, 3:0.2:2.2, 5:0.1:0.7), setup
    /// spread 0.5″, 20 s per stop, no effects, seed 1; normal noise, no temperature and no
    /// elevation model.
    fn default() -> Self {
        let h = |order, amplitude_arcsec, phase_rad| Harmonic {
            order,
            amplitude_arcsec,
            phase_rad,
        };
        SimulationConfig {
            faces: 24,
            ac_faces: vec![1, 2],
            setups: 1,
            setup_shift_faces: 1,
            table_shift_deg: Vec::new(),
            cycles: 6,
            closing: true,
            bidirectional: false,
            noise_arcsec: 0.05,
            pitch_spread_arcsec: 0.5,
            encoder_harmonics: vec![
                h(1, 0.6, 0.4),
                h(2, 0.35, 1.3),
                h(3, 0.2, 2.2),
                h(5, 0.1, 0.7),
            ],
            setup_error_spread_arcsec: 0.5,
            step_seconds: 20.0,
            effects: Vec::new(),
            seed: 1,
            temperature: None,
            elevation: None,
            noise_student_dof: None,
            rezero: Vec::new(),
            random_walk: Vec::new(),
            no_time: false,
        }
    }
}

impl SimulationConfig {
    /// Number of autocollimators (`ac_faces.len()`).
    pub fn ac_count(&self) -> usize {
        self.ac_faces.len()
    }

    /// Whether the closing reading (step N) is taken in every cycle.
    pub fn has_closing(&self) -> bool {
        self.closing || self.bidirectional
    }

    /// Stops per cycle: N + 1 with the closing reading, else N.
    pub fn stops_per_cycle(&self) -> usize {
        if self.has_closing() {
            self.faces + 1
        } else {
            self.faces
        }
    }

    /// Number of readings of the run: setups · cycles · stops per cycle · autocollimators.
    pub fn reading_count(&self) -> usize {
        (self.setups as usize)
            .saturating_mul(self.cycles as usize)
            .saturating_mul(self.stops_per_cycle())
            .saturating_mul(self.ac_count())
    }

    /// The face autocollimator `ac` (1-based) reads at `step` of `setup` (1-based):
    /// `((ac_faces[ac-1] − 1) + (setup − 1)·setup_shift_faces + step) mod N + 1`.
    /// Call on a valid configuration only ([`SimulationConfig::validate`]); returns 0 for an
    /// autocollimator that does not exist.
    pub fn face_at(&self, setup: u32, ac: u32, step: usize) -> usize {
        let n = self.faces;
        let Some(&f0) = (ac as usize)
            .checked_sub(1)
            .and_then(|j| self.ac_faces.get(j))
        else {
            return 0;
        };
        let shift = ((setup.saturating_sub(1) as usize) % n) * (self.setup_shift_faces % n) % n;
        crate::measurement::face_at(step, ((f0 + n - 1) % n + shift) % n, n)
    }

    /// The table's angle at step 0 of `setup` (1-based), degrees: `table_shift_deg[setup-1]`,
    /// 0 when the list is empty (or does not reach that setup).
    pub fn table_shift_of(&self, setup: u32) -> f64 {
        (setup as usize)
            .checked_sub(1)
            .and_then(|i| self.table_shift_deg.get(i))
            .copied()
            .unwrap_or(0.0)
    }

    /// The comment line `polycal simulate` writes at the head of the measurement CSV:
    /// the version, the design, the noise and the seed, and the table shifts, Student-t
    /// noise and the temperature and elevation models when there are any. The CLI and the
    /// Python package write the same line, so that one run is the same file from both.
    pub fn comment(&self) -> String {
        let mut comment = format!(
            "polycal {} simulate: {} faces, ac faces {:?}, {} cycles, noise {} arcsec, seed {}",
            crate::SOFTWARE_VERSION,
            self.faces,
            self.ac_faces,
            self.cycles,
            self.noise_arcsec,
            self.seed
        );
        if !self.table_shift_deg.is_empty() {
            comment += &format!(", table shifts {:?} degrees", self.table_shift_deg);
        }
        if let Some(nu) = self.noise_student_dof {
            comment += &format!(", Student-t noise with {nu} dof");
        }
        if let Some(model) = &self.temperature {
            comment += &format!(", temperature {model}");
        }
        if let Some(model) = &self.elevation {
            comment += &format!(", elevation {model}");
        }
        comment
    }

    /// Checks the settings; the error names the first problem found.
    ///
    /// Refused: faces < 3; no autocollimator, a face outside 1 … N or the same face twice
    /// in `ac_faces`; setups or cycles 0; a shift ≥ N; table shifts that are not one per
    /// setup or not finite in 0 ≤ shift < 360; a negative or non-finite spread or
    /// noise; a step time that is not positive and finite; a harmonic of order 0 or with
    /// a non-finite number; a run of more than [`MAX_READINGS`] readings; Student-t
    /// degrees of freedom that are not a finite number > 2; a temperature or elevation
    /// model with a non-finite number, a negative amplitude, spread or noise, or a time
    /// constant or period that is not > 0; an effect that is not finite (value, or a
    /// drift's `quadratic`) or names an autocollimator, setup, cycle or step the run does
    /// not have, a direction effect without `bidirectional`, an outlier without a setup
    /// when there are several setups, a temperature effect without a temperature model
    /// and a cross-talk effect without an elevation model.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Config`] with the [`SimulationConfigError`] of the first problem.
    pub fn validate(&self) -> Result<(), SimulateError> {
        self.check().map_err(SimulateError::Config)
    }

    fn check(&self) -> Result<(), SimulationConfigError> {
        use SimulationConfigError as E;
        let n = self.faces;
        if n < 3 {
            return Err(E::TooFewFaces { faces: n });
        }
        if self.ac_faces.is_empty() {
            return Err(E::NoAutocollimator);
        }
        let mut seen = HashSet::new();
        for (j, &face) in self.ac_faces.iter().enumerate() {
            let ac = j + 1;
            if !(1..=n).contains(&face) {
                return Err(E::AcFaceOutOfRange { ac, face, faces: n });
            }
            if !seen.insert(face) {
                return Err(E::AcFaceTwice { ac, face });
            }
        }
        if self.setups == 0 {
            return Err(E::NoSetups);
        }
        if self.setup_shift_faces >= n {
            return Err(E::SetupShift {
                shift_faces: self.setup_shift_faces,
                faces: n,
            });
        }
        if !self.table_shift_deg.is_empty() {
            if self.table_shift_deg.len() != self.setups as usize {
                return Err(E::TableShiftCount {
                    shifts: self.table_shift_deg.len(),
                    setups: self.setups,
                });
            }
            for (i, &shift_deg) in self.table_shift_deg.iter().enumerate() {
                if !(shift_deg.is_finite() && (0.0..360.0).contains(&shift_deg)) {
                    return Err(E::TableShift {
                        shift_deg,
                        setup: i + 1,
                    });
                }
            }
        }
        if self.cycles == 0 {
            return Err(E::NoCycles);
        }
        for (what, value) in [
            ("noise", self.noise_arcsec),
            ("pitch spread", self.pitch_spread_arcsec),
            ("setup error spread", self.setup_error_spread_arcsec),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(E::NotNonNegative { what, value });
            }
        }
        if !(self.step_seconds.is_finite() && self.step_seconds > 0.0) {
            return Err(E::StepSeconds {
                seconds: self.step_seconds,
            });
        }
        for h in &self.encoder_harmonics {
            h.check()?;
        }
        if let Some(dof) = self.noise_student_dof
            && !(dof.is_finite() && dof > 2.0)
        {
            return Err(E::StudentDof { dof });
        }
        if let Some(model) = &self.temperature {
            model.check().map_err(E::Temperature)?;
        }
        if let Some(model) = &self.elevation {
            model.check().map_err(E::Elevation)?;
        }
        super::habits::check(self)?;
        let readings = self.reading_count();
        if readings > MAX_READINGS {
            return Err(E::TooManyReadings { readings });
        }
        for e in &self.effects {
            self.check_effect(e).map_err(|problem| E::Effect {
                effect: e.clone(),
                problem,
            })?;
        }
        Ok(())
    }

    /// Checks that an effect is finite, names only things this run has, and has the model
    /// it acts through (temperature, elevation).
    pub(super) fn check_effect(&self, e: &Effect) -> Result<(), RunEffectError> {
        use RunEffectError as E;
        if !e.value().is_finite() {
            return Err(E::ValueNotFinite);
        }
        let acs = self.ac_count();
        let check_ac = |ac: u32| {
            if ac == 0 || ac as usize > acs {
                Err(E::NoAutocollimator { ac, acs })
            } else {
                Ok(())
            }
        };
        let check_cycle = |cycle: u32| {
            if cycle == 0 || cycle > self.cycles {
                Err(E::NoCycle {
                    cycle,
                    cycles: self.cycles,
                })
            } else {
                Ok(())
            }
        };
        let check_step = |step: usize| {
            let last = self.stops_per_cycle() - 1;
            if step > last {
                Err(E::NoStep { step, last })
            } else {
                Ok(())
            }
        };
        let check_setup = |setup: u32| {
            if setup == 0 || setup > self.setups {
                Err(E::NoSetup {
                    setup,
                    setups: self.setups,
                })
            } else {
                Ok(())
            }
        };
        match *e {
            Effect::Rezero {
                ac,
                setup,
                ref offsets,
                ..
            } => {
                check_ac(ac)?;
                if let Some(s) = setup {
                    check_setup(s)?;
                }
                if offsets.iter().any(|o| !o.is_finite()) {
                    return Err(E::OffsetNotFinite);
                }
                Ok(())
            }
            Effect::Drift { ac, quadratic, .. } => {
                check_ac(ac)?;
                match quadratic {
                    Some(q) if !q.is_finite() => Err(E::QuadraticNotFinite),
                    _ => Ok(()),
                }
            }
            Effect::Temperature { ac, .. } => {
                check_ac(ac)?;
                if self.temperature.is_none() {
                    return Err(E::NoTemperatureModel);
                }
                Ok(())
            }
            Effect::CrossTalk { ac, .. } => {
                check_ac(ac)?;
                if self.elevation.is_none() {
                    return Err(E::NoElevationModel);
                }
                Ok(())
            }
            Effect::OffsetStep {
                ac,
                cycle,
                step,
                setup,
                ..
            } => {
                check_ac(ac)?;
                check_cycle(cycle)?;
                if let Some(step) = step {
                    check_step(step)?;
                }
                if let Some(s) = setup {
                    check_setup(s)?;
                }
                Ok(())
            }
            Effect::Direction { ac, .. } => {
                if let Some(ac) = ac {
                    check_ac(ac)?;
                }
                if !self.bidirectional || self.cycles < 2 {
                    return Err(E::NoCounterClockwiseCycle);
                }
                Ok(())
            }
            Effect::Outlier {
                cycle,
                step,
                ac,
                setup,
                ..
            } => {
                check_ac(ac)?;
                check_cycle(cycle)?;
                check_step(step)?;
                match setup {
                    Some(s) => check_setup(s),
                    None if self.setups > 1 => Err(E::OutlierSetupUnnamed {
                        setups: self.setups,
                    }),
                    _ => Ok(()),
                }
            }
        }
    }
}

/// Why the settings of a simulated polygon run ([`SimulationConfig`]) are refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SimulationConfigError {
    /// Fewer than 3 faces.
    #[error("faces is {faces}; a polygon needs at least 3 faces")]
    TooFewFaces {
        /// The number of faces.
        faces: usize,
    },
    /// No autocollimator.
    #[error("no autocollimator (ac_faces is empty)")]
    NoAutocollimator,
    /// An autocollimator reading a face the polygon does not have.
    #[error("autocollimator {ac} reads face {face} at step 0, outside 1 … {faces}")]
    AcFaceOutOfRange {
        /// The autocollimator.
        ac: usize,
        /// The face it reads at step 0.
        face: usize,
        /// The number of faces.
        faces: usize,
    },
    /// Two autocollimators reading the same face.
    #[error("autocollimator {ac} reads face {face} at step 0, like an earlier one")]
    AcFaceTwice {
        /// The later autocollimator.
        ac: usize,
        /// The face.
        face: usize,
    },
    /// No setup.
    #[error("setups is 0; need at least 1")]
    NoSetups,
    /// A shift between setups of N faces or more.
    #[error("setup shift of {shift_faces} faces; must be 0 … {}", faces - 1)]
    SetupShift {
        /// The shift, faces.
        shift_faces: usize,
        /// The number of faces.
        faces: usize,
    },
    /// Table shifts that are not one per setup.
    #[error("{shifts} table shift(s) for {setups} setup(s); give one per setup")]
    TableShiftCount {
        /// The number of table shifts.
        shifts: usize,
        /// The number of setups.
        setups: u32,
    },
    /// A table shift that is not a finite angle in [0°, 360°).
    #[error("table shift {shift_deg}° of setup {setup}; must be a finite angle, 0 ≤ shift < 360")]
    TableShift {
        /// The shift, degrees.
        shift_deg: f64,
        /// Its setup.
        setup: usize,
    },
    /// No cycle.
    #[error("cycles is 0; need at least 1")]
    NoCycles,
    /// A noise or spread that is not a finite number ≥ 0.
    #[error("{what} is {value}; must be a finite number ≥ 0")]
    NotNonNegative {
        /// Which: `noise`, `pitch spread`, `setup error spread`.
        what: &'static str,
        /// Its value, arcsec.
        value: f64,
    },
    /// A step time that is not a finite number > 0.
    #[error("step time is {seconds} s; must be a finite number > 0")]
    StepSeconds {
        /// The step time, seconds.
        seconds: f64,
    },
    /// An encoder harmonic of order 0, or not finite.
    #[error(transparent)]
    Harmonic(#[from] HarmonicError),
    /// Student-t degrees of freedom that are not a finite number > 2.
    #[error(
        "Student-t noise with {dof} degrees of freedom; must be a finite number > 2 \
         (the variance is infinite below)"
    )]
    StudentDof {
        /// The degrees of freedom.
        dof: f64,
    },
    /// Student-t degrees of freedom the chi-squared distribution refuses.
    #[error("Student-t noise with {dof} degrees of freedom: {error}")]
    StudentNoise {
        /// The degrees of freedom.
        dof: f64,
        /// The distribution's refusal.
        error: rand_distr::ChiSquaredError,
    },
    /// An invalid temperature model.
    #[error("temperature model: {0}")]
    Temperature(ModelError),
    /// An invalid elevation model.
    #[error("elevation model: {0}")]
    Elevation(ModelError),
    /// An invalid habit (`rezero`, `random walk`).
    #[error(transparent)]
    Habit(#[from] HabitError),
    /// A run of more than [`MAX_READINGS`] readings.
    #[error("the run would have {readings} readings, more than {MAX_READINGS}")]
    TooManyReadings {
        /// The number of readings.
        readings: usize,
    },
    /// An effect that does not fit the run.
    #[error("effect {}: {problem}", effect_json(effect))]
    Effect {
        /// The effect.
        effect: Effect,
        /// Why it does not fit.
        problem: RunEffectError,
    },
}
