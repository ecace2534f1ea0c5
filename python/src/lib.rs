//! `polycal._polycal`: the library's entry points for Python, as thin as `cli/` is for the
//! command line. It parses Python's arguments, calls the library with the GIL released,
//! and hands back the very JSON objects the commands print (docs/FORMAT.md §5), which
//! the Python package (`polycal/__init__.py`) turns into numpy arrays. No maths here.
//!
//! Every refusal of the library becomes a Python exception with the library's one-line
//! message: `InputError` (with `path`, `line`, `column`) for a file or text that is not
//! valid, `DesignError` (with `lost_harmonics`) for a design that cannot determine some
//! harmonics, `PolycalError` for the rest, `ValueError` for a bad argument. A Rust panic
//! becomes `pyo3_runtime.PanicException`, never an abort.

use std::path::Path;

use polycal::compare::{CompareOptions, Comparison, compare};
use polycal::diagnose::{DiagnoseOptions, diagnose as diagnose_set};
use polycal::input::Location;
use polycal::measurement::{Direction, MeasurementError, MeasurementSet, Reading, Sigma};
use polycal::output::SolveReport;
use polycal::output::diagnose::DiagnoseReport;
use polycal::output::selfcal::SelfcalReport;
use polycal::results::{Quantity, ResultRow, ResultsError};
use polycal::selfcal::{SelfcalError, SelfcalOptions, SelfcalSet};
use polycal::simulate::{SimulationConfig, Truth};
use polycal::solve::sub_pitch::{ShiftGeometry, solve_shifted};
use polycal::solve::{Method, Solution, SolveError, SolveOptions};
use polycal::uncertainty::BudgetError;
use polycal::uncertainty::calibration::{InstrumentBudget, McOptions, McSolver, evaluate};
use polycal::uncertainty::monte_carlo::Trials;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

create_exception!(
    _polycal,
    PolycalError,
    PyException,
    "A refusal of the polycal library."
);
create_exception!(
    _polycal,
    InputError,
    PolycalError,
    "A file or text that is not valid: `path`, `line` and `column` say where (0 when unknown)."
);
create_exception!(
    _polycal,
    DesignError,
    PolycalError,
    "A design that cannot determine some harmonics: `lost_harmonics` lists them."
);

/// An `InputError` at a location (or none).
fn input_error(py: Python<'_>, message: String, at: Option<&Location>) -> PyErr {
    let error = InputError::new_err(message);
    let value = error.value(py);
    let (path, line, column) = at.map_or((String::new(), 0, 0), |l| {
        (l.file().to_string(), l.line(), l.column())
    });
    // setting attributes on a fresh exception object cannot fail but for memory
    let _ = value.setattr("path", path);
    let _ = value.setattr("line", line);
    let _ = value.setattr("column", column);
    error
}

fn measurement_error(py: Python<'_>, e: MeasurementError) -> PyErr {
    let at = e.location().cloned();
    input_error(py, e.to_string(), at.as_ref())
}

fn results_error(py: Python<'_>, e: ResultsError) -> PyErr {
    let at = e.location().cloned();
    input_error(py, e.to_string(), at.as_ref())
}

fn selfcal_error(py: Python<'_>, e: SelfcalError) -> PyErr {
    let at = e.location().cloned();
    input_error(py, e.to_string(), at.as_ref())
}

fn solve_error(py: Python<'_>, e: SolveError) -> PyErr {
    match &e {
        SolveError::Unobservable(u) => {
            let error = DesignError::new_err(e.to_string());
            let _ = error
                .value(py)
                .setattr("lost_harmonics", u.harmonics.clone());
            error
        }
        _ => PolycalError::new_err(e.to_string()),
    }
}

fn refusal(e: impl std::fmt::Display) -> PyErr {
    PolycalError::new_err(e.to_string())
}

fn to_json<T: serde::Serialize>(object: &T) -> PyResult<String> {
    polycal::output::to_json(object).map_err(refusal)
}

/// Reads `path`, or `text` named `name`, with the reader `read`.
fn read_source<T, E>(
    path: Option<&str>,
    text: Option<&str>,
    name: &str,
    read_path: impl FnOnce(&Path) -> Result<T, E>,
    read_text: impl FnOnce(&[u8], &str) -> Result<T, E>,
) -> PyResult<Result<T, E>> {
    match (path, text) {
        (Some(path), None) => Ok(read_path(Path::new(path))),
        (None, Some(text)) => Ok(read_text(text.as_bytes(), name)),
        _ => Err(PyValueError::new_err("give a path or a text, one of them")),
    }
}

/// A measurement set (docs/FORMAT.md §2).
#[pyclass(name = "MeasurementSet", module = "polycal._polycal", frozen)]
#[derive(Clone)]
struct PyMeasurementSet {
    inner: MeasurementSet,
}

#[pymethods]
impl PyMeasurementSet {
    /// N, the number of faces.
    #[getter]
    fn faces(&self) -> usize {
        self.inner.faces
    }

    /// Where the readings came from.
    #[getter]
    fn source(&self) -> String {
        self.inner.source.clone()
    }

    fn __len__(&self) -> usize {
        self.inner.readings.len()
    }

    fn __repr__(&self) -> String {
        format!(
            "MeasurementSet({} readings, {} faces, from {})",
            self.inner.readings.len(),
            self.inner.faces,
            self.inner.source
        )
    }

    /// The readings as columns named as the file's (docs/FORMAT.md §2): lists, `None`
    /// where a reading has no value of an optional column.
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.inner.readings;
        let d = PyDict::new(py);
        d.set_item("setup", r.iter().map(|x| x.setup).collect::<Vec<_>>())?;
        d.set_item("cycle", r.iter().map(|x| x.cycle).collect::<Vec<_>>())?;
        d.set_item("step", r.iter().map(|x| x.step).collect::<Vec<_>>())?;
        d.set_item("ac", r.iter().map(|x| x.ac).collect::<Vec<_>>())?;
        d.set_item("face", r.iter().map(|x| x.face).collect::<Vec<_>>())?;
        d.set_item(
            "reading",
            r.iter().map(|x| x.reading_arcsec).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "direction",
            r.iter().map(|x| x.direction.as_str()).collect::<Vec<_>>(),
        )?;
        d.set_item("time", r.iter().map(|x| x.time_seconds).collect::<Vec<_>>())?;
        d.set_item(
            "reading_y",
            r.iter().map(|x| x.reading_y_arcsec).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "temperature",
            r.iter().map(|x| x.temperature_celsius).collect::<Vec<_>>(),
        )?;
        Ok(d)
    }
}

/// Reads a measurement file (`path`) or its text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<text>", faces=None))]
fn read_measurements(
    py: Python<'_>,
    path: Option<&str>,
    text: Option<&str>,
    name: &str,
    faces: Option<usize>,
) -> PyResult<PyMeasurementSet> {
    let read = read_source(
        path,
        text,
        name,
        |p| MeasurementSet::read_path(p, faces),
        |bytes, name| MeasurementSet::read_from(bytes, name, faces),
    )?;
    read.map(|inner| PyMeasurementSet { inner })
        .map_err(|e| measurement_error(py, e))
}

/// Builds a measurement set from columns; every reading is checked as the file reader
/// checks it. Integer columns arrive as Python ints (the package checks dtypes).
#[pyfunction]
#[pyo3(signature = (cycle, step, ac, face, reading, direction=None, time=None, setup=None, shift=None, temperature=None, reading_y=None, faces=None, name="<arrays>"))]
#[allow(clippy::too_many_arguments)]
fn measurement_set_from_columns(
    py: Python<'_>,
    cycle: Vec<i64>,
    step: Vec<i64>,
    ac: Vec<i64>,
    face: Vec<i64>,
    reading: Vec<f64>,
    direction: Option<Vec<String>>,
    time: Option<Vec<Option<f64>>>,
    setup: Option<Vec<i64>>,
    shift: Option<Vec<f64>>,
    temperature: Option<Vec<Option<f64>>>,
    reading_y: Option<Vec<Option<f64>>>,
    faces: Option<usize>,
    name: &str,
) -> PyResult<PyMeasurementSet> {
    let n = reading.len();
    let lengths = [
        ("cycle", cycle.len()),
        ("step", step.len()),
        ("ac", ac.len()),
        ("face", face.len()),
        ("direction", direction.as_ref().map_or(n, Vec::len)),
        ("time", time.as_ref().map_or(n, Vec::len)),
        ("setup", setup.as_ref().map_or(n, Vec::len)),
        ("shift", shift.as_ref().map_or(n, Vec::len)),
        ("temperature", temperature.as_ref().map_or(n, Vec::len)),
        ("reading_y", reading_y.as_ref().map_or(n, Vec::len)),
    ];
    for (column, len) in lengths {
        if len != n {
            return Err(PyValueError::new_err(format!(
                "column {column} has {len} values, reading has {n}"
            )));
        }
    }
    let whole = |column: &str, values: &[i64], i: usize| -> PyResult<u64> {
        u64::try_from(values[i]).map_err(|_| {
            PyValueError::new_err(format!(
                "column {column}, index {i}: {} is negative",
                values[i]
            ))
        })
    };
    let mut readings = Vec::with_capacity(n);
    for i in 0..n {
        let direction = direction_at(direction.as_deref(), i)?;
        let narrow = |column: &str, v: u64| -> PyResult<u32> {
            u32::try_from(v).map_err(|_| {
                PyValueError::new_err(format!("column {column}, index {i}: {v} is too large"))
            })
        };
        let wide = |column: &str, v: u64| -> PyResult<usize> {
            usize::try_from(v).map_err(|_| {
                PyValueError::new_err(format!("column {column}, index {i}: {v} is too large"))
            })
        };
        readings.push(Reading {
            setup: match &setup {
                Some(s) => narrow("setup", whole("setup", s, i)?)?,
                None => 1,
            },
            cycle: narrow("cycle", whole("cycle", &cycle, i)?)?,
            step: wide("step", whole("step", &step, i)?)?,
            ac: narrow("ac", whole("ac", &ac, i)?)?,
            face: wide("face", whole("face", &face, i)?)?,
            reading_arcsec: reading[i],
            direction,
            time_seconds: time.as_ref().and_then(|t| t[i]),
            reading_y_arcsec: reading_y.as_ref().and_then(|t| t[i]),
            temperature_celsius: temperature.as_ref().and_then(|t| t[i]),
            encoder_degrees: None,
            line: 0,
        });
    }
    // the shift column (docs/FORMAT.md §2): the table's angle at step 0 of each setup,
    // one value per setup
    let mut shifts: Vec<(u32, f64)> = Vec::new();
    if let Some(shift) = &shift {
        for (i, (r, &value)) in readings.iter().zip(shift).enumerate() {
            match shifts.iter().find(|(s, _)| *s == r.setup) {
                Some(&(_, first)) if first.to_bits() != value.to_bits() => {
                    return Err(PyValueError::new_err(format!(
                        "column shift, index {i}: {value} differs from setup {}'s shift {first}",
                        r.setup
                    )));
                }
                Some(_) => {}
                None => shifts.push((r.setup, value)),
            }
        }
    }
    let inner = py
        .detach(|| {
            MeasurementSet::from_readings(readings, faces, name)
                .and_then(|set| set.with_setup_shifts(shifts))
        })
        .map_err(|e| measurement_error(py, e))?;
    Ok(PyMeasurementSet { inner })
}

/// The direction of reading `i` (`cw` when the column is not given).
fn direction_at(direction: Option<&[String]>, i: usize) -> PyResult<Direction> {
    match direction.map(|d| d[i].as_str()) {
        None | Some("cw") => Ok(Direction::Cw),
        Some("ccw") => Ok(Direction::Ccw),
        Some(other) => Err(PyValueError::new_err(format!(
            "column direction, index {i}: expected cw or ccw, got {other:?}"
        ))),
    }
}

/// An instrument budget (docs/FORMAT.md §5.1).
#[pyclass(name = "Budget", module = "polycal._polycal", frozen)]
struct PyBudget {
    inner: InstrumentBudget,
}

/// Reads an instrument budget: a TOML file (`path`) or TOML text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<budget>"))]
fn read_budget(path: Option<&str>, text: Option<&str>, name: &str) -> PyResult<PyBudget> {
    let read = read_source(
        path,
        text,
        name,
        |p: &Path| InstrumentBudget::read_path(p),
        |bytes, name| InstrumentBudget::from_toml_str(&String::from_utf8_lossy(bytes), name),
    )?;
    read.map(|inner| PyBudget { inner }).map_err(|e| match &e {
        BudgetError::File { location, .. } => {
            Python::attach(|py| input_error(py, e.to_string(), Some(location)))
        }
        _ => refusal(e),
    })
}

/// The rows of a result (docs/FORMAT.md §3): a solve's, or a result file's.
#[pyclass(name = "ResultRows", module = "polycal._polycal", frozen)]
struct PyRows {
    rows: Vec<ResultRow>,
    label: String,
}

#[pymethods]
impl PyRows {
    fn __len__(&self) -> usize {
        self.rows.len()
    }

    /// The label the comparison shows.
    #[getter]
    fn label(&self) -> String {
        self.label.clone()
    }
}

/// Reads a result file (docs/FORMAT.md §3).
#[pyfunction]
fn read_results(py: Python<'_>, path: &str) -> PyResult<PyRows> {
    let bytes = std::fs::read(path)
        .map_err(|e| input_error(py, format!("{path}: {e}"), Some(&Location::file_only(path))))?;
    let file = polycal::results::read_results_from(bytes.as_slice(), path)
        .map_err(|e| results_error(py, e))?;
    Ok(PyRows {
        rows: file.rows,
        label: path.to_string(),
    })
}

/// A solved measurement: the JSON object of `polycal solve --format json`, the solution
/// (for covariances) and the result rows (for comparisons).
#[pyclass(name = "SolveResult", module = "polycal._polycal", frozen)]
struct PySolveResult {
    json: String,
    solution: Solution,
    rows: Vec<ResultRow>,
    label: String,
}

#[pymethods]
impl PySolveResult {
    /// The JSON object `polycal solve --format json` prints.
    fn json(&self) -> String {
        self.json.clone()
    }

    /// The result rows (`--format csv`), for `compare`.
    fn rows(&self) -> PyRows {
        PyRows {
            rows: self.rows.clone(),
            label: self.label.clone(),
        }
    }

    /// The table angle of every encoder position, degrees (`step_angle_deg`).
    fn encoder_angle_deg(&self) -> Vec<f64> {
        let positions = self.solution.encoder_error.len();
        (0..positions)
            .map(|p| polycal::measurement::step_angle_deg(p as u32, positions))
            .collect()
    }

    /// The fit's covariance of a family (σ²Q, arcsec²): its size n and the n × n values,
    /// row-major; `None` when σ is unknown.
    fn covariance(&self, py: Python<'_>, family: &str) -> PyResult<Option<(usize, Vec<f64>)>> {
        let family = match family {
            "pitch_deviation" => Quantity::PitchDeviation,
            "face_deviation" => Quantity::FaceDeviation,
            "encoder_error" => Quantity::EncoderError,
            "setup_error" => Quantity::SetupError,
            other => {
                return Err(PyValueError::new_err(format!(
                    "family {other:?}: expected pitch_deviation, face_deviation, encoder_error or setup_error"
                )));
            }
        };
        Ok(py.detach(|| self.solution.family_covariance(family)))
    }
}

/// Why an evaluation without the GIL failed: the solver's refusal (a `DesignError` or a
/// `PolycalError`) or another's message.
enum Failure {
    Solve(Box<SolveError>),
    Other(String),
}

/// The Monte Carlo option: a number of trials or `"adaptive"`.
fn trials(monte_carlo: Option<&Bound<'_, PyAny>>) -> PyResult<Option<Trials>> {
    let Some(value) = monte_carlo else {
        return Ok(None);
    };
    if let Ok(text) = value.extract::<String>() {
        return match text.as_str() {
            "adaptive" => Ok(Some(Trials::Adaptive {
                significant_digits: 2,
                max_trials: 10_000_000,
            })),
            other => Err(PyValueError::new_err(format!(
                "monte_carlo: expected a number of trials or \"adaptive\", got {other:?}"
            ))),
        };
    }
    let count: usize = value.extract().map_err(|_| {
        PyValueError::new_err("monte_carlo: expected a number of trials or \"adaptive\"")
    })?;
    Ok(Some(Trials::Fixed(count)))
}

fn sigma(value: Option<f64>) -> PyResult<Option<Sigma>> {
    value
        .map(|s| Sigma::new(s).map_err(|e| PyValueError::new_err(format!("sigma: {e}"))))
        .transpose()
}

/// Solves a measurement set as `polycal solve` does: the closed form or least squares,
/// the budget's U and k, and Monte Carlo when asked. The GIL is released meanwhile.
#[pyfunction]
#[pyo3(signature = (ms, method="auto", sigma=None, budget=None, monte_carlo=None, seed=1))]
fn solve(
    py: Python<'_>,
    ms: &PyMeasurementSet,
    method: &str,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
    monte_carlo: Option<&Bound<'_, PyAny>>,
    seed: u64,
) -> PyResult<PySolveResult> {
    let method = match method {
        "auto" => Method::Auto,
        "closed-form" => Method::ClosedForm,
        "lsq" => Method::LeastSquares,
        "dense" => Method::Dense,
        other => {
            return Err(PyValueError::new_err(format!(
                "method {other:?}: expected auto, closed-form, lsq or dense"
            )));
        }
    };
    let options = SolveOptions::new()
        .with_method(method)
        .with_sigma_opt(self::sigma(sigma)?);
    let trials = trials(monte_carlo)?;
    if trials.is_some() && budget.is_none() {
        return Err(PyValueError::new_err(
            "monte_carlo needs a budget: the Monte Carlo propagates the instrument budget with the reading noise",
        ));
    }
    let set = &ms.inner;
    let budget = budget.map(|b| &b.inner);
    let done = py.detach(|| {
        if set.has_shifts() && budget.is_some() {
            return Err(Failure::Other(format!(
                "{}: an instrument budget is not supported for shifted mountings",
                set.source
            )));
        }
        let (solution, report) = if set.has_shifts() && ShiftGeometry::of(set).is_sub_pitch() {
            match solve_shifted(set, &options) {
                Ok(solved) => {
                    let report = SolveReport::sub_pitch(&solved, None);
                    (solved.solution.clone(), report)
                }
                Err(e) => return Err(Failure::Solve(Box::new(e))),
            }
        } else {
            match polycal::solve::solve(set, &options) {
                Ok(solution) => {
                    let report = SolveReport::new(&solution, None);
                    (solution, report)
                }
                Err(e) => return Err(Failure::Solve(Box::new(e))),
            }
        };
        let gum = match budget.map(|b| evaluate(set, &solution, b)).transpose() {
            Ok(gum) => gum,
            Err(e) => return Err(Failure::Other(e.to_string())),
        };
        let mut report = report;
        if let Some(gum) = &gum {
            report = report.with_uncertainty(gum);
        }
        if let (Some(trials), Some(budget), Some(gum)) = (trials, budget, &gum) {
            let options = McOptions::new(trials)
                .with_seed(seed)
                .with_significant_digits(2)
                .with_solver(McSolver::Auto);
            match polycal::uncertainty::calibration::monte_carlo(
                set, &solution, budget, gum, &options,
            ) {
                Ok(mc) => report = report.with_monte_carlo(mc),
                Err(e) => return Err(Failure::Other(e.to_string())),
            }
        }
        let json = polycal::output::to_json(&report).map_err(|e| Failure::Other(e.to_string()))?;
        let rows = polycal::output::result_rows_with(&solution, gum.as_ref());
        Ok((solution, rows, json))
    });
    match done {
        Ok((solution, rows, json)) => Ok(PySolveResult {
            json,
            solution,
            rows,
            label: set.source.clone(),
        }),
        Err(Failure::Solve(e)) => Err(solve_error(py, *e)),
        Err(Failure::Other(message)) => Err(PolycalError::new_err(message)),
    }
}

/// Compares two results by En as `polycal compare` does; returns its JSON object.
#[pyfunction]
#[pyo3(signature = (a, b, correlation=0.0, include_setup=false))]
fn compare_rows(
    py: Python<'_>,
    a: &PyRows,
    b: &PyRows,
    correlation: f64,
    include_setup: bool,
) -> PyResult<String> {
    let options = CompareOptions::new()
        .with_correlation(correlation)
        .with_include_setup(include_setup)
        .with_labels(a.label.clone(), b.label.clone());
    let comparison: Comparison = py
        .detach(|| compare(&a.rows, &b.rows, &options))
        .map_err(refusal)?;
    to_json(&comparison)
}

/// Simulates a run with a known truth (`polycal simulate`): the set and the truth's JSON.
#[pyfunction]
#[pyo3(signature = (faces=24, ac_faces=vec![1, 2], cycles=6, closing=true, bidirectional=false, noise=0.05, pitch_spread=None, setup_spread=None, step_seconds=None, setups=1, setup_shift_faces=None, seed=1))]
#[allow(clippy::too_many_arguments)]
fn simulate(
    py: Python<'_>,
    faces: usize,
    ac_faces: Vec<usize>,
    cycles: u32,
    closing: bool,
    bidirectional: bool,
    noise: f64,
    pitch_spread: Option<f64>,
    setup_spread: Option<f64>,
    step_seconds: Option<f64>,
    setups: u32,
    setup_shift_faces: Option<usize>,
    seed: u64,
) -> PyResult<(PyMeasurementSet, String)> {
    let defaults = SimulationConfig::default();
    let config = SimulationConfig {
        faces,
        ac_faces,
        cycles,
        closing,
        bidirectional,
        noise_arcsec: noise,
        pitch_spread_arcsec: pitch_spread.unwrap_or(defaults.pitch_spread_arcsec),
        setup_error_spread_arcsec: setup_spread.unwrap_or(defaults.setup_error_spread_arcsec),
        step_seconds: step_seconds.unwrap_or(defaults.step_seconds),
        setups,
        setup_shift_faces: setup_shift_faces.unwrap_or(defaults.setup_shift_faces),
        seed,
        ..defaults
    };
    let (set, truth) = py
        .detach(|| polycal::simulate::simulate(&config))
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let truth = serde_json::to_string(&truth).map_err(refusal)?;
    Ok((PyMeasurementSet { inner: set }, truth))
}

/// Diagnoses a measurement set as `polycal diagnose` does; returns its JSON object (the
/// budget acts on the final model).
#[pyfunction]
#[pyo3(signature = (ms, truth=None, sigma=None, budget=None))]
fn diagnose(
    py: Python<'_>,
    ms: &PyMeasurementSet,
    truth: Option<&str>,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
) -> PyResult<String> {
    let truth = truth
        .map(|t| Truth::from_json_bytes(t.as_bytes(), "<truth>"))
        .transpose()
        .map_err(|e| PyValueError::new_err(format!("truth: {e}")))?;
    let options = DiagnoseOptions::new().with_sigma_opt(self::sigma(sigma)?);
    let set = &ms.inner;
    let budget = budget.map(|b| &b.inner);
    let done = py.detach(|| {
        let found = diagnose_set(set, &options).map_err(|e| Failure::Solve(Box::new(e)))?;
        let mut report =
            DiagnoseReport::new(&found, truth.as_ref(), None).with_residuals(&found, set);
        if let Some(b) = budget {
            let gum = evaluate(set, &found.after, b).map_err(|e| Failure::Other(e.to_string()))?;
            report.after = report.after.with_uncertainty(&gum);
        }
        polycal::output::to_json(&report).map_err(|e| Failure::Other(e.to_string()))
    });
    done.map_err(|failure| match failure {
        Failure::Solve(e) => solve_error(py, *e),
        Failure::Other(message) => PolycalError::new_err(message),
    })
}

/// A self-calibration set (docs/FORMAT.md §9.2).
#[pyclass(name = "SelfcalSet", module = "polycal._polycal", frozen)]
struct PySelfcalSet {
    inner: SelfcalSet,
    name: String,
}

#[pymethods]
impl PySelfcalSet {
    fn __len__(&self) -> usize {
        self.inner.readings.len()
    }
}

/// Reads a self-calibration file (`path`) or its text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<text>", positions=None))]
fn read_selfcal(
    py: Python<'_>,
    path: Option<&str>,
    text: Option<&str>,
    name: &str,
    positions: Option<usize>,
) -> PyResult<PySelfcalSet> {
    let read = read_source(
        path,
        text,
        name,
        |p| SelfcalSet::read_path(p, positions),
        |bytes, name| SelfcalSet::read_from(bytes, name, positions),
    )?;
    let name = path.unwrap_or(name).to_string();
    read.map(|inner| PySelfcalSet { inner, name })
        .map_err(|e| selfcal_error(py, e))
}

/// Builds a self-calibration set from columns, checked as the file reader checks them.
#[pyfunction]
#[pyo3(signature = (cycle, step, head, head_angle, reading, direction=None, time=None, positions=None, name="<arrays>"))]
#[allow(clippy::too_many_arguments)]
fn selfcal_set_from_columns(
    py: Python<'_>,
    cycle: Vec<u32>,
    step: Vec<usize>,
    head: Vec<u32>,
    head_angle: Vec<f64>,
    reading: Vec<f64>,
    direction: Option<Vec<String>>,
    time: Option<Vec<Option<f64>>>,
    positions: Option<usize>,
    name: &str,
) -> PyResult<PySelfcalSet> {
    let n = reading.len();
    for (column, len) in [
        ("cycle", cycle.len()),
        ("step", step.len()),
        ("head", head.len()),
        ("head_angle", head_angle.len()),
        ("direction", direction.as_ref().map_or(n, Vec::len)),
        ("time", time.as_ref().map_or(n, Vec::len)),
    ] {
        if len != n {
            return Err(PyValueError::new_err(format!(
                "column {column} has {len} values, reading has {n}"
            )));
        }
    }
    let mut readings = Vec::with_capacity(n);
    for i in 0..n {
        readings.push(polycal::selfcal::HeadReading {
            cycle: cycle[i],
            step: step[i],
            head: head[i],
            head_angle_deg: head_angle[i],
            reading_arcsec: reading[i],
            direction: direction_at(direction.as_deref(), i)?,
            time_seconds: time.as_ref().and_then(|t| t[i]),
            line: 0,
        });
    }
    let inner = py
        .detach(|| SelfcalSet::from_readings(readings, positions))
        .map_err(|e| selfcal_error(py, e))?;
    Ok(PySelfcalSet {
        inner,
        name: name.to_string(),
    })
}

/// Self-calibrates the encoder as `polycal selfcal` does; returns its JSON object.
#[pyfunction]
#[pyo3(signature = (set, sigma=None, budget=None))]
fn selfcal(
    py: Python<'_>,
    set: &PySelfcalSet,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
) -> PyResult<String> {
    let options = SelfcalOptions::new().with_sigma_opt(self::sigma(sigma)?);
    let budget = budget.map(|b| &b.inner);
    let name = set.name.clone();
    py.detach(|| {
        let solution = polycal::selfcal::solve(&set.inner, &options).map_err(|e| e.to_string())?;
        let mut report = SelfcalReport::new(&solution, &name);
        if let Some(b) = budget {
            let u = polycal::selfcal::evaluate_budget(&solution, b).map_err(|e| e.to_string())?;
            report = report.with_uncertainty(&u);
        }
        report.to_json().map_err(|e| e.to_string())
    })
    .map_err(PolycalError::new_err)
}

/// The software version every JSON object carries.
#[pyfunction]
fn version() -> &'static str {
    polycal::output::SOFTWARE_VERSION
}

#[pymodule]
fn _polycal(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add("PolycalError", py.get_type::<PolycalError>())?;
    m.add("InputError", py.get_type::<InputError>())?;
    m.add("DesignError", py.get_type::<DesignError>())?;
    m.add_class::<PyMeasurementSet>()?;
    m.add_class::<PyBudget>()?;
    m.add_class::<PyRows>()?;
    m.add_class::<PySolveResult>()?;
    m.add_class::<PySelfcalSet>()?;
    m.add_function(wrap_pyfunction!(read_measurements, m)?)?;
    m.add_function(wrap_pyfunction!(measurement_set_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(read_budget, m)?)?;
    m.add_function(wrap_pyfunction!(read_results, m)?)?;
    m.add_function(wrap_pyfunction!(solve, m)?)?;
    m.add_function(wrap_pyfunction!(compare_rows, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(read_selfcal, m)?)?;
    m.add_function(wrap_pyfunction!(selfcal_set_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(selfcal, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    Ok(())
}
