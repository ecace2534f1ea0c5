"""The paper's two-autocollimator evaluation and its En comparison, from Python.

Hsieh, Lin, Yeh and Watanabe, Appl. Sci. 2023, 13, 1865: a 24-faced polygon on a rotary
table, two autocollimators on adjacent faces, six cycles. The bundled run is simulated
(its truth beside it); the reference result is a shift-angle calibration of the same
polygon. Run from the repository's root after `pip install ./python`:

    python examples/python/paper_example.py
"""

import json
from pathlib import Path

import numpy as np

import polycal

root = Path(__file__).resolve().parents[2]
data = root / "examples/data/polygon24-2ac-6cycles.csv"

# read the run and the instrument budget (docs/FORMAT.md §2, §5.1)
ms = polycal.read_measurements(data)
budget = polycal.budget(root / "examples/budgets/instrument.toml")
print(ms)

# solve: the paper's eqs. (6)-(10) give β, φ and α; the budget gives U and k (eqs. (11)-(13))
result = polycal.solve(ms, budget=budget)
print(f"method {result.method}, dof {result.dof}, residual RMS {result.residual_rms:.4f}″")
print(" face      β/″     U(β)/″")
for k, (beta, big_u) in enumerate(zip(result.pitch_deviation, result.pitch_deviation_U), 1):
    print(f"{k:>5} {beta:+8.4f} {big_u:8.4f}")
print(" step   angle/°      α/″     U(α)/″")
for p, (alpha, big_u) in enumerate(zip(result.encoder_error, result.encoder_error_U)):
    print(f"{p:>5} {p * 15:>8.1f} {alpha:+8.4f} {big_u:8.4f}")

# against the truth the simulation drew
truth = json.loads((root / "examples/data/polygon24-2ac-6cycles.truth.json").read_text())
error = result.pitch_deviation - np.asarray(truth["pitch_deviation"])
print(f"β − truth: RMS {np.sqrt(np.mean(error**2)):.4f}″, largest {np.max(np.abs(error)):.4f}″")

# the covariance of α from the fit, formed on request (24 × 24)
cov = result.covariance("encoder_error")
print(f"u(α[0]) from the covariance: {np.sqrt(cov[0, 0]):.5f}″ (the fit's type A)")

# En against the shift-angle reference (the paper's eqs. (14)-(15), ISO 13528)
comparison = polycal.compare(result, root / "examples/data/polygon24-shift-angle.result.csv")
verdict = "agree" if comparison.max_abs_en <= 1 else "do NOT agree"
print(f"largest |En| = {comparison.max_abs_en:.2f}: the calibrations {verdict}")
