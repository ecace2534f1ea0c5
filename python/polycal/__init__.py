"""polycal for Python: calibrate an optical polygon and a rotary encoder at the same time.

The two-autocollimator method of Hsieh, Lin, Yeh and Watanabe, *Calibration of a Rotary
Encoder and a Polygon Using a Two-Autocollimator Method*, Appl. Sci. 2023, 13, 1865 ("the
paper"), with uncertainty, comparison, diagnosis and self-calibration. This package is a
thin skin over the Rust library (the same code the ``polycal`` command runs): it reads
arguments, calls the library with the GIL released, and gives back numpy arrays. Every
number is the command's JSON number, to the last bit.

All angles are arcseconds unless a name says otherwise. Contract: docs/FORMAT.md of the
repository.
"""

from __future__ import annotations

import json as _json
import os as _os
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as _np

from . import _polycal
from ._polycal import DesignError, InputError, PolycalError

__all__ = [
    "PolycalError",
    "InputError",
    "DesignError",
    "MeasurementSet",
    "SelfcalSet",
    "Budget",
    "Result",
    "SolveResult",
    "read_measurements",
    "read_selfcal",
    "read_results",
    "budget",
    "solve",
    "diagnose",
    "selfcal",
    "compare",
    "simulate",
    "__version__",
]

__version__ = _polycal.version()

PathOrText = Union[str, "_os.PathLike[str]"]


def _path_or_text(source: PathOrText) -> Dict[str, str]:
    """A path (``os.PathLike``, or a string without a line break) or a text (a string with
    one)."""
    if isinstance(source, _os.PathLike):
        return {"path": _os.fspath(source)}
    if not isinstance(source, str):
        raise TypeError(f"expected a path or a text, got {type(source).__name__}")
    if "\n" in source:
        return {"text": source}
    return {"path": source}


class MeasurementSet:
    """Readings of a two-autocollimator run (docs/FORMAT.md §2): one reading is
    α[p mod N] + φ[face] + U[setup, ac] + noise (the paper's eq. (2))."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    @property
    def faces(self) -> int:
        """N, the number of faces."""
        return self._inner.faces

    @property
    def source(self) -> str:
        """Where the readings came from."""
        return self._inner.source

    def __len__(self) -> int:
        return len(self._inner)

    def __repr__(self) -> str:
        return repr(self._inner)

    def columns(self) -> Dict[str, _np.ndarray]:
        """The readings as numpy columns named as the file's; optional columns hold NaN
        where a reading has no value."""
        out = {}
        for name, values in self._inner.columns().items():
            if name == "direction":
                out[name] = _np.asarray(values, dtype=object)
            elif name in ("reading", "time", "reading_y", "temperature"):
                out[name] = _np.asarray(
                    [_np.nan if v is None else v for v in values], dtype=_np.float64
                )
            else:
                out[name] = _np.asarray(values, dtype=_np.int64)
        return out

    @classmethod
    def from_arrays(
        cls,
        *,
        cycle: Sequence[int],
        step: Sequence[int],
        ac: Sequence[int],
        face: Sequence[int],
        reading: Sequence[float],
        direction: Optional[Sequence[str]] = None,
        time: Optional[Sequence[float]] = None,
        setup: Optional[Sequence[int]] = None,
        shift: Optional[Sequence[float]] = None,
        temperature: Optional[Sequence[float]] = None,
        reading_y: Optional[Sequence[float]] = None,
        faces: Optional[int] = None,
        name: str = "<arrays>",
    ) -> "MeasurementSet":
        """A set from columns (numpy arrays or lists), checked as a file is: integer
        columns take any integer dtype (or floats that are whole numbers), value columns any
        real dtype; NaN in an optional column means no value there. A bad shape, a bad
        dtype or a NaN reading is refused naming the column and the index."""
        integers = {
            "cycle": cycle,
            "step": step,
            "ac": ac,
            "face": face,
        }
        if setup is not None:
            integers["setup"] = setup
        arguments: Dict[str, Any] = {
            key: _integer_column(key, values) for key, values in integers.items()
        }
        arguments["reading"] = _real_column("reading", reading, optional=False)
        if shift is not None:
            arguments["shift"] = _real_column("shift", shift, optional=False)
        for key, values in (
            ("time", time),
            ("temperature", temperature),
            ("reading_y", reading_y),
        ):
            if values is not None:
                arguments[key] = _real_column(key, values, optional=True)
        if direction is not None:
            arguments["direction"] = [str(d) for d in _one_dimensional("direction", direction)]
        return cls(
            _polycal.measurement_set_from_columns(faces=faces, name=name, **arguments)
        )

    @classmethod
    def from_dataframe(cls, df: Any, faces: Optional[int] = None) -> "MeasurementSet":
        """A set from a pandas DataFrame with the file's column names (docs/FORMAT.md §2:
        ``cycle``, ``step``, ``ac``, ``face``, ``reading`` and optionally ``direction``,
        ``time``, ``setup``, ``temperature``, ``reading_y``)."""
        known = {
            "cycle",
            "step",
            "ac",
            "face",
            "reading",
            "direction",
            "time",
            "setup",
            "shift",
            "temperature",
            "reading_y",
        }
        columns = {c: df[c].to_numpy() for c in df.columns if c in known}
        missing = {"cycle", "step", "ac", "face", "reading"} - set(columns)
        if missing:
            raise ValueError(f"the DataFrame lacks the columns {sorted(missing)}")
        return cls.from_arrays(faces=faces, name="<DataFrame>", **columns)


def _one_dimensional(name: str, values: Any) -> _np.ndarray:
    array = _np.asarray(values)
    if array.ndim != 1:
        raise ValueError(f"column {name}: expected one dimension, got shape {array.shape}")
    return array


def _integer_column(name: str, values: Any) -> list:
    array = _one_dimensional(name, values)
    if array.dtype.kind in "iu":
        return array.astype(_np.int64).tolist()
    if array.dtype.kind == "f":
        bad = ~_np.isfinite(array) | (array != _np.round(array))
        if bad.any():
            index = int(_np.argmax(bad))
            raise ValueError(
                f"column {name}, index {index}: {array[index].item()!r} is not a whole number"
            )
        return array.astype(_np.int64).tolist()
    if array.dtype.kind == "b":
        raise ValueError(f"column {name}: booleans are not numbers of {name}")
    raise ValueError(f"column {name}: expected integers, got dtype {array.dtype}")


def _real_column(name: str, values: Any, optional: bool) -> list:
    array = _one_dimensional(name, values)
    if array.dtype.kind not in "iuf":
        raise ValueError(f"column {name}: expected real numbers, got dtype {array.dtype}")
    array = array.astype(_np.float64)
    finite = _np.isfinite(array)
    if optional:
        bad = _np.isinf(array)
        if bad.any():
            index = int(_np.argmax(bad))
            raise ValueError(f"column {name}, index {index}: {array[index].item()!r} is not finite")
        return [float(v) if ok else None for v, ok in zip(array.tolist(), finite.tolist())]
    if not finite.all():
        index = int(_np.argmax(~finite))
        raise ValueError(
            f"column {name}, index {index}: {array[index].item()!r} is not a finite number"
        )
    return array.tolist()


def read_measurements(source: PathOrText, faces: Optional[int] = None) -> MeasurementSet:
    """Reads a measurement file, or a measurement file's text (a string with a line
    break). A file that is not valid raises ``InputError`` with ``path``, ``line`` and
    ``column``."""
    return MeasurementSet(_polycal.read_measurements(faces=faces, **_path_or_text(source)))


class SelfcalSet:
    """Readings of a multi-head self-calibration (docs/FORMAT.md §9.2): reading = t[cycle,
    step] + e(table angle + head angle) + c[head] + noise."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __len__(self) -> int:
        return len(self._inner)

    @classmethod
    def from_arrays(
        cls,
        *,
        cycle: Sequence[int],
        step: Sequence[int],
        head: Sequence[int],
        head_angle: Sequence[float],
        reading: Sequence[float],
        direction: Optional[Sequence[str]] = None,
        time: Optional[Sequence[float]] = None,
        positions: Optional[int] = None,
        name: str = "<arrays>",
    ) -> "SelfcalSet":
        """A set from columns named as the file's, checked as a file is."""
        arguments: Dict[str, Any] = {
            key: _integer_column(key, values)
            for key, values in (("cycle", cycle), ("step", step), ("head", head))
        }
        arguments["head_angle"] = _real_column("head_angle", head_angle, optional=False)
        arguments["reading"] = _real_column("reading", reading, optional=False)
        if time is not None:
            arguments["time"] = _real_column("time", time, optional=True)
        if direction is not None:
            arguments["direction"] = [str(d) for d in _one_dimensional("direction", direction)]
        return cls(
            _polycal.selfcal_set_from_columns(positions=positions, name=name, **arguments)
        )

    @classmethod
    def from_dataframe(cls, df: Any, positions: Optional[int] = None) -> "SelfcalSet":
        """A set from a pandas DataFrame with the file's column names."""
        known = {"cycle", "step", "head", "head_angle", "reading", "direction", "time"}
        columns = {c: df[c].to_numpy() for c in df.columns if c in known}
        return cls.from_arrays(positions=positions, name="<DataFrame>", **columns)


def read_selfcal(source: PathOrText, positions: Optional[int] = None) -> SelfcalSet:
    """Reads a self-calibration file or its text."""
    return SelfcalSet(_polycal.read_selfcal(positions=positions, **_path_or_text(source)))


class Budget:
    """An instrument budget (docs/FORMAT.md §5.1)."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner


def budget(source: Union[PathOrText, Dict[str, Any]]) -> Budget:
    """An instrument budget from a TOML file, its text, or a dict with the file's keys
    (e.g. ``{"p": 0.95, "component": [{...}, ...]}``)."""
    if isinstance(source, dict):
        return Budget(_polycal.read_budget(text=_toml(source), name="<dict>"))
    return Budget(_polycal.read_budget(**_path_or_text(source)))


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return _json.dumps(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_json.dumps(k)} = {_toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(f"budget: {type(value).__name__} is not a TOML value")


def _toml(data: Dict[str, Any]) -> str:
    """A dict as TOML text for the library's reader: scalars and lists as ``key = value``,
    a list of dicts as an array of tables (``[[component]]``), one key per line."""
    lines = []
    tables = []
    for key, value in data.items():
        if isinstance(value, (list, tuple)) and value and all(isinstance(v, dict) for v in value):
            tables.append((key, value))
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    for key, entries in tables:
        for entry in entries:
            lines.append("")
            lines.append(f"[[{key}]]")
            lines.extend(f"{k} = {_toml_value(v)}" for k, v in entry.items())
    return "\n".join(lines) + "\n"


class Result:
    """A command's JSON object (docs/FORMAT.md §5) with its number arrays as numpy."""

    _families = (
        "pitch_deviation",
        "face_deviation",
        "encoder_error",
        "encoder_angle_deg",
    )

    def __init__(self, text: str) -> None:
        self._json = text
        self._dict = _json.loads(text)

    def to_json(self) -> str:
        """The JSON text the command prints with ``--format json``."""
        return self._json

    def to_dict(self) -> Dict[str, Any]:
        """The JSON object as a dict (a fresh copy)."""
        return _json.loads(self._json)

    def __getitem__(self, key: str) -> Any:
        return self._value(key)

    def __getattr__(self, key: str) -> Any:
        if key.startswith("_"):
            raise AttributeError(key)
        try:
            return self._value(key)
        except KeyError:
            raise AttributeError(key) from None

    def keys(self):
        return self._dict.keys()

    def _value(self, key: str) -> Any:
        value = self._dict[key]
        if isinstance(value, list) and value and all(
            isinstance(v, (int, float)) or v is None for v in value
        ) and any(isinstance(v, float) for v in value):
            return _np.asarray([_np.nan if v is None else v for v in value], dtype=_np.float64)
        return value

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(self._dict)})"


class SolveResult(Result):
    """The result of :func:`solve`: β (``pitch_deviation``), φ (``face_deviation``), α
    (``encoder_error``) and their ``_u``, ``_U`` and ``_k`` as numpy arrays, the setup
    errors, the fit, and with a budget the uncertainty evaluation."""

    def __init__(self, inner: Any) -> None:
        super().__init__(inner.json())
        self._inner = inner

    def _setup(self, key: str) -> _np.ndarray:
        return _np.asarray(
            [_np.nan if s.get(key) is None else s[key] for s in self._dict["setup_error"]],
            dtype=_np.float64,
        )

    @property
    def setup_error_value(self) -> _np.ndarray:
        """The setup errors U[setup, ac] (the JSON's ``setup_error[].value``), in its order;
        ``setup_error_setup`` and ``setup_error_ac`` say whose."""
        return self._setup("value")

    @property
    def setup_error_setup(self) -> _np.ndarray:
        """The mounting of each setup error."""
        return _np.asarray([s["setup"] for s in self._dict["setup_error"]], dtype=_np.int64)

    @property
    def setup_error_ac(self) -> _np.ndarray:
        """The autocollimator of each setup error."""
        return _np.asarray([s["ac"] for s in self._dict["setup_error"]], dtype=_np.int64)

    @property
    def setup_error_u(self) -> _np.ndarray:
        """u of each setup error (NaN when σ is unknown)."""
        return self._setup("u")

    @property
    def setup_error_U(self) -> _np.ndarray:
        """U of each setup error (with a budget; NaN without)."""
        return self._setup("U")

    @property
    def setup_error_k(self) -> _np.ndarray:
        """k of each setup error (with a budget; NaN without)."""
        return self._setup("k")

    @property
    def angle_deg(self) -> _np.ndarray:
        """The table angle of every encoder error, degrees: ``encoder_angle_deg`` where the
        JSON has it (sub-pitch mountings), else p·360°/N as the library states it."""
        if "encoder_angle_deg" in self._dict:
            return self["encoder_angle_deg"]
        return _np.asarray(self._inner.encoder_angle_deg(), dtype=_np.float64)

    def covariance(self, family: str) -> Optional[_np.ndarray]:
        """The fit's covariance σ²Q of one family (``pitch_deviation``,
        ``face_deviation``, ``encoder_error``, ``setup_error``), arcsec², as a dense n × n
        array formed only now; ``None`` when σ is unknown. Its diagonal is ``…_u`` squared."""
        found = self._inner.covariance(family)
        if found is None:
            return None
        n, values = found
        return _np.asarray(values, dtype=_np.float64).reshape(n, n)

    def to_dataframe(self) -> Any:
        """The results as a pandas DataFrame, one row per quantity (``quantity``,
        ``index``, ``value``, ``u``, and ``U``, ``k`` with a budget). Needs pandas."""
        import pandas as pd

        rows = []
        for quantity, first in (
            ("pitch_deviation", 1),
            ("face_deviation", 1),
            ("encoder_error", 0),
        ):
            values = self._dict[quantity]
            for i, value in enumerate(values):
                row = {"quantity": quantity, "index": i + first, "value": value}
                for suffix in ("_u", "_U", "_k"):
                    column = self._dict.get(quantity + suffix)
                    if column is not None:
                        row[suffix[1:]] = column[i]
                rows.append(row)
        return pd.DataFrame(rows)

    def plot(self, family: str = "pitch_deviation", ax: Any = None) -> Any:
        """Draws a family with its U bars (or u without a budget) through matplotlib;
        returns the axes. Needs matplotlib."""
        import matplotlib.pyplot as plt

        values = self[family]
        bars = self._dict.get(family + "_U") or self._dict.get(family + "_u")
        if ax is None:
            _, ax = plt.subplots()
        x = _np.arange(len(values)) + (0 if family == "encoder_error" else 1)
        ax.errorbar(x, values, yerr=None if bars is None else _np.asarray(bars, dtype=float), fmt="o", capsize=3)
        ax.set_xlabel("position p" if family == "encoder_error" else "face")
        ax.set_ylabel(f"{family} / arcsec")
        return ax


class _Rows:
    def __init__(self, inner: Any) -> None:
        self._inner = inner


def read_results(path: PathOrText) -> _Rows:
    """Reads a result file (docs/FORMAT.md §3), for :func:`compare`."""
    return _Rows(_polycal.read_results(_os.fspath(path)))


def _sigma(sigma: Optional[float]) -> Optional[float]:
    return None if sigma is None else float(sigma)


def solve(
    ms: MeasurementSet,
    method: str = "auto",
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> SolveResult:
    """Solves the set as ``polycal solve`` does: the paper's closed form (eqs. (6)–(10))
    for two adjacent autocollimators, least squares for any design (``method``: ``auto``,
    ``closed-form``, ``lsq``, ``dense``); with a budget, U and k of every result (eqs.
    (11)–(13)); with ``monte_carlo`` (a number of trials or ``"adaptive"``) the JCGM 101
    evaluation. ``sigma`` is σ of one reading for an exactly determined fit (dof = 0).
    A design that cannot determine some harmonics raises ``DesignError``."""
    return SolveResult(
        _polycal.solve(
            ms._inner,
            method=method,
            sigma=_sigma(sigma),
            budget=None if budget is None else budget._inner,
            monte_carlo=monte_carlo,
            seed=seed,
        )
    )


def diagnose(
    ms: MeasurementSet,
    truth: Optional[Union[Dict[str, Any], str]] = None,
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
) -> Result:
    """Diagnoses the set as ``polycal diagnose`` does: finds the effects the model lacks,
    adds them, and says whether the final model is adequate; with a truth (a dict or JSON
    text, as :func:`simulate` returns) the error before and after."""
    if isinstance(truth, dict):
        truth = _json.dumps(truth)
    return Result(
        _polycal.diagnose(
            ms._inner,
            truth=truth,
            sigma=_sigma(sigma),
            budget=None if budget is None else budget._inner,
        )
    )


def selfcal(
    set: SelfcalSet, sigma: Optional[float] = None, budget: Optional[Budget] = None
) -> Result:
    """Self-calibrates the encoder from a multi-head run as ``polycal selfcal`` does."""
    return Result(
        _polycal.selfcal(
            set._inner, sigma=_sigma(sigma), budget=None if budget is None else budget._inner
        )
    )


def compare(
    a: Union[SolveResult, _Rows, PathOrText],
    b: Union[SolveResult, _Rows, PathOrText],
    correlation: float = 0.0,
    include_setup: bool = False,
) -> Result:
    """Compares two results by En (the paper's eqs. (14)–(15), ISO 13528) as ``polycal
    compare`` does: ``rows`` with ``en`` per quantity, ``max_abs_en``; each of ``a`` and
    ``b`` a :class:`SolveResult` (with a budget) or a result file."""

    def rows(x: Any) -> Any:
        if isinstance(x, SolveResult):
            return x._inner.rows()
        if isinstance(x, _Rows):
            return x._inner
        return _polycal.read_results(_os.fspath(x))

    return Result(
        _polycal.compare_rows(
            rows(a), rows(b), correlation=float(correlation), include_setup=bool(include_setup)
        )
    )


def simulate(
    faces: int = 24,
    ac_faces: Sequence[int] = (1, 2),
    cycles: int = 6,
    closing: bool = True,
    bidirectional: bool = False,
    noise: float = 0.05,
    pitch_spread: Optional[float] = None,
    setup_spread: Optional[float] = None,
    step_seconds: Optional[float] = None,
    setups: int = 1,
    setup_shift_faces: Optional[int] = None,
    seed: int = 1,
) -> Tuple[MeasurementSet, Dict[str, Any]]:
    """A simulated run with a known truth, as ``polycal simulate`` draws it: the set and
    the truth (β, α, the setup errors) as a dict."""
    inner, truth = _polycal.simulate(
        faces=faces,
        ac_faces=list(ac_faces),
        cycles=cycles,
        closing=closing,
        bidirectional=bidirectional,
        noise=noise,
        pitch_spread=pitch_spread,
        setup_spread=setup_spread,
        step_seconds=step_seconds,
        setups=setups,
        setup_shift_faces=setup_shift_faces,
        seed=seed,
    )
    return MeasurementSet(inner), _json.loads(truth)
