//! The truth files (docs/FORMAT.md §4): a polygon run's ([`Truth`]) and a
//! self-calibration's ([`SelfcalTruth`]), read by one reader that tells them apart by their
//! content ([`TruthFile`]), and why a truth is refused ([`TruthError`]).

use std::fmt;
use std::path::Path;

use serde::de::{self, DeserializeOwned, IgnoredAny, MapAccess, Visitor};

use super::harmonic::HarmonicError;
use super::run_effect::{RunEffectError, effect_json};
use super::{MIN_POSITIONS, SelfcalTruth, SimulateError, Truth};
use crate::effects::Effect;
use crate::input::limits::LimitError;

/// A truth file of either kind, told by its content: a self-calibration's has `positions`
/// and no `faces`, every other file is read as a polygon run's.
///
/// ```
/// use polycal::simulate::{SimulationConfig, Truth, TruthFile};
///
/// let truth = Truth::draw(&SimulationConfig { faces: 8, ..SimulationConfig::default() })?;
/// let read = TruthFile::from_json_bytes(truth.to_json_pretty().as_bytes(), "truth.json")?;
/// assert_eq!(read, TruthFile::Polygon(truth));
/// # Ok::<(), polycal::simulate::SimulateError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum TruthFile {
    /// A polygon run's truth (docs/FORMAT.md §4).
    Polygon(Truth),
    /// A self-calibration's truth (`simulate --selfcal --truth-out`).
    Selfcal(SelfcalTruth),
}

impl TruthFile {
    /// Reads a truth file of either kind (`-`: standard input) and checks it as
    /// [`Truth::read_path`] or [`SelfcalTruth::read_path`] does.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Io`] naming the file, [`SimulateError::Json`] (file, line, column)
    /// for bad JSON, [`SimulateError::Truth`] for a truth that breaks a rule.
    pub fn read_path(path: &Path) -> Result<TruthFile, SimulateError> {
        let (bytes, name) = read_bytes(path)?;
        TruthFile::from_json_bytes(&bytes, &name)
    }

    /// [`TruthFile::read_path`] of bytes already read; `source` names them in messages.
    ///
    /// # Errors
    ///
    /// [`SimulateError::Json`] or [`SimulateError::Truth`].
    pub fn from_json_bytes(bytes: &[u8], source: &str) -> Result<TruthFile, SimulateError> {
        if is_selfcal(bytes) {
            from_json_bytes(bytes, source).map(TruthFile::Selfcal)
        } else {
            from_json_bytes(bytes, source).map(TruthFile::Polygon)
        }
    }
}

/// A truth of one kind as its file holds it: the rules it is checked against, and what a
/// file may leave out.
pub(super) trait TruthJson: DeserializeOwned {
    /// Checks the truth; the error names the first problem.
    fn check(&self) -> Result<(), TruthError>;
    /// Fills in what a file may leave out (computed from the rest).
    fn fill_left_out(&mut self);
}

/// A file's bytes and its name in messages (`<stdin>` for `-`).
pub(super) fn read_bytes(path: &Path) -> Result<(Vec<u8>, String), SimulateError> {
    crate::input::read_bytes(path).map_err(|(name, source)| SimulateError::Io {
        path: name.into(),
        source,
    })
}

/// A truth file's bytes parsed, checked ([`TruthJson::check`]) and completed
/// ([`TruthJson::fill_left_out`]); `source` names them in messages.
pub(super) fn from_json_bytes<T: TruthJson>(
    bytes: &[u8],
    source: &str,
) -> Result<T, SimulateError> {
    let mut truth: T = parse_json(bytes, source)?;
    truth.check().map_err(|problem| SimulateError::Truth {
        origin: source.to_string(),
        problem,
    })?;
    truth.fill_left_out();
    Ok(truth)
}

/// Parses JSON bytes into `T`; `name` names them in [`SimulateError::Json`].
fn parse_json<T: DeserializeOwned>(bytes: &[u8], name: &str) -> Result<T, SimulateError> {
    let text = crate::input::text::utf8(bytes).map_err(|((line, column), message)| {
        SimulateError::Json {
            location: crate::input::Location::new(name, line, column),
            message,
        }
    })?;
    serde_json::from_str(text).map_err(|e| {
        let position = format!(" at line {} column {}", e.line(), e.column());
        let text = e.to_string();
        SimulateError::Json {
            location: crate::input::Location::new(name, e.line() as u64, e.column() as u64),
            message: text.strip_suffix(&position).unwrap_or(&text).to_string(),
        }
    })
}

/// Whether the bytes are a self-calibration's truth: a JSON object with a `positions` key
/// and no `faces` key (whatever their values). Anything else, bad JSON included, is not:
/// it is read, and refused, as a polygon run's truth.
fn is_selfcal(bytes: &[u8]) -> bool {
    serde_json::from_slice::<TopKeys>(bytes).is_ok_and(|keys| keys.positions && !keys.faces)
}

/// Which of the keys that tell the kinds apart a JSON object has.
struct TopKeys {
    positions: bool,
    faces: bool,
}

impl<'de> de::Deserialize<'de> for TopKeys {
    fn deserialize<D: de::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_map(TopKeysVisitor)
    }
}

struct TopKeysVisitor;

impl<'de> Visitor<'de> for TopKeysVisitor {
    type Value = TopKeys;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("a JSON object")
    }

    fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<TopKeys, A::Error> {
        let mut keys = TopKeys {
            positions: false,
            faces: false,
        };
        while let Some(key) = map.next_key::<std::borrow::Cow<'de, str>>()? {
            match key.as_ref() {
                "positions" => keys.positions = true,
                "faces" => keys.faces = true,
                _ => {}
            }
            map.next_value::<IgnoredAny>()?;
        }
        Ok(keys)
    }
}

/// Why a truth is refused: a rule of the truth file broken (docs/FORMAT.md §4; a polygon
/// run's or a self-calibration's), or a truth that does not fit the run it is used for.
/// The message leaves out where the truth came from ([`SimulateError::Truth`] adds it).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum TruthError {
    /// Fewer than 3 faces.
    #[error("faces is {faces}; a polygon needs at least 3 faces")]
    TooFewFaces {
        /// The number of faces.
        faces: usize,
    },
    /// Fewer encoder angles than faces.
    #[error("encoder_angle_deg has {angles} angles, fewer than faces ({faces})")]
    TooFewEncoderAngles {
        /// The number of angles.
        angles: usize,
        /// The number of faces.
        faces: usize,
    },
    /// An encoder angle that is not a finite angle in [0°, 360°).
    #[error("encoder_angle_deg[{index}] is not a finite angle, 0 <= angle < 360")]
    EncoderAngleOutOfRange {
        /// Its index in the list.
        index: usize,
    },
    /// Encoder angles that do not ascend.
    #[error("encoder_angle_deg[{index}] is not above the angle before it; the angles ascend")]
    EncoderAnglesNotAscending {
        /// The index of the first angle not above the one before it.
        index: usize,
    },
    /// A list whose length is not the number of faces.
    #[error("{list} has {len} values, but faces is {faces}")]
    LengthNotFaces {
        /// The list: `pitch_deviation`, `encoder_error`, `face_deviation`.
        list: &'static str,
        /// Its length.
        len: usize,
        /// The number of faces.
        faces: usize,
    },
    /// An `encoder_error` whose length is not that of `encoder_angle_deg`.
    #[error("{list} has {len} values, but encoder_angle_deg {angles} angles")]
    LengthNotAngles {
        /// The list: `encoder_error`.
        list: &'static str,
        /// Its length.
        len: usize,
        /// The number of encoder angles.
        angles: usize,
    },
    /// A list whose length is not the number of positions of a self-calibration.
    #[error("{list} has {len} values, but positions is {positions}")]
    LengthNotPositions {
        /// The list: `encoder_error`, `encoder_angle_deg`.
        list: &'static str,
        /// Its length.
        len: usize,
        /// The number of positions.
        positions: usize,
    },
    /// A value of a list beyond the limits of a truth value (docs/FORMAT.md §2.2).
    #[error("{list}[{index}]: {rule}")]
    ValueBeyondLimits {
        /// The list.
        list: &'static str,
        /// The value's index.
        index: usize,
        /// The limit it breaks.
        rule: Box<LimitError>,
    },
    /// A setup error numbered from 0.
    #[error("setup_error for setup {setup} ac {ac}: numbers start at 1")]
    SetupErrorNumbering {
        /// Its setup.
        setup: u32,
        /// Its autocollimator.
        ac: u32,
    },
    /// A setup error beyond the limits of a truth value.
    #[error("setup_error for setup {setup} ac {ac}: {rule}")]
    SetupErrorBeyondLimits {
        /// Its setup.
        setup: u32,
        /// Its autocollimator.
        ac: u32,
        /// The limit it breaks.
        rule: Box<LimitError>,
    },
    /// Two setup errors of one setup and autocollimator.
    #[error("setup_error for setup {setup} ac {ac} is given twice")]
    SetupErrorTwice {
        /// The setup.
        setup: u32,
        /// The autocollimator.
        ac: u32,
    },
    /// An effect whose value is not finite.
    #[error("effect {effect}: value is not finite")]
    EffectNotFinite {
        /// The effect.
        effect: Effect,
    },
    /// A drift whose `quadratic` is not finite.
    #[error("effect {effect}: quadratic is not finite")]
    EffectQuadraticNotFinite {
        /// The effect.
        effect: Effect,
    },
    /// An effect that names autocollimator, setup or cycle 0.
    #[error("effect {effect}: autocollimator, setup and cycle numbers start at 1")]
    EffectNumbering {
        /// The effect.
        effect: Effect,
    },
    /// A reading noise that is not a finite number ≥ 0.
    #[error("noise_arcsec is {noise}; must be a finite number ≥ 0")]
    Noise {
        /// The noise, arcsec.
        noise: f64,
    },
    /// Student-t degrees of freedom that are not a finite number > 2.
    #[error("noise_student_dof is {dof}; must be a finite number > 2")]
    StudentDof {
        /// The degrees of freedom.
        dof: f64,
    },
    /// A reference temperature that is not finite.
    #[error("reference_temperature_celsius is {celsius}; must be a finite number")]
    ReferenceTemperature {
        /// The temperature, °C.
        celsius: f64,
    },
    /// A random walk of autocollimator 0.
    #[error("random_walk: autocollimator numbers start at 1")]
    RandomWalkNumbering,
    /// A random walk with a number that is not finite.
    #[error("random_walk of autocollimator {ac}: a number is not finite")]
    RandomWalkNotFinite {
        /// The walk's autocollimator.
        ac: u32,
    },
    /// Not one pyramidal error per face.
    #[error("elevation.pyramidal_error_arcsec has {len} values, but faces is {faces}")]
    PyramidalLength {
        /// The number of pyramidal errors.
        len: usize,
        /// The number of faces.
        faces: usize,
    },
    /// A pyramidal error that is not finite.
    #[error("elevation.pyramidal_error_arcsec[{index}] is not a finite number")]
    PyramidalNotFinite {
        /// Its index.
        index: usize,
    },
    /// A mounting tilt of setup 0.
    #[error("elevation.mounting_tilt: setup numbers start at 1")]
    TiltNumbering,
    /// A mounting tilt with a number that is not finite.
    #[error("elevation.mounting_tilt of setup {setup} is not finite")]
    TiltNotFinite {
        /// Its setup.
        setup: u32,
    },
    /// Two mounting tilts of one setup.
    #[error("elevation.mounting_tilt of setup {setup} is given twice")]
    TiltTwice {
        /// The setup.
        setup: u32,
    },
    /// An elevation offset numbered from 0.
    #[error("elevation.offset for setup {setup} ac {ac}: numbers start at 1")]
    OffsetNumbering {
        /// Its setup.
        setup: u32,
        /// Its autocollimator.
        ac: u32,
    },
    /// An elevation offset that is not finite.
    #[error("elevation.offset for setup {setup} ac {ac} is not a finite number")]
    OffsetNotFinite {
        /// Its setup.
        setup: u32,
        /// Its autocollimator.
        ac: u32,
    },
    /// Two elevation offsets of one setup and autocollimator.
    #[error("elevation.offset for setup {setup} ac {ac} is given twice")]
    OffsetTwice {
        /// The setup.
        setup: u32,
        /// The autocollimator.
        ac: u32,
    },
    /// A wobble whose amplitude or phase is not finite.
    #[error("elevation wobble is not finite")]
    WobbleNotFinite,
    /// An elevation noise that is not a finite number ≥ 0.
    #[error("elevation.noise_arcsec is {noise}; must be a finite number ≥ 0")]
    ElevationNoise {
        /// The noise, arcsec.
        noise: f64,
    },
    /// A self-calibration truth with fewer than [`MIN_POSITIONS`] positions.
    #[error("positions is {positions}; a self-calibration has at least {MIN_POSITIONS}")]
    TooFewPositions {
        /// The number of positions.
        positions: usize,
    },
    /// A table-error row whose length is not the number of positions.
    #[error("table_error of cycle {cycle} has {len} values, but positions is {positions}")]
    TableErrorLength {
        /// The row's cycle.
        cycle: usize,
        /// Its length.
        len: usize,
        /// The number of positions.
        positions: usize,
    },
    /// A table error that is not finite.
    #[error("table_error of cycle {cycle} step {step} is not a finite number")]
    TableErrorNotFinite {
        /// Its cycle.
        cycle: usize,
        /// Its step.
        step: usize,
    },
    /// A head error of head 1 (or 0): head 1 is the reference.
    #[error(
        "head_error for head {head}: head 1 is the reference (c[1] = 0); the list starts at \
         head 2"
    )]
    HeadErrorOfReference {
        /// The head.
        head: u32,
    },
    /// A head error with a number that is not finite.
    #[error("head_error for head {head} is not a finite number")]
    HeadErrorNotFinite {
        /// The head.
        head: u32,
    },
    /// Two head errors of one head.
    #[error("head_error for head {head} is given twice")]
    HeadErrorTwice {
        /// The head.
        head: u32,
    },
    /// An encoder harmonic of order 0, or not finite.
    #[error(transparent)]
    Harmonic(#[from] HarmonicError),
    /// A truth of another number of faces than the run's.
    #[error("it has {truth_faces} faces, {run} {run_faces}")]
    FacesDiffer {
        /// The truth's number of faces.
        truth_faces: usize,
        /// What the run is: `the simulation settings`, `the lab`.
        run: &'static str,
        /// The run's number of faces.
        run_faces: usize,
    },
    /// An effect of the truth that does not fit the run.
    #[error("effect {}: {problem}", effect_json(effect))]
    EffectNotInRun {
        /// The effect.
        effect: Effect,
        /// Why it does not fit.
        problem: RunEffectError,
    },
    /// A temperature effect without the temperature it acts against.
    #[error("it has a temperature effect but no reference_temperature_celsius")]
    NoReferenceTemperature,
    /// No encoder error at a table angle the run stops at.
    #[error("it has no encoder error at the table angle {angle_deg}° (setup {setup}, step {step})")]
    NoEncoderErrorAt {
        /// The table angle, degrees.
        angle_deg: f64,
        /// The setup that stops there.
        setup: u32,
        /// The step.
        step: usize,
    },
    /// Settings with an elevation model and a truth without its geometry.
    #[error("the simulation settings have an elevation model, the truth no elevation")]
    NoElevation,
    /// A random walk with another number of values than the run has stops.
    #[error("its random walk of autocollimator {ac} has {len} values, the run {stops} stops")]
    RandomWalkLength {
        /// The walk's autocollimator.
        ac: u32,
        /// Its number of values.
        len: usize,
        /// The run's number of stops.
        stops: usize,
    },
    /// A random walk of an autocollimator the run does not have.
    #[error("its random walk names autocollimator {ac}; the run has 1 … {acs}")]
    RandomWalkAc {
        /// The walk's autocollimator.
        ac: u32,
        /// The run's number of autocollimators.
        acs: u32,
    },
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulate::{SelfcalSimConfig, SimulationConfig, simulate_selfcal};

    #[test]
    fn the_kind_is_told_by_the_keys_and_both_kinds_read_back() {
        let polygon = Truth::draw(&SimulationConfig {
            faces: 6,
            ..SimulationConfig::default()
        })
        .expect("valid settings");
        let read = TruthFile::from_json_bytes(polygon.to_json_pretty().as_bytes(), "p.json");
        assert_eq!(read.ok(), Some(TruthFile::Polygon(polygon)));

        let (_, selfcal) = simulate_selfcal(&SelfcalSimConfig::default()).expect("valid");
        let read = TruthFile::from_json_bytes(selfcal.to_json_pretty().as_bytes(), "s.json");
        assert_eq!(read.ok(), Some(TruthFile::Selfcal(selfcal)));
    }

    #[test]
    fn a_file_with_faces_or_without_positions_is_a_polygon_runs() {
        for text in [
            r#"{"positions": 3, "faces": null, "encoder_error": [0, 0, 0]}"#,
            r#"{"encoder_error": [0, 0, 0]}"#,
            r#"[1, 2]"#,
            "{\"positions\": 3,\n \"encoder_error\": [1, -1, x]}",
        ] {
            assert!(!is_selfcal(text.as_bytes()), "{text}");
        }
        assert!(is_selfcal(br#"{"faces_seen": 1, "positions": 3}"#));
    }

    #[test]
    fn refusals_name_the_file_and_the_problem() {
        let err =
            TruthFile::from_json_bytes(br#"{"positions": 2, "encoder_error": [1, -1]}"#, "s.json")
                .expect_err("too few positions");
        assert!(matches!(
            &err,
            SimulateError::Truth {
                problem: TruthError::TooFewPositions { positions: 2 },
                ..
            }
        ));
        assert_eq!(
            err.to_string(),
            "s.json: invalid truth: positions is 2; a self-calibration has at least 3"
        );
        let err =
            TruthFile::from_json_bytes(b"{\"faces\": 3,\n \"pitch_deviation\": [1,,]}", "p.json")
                .expect_err("bad JSON");
        assert!(matches!(err, SimulateError::Json { .. }), "{err}");
        assert!(err.to_string().starts_with("p.json:2:"), "{err}");
    }
}
