"""The results: a command's JSON object with its number lists as numpy arrays."""

from __future__ import annotations

import json as _json
import os as _os
from typing import Any, Dict, Optional

import numpy as _np

from . import _polycal
from ._data import PathOrText

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


