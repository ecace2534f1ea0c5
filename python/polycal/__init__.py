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
from typing import Any, Dict, Mapping, Optional, Sequence, Tuple, Union


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
from ._polycal import DesignError, InputError, PolycalError
from ._results import Result, SolveResult, _Rows, read_results

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
    "kc",
    "simulate",
    "__version__",
]

__version__ = _polycal.version()
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
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> Result:
    """Diagnoses the set as ``polycal diagnose`` does: finds the effects the model lacks,
    adds them, and says whether the final model is adequate; with a truth (a dict or JSON
    text, as :func:`simulate` returns) the error before and after. With a budget, U and k
    of the final model's results, and with ``monte_carlo`` (a number of trials or
    ``"adaptive"``) its JCGM 101 evaluation, effect columns included (``after``'s
    ``monte_carlo``)."""
    if isinstance(truth, dict):
        truth = _json.dumps(truth)
    return Result(
        _polycal.diagnose(
            ms._inner,
            truth=truth,
            sigma=_sigma(sigma),
            budget=None if budget is None else budget._inner,
            monte_carlo=monte_carlo,
            seed=seed,
        )
    )


def selfcal(
    set: SelfcalSet,
    sigma: Optional[float] = None,
    budget: Optional[Budget] = None,
    monte_carlo: Union[None, int, str] = None,
    seed: int = 1,
) -> Result:
    """Self-calibrates the encoder from a multi-head run as ``polycal selfcal`` does; with
    a budget, U and k of e and of the heads' errors, and with ``monte_carlo`` (a number of
    trials or ``"adaptive"``) the budget's JCGM 101 evaluation (``monte_carlo``)."""
    return Result(
        _polycal.selfcal(
            set._inner,
            sigma=_sigma(sigma),
            budget=None if budget is None else budget._inner,
            monte_carlo=monte_carlo,
            seed=seed,
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

    return Result(
        _polycal.compare_rows(
            _rows_of(a),
            _rows_of(b),
            correlation=float(correlation),
            include_setup=bool(include_setup),
        )
    )


def _rows_of(x: Any) -> Any:
    """The result rows of a :class:`SolveResult`, of rows, or of a result file."""
    if isinstance(x, SolveResult):
        return x._inner.rows()
    if isinstance(x, _Rows):
        return x._inner
    return _polycal.read_results(_os.fspath(x))


def kc(
    labs: Mapping[str, Union[SolveResult, _Rows, PathOrText]],
    pilot: Optional[Sequence[Tuple[str, Union[SolveResult, _Rows, PathOrText]]]] = None,
    quantity: str = "pitch_deviation",
    method: str = "weighted-mean",
) -> Result:
    """Evaluates a key comparison as ``polycal kc`` does (docs/FORMAT.md §12): per face
    (or per common angle for ``quantity="encoder_error"``) the reference (weighted mean,
    or ``method="dersimonian-laird"``) with ``reference_u``, ``chi2`` and ``consistent``;
    the closed vector's test in ``vector``; the laboratories left out in ``excluded``;
    ``degrees_of_equivalence`` and ``pairs``. ``labs`` maps each laboratory's name to its
    result (a :class:`SolveResult` with a budget, rows, or a result file), in order;
    ``pilot`` lists the pilot's repeated results as (name, result) pairs."""

    def named(items: Any) -> Any:
        return [(str(name), _rows_of(result)) for name, result in items]

    return Result(
        _polycal.kc(
            named(labs.items()),
            named(pilot or ()),
            quantity=str(quantity),
            method=str(method),
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

