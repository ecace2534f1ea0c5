"""The data a user hands over: measurement and self-calibration sets (a file, its text,
numpy arrays, a pandas DataFrame; column shapes and dtypes checked here, every reading by
the library) and instrument budgets."""

from __future__ import annotations

import json as _json
import os as _os
import warnings as _warnings
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as _np

from . import _polycal
from ._polycal import PolycalWarning

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

    @property
    def comments(self) -> List[str]:
        """The comment lines :meth:`write` puts at the head of the file (a simulated run's
        description, as ``polycal simulate`` writes it); empty for a set read or built."""
        return self._inner.comments

    def write(self, path: PathOrText) -> None:
        """Writes the set as a measurement file (docs/FORMAT.md §2), whole or not at all
        (a new file renamed over the old one), with its :attr:`comments` first: a set of
        :func:`simulate` is then the file ``polycal simulate --out`` writes, to the byte."""
        self._inner.write(_os.fspath(path))

    def to_dataframe(self) -> Any:
        """The readings as a pandas DataFrame, one row per reading in file order, the
        columns of :meth:`columns` (named as the file's: ``setup``, ``cycle``, ``step``,
        ``ac``, ``face``, ``reading``, ``direction``, ``time``, ``reading_y``,
        ``temperature``, ``encoder`` — the commanded position a file gave, degrees — and
        ``shift`` for a set with shifted mountings; NaN where a reading has no value).
        Needs pandas; the inverse of :meth:`from_dataframe`."""
        import pandas as pd

        return pd.DataFrame(self.columns())

    def columns(self) -> Dict[str, _np.ndarray]:
        """The readings as numpy columns named as the file's (``encoder`` the commanded
        position a file gave, degrees; ``shift`` only with shifted mountings); optional
        columns hold NaN where a reading has no value."""
        out = {}
        for name, values in self._inner.columns().items():
            if name == "direction":
                out[name] = _np.asarray(values, dtype=object)
            elif name in ("reading", "time", "reading_y", "temperature", "encoder", "shift"):
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
        # refused up front when the set would not fit (MemoryError), before any copy
        _polycal.check_columns_fit(len(reading))
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


_INT64_MAX = 2**63 - 1


def _beyond_int64(name: str, array: Any, too_large: Any) -> None:
    """Refuses the first value the library's integers cannot hold (a uint64 above 2⁶³ − 1
    once wrapped to a negative number and was called negative)."""
    if too_large.any():
        index = int(_np.argmax(too_large))
        raise ValueError(
            f"column {name}, index {index}: {array[index].item()!r} is too large "
            f"(at most {_INT64_MAX})"
        )


def _integer_column(name: str, values: Any) -> list:
    array = _one_dimensional(name, values)
    if array.dtype.kind == "u":
        _beyond_int64(name, array, array > _np.uint64(_INT64_MAX))
        return array.astype(_np.int64).tolist()
    if array.dtype.kind == "i":
        return array.astype(_np.int64).tolist()
    if array.dtype.kind == "f":
        bad = ~_np.isfinite(array) | (array != _np.round(array))
        if bad.any():
            index = int(_np.argmax(bad))
            raise ValueError(
                f"column {name}, index {index}: {array[index].item()!r} is not a whole number"
            )
        # 2⁶³ is the first float beyond int64
        _beyond_int64(name, array, _np.abs(array) >= 2.0**63)
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
    ``column``; a file that is not there ``FileNotFound`` (a ``FileNotFoundError``, with
    ``filename`` and ``path``)."""
    return MeasurementSet(_polycal.read_measurements(faces=faces, **_path_or_text(source)))


class SelfcalSet:
    """Readings of a multi-head self-calibration (docs/FORMAT.md §9.2): reading = t[cycle,
    step] + e(table angle + head angle) + c[head] + noise."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __len__(self) -> int:
        return len(self._inner)

    def __repr__(self) -> str:
        return repr(self._inner)

    @property
    def positions(self) -> int:
        """P, the number of table positions per turn."""
        return self._inner.positions

    @property
    def source(self) -> str:
        """Where the readings came from."""
        return self._inner.source

    @property
    def comments(self) -> List[str]:
        """The comment lines :meth:`write` puts at the head of the file (a simulated run's
        description, as ``polycal simulate --selfcal`` writes it)."""
        return self._inner.comments

    def write(self, path: PathOrText) -> None:
        """Writes the set as a self-calibration file (docs/FORMAT.md §9.2), whole or not
        at all, with its :attr:`comments` first: a set of :func:`simulate_selfcal` is then
        the file ``polycal simulate --selfcal --out`` writes, to the byte."""
        self._inner.write(_os.fspath(path))

    def columns(self) -> Dict[str, _np.ndarray]:
        """The readings as numpy columns named as the file's (``cycle``, ``step``,
        ``head``, ``head_angle``, ``reading``, ``direction``, ``time``; NaN where a
        reading has no time)."""
        out = {}
        for name, values in self._inner.columns().items():
            if name == "direction":
                out[name] = _np.asarray(values, dtype=object)
            elif name in ("head_angle", "reading", "time"):
                out[name] = _np.asarray(
                    [_np.nan if v is None else v for v in values], dtype=_np.float64
                )
            else:
                out[name] = _np.asarray(values, dtype=_np.int64)
        return out

    def to_dataframe(self) -> Any:
        """The readings as a pandas DataFrame with the columns of :meth:`columns`. Needs
        pandas; the inverse of :meth:`from_dataframe`."""
        import pandas as pd

        return pd.DataFrame(self.columns())

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
        _polycal.check_columns_fit(len(reading))
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
    """An instrument budget (docs/FORMAT.md §5.1): its coverage probability ``p`` and its
    ``components``; the repr lists them."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    @property
    def p(self) -> float:
        """The coverage probability of every U."""
        return self._inner.p

    @property
    def source(self) -> str:
        """Where the budget came from: its path, or the name of its text."""
        return self._inner.source

    @property
    def components(self) -> List[Dict[str, Any]]:
        """The components in file order (nested budgets flattened), each a dict: ``name``,
        ``type`` (A or B), ``distribution``, ``u`` (|c|·u(x), arcsec: the standard
        uncertainty one draw adds to a reading), ``sensitivity``, ``dof`` (``None``:
        infinitely many) and ``acts_on`` (which readings share one draw)."""
        return self._inner.components()

    def notes(self) -> List[str]:
        """The cautions ``polycal`` prints when it reads the budget."""
        return self._inner.notes()

    def __repr__(self) -> str:
        lines = [f"Budget(p = {self.p}, from {self.source}:"]
        for c in self.components:
            dof = "∞" if c["dof"] is None else f"{c['dof']:g}"
            lines.append(
                f"  {c['name']}: type {c['type']}, {c['distribution']}, "
                f"u = {c['u']:.4g} arcsec, ν = {dof}, acts on {c['acts_on']}"
            )
        return "\n".join(lines) + ")"


def budget(source: Union[PathOrText, Dict[str, Any]]) -> Budget:
    """An instrument budget from a TOML file, its text, or a dict with the file's keys
    (e.g. ``{"p": 0.95, "component": [{...}, ...]}``). The cautions ``polycal`` prints when
    it reads a budget (a type A component that the fit already counts) are issued as
    ``PolycalWarning`` (a ``UserWarning``). A file that is not there raises
    ``FileNotFound`` (a ``FileNotFoundError``). A dict that is not a valid budget raises ``ValueError`` quoting the
    entry at fault."""
    if isinstance(source, dict):
        text = _toml(source)
        try:
            inner = _polycal.read_budget(text=text, name="<dict>")
        except _polycal.InputError as error:
            lines = text.splitlines()
            at = lines[error.line - 1] if 0 < error.line <= len(lines) else ""
            message = str(error).split(": ", 1)[-1]
            raise ValueError(f"budget: {message} (at `{at}`)") from error
    else:
        inner = _polycal.read_budget(**_path_or_text(source))
    for note in inner.notes():
        _warnings.warn(note, PolycalWarning, stacklevel=2)
    return Budget(inner)


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


