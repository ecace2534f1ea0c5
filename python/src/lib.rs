//! `polycal._polycal`: the library's entry points for Python, as thin as `cli/` is for the
//! command line. It parses Python's arguments, calls the library with the GIL released,
//! and hands back the very JSON objects the commands print (docs/FORMAT.md §5), which
//! the Python package (`polycal/__init__.py`) turns into numpy arrays. No maths here.
//!
//! Every refusal of the library becomes a Python exception with the library's one-line
//! message: `InputError` (with `path`, `line`, `column`) for a file or text that is not
//! valid, `DesignError` (with `lost_harmonics`) for a design that cannot determine some
//! harmonics, `FileNotFound` (a `PolycalError` and a `FileNotFoundError`, with `filename`,
//! `path` and `errno`) for a file that is not there, `PolycalError` for the rest,
//! `ValueError` for a bad argument. A Rust panic becomes `pyo3_runtime.PanicException`,
//! never an abort. The cautions the commands print as `warning:` lines are
//! `PolycalWarning`s (a `UserWarning`). Every exception class is `polycal.`'s
//! (`type(e).__module__ == "polycal"`): the package re-exports them, so they pickle.
//!
//! Sets, budgets, result rows and solve results pickle (`state.rs`) through their own fields as
//! Python values and come back equal to the bit.
//!
//! `Session` (`lab.rs`) is the run's session (docs/FORMAT.md §7.6) with the run directory
//! as its store, for lab software in Python that drives its own instruments.

mod evaluate;
mod lab;
mod sets;
mod simulate;
mod state;
mod wire;

use std::path::Path;

use polycal::input::FileError;
use polycal::input::Location;
use polycal::measurement::{Direction, Sigma};
use polycal::solve::SolveError;
use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyUserWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PyDict, PyTuple, PyType};

use evaluate::{PyRows, PySolveResult};
use sets::{PyBudget, PyMeasurementSet, PySelfcalSet};

create_exception!(
    polycal,
    PolycalError,
    PyException,
    "A refusal of the polycal library."
);
create_exception!(
    polycal,
    InputError,
    PolycalError,
    "A file or text that is not valid: `path`, `line` and `column` say where (0 when unknown)."
);
create_exception!(
    polycal,
    DesignError,
    PolycalError,
    "A design that cannot determine some harmonics: `lost_harmonics` lists them."
);

create_exception!(
    polycal,
    PolycalWarning,
    PyUserWarning,
    "A caution of the polycal library (what the command line prints as a `warning:` line)."
);

/// The class `FileNotFound(PolycalError, FileNotFoundError)`, made when the module is.
static FILE_NOT_FOUND: PyOnceLock<Py<PyType>> = PyOnceLock::new();

/// Makes the class `FileNotFound`: a refusal of the library that a Python user catches as
/// the built-in `FileNotFoundError` too.
fn file_not_found_class(py: Python<'_>) -> PyResult<Bound<'_, PyType>> {
    let builtins = py.import("builtins")?;
    let bases = PyTuple::new(
        py,
        [
            py.get_type::<PolycalError>().into_any(),
            builtins.getattr("FileNotFoundError")?,
        ],
    )?;
    let namespace = PyDict::new(py);
    namespace.set_item("__module__", "polycal")?;
    namespace.set_item(
        "__doc__",
        "A file that is not there: a `PolycalError` and a `FileNotFoundError`, with \
         `filename` and `path` the path as given and `errno` ENOENT.",
    )?;
    let class = builtins
        .getattr("type")?
        .call1(("FileNotFound", bases, namespace))?;
    Ok(class.cast_into::<PyType>()?)
}

/// A `FileNotFound` for `path` (the path as given), from the error the system gave.
pub(crate) fn file_not_found(py: Python<'_>, path: &str, source: &std::io::Error) -> PyErr {
    let Some(class) = FILE_NOT_FOUND.get(py) else {
        return PolycalError::new_err(format!("{path}: {source}"));
    };
    // ENOENT is 2 on every system Python runs on; the system's own number when it gave one
    let errno = source.raw_os_error().unwrap_or(2);
    match class
        .bind(py)
        .call1((errno, "No such file or directory", path))
    {
        Ok(value) => {
            let _ = value.setattr("path", path);
            PyErr::from_value(value)
        }
        Err(e) => e,
    }
}

/// Whether an input/output error says the file is not there.
pub(crate) fn is_not_found(source: &std::io::Error) -> bool {
    source.kind() == std::io::ErrorKind::NotFound
}

/// An `InputError` at a location (or none).
pub(crate) fn input_error(py: Python<'_>, message: String, at: Option<&Location>) -> PyErr {
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

/// A table file's refusal (a measurement, self-calibration or result file): Python's
/// `FileNotFoundError` for a file that is not there, an `InputError` at the refusal's
/// location otherwise.
pub(crate) fn file_error(py: Python<'_>, e: FileError) -> PyErr {
    if let FileError::Io { file, source } = &e
        && is_not_found(source)
    {
        return file_not_found(py, file, source);
    }
    let at = e.location().cloned();
    input_error(py, e.to_string(), at.as_ref())
}

pub(crate) fn solve_error(py: Python<'_>, e: SolveError) -> PyErr {
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

pub(crate) fn refusal(e: impl std::fmt::Display) -> PyErr {
    PolycalError::new_err(e.to_string())
}

pub(crate) fn to_json<T: serde::Serialize>(object: &T) -> PyResult<String> {
    polycal::output::to_json(object).map_err(refusal)
}

/// Reads `path`, or `text` named `name`, with the reader `read`.
pub(crate) fn read_source<T, E>(
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

/// The direction of reading `i` (`cw` when the column is not given).
pub(crate) fn direction_at(direction: Option<&[String]>, i: usize) -> PyResult<Direction> {
    match direction.map(|d| d[i].as_str()) {
        None | Some("cw") => Ok(Direction::Cw),
        Some("ccw") => Ok(Direction::Ccw),
        Some(other) => Err(PyValueError::new_err(format!(
            "column direction, index {i}: expected cw or ccw, got {other:?}"
        ))),
    }
}

pub(crate) fn sigma(value: Option<f64>) -> PyResult<Option<Sigma>> {
    value
        .map(|s| Sigma::new(s).map_err(|e| PyValueError::new_err(format!("sigma: {e}"))))
        .transpose()
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
    m.add("PolycalWarning", py.get_type::<PolycalWarning>())?;
    let file_not_found =
        FILE_NOT_FOUND.get_or_try_init(py, || file_not_found_class(py).map(Bound::unbind))?;
    m.add("FileNotFound", file_not_found.bind(py))?;
    m.add_class::<PyMeasurementSet>()?;
    m.add_class::<PyBudget>()?;
    m.add_class::<PyRows>()?;
    m.add_class::<PySolveResult>()?;
    m.add_class::<PySelfcalSet>()?;
    m.add_class::<lab::PySession>()?;
    m.add_class::<lab::PyAction>()?;
    m.add_class::<wire::PyTableWire>()?;
    m.add_class::<wire::PyAcWire>()?;
    m.add_class::<wire::PyWireAction>()?;
    m.add_function(wrap_pyfunction!(sets::read_measurements, m)?)?;
    m.add_function(wrap_pyfunction!(sets::measurement_set_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(sets::check_columns_fit, m)?)?;
    m.add_function(wrap_pyfunction!(sets::read_budget, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::read_results, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::solve, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::compare_rows, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::kc, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::shared_quantities, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::history, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate_selfcal, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(sets::read_selfcal, m)?)?;
    m.add_function(wrap_pyfunction!(sets::selfcal_set_from_columns, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::selfcal, m)?)?;
    m.add_function(wrap_pyfunction!(version, m)?)?;
    m.add_function(wrap_pyfunction!(sets::_restore_measurement_set, m)?)?;
    m.add_function(wrap_pyfunction!(sets::_restore_selfcal_set, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::_restore_rows, m)?)?;
    m.add_function(wrap_pyfunction!(sets::_restore_budget, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::_restore_solve_result, m)?)?;
    Ok(())
}
