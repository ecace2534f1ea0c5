//! The evaluations, each as its command makes it and returning its JSON object: solve
//! (with the budget and Monte Carlo), compare, kc, diagnose, selfcal.

use std::path::Path;
use std::sync::{Arc, OnceLock};

use polycal::compare::{CompareOptions, Comparison, VerdictRule, compare};
use polycal::diagnose::{DiagnoseOptions, diagnose as diagnose_set};
use polycal::input::Location;
use polycal::kc::{KcOptions, LabResult, ReferenceMethod};
use polycal::measurement::MeasurementSet;
use polycal::output::SolveReport;
use polycal::output::diagnose::DiagnoseReport;
use polycal::output::selfcal::SelfcalReport;
use polycal::results::{Quantity, ResultRow};
use polycal::selfcal::SelfcalOptions;
use polycal::simulate::{SimulateError, Truth};
use polycal::solve::sub_pitch::{ShiftGeometry, solve_shifted};
use polycal::solve::{Method, Solution, SolveError, SolveOptions};
use polycal::uncertainty::calibration::{McOptions, McSolver, evaluate};
use polycal::uncertainty::monte_carlo::Trials;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::sets::{PyBudget, PyMeasurementSet, PySelfcalSet};
use crate::state::{
    RowState, RowsState, columns_state, restorer, rows_file_from_state, rows_from_state, rows_state,
};
use crate::{PolycalError, file_error, input_error, refusal, solve_error, to_json};

/// The rows of a result (docs/FORMAT.md §3): a solve's, or a result file's.
#[pyclass(name = "ResultRows", module = "polycal._polycal", frozen)]
pub(crate) struct PyRows {
    pub(crate) rows: Vec<ResultRow>,
    pub(crate) label: String,
    /// The file the rows were read from (rows named by file and line in messages).
    pub(crate) file: Option<polycal::results::ResultFile>,
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

    /// Pickles the rows (and, for a file's, its name, the rows' lines and columns) as Python
    /// values: back equal to the bit.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (RowsState,))> {
        let file = self
            .file
            .as_ref()
            .map(|f| (f.source.clone(), f.lines.clone(), columns_state(&f.columns)));
        let state = (rows_state(&self.rows), self.label.clone(), file);
        Ok((restorer(py, "_restore_rows")?, (state,)))
    }
}

/// Reads a result file (docs/FORMAT.md §3), or a DCC certificate by its content (§13.3);
/// a file larger than polycal reads from one input is refused before it is read.
#[pyfunction]
pub(crate) fn read_results(py: Python<'_>, path: &str) -> PyResult<PyRows> {
    let (bytes, _) = polycal::input::read_bytes(std::path::Path::new(path)).map_err(|(_, e)| {
        if crate::is_not_found(&e) {
            return crate::file_not_found(py, path, &e);
        }
        input_error(py, format!("{path}: {e}"), Some(&Location::file_only(path)))
    })?;
    let file = polycal::results::read_results_from(bytes.as_slice(), path)
        .map_err(|e| file_error(py, e))?;
    Ok(PyRows {
        rows: file.rows.clone(),
        label: path.to_string(),
        file: Some(file),
    })
}

/// A solved measurement: the JSON object of `polycal solve --format json`, the solution
/// (for covariances) and the result rows (for comparisons).
///
/// It keeps the set and the solve's options: a pickled result carries its JSON, rows and
/// set, not the solution (whose cofactor is an operator, not data), and re-solves the set
/// with the same options — the same code on the same readings, the same bits — the first
/// time `covariance` is asked after the round trip.
#[pyclass(name = "SolveResult", module = "polycal._polycal", frozen)]
pub(crate) struct PySolveResult {
    pub(crate) json: String,
    /// Set when solved; after a pickle, on the first `covariance`.
    pub(crate) solution: OnceLock<Solution>,
    pub(crate) rows: Vec<ResultRow>,
    pub(crate) label: String,
    /// The set solved, shared with its `MeasurementSet`.
    pub(crate) set: Arc<MeasurementSet>,
    /// The solve's `method` and `sigma`, as given.
    pub(crate) method: String,
    pub(crate) sigma: Option<f64>,
    /// The number of encoder positions the solution has (α's length).
    pub(crate) positions: usize,
}

impl PySolveResult {
    /// The solution: the one solved, or after a pickle the set solved again.
    fn solution(&self, py: Python<'_>) -> PyResult<&Solution> {
        if let Some(solution) = self.solution.get() {
            return Ok(solution);
        }
        let options = solve_options(&self.method, self.sigma)?;
        let set = &self.set;
        let (solution, _) = py
            .detach(|| solve_set(set, &options))
            .map_err(|e| solve_error(py, e))?;
        // another thread may have set it meanwhile: the same solution either way
        Ok(self.solution.get_or_init(|| solution))
    }
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
            file: None,
        }
    }

    /// The table angle of every encoder position, degrees (`step_angle_deg`).
    fn encoder_angle_deg(&self) -> Vec<f64> {
        let positions = self.positions;
        (0..positions)
            .map(|p| polycal::measurement::step_angle_deg(p as u32, positions))
            .collect()
    }

    /// The nominal angle of every face f = 1 … N, degrees: f·360°/N (`step_angle_deg`,
    /// face N at 360°).
    fn face_angle_deg(&self) -> Vec<f64> {
        let faces = self.set.faces;
        (1..=faces)
            .map(|f| polycal::measurement::step_angle_deg(f as u32, faces))
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
        let solution = self.solution(py)?;
        Ok(py.detach(|| solution.family_covariance(family)))
    }

    /// Pickles the result as its JSON, rows and set (module documentation of the type):
    /// back equal to the bit.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (SolveState,))> {
        let state = (
            self.json.clone(),
            rows_state(&self.rows),
            self.label.clone(),
            Py::new(
                py,
                PyMeasurementSet {
                    inner: Arc::clone(&self.set),
                    comments: Vec::new(),
                },
            )?,
            self.method.clone(),
            self.sigma,
            self.positions,
        );
        Ok((restorer(py, "_restore_solve_result")?, (state,)))
    }
}

/// The options of `solve(method=, sigma=)`.
pub(crate) fn solve_options(method: &str, sigma: Option<f64>) -> PyResult<SolveOptions> {
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
    Ok(SolveOptions::new()
        .with_method(method)
        .with_sigma_opt(crate::sigma(sigma)?))
}

/// Solves a set as `polycal solve` does: by cosets for sub-pitch mountings, else the
/// closed form or least squares; the solution and its report.
fn solve_set(
    set: &MeasurementSet,
    options: &SolveOptions,
) -> Result<(Solution, SolveReport), SolveError> {
    if set.has_shifts() && ShiftGeometry::of(set).is_sub_pitch() {
        let solved = solve_shifted(set, options)?;
        let report = SolveReport::sub_pitch(&solved, None);
        Ok((solved.solution, report))
    } else {
        let solution = polycal::solve::solve(set, options)?;
        let report = SolveReport::new(&solution, None);
        Ok((solution, report))
    }
}

/// Why an evaluation without the GIL failed: the solver's refusal (a `DesignError` or a
/// `PolycalError`) or another's message.
pub(crate) enum Failure {
    Solve(Box<SolveError>),
    Other(String),
}

/// The Monte Carlo options of `monte_carlo` (a number of trials or `"adaptive"`) and
/// `seed`, as the commands' `--monte-carlo` and `--seed` make them; `None` without
/// `monte_carlo`, refused without a budget, which is what the Monte Carlo propagates.
pub(crate) fn mc_options(
    monte_carlo: Option<&Bound<'_, PyAny>>,
    has_budget: bool,
    seed: u64,
) -> PyResult<Option<McOptions<'static>>> {
    let Some(value) = monte_carlo else {
        return Ok(None);
    };
    let trials = if let Ok(text) = value.extract::<String>() {
        match text.as_str() {
            "adaptive" => Trials::Adaptive {
                significant_digits: 2,
                max_trials: 10_000_000,
            },
            other => {
                return Err(PyValueError::new_err(format!(
                    "monte_carlo: expected a number of trials or \"adaptive\", got {other:?}"
                )));
            }
        }
    } else {
        Trials::Fixed(value.extract().map_err(|_| {
            PyValueError::new_err("monte_carlo: expected a number of trials or \"adaptive\"")
        })?)
    };
    if !has_budget {
        return Err(PyValueError::new_err(
            "monte_carlo needs a budget: the Monte Carlo propagates the instrument budget with the reading noise",
        ));
    }
    Ok(Some(
        McOptions::new(trials)
            .with_seed(seed)
            .with_significant_digits(2)
            .with_solver(McSolver::Auto),
    ))
}

/// Solves a measurement set as `polycal solve` does: the closed form or least squares,
/// the budget's U and k, and Monte Carlo when asked. The GIL is released meanwhile.
#[pyfunction]
#[pyo3(signature = (ms, method="auto", sigma=None, budget=None, monte_carlo=None, seed=1))]
pub(crate) fn solve(
    py: Python<'_>,
    ms: &PyMeasurementSet,
    method: &str,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
    monte_carlo: Option<&Bound<'_, PyAny>>,
    seed: u64,
) -> PyResult<PySolveResult> {
    let options = solve_options(method, sigma)?;
    let mc = mc_options(monte_carlo, budget.is_some(), seed)?;
    let set = &ms.inner;
    let budget = budget.map(|b| &b.inner);
    let done = py.detach(|| {
        if set.has_shifts() && budget.is_some() {
            return Err(Failure::Other(format!(
                "{}: an instrument budget is not supported for shifted mountings",
                set.source
            )));
        }
        let (solution, report) =
            solve_set(set, &options).map_err(|e| Failure::Solve(Box::new(e)))?;
        let gum = match budget.map(|b| evaluate(set, &solution, b)).transpose() {
            Ok(gum) => gum,
            Err(e) => return Err(Failure::Other(e.to_string())),
        };
        let mut report = report;
        if let Some(gum) = &gum {
            report = report.with_uncertainty(gum);
        }
        if let (Some(options), Some(budget), Some(gum)) = (&mc, budget, &gum) {
            match polycal::uncertainty::calibration::monte_carlo(
                set, &solution, budget, gum, options,
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
            positions: solution.encoder_error.len(),
            solution: OnceLock::from(solution),
            rows,
            label: set.source.clone(),
            set: Arc::clone(&ms.inner),
            method: method.to_string(),
            sigma,
        }),
        Err(Failure::Solve(e)) => Err(solve_error(py, *e)),
        Err(Failure::Other(message)) => Err(PolycalError::new_err(message)),
    }
}

/// Compares two results by En, with one verdict for the whole comparison (`verdict`:
/// `vector` or `en`, docs/FORMAT.md §5.4), as `polycal compare` does; returns its JSON
/// object.
#[pyfunction]
#[pyo3(signature = (a, b, correlation=0.0, include_setup=false, verdict="vector"))]
pub(crate) fn compare_rows(
    py: Python<'_>,
    a: &PyRows,
    b: &PyRows,
    correlation: f64,
    include_setup: bool,
    verdict: &str,
) -> PyResult<String> {
    let verdict = verdict
        .parse::<VerdictRule>()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let options = CompareOptions::new()
        .with_correlation(correlation)
        .with_include_setup(include_setup)
        .with_verdict(verdict)
        .with_labels(a.label.clone(), b.label.clone());
    let comparison: Comparison = py
        .detach(|| compare(&a.rows, &b.rows, &options))
        .map_err(refusal)?;
    to_json(&comparison)
}

/// Evaluates a key comparison as `polycal kc` does (docs/FORMAT.md §12); returns its JSON
/// object and, with `anonymise` (`--anonymise`: Draft A), the key's CSV text. `labs` and
/// `pilot` are (name, rows) pairs in order; `key` is a key's CSV text read (Draft B: its
/// codes), else the codes are drawn in an order from `seed`.
#[pyfunction]
#[pyo3(signature = (labs, pilot=Vec::new(), quantity="pitch_deviation", method="weighted-mean", keep=Vec::new(), not_in_reference=Vec::new(), link=None, monte_carlo=None, anonymise=false, key=None, seed=0))]
#[allow(clippy::too_many_arguments)] // the keyword arguments of `polycal kc`'s flags
pub(crate) fn kc(
    py: Python<'_>,
    labs: Vec<(String, PyRef<'_, PyRows>)>,
    pilot: Vec<(String, PyRef<'_, PyRows>)>,
    quantity: &str,
    method: &str,
    keep: Vec<String>,
    not_in_reference: Vec<String>,
    link: Option<String>,
    monte_carlo: Option<usize>,
    anonymise: bool,
    key: Option<String>,
    seed: u64,
) -> PyResult<(String, Option<String>)> {
    let quantity = polycal::kc::compared_quantity(quantity)
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let method = method
        .parse::<ReferenceMethod>()
        .map_err(|e| PyValueError::new_err(e.to_string()))?;
    let (mut labs, pilot) = (lab_results(&labs), lab_results(&pilot));
    let mut linked = match &link {
        Some(text) => Some(polycal::kc::read_json(text.as_bytes(), "link").map_err(refusal)?),
        None => None,
    };
    let (mut keep, mut not_in_reference) = (keep, not_in_reference);
    // Draft A as `--anonymise` makes it: the laboratories, the names the options give and
    // the linked comparison's laboratories by their codes
    let code_key = if anonymise {
        let read = match &key {
            Some(text) => {
                Some(polycal::kc::CodeKey::read(text.as_bytes(), "key").map_err(refusal)?)
            }
            None => None,
        };
        let (coded, code_key) =
            polycal::kc::anonymise(&labs, &pilot, read.as_ref(), seed).map_err(refusal)?;
        labs = coded;
        keep = code_key.coded_names(keep.iter().map(String::as_str));
        not_in_reference = code_key.coded_names(not_in_reference.iter().map(String::as_str));
        linked = linked.map(|l| code_key.coded_comparison(&l));
        Some(code_key)
    } else {
        None
    };
    let options = KcOptions::new()
        .with_quantity(quantity)
        .with_method(method)
        .with_keep(keep)
        .with_not_in_reference(not_in_reference);
    let options = match monte_carlo {
        Some(draws) => options.with_monte_carlo(draws),
        None => options,
    };
    let mut comparison = py
        .detach(|| polycal::kc::evaluate(&labs, &pilot, &options))
        .map_err(refusal)?;
    if let Some(linked) = &linked {
        polycal::kc::link(&mut comparison, linked).map_err(refusal)?;
    }
    let key_text = match &code_key {
        Some(code_key) => {
            comparison.notes.push(polycal::kc::DRAFT_A_NOTE.to_string());
            let mut bytes = Vec::new();
            polycal::output::kc::write_key_csv(&mut bytes, code_key)
                .map_err(|e| PyValueError::new_err(e.to_string()))?;
            Some(String::from_utf8(bytes).map_err(|e| PyValueError::new_err(e.to_string()))?)
        }
        None => None,
    };
    Ok((to_json(&comparison)?, key_text))
}

/// The (name, rows) pairs of `kc`'s `labs` and `pilot` as the library's results, in order.
fn lab_results(list: &[(String, PyRef<'_, PyRows>)]) -> Vec<LabResult> {
    list.iter()
        .map(|(name, rows)| match &rows.file {
            Some(file) => LabResult::from_file(name.clone(), file.clone()),
            None => LabResult::from_rows(name.clone(), rows.rows.clone()),
        })
        .collect()
}

/// The names of the quantities a key comparison compares that every laboratory's and
/// every pilot repeat's result has rows of, in the order `polycal kc` without `--quantity`
/// compares them (`polycal::kc::shared_quantities`); refused naming the results that lack
/// each when there is none.
#[pyfunction]
#[pyo3(signature = (labs, pilot=Vec::new()))]
pub(crate) fn shared_quantities(
    labs: Vec<(String, PyRef<'_, PyRows>)>,
    pilot: Vec<(String, PyRef<'_, PyRows>)>,
) -> PyResult<Vec<String>> {
    let shared = polycal::kc::shared_quantities(&lab_results(&labs), &lab_results(&pilot))
        .map_err(refusal)?;
    Ok(shared.iter().map(|q| q.name().to_string()).collect())
}

/// Diagnoses a measurement set as `polycal diagnose` does; returns its JSON object (the
/// budget, and the Monte Carlo when asked, act on the final model).
#[pyfunction]
/// `truth` is a truth's JSON text, `truth_path` a truth file (docs/FORMAT.md §4), read
/// as `--truth` reads it: a missing file is `FileNotFound`, a file that is not a valid
/// truth an `InputError` naming it (line and column for bad JSON).
#[pyo3(signature = (ms, truth=None, sigma=None, budget=None, monte_carlo=None, seed=1, truth_path=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn diagnose(
    py: Python<'_>,
    ms: &PyMeasurementSet,
    truth: Option<&str>,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
    monte_carlo: Option<&Bound<'_, PyAny>>,
    seed: u64,
    truth_path: Option<&str>,
) -> PyResult<String> {
    let truth = match (truth, truth_path) {
        (Some(_), Some(_)) => {
            return Err(PyValueError::new_err(
                "give a truth or a truth file, one of them",
            ));
        }
        (Some(t), None) => Some(
            Truth::from_json_bytes(t.as_bytes(), "<truth>")
                .map_err(|e| PyValueError::new_err(format!("truth: {e}")))?,
        ),
        (None, Some(path)) => Some(Truth::read_path(Path::new(path)).map_err(|e| match &e {
            SimulateError::Io { source, .. } if crate::is_not_found(source) => {
                crate::file_not_found(py, path, source)
            }
            SimulateError::Json { location, .. } => input_error(py, e.to_string(), Some(location)),
            _ => input_error(py, e.to_string(), Some(&Location::file_only(path))),
        })?),
        (None, None) => None,
    };
    let options = DiagnoseOptions::new().with_sigma_opt(crate::sigma(sigma)?);
    let mc = mc_options(monte_carlo, budget.is_some(), seed)?;
    let set = &ms.inner;
    let budget = budget.map(|b| &b.inner);
    let done = py.detach(|| {
        let found = diagnose_set(set, &options).map_err(|e| Failure::Solve(Box::new(e)))?;
        let mut report =
            DiagnoseReport::new(&found, truth.as_ref(), None).with_residuals(&found, set);
        if let Some(b) = budget {
            let gum = evaluate(set, &found.after, b).map_err(|e| Failure::Other(e.to_string()))?;
            report.after = report.after.with_uncertainty(&gum);
            if let Some(options) = &mc {
                let mc = polycal::uncertainty::calibration::monte_carlo(
                    set,
                    &found.after,
                    b,
                    &gum,
                    options,
                )
                .map_err(|e| Failure::Other(e.to_string()))?;
                report.after = report.after.with_monte_carlo(mc);
            }
        }
        polycal::output::to_json(&report).map_err(|e| Failure::Other(e.to_string()))
    });
    done.map_err(|failure| match failure {
        Failure::Solve(e) => solve_error(py, *e),
        Failure::Other(message) => PolycalError::new_err(message),
    })
}

/// Self-calibrates the encoder as `polycal selfcal` does; returns its JSON object (with
/// the budget's Monte Carlo when asked).
#[pyfunction]
#[pyo3(signature = (set, sigma=None, budget=None, monte_carlo=None, seed=1))]
pub(crate) fn selfcal(
    py: Python<'_>,
    set: &PySelfcalSet,
    sigma: Option<f64>,
    budget: Option<&PyBudget>,
    monte_carlo: Option<&Bound<'_, PyAny>>,
    seed: u64,
) -> PyResult<String> {
    let options = SelfcalOptions::new().with_sigma_opt(crate::sigma(sigma)?);
    let mc = mc_options(monte_carlo, budget.is_some(), seed)?;
    let budget = budget.map(|b| &b.inner);
    let name = set.name.clone();
    py.detach(|| {
        let solution = polycal::selfcal::solve(&set.inner, &options).map_err(|e| e.to_string())?;
        let mut report = SelfcalReport::new(&solution, &name);
        if let Some(b) = budget {
            let u = polycal::selfcal::evaluate_budget(&solution, b).map_err(|e| e.to_string())?;
            report = report.with_uncertainty(&u);
            if let Some(options) = &mc {
                let mc = polycal::selfcal::monte_carlo(&set.inner, &solution, b, &u, options)
                    .map_err(|e| e.to_string())?;
                report = report.with_monte_carlo(mc);
            }
        }
        report.to_json().map_err(|e| e.to_string())
    })
    .map_err(PolycalError::new_err)
}

/// The rows a pickled state (`ResultRows.__reduce__`) describes.
#[pyfunction]
pub(crate) fn _restore_rows(state: RowsState) -> PyResult<PyRows> {
    let (rows, label, file) = rows_file_from_state(state)?;
    Ok(PyRows { rows, label, file })
}

/// The pickled state of a solve result: the JSON, the rows, the label, the set, the
/// method and σ as given, and α's length.
pub(crate) type SolveState = (
    String,
    Vec<RowState>,
    String,
    Py<PyMeasurementSet>,
    String,
    Option<f64>,
    usize,
);

/// The result a pickled state (`SolveResult.__reduce__`) describes.
#[pyfunction]
pub(crate) fn _restore_solve_result(state: SolveState) -> PyResult<PySolveResult> {
    let (json, rows, label, set, method, sigma, positions) = state;
    solve_options(&method, sigma)?;
    Ok(PySolveResult {
        json,
        solution: OnceLock::new(),
        rows: rows_from_state(rows)?,
        label,
        set: Arc::clone(&set.get().inner),
        method,
        sigma,
        positions,
    })
}

/// Evaluates a standard's history as `polycal history` does (docs/FORMAT.md §13.2);
/// returns its JSON object. `calibrations` are (rows, date) pairs, each date a day
/// `YYYY-MM-DD`; `at` defaults to today (UTC).
#[pyfunction]
#[pyo3(signature = (calibrations, at=None, quantity="pitch_deviation", max_u=None))]
pub(crate) fn history(
    py: Python<'_>,
    calibrations: Vec<(PyRef<'_, PyRows>, String)>,
    at: Option<&str>,
    quantity: &str,
    max_u: Option<f64>,
) -> PyResult<String> {
    use polycal::history::{Calibration, HistoryOptions};
    let quantity = polycal::results::Quantity::from_name(quantity)
        .ok_or_else(|| PyValueError::new_err(format!("unknown quantity {quantity:?}")))?;
    let at = at.map_or_else(polycal::clock::today, str::to_string);
    let mut options = HistoryOptions::new(&at)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .with_quantity(quantity);
    if let Some(max_u) = max_u {
        if !(max_u > 0.0 && max_u.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "max_u = {max_u}: a positive number of arcseconds"
            )));
        }
        options = options.with_max_expanded_u(max_u);
    }
    let calibrations = calibrations
        .iter()
        .map(|(rows, date)| {
            let file = rows
                .file
                .clone()
                .unwrap_or_else(|| polycal::results::ResultFile {
                    source: rows.label.clone(),
                    rows: rows.rows.clone(),
                    lines: Vec::new(),
                    columns: Vec::new(),
                });
            Calibration::new(date, file).map_err(|e| PyValueError::new_err(e.to_string()))
        })
        .collect::<PyResult<Vec<_>>>()?;
    let history = py
        .detach(|| polycal::history::evaluate(&calibrations, &options))
        .map_err(refusal)?;
    to_json(&history)
}
