//! The pickled states of the library's values: each native object's `__reduce__` (in
//! `sets.rs` and `evaluate.rs`) gives its fields as Python values made here — every float
//! as its own 8 bytes, pickled exactly — and its `_restore_…` function builds the value
//! again from them here, equal to the bit. A budget travels as its components (not its
//! file, which may name others). This file knows the library's types only, not the
//! Python classes that hold them: the classes call it, never the other way round.

use std::collections::BTreeMap;

use polycal::measurement::{MeasurementSet, Reading};
use polycal::results::{Quantity, ResultFile, ResultRow, RowColumns};
use polycal::selfcal::{HeadReading, SelfcalSet};
use polycal::uncertainty::calibration::{InstrumentBudget, Scope, ScopedComponent};
use polycal::uncertainty::{Distribution, DofPolicy, EvaluationType};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::direction_at;

/// The function of this module named `name`, for a `__reduce__` to return.
pub(crate) fn restorer<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("polycal._polycal")?.getattr(name)
}

/// Refuses a pickled state whose columns differ in length (a state not made by
/// `__reduce__`).
fn same_lengths(what: &str, lengths: &[usize]) -> PyResult<()> {
    if lengths.windows(2).any(|w| w[0] != w[1]) {
        return Err(PyValueError::new_err(format!(
            "{what}: a pickled state whose columns differ in length: {lengths:?}"
        )));
    }
    Ok(())
}

/// A measurement set's readings as the columns of its pickled state: setup, cycle, step,
/// ac, face, reading, direction, time, reading_y, temperature, encoder, line.
pub(crate) type ReadingColumns = (
    Vec<u32>,
    Vec<u32>,
    Vec<usize>,
    Vec<u32>,
    Vec<usize>,
    Vec<f64>,
    Vec<String>,
    Vec<Option<f64>>,
    Vec<Option<f64>>,
    Vec<Option<f64>>,
    Vec<Option<f64>>,
    Vec<u64>,
);

/// The pickled state of a measurement set: faces, source, the shifts by setup, the
/// comment lines and the readings' columns.
pub(crate) type MeasurementState = (usize, String, Vec<(u32, f64)>, Vec<String>, ReadingColumns);

/// The pickled state of a measurement set with its comment lines
/// (`MeasurementSet.__reduce__`).
pub(crate) fn measurement_state(set: &MeasurementSet, comments: &[String]) -> MeasurementState {
    let r = &set.readings;
    let columns = (
        r.iter().map(|x| x.setup).collect(),
        r.iter().map(|x| x.cycle).collect(),
        r.iter().map(|x| x.step).collect(),
        r.iter().map(|x| x.ac).collect(),
        r.iter().map(|x| x.face).collect(),
        r.iter().map(|x| x.reading_arcsec).collect(),
        r.iter().map(|x| x.direction.as_str().to_string()).collect(),
        r.iter().map(|x| x.time_seconds).collect(),
        r.iter().map(|x| x.reading_y_arcsec).collect(),
        r.iter().map(|x| x.temperature_celsius).collect(),
        r.iter().map(|x| x.encoder_degrees).collect(),
        r.iter().map(|x| x.line).collect(),
    );
    (
        set.faces,
        set.source.clone(),
        set.setup_shift_deg.iter().map(|(&s, &d)| (s, d)).collect(),
        comments.to_vec(),
        columns,
    )
}

/// The set and comment lines a pickled state (`MeasurementSet.__reduce__`) describes,
/// field by field.
pub(crate) fn measurement_from_state(
    state: MeasurementState,
) -> PyResult<(MeasurementSet, Vec<String>)> {
    let (faces, source, shifts, comments, columns) = state;
    let (
        setup,
        cycle,
        step,
        ac,
        face,
        reading,
        direction,
        time,
        reading_y,
        temperature,
        encoder,
        line,
    ) = columns;
    same_lengths(
        "MeasurementSet",
        &[
            setup.len(),
            cycle.len(),
            step.len(),
            ac.len(),
            face.len(),
            reading.len(),
            direction.len(),
            time.len(),
            reading_y.len(),
            temperature.len(),
            encoder.len(),
            line.len(),
        ],
    )?;
    let readings = (0..reading.len())
        .map(|i| {
            Ok(Reading {
                setup: setup[i],
                cycle: cycle[i],
                step: step[i],
                ac: ac[i],
                face: face[i],
                reading_arcsec: reading[i],
                direction: direction_at(Some(&direction), i)?,
                time_seconds: time[i],
                reading_y_arcsec: reading_y[i],
                temperature_celsius: temperature[i],
                encoder_degrees: encoder[i],
                line: line[i],
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let inner = MeasurementSet {
        faces,
        readings,
        source,
        setup_shift_deg: shifts.into_iter().collect::<BTreeMap<_, _>>(),
    };
    Ok((inner, comments))
}

/// A self-calibration set's readings as the columns of its pickled state: cycle, step,
/// head, head_angle, reading, direction, time, line.
type HeadColumns = (
    Vec<u32>,
    Vec<usize>,
    Vec<u32>,
    Vec<f64>,
    Vec<f64>,
    Vec<String>,
    Vec<Option<f64>>,
    Vec<u64>,
);

/// The pickled state of a self-calibration set: positions, source, comment lines and
/// the readings' columns.
pub(crate) type SelfcalState = (usize, String, Vec<String>, HeadColumns);

/// The pickled state of a self-calibration set with its name and comment lines
/// (`SelfcalSet.__reduce__`).
pub(crate) fn selfcal_state(set: &SelfcalSet, name: &str, comments: &[String]) -> SelfcalState {
    let r = &set.readings;
    let columns = (
        r.iter().map(|x| x.cycle).collect(),
        r.iter().map(|x| x.step).collect(),
        r.iter().map(|x| x.head).collect(),
        r.iter().map(|x| x.head_angle_deg).collect(),
        r.iter().map(|x| x.reading_arcsec).collect(),
        r.iter().map(|x| x.direction.as_str().to_string()).collect(),
        r.iter().map(|x| x.time_seconds).collect(),
        r.iter().map(|x| x.line).collect(),
    );
    (set.positions, name.to_string(), comments.to_vec(), columns)
}

/// The set, name and comment lines a pickled state (`SelfcalSet.__reduce__`) describes,
/// field by field.
pub(crate) fn selfcal_from_state(
    state: SelfcalState,
) -> PyResult<(SelfcalSet, String, Vec<String>)> {
    let (positions, name, comments, columns) = state;
    let (cycle, step, head, head_angle, reading, direction, time, line) = columns;
    same_lengths(
        "SelfcalSet",
        &[
            cycle.len(),
            step.len(),
            head.len(),
            head_angle.len(),
            reading.len(),
            direction.len(),
            time.len(),
            line.len(),
        ],
    )?;
    let readings = (0..reading.len())
        .map(|i| {
            Ok(HeadReading {
                cycle: cycle[i],
                step: step[i],
                head: head[i],
                head_angle_deg: head_angle[i],
                reading_arcsec: reading[i],
                direction: direction_at(Some(&direction), i)?,
                time_seconds: time[i],
                line: line[i],
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    Ok((
        SelfcalSet {
            positions,
            readings,
        },
        name,
        comments,
    ))
}

/// A result row in a pickled state: quantity, index, value, u, U, k, angle_deg, dof,
/// nominal_deg.
pub(crate) type RowState = (
    String,
    u32,
    f64,
    Option<f64>,
    Option<f64>,
    Option<f64>,
    Option<f64>,
    Option<f64>,
    Option<f64>,
);

/// The columns of a row's fields as pickled: quantity, index, value, U, u, k, nominal_deg.
pub(crate) type ColumnsState = (
    u64,
    u64,
    u64,
    Option<u64>,
    Option<u64>,
    Option<u64>,
    Option<u64>,
);

/// The pickled state of result rows: the rows, the label and, for a file's, its name,
/// the rows' lines and their fields' columns.
pub(crate) type RowsState = (
    Vec<RowState>,
    String,
    Option<(String, Vec<u64>, Vec<ColumnsState>)>,
);

/// The columns of a file's rows as pickled.
pub(crate) fn columns_state(columns: &[RowColumns]) -> Vec<ColumnsState> {
    columns
        .iter()
        .map(|c| {
            (
                c.quantity,
                c.index,
                c.value,
                c.expanded_u,
                c.u,
                c.k,
                c.nominal_deg,
            )
        })
        .collect()
}

pub(crate) fn rows_state(rows: &[ResultRow]) -> Vec<RowState> {
    rows.iter()
        .map(|r| {
            (
                r.quantity.name().to_string(),
                r.index,
                r.value,
                r.u,
                r.expanded_u,
                r.k,
                r.angle_deg,
                r.dof,
                r.nominal_deg,
            )
        })
        .collect()
}

pub(crate) fn rows_from_state(state: Vec<RowState>) -> PyResult<Vec<ResultRow>> {
    state
        .into_iter()
        .map(
            |(quantity, index, value, u, expanded_u, k, angle_deg, dof, nominal_deg)| {
                let quantity = Quantity::from_name(&quantity).ok_or_else(|| {
                    PyValueError::new_err(format!("a pickled row of quantity {quantity:?}"))
                })?;
                let mut row = ResultRow::new(quantity, index, value);
                row.u = u;
                row.expanded_u = expanded_u;
                row.k = k;
                row.angle_deg = angle_deg;
                row.dof = dof;
                row.nominal_deg = nominal_deg;
                Ok(row)
            },
        )
        .collect()
}

/// The rows, label and file a pickled state (`ResultRows.__reduce__`) describes.
pub(crate) fn rows_file_from_state(
    state: RowsState,
) -> PyResult<(Vec<ResultRow>, String, Option<ResultFile>)> {
    let (rows, label, file) = state;
    let rows = rows_from_state(rows)?;
    let file = match file {
        Some((source, lines, columns)) => {
            same_lengths("ResultRows", &[rows.len(), lines.len(), columns.len()])?;
            let columns = columns
                .into_iter()
                .map(
                    |(quantity, index, value, expanded_u, u, k, nominal_deg)| RowColumns {
                        quantity,
                        index,
                        value,
                        expanded_u,
                        u,
                        k,
                        nominal_deg,
                    },
                )
                .collect();
            Some(ResultFile {
                source,
                rows: rows.clone(),
                lines,
                columns,
            })
        }
        None => None,
    };
    Ok((rows, label, file))
}

/// A budget component in a pickled state: name, type (`A`/`B`), the distribution (its
/// kind and its one or two parameters), sensitivity, dof and scope.
type ComponentState = (String, String, (String, f64, f64), f64, Option<f64>, String);

/// The pickled state of a budget: source, p, the dof policy and the components.
pub(crate) type BudgetState = (String, f64, String, Vec<ComponentState>);

/// The pickled state of a budget (`Budget.__reduce__`).
pub(crate) fn budget_state(budget: &InstrumentBudget) -> BudgetState {
    let components = budget
        .components
        .iter()
        .map(|c| {
            // the kind by the library's name of it, and its one or two parameters
            let (x, y) = match c.distribution {
                Distribution::Normal { u } => (u, 0.0),
                Distribution::Rectangular { half_width }
                | Distribution::Triangular { half_width }
                | Distribution::Arcsine { half_width } => (half_width, 0.0),
                Distribution::StudentT { scale, dof } => (scale, dof),
            };
            (
                c.name.clone(),
                c.evaluation.to_string(),
                (c.distribution.name().to_string(), x, y),
                c.sensitivity,
                c.dof,
                c.scope.as_str().to_string(),
            )
        })
        .collect();
    (
        budget.source.clone(),
        budget.p,
        budget.dof_policy.as_str().to_string(),
        components,
    )
}

/// The budget a pickled state (`Budget.__reduce__`) describes, field by field.
pub(crate) fn budget_from_state(state: BudgetState) -> PyResult<InstrumentBudget> {
    let (source, p, dof_policy, components) = state;
    let bad = |what: &str, value: &str| {
        PyValueError::new_err(format!("Budget: a pickled state with {what} {value:?}"))
    };
    let components = components
        .into_iter()
        .map(
            |(name, evaluation, (kind, x, y), sensitivity, dof, scope)| {
                let evaluation = match evaluation.as_str() {
                    "A" => EvaluationType::A,
                    "B" => EvaluationType::B,
                    other => return Err(bad("the type", other)),
                };
                let distribution = match kind.as_str() {
                    "normal" => Distribution::Normal { u: x },
                    "rectangular" => Distribution::Rectangular { half_width: x },
                    "triangular" => Distribution::Triangular { half_width: x },
                    "arcsine" => Distribution::Arcsine { half_width: x },
                    "t" => Distribution::StudentT { scale: x, dof: y },
                    other => return Err(bad("the distribution", other)),
                };
                Ok(ScopedComponent {
                    name,
                    evaluation,
                    distribution,
                    sensitivity,
                    dof,
                    scope: scope
                        .parse::<Scope>()
                        .map_err(|_| bad("the scope", &scope))?,
                })
            },
        )
        .collect::<PyResult<Vec<_>>>()?;
    let dof_policy = dof_policy
        .parse::<DofPolicy>()
        .map_err(|_| bad("the dof policy", &dof_policy))?;
    Ok(InstrumentBudget {
        source,
        p,
        dof_policy,
        components,
    })
}
