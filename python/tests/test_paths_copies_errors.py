"""What a notebook does with the package (issue 48, item 9): a path string or a
`pathlib.Path` wherever a set or a result is taken, results and sets through pickle and
`copy.deepcopy` equal to the bit, the exceptions as `polycal.`'s, the fields only an
uncertainty evaluation gives as `None` without it, and a plot legend that covers no point.

Numbers are checked against the command line's JSON (the same library, another path
through it), against the object before the round trip compared byte by byte, or against
the figure's own geometry in display coordinates; never against a copy the test itself
made the same way."""

import copy
import json
import pickle
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest

import polycal
from test_polycal import BUDGET, DATA, KC, REFERENCE, SELFCAL, SELFCAL_BUDGET, _binary, cli

SHIFTED = DATA.parent / "polygon24-shift-angle-5setups.csv"


def _sub_pitch():
    """A simulated set of two mountings 7.5° apart (sub-pitch: the `shift` column)."""
    ms, _ = polycal.simulate(faces=12, setups=2, shift_deg=[0, 7.5], cycles=2, seed=3)
    return ms


def cli_error(*args):
    """The command's one `error:` line for a refused input (status 2)."""
    out = subprocess.run([_binary(), *map(str, args)], capture_output=True, text=True)
    assert out.returncode == 2, out.stderr
    return out.stderr.strip()


def _three_ways(path):
    """The path as a string, as a `pathlib.Path`, and as the `os.PathLike` a user
    might write (a class with `__fspath__` only)."""

    class Fspath:
        def __fspath__(self):
            return str(path)

    return [str(path), Path(path), Fspath()]


# ---------------------------------------------------------------- a path wherever a set is taken


def test_solve_and_diagnose_take_a_path_string_and_a_pathlib_path():
    plain = cli("solve", DATA, "--format", "json")
    budgeted = cli("solve", DATA, "--budget", BUDGET, "--format", "json")
    diagnosed = cli("diagnose", DATA, "--format", "json")
    for data in _three_ways(DATA):
        assert polycal.solve(data).to_json() == plain
        assert polycal.diagnose(data).to_json() == diagnosed
        for budget in _three_ways(BUDGET):
            assert polycal.solve(data, budget=budget).to_json() == budgeted
    # a budget as a dict or a TOML text is what `polycal.budget` takes, here too
    # (named by its text's name, as the command names it by its path)
    text = BUDGET.read_text()
    from_text = json.loads(polycal.solve(DATA, budget=text).to_json())
    assert from_text["uncertainty"].pop("budget") == "<budget>"
    expected = json.loads(budgeted)
    assert expected["uncertainty"].pop("budget") == str(BUDGET)
    assert from_text == expected


def test_diagnose_takes_its_truth_as_a_path_string_and_a_pathlib_path(tmp_path):
    truth = DATA.parent / "polygon24-2ac-6cycles.truth.json"
    expected = cli("diagnose", DATA, "--truth", truth, "--format", "json")
    for given in _three_ways(truth) + [truth.read_text(), json.loads(truth.read_text())]:
        assert polycal.diagnose(DATA, truth=given).to_json() == expected
    with pytest.raises(FileNotFoundError) as raised:
        polycal.diagnose(DATA, truth=tmp_path / "no-truth.json")
    assert raised.value.filename == str(tmp_path / "no-truth.json")
    bad = tmp_path / "bad-truth.json"
    bad.write_text('{"faces": 24,\n  "pitch_deviation": [1, 2,]}\n')
    with pytest.raises(polycal.InputError) as raised:
        polycal.diagnose(DATA, truth=bad)
    out = cli_error("diagnose", DATA, "--truth", bad)
    assert out == f"error: {raised.value}"
    assert (raised.value.path, raised.value.line) == (str(bad), 2)


def test_selfcal_takes_a_path_string_and_a_pathlib_path():
    expected = cli("selfcal", SELFCAL, "--budget", SELFCAL_BUDGET, "--format", "json")
    for data in _three_ways(SELFCAL):
        for budget in (str(SELFCAL_BUDGET), Path(SELFCAL_BUDGET)):
            assert polycal.selfcal(data, budget=budget).to_json() == expected


def test_compare_and_kc_take_path_strings_and_pathlib_paths():
    expected = cli("compare", REFERENCE, REFERENCE, "--format", "json")
    for a in _three_ways(REFERENCE):
        for b in (str(REFERENCE), Path(REFERENCE)):
            assert polycal.compare(a, b).to_json() == expected
    labs = {name: KC / f"{name}.csv" for name in "ABCDEF"}
    pilot = [(name, KC / f"pilot-{name}.csv") for name in ("start", "middle", "end")]
    args = [f"{name}={path}" for name, path in labs.items()]
    args += [f"--pilot={name}={path}" for name, path in pilot]
    expected = cli("kc", *args, "--quantity", "pitch_deviation", "--format", "json")
    as_strings = polycal.kc(
        {k: str(v) for k, v in labs.items()}, pilot=[(k, str(v)) for k, v in pilot]
    )
    as_paths = polycal.kc(labs, pilot=pilot)
    assert as_strings.to_json() == expected
    assert as_paths.to_json() == expected


def test_the_readers_and_writers_take_both_and_anything_else_is_a_type_error(tmp_path):
    for data in (str(DATA), Path(DATA)):
        assert len(polycal.read_measurements(data)) == 300
    # the file's rows, counted here: the lines after the comments and the header
    lines = [l for l in REFERENCE.read_text().splitlines() if l and not l.startswith("#")]
    for reference in (str(REFERENCE), Path(REFERENCE)):
        assert len(polycal.read_results(reference)._inner) == len(lines) - 1
    for data in (str(SELFCAL), Path(SELFCAL)):
        assert polycal.read_selfcal(data).positions == 168
    ms = polycal.read_measurements(DATA)
    s = polycal.read_selfcal(SELFCAL)
    for out in (str(tmp_path / "a.csv"), tmp_path / "b.csv"):
        ms.write(out)
        assert Path(out).read_bytes() == (tmp_path / "a.csv").read_bytes()
    s.write(tmp_path / "s.csv")
    assert polycal.read_selfcal(tmp_path / "s.csv").columns()["reading"].tobytes() == (
        s.columns()["reading"].tobytes()
    )
    for call in (
        lambda: polycal.solve(42),
        lambda: polycal.diagnose(b"m.csv"),
        lambda: polycal.selfcal(ms),
        lambda: polycal.solve(ms, budget=3),
        lambda: polycal.compare(1.0, REFERENCE),
    ):
        with pytest.raises(TypeError, match="expected"):
            call()
    # a path that is not there is the same FileNotFound, however it is given
    for missing in (str(tmp_path / "no.csv"), tmp_path / "no.csv"):
        with pytest.raises(FileNotFoundError) as raised:
            polycal.solve(missing)
        assert raised.value.filename == str(tmp_path / "no.csv")


# ---------------------------------------------------------------- pickle and deepcopy


def _round_trips(obj):
    """The object through pickle (every protocol from 2) and through `copy.deepcopy`."""
    copies = [pickle.loads(pickle.dumps(obj, protocol)) for protocol in range(2, 6)]
    copies.append(copy.deepcopy(obj))
    return copies


def _same_bits(a, b, where="result"):
    """a and b are equal with every float compared by its 8 bytes (NaN too), at every
    depth of dicts, lists and numpy arrays."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray) and a.dtype == b.dtype and a.shape == b.shape, where
        assert a.tobytes() == b.tobytes(), where
    elif isinstance(a, dict):
        assert isinstance(b, dict) and list(a) == list(b), where
        for key in a:
            _same_bits(a[key], b[key], f"{where}.{key}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b)):
            _same_bits(x, y, f"{where}[{i}]")
    elif isinstance(a, float):
        assert isinstance(b, float) and np.float64(a).tobytes() == np.float64(b).tobytes(), where
    else:
        assert type(a) is type(b) and a == b, where


def _assert_same_result(a, b):
    assert type(a) is type(b)
    assert a.to_json() == b.to_json()
    _same_bits(a.to_dict(), b.to_dict())
    _same_bits({k: a[k] for k in a}, {k: b[k] for k in b})
    assert repr(a) == repr(b)


def test_every_result_type_pickles_and_deep_copies_to_the_bit():
    ms = polycal.read_measurements(DATA)
    budget = polycal.budget(BUDGET)
    results = [
        polycal.solve(ms),
        polycal.solve(ms, budget=budget, monte_carlo=300, seed=3),
        polycal.diagnose(ms, budget=budget),
        polycal.selfcal(SELFCAL, budget=SELFCAL_BUDGET),
        polycal.compare(polycal.solve(ms, budget=budget), REFERENCE),
        polycal.kc({name: KC / f"{name}.csv" for name in "ABCDEF"}),
    ]
    assert [type(r).__name__ for r in results] == [
        "SolveResult",
        "SolveResult",
        "DiagnoseResult",
        "SelfcalResult",
        "Comparison",
        "KeyComparison",
    ]
    for result in results:
        for back in _round_trips(result):
            _assert_same_result(result, back)


def test_a_solve_result_keeps_its_covariance_rows_and_angles_through_a_pickle():
    ms, _ = polycal.simulate(faces=12, cycles=3, seed=8)
    budget = polycal.budget(BUDGET)
    shifted = polycal.read_measurements(SHIFTED)
    for result in (
        polycal.solve(ms, budget=budget),
        polycal.solve(shifted, method="lsq"),
        polycal.solve(_sub_pitch()),
    ):
        for back in _round_trips(result):
            _assert_same_result(result, back)
            # the covariance is formed from a solution solved again after the round
            # trip: the same bits as the original's
            for family in ("pitch_deviation", "face_deviation", "encoder_error", "setup_error"):
                assert back.covariance(family).tobytes() == result.covariance(family).tobytes()
            assert back.angle_deg.tobytes() == result.angle_deg.tobytes()
            assert back.to_dataframe().equals(result.to_dataframe())
            assert back.face_angle_deg.tobytes() == result.face_angle_deg.tobytes()
    # the rows a comparison reads, through pickle: the same comparison as the CLI's
    solved = polycal.solve(DATA, budget=budget)
    back = pickle.loads(pickle.dumps(solved))
    assert polycal.compare(back, REFERENCE).to_json() == (
        polycal.compare(solved, REFERENCE).to_json()
    )
    # σ unknown (dof = 0): covariance None before and after
    bare, _ = polycal.simulate(faces=6, cycles=1, closing=False, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", polycal.PolycalWarning)
        exact = polycal.solve(bare)
    assert exact.covariance("pitch_deviation") is None
    assert pickle.loads(pickle.dumps(exact)).covariance("pitch_deviation") is None


def _assert_same_set(a, b):
    assert type(a) is type(b)
    assert len(a) == len(b) and a.source == b.source and a.comments == b.comments
    assert repr(a) == repr(b)
    ca, cb = a.columns(), b.columns()
    assert list(ca) == list(cb)
    for name in ca:
        assert ca[name].dtype == cb[name].dtype, name
        if ca[name].dtype == object:
            assert ca[name].tolist() == cb[name].tolist(), name
        else:
            assert ca[name].tobytes() == cb[name].tobytes(), name


def test_every_set_type_pickles_and_deep_copies_to_the_bit(tmp_path):
    simulated, _ = polycal.simulate(
        faces=12, cycles=2, bidirectional=True, temperature=True, elevation=True, seed=5
    )
    columns = polycal.read_measurements(DATA).columns()
    from_arrays = polycal.MeasurementSet.from_arrays(
        **{k: columns[k] for k in ("cycle", "step", "ac", "face", "reading", "time")}
    )
    sets = [
        polycal.read_measurements(DATA),
        _sub_pitch(),
        simulated,
        from_arrays,
        polycal.read_selfcal(SELFCAL),
        polycal.simulate_selfcal(positions=24, heads=(0, 90, 180, 270), bidirectional=True)[0],
    ]
    # optional columns with values (temperature, reading_y) and without (NaN) both travel
    assert np.isfinite(simulated.columns()["temperature"]).all()
    assert np.isfinite(simulated.columns()["reading_y"]).all()
    assert np.isnan(from_arrays.columns()["temperature"]).all()
    assert "shift" in sets[1].columns()
    for i, s in enumerate(sets):
        for j, back in enumerate(_round_trips(s)):
            _assert_same_set(s, back)
            # written, the copy is the original's file to the byte
            s.write(tmp_path / f"a{i}.csv")
            back.write(tmp_path / f"b{i}-{j}.csv")
            assert (tmp_path / f"a{i}.csv").read_bytes() == (
                tmp_path / f"b{i}-{j}.csv"
            ).read_bytes()
    # and solved, the same JSON
    for s in sets[:4]:
        assert polycal.solve(pickle.loads(pickle.dumps(s))).to_json() == polycal.solve(s).to_json()
    assert polycal.selfcal(copy.deepcopy(sets[4])).to_json() == polycal.selfcal(sets[4]).to_json()


def _solve_in_a_worker(ms, budget):
    return polycal.solve(ms, budget=budget)


def test_sets_budgets_and_results_travel_to_and_from_worker_processes():
    import concurrent.futures
    import multiprocessing

    ms = polycal.read_measurements(DATA)
    budget = polycal.budget(BUDGET)
    here = polycal.solve(ms, budget=budget)
    context = multiprocessing.get_context("spawn")  # a fresh interpreter: all by pickle
    with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        there = pool.submit(_solve_in_a_worker, ms, budget).result(timeout=120)
    assert there.to_json() == here.to_json()
    for family in ("pitch_deviation", "encoder_error"):
        assert there.covariance(family).tobytes() == here.covariance(family).tobytes()


def test_a_budget_pickles_and_deep_copies_to_the_bit():
    nested = polycal.budget(
        {
            "p": 0.99,
            "dof_policy": "floor",
            "component": [
                {"name": "scale", "type": "B", "distribution": "rectangular",
                 "half_width": 0.05, "acts_on": "each-position"},
                {"name": "mount", "type": "B", "distribution": "triangular",
                 "half_width": 0.02, "sensitivity": 1.5, "acts_on": "each-stop"},
                {"name": "cyclic", "type": "B", "distribution": "arcsine",
                 "half_width": 0.03, "acts_on": "each-autocollimator"},
                {"name": "cert", "type": "B", "distribution": "t", "scale": 0.01,
                 "dof": 9},
                {"name": "ref", "type": "B", "distribution": "normal", "u": 0.015, "dof": 20},
            ],
        }
    )
    for budget in (polycal.budget(BUDGET), polycal.budget(SELFCAL_BUDGET), nested):
        expected = polycal.solve(DATA, budget=budget).to_json()
        for back in _round_trips(budget):
            assert (back.p, back.source, repr(back)) == (budget.p, budget.source, repr(budget))
            _same_bits(back.components, budget.components)
            # the same evaluation to the byte, its dof policy, scopes and k included
            assert polycal.solve(DATA, budget=back).to_json() == expected
    assert {c["distribution"] for c in nested.components} == {
        "rectangular", "triangular", "arcsine", "t", "normal"
    }


def test_result_rows_pickle_with_their_file_and_lines(tmp_path):
    # a result file whose second row breaks the closure is named by file and line in
    # kc's refusal, from the rows read and from their copy alike
    rows = polycal.read_results(REFERENCE)
    for back in _round_trips(rows):
        assert repr(back) == repr(rows)
        assert polycal.compare(back, REFERENCE).to_json() == (
            polycal.compare(rows, REFERENCE).to_json()
        )
    labs = {name: polycal.read_results(KC / f"{name}.csv") for name in "ABCDEF"}
    copied = {name: pickle.loads(pickle.dumps(r)) for name, r in labs.items()}
    assert polycal.kc(copied).to_json() == polycal.kc(labs).to_json()


# ---------------------------------------------------------------- the exceptions are polycal's


def test_every_exception_class_is_polycals():
    classes = [
        polycal.PolycalError,
        polycal.InputError,
        polycal.DesignError,
        polycal.FileNotFound,
        polycal.PolycalWarning,
    ]
    for cls in classes:
        assert cls.__module__ == "polycal", cls
        assert getattr(polycal, cls.__name__) is cls
        assert repr(cls) == f"<class 'polycal.{cls.__name__}'>"


def test_every_raised_exception_shows_as_polycals(tmp_path):
    bad = tmp_path / "bad.csv"
    bad.write_text("cycle,step,ac,face,reading\n1,0,1,1,0.1\n1,1,1,2,zero\n")
    lossy, _ = polycal.simulate(faces=24, ac_faces=(1, 13), cycles=2, closing=False)
    raised = {}
    for name, call in (
        ("InputError", lambda: polycal.read_measurements(bad)),
        ("FileNotFound", lambda: polycal.solve(tmp_path / "none.csv")),
        ("DesignError", lambda: polycal.solve(lossy)),
        ("PolycalError", lambda: polycal.kc({"A": KC / "A.csv"})),
    ):
        with pytest.raises(polycal.PolycalError) as caught:
            call()
        error = caught.value
        assert type(error).__name__ == name
        assert type(error).__module__ == "polycal"
        raised[name] = error
    with pytest.warns(polycal.PolycalWarning) as warned:
        polycal.budget({"p": 0.95, "component": [
            {"name": "repeatability", "type": "A", "distribution": "normal", "u": 0.01},
        ]})
    assert type(warned[0].message).__module__ == "polycal"
    # they pickle (a worker's exception reaches the parent) with their attributes
    error = raised["InputError"]
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is polycal.InputError and str(back) == str(error)
    assert (back.path, back.line, back.column) == (str(bad), 3, 9)
    back = pickle.loads(pickle.dumps(raised["DesignError"]))
    assert back.lost_harmonics == list(range(2, 24, 2))
    missing = raised["FileNotFound"]
    back = pickle.loads(pickle.dumps(missing))
    assert type(back) is polycal.FileNotFound and isinstance(back, FileNotFoundError)
    assert (back.filename, back.errno, back.path) == (missing.filename, missing.errno, missing.path)


# ---------------------------------------------------------------- U without a budget


def test_every_field_of_an_uncertainty_evaluation_is_none_without_it():
    expected = json.loads(cli("solve", DATA, "--budget", BUDGET, "--format", "json"))
    plain = polycal.solve(DATA)
    evaluated = polycal.solve(DATA, budget=BUDGET)
    u_like = [
        "p",
        "pitch_deviation_U",
        "face_deviation_U",
        "encoder_error_U",
        "pitch_deviation_k",
        "face_deviation_k",
        "encoder_error_k",
        "uncertainty",
        "monte_carlo",
    ]
    for key in u_like:
        assert getattr(plain, key) is None and plain[key] is None and plain.get(key) is None
        assert key not in plain and key not in plain.to_dict()
        assert key in dir(plain)
        if key != "monte_carlo":
            assert getattr(evaluated, key) is not None
    assert evaluated.monte_carlo is None  # a budget without monte_carlo=
    assert evaluated.pitch_deviation_U.tolist() == expected["pitch_deviation_U"]
    assert plain.setup_error_U is None and plain.setup_error_k is None
    assert plain.setup_error[0].U is None and plain.setup_error[0]["k"] is None
    assert evaluated.setup_error_U.tolist() == [s["U"] for s in expected["setup_error"]]
    assert evaluated.setup_error[0].U == expected["setup_error"][0]["U"]
    # a field no evaluation gives is still an AttributeError naming the fields
    with pytest.raises(AttributeError, match="no field 'pitch_deviation_V'"):
        plain.pitch_deviation_V
    # diagnose's models and selfcal's evaluation alike
    found = polycal.diagnose(DATA)
    assert found.after.pitch_deviation_U is None and found.after["uncertainty"] is None
    assert found.before.p is None
    assert found.after.setup_error[0].U is None
    assert polycal.diagnose(DATA, budget=BUDGET).after.pitch_deviation_U.tolist() == (
        json.loads(cli("diagnose", DATA, "--budget", BUDGET, "--format", "json"))["after"][
            "pitch_deviation_U"
        ]
    )
    # and so after a pickle or a deep copy
    for back in _round_trips(plain):
        assert back.pitch_deviation_U is None and back["p"] is None
        assert back.setup_error[0].U is None and back.setup_error_k is None
    for back in _round_trips(found):
        assert back.after.pitch_deviation_U is None and back.after.setup_error[0].k is None
        with pytest.raises(AttributeError):
            back.after.pitch_deviation_V
    disc = polycal.selfcal(SELFCAL)
    assert disc.uncertainty is None and disc.monte_carlo is None
    # selfcal's U is the fit's and there without a budget, as the command's JSON has it
    assert disc.encoder_error_U.tolist() == json.loads(
        cli("selfcal", SELFCAL, "--format", "json")
    )["encoder_error_U"]
    # σ unknown: the fit's u are None, as the U without a budget
    bare, _ = polycal.simulate(faces=6, cycles=1, closing=False, seed=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", polycal.PolycalWarning)
        exact = polycal.solve(bare)
    assert exact.pitch_deviation_u is None and exact.setup_error_u is None


# ---------------------------------------------------------------- the plot's legend


def _drawn(ax):
    ax.figure.canvas.draw()
    return ax.get_legend().get_window_extent()


def _assert_legend_covers_no_point(ax, x, y, bars):
    box = _drawn(ax)
    ends = [np.asarray(y, dtype=float)]
    if bars is not None:
        bars = np.nan_to_num(np.asarray(bars, dtype=float))
        ends += [y - bars, y + bars]
    for values in ends:
        points = ax.transData.transform(np.column_stack([x, values]))
        inside = [
            (x[i], values[i])
            for i, (px, py) in enumerate(points)
            if box.x0 <= px <= box.x1 and box.y0 <= py <= box.y1
        ]
        assert not inside, f"the legend {box} covers {inside}"
    # and every point is within the axes' y range (none pushed out of sight)
    low, high = ax.get_ylim()
    for values in ends:
        assert np.all((values >= low) & (values <= high))


def test_the_legend_covers_no_point_and_no_bar():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    expected = json.loads(cli("solve", DATA, "--budget", BUDGET, "--format", "json"))
    result = polycal.solve(DATA, budget=BUDGET)
    # β7 and α at 330° are what the legend covered in the figure
    for family, x in (
        ("pitch_deviation", np.arange(1, 25)),
        ("face_deviation", np.arange(1, 25)),
        ("encoder_error", 15.0 * np.arange(24)),
    ):
        for figsize in ((6.4, 4.8), (4.0, 3.0), (12.0, 3.0)):
            fig, ax = plt.subplots(figsize=figsize)
            result.plot(family, ax=ax)
            y = np.asarray(expected[family], dtype=float)
            bars = [np.nan if v is None else v for v in expected[family + "_U"]]
            _assert_legend_covers_no_point(ax, x, y, bars)
            plt.close(fig)
    # the fit's u, and a set whose largest values sit where the legend goes (face 1)
    ms, truth = polycal.simulate(faces=12, cycles=3, pitch_spread=2.0, seed=11)
    plain = polycal.solve(ms)
    plain_json = json.loads(plain.to_json())
    ax = plain.plot("pitch_deviation")
    _assert_legend_covers_no_point(
        ax, np.arange(1, 13), np.asarray(plain_json["pitch_deviation"]),
        plain_json["pitch_deviation_u"],
    )
    plt.close(ax.figure)


def test_the_legend_says_k_once_when_every_k_shows_the_same():
    matplotlib = pytest.importorskip("matplotlib")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    expected = json.loads(cli("solve", DATA, "--budget", BUDGET, "--format", "json"))
    result = polycal.solve(DATA, budget=BUDGET)
    for family in ("pitch_deviation", "encoder_error"):
        k = [v for v in expected[family + "_k"] if v is not None]
        # the k differ in their last digits (1.98520… to 1.98644…), all 1.99 to two
        assert len(set(k)) > 1 and {f"{v:.2f}" for v in k} == {"1.99"}
        ax = result.plot(family)
        text = ax.get_legend().get_texts()[0].get_text()
        assert text.count("k = ") == 1 and "…" not in text
        assert "(k = 1.99, p = 0.95)" in text
        plt.close(ax.figure)
