"""polycal.history against the command line (the same library: the same JSON to the
byte), and its refusals as the command's."""

import subprocess
from pathlib import Path

import numpy as np
import pytest

import polycal
from test_polycal import _binary, cli

ROOT = Path(__file__).resolve().parents[2]
HISTORY = ROOT / "examples/data/history"
DATES = ["2019-03-12", "2020-03-10", "2021-03-02", "2022-03-15", "2023-03-07", "2024-03-05"]


def calibrations():
    return [(HISTORY / f"{d[:4]}.csv", d) for d in DATES]


def test_history_is_the_clis_json_to_the_byte():
    args = [f"{path}@{date}" for path, date in calibrations()]
    result = polycal.history(calibrations(), at="2025-03-01", max_u=0.3)
    expected = cli("history", *args, "--at", "2025-03-01", "--max-u", "0.3", "--format", "json")
    assert result.to_json() == expected
    assert result["model"] == "linear"
    assert isinstance(result["drift"], np.ndarray) and result["drift"].shape == (24,)
    encoder = polycal.history(calibrations()[::5], at="2025-03-01", quantity="encoder_error")
    assert encoder.to_json() == cli(
        "history", *args[::5], "--at", "2025-03-01", "--quantity", "encoder_error", "--format", "json"
    )
    assert encoder["model"] == "constant"


def test_history_refuses_as_the_cli_does():
    with pytest.raises(polycal.PolycalError) as caught:
        polycal.history(calibrations()[:1], at="2025-03-01")
    out = subprocess.run(
        [_binary(), "history", f"{HISTORY / '2019.csv'}@2019-03-12"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert out.returncode == 2
    assert str(caught.value) in out.stderr
    with pytest.raises(ValueError):
        polycal.history(calibrations(), at="2025-02-30")
