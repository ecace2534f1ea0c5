"""polycal for Python: calibrate an optical polygon and a rotary encoder at the same time.

The two-autocollimator method of Hsieh, Lin, Yeh and Watanabe, *Calibration of a Rotary
Encoder and a Polygon Using a Two-Autocollimator Method*, Appl. Sci. 2023, 13, 1865 ("the
paper"), with uncertainty, comparison, diagnosis and self-calibration. This package is a
thin skin over the Rust library (the same code the ``polycal`` command runs): it reads
arguments, calls the library with the GIL released, and gives back numpy arrays. Every
number is the command's JSON number, to the last bit.

:class:`Session` drives the rules of ``polycal run`` with instruments of your own
(docs/FORMAT.md §7.6), the run directory kept as the command keeps it; :class:`AcWire`
and :class:`TableWire` are the wire rules for a port of your own (§7.7).

All angles are arcseconds unless a name says otherwise. Contract: docs/FORMAT.md of the
repository.
"""

from __future__ import annotations

import json as _json
import os as _os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union


from . import _polycal
from ._data import (
    Budget,
    MeasurementSet,
    PathOrText,
    SelfcalSet,
    budget,
    read_measurements,
    read_selfcal,
)
from ._data import budget as _read_budget
from ._polycal import (
    AcWire,
    Action,
    DesignError,
    FileNotFound,
    InputError,
    PolycalError,
    PolycalWarning,
    Session,
    TableWire,
    WireAction,
)
from ._results import (
    Comparison,
    DiagnoseResult,
    History,
    KeyComparison,
    Result,
    Section,
    SelfcalResult,
    SolveResult,
    _Rows,
    _warn_without_u,
    read_results,
)

__all__ = [
    "PolycalError",
    "InputError",
    "DesignError",
    "FileNotFound",
    "PolycalWarning",
    "MeasurementSet",
    "SelfcalSet",
    "Budget",
    "Result",
    "Section",
    "SolveResult",
    "DiagnoseResult",
    "SelfcalResult",
    "Comparison",
    "KeyComparison",
    "History",
    "read_measurements",
    "read_selfcal",
    "read_results",
    "budget",
    "solve",
    "diagnose",
    "selfcal",
    "compare",
    "kc",
    "kc_draft_a",
    "shared_quantities",
    "history",
    "simulate",
    "simulate_selfcal",
    "Session",
    "Action",
    "AcWire",
    "TableWire",
    "WireAction",
    "__version__",
]

__version__ = _polycal.version()


def _sigma(sigma: Optional[float]) -> Optional[float]:
    return None if sigma is None else float(sigma)


def _measurement_set(ms: Union[MeasurementSet, PathOrText]) -> Any:
    """The native set of a :class:`MeasurementSet`, or of a measurement file (a path
    string or an ``os.PathLike``) or its text, read by :func:`read_measurements`."""
    if isinstance(ms, MeasurementSet):
        return ms._inner
    if isinstance(ms, (str, _os.PathLike)):
        return read_measurements(ms)._inner
    raise TypeError(
        f"expected a MeasurementSet, a path or a measurement file's text, got {type(ms).__name__}"
    )


def _selfcal_set(set: Union[SelfcalSet, PathOrText]) -> Any:
    """The native set of a :class:`SelfcalSet`, or of a self-calibration file (a path
    string or an ``os.PathLike``) or its text, read by :func:`read_selfcal`."""
    if isinstance(set, SelfcalSet):
        return set._inner
    if isinstance(set, (str, _os.PathLike)):
        return read_selfcal(set)._inner
    raise TypeError(
        f"expected a SelfcalSet, a path or a self-calibration file's text, got {type(set).__name__}"
    )


def _budget(given: Union[None, Budget, PathOrText, Dict[str, Any]]) -> Any:
    """The native budget of a :class:`Budget`, or of a TOML file (a path string or an
    ``os.PathLike``), its text or a dict, read by :func:`budget`; ``None`` for none."""
    if given is None:
        return None
    if isinstance(given, Budget):
        return given._inner
    if isinstance(given, (str, _os.PathLike, dict)):
        return _read_budget(given)._inner
    raise TypeError(
        f"budget: expected a Budget, a path, a TOML text or a dict, got {type(given).__name__}"
    )


#: What a set is given as: the set, a file's path (``str`` or ``os.PathLike``) or its text.
SetLike = Union[MeasurementSet, PathOrText]
#: What a budget is given as: the budget, a TOML file's path, its text or a dict.
BudgetLike = Union[Budget, PathOrText, Dict[str, Any]]


def solve(
    ms: SetLike,
    method: str = "auto",
    sigma: Optional[float] = None,
    budget: Optional[BudgetLike] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> SolveResult:
    """Solves the set as ``polycal solve`` does: the paper's closed form (eqs. (6)–(10))
    for two adjacent autocollimators, least squares for any design (``method``: ``auto``,
    ``closed-form``, ``lsq``, ``dense``); with a budget, U and k of every result (eqs.
    (11)–(13)); with ``monte_carlo`` (a number of trials or ``"adaptive"``) the JCGM 101
    evaluation. ``sigma`` is σ of one reading for an exactly determined fit (dof = 0).
    A design that cannot determine some harmonics raises ``DesignError``; a fit without
    residual degrees of freedom and without ``sigma`` has no u (``None``) and warns
    (``PolycalWarning``). ``ms`` is a :class:`MeasurementSet` or a measurement file (a
    path string or ``os.PathLike``, read as :func:`read_measurements` reads it), ``budget``
    a :class:`Budget` or what :func:`budget` takes."""
    result = SolveResult(
        _polycal.solve(
            _measurement_set(ms),
            method=method,
            sigma=_sigma(sigma),
            budget=_budget(budget),
            monte_carlo=monte_carlo,
            seed=seed,
        )
    )
    _warn_without_u(result, "solve")
    return result


def diagnose(
    ms: SetLike,
    truth: Optional[Union[Dict[str, Any], PathOrText]] = None,
    sigma: Optional[float] = None,
    budget: Optional[BudgetLike] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> DiagnoseResult:
    """Diagnoses the set as ``polycal diagnose`` does: finds the effects the model lacks,
    adds them, and says whether the final model is adequate; with a truth (a dict as
    :func:`simulate` returns it, its JSON text, or a truth file's path — a string that
    does not start with ``{``, or an ``os.PathLike`` — read as ``--truth`` reads it) the
    error before and after. With a budget, U and k
    of the final model's results, and with ``monte_carlo`` (a number of trials or
    ``"adaptive"``) its JCGM 101 evaluation, effect columns included (``after``'s
    ``monte_carlo``). ``ms`` and ``budget`` as :func:`solve` takes them."""
    truth_path = None
    if isinstance(truth, dict):
        truth = _json.dumps(truth)
    elif isinstance(truth, _os.PathLike) or (
        isinstance(truth, str) and not truth.lstrip().startswith("{")
    ):
        truth, truth_path = None, _os.fspath(truth)
    elif truth is not None and not isinstance(truth, str):
        raise TypeError(
            f"truth: expected a dict, a JSON text or a truth file's path, got {type(truth).__name__}"
        )
    result = DiagnoseResult(
        _polycal.diagnose(
            _measurement_set(ms),
            truth=truth,
            truth_path=truth_path,
            sigma=_sigma(sigma),
            budget=_budget(budget),
            monte_carlo=monte_carlo,
            seed=seed,
        )
    )
    _warn_without_u(result, "diagnose")
    return result


def selfcal(
    set: Union[SelfcalSet, PathOrText],
    sigma: Optional[float] = None,
    budget: Optional[BudgetLike] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> SelfcalResult:
    """Self-calibrates the encoder from a multi-head run as ``polycal selfcal`` does; with
    a budget, U and k of e and of the heads' errors, and with ``monte_carlo`` (a number of
    trials or ``"adaptive"``) the budget's JCGM 101 evaluation (``monte_carlo``). ``set``
    is a :class:`SelfcalSet` or a self-calibration file (a path string or
    ``os.PathLike``, read as :func:`read_selfcal` reads it), ``budget`` as :func:`solve`
    takes it."""
    result = SelfcalResult(
        _polycal.selfcal(
            _selfcal_set(set),
            sigma=_sigma(sigma),
            budget=_budget(budget),
            monte_carlo=monte_carlo,
            seed=seed,
        )
    )
    _warn_without_u(result, "selfcal")
    return result


def compare(
    a: Union[SolveResult, _Rows, PathOrText],
    b: Union[SolveResult, _Rows, PathOrText],
    correlation: float = 0.0,
    include_setup: bool = False,
    verdict: str = "vector",
) -> Comparison:
    """Compares two results by En (the paper's eqs. (14)–(15), ISO 13528) as ``polycal
    compare`` does: ``rows`` with ``en`` per quantity, ``max_abs_en``, and one verdict for
    the whole comparison (docs/FORMAT.md §5.4): ``vector`` (the closed families'
    differences as one χ² test at 5 %), ``en_exceeding`` beside ``en_expected``;
    ``verdict="en"`` for the per-row rule. Each of ``a`` and ``b`` a :class:`SolveResult`
    (with a budget) or a result file."""

    return Comparison(
        _polycal.compare_rows(
            _rows_of(a),
            _rows_of(b),
            correlation=float(correlation),
            include_setup=bool(include_setup),
            verdict=str(verdict),
        )
    )


def _rows_of(x: Any) -> Any:
    """The result rows of a :class:`SolveResult`, of rows, or of a result file (a path
    string or ``os.PathLike``)."""
    if isinstance(x, SolveResult):
        return x._inner.rows()
    if isinstance(x, _Rows):
        return x._inner
    if isinstance(x, (str, _os.PathLike)):
        return _polycal.read_results(_os.fspath(x))
    raise TypeError(
        f"expected a SolveResult, result rows or a result file's path, got {type(x).__name__}"
    )


def kc(
    labs: Mapping[str, Union[SolveResult, _Rows, PathOrText]],
    pilot: Optional[Sequence[Tuple[str, Union[SolveResult, _Rows, PathOrText]]]] = None,
    quantity: str = "pitch_deviation",
    method: str = "weighted-mean",
    keep: Sequence[str] = (),
    not_in_reference: Sequence[str] = (),
    link: Optional[KeyComparison] = None,
    monte_carlo: Optional[int] = None,
) -> KeyComparison:
    """Evaluates a key comparison as ``polycal kc`` does (docs/FORMAT.md §12): the one
    decision at 5 % in ``vector_all`` (the closed vector of every laboratory) and, when it
    fails, the largest consistent subset in ``search`` and ``excluded``; the closed
    reference (``method="dersimonian-laird"`` or ``"mandel-paule"``: with the dark uncertainty τ, nobody left
    out) with ``reference_u``; per face ``chi2`` and ``consistent`` as information;
    ``degrees_of_equivalence`` and ``pairs``. ``labs`` maps each laboratory's name to its
    result (a :class:`SolveResult` with a budget, rows, or a result file), in order;
    ``pilot`` lists the pilot's repeated results as (name, result) pairs; ``keep`` names
    laboratories held in the reference (``--keep``); ``not_in_reference`` names
    laboratories kept out of it but given degrees of equivalence
    (``--not-in-reference``); ``link`` is the comparison this one is linked to
    (``--link``), ``monte_carlo`` the number of draws for every U (``--monte-carlo``).
    ``quantity`` is ``pitch_deviation``, ``encoder_error`` or ``angle_block``; a number a
    laboratory did not measure (an angle block, an encoder position) is NaN in the arrays,
    ``null`` in :meth:`KeyComparison.to_json`."""

    text, _ = _kc(labs, pilot, quantity, method, keep, not_in_reference, link, monte_carlo)
    return KeyComparison(text)


def _kc(
    labs: Mapping[str, Union[SolveResult, _Rows, PathOrText]],
    pilot: Optional[Sequence[Tuple[str, Union[SolveResult, _Rows, PathOrText]]]],
    quantity: str,
    method: str,
    keep: Sequence[str],
    not_in_reference: Sequence[str],
    link: Optional[KeyComparison],
    monte_carlo: Optional[int],
    anonymise: bool = False,
    key: Optional[str] = None,
    seed: int = 0,
) -> Tuple[str, Optional[str]]:
    """``_polycal.kc`` with :func:`kc`'s arguments: the JSON text and the key's CSV text
    (Draft A only)."""

    def named(items: Any) -> Any:
        return [(str(name), _rows_of(result)) for name, result in items]

    return _polycal.kc(
        named(labs.items()),
        named(pilot or ()),
        quantity=str(quantity),
        method=str(method),
        keep=[str(name) for name in keep],
        not_in_reference=[str(name) for name in not_in_reference],
        link=None if link is None else link.to_json(),
        monte_carlo=None if monte_carlo is None else int(monte_carlo),
        anonymise=anonymise,
        key=None if key is None else str(key),
        seed=int(seed),
    )


def kc_draft_a(
    labs: Mapping[str, Union[SolveResult, _Rows, PathOrText]],
    pilot: Optional[Sequence[Tuple[str, Union[SolveResult, _Rows, PathOrText]]]] = None,
    quantity: str = "pitch_deviation",
    method: str = "weighted-mean",
    keep: Sequence[str] = (),
    not_in_reference: Sequence[str] = (),
    link: Optional[KeyComparison] = None,
    monte_carlo: Optional[int] = None,
    key: Optional[str] = None,
    seed: Optional[int] = None,
) -> Tuple[KeyComparison, str]:
    """Draft A of a key comparison as ``polycal kc --anonymise KEY.csv`` makes it
    (docs/FORMAT.md §12, "Draft A"): :func:`kc` with every laboratory named by a code
    letter (the pilot's repeats keep their names), and the key. Returns the comparison and
    the key's CSV text (``code,lab``), which the pilot keeps alone: nothing else names the
    laboratories. ``key`` is a key's CSV text read back (Draft B: its codes, every
    laboratory in it); without it the codes ``A``, ``B``, … go to the laboratories in an
    order drawn at random (from ``seed`` when given, for a repeatable draw). ``keep`` and
    ``not_in_reference`` name laboratories by their real names, and a ``link``ed
    comparison's laboratories are matched by them too, as the command does. Raises
    :class:`PolycalError` with the command's message for a key that lacks a laboratory or
    cannot be read."""
    import secrets

    drawn = secrets.randbits(63) if seed is None else int(seed)
    text, key_text = _kc(
        labs,
        pilot,
        quantity,
        method,
        keep,
        not_in_reference,
        link,
        monte_carlo,
        anonymise=True,
        key=key,
        seed=drawn,
    )
    return KeyComparison(text), str(key_text)


def shared_quantities(
    labs: Mapping[str, Union[SolveResult, _Rows, PathOrText]],
    pilot: Optional[Sequence[Tuple[str, Union[SolveResult, _Rows, PathOrText]]]] = None,
) -> List[str]:
    """The quantities a key comparison compares (``pitch_deviation``, ``encoder_error``, ``angle_block``)
    that every laboratory's result in ``labs`` and every repeat in ``pilot`` has rows of,
    in the order ``polycal kc`` without ``--quantity`` compares them, as names for
    :func:`kc`'s ``quantity``: ``[kc(labs, quantity=q) for q in shared_quantities(labs)]``.
    ``labs`` and ``pilot`` are as :func:`kc` takes them. Raises :class:`PolycalError`,
    naming the results that lack each quantity, when none is in every result."""
    return list(
        _polycal.shared_quantities(
            [(str(name), _rows_of(result)) for name, result in labs.items()],
            [(str(name), _rows_of(result)) for name, result in (pilot or ())],
        )
    )


def history(
    calibrations: Sequence[Tuple[Union[SolveResult, _Rows, PathOrText], str]],
    at: Optional[str] = None,
    quantity: str = "pitch_deviation",
    max_u: Optional[float] = None,
) -> History:
    """Evaluates a standard's history as ``polycal history`` does (docs/FORMAT.md §13.2):
    ``calibrations`` are (result, date) pairs, each result a :class:`SolveResult` with a
    budget, rows or a result file, each date a day ``YYYY-MM-DD``. Returns per position
    the ``drift`` per year with ``drift_u``, the one decision in ``model`` (``constant``
    or ``linear``, by the test of the whole drift vector in ``vector``), the chosen
    model's ``fit``, and the value ``predicted`` at ``at`` (default today, UTC) with
    ``predicted_u`` (U = 2u); with ``max_u`` (U, arcsec) the date it is reached."""
    return History(
        _polycal.history(
            [(_rows_of(result), str(date)) for result, date in calibrations],
            at=None if at is None else str(at),
            quantity=str(quantity),
            max_u=None if max_u is None else float(max_u),
        )
    )


Specs = Union[str, Sequence[Any], Sequence[Union[str, Sequence[Any]]]]


def _specs(name: str, value: Any) -> list:
    """An effect option as the command's specs: one spec (``"2:1.5"`` or ``(2, 1.5)``) or
    a list of them; a tuple's parts joined by ``:`` (numbers as Python writes them, which
    the library reads back to the same float)."""
    if value is None:
        return []
    if isinstance(value, str):
        return [value]
    items = list(value)
    if items and all(not isinstance(v, (str, list, tuple)) for v in items):
        items = [items]  # one spec given as a tuple of numbers
    out = []
    for item in items:
        if isinstance(item, str):
            out.append(item)
        elif isinstance(item, (list, tuple)):
            out.append(":".join(repr(float(v)) if isinstance(v, float) else str(v) for v in item))
        else:
            raise TypeError(f"{name}: expected a spec such as \"1:0.5\" or a tuple, got {item!r}")
    return out


def _model(name: str, value: Any) -> Optional[str]:
    """A model option: ``None``/``False`` none, ``True`` the command's default model, a
    spec string, or a tuple of the spec's numbers."""
    if value is None or value is False:
        return None
    if value is True:
        return ""
    return _specs(name, value)[0] if not isinstance(value, str) else value


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
    *,
    setup_shift: Optional[int] = None,
    shift_deg: Optional[Sequence[float]] = None,
    harmonic: Specs = None,
    noise_dof: Optional[float] = None,
    temperature: Union[None, bool, str, Sequence[float]] = None,
    elevation: Union[None, bool, str, Sequence[float]] = None,
    drift: Specs = None,
    offset_step: Specs = None,
    temperature_effect: Specs = None,
    cross_talk: Specs = None,
    direction: Specs = None,
    outlier: Specs = None,
    rezero: Specs = None,
    random_walk: Specs = None,
    no_time: bool = False,
) -> Tuple[MeasurementSet, Dict[str, Any]]:
    """A simulated polygon run with a known truth, as ``polycal simulate`` draws it: the
    set and the truth (β, α, the setup errors, the effects; docs/FORMAT.md §4) as a dict.
    Same seed and options, same readings: ``set.write(path)`` is the command's ``--out``
    file to the byte (``closing`` is on by default here, off on the command line).

    Every option is the command's (docs/FORMAT.md §5.5), named with ``_`` for ``-`` and
    in its units: ``harmonic`` (encoder harmonics ``ORDER:AMPLITUDE[:PHASE]``, arcsec and
    radians), ``setup_shift`` (whole faces between mountings; ``setup_shift_faces`` is the
    same), ``shift_deg`` (the table's angle at step 0 of each mounting, degrees),
    ``noise_dof`` (Student-t noise), ``temperature`` and ``elevation`` (``True`` for the
    command's default model, or its spec), and the effects, each one spec or a list of
    them, a spec a string or a tuple of its numbers: ``drift`` ``AC:RATE[:QUADRATIC]``
    (arcsec per hour), ``offset_step`` ``[SETUP:AC:CYCLE:STEP|AC:CYCLE[:STEP]]:VALUE``,
    ``temperature_effect`` ``AC:COEFF`` (arcsec per °C; needs ``temperature``),
    ``cross_talk`` ``AC:COEFF`` (needs ``elevation``), ``direction`` ``[AC:]VALUE``
    (needs ``bidirectional``), ``outlier`` ``[SETUP:]CYCLE:STEP:AC:VALUE``, ``rezero``
    ``AC:SIGMA`` (re-zeroing every cycle), ``random_walk`` ``AC:RATE_PER_SQRT_H``, and
    ``no_time`` (no ``time`` column). A spec the library refuses raises ``ValueError``
    naming the option."""
    if setup_shift is not None and setup_shift_faces is not None and setup_shift != setup_shift_faces:
        raise ValueError("setup_shift and setup_shift_faces are one option: give one of them")
    inner, truth = _polycal.simulate(
        faces=faces,
        ac_faces=list(ac_faces),
        cycles=cycles,
        closing=closing,
        bidirectional=bidirectional,
        noise=noise,
        pitch_spread=pitch_spread,
        harmonic=_specs("harmonic", harmonic),
        setup_spread=setup_spread,
        step_seconds=step_seconds,
        setups=setups,
        setup_shift_faces=setup_shift if setup_shift is not None else setup_shift_faces,
        shift_deg=[float(v) for v in (shift_deg or ())],
        seed=seed,
        noise_dof=None if noise_dof is None else float(noise_dof),
        temperature=_model("temperature", temperature),
        elevation=_model("elevation", elevation),
        drift=_specs("drift", drift),
        offset_step=_specs("offset_step", offset_step),
        temperature_effect=_specs("temperature_effect", temperature_effect),
        cross_talk=_specs("cross_talk", cross_talk),
        direction=_specs("direction", direction),
        outlier=_specs("outlier", outlier),
        rezero=_specs("rezero", rezero),
        random_walk=_specs("random_walk", random_walk),
        no_time=bool(no_time),
    )
    return MeasurementSet(inner), _json.loads(truth)


def simulate_selfcal(
    positions: int = 168,
    heads: Union[str, Sequence[float]] = "selfa",
    cycles: int = 2,
    bidirectional: bool = False,
    noise: float = 0.02,
    harmonic: Specs = None,
    max_order: int = 60,
    table_error: float = 1.0,
    head_error: float = 2.0,
    step_seconds: float = 20.0,
    seed: int = 1,
) -> Tuple[SelfcalSet, Dict[str, Any]]:
    """A simulated self-calibration run with a known truth, as ``polycal simulate
    --selfcal`` draws it (docs/FORMAT.md §9): reading = t[cycle, step] + e(step·360°/P +
    head angle) + c[head] + noise. The set and the truth as a dict; ``set.write(path)`` is
    the command's ``--out`` file to the byte. The options are the command's, with its
    defaults and units: ``positions`` P, ``heads`` (``"selfa"``, the SelfA encoder's
    twelve, or the head angles from head 1 in degrees, head 1 first at 0), ``cycles``,
    ``bidirectional``, ``noise`` (arcsec), ``harmonic`` (the disc's graduation error as
    ``ORDER:AMPLITUDE[:PHASE]`` specs, else drawn to ``max_order``), ``table_error`` (σ of
    the table's error at every stop, arcsec), ``head_error`` (the head errors drawn in
    ± this, arcsec), ``step_seconds`` and ``seed``."""
    if isinstance(heads, str):
        if heads.strip().lower() != "selfa":
            raise ValueError(f"heads {heads!r}: expected \"selfa\" or the head angles in degrees")
        angles = None
    else:
        angles = [float(a) for a in heads]
    inner, truth = _polycal.simulate_selfcal(
        positions=positions,
        heads=angles,
        cycles=cycles,
        bidirectional=bidirectional,
        noise=noise,
        harmonic=_specs("harmonic", harmonic),
        max_order=max_order,
        table_error=table_error,
        head_error=head_error,
        step_seconds=step_seconds,
        seed=seed,
    )
    return SelfcalSet(inner), _json.loads(truth)
