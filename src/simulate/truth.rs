//! The true values behind a simulated run, and the truth file (docs/FORMAT.md §4).

use std::collections::HashSet;
use std::path::Path;

use crate::input::limits::READING_ARCSEC;

use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use serde::{Deserialize, Serialize};

use super::models::ElevationTruth;
use super::truth_file::{self, TruthError, TruthJson};
use super::{ELEVATION_TRUTH_STREAM, SimulateError, SimulationConfig, TRUTH_STREAM};
use crate::effects::{Effect, EffectContext};
use crate::measurement::Reading;
use crate::polygon::face_deviation_from_pitch;
use crate::results::Quantity;
use crate::solve::sub_pitch::{POSITION_TOLERANCE, ShiftGeometry};

/// The true setup error `U[setup, ac]` of one autocollimator in one mounting, in the
/// generic gauge of docs/FORMAT.md §1.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SetupErrorTruth {
    /// Setup (mounting) number, ≥ 1.
    pub setup: u32,
    /// Autocollimator number, ≥ 1.
    pub ac: u32,
    /// Setup error, arcsec.
    pub value: f64,
}

/// The true values of a simulated run: the truth file of docs/FORMAT.md §4.
///
/// `pitch_deviation[k-1]` is β\[k\], `encoder_error[p]` is α\[p\] and `face_deviation[f-1]`
/// is φ\[f\] = β\[1\] + … + β\[f\]. Only `faces`, `pitch_deviation` and `encoder_error` are
/// required in a file; the rest default to empty (no setup errors, no effects).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    /// Number of faces N.
    pub faces: usize,
    /// Pitch deviations β\[1\] … β\[N\], arcsec.
    pub pitch_deviation: Vec<f64>,
    /// Encoder errors α\[0\] … α\[N−1\], arcsec; with `encoder_angle_deg`, one per angle.
    pub encoder_error: Vec<f64>,
    /// Only for a run with sub-pitch mountings (docs/FORMAT.md §9.1): the table angle of
    /// each `encoder_error`, degrees, ascending: every table angle of every coset the
    /// mountings stop at. `None`: `encoder_error[p]` is at p·360°/N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub encoder_angle_deg: Option<Vec<f64>>,
    /// Face deviations φ\[1\] … φ\[N\], arcsec (cumulative sums of `pitch_deviation`); empty
    /// means "compute from `pitch_deviation`".
    #[serde(default)]
    pub face_deviation: Vec<f64>,
    /// Setup errors U\[setup, ac\]; one missing counts as 0.
    #[serde(default)]
    pub setup_error: Vec<SetupErrorTruth>,
    /// Effects in the readings (docs/FORMAT.md §6).
    #[serde(default)]
    pub effects: Vec<Effect>,
    /// Standard deviation of the reading noise the run was made with, arcsec.
    #[serde(default)]
    pub noise_arcsec: Option<f64>,
    /// The temperature a `temperature` effect acts against (the mean of the run's
    /// `temperature` column), °C; needed only when there is such an effect.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reference_temperature_celsius: Option<f64>,
    /// Degrees of freedom of the Student-t reading noise the run was made with; `None`
    /// for normal noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_student_dof: Option<f64>,
    /// The true geometry of the elevation axis (`reading_y`), when the run has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elevation: Option<ElevationTruth>,
    /// The random walks of autocollimator zeros (`simulate --random-walk`): each one's
    /// value at every stop of the run, in the run's order; empty without.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub random_walk: Vec<super::RandomWalkTruth>,
}

/// Removes the mean, then sets the last element to minus the (left-to-right) sum of the
/// others, so that the left-to-right sum is exactly 0.
pub(super) fn close(v: &mut [f64]) {
    if v.is_empty() {
        return;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    v.iter_mut().for_each(|x| *x -= mean);
    let last = v.len() - 1;
    let rest: f64 = v[..last].iter().sum();
    v[last] = -rest;
}

impl Truth {
    /// Draws the true values for `config` (which is validated first).
    ///
    /// - β\[k\] = `pitch_spread_arcsec`·z − mean, z standard normal, so Σβ = 0;
    /// - α\[p\] = Σ over harmonics of `a·cos(2π·k·p/N + phase)`, minus the mean, so Σα = 0;
    ///   with sub-pitch mountings (`table_shift_deg` not all whole multiples of 360°/N),
    ///   the same continuous function at every table angle the run stops at (every angle
    ///   of every coset, ascending, in `encoder_angle_deg`), minus its mean over those
    ///   angles: the encoder error is harmonics only, so that it has a value at any angle
    ///   (a harmonic whose order is a multiple of N is a different constant in each
    ///   coset, which the polygon cannot see);
    /// - U\[setup, ac\] = `setup_error_spread_arcsec`·z for every setup and autocollimator;
    /// - φ = cumulative sums of β; `effects`, `noise_arcsec` and `noise_student_dof`
    ///   copied from `config`;
    /// - with a temperature model, `reference_temperature_celsius` = the mean of the
    ///   `temperature` column [`simulate`](super::simulate) writes with this `config`
    ///   (over all readings, in row order);
    /// - with an elevation model, `elevation` drawn as [`ElevationTruth`] says.
    ///
    /// After the mean is removed, the last β and the last α are set to minus the sum of
    /// the others, so both closures hold exactly in floating point (and φ\[N\] = 0).
    ///
    /// The random draws come from stream 0 of `ChaCha8Rng::seed_from_u64(config.seed)`, in
    /// this fixed order: N standard normals for β\[1\] … β\[N\], then one per (setup, ac),
    /// setup 1's autocollimators 1, 2, … first. Draws are taken even when a spread is 0,
    /// so changing a spread never changes the other values. The elevation geometry comes
    /// from stream 3, the temperature noise from stream 2, so neither changes the rest.
    pub fn draw(config: &SimulationConfig) -> Result<Truth, SimulateError> {
        config.validate()?;
        let n = config.faces;
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        rng.set_stream(TRUTH_STREAM);
        let mut normal = || -> f64 { StandardNormal.sample(&mut rng) };

        let mut pitch_deviation: Vec<f64> = (0..n)
            .map(|_| config.pitch_spread_arcsec * normal())
            .collect();
        close(&mut pitch_deviation);

        let geometry = ShiftGeometry::new(
            n,
            (1..=config.setups).map(|s| (s, config.table_shift_of(s))),
        );
        let (mut encoder_error, encoder_angle_deg): (Vec<f64>, _) = if geometry.is_sub_pitch() {
            let angles = geometry.angles_deg();
            let values = angles
                .iter()
                .map(|&a| {
                    config
                        .encoder_harmonics
                        .iter()
                        .map(|h| h.value_at_deg(a))
                        .sum()
                })
                .collect();
            (values, Some(angles))
        } else {
            let values = (0..n)
                .map(|p| {
                    config
                        .encoder_harmonics
                        .iter()
                        .map(|h| h.value_at(p, n))
                        .sum()
                })
                .collect();
            (values, None)
        };
        close(&mut encoder_error);

        let mut setup_error = Vec::new();
        for setup in 1..=config.setups {
            for ac in 1..=config.ac_count() as u32 {
                setup_error.push(SetupErrorTruth {
                    setup,
                    ac,
                    value: config.setup_error_spread_arcsec * normal(),
                });
            }
        }

        let reference_temperature_celsius = config.temperature.as_ref().map(|model| {
            let n_ac = config.ac_count();
            let (sum, count) = model
                .stop_temperatures(config)
                .iter()
                .flat_map(|&t| std::iter::repeat_n(t, n_ac))
                .fold((0.0, 0usize), |(s, c), t| (s + t, c + 1));
            sum / count as f64
        });
        let elevation = config.elevation.as_ref().map(|model| {
            let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
            rng.set_stream(ELEVATION_TRUTH_STREAM);
            ElevationTruth::draw(config, model, &mut rng)
        });

        Ok(Truth {
            faces: n,
            face_deviation: face_deviation_from_pitch(&pitch_deviation),
            pitch_deviation,
            encoder_error,
            encoder_angle_deg,
            setup_error,
            effects: config
                .effects
                .iter()
                .cloned()
                .chain(super::habits::draw_rezero(config))
                .collect(),
            noise_arcsec: Some(config.noise_arcsec),
            reference_temperature_celsius,
            noise_student_dof: config.noise_student_dof,
            elevation,
            random_walk: super::habits::draw_random_walks(
                config,
                config.reading_count() / config.ac_count().max(1),
            ),
        })
    }

    /// The value of autocollimator `ac`'s random walk at stop `stop` of the run (the
    /// run's order, setup 1's stops first), arcsec; 0 without a walk of that
    /// autocollimator.
    pub fn random_walk_at(&self, ac: u32, stop: usize) -> f64 {
        self.random_walk
            .iter()
            .filter(|w| w.ac == ac)
            .filter_map(|w| w.values_arcsec.get(stop))
            .sum()
    }

    /// Reads a truth file (JSON, docs/FORMAT.md §4) and checks it ([`Truth::validate`]).
    /// An empty or missing `face_deviation` is filled from `pitch_deviation`. Errors name
    /// the file, and for bad JSON also the line and column.
    /// [`TruthFile::read_path`](super::TruthFile::read_path) reads a truth file of either
    /// kind.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Io`], [`SimulateError::Json`] or [`SimulateError::Truth`].
    pub fn read_path(path: &Path) -> Result<Truth, SimulateError> {
        let (bytes, name) = truth_file::read_bytes(path)?;
        Truth::from_json_bytes(&bytes, &name)
    }

    /// A truth file's bytes (JSON, docs/FORMAT.md §4), checked as [`Truth::read_path`]
    /// checks a file; `source` names them in messages.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Json`] (source, line, column) for bad JSON,
    /// [`SimulateError::Truth`] for a truth that breaks a rule.
    pub fn from_json_bytes(bytes: &[u8], source: &str) -> Result<Truth, SimulateError> {
        truth_file::from_json_bytes(bytes, source)
    }

    /// Checks the truth: faces ≥ 3; `pitch_deviation` and `encoder_error` (and
    /// `face_deviation` unless empty) have `faces` elements; every number is finite; setup
    /// errors name setups and autocollimators ≥ 1, each pair once; effects name cycles,
    /// setups and autocollimators ≥ 1 and a drift's `quadratic` is finite; the noise is
    /// ≥ 0, Student-t degrees of freedom > 2, the reference temperature finite; the
    /// `elevation` geometry has `faces` pyramidal errors, finite numbers, setups and
    /// autocollimators ≥ 1, each once, and a noise ≥ 0. The closures Σβ = 0 and Σα = 0 are not
    /// enforced (a file written by hand may be rounded). The error names the first
    /// problem.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Truth`] (origin `truth`) with the [`TruthError`] of the first
    /// problem.
    pub fn validate(&self) -> Result<(), SimulateError> {
        self.check().map_err(|problem| SimulateError::Truth {
            origin: "truth".into(),
            problem,
        })
    }

    fn check(&self) -> Result<(), TruthError> {
        let n = self.faces;
        if n < 3 {
            return Err(TruthError::TooFewFaces { faces: n });
        }
        let angles = self.encoder_angle_deg.as_deref();
        if let Some(angles) = angles {
            if angles.len() < n {
                return Err(TruthError::TooFewEncoderAngles {
                    angles: angles.len(),
                    faces: n,
                });
            }
            if let Some(index) = angles
                .iter()
                .position(|a| !(a.is_finite() && (0.0..360.0).contains(a)))
            {
                return Err(TruthError::EncoderAngleOutOfRange { index });
            }
            if let Some(i) = angles.windows(2).position(|w| w[1] <= w[0]) {
                return Err(TruthError::EncoderAnglesNotAscending { index: i + 1 });
            }
        }
        let lists = [
            (Quantity::PitchDeviation, &self.pitch_deviation, n, false),
            (
                Quantity::EncoderError,
                &self.encoder_error,
                angles.map_or(n, <[f64]>::len),
                false,
            ),
            (Quantity::FaceDeviation, &self.face_deviation, n, true),
        ];
        for (quantity, list, len, may_be_empty) in lists {
            let name = quantity.name();
            if list.len() != len && !(may_be_empty && list.is_empty()) {
                return Err(if len == n {
                    TruthError::LengthNotFaces {
                        list: name,
                        len: list.len(),
                        faces: n,
                    }
                } else {
                    TruthError::LengthNotAngles {
                        list: name,
                        len: list.len(),
                        angles: len,
                    }
                });
            }
            check_values(name, list)?;
        }
        let mut seen = HashSet::new();
        for &SetupErrorTruth { setup, ac, value } in &self.setup_error {
            if setup == 0 || ac == 0 {
                return Err(TruthError::SetupErrorNumbering { setup, ac });
            }
            if let Err(rule) = READING_ARCSEC.check(value, TRUTH_VALUE) {
                return Err(TruthError::SetupErrorBeyondLimits {
                    setup,
                    ac,
                    rule: Box::new(rule),
                });
            }
            if !seen.insert((setup, ac)) {
                return Err(TruthError::SetupErrorTwice { setup, ac });
            }
        }
        for e in &self.effects {
            if !e.value().is_finite() {
                return Err(TruthError::EffectNotFinite { effect: e.clone() });
            }
            if let Effect::Drift {
                quadratic: Some(q), ..
            } = *e
                && !q.is_finite()
            {
                return Err(TruthError::EffectQuadraticNotFinite { effect: e.clone() });
            }
            let zero = match *e {
                Effect::Drift { ac, .. }
                | Effect::Temperature { ac, .. }
                | Effect::CrossTalk { ac, .. } => ac == 0,
                Effect::Rezero { ac, setup, .. } => ac == 0 || setup == Some(0),
                Effect::OffsetStep {
                    ac, cycle, setup, ..
                } => ac == 0 || cycle == 0 || setup == Some(0),
                Effect::Direction { ac, .. } => ac == Some(0),
                Effect::Outlier {
                    cycle, ac, setup, ..
                } => cycle == 0 || ac == 0 || setup == Some(0),
            };
            if zero {
                return Err(TruthError::EffectNumbering { effect: e.clone() });
            }
        }
        check_noise(self.noise_arcsec)?;
        if let Some(dof) = self.noise_student_dof
            && !(dof.is_finite() && dof > 2.0)
        {
            return Err(TruthError::StudentDof { dof });
        }
        if let Some(celsius) = self.reference_temperature_celsius
            && !celsius.is_finite()
        {
            return Err(TruthError::ReferenceTemperature { celsius });
        }
        for walk in &self.random_walk {
            if walk.ac == 0 {
                return Err(TruthError::RandomWalkNumbering);
            }
            if !walk.rate_arcsec_per_sqrt_h.is_finite()
                || walk.values_arcsec.iter().any(|v| !v.is_finite())
            {
                return Err(TruthError::RandomWalkNotFinite { ac: walk.ac });
            }
        }
        if let Some(elevation) = &self.elevation {
            elevation.check(n)?;
        }
        Ok(())
    }

    /// The truth as pretty-printed JSON (numbers at full precision: they read back to the
    /// same doubles).
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).expect("a Truth always serializes to JSON")
    }

    /// The true setup error U\[setup, ac\], if the truth has one.
    pub fn setup_error_of(&self, setup: u32, ac: u32) -> Option<f64> {
        self.setup_error
            .iter()
            .find(|u| u.setup == setup && u.ac == ac)
            .map(|u| u.value)
    }

    /// The true face deviation φ\[face\] (1 … N): `face_deviation[face-1]`, or the sum
    /// β\[1\] + … + β\[face\] when `face_deviation` is empty. NaN for a face outside 1 … N.
    pub fn face_deviation_at(&self, face: usize) -> f64 {
        if face == 0 || face > self.faces {
            return f64::NAN;
        }
        match self.face_deviation.get(face - 1) {
            Some(&phi) if self.face_deviation.len() == self.faces => phi,
            _ => self
                .pitch_deviation
                .iter()
                .take(face)
                .fold(0.0, |s, &b| s + b),
        }
    }

    /// The true encoder error at the table angle `angle_deg` (degrees, taken modulo 360):
    /// the `encoder_error` whose angle is within 10⁻⁶ positions of it (`encoder_angle_deg`,
    /// or p·360°/N without it); `None` when the truth has no value there.
    ///
    /// ```
    /// use polycal::simulate::{SimulationConfig, Truth};
    ///
    /// let truth = Truth::draw(&SimulationConfig { faces: 8, ..SimulationConfig::default() })?;
    /// assert_eq!(truth.encoder_error_at_deg(90.0), Some(truth.encoder_error[2]));
    /// assert_eq!(truth.encoder_error_at_deg(-45.0), Some(truth.encoder_error[7]));
    /// assert_eq!(truth.encoder_error_at_deg(10.0), None);
    /// # Ok::<(), polycal::simulate::SimulateError>(())
    /// ```
    pub fn encoder_error_at_deg(&self, angle_deg: f64) -> Option<f64> {
        let n = self.faces;
        if n == 0 || !angle_deg.is_finite() {
            return None;
        }
        let pitch = 360.0 / n as f64;
        let a = angle_deg.rem_euclid(360.0);
        let Some(angles) = &self.encoder_angle_deg else {
            let x = a / pitch;
            let q = x.round();
            return ((x - q).abs() <= POSITION_TOLERANCE)
                .then(|| self.encoder_error.get(q as usize % n).copied())
                .flatten();
        };
        let last = angles.len().checked_sub(1)?;
        let i = angles.partition_point(|&b| b < a);
        [i.checked_sub(1), Some(i.min(last)), Some(0), Some(last)]
            .into_iter()
            .flatten()
            .find(|&j| {
                let d = (angles[j] - a).abs();
                d.min(360.0 - d) <= POSITION_TOLERANCE * pitch
            })
            .and_then(|j| self.encoder_error.get(j).copied())
    }

    /// The noise-free model value of a reading:
    /// `α[step mod N] + φ[face] + U[setup, ac] + Σ effect.value · effect.regressor(reading)`,
    /// added in that order. A missing setup error counts as 0. NaN when the reading's face
    /// is outside 1 … N or the truth is incomplete. The reading's mounting is taken as
    /// unshifted ([`Truth::model_reading_shifted`] with 0).
    pub fn model_reading(&self, reading: &Reading) -> f64 {
        self.model_reading_shifted(reading, 0.0)
    }

    /// [`Truth::model_reading`] of a reading of a mounting whose table stands at
    /// `shift_deg` degrees at step 0: α is the encoder error at the table angle
    /// `shift_deg` + (step mod N)·360°/N ([`Truth::encoder_error_at_deg`]; NaN when the
    /// truth has none there). With a shift of 0 and no `encoder_angle_deg`, α\[step mod N\].
    pub fn model_reading_shifted(&self, reading: &Reading, shift_deg: f64) -> f64 {
        let n = self.faces;
        if n == 0 {
            return f64::NAN;
        }
        let alpha = if shift_deg == 0.0 && self.encoder_angle_deg.is_none() {
            self.encoder_error.get(reading.step % n).copied()
        } else {
            self.encoder_error_at_deg(shift_deg + (reading.step % n) as f64 * 360.0 / n as f64)
        }
        .unwrap_or(f64::NAN);
        let phi = self.face_deviation_at(reading.face);
        let u = self
            .setup_error_of(reading.setup, reading.ac)
            .unwrap_or(0.0);
        let mut value = alpha + phi + u;
        let context =
            EffectContext::with_mean_temperature(self.reference_temperature_celsius.unwrap_or(0.0));
        for e in &self.effects {
            value += e.contribution(reading, &context);
        }
        value
    }
}

impl TruthJson for Truth {
    fn check(&self) -> Result<(), TruthError> {
        Truth::check(self)
    }

    fn fill_left_out(&mut self) {
        if self.face_deviation.is_empty() {
            self.face_deviation = face_deviation_from_pitch(&self.pitch_deviation);
        }
    }
}

/// What a truth value is, in the message of one beyond its limits.
const TRUTH_VALUE: &str = "a truth value";

/// Every value of the list `list` within the limits of a truth value
/// ([`READING_ARCSEC`]).
pub(super) fn check_values(list: &'static str, values: &[f64]) -> Result<(), TruthError> {
    for (index, &value) in values.iter().enumerate() {
        if let Err(rule) = READING_ARCSEC.check(value, TRUTH_VALUE) {
            return Err(TruthError::ValueBeyondLimits {
                list,
                index,
                rule: Box::new(rule),
            });
        }
    }
    Ok(())
}

/// A truth's reading noise, when it has one, a finite number ≥ 0.
pub(super) fn check_noise(noise: Option<f64>) -> Result<(), TruthError> {
    match noise {
        Some(noise) if !(noise.is_finite() && noise >= 0.0) => Err(TruthError::Noise { noise }),
        _ => Ok(()),
    }
}
