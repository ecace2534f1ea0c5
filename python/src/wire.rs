//! `polycal.TableWire` and `polycal.AcWire`: the wire rules (`polycal::lab::wire`,
//! docs/FORMAT.md §7.7) for a Python driver that owns its ports. Each wraps the library's
//! machine; this file only names its actions and events for Python.

use std::time::Duration;

use polycal::lab::driver::{
    AcOp, AcOutcome, AcWire, TableOp, TableOptions, TableOutcome, TableState, TableWire,
};
use polycal::lab::profile::Profile;
use polycal::lab::wire::{Wire, WireAction, WireEvent};
use polycal::lab::{InstrumentError, QueryOptions};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::refusal;

/// What the wire rules ask of the port next (`TableWire.poll()`, `AcWire.poll()`): `kind`
/// says what, and the fields of that kind are set.
#[pyclass(name = "WireAction", module = "polycal", frozen)]
#[derive(Debug, Clone, Default)]
pub struct PyWireAction {
    /// `drain`, `clear`, `send`, `read_line`, `await_input`, `wait`, `note` or `done`.
    #[pyo3(get)]
    kind: String,
    /// `send`: the text to write (terminator included); `note`: the line it is about.
    #[pyo3(get)]
    text: Option<String>,
    /// `read_line`, `await_input`, `wait`: how long, seconds.
    #[pyo3(get)]
    seconds: Option<f64>,
    /// `note`: the traffic log's event (`discarded`, `doubtful`, `latched`, `no
    /// acknowledgement`).
    #[pyo3(get)]
    event: Option<String>,
}

#[pymethods]
impl PyWireAction {
    fn __repr__(&self) -> String {
        format!("{self:?}")
    }
}

fn py_action(action: WireAction) -> PyWireAction {
    let (kind, text, seconds, event) = match action {
        WireAction::Drain => ("drain", None, None, None),
        WireAction::ClearInput => ("clear", None, None, None),
        WireAction::Send(text) => ("send", Some(text), None, None),
        WireAction::ReadLine(t) => ("read_line", None, Some(t.as_secs_f64()), None),
        WireAction::AwaitInput(t) => ("await_input", None, Some(t.as_secs_f64()), None),
        WireAction::Wait(t) => ("wait", None, Some(t.as_secs_f64()), None),
        WireAction::Note { event, text } => ("note", Some(text), None, Some(event)),
        _ => ("done", None, None, None),
    };
    PyWireAction {
        kind: kind.to_string(),
        text,
        seconds,
        event,
    }
}

fn seconds(name: &str, value: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(value).map_err(|_| {
        PyValueError::new_err(format!(
            "{name}: expected a finite number of seconds ≥ 0, got {value}"
        ))
    })
}

fn query_options(reply_timeout: f64, retries: u32, alone_wait: f64) -> PyResult<QueryOptions> {
    Ok(
        QueryOptions::new(seconds("reply_timeout", reply_timeout)?, retries)
            .with_alone_wait(seconds("alone_wait", alone_wait)?),
    )
}

/// The event of a port's answer, as Python tells it.
fn event(
    port: &str,
    kind: &str,
    lines: Option<Vec<String>>,
    line: Option<String>,
    message: Option<String>,
) -> PyResult<WireEvent> {
    Ok(match kind {
        "drained" => WireEvent::Drained(lines.unwrap_or_default()),
        "input" => WireEvent::Input(lines.unwrap_or_default()),
        "cleared" => WireEvent::Cleared,
        "sent" => WireEvent::Sent,
        "line" => WireEvent::Line(line),
        "waited" => WireEvent::Waited,
        "failed" => WireEvent::Failed(InstrumentError::Reported {
            port: port.to_string(),
            message: message.unwrap_or_else(|| "the port failed".to_string()),
        }),
        other => {
            return Err(PyValueError::new_err(format!(
                "event: expected drained, input, cleared, sent, line, waited or failed, got {other:?}"
            )));
        }
    })
}

/// A rotary table's wire rules for a port of your own (docs/FORMAT.md §7.7): `begin` an
/// operation, carry out each action `poll()` gives on your port and `tell` what happened,
/// until the action is `done`; then `outcome()`. The profile is a bundled name or a file.
#[pyclass(name = "TableWire", module = "polycal")]
pub struct PyTableWire {
    wire: TableWire,
}

#[pymethods]
impl PyTableWire {
    #[new]
    #[pyo3(signature = (port, profile = "smc100", *, reply_timeout = 1.0, retries = 3, alone_wait = 0.0, poll_interval = 0.02, motion_timeout = 120.0, position_tolerance_deg = 0.001))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        port: &str,
        profile: &str,
        reply_timeout: f64,
        retries: u32,
        alone_wait: f64,
        poll_interval: f64,
        motion_timeout: f64,
        position_tolerance_deg: f64,
    ) -> PyResult<PyTableWire> {
        let profile = Profile::load(profile).map_err(refusal)?;
        if !(position_tolerance_deg.is_finite() && position_tolerance_deg > 0.0) {
            return Err(PyValueError::new_err(format!(
                "position_tolerance_deg: expected a number > 0, got {position_tolerance_deg}"
            )));
        }
        let options = TableOptions::new(query_options(reply_timeout, retries, alone_wait)?)
            .with_poll_interval(seconds("poll_interval", poll_interval)?)
            .with_motion_timeout(seconds("motion_timeout", motion_timeout)?)
            .with_position_tolerance_deg(position_tolerance_deg);
        let wire = TableWire::new(port, &profile, options).map_err(refusal)?;
        Ok(PyTableWire { wire })
    }

    /// Begins `op`: `start`, `identify`, `state`, `move` (with `deg`), `position` or
    /// `stop`.
    #[pyo3(signature = (op, deg = None))]
    fn begin(&mut self, op: &str, deg: Option<f64>) -> PyResult<()> {
        let op = match (op, deg) {
            ("start", None) => TableOp::Start,
            ("identify", None) => TableOp::Identify,
            ("state", None) => TableOp::State,
            ("position", None) => TableOp::Position,
            ("stop", None) => TableOp::Stop,
            ("move", Some(deg)) if deg.is_finite() => TableOp::MoveTo(deg),
            _ => {
                return Err(PyValueError::new_err(format!(
                    "op: expected start, identify, state, position, stop, or move with a finite deg; got {op:?} with deg={deg:?}"
                )));
            }
        };
        self.wire.begin(op);
        Ok(())
    }

    /// The next action.
    fn poll(&mut self) -> PyWireAction {
        py_action(self.wire.poll())
    }

    /// Tells what the port did for the action asked, at `now` seconds on your clock:
    /// `drained` / `input` (`lines`), `cleared`, `sent`, `line` (`line`, `None` at the
    /// deadline), `waited`, `failed` (`message`). A refusal raises `PolycalError`.
    #[pyo3(signature = (now, event, *, lines = None, line = None, message = None))]
    fn tell(
        &mut self,
        now: f64,
        event: &str,
        lines: Option<Vec<String>>,
        line: Option<String>,
        message: Option<String>,
    ) -> PyResult<()> {
        let event = self::event(self.wire.port(), event, lines, line, message)?;
        self.wire.tell(now, event).map_err(refusal)
    }

    /// A stop was requested: a move under way is stopped.
    fn interrupt(&mut self) {
        self.wire.interrupt();
    }

    /// The operation's outcome, once `poll()` said `done`: `None` (start, stop), the
    /// identification's text, the state (`ready`, `moving`, `not-referenced`), or the
    /// position in degrees (move, position). The instrument's error raises
    /// `PolycalError` with polycal's message.
    fn outcome(&mut self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        let outcome = self
            .wire
            .outcome()
            .ok_or_else(|| refusal("no outcome: the operation is not done (or was taken)"))?
            .map_err(refusal)?;
        Ok(match outcome {
            TableOutcome::Identified(text) => Some(text.into_pyobject(py)?.into_any().unbind()),
            TableOutcome::At(deg) => Some(deg.into_pyobject(py)?.into_any().unbind()),
            TableOutcome::State(state) => {
                let name = match state {
                    TableState::Ready => "ready",
                    TableState::Moving => "moving",
                    _ => "not-referenced",
                };
                Some(name.into_pyobject(py)?.into_any().unbind())
            }
            _ => None,
        })
    }
}

/// An autocollimator's wire rules for a port of your own (docs/FORMAT.md §7.7), as
/// `TableWire`; `outcome()` of `measure` is `(status, x_arcsec, y_arcsec)` (Y `None`
/// when not valid).
#[pyclass(name = "AcWire", module = "polycal")]
pub struct PyAcWire {
    wire: AcWire,
    port: String,
}

#[pymethods]
impl PyAcWire {
    #[new]
    #[pyo3(signature = (port, profile = "elcomat3000", *, reply_timeout = 1.0, retries = 3, alone_wait = 0.0, start_wait = 0.05))]
    fn new(
        port: &str,
        profile: &str,
        reply_timeout: f64,
        retries: u32,
        alone_wait: f64,
        start_wait: f64,
    ) -> PyResult<PyAcWire> {
        let profile = Profile::load(profile).map_err(refusal)?;
        let wire = AcWire::new(
            port,
            &profile,
            query_options(reply_timeout, retries, alone_wait)?,
        )
        .map_err(refusal)?
        .with_drain(seconds("start_wait", start_wait)?);
        Ok(PyAcWire {
            wire,
            port: port.to_string(),
        })
    }

    /// Begins `op`: `start`, `identify` or `measure`.
    fn begin(&mut self, op: &str) -> PyResult<()> {
        let op = match op {
            "start" => AcOp::Start,
            "identify" => AcOp::Identify,
            "measure" => AcOp::Measure,
            other => {
                return Err(PyValueError::new_err(format!(
                    "op: expected start, identify or measure, got {other:?}"
                )));
            }
        };
        self.wire.begin(op);
        Ok(())
    }

    /// The next action.
    fn poll(&mut self) -> PyWireAction {
        py_action(self.wire.poll())
    }

    /// As `TableWire.tell`.
    #[pyo3(signature = (now, event, *, lines = None, line = None, message = None))]
    fn tell(
        &mut self,
        now: f64,
        event: &str,
        lines: Option<Vec<String>>,
        line: Option<String>,
        message: Option<String>,
    ) -> PyResult<()> {
        let event = self::event(&self.port, event, lines, line, message)?;
        self.wire.tell(now, event).map_err(refusal)
    }

    /// The operation's outcome once done: `None` (start), the identification's text, or
    /// `(status, x_arcsec, y_arcsec)`. The instrument's error raises `PolycalError`.
    fn outcome(&mut self, py: Python<'_>) -> PyResult<Option<Py<PyAny>>> {
        let outcome = self
            .wire
            .outcome()
            .ok_or_else(|| refusal("no outcome: the operation is not done (or was taken)"))?
            .map_err(refusal)?;
        Ok(match outcome {
            AcOutcome::Identified(text) => Some(text.into_pyobject(py)?.into_any().unbind()),
            AcOutcome::Reading(r) => Some(
                (r.status, r.x_arcsec, r.y_arcsec)
                    .into_pyobject(py)?
                    .into_any()
                    .unbind(),
            ),
            _ => None,
        })
    }
}
