"""Type stubs of the native module (python/src/lib.rs); the package's public API is
polycal/__init__.py, typed inline. The exceptions are `polycal.`'s (`__module__ ==
"polycal"`); sets, budgets, result rows and solve results pickle through `__reduce__` and the
`_restore_…` functions (python/src/state.rs)."""

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
def read_results(path: str) -> ResultRows: ...
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
