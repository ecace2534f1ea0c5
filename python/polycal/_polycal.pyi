"""Type stubs of the native module (python/src/lib.rs); the package's public API is
polycal/__init__.py, typed inline. The exceptions are `polycal.`'s (`__module__ ==
"polycal"`); sets, budgets, result rows and solve results pickle through `__reduce__` and the
`_restore_…` functions (python/src/state.rs)."""

import os
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

class PolycalError(Exception): ...

class FileNotFound(PolycalError, FileNotFoundError):
    path: str

class PolycalWarning(UserWarning): ...

class InputError(PolycalError):
    path: str
    line: int
    column: int

class DesignError(PolycalError):
    lost_harmonics: List[int]

class MeasurementSet:
    def __reduce__(self) -> Tuple[Any, Tuple[Any]]: ...
    @property
    def faces(self) -> int: ...
    @property
    def source(self) -> str: ...
    @property
    def comments(self) -> List[str]: ...
    def __len__(self) -> int: ...
    def columns(self) -> Dict[str, list]: ...
    def write(self, path: str) -> None: ...

class SelfcalSet:
    def __reduce__(self) -> Tuple[Any, Tuple[Any]]: ...
    @property
    def positions(self) -> int: ...
    @property
    def source(self) -> str: ...
    @property
    def comments(self) -> List[str]: ...
    def __len__(self) -> int: ...
    def columns(self) -> Dict[str, list]: ...
    def write(self, path: str) -> None: ...

class Budget:
    def __reduce__(self) -> Tuple[Any, Tuple[Any]]: ...
    @property
    def source(self) -> str: ...
    @property
    def p(self) -> float: ...
    def components(self) -> List[Dict[str, Any]]: ...
    def notes(self) -> List[str]: ...

class ResultRows:
    def __reduce__(self) -> Tuple[Any, Tuple[Any]]: ...
    @property
    def label(self) -> str: ...
    def __len__(self) -> int: ...

class SolveResult:
    def __reduce__(self) -> Tuple[Any, Tuple[Any]]: ...
    def json(self) -> str: ...
    def rows(self) -> ResultRows: ...
    def encoder_angle_deg(self) -> List[float]: ...
    def face_angle_deg(self) -> List[float]: ...
    def covariance(self, family: str) -> Optional[Tuple[int, List[float]]]: ...

class Action:
    """What a `Session` asks its driver to do next; the fields of its `kind` are set."""

    kind: str  # move, position, read, wait, remount, progress, halt, finished
    to_deg: Optional[float]
    ac: Optional[int]
    until_seconds: Optional[float]
    mounting: Optional[str]
    setup: Optional[int]
    table_deg: Optional[float]
    faces: Optional[List[Tuple[int, int]]]
    done: Optional[int]
    total: Optional[int]
    cycle: Optional[Tuple[int, int]]
    stop: Optional[Tuple[int, int]]
    step: Optional[int]
    seconds_left: Optional[float]
    refused: Optional[int]
    cycle_check: Optional[Dict[str, Any]]
    outcome: Optional[str]

class Session:
    """The run's rules as a session driven from Python, the run directory its store."""

    def __init__(
        self,
        dir: Union[str, "os.PathLike[str]"],
        *,
        faces: int,
        cycles: int,
        closing: bool = False,
        bidirectional: bool = False,
        ac_faces: Optional[Sequence[int]] = None,
        reads_per_stop: Optional[int] = None,
        reading_noise_arcsec: Optional[float] = None,
        settle_seconds: float = 0.0,
        resume: bool = False,
        ports: Optional[Dict[str, str]] = None,
    ) -> None: ...
    @property
    def dir(self) -> Optional[Path]: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def readings_done(self) -> int: ...
    @property
    def refused(self) -> int: ...
    def now(self) -> float: ...
    def begin(self, ac_identifications: Sequence[str], table_identification: str) -> None: ...
    def poll(self) -> Action: ...
    def moved(self, at_deg: float) -> None: ...
    def position(self, deg: float) -> None: ...
    def read(self, status: int, x_arcsec: float, y_arcsec: Optional[float] = None) -> None: ...
    def waited(self) -> None: ...
    def remounted(self, confirmed: bool) -> None: ...
    def failed(self, message: str) -> None: ...
    def traffic(self, device: str, port: str, event: str, text: str) -> None: ...
    def interrupt(self) -> None: ...
    def finish(self) -> str: ...

class WireAction:
    """What the wire rules ask of your port next; the fields of its `kind` are set."""

    kind: str  # drain, clear, send, read_line, await_input, wait, note, done
    text: Optional[str]
    seconds: Optional[float]
    event: Optional[str]

class AcWire:
    """An autocollimator's wire rules for a port of your own (docs/FORMAT.md §7.7)."""

    def __init__(
        self,
        port: str,
        profile: str = "elcomat3000",
        *,
        reply_timeout: float = 1.0,
        retries: int = 3,
        alone_wait: float = 0.0,
        start_wait: float = 0.05,
    ) -> None: ...
    def begin(self, op: str) -> None: ...
    def poll(self) -> WireAction: ...
    def tell(
        self,
        now: float,
        event: str,
        *,
        lines: Optional[Sequence[str]] = None,
        line: Optional[str] = None,
        message: Optional[str] = None,
    ) -> None: ...
    def outcome(self) -> Union[None, str, Tuple[int, float, Optional[float]]]: ...

class TableWire:
    """A rotary table's wire rules for a port of your own (docs/FORMAT.md §7.7)."""

    def __init__(
        self,
        port: str,
        profile: str = "smc100",
        *,
        reply_timeout: float = 1.0,
        retries: int = 3,
        alone_wait: float = 0.0,
        poll_interval: float = 0.02,
        motion_timeout: float = 120.0,
        position_tolerance_deg: float = 0.001,
    ) -> None: ...
    def begin(self, op: str, deg: Optional[float] = None) -> None: ...
    def poll(self) -> WireAction: ...
    def tell(
        self,
        now: float,
        event: str,
        *,
        lines: Optional[Sequence[str]] = None,
        line: Optional[str] = None,
        message: Optional[str] = None,
    ) -> None: ...
    def interrupt(self) -> None: ...
    def outcome(self) -> Union[None, str, float]: ...

def version() -> str: ...
def read_measurements(
    path: Optional[str] = None,
    text: Optional[str] = None,
    name: str = "<text>",
    faces: Optional[int] = None,
) -> MeasurementSet: ...
def check_columns_fit(rows: int) -> None: ...
def measurement_set_from_columns(
    cycle: Sequence[int],
    step: Sequence[int],
    ac: Sequence[int],
    face: Sequence[int],
    reading: Sequence[float],
    direction: Optional[Sequence[str]] = None,
    time: Optional[Sequence[Optional[float]]] = None,
    setup: Optional[Sequence[int]] = None,
    shift: Optional[Sequence[float]] = None,
    temperature: Optional[Sequence[Optional[float]]] = None,
    reading_y: Optional[Sequence[Optional[float]]] = None,
    faces: Optional[int] = None,
    name: str = "<arrays>",
) -> MeasurementSet: ...
def read_budget(
    path: Optional[str] = None, text: Optional[str] = None, name: str = "<budget>"
) -> Budget: ...
def read_results(path: str) -> ResultRows:
    """A result file (docs/FORMAT.md §3) or a DCC certificate (§13.3), by its content."""
    ...
def solve(
    ms: MeasurementSet,
    method: str = "auto",
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> SolveResult: ...
def compare_rows(
    a: ResultRows,
    b: ResultRows,
    correlation: float = 0.0,
    include_setup: bool = False,
    verdict: str = "vector",
) -> str: ...
def kc(
    labs: Sequence[Tuple[str, ResultRows]],
    pilot: Sequence[Tuple[str, ResultRows]] = ...,
    quantity: str = "pitch_deviation",
    method: str = "weighted-mean",
    keep: Sequence[str] = ...,
    not_in_reference: Sequence[str] = ...,
    link: Optional[str] = None,
    monte_carlo: Optional[int] = None,
    anonymise: bool = False,
    key: Optional[str] = None,
    seed: int = 0,
) -> Tuple[str, Optional[str]]: ...
def shared_quantities(
    labs: Sequence[Tuple[str, ResultRows]],
    pilot: Sequence[Tuple[str, ResultRows]] = ...,
) -> List[str]: ...
def history(
    calibrations: Sequence[Tuple[ResultRows, str]],
    at: Optional[str] = None,
    quantity: str = "pitch_deviation",
    max_u: Optional[float] = None,
) -> str: ...
def simulate(
    faces: int = 24,
    ac_faces: Sequence[int] = ...,
    cycles: int = 6,
    closing: bool = True,
    bidirectional: bool = False,
    noise: float = 0.05,
    pitch_spread: Optional[float] = None,
    harmonic: Sequence[str] = ...,
    setup_spread: Optional[float] = None,
    step_seconds: Optional[float] = None,
    setups: int = 1,
    setup_shift_faces: Optional[int] = None,
    shift_deg: Sequence[float] = ...,
    seed: int = 1,
    noise_dof: Optional[float] = None,
    temperature: Optional[str] = None,
    elevation: Optional[str] = None,
    drift: Sequence[str] = ...,
    offset_step: Sequence[str] = ...,
    temperature_effect: Sequence[str] = ...,
    cross_talk: Sequence[str] = ...,
    direction: Sequence[str] = ...,
    outlier: Sequence[str] = ...,
    rezero: Sequence[str] = ...,
    random_walk: Sequence[str] = ...,
    no_time: bool = False,
) -> Tuple[MeasurementSet, str]: ...
def simulate_selfcal(
    positions: int = 168,
    heads: Optional[Sequence[float]] = None,
    cycles: int = 2,
    bidirectional: bool = False,
    noise: float = 0.02,
    harmonic: Sequence[str] = ...,
    max_order: int = 60,
    table_error: float = 1.0,
    head_error: float = 2.0,
    step_seconds: float = 20.0,
    seed: int = 1,
) -> Tuple[SelfcalSet, str]: ...
def diagnose(
    ms: MeasurementSet,
    truth: Optional[str] = None,
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
    truth_path: Optional[str] = None,
) -> str: ...
def read_selfcal(
    path: Optional[str] = None,
    text: Optional[str] = None,
    name: str = "<text>",
    positions: Optional[int] = None,
) -> SelfcalSet: ...
def selfcal_set_from_columns(
    cycle: Sequence[int],
    step: Sequence[int],
    head: Sequence[int],
    head_angle: Sequence[float],
    reading: Sequence[float],
    direction: Optional[Sequence[str]] = None,
    time: Optional[Sequence[Optional[float]]] = None,
    positions: Optional[int] = None,
    name: str = "<arrays>",
) -> SelfcalSet: ...
def selfcal(
    set: SelfcalSet,
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> str: ...
def _restore_measurement_set(state: Any) -> MeasurementSet: ...
def _restore_selfcal_set(state: Any) -> SelfcalSet: ...
def _restore_rows(state: Any) -> ResultRows: ...
def _restore_budget(state: Any) -> Budget: ...
def _restore_solve_result(state: Any) -> SolveResult: ...
