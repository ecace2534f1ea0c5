//! The data a Python user hands over: measurement and self-calibration sets (from a file,
//! a text or columns, each checked as the file reader checks it) and instrument budgets.

use std::path::Path;
use std::sync::Arc;

use polycal::measurement::{MeasurementSet, Reading};
use polycal::selfcal::{HeadReading, SelfcalSet};
use polycal::uncertainty::BudgetError;
use polycal::uncertainty::calibration::InstrumentBudget;
use pyo3::exceptions::{PyMemoryError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::state::{self, restorer};

use crate::{
    direction_at, file_error, file_not_found, input_error, is_not_found, read_source, refusal,
};

/// A measurement set (docs/FORMAT.md §2).
#[pyclass(name = "MeasurementSet", module = "polycal._polycal", frozen)]
#[derive(Clone)]
pub(crate) struct PyMeasurementSet {
    /// Shared with the solve results made from it (which re-solve it after a pickle).
    pub(crate) inner: Arc<MeasurementSet>,
    /// The comment lines a written file starts with (a simulated run's description).
    pub(crate) comments: Vec<String>,
}

impl PyMeasurementSet {
    /// A set without comment lines.
    pub(crate) fn new(inner: MeasurementSet) -> Self {
        PyMeasurementSet {
            inner: Arc::new(inner),
            comments: Vec::new(),
        }
    }
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

    /// Pickles the set as its fields (every float its own 8 bytes): back equal to the bit.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (state::MeasurementState,))> {
        Ok((
            restorer(py, "_restore_measurement_set")?,
            (state::measurement_state(&self.inner, &self.comments),),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "MeasurementSet({} readings, {} faces, from {})",
            self.inner.readings.len(),
            self.inner.faces,
            self.inner.source
        )
    }

    /// Writes the set as a measurement file (docs/FORMAT.md §2) at `path`, whole or not
    /// at all, starting with its comment lines (a simulated run's, as `polycal simulate`
    /// writes them).
    fn write(&self, py: Python<'_>, path: &str) -> PyResult<()> {
        let comments = &self.comments;
        py.detach(|| self.inner.write_path(Path::new(path), comments))
            .map_err(|e| file_error(py, e))
    }

    /// The comment lines a written file starts with.
    #[getter]
    fn comments(&self) -> Vec<String> {
        self.comments.clone()
    }

    /// The readings as columns named as the file's (docs/FORMAT.md §2): lists, `None`
    /// where a reading has no value of an optional column (`encoder` the commanded
    /// position a file gave, degrees); `shift` (each reading's mounting's) only for a set
    /// with shifted mountings.
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
        d.set_item(
            "encoder",
            r.iter().map(|x| x.encoder_degrees).collect::<Vec<_>>(),
        )?;
        if self.inner.has_shifts() {
            let set = &self.inner;
            d.set_item(
                "shift",
                r.iter().map(|x| set.shift_deg(x.setup)).collect::<Vec<_>>(),
            )?;
        }
        Ok(d)
    }
}

/// Reads a measurement file (`path`) or its text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<text>", faces=None))]
pub(crate) fn read_measurements(
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
    read.map(PyMeasurementSet::new)
        .map_err(|e| file_error(py, e))
}

/// What building a set of one row from columns takes, bytes: the package's Python lists
/// of the columns (about 225), the binding's copies of them (about 80) and the reading
/// itself (about 100), with room to spare.
const BYTES_PER_ROW_FROM_COLUMNS: u128 = 448;

/// Refuses, with `MemoryError` and before any column is converted, a set of `rows` rows
/// that would not fit in the memory this process may take (the library's
/// `solve::memory::room`: available memory, `ulimit -v`, the control group's limit).
#[pyfunction]
pub(crate) fn check_columns_fit(rows: usize) -> PyResult<()> {
    use polycal::solve::memory::{human_bytes, room};
    let needed = rows as u128 * BYTES_PER_ROW_FROM_COLUMNS;
    // small sets are not worth reading the limits for
    if needed < 64 << 20 {
        return Ok(());
    }
    match room() {
        Some((left, text)) if needed > u128::from(left) => Err(PyMemoryError::new_err(format!(
            "{rows} rows need about {} of memory to become a set; {} {text}",
            human_bytes(needed),
            human_bytes(u128::from(left))
        ))),
        _ => Ok(()),
    }
}

/// Builds a measurement set from columns; every reading is checked as the file reader
/// checks it. Integer columns arrive as Python ints (the package checks dtypes).
#[pyfunction]
#[pyo3(signature = (cycle, step, ac, face, reading, direction=None, time=None, setup=None, shift=None, temperature=None, reading_y=None, faces=None, name="<arrays>"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn measurement_set_from_columns(
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
        .map_err(|e| file_error(py, e))?;
    Ok(PyMeasurementSet::new(inner))
}

/// An instrument budget (docs/FORMAT.md §5.1).
#[pyclass(name = "Budget", module = "polycal._polycal", frozen)]
pub(crate) struct PyBudget {
    pub(crate) inner: InstrumentBudget,
}

#[pymethods]
impl PyBudget {
    /// Where the budget came from (a path, or the name of its text).
    #[getter]
    fn source(&self) -> String {
        self.inner.source.clone()
    }

    /// The coverage probability p.
    #[getter]
    fn p(&self) -> f64 {
        self.inner.p
    }

    /// The components in file order (nested budgets flattened), each a dict: `name`,
    /// `type` (A or B), `distribution`, `u` (|c|·u(x), arcsec: the standard uncertainty
    /// one draw adds to a reading), `sensitivity`, `dof` (`None`: infinitely many) and
    /// `acts_on` (which readings share one draw, docs/FORMAT.md §5.1).
    fn components<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        self.inner
            .components
            .iter()
            .map(|c| {
                let d = PyDict::new(py);
                d.set_item("name", &c.name)?;
                d.set_item("type", c.evaluation.to_string())?;
                d.set_item("distribution", c.distribution.name())?;
                d.set_item("u", c.standard_uncertainty())?;
                d.set_item("sensitivity", c.sensitivity)?;
                d.set_item("dof", c.dof)?;
                d.set_item("acts_on", c.scope.as_str())?;
                Ok(d)
            })
            .collect()
    }

    /// Pickles the budget as its components (every float its own 8 bytes): back equal
    /// to the bit.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (state::BudgetState,))> {
        Ok((
            restorer(py, "_restore_budget")?,
            (state::budget_state(&self.inner),),
        ))
    }

    /// The cautions `polycal` prints as warnings when it reads the budget (a type A
    /// component counted twice).
    fn notes(&self) -> Vec<String> {
        self.inner.notes()
    }
}

/// Reads an instrument budget: a TOML file (`path`) or TOML text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<budget>"))]
pub(crate) fn read_budget(
    path: Option<&str>,
    text: Option<&str>,
    name: &str,
) -> PyResult<PyBudget> {
    let read = read_source(
        path,
        text,
        name,
        |p: &Path| InstrumentBudget::read_path(p),
        |bytes, name| InstrumentBudget::from_toml_str(&String::from_utf8_lossy(bytes), name),
    )?;
    read.map(|inner| PyBudget { inner }).map_err(|e| match &e {
        BudgetError::Io { source, .. } if is_not_found(source) => {
            Python::attach(|py| file_not_found(py, path.unwrap_or(name), source))
        }
        BudgetError::File { location, .. } | BudgetError::WrongKind { location, .. } => {
            Python::attach(|py| input_error(py, e.to_string(), Some(location)))
        }
        _ => refusal(e),
    })
}

/// A self-calibration set (docs/FORMAT.md §9.2).
#[pyclass(name = "SelfcalSet", module = "polycal._polycal", frozen)]
pub(crate) struct PySelfcalSet {
    pub(crate) inner: SelfcalSet,
    pub(crate) name: String,
    /// The comment lines a written file starts with (a simulated run's description).
    pub(crate) comments: Vec<String>,
}

#[pymethods]
impl PySelfcalSet {
    fn __len__(&self) -> usize {
        self.inner.readings.len()
    }

    /// P, the number of table positions per turn.
    #[getter]
    fn positions(&self) -> usize {
        self.inner.positions
    }

    /// Where the readings came from.
    #[getter]
    fn source(&self) -> String {
        self.name.clone()
    }

    /// Pickles the set as its fields (every float its own 8 bytes): back equal to the bit.
    fn __reduce__<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Bound<'py, PyAny>, (state::SelfcalState,))> {
        Ok((
            restorer(py, "_restore_selfcal_set")?,
            (state::selfcal_state(
                &self.inner,
                &self.name,
                &self.comments,
            ),),
        ))
    }

    fn __repr__(&self) -> String {
        format!(
            "SelfcalSet({} readings, {} positions, from {})",
            self.inner.readings.len(),
            self.inner.positions,
            self.name
        )
    }

    /// The comment lines a written file starts with.
    #[getter]
    fn comments(&self) -> Vec<String> {
        self.comments.clone()
    }

    /// Writes the set as a self-calibration file (docs/FORMAT.md §9.2) at `path`, whole
    /// or not at all, starting with its comment lines.
    fn write(&self, py: Python<'_>, path: &str) -> PyResult<()> {
        let comments = &self.comments;
        py.detach(|| self.inner.write_path(Path::new(path), comments))
            .map_err(|e| file_error(py, e))
    }

    /// The readings as columns named as the file's (docs/FORMAT.md §9.2): lists, `None`
    /// where a reading has no time.
    fn columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let r = &self.inner.readings;
        let d = PyDict::new(py);
        d.set_item("cycle", r.iter().map(|x| x.cycle).collect::<Vec<_>>())?;
        d.set_item("step", r.iter().map(|x| x.step).collect::<Vec<_>>())?;
        d.set_item("head", r.iter().map(|x| x.head).collect::<Vec<_>>())?;
        d.set_item(
            "head_angle",
            r.iter().map(|x| x.head_angle_deg).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "reading",
            r.iter().map(|x| x.reading_arcsec).collect::<Vec<_>>(),
        )?;
        d.set_item(
            "direction",
            r.iter().map(|x| x.direction.as_str()).collect::<Vec<_>>(),
        )?;
        d.set_item("time", r.iter().map(|x| x.time_seconds).collect::<Vec<_>>())?;
        Ok(d)
    }
}

/// Reads a self-calibration file (`path`) or its text (`text`, named `name`).
#[pyfunction]
#[pyo3(signature = (path=None, text=None, name="<text>", positions=None))]
pub(crate) fn read_selfcal(
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
    read.map(|inner| PySelfcalSet {
        inner,
        name,
        comments: Vec::new(),
    })
    .map_err(|e| file_error(py, e))
}

/// Builds a self-calibration set from columns, checked as the file reader checks them.
#[pyfunction]
#[pyo3(signature = (cycle, step, head, head_angle, reading, direction=None, time=None, positions=None, name="<arrays>"))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn selfcal_set_from_columns(
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
        readings.push(HeadReading {
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
        .map_err(|e| file_error(py, e))?;
    Ok(PySelfcalSet {
        inner,
        name: name.to_string(),
        comments: Vec::new(),
    })
}

/// The set a pickled state (`MeasurementSet.__reduce__`) describes, field by field.
#[pyfunction]
pub(crate) fn _restore_measurement_set(
    state: state::MeasurementState,
) -> PyResult<PyMeasurementSet> {
    let (set, comments) = state::measurement_from_state(state)?;
    Ok(PyMeasurementSet {
        inner: Arc::new(set),
        comments,
    })
}

/// The set a pickled state (`SelfcalSet.__reduce__`) describes, field by field.
#[pyfunction]
pub(crate) fn _restore_selfcal_set(state: state::SelfcalState) -> PyResult<PySelfcalSet> {
    let (inner, name, comments) = state::selfcal_from_state(state)?;
    Ok(PySelfcalSet {
        inner,
        name,
        comments,
    })
}

/// The budget a pickled state (`Budget.__reduce__`) describes, field by field.
#[pyfunction]
pub(crate) fn _restore_budget(state: state::BudgetState) -> PyResult<PyBudget> {
    Ok(PyBudget {
        inner: state::budget_from_state(state)?,
    })
}
