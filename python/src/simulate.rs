//! Simulated runs with a known truth, as `polycal simulate` draws them: the polygon run
//! with every effect the command can add, and the self-calibration run (`--selfcal`).
//! The options carry the command's names and units; each is parsed by the library's own
//! parser (`Effect::parse_spec`, the models' and specs' `FromStr`), and the set carries
//! the comment line the command writes, so that its file is the command's to the byte.

use polycal::effects::Effect;
use polycal::simulate::{
    self as sim, ElevationModel, Harmonic, RandomWalkSpec, RezeroSpec, SelfcalSimConfig,
    SimulationConfig, TemperatureModel,
};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::sets::{PyMeasurementSet, PySelfcalSet};

/// Parses every spec of an option with `parse`, naming the option and the spec when one
/// is refused.
fn parsed<T, E: std::fmt::Display>(
    option: &str,
    specs: &[String],
    parse: impl Fn(&str) -> Result<T, E>,
) -> PyResult<Vec<T>> {
    specs
        .iter()
        .map(|spec| {
            parse(spec).map_err(|e| PyValueError::new_err(format!("{option} {spec:?}: {e}")))
        })
        .collect()
}

/// A model option: `None` none, `""` the command's default model, else its spec.
fn model<T: std::str::FromStr + Default>(option: &str, spec: Option<&str>) -> PyResult<Option<T>>
where
    T::Err: std::fmt::Display,
{
    match spec {
        None => Ok(None),
        Some("") => Ok(Some(T::default())),
        Some(spec) => spec
            .parse::<T>()
            .map(Some)
            .map_err(|e| PyValueError::new_err(format!("{option} {spec:?}: {e}"))),
    }
}

/// Simulates a polygon run as `polycal simulate` does: the set (with the command's
/// comment line) and the truth's JSON (docs/FORMAT.md §4).
#[pyfunction]
#[pyo3(signature = (
    faces=24, ac_faces=vec![1, 2], cycles=6, closing=true, bidirectional=false, noise=0.05,
    pitch_spread=None, harmonic=Vec::new(), setup_spread=None, step_seconds=None, setups=1,
    setup_shift_faces=None, shift_deg=Vec::new(), seed=1, noise_dof=None, temperature=None,
    elevation=None, drift=Vec::new(), offset_step=Vec::new(), temperature_effect=Vec::new(),
    cross_talk=Vec::new(), direction=Vec::new(), outlier=Vec::new(), rezero=Vec::new(),
    random_walk=Vec::new(), no_time=false
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate(
    py: Python<'_>,
    faces: usize,
    ac_faces: Vec<usize>,
    cycles: u32,
    closing: bool,
    bidirectional: bool,
    noise: f64,
    pitch_spread: Option<f64>,
    harmonic: Vec<String>,
    setup_spread: Option<f64>,
    step_seconds: Option<f64>,
    setups: u32,
    setup_shift_faces: Option<usize>,
    shift_deg: Vec<f64>,
    seed: u64,
    noise_dof: Option<f64>,
    temperature: Option<&str>,
    elevation: Option<&str>,
    drift: Vec<String>,
    offset_step: Vec<String>,
    temperature_effect: Vec<String>,
    cross_talk: Vec<String>,
    direction: Vec<String>,
    outlier: Vec<String>,
    rezero: Vec<String>,
    random_walk: Vec<String>,
    no_time: bool,
) -> PyResult<(PyMeasurementSet, String)> {
    let defaults = SimulationConfig::default();
    let mut effects = Vec::new();
    for (kind, option, specs) in [
        ("drift", "drift", &drift),
        ("offset-step", "offset_step", &offset_step),
        ("direction", "direction", &direction),
        ("outlier", "outlier", &outlier),
        ("temperature", "temperature_effect", &temperature_effect),
        ("cross-talk", "cross_talk", &cross_talk),
    ] {
        effects.extend(parsed(option, specs, |spec| {
            Effect::parse_spec(kind, spec)
        })?);
    }
    let encoder_harmonics = if harmonic.is_empty() {
        defaults.encoder_harmonics.clone()
    } else {
        parsed("harmonic", &harmonic, str::parse::<Harmonic>)?
    };
    let config = SimulationConfig {
        faces,
        ac_faces,
        cycles,
        // as the command: a bidirectional run has the closing reading
        closing: closing || bidirectional,
        bidirectional,
        noise_arcsec: noise,
        pitch_spread_arcsec: pitch_spread.unwrap_or(defaults.pitch_spread_arcsec),
        encoder_harmonics,
        setup_error_spread_arcsec: setup_spread.unwrap_or(defaults.setup_error_spread_arcsec),
        step_seconds: step_seconds.unwrap_or(defaults.step_seconds),
        setups,
        setup_shift_faces: setup_shift_faces.unwrap_or(defaults.setup_shift_faces),
        table_shift_deg: shift_deg,
        effects,
        seed,
        temperature: model::<TemperatureModel>("temperature", temperature)?,
        elevation: model::<ElevationModel>("elevation", elevation)?,
        noise_student_dof: noise_dof,
        rezero: parsed("rezero", &rezero, str::parse::<RezeroSpec>)?,
        random_walk: parsed("random_walk", &random_walk, str::parse::<RandomWalkSpec>)?,
        no_time,
    };
    let (set, truth) = py
        .detach(|| sim::simulate(&config))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    Ok((
        PyMeasurementSet {
            inner: std::sync::Arc::new(set),
            comments: vec![config.comment()],
        },
        truth.to_json_pretty(),
    ))
}

/// Simulates a self-calibration run as `polycal simulate --selfcal` does: the set (with
/// the command's comment line) and the truth's JSON (docs/FORMAT.md §9.4). `heads`:
/// the head angles from head 1, degrees; `None` the SelfA encoder's twelve.
#[pyfunction]
#[pyo3(signature = (
    positions=168, heads=None, cycles=2, bidirectional=false, noise=0.02, harmonic=Vec::new(),
    max_order=60, table_error=1.0, head_error=2.0, step_seconds=20.0, seed=1
))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn simulate_selfcal(
    py: Python<'_>,
    positions: usize,
    heads: Option<Vec<f64>>,
    cycles: u32,
    bidirectional: bool,
    noise: f64,
    harmonic: Vec<String>,
    max_order: usize,
    table_error: f64,
    head_error: f64,
    step_seconds: f64,
    seed: u64,
) -> PyResult<(PySelfcalSet, String)> {
    let mut config = SelfcalSimConfig::default();
    config.positions = positions;
    config.cycles = cycles;
    config.head_angles_deg = heads.unwrap_or_else(sim::selfa_head_angles_deg);
    config.encoder_harmonics = parsed("harmonic", &harmonic, str::parse::<Harmonic>)?;
    config.max_order = max_order;
    config.head_error_arcsec = head_error;
    config.table_error_arcsec = table_error;
    config.noise_arcsec = noise;
    config.bidirectional = bidirectional;
    config.step_seconds = Some(step_seconds);
    config.seed = seed;
    let (set, truth) = py
        .detach(|| sim::simulate_selfcal(&config))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let comments = vec![config.comment(&harmonic)];
    let truth = truth.to_json_pretty();
    Ok((
        PySelfcalSet {
            inner: set,
            name: "<simulated>".to_string(),
            comments,
        },
        truth,
    ))
}
