"""polycal for Python against the command line (the same library: the same JSON to the
byte), against the paper's closed form written here in numpy, and its refusals.

The command-line binary is found as $POLYCAL_BIN, or target/release or target/debug of
the repository (`cargo build` makes it).
"""

import json
import os
import subprocess
import threading
from pathlib import Path

import numpy as np
import pytest

import polycal

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "examples/data/polygon24-2ac-6cycles.csv"
BUDGET = ROOT / "examples/budgets/instrument.toml"
REFERENCE = ROOT / "examples/data/polygon24-shift-angle.result.csv"
SELFCAL = ROOT / "examples/data/selfa-168.csv"
SELFCAL_BUDGET = ROOT / "examples/budgets/selfcal.toml"


def _binary() -> str:
    for candidate in (
        os.environ.get("POLYCAL_BIN"),
        ROOT / "target/release/polycal",
        ROOT / "target/debug/polycal",
    ):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    pytest.fail("the polycal binary is not built: run `cargo build` (or set POLYCAL_BIN)")


def cli(*args: str) -> str:
    out = subprocess.run(
        [_binary(), *map(str, args)], capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode in (0, 1), out.stderr
    return out.stdout.strip()


# ---------------------------------------------------------------- parity with the CLI


def test_solve_is_the_clis_json_to_the_byte():
    ms = polycal.read_measurements(str(DATA))
    plain = polycal.solve(ms)
    assert plain.to_json() == cli("solve", DATA, "--format", "json")
    with_budget = polycal.solve(ms, budget=polycal.budget(BUDGET))
    expected = cli("solve", DATA, "--budget", BUDGET, "--format", "json")
    assert with_budget.to_json() == expected
    parsed = json.loads(expected)
    assert list(with_budget.keys()) == list(parsed.keys())
    for family in ("pitch_deviation", "face_deviation", "encoder_error"):
        for suffix in ("", "_u", "_U", "_k"):
            array = with_budget[family + suffix]
            assert isinstance(array, np.ndarray) and array.dtype == np.float64
            expected_values = [np.nan if v is None else v for v in parsed[family + suffix]]
            np.testing.assert_array_equal(array, expected_values)  # bit for bit, NaN for null
    for key in ("value", "u", "U", "k"):
        array = getattr(with_budget, "setup_error_" + key)
        assert array.dtype == np.float64
        assert array.tolist() == [s[key] for s in parsed["setup_error"]]
    assert with_budget.setup_error_ac.tolist() == [s["ac"] for s in parsed["setup_error"]]
    assert with_budget.angle_deg.tolist() == [15.0 * p for p in range(24)]
    assert isinstance(with_budget.residual_rms, float) and isinstance(with_budget.dof, int)


def test_monte_carlo_is_the_clis_for_the_same_seed():
    ms = polycal.read_measurements(DATA)
    result = polycal.solve(ms, budget=polycal.budget(BUDGET), monte_carlo=2000, seed=5)
    expected = cli(
        "solve", DATA, "--budget", BUDGET, "--monte-carlo", "2000", "--seed", "5",
        "--format", "json",
    )
    assert result.to_json() == expected


def test_diagnose_monte_carlo_is_the_clis_for_the_same_seed():
    ms = polycal.read_measurements(DATA)
    result = polycal.diagnose(ms, budget=polycal.budget(BUDGET), monte_carlo=3000, seed=4)
    expected = cli(
        "diagnose", DATA, "--budget", BUDGET, "--monte-carlo", "3000", "--seed", "4",
        "--format", "json",
    )
    assert result.to_json() == expected
    assert json.loads(expected)["after"]["monte_carlo"]["trials"] == 3000
    with pytest.raises(ValueError, match="needs a budget"):
        polycal.diagnose(ms, monte_carlo=3000)


def test_selfcal_monte_carlo_is_the_clis_for_the_same_seed():
    s = polycal.read_selfcal(str(SELFCAL))
    result = polycal.selfcal(
        s, budget=polycal.budget(SELFCAL_BUDGET), monte_carlo=2000, seed=3
    )
    expected = cli(
        "selfcal", SELFCAL, "--budget", SELFCAL_BUDGET, "--monte-carlo", "2000",
        "--seed", "3", "--format", "json",
    )
    assert result.to_json() == expected
    mc = json.loads(expected)["monte_carlo"]
    assert mc["trials"] == 2000 and len(mc["head_error"]["u"]) == 11
    with pytest.raises(ValueError, match="needs a budget"):
        polycal.selfcal(s, monte_carlo=2000)


def test_selfcal_monte_carlo_between_the_positions_is_the_clis(tmp_path):
    # heads at 97° on 24 positions sit between them: the band-limited fit's trials
    data = tmp_path / "off-grid.csv"
    cli(
        "simulate", "--selfcal", "--positions", "24", "--heads", "0,97,180",
        "--cycles", "2", "--out", data,
    )
    s = polycal.read_selfcal(str(data))
    result = polycal.selfcal(
        s, budget=polycal.budget(SELFCAL_BUDGET), monte_carlo=2000, seed=7
    )
    expected = cli(
        "selfcal", data, "--budget", SELFCAL_BUDGET, "--monte-carlo", "2000",
        "--seed", "7", "--format", "json",
    )
    assert result.to_json() == expected
    mc = json.loads(expected)["monte_carlo"]
    assert len(mc["encoder_error"]["u"]) == 24 and len(mc["head_error"]["u"]) == 2


def test_diagnose_selfcal_and_compare_are_the_clis():
    ms = polycal.read_measurements(DATA)
    assert polycal.diagnose(ms).to_json() == cli("diagnose", DATA, "--format", "json")
    budget = polycal.budget(BUDGET)
    assert polycal.diagnose(ms, budget=budget).to_json() == cli(
        "diagnose", DATA, "--budget", BUDGET, "--format", "json"
    )
    truth_path = ROOT / "examples/data/polygon24-2ac-6cycles.truth.json"
    truth = json.loads(truth_path.read_text())
    assert polycal.diagnose(ms, truth=truth).to_json() == cli(
        "diagnose", DATA, "--truth", truth_path, "--format", "json"
    )
    s = polycal.read_selfcal(str(SELFCAL))
    assert polycal.selfcal(s, budget=polycal.budget(SELFCAL_BUDGET)).to_json() == cli(
        "selfcal", SELFCAL, "--budget", SELFCAL_BUDGET, "--format", "json"
    )
    assert polycal.selfcal(s).to_json() == cli("selfcal", SELFCAL, "--format", "json")
    budget_text = BUDGET.read_text()
    from_text = polycal.solve(ms, budget=polycal.budget(budget_text))
    assert from_text.pitch_deviation_U.tolist() == polycal.solve(ms, budget=budget).pitch_deviation_U.tolist()
    # compare: this run (with its budget) against the shift-angle reference
    ours = ROOT / "target" / "python-test-ours.csv"
    ours.parent.mkdir(exist_ok=True)
    ours.write_text(cli("solve", DATA, "--budget", BUDGET, "--format", "csv") + "\n")
    expected = json.loads(cli("compare", ours, REFERENCE, "--format", "json"))
    solved = polycal.solve(ms, budget=budget)
    got = polycal.compare(solved, polycal.read_results(REFERENCE))
    assert [r["en"] for r in got["rows"]] == [r["en"] for r in expected["rows"]]
    assert got["max_abs_en"] == expected["max_abs_en"]
    # and from two files, exactly the CLI's object, its verdict's fields with it
    from_files = polycal.compare(str(ours), str(REFERENCE)).to_dict()
    assert from_files["rows"] == expected["rows"]
    for key in ("verdict", "vector", "en_exceeding", "en_expected"):
        assert from_files[key] == expected[key], key
    assert got["vector"]["consistent"] is True and got["verdict"] == "vector"
    # the per-row rule, as `--verdict en`
    expected_en = json.loads(
        cli("compare", ours, REFERENCE, "--format", "json", "--verdict", "en")
    )
    got_en = polycal.compare(str(ours), str(REFERENCE), verdict="en").to_dict()
    assert got_en["verdict"] == "en"
    for key in ("rows", "vector", "en_exceeding", "en_expected"):
        assert got_en[key] == expected_en[key], key
    with pytest.raises(ValueError):
        polycal.compare(str(ours), str(REFERENCE), verdict="max")


def test_simulate_is_the_clis():
    ms, truth = polycal.simulate(faces=12, cycles=3, seed=7)
    text = cli("simulate", "--faces", "12", "--cycles", "3", "--closing", "--seed", "7")
    from_cli = polycal.read_measurements(text + "\n")
    ours, theirs = ms.columns(), from_cli.columns()
    for column in ("cycle", "step", "ac", "face", "reading"):
        assert ours[column].tolist() == theirs[column].tolist(), column
    assert truth["faces"] == 12 and len(truth["pitch_deviation"]) == 12


# ---------------------------------------------------------------- numpy in and out


INTEGER_DTYPES = [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64]
FLOAT_DTYPES = [np.float32, np.float64]


def _columns(ms):
    c = ms.columns()
    return {k: c[k] for k in ("cycle", "step", "ac", "face", "reading")}


@pytest.mark.parametrize("int_dtype", INTEGER_DTYPES)
@pytest.mark.parametrize("float_dtype", FLOAT_DTYPES)
def test_arrays_of_every_dtype_give_the_files_results(int_dtype, float_dtype):
    ms = polycal.read_measurements(DATA)
    c = _columns(ms)
    built = polycal.MeasurementSet.from_arrays(
        cycle=c["cycle"].astype(int_dtype),
        step=c["step"].astype(int_dtype),
        ac=c["ac"].astype(int_dtype),
        face=c["face"].astype(int_dtype),
        reading=c["reading"].astype(float_dtype),
    )
    solved = polycal.solve(built)
    reference = polycal.solve(ms)
    if float_dtype == np.float64:
        assert solved.pitch_deviation.tolist() == reference.pitch_deviation.tolist()
    else:  # float32 readings round the data at 1e-7 relative
        assert np.allclose(solved.pitch_deviation, reference.pitch_deviation, atol=1e-5)


def test_lists_and_a_dataframe_are_taken_too():
    ms = polycal.read_measurements(DATA)
    c = _columns(ms)
    lists = polycal.MeasurementSet.from_arrays(**{k: v.tolist() for k, v in c.items()})
    assert polycal.solve(lists).to_json() != ""
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame(c)
    from_frame = polycal.MeasurementSet.from_dataframe(frame)
    assert polycal.solve(from_frame).encoder_error.tolist() == polycal.solve(ms).encoder_error.tolist()
    df = polycal.solve(ms, budget=polycal.budget(BUDGET)).to_dataframe()
    assert set(df["quantity"]) == {"pitch_deviation", "face_deviation", "encoder_error", "setup_error"}


def test_bad_shapes_dtypes_and_nan_are_refused_by_column_and_index():
    ms = polycal.read_measurements(DATA)
    c = _columns(ms)
    reading = c["reading"].copy()
    reading[17] = np.nan
    with pytest.raises(ValueError, match=r"column reading, index 17"):
        polycal.MeasurementSet.from_arrays(**{**c, "reading": reading})
    with pytest.raises(ValueError, match=r"column step: expected one dimension"):
        polycal.MeasurementSet.from_arrays(**{**c, "step": c["step"].reshape(-1, 2)})
    with pytest.raises(ValueError, match=r"column face: expected integers"):
        polycal.MeasurementSet.from_arrays(**{**c, "face": c["face"].astype(str)})
    step = c["step"].astype(float)
    step[3] = 2.5
    with pytest.raises(ValueError, match=r"column step, index 3: 2.5 is not a whole number"):
        polycal.MeasurementSet.from_arrays(**{**c, "step": step})
    with pytest.raises(ValueError, match=r"column ac, index 0: -1 is negative"):
        polycal.MeasurementSet.from_arrays(**{**c, "ac": -c["ac"]})
    with pytest.raises(ValueError, match=r"column cycle has 299 values, reading has 300"):
        polycal.MeasurementSet.from_arrays(**{**c, "cycle": c["cycle"][1:]})
    # the largest uint64 was wrapped to -1 and called negative
    ac = c["ac"].astype(np.uint64)
    ac[4] = np.iinfo(np.uint64).max
    with pytest.raises(
        ValueError,
        match=r"column ac, index 4: 18446744073709551615 is too large \(at most 9223372036854775807\)",
    ):
        polycal.MeasurementSet.from_arrays(**{**c, "ac": ac})
    face = c["face"].astype(float)
    face[2] = 1e20
    with pytest.raises(ValueError, match=r"column face, index 2: 1e\+20 is too large"):
        polycal.MeasurementSet.from_arrays(**{**c, "face": face})


def test_a_set_too_big_for_the_memory_is_refused_before_any_copy():
    # 10¹² rows of zero-stride columns take no memory themselves; as a set they would
    # take about 400 TB: MemoryError at once (they were converted row by row first,
    # about 225 bytes a row, until the interpreter aborted)
    n = 10**12
    ints = np.broadcast_to(np.int64(1), (n,))
    reals = np.broadcast_to(np.float64(0.5), (n,))
    with pytest.raises(MemoryError, match=r"1000000000000 rows need about .* of memory to become a set; "):
        polycal.MeasurementSet.from_arrays(cycle=ints, step=ints, ac=ints, face=ints, reading=reals)
    with pytest.raises(MemoryError, match=r"1000000000000 rows need about "):
        polycal.SelfcalSet.from_arrays(
            cycle=ints, step=ints, head=ints, head_angle=reals, reading=reals
        )


def test_covariance_is_formed_on_request_and_its_diagonal_is_u_squared():
    r = polycal.solve(polycal.read_measurements(DATA), budget=polycal.budget(BUDGET))
    for family in ("pitch_deviation", "face_deviation", "encoder_error"):
        cov = r.covariance(family)
        assert cov.shape == (24, 24)
        assert np.allclose(cov, cov.T, atol=1e-15)
        assert np.allclose(np.sqrt(np.diag(cov)), r[family + "_u"], rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="family"):
        r.covariance("beta")


# ---------------------------------------------------------------- the paper's design


def test_the_paper_design_equals_its_closed_form_written_here():
    # one setup, AC1 on face p+1 and AC2 on face p+2 at step p, cycles averaged
    ms, _ = polycal.simulate(faces=24, ac_faces=(1, 2), cycles=4, closing=False, seed=11)
    c = ms.columns()
    n = 24
    m = np.zeros((2, n))
    count = np.zeros((2, n))
    for ac, step, reading in zip(c["ac"], c["step"], c["reading"]):
        m[ac - 1, step] += reading
        count[ac - 1, step] += 1
    m /= count
    # eqs. (6)-(8): m2[p] - m1[p] = φ[p+2] - φ[p+1] + U₂ - U₁ = β[p+2] + const; Σβ = 0
    d = m[1] - m[0]
    beta = np.empty(n)
    for p in range(n):
        beta[(p + 2 - 1) % n] = d[p]  # β of face p+2, 0-based index p+1
    beta -= beta.mean()
    phi = np.cumsum(beta)  # φ[f] = β[1] + … + β[f], φ[N] = 0
    phi[-1] = 0.0
    # eq. (9)-(10): α[p] = m1[p] − φ[p+1] − U₁ with Σα = 0
    alpha = np.array([m[0, p] - phi[p % n] for p in range(n)])
    alpha -= alpha.mean()
    solved = polycal.solve(ms, method="closed-form")
    assert np.max(np.abs(solved.pitch_deviation - beta)) < 1e-12
    assert np.max(np.abs(solved.encoder_error - alpha)) < 1e-12
    lsq = polycal.solve(ms, method="lsq")
    assert np.max(np.abs(lsq.pitch_deviation - beta)) < 1e-12


def test_the_paper_comparison_gives_the_clis_en():
    ms = polycal.read_measurements(DATA)
    budget = polycal.budget({
        "p": 0.95,
        "component": [
            {"name": "Angle error of the autocollimators", "type": "B", "distribution": "rectangular",
             "half_width": 0.135, "acts_on": "each-reading", "dof": 50},
        ],
    })
    solved = polycal.solve(ms, budget=budget)
    assert solved.p == 0.95 and np.all(solved.pitch_deviation_U > 0)
    result = polycal.compare(solved, REFERENCE)
    assert result.max_abs_en == max(abs(r["en"]) for r in result.rows if r["in_verdict"])


# ---------------------------------------------------------------- refusals


def test_a_malformed_file_raises_input_error_with_its_position(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("cycle,step,ac,face,reading\n1,0,1,1,0.1\n1,1,1,2,zero\n")
    with pytest.raises(polycal.InputError) as raised:
        polycal.read_measurements(bad)
    error = raised.value
    assert (error.path, error.line, error.column) == (str(bad), 3, 9)
    expected = subprocess.run([_binary(), "solve", str(bad)], capture_output=True, text=True)
    assert expected.returncode == 2
    assert expected.stderr.strip() == f"error: {error}"
    with pytest.raises(polycal.InputError) as raised:
        polycal.budget("p = 2.0\n")
    assert raised.value.line == 1


def test_a_design_that_loses_harmonics_raises_design_error():
    ms, _ = polycal.simulate(faces=24, ac_faces=(1, 13), cycles=2, closing=False)
    with pytest.raises(polycal.DesignError) as raised:
        polycal.solve(ms)
    assert raised.value.lost_harmonics == list(range(2, 24, 2))
    assert "harmonics 2, 4" in str(raised.value)


def test_sizes_that_would_break_the_machine_are_refused_not_aborted():
    with pytest.raises(polycal.InputError, match="step"):
        polycal.MeasurementSet.from_arrays(
            cycle=[1, 1, 1], step=[0, 1, 2**40], ac=[1, 1, 1], face=[1, 2, 3], reading=[0.0] * 3
        )
    with pytest.raises(polycal.InputError):
        polycal.MeasurementSet.from_arrays(
            cycle=[1, 1, 1], step=[0, 1, 2], ac=[1, 1, 1], face=[1, 2, 3], reading=[0.0] * 3,
            faces=2**40,
        )
    with pytest.raises(ValueError, match="too large"):
        polycal.MeasurementSet.from_arrays(
            cycle=[2**40], step=[0], ac=[1], face=[1], reading=[0.0]
        )
    with pytest.raises(ValueError):
        polycal.solve(polycal.read_measurements(DATA), method="magic")
    with pytest.raises(ValueError):
        polycal.solve(polycal.read_measurements(DATA), sigma=-1.0)


# ---------------------------------------------------------------- threads


def test_two_solves_in_two_threads_finish_and_agree():
    ms, _ = polycal.simulate(faces=360, cycles=4, seed=3)
    budget = polycal.budget(BUDGET)
    results = [None, None]

    def work(i):
        results[i] = polycal.solve(ms, budget=budget, monte_carlo=300, seed=9).to_json()

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=300)
    assert all(r is not None for r in results)
    assert results[0] == results[1]


# ---------------------------------------------------------------- optional paths, example


def test_plot_draws_the_family_with_its_bars():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    r = polycal.solve(polycal.read_measurements(DATA), budget=polycal.budget(BUDGET))
    ax = r.plot("encoder_error")
    line = ax.lines[0]
    assert line.get_ydata().tolist() == r.encoder_error.tolist()


def test_the_example_script_runs_and_reproduces_the_papers_comparison():
    import sys

    out = subprocess.run(
        [sys.executable, str(ROOT / "examples/python/paper_example.py")],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert out.returncode == 0, out.stderr
    # the CLI's comparison of the same results
    ours = ROOT / "target" / "python-test-example.csv"
    ours.parent.mkdir(exist_ok=True)
    ours.write_text(cli("solve", DATA, "--budget", BUDGET, "--format", "csv") + "\n")
    expected = json.loads(cli("compare", ours, REFERENCE, "--format", "json"))
    assert f"largest |En| = {expected['max_abs_en']:.2f}: the calibrations agree" in out.stdout


def test_shifted_mountings_and_self_calibration_sets_from_arrays():
    # sub-pitch mountings: the shift column from arrays, solved as the CLI solves the file
    text = cli("simulate", "--faces", "12", "--setups", "2", "--shift-deg", "0,7.5",
               "--cycles", "2", "--seed", "3")
    path = ROOT / "target" / "python-test-subpitch.csv"
    path.write_text(text + "\n")
    from_file = polycal.read_measurements(path)
    c = from_file.columns()
    import csv

    with open(path) as f:
        rows = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    shift = [float(r["shift"]) for r in rows]
    built = polycal.MeasurementSet.from_arrays(
        cycle=c["cycle"], step=c["step"], ac=c["ac"], face=c["face"], reading=c["reading"],
        setup=c["setup"], shift=shift, direction=c["direction"],
    )
    expected = json.loads(cli("solve", path, "--format", "json"))
    got = polycal.solve(built).to_dict()
    assert got["encoder_error"] == expected["encoder_error"]
    assert got["encoder_angle_deg"] == expected["encoder_angle_deg"]
    bad = list(shift)
    bad[-1] = 3.0
    with pytest.raises(ValueError, match=r"column shift, index 95: 3 differs from setup 2.s shift 7.5"):
        polycal.MeasurementSet.from_arrays(
            cycle=c["cycle"], step=c["step"], ac=c["ac"], face=c["face"], reading=c["reading"],
            setup=c["setup"], shift=bad,
        )
    # a self-calibration set from the file's columns gives the file's result
    with open(SELFCAL) as f:
        rows = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    columns = {
        key: np.asarray([float(r[key]) for r in rows])
        for key in ("cycle", "step", "head", "head_angle", "reading", "time")
    }
    for key in ("cycle", "step", "head"):
        columns[key] = columns[key].astype(np.uint16)
    s = polycal.SelfcalSet.from_arrays(**columns)
    ours = polycal.selfcal(s).to_dict()
    pd = pytest.importorskip("pandas")
    from_frame = polycal.selfcal(polycal.SelfcalSet.from_dataframe(pd.DataFrame(columns)))
    assert from_frame.to_dict()["encoder_error"] == ours["encoder_error"]
    theirs = json.loads(cli("selfcal", SELFCAL, "--format", "json"))
    assert ours["encoder_error"] == theirs["encoder_error"]
    assert ours["head_error"] == theirs["head_error"]


def test_a_budget_warns_as_the_cli_does_and_a_bad_dict_names_its_entry():
    component = {
        "name": "Repeatability", "type": "A", "distribution": "normal", "u": 0.05,
        "acts_on": "each-reading",
    }
    with pytest.warns(UserWarning, match="Repeatability.*type A"):
        polycal.budget({"p": 0.95, "component": [component]})
    with pytest.raises(ValueError, match=r"budget: .* \(at `p = 2.0`\)"):
        polycal.budget({"p": 2.0, "component": [component]})


# ---------------------------------------------------------------- key comparisons

KC = ROOT / "examples/data/kc"


def test_kc_is_the_clis_json_to_the_byte(tmp_path):
    labs = {name: KC / f"{name}.csv" for name in "ABCDEF"}
    args = [f"{name}={path}" for name, path in labs.items()]
    result = polycal.kc(labs)
    assert result.to_json() == cli("kc", *args, "--quantity", "pitch_deviation", "--format", "json")
    # the reference and the laboratories' degrees of equivalence as numpy arrays
    assert isinstance(result["reference"], np.ndarray)
    assert result["reference"].shape == (12,)
    assert [e["lab"] for e in result["excluded"]] == ["F"]
    random = polycal.kc(labs, method="dersimonian-laird")
    expected = cli(
        "kc", *args, "--method", "dersimonian-laird", "--quantity", "pitch_deviation", "--format", "json"
    )
    assert random.to_json() == expected
    encoder = polycal.kc(labs, quantity="encoder_error")
    assert encoder.to_json() == cli(
        "kc", *args, "--quantity", "encoder_error", "--format", "json"
    )
    # the one decision and the search, and a laboratory kept in by the pilot
    assert not result["vector_all"]["consistent"]
    assert list(result["search"]["steps"][0]["best"]) == list("ABCDE")
    kept = polycal.kc(labs, keep=["F"])
    assert kept.to_json() == cli("kc", *args, "--keep", "F", "--quantity", "pitch_deviation", "--format", "json")
    assert list(kept["kept"]) == ["F"]
    # a laboratory kept out of the reference, with its degrees of equivalence
    out = polycal.kc(labs, not_in_reference=["F"])
    assert out.to_json() == cli(
        "kc", *args, "--not-in-reference", "F", "--quantity", "pitch_deviation", "--format", "json"
    )
    assert list(out["not_in_reference"]) == ["F"]
    assert list(out["excluded"]) == []
    # linked to another comparison, and U by Monte Carlo: the CLI's bytes
    cipm = polycal.kc({name: KC / f"{name}.csv" for name in "ABCD"})
    cipm_path = tmp_path / "cipm.json"
    cipm_path.write_text(cipm.to_json())
    rmo_labs = {name: KC / f"{name}.csv" for name in "BCEF"}
    rmo_args = [f"{name}={path}" for name, path in rmo_labs.items()]
    linked = polycal.kc(rmo_labs, link=cipm, monte_carlo=2000)
    assert linked.to_json() == cli(
        "kc", *rmo_args, "--link", str(cipm_path), "--monte-carlo", "2000",
        "--quantity", "pitch_deviation", "--format", "json",
    )
    assert list(linked["link"]["labs"]) == ["B", "C"]


def test_kc_draft_a_is_the_clis_with_the_same_key(tmp_path):
    # Draft A: the laboratories by code letters, the key apart; the CLI reading the
    # same key writes the same bytes, and nothing but the key names a laboratory
    real = {"PTB": "A", "NPL": "B", "NIST": "C", "NMIJ": "D", "METAS": "E", "INRIM": "F"}
    labs = {name: KC / f"{file}.csv" for name, file in real.items()}
    args = [f"{name}={path}" for name, path in labs.items()]
    draft, key = polycal.kc_draft_a(labs, seed=7)
    rows = [line.split(",") for line in key.strip().splitlines()]
    assert rows[0] == ["code", "lab"]
    assert sorted(lab for _, lab in rows[1:]) == sorted(real)
    assert sorted(code for code, _ in rows[1:]) == list("ABCDEF")
    text = draft.to_json()
    assert not any(name in text for name in real), text
    assert sorted(draft["labs"]) == list("ABCDEF")
    assert any("Draft A" in note for note in draft["notes"])
    key_path = tmp_path / "key.csv"
    key_path.write_text(key)
    assert text == cli(
        "kc", *args, "--anonymise", str(key_path), "--quantity", "pitch_deviation",
        "--format", "json",
    )
    # Draft B: the key read back gives the same codes; the seed repeats the draw
    again, same_key = polycal.kc_draft_a(labs, key=key)
    assert again.to_json() == text and same_key == key
    assert polycal.kc_draft_a(labs, seed=7)[1] == key
    # kept in by its real name, as --keep takes it
    kept, _ = polycal.kc_draft_a(labs, key=key, keep=["INRIM"])
    code = {lab: code for code, lab in rows[1:]}["INRIM"]
    assert list(kept["kept"]) == [code]
    # a key without a laboratory: the command's refusal
    short = "".join(line + "\n" for line in key.strip().splitlines() if not line.endswith(",PTB"))
    with pytest.raises(polycal.PolycalError, match="PTB"):
        polycal.kc_draft_a(labs, key=short)


def test_shared_quantities_loop_is_the_clis_json_lines(tmp_path):
    # without --quantity the CLI compares every quantity the files share, one JSON
    # object per line; a Python user loops over shared_quantities for the same objects
    labs = {name: KC / f"{name}.csv" for name in "ABC"}
    pilot = [(name, KC / f"pilot-{name}.csv") for name in ("start", "end")]
    args = [f"{name}={path}" for name, path in labs.items()]
    args += [f"--pilot={name}={path}" for name, path in pilot]
    shared = polycal.shared_quantities(labs, pilot=pilot)
    assert shared == ["pitch_deviation", "encoder_error", "angle_block"]
    lines = cli("kc", *args, "--format", "json").splitlines()
    looped = [polycal.kc(labs, pilot=pilot, quantity=q).to_json() for q in shared]
    assert [json.loads(line) for line in lines] == [json.loads(j) for j in looped]
    # a result without encoder errors: the pitch deviations alone
    pitch_only = tmp_path / "pitch.csv"
    pitch_only.write_text(
        "quantity,index,value,U,k\n"
        + "".join(f"pitch_deviation,{f},0.0,0.2,2\n" for f in range(1, 13))
    )
    assert polycal.shared_quantities({"A": KC / "A.csv", "P": pitch_only}) == [
        "pitch_deviation"
    ]


def test_kc_of_angle_blocks_is_the_clis_json_and_a_block_not_measured_is_nan():
    labs = {name: KC / f"{name}.csv" for name in "ABCDEF"}
    args = [f"{name}={path}" for name, path in labs.items()]
    blocks = polycal.kc(labs, quantity="angle_block")
    assert blocks.to_json() == cli("kc", *args, "--quantity", "angle_block", "--format", "json")
    assert list(blocks["index"]) == [1, 2, 3, 4]
    assert [e["lab"] for e in blocks["excluded"]] == ["E"]
    # D did not measure the 90° block: NaN there (null in the JSON), numbers elsewhere
    d = blocks["degrees_of_equivalence"][3]
    assert d["lab"] == "D"
    assert np.isnan(d["d"][3]) and np.isnan(d["U"][3])
    assert np.all(np.isfinite(d["d"][:3]))
    assert json.loads(blocks.to_json())["degrees_of_equivalence"][3]["d"][3] is None


def test_shared_quantities_refuses_as_the_cli_does(tmp_path):
    pitch = tmp_path / "pitch.csv"
    pitch.write_text(
        "quantity,index,value,U,k\n"
        + "".join(f"pitch_deviation,{f},0.0,0.2,2\n" for f in range(1, 13))
    )
    encoder = tmp_path / "encoder.csv"
    encoder.write_text(
        "quantity,index,value,U,k\n"
        + "".join(f"encoder_error,{p},0.0,0.2,2\n" for p in range(12))
    )
    with pytest.raises(polycal.PolycalError) as caught:
        polycal.shared_quantities({"P": pitch, "E": encoder})
    out = subprocess.run(
        [_binary(), "kc", f"P={pitch}", f"E={encoder}"], capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode == 2
    assert str(caught.value) in out.stderr
    assert "no pitch_deviation rows in" in str(caught.value)
    assert "no encoder_error rows in" in str(caught.value)


def test_kc_refuses_as_the_cli_does():
    with pytest.raises(polycal.PolycalError) as caught:
        polycal.kc({"A": KC / "A.csv"})
    out = subprocess.run(
        [_binary(), "kc", f"A={KC / 'A.csv'}"], capture_output=True, text=True, cwd=ROOT
    )
    assert out.returncode == 2
    assert str(caught.value) in out.stderr
    with pytest.raises(ValueError):
        polycal.kc({"A": KC / "A.csv", "B": KC / "B.csv"}, method="median")
