"""The results: a command's JSON object with its number lists as numpy arrays at every
depth, its fields as attributes (listed by ``dir()``, so a notebook completes them), a
repr that shows the main numbers, and tables and figures of them."""

from __future__ import annotations

import json as _json
import os as _os
import warnings as _warnings
from typing import Any, Dict, Iterator, List, Optional

import numpy as _np

from . import _polycal
from ._data import PathOrText
from ._polycal import PolycalWarning


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _array(values: list) -> Optional[_np.ndarray]:
    """A list of numbers (``None`` for a number not known) as a numpy array: int64 when
    every entry is a whole number of the JSON, else float64 with NaN for ``None``;
    ``None`` when the list holds anything else."""
    if not values or not all(v is None or _is_number(v) for v in values):
        return None
    if all(isinstance(v, int) and not isinstance(v, bool) for v in values):
        try:
            return _np.asarray(values, dtype=_np.int64)
        except OverflowError:
            return None
    return _np.asarray([_np.nan if v is None else v for v in values], dtype=_np.float64)


#: The fields of a solve's JSON object (and of ``diagnose``'s ``before`` and ``after``)
#: that only an uncertainty evaluation gives: with a budget (``p``, U, k, ``uncertainty``)
#: or with ``monte_carlo=``. Without it they read as ``None`` (the JSON has no such key).
_SOLVE_EVALUATED = frozenset(
    {
        "p",
        "pitch_deviation_U",
        "face_deviation_U",
        "encoder_error_U",
        "pitch_deviation_k",
        "face_deviation_k",
        "encoder_error_k",
        "uncertainty",
        "monte_carlo",
    }
)

#: The same for a setup error of a solve (``setup_error[i]``): U and k with a budget.
_SETUP_EVALUATED = frozenset({"U", "k"})

#: The same for ``selfcal``'s object: its U and k are the fit's and always there; the
#: budget's evaluation and the Monte Carlo are not.
_SELFCAL_EVALUATED = frozenset({"uncertainty", "monte_carlo"})


def _convert(value: Any) -> Any:
    """The JSON value with its number lists as numpy arrays and its objects as
    :class:`Section`, at every depth; scalars and strings as they are."""
    if isinstance(value, dict):
        return Section({k: _convert(v) for k, v in value.items()})
    if isinstance(value, list):
        array = _array(value)
        if array is not None:
            return array
        return [_convert(v) for v in value]
    return value


def _summary(value: Any, width: int = 4) -> str:
    """A short text of a value for a repr: numbers to 4 significant digits, the first
    entries of an array."""
    if isinstance(value, _np.ndarray):
        shown = ", ".join(_number(v) for v in value[:width])
        more = ", …" if len(value) > width else ""
        return f"[{shown}{more}] ({len(value)})"
    if isinstance(value, float):
        return _number(value)
    if isinstance(value, (dict, list)):
        return f"{type(value).__name__}({len(value)})"
    return repr(value)


def _number(v: Any) -> str:
    return "nan" if v != v else f"{v:.4g}"


class Section(dict):
    """An object of a command's JSON: a dict whose keys are attributes too (``dir()``
    lists them), its number lists numpy arrays. A field only an uncertainty evaluation
    gives (U, k, ``p``, ``uncertainty``, ``monte_carlo``) reads as ``None`` when the
    evaluation was not made."""

    #: The fields that read as ``None`` when absent.
    _optional: frozenset = frozenset()

    def __getattr__(self, key: str) -> Any:
        try:
            return self[key]
        except KeyError:
            raise AttributeError(key) from None

    def __missing__(self, key: Any) -> Any:
        if key in self._optional:
            return None
        raise KeyError(key)

    def __dir__(self) -> List[str]:
        keys = set(self) | set(self._optional)
        return sorted(set(dir(dict)) | {k for k in keys if k.isidentifier()})



def _optional_section(value: Any, optional: frozenset) -> Any:
    """``value`` (a :class:`Section`) with its ``optional`` fields reading as ``None``
    when absent; anything else as it is."""
    if isinstance(value, Section):
        value._optional = optional
    return value


class Result:
    """A command's JSON object (docs/FORMAT.md §5): ``result.key`` and ``result["key"]``
    give a field, its number lists as numpy arrays (float64 with NaN for ``null``, int64
    for whole numbers) and its objects as :class:`Section` at every depth; ``dir()`` lists
    the fields; ``to_json()`` is the command's text, ``to_dict()`` the plain object.

    A field that only an uncertainty evaluation gives — with a budget ``p``, the ``_U``
    and ``_k`` arrays and ``uncertainty``, with ``monte_carlo=`` ``monte_carlo`` — is
    ``None`` when it was not made (``result.pitch_deviation_U`` and
    ``result["pitch_deviation_U"]`` alike; the JSON has no such key, so ``"pitch_deviation_U"
    in result`` is ``False``), as the fit's ``_u`` are ``None`` when σ is unknown.

    Results pickle and deep-copy as their JSON text (``copy.deepcopy``, ``pickle``,
    ``multiprocessing``): the copy is the same text, parsed again, equal to the bit."""

    _main: tuple = ()
    #: The fields that read as ``None`` when the JSON has none of that name.
    _optional: frozenset = frozenset()

    def __init__(self, text: str) -> None:
        self._json = text
        self._dict = _json.loads(text)
        self._data = {k: _convert(v) for k, v in self._dict.items()}
        self._mark_optional()

    def _mark_optional(self) -> None:
        """Marks the nested objects whose fields read as ``None`` when absent."""

    def __getstate__(self) -> Dict[str, Any]:
        return {"json": self._json}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        Result.__init__(self, state["json"])

    def to_json(self) -> str:
        """The JSON text the command prints with ``--format json``."""
        return self._json

    def to_dict(self) -> Dict[str, Any]:
        """The JSON object as plain dicts and lists (a fresh copy)."""
        return _json.loads(self._json)

    def __getitem__(self, key: str) -> Any:
        try:
            return self._data[key]
        except KeyError:
            if key in self._optional:
                return None
            raise

    def __contains__(self, key: object) -> bool:
        return key in self._data

    def __iter__(self) -> Iterator[str]:
        return iter(self._data)

    def __len__(self) -> int:
        return len(self._data)

    def get(self, key: str, default: Any = None) -> Any:
        """A field, or ``default`` when the object has none of that name."""
        return self._data.get(key, default)

    def __getattr__(self, key: str) -> Any:
        if key.startswith("_"):
            raise AttributeError(key)
        try:
            return self._data[key]
        except KeyError:
            if key in self._optional:
                return None
            raise AttributeError(
                f"{type(self).__name__} has no field {key!r}; its fields: {', '.join(self._data)}"
            ) from None

    def __dir__(self) -> List[str]:
        keys = set(self._data) | set(self._optional)
        return sorted(set(super().__dir__()) | {k for k in keys if k.isidentifier()})

    def keys(self):
        """The fields, in the JSON's order."""
        return self._data.keys()

    def __repr__(self) -> str:
        shown = [k for k in self._main if k in self._data] or [
            k for k in self._data if not isinstance(self._data[k], (dict, list))
        ][:8]
        fields = ", ".join(f"{k}={_summary(self._data[k])}" for k in shown)
        return f"{type(self).__name__}({fields})"


def _warn_without_u(result: Result, command: str) -> None:
    """Warns (``PolycalWarning``) when the fit's u could not be given: the fit has no
    residual degrees of freedom and no σ was stated (``sigma`` is ``None``). The command
    line says so in its table; the JSON only has ``null``."""
    missing: List[str] = []

    def walk(prefix: str, value: Any) -> None:
        if not isinstance(value, dict):
            return
        if "sigma" in value and value["sigma"] is None:
            missing.append(prefix or "the result")
        for k, v in value.items():
            if k in ("before", "after"):
                walk(f"{prefix}{k}", v)

    walk("", result._dict)
    if missing:
        _warnings.warn(
            f"{command}: no uncertainties u in {', '.join(missing)} (the fit's `_u` are "
            "None): the fit has no residual degrees of freedom (dof = 0) and no σ was "
            "stated; pass sigma= (σ of one reading, arcsec) or measure more cycles to get them",
            PolycalWarning,
            stacklevel=3,
        )


#: The words of each family for labels and tables: (name in words, symbol, index word).
_FAMILY_WORDS = {
    "pitch_deviation": ("pitch deviation", "β", "face"),
    "face_deviation": ("face deviation", "φ", "face"),
    "encoder_error": ("encoder error", "α", "position"),
}


class SolveResult(Result):
    """The result of :func:`solve`, the JSON object of ``polycal solve --format json``:
    β (``pitch_deviation``), φ (``face_deviation``), α (``encoder_error``) and their
    ``_u``, ``_U`` and ``_k`` as numpy arrays, the setup errors, the fit, and with a budget
    the uncertainty evaluation (docs/FORMAT.md §5.1)."""

    version: str
    faces: int
    readings: int
    dof: int
    residual_rms: Optional[float]
    pitch_deviation: _np.ndarray
    face_deviation: _np.ndarray
    encoder_error: _np.ndarray
    pitch_deviation_u: Optional[_np.ndarray]
    face_deviation_u: Optional[_np.ndarray]
    encoder_error_u: Optional[_np.ndarray]
    setup_error: List[Section]
    effects: List[Section]
    method: str
    engine: str
    sigma: Optional[float]
    sigma_source: Optional[str]
    p: Optional[float]
    pitch_deviation_U: Optional[_np.ndarray]
    face_deviation_U: Optional[_np.ndarray]
    encoder_error_U: Optional[_np.ndarray]
    pitch_deviation_k: Optional[_np.ndarray]
    face_deviation_k: Optional[_np.ndarray]
    encoder_error_k: Optional[_np.ndarray]
    uncertainty: Optional[Section]
    monte_carlo: Optional[Section]
    encoder_angle_deg: _np.ndarray
    notes: List[str]

    _optional = _SOLVE_EVALUATED

    def __init__(self, inner: Any) -> None:
        super().__init__(inner.json())
        self._inner = inner

    def _mark_optional(self) -> None:
        for setup_error in self._data.get("setup_error", ()):
            _optional_section(setup_error, _SETUP_EVALUATED)

    def __getstate__(self) -> Dict[str, Any]:
        # the native result pickles its JSON, rows and set (python/src/evaluate.rs)
        return {"inner": self._inner}

    def __setstate__(self, state: Dict[str, Any]) -> None:
        SolveResult.__init__(self, state["inner"])

    def __repr__(self) -> str:
        d = self._data
        parts = [f"N={d['faces']}", f"{d['readings']} readings", f"method={d['method']}",
                 f"dof={d['dof']}"]
        sigma = d.get("sigma")
        parts.append(
            "σ unknown" if sigma is None else f"σ={_number(sigma)} arcsec ({d['sigma_source']})"
        )
        parts.append(f"β={_summary(d['pitch_deviation'])} arcsec")
        parts.append(f"α={_summary(d['encoder_error'])} arcsec")
        if "pitch_deviation_U" in d:
            k = d["pitch_deviation_k"]
            low, high = _number(_np.nanmin(k)), _number(_np.nanmax(k))
            parts.append(
                f"U(β) ≤ {_number(_np.nanmax(d['pitch_deviation_U']))} arcsec "
                f"(k = {low if low == high else f'{low} … {high}'}, p = {d['p']})"
            )
        elif d.get("pitch_deviation_u") is not None:
            parts.append(f"u(β) ≤ {_number(_np.nanmax(d['pitch_deviation_u']))} arcsec (k = 1)")
        return f"SolveResult({', '.join(parts)})"

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
    def setup_error_u(self) -> Optional[_np.ndarray]:
        """u of each setup error, the fit's (k = 1); ``None`` when σ is unknown, as the
        ``_u`` arrays."""
        if self.sigma is None:
            return None
        return self._setup("u")

    @property
    def setup_error_U(self) -> Optional[_np.ndarray]:
        """U of each setup error; ``None`` without a budget, as the ``_U`` arrays."""
        if "uncertainty" not in self._dict:
            return None
        return self._setup("U")

    @property
    def setup_error_k(self) -> Optional[_np.ndarray]:
        """k of each setup error; ``None`` without a budget, as the ``_k`` arrays."""
        if "uncertainty" not in self._dict:
            return None
        return self._setup("k")

    @property
    def angle_deg(self) -> _np.ndarray:
        """The table angle of every encoder error, degrees: ``encoder_angle_deg`` where the
        JSON has it (sub-pitch mountings), else p·360°/N as the library states it."""
        if "encoder_angle_deg" in self._dict:
            return self["encoder_angle_deg"]
        return _np.asarray(self._inner.encoder_angle_deg(), dtype=_np.float64)

    @property
    def face_angle_deg(self) -> _np.ndarray:
        """The nominal angle of every face f = 1 … N, degrees: f·360°/N (face N at 360°,
        where the closure puts φ[N] = 0), the angle φ[f] deviates from."""
        return _np.asarray(self._inner.face_angle_deg(), dtype=_np.float64)

    def covariance(self, family: str) -> Optional[_np.ndarray]:
        """The fit's covariance σ²Q of one family (``pitch_deviation``,
        ``face_deviation``, ``encoder_error``, ``setup_error``), arcsec², as a dense n × n
        array formed only now; ``None`` when σ is unknown. Its diagonal is ``…_u`` squared."""
        found = self._inner.covariance(family)
        if found is None:
            return None
        n, values = found
        return _np.asarray(values, dtype=_np.float64).reshape(n, n)

    def _column(self, key: str, n: int) -> _np.ndarray:
        values = self._data.get(key)
        if values is None:
            return _np.full(n, _np.nan)
        return _np.asarray(values, dtype=_np.float64)

    def to_dataframe(self) -> Any:
        """The results as a pandas DataFrame, one row per quantity, in the order of the
        result file (``--format csv``, docs/FORMAT.md §3.1): ``pitch_deviation`` 1 … N,
        ``face_deviation`` 1 … N (with φ[N] = 0 of the closure, which the file leaves
        out), ``encoder_error`` 0 … N − 1 (every table angle with sub-pitch mountings),
        then ``setup_error``.
        Columns: ``quantity``, ``index`` (face, position, or for a setup error the
        autocollimator, setup·1000 + ac with several mountings), ``angle_deg`` (for β and φ
        the face's nominal angle f·360°/N, for α the table angle of the position, NaN for
        setup errors), and as the result file ``value``, ``U``, ``u`` and ``k`` (with a
        budget U, the combined standard uncertainty u_c and k = U/u_c; without, NaN, the
        fit's u and NaN), ``u_fit`` (the fit's u, k = 1: the JSON's ``_u``; NaN when σ is
        unknown), ``setup`` and ``ac`` (on setup-error rows; <NA> on the others). Arcsec.
        Built from numpy columns in one go. Needs pandas."""
        import pandas as pd

        d = self._data
        n_faces = len(d["pitch_deviation"])
        n_alpha = len(d["encoder_error"])
        setups = self.setup_error_setup
        acs = self.setup_error_ac
        several = len(set(setups.tolist())) > 1
        n_setup = len(acs)
        quantity = _np.repeat(
            _np.array(["pitch_deviation", "face_deviation", "encoder_error", "setup_error"],
                      dtype=object),
            [n_faces, n_faces, n_alpha, n_setup],
        )
        faces = _np.arange(1, n_faces + 1, dtype=_np.int64)
        index = _np.concatenate([
            faces, faces, _np.arange(n_alpha, dtype=_np.int64),
            setups * 1000 + acs if several else acs,
        ])
        face_angle = self.face_angle_deg
        angle = _np.concatenate([face_angle, face_angle, self.angle_deg, _np.full(n_setup, _np.nan)])
        columns: Dict[str, Any] = {"quantity": quantity, "index": index, "angle_deg": angle}
        sizes = (n_faces, n_faces, n_alpha)
        families = ("pitch_deviation", "face_deviation", "encoder_error")

        def family_columns(suffix: str, setup_key: str) -> _np.ndarray:
            return _np.concatenate(
                [self._column(f + suffix, n) for f, n in zip(families, sizes)]
                + [self._setup(setup_key)]
            )

        columns["value"] = family_columns("", "value")
        columns["U"] = family_columns("_U", "U")
        fit_u = family_columns("_u", "u")
        evaluation = d.get("uncertainty")
        if evaluation is None:
            columns["u"] = fit_u
        else:
            # with a budget the result file's u is the combined u_c (U = k·u_c)
            columns["u"] = _np.concatenate(
                [_np.asarray(evaluation[f]["u"], dtype=_np.float64) for f in families]
                + [_np.asarray(evaluation["setup_error"]["u"], dtype=_np.float64)]
            )
        columns["k"] = family_columns("_k", "k")
        columns["u_fit"] = fit_u
        others = 2 * n_faces + n_alpha
        mask = _np.concatenate([_np.ones(others, dtype=bool), _np.zeros(n_setup, dtype=bool)])
        for column, values in (("setup", setups), ("ac", acs)):
            data = _np.concatenate([_np.zeros(others, dtype=_np.int64), values])
            columns[column] = pd.arrays.IntegerArray(data, mask)
        return pd.DataFrame(columns)

    def plot(self, family: str = "pitch_deviation", ax: Any = None) -> Any:
        """Draws a family (``pitch_deviation``, ``face_deviation`` or ``encoder_error``)
        with its uncertainty bars through matplotlib and returns the axes: the bars are
        the expanded uncertainty U (its k in the legend) with a budget, else the fit's
        standard uncertainty u (k = 1), else none. β and φ against the face, α against the
        table angle in degrees. Needs matplotlib."""
        import matplotlib.pyplot as plt

        if family not in _FAMILY_WORDS:
            raise ValueError(
                f"family {family!r}: expected pitch_deviation, face_deviation or encoder_error"
            )
        words, symbol, _ = _FAMILY_WORDS[family]
        values = self[family]
        if ax is None:
            _, ax = plt.subplots()
        if family == "encoder_error":
            x = self.angle_deg
            ax.set_xlabel("table angle / degree")
        else:
            x = _np.arange(1, len(values) + 1)
            ax.set_xlabel("face")
        expanded = self._data.get(family + "_U")
        standard = self._data.get(family + "_u")
        if expanded is not None:
            k = _np.asarray(self._data[family + "_k"], dtype=float)
            shown = sorted({f"{v:.2f}" for v in k[_np.isfinite(k)]}, key=float)
            k_text = (
                "k unknown" if not shown
                else f"k = {shown[0]}" if len(shown) == 1
                else f"k = {shown[0]} … {shown[-1]}"
            )
            bars = _np.asarray(expanded, dtype=float)
            label = f"{symbol} with expanded uncertainty U ({k_text}, p = {self._data['p']})"
        elif standard is not None:
            bars = _np.asarray(standard, dtype=float)
            label = f"{symbol} with standard uncertainty u (k = 1)"
        else:
            bars = None
            label = f"{symbol} (no uncertainty: dof = 0 and no σ)"
        ax.errorbar(x, values, yerr=bars, fmt="o", capsize=3, label=label)
        ax.axhline(0.0, color="0.6", linewidth=0.8)
        ax.set_ylabel(f"{words} {symbol} / arcsec")
        ax.set_title(f"{words[0].upper()}{words[1:]} {symbol}, N = {self._data['faces']}")
        legend = ax.legend(loc="upper left")
        _room_for_legend(ax, legend, _np.asarray(values, dtype=float), bars)
        return ax


def _room_for_legend(ax: Any, legend: Any, values: _np.ndarray, bars: Optional[_np.ndarray]) -> None:
    """Raises the top of the y axis so that the legend, in the upper left corner, sits
    above every point and every bar: the data keep to the band below the legend's
    bottom edge (as the axes are now sized; a later change of the figure's layout or
    limits is the caller's)."""
    low_ends = values if bars is None else values - _np.nan_to_num(bars)
    high_ends = values if bars is None else values + _np.nan_to_num(bars)
    finite = _np.isfinite(values)
    if not finite.any():
        return
    low = min(float(_np.min(low_ends[finite])), 0.0)
    high = max(float(_np.max(high_ends[finite])), 0.0)
    span = high - low if high > low else 1.0
    figure = ax.figure
    get_renderer = getattr(figure.canvas, "get_renderer", None)
    renderer = get_renderer() if get_renderer is not None else figure._get_renderer()
    box = legend.get_window_extent(renderer)
    axes = ax.get_window_extent(renderer)
    # the share of the axes' height from the legend's bottom edge to the top
    taken = (axes.y1 - box.y0) / axes.height if axes.height > 0 else 0.0
    if not 0.0 < taken < 0.8:
        # no room to make inside axes this small: the legend goes above them
        if hasattr(legend, "set_loc"):  # matplotlib 3.8 and later
            legend.set_loc("lower left")
            legend.set_bbox_to_anchor((0.0, 1.02), transform=ax.transAxes)
        return
    bottom = low - 0.05 * span
    # the highest end 3 % of the span below the legend
    top = bottom + (high + 0.03 * span - bottom) / (1.0 - taken)
    ax.set_ylim(bottom, top)


class DiagnoseResult(Result):
    """The result of :func:`diagnose`, the JSON object of ``polycal diagnose --format
    json`` (docs/FORMAT.md §5.2): ``before`` and ``after`` (each a solve's object), the
    findings, the verdict and the notes; the cycles that disagree with the others
    (``cycles``: repaired or set aside), likewise whole mountings (``mountings``), the
    test of equal noise (``noise``), what ended
    the search when a limit did (``search_stopped``) and the scatter the autocollimators
    share at a stop (``stop_scatter``)."""

    _main = ("adequate", "testable", "effects")

    version: str
    before: Section
    after: Section
    effects: List[Section]
    adequate: bool
    search_stopped: Optional[str]
    testable: bool
    checks: List[Section]
    notes: List[str]
    lack_of_fit: Section
    structure: List[Section]
    tried: List[Section]
    unattributed: List[Section]
    cycles: List[Section]
    mountings: List[Section]
    noise: Optional[Section]
    stop_scatter: Optional[Section]
    residuals: Section
    truth: Section

    def _mark_optional(self) -> None:
        for key in ("before", "after"):
            model = _optional_section(self._data.get(key), _SOLVE_EVALUATED)
            if isinstance(model, Section):
                for setup_error in model.get("setup_error", ()):
                    _optional_section(setup_error, _SETUP_EVALUATED)


class SelfcalResult(Result):
    """The result of :func:`selfcal`, the JSON object of ``polycal selfcal --format json``
    (docs/FORMAT.md §9.3): the encoder error e at every position (``encoder_error``,
    ``encoder_angle_deg``), the heads' errors (``head_error``), the fit."""

    _main = ("positions", "heads", "dof", "residual_rms", "sigma", "encoder_error")

    version: str
    file: str
    positions: int
    heads: int
    cycles: int
    readings: int
    dof: int
    residual_rms: Optional[float]
    sigma: Optional[float]
    sigma_source: Optional[str]
    head_grid: str
    engine: str
    encoder_error: _np.ndarray
    encoder_error_u: Optional[_np.ndarray]
    p: float
    encoder_error_U: _np.ndarray
    encoder_error_k: _np.ndarray
    encoder_angle_deg: _np.ndarray
    head_angle_u: Optional[float]
    gauge_positions: Optional[int]
    head_error: List[Section]
    lost_harmonics: Any
    lost_harmonic_u: Optional[float]
    notes: List[str]
    uncertainty: Optional[Section]
    monte_carlo: Optional[Section]

    _optional = _SELFCAL_EVALUATED


class Comparison(Result):
    """The result of :func:`compare`, the JSON object of ``polycal compare --format
    json`` (docs/FORMAT.md §5.4): ``rows`` with En per quantity, ``max_abs_en``, the
    verdict's rule (``verdict``), the test of the whole comparison as one vector
    (``vector``: ``chi2``, ``dof``, ``critical``, ``consistent``, ``families``) and the rows
    with |En| > 1 (``en_exceeding``) beside the number expected by chance
    (``en_expected``)."""

    _main = ("max_abs_en", "verdict", "en_exceeding", "en_expected", "encoder_matched_by", "rows")

    version: str
    rows: List[Section]
    max_abs_en: Optional[float]
    verdict: str
    vector: Optional[Section]
    en_exceeding: int
    en_expected: Optional[float]
    encoder_matched_by: str


class KeyComparison(Result):
    """The result of :func:`kc`, the JSON object of ``polycal kc --format json``
    (docs/FORMAT.md §12)."""

    _main = ("quantity", "method", "labs", "reference", "comparison_consistent")

    version: str
    quantity: str
    method: str
    index: _np.ndarray
    labs: List[str]
    reference: _np.ndarray
    reference_u: _np.ndarray
    chi2: _np.ndarray
    chi2_dof: _np.ndarray
    chi2_critical: _np.ndarray
    consistent: List[bool]
    vector: Section
    vector_all: Section
    excluded: List[Section]
    tau: _np.ndarray
    degrees_of_equivalence: List[Section]
    pairs: List[Section]
    comparison_consistent: bool
    notes: List[str]


class History(Result):
    """The result of :func:`history`, the JSON object of ``polycal history --format
    json`` (docs/FORMAT.md §13.2)."""

    _main = ("quantity", "model", "drift", "predicted", "at")

    version: str
    quantity: str
    index: _np.ndarray
    files: List[str]
    dates: List[str]
    model: str
    drift: _np.ndarray
    drift_u: _np.ndarray
    at: str
    predicted: _np.ndarray
    predicted_u: _np.ndarray
    k: float
    vector: Section
    fit: Optional[Section]
    notes: List[str]


class _Rows:
    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __repr__(self) -> str:
        return f"ResultRows({len(self._inner)} rows, from {self._inner.label})"


def read_results(path: PathOrText) -> _Rows:
    """Reads a result file (docs/FORMAT.md §3), for :func:`compare`. A file that is not
    there raises ``FileNotFound`` (a ``FileNotFoundError``)."""
    return _Rows(_polycal.read_results(_os.fspath(path)))
