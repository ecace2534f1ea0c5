"""polycal.Session: the run's rules driven from Python, the run directory its store
(docs/FORMAT.md §7.6). First with instruments of a few lines of physics written here
(paper eq. (2), as tests/lab/session_rules.rs has them), then the example
examples/python/own_instruments.py against `polycal sim-lab` over pseudo-terminals.

The command-line binary is found as $POLYCAL_BIN, or target/release or target/debug of
the repository (`cargo build` makes it); the example needs pyserial (CI installs it).
"""

import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import polycal

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples/python/own_instruments.py"
FACES = 8
PORTS = {"ac1": "lab:ac1", "ac2": "lab:ac2", "table": "lab:table"}


def _binary() -> str:
    for candidate in (
        os.environ.get("POLYCAL_BIN"),
        ROOT / "target/release/polycal",
        ROOT / "target/debug/polycal",
    ):
        if candidate and Path(candidate).is_file():
            return str(candidate)
    pytest.fail("the polycal binary is not built: run `cargo build` (or set POLYCAL_BIN)")


class Physics:
    """A polygon of 8 faces on a table, two autocollimators at faces 1 and 2: encoder
    error + face angle deviation + setup error, ±0.005″ of noise (X); the face's
    pyramidal error (Y)."""

    def __init__(self):
        self.table_deg = 0.0
        self.state = 0x2545F4914F6CDD1D

    def noise(self):
        mask = (1 << 64) - 1
        self.state ^= (self.state << 13) & mask
        self.state ^= self.state >> 7
        self.state ^= (self.state << 17) & mask
        return ((self.state >> 11) / (1 << 53) - 0.5) * 0.01

    def truth(self, ac):
        step = round(self.table_deg * FACES / 360.0) % FACES
        face = (step + ac - 1) % FACES + 1
        encoder = 0.6 * math.sin(2 * math.pi * step / FACES)
        face_deviation = [0.0, 0.4, -0.3, 0.9, 0.2, -0.5, 0.7, 0.0][face - 1]
        return encoder + face_deviation + [0.8, -1.1][ac - 1], face

    def reply(self, ac):
        x, face = self.truth(ac)
        y = [3.0, -2.0, 5.0, 1.0, -4.0, 2.5, -1.5, 0.5][face - 1]
        return 3, x + self.noise(), y + self.noise()


def drive(session, physics, tamper=lambda ac, deg, reply: reply):
    """Carries out every action until the session is over; the kinds seen, in order."""
    kinds = []
    while True:
        action = session.poll()
        kinds.append(action.kind)
        if action.kind == "move":
            physics.table_deg = action.to_deg
            session.moved(action.to_deg)
        elif action.kind == "position":
            session.position(physics.table_deg)
        elif action.kind == "read":
            session.read(*tamper(action.ac, physics.table_deg, physics.reply(action.ac)))
        elif action.kind == "wait":
            session.waited()
        elif action.kind == "remount":
            session.remounted(True)
        elif action.kind == "finished":
            return action.outcome, kinds


def traffic(run_dir):
    return [json.loads(line) for line in (run_dir / "traffic.jsonl").read_text().splitlines()]


def manifest(run_dir):
    return json.loads((run_dir / "manifest.json").read_text())


def new_session(run_dir, **options):
    session = polycal.Session(
        run_dir, faces=FACES, cycles=1, reading_noise_arcsec=0.02, ports=PORTS, **options
    )
    session.begin(["AC S/N 1", "AC S/N 2"], "TABLE 1.0")
    return session


def test_a_stale_reply_is_refused_and_the_run_kept_in_its_directory(tmp_path):
    run_dir = tmp_path / "run"
    session = new_session(run_dir)
    # Autocollimator 1's first reply at step 3 is its last reply at step 2, again.
    seen = {"at_2": None, "at_3": 0}

    def stale(ac, deg, reply):
        if ac != 1:
            return reply
        if deg == 90.0:
            seen["at_2"] = reply
        if deg == 135.0:
            seen["at_3"] += 1
            if seen["at_3"] == 1:
                return seen["at_2"]
        return reply

    outcome, kinds = drive(session, Physics(), stale)
    assert outcome == "completed"
    assert "progress" in kinds and "halt" not in kinds
    assert session.refused == 1
    assert session.finish() == "completed"
    assert session.finish() == "completed"  # recorded once; the same outcome again

    lines = traffic(run_dir)
    assert lines[0]["event"] == "session" and "Session (Python)" in lines[0]["text"]
    refused = [line for line in lines if line["event"] == "refused"]
    assert len(refused) == 1, refused
    assert (refused[0]["device"], refused[0]["port"]) == ("ac1", "lab:ac1")
    assert "stale: the same X, Y and status" in refused[0]["text"]

    ms = polycal.read_measurements(run_dir / "measurements.csv")
    columns = ms.columns()
    assert len(ms) == FACES * 2
    assert columns["step"].tolist() == [s for s in range(FACES) for _ in (1, 2)]
    assert columns["ac"].tolist() == [1, 2] * FACES
    # The reading kept at step 3 is the physics', not the stale one.
    at_3 = columns["reading"][6]
    truth = 0.6 * math.sin(math.radians(135)) + 0.9 + 0.8
    assert abs(at_3 - truth) < 0.01
    assert all(t >= 0 for t in columns["time"])  # the run clock's seconds

    recorded = manifest(run_dir)
    assert recorded["outcome"] == "completed"
    assert recorded["readings"] == FACES * 2
    assert recorded["ports"] == PORTS
    assert recorded["instruments"] == {"ac1": "AC S/N 1", "ac2": "AC S/N 2", "table": "TABLE 1.0"}


def test_a_failure_the_driver_reports_ends_the_session_naming_the_instrument(tmp_path):
    run_dir = tmp_path / "run"
    session = new_session(run_dir)
    physics = Physics()
    # Two stops, then autocollimator 2 stops answering.
    reads, halted = 0, False
    while True:
        action = session.poll()
        if action.kind == "move":
            physics.table_deg = action.to_deg
            session.moved(action.to_deg)
        elif action.kind == "read":
            reads += 1
            if action.ac == 2 and reads > 8:
                session.failed("no reply to 'a\\n' within 1000 ms")
            else:
                session.read(*physics.reply(action.ac))
        elif action.kind == "wait":
            session.waited()
        elif action.kind == "halt":
            halted = True
        elif action.kind == "finished":
            break
    assert halted
    expected = (
        "instrument-error: autocollimator 2 at lab:ac2: no reply to 'a\\n' within 1000 ms "
        "(reported by its driver)"
    )
    assert action.outcome == expected
    assert session.finish() == expected
    assert manifest(run_dir)["outcome"] == expected
    # The readings kept before the failure stay: two stops, and autocollimator 1 at the
    # third, whose two reads agreed before autocollimator 2 was asked.
    ms = polycal.read_measurements(run_dir / "measurements.csv")
    assert len(ms) == session.readings_done == 5
    assert ms.columns()["ac"].tolist() == [1, 2, 1, 2, 1]

    # The table failing at the first move names the table and its port.
    session = new_session(tmp_path / "table")
    assert session.poll().kind == "move"
    session.failed("controller state 1TS00013D")
    assert session.poll().kind == "halt"
    outcome = session.poll().outcome
    assert outcome.startswith("instrument-error: rotary table at lab:table: controller state")


def test_refusals_are_the_librarys(tmp_path):
    run_dir = tmp_path / "run"
    session = new_session(run_dir)
    action = session.poll()
    assert action.kind == "move" and action.to_deg == -0.5  # approached from below
    assert session.poll().kind == "move"  # asked again until answered
    with pytest.raises(polycal.PolycalError, match=r"the session asked for a move to -0\.5°, and was told"):
        session.read(3, 0.1, 0.2)
    with pytest.raises(ValueError, match="finite"):
        session.read(3, float("nan"))
    # A position that is not a number (an encoder read as garbage) is the library's refusal.
    with pytest.raises(polycal.PolycalError, match="whose position is not a finite number"):
        session.moved(float("nan"))
    assert session.poll().kind == "move"  # still asked
    with pytest.raises(polycal.PolycalError, match="has begun already"):
        session.begin(["a", "b"], "t")
    session.interrupt()
    assert session.poll().kind == "halt"
    assert session.poll().outcome == "interrupted"
    assert session.finish() == "interrupted"

    # A directory that holds a run already; a resumed run with other instruments.
    with pytest.raises(polycal.PolycalError, match="already"):
        polycal.Session(run_dir, faces=FACES, cycles=1, reading_noise_arcsec=0.02)
    resumed = polycal.Session(
        run_dir, faces=FACES, cycles=1, reading_noise_arcsec=0.02, resume=True, ports=PORTS
    )
    with pytest.raises(polycal.PolycalError, match=r"ac2 was \"AC S/N 2\", is now \"AC S/N 3\""):
        resumed.begin(["AC S/N 1", "AC S/N 3"], "TABLE 1.0")
    # Other settings than the run's.
    with pytest.raises(polycal.PolycalError, match="faces"):
        polycal.Session(run_dir, faces=12, cycles=1, resume=True)
    with pytest.raises(polycal.PolycalError, match="faces 2"):
        polycal.Session(tmp_path / "two", faces=2, cycles=1)
    with pytest.raises(ValueError, match="ports"):
        polycal.Session(tmp_path / "ports", faces=FACES, cycles=1, ports={"ac1": "x", "table": "y"})
    fresh = polycal.Session(tmp_path / "fresh", faces=FACES, cycles=1)
    with pytest.raises(polycal.PolycalError, match="begin"):
        fresh.poll()


def test_a_resumed_run_goes_on_where_the_last_session_stopped(tmp_path):
    run_dir = tmp_path / "run"
    session = new_session(run_dir)
    physics = Physics()
    kept = 0
    while kept < 5:
        action = session.poll()
        if action.kind == "move":
            physics.table_deg = action.to_deg
            session.moved(action.to_deg)
        elif action.kind == "read":
            session.read(*physics.reply(action.ac))
        elif action.kind == "wait":
            session.waited()
        elif action.kind == "progress":
            kept = action.done
    assert session.finish() == "interrupted"  # not over: ended as interrupt() ends it

    session = new_session(run_dir, resume=True)
    outcome, _ = drive(session, physics)
    assert outcome == "completed" and session.finish() == "completed"
    compared = [line for line in traffic(run_dir) if line["event"] == "compared"]
    assert len(compared) == 1 and compared[0]["text"].endswith(": agree"), compared
    assert len(polycal.read_measurements(run_dir / "measurements.csv")) == FACES * 2
    assert [s["outcome"] for s in manifest(run_dir)["sessions"]] == ["interrupted", "completed"]


# ------------------------------------------------- the example against polycal sim-lab


def test_the_example_drives_sim_lab_over_pyserial_and_prints_the_solved_beta(tmp_path):
    if not os.environ.get("CI"):
        pytest.importorskip("serial", reason="pyserial is not installed")
    binary = _binary()
    env = dict(os.environ, PATH=f"{Path(binary).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    ran = subprocess.run(
        [sys.executable, str(EXAMPLE)], cwd=tmp_path, env=env, capture_output=True, text=True,
        timeout=600,
    )
    assert ran.returncode == 0, ran.stdout + ran.stderr
    found = re.search(r"^run directory (\S+): completed, (\d+) replies refused$", ran.stdout, re.M)
    assert found, ran.stdout
    run_dir = tmp_path / found.group(1)
    assert run_dir.parent == tmp_path / "out"
    assert re.fullmatch(r"own-instruments-\d{8}-\d{6}(-\d+)?", run_dir.name)

    rows = re.findall(r"^\s*(\d+)\s+([+-]\d+\.\d{4})\s+(\d+\.\d{4})$", ran.stdout, re.M)
    assert [int(face) for face, _, _ in rows] == list(range(1, 13)), ran.stdout

    ms = polycal.read_measurements(run_dir / "measurements.csv")
    assert len(ms) == 2 * 13 * 2  # cycles · stops with the closing step · autocollimators
    recorded = manifest(run_dir)
    assert recorded["outcome"] == "completed"
    assert recorded["readings"] == 52
    assert "simulated by polycal" in recorded["instruments"]["table"]

    solved = subprocess.run(
        [binary, "solve", str(run_dir / "measurements.csv"), "--format", "json"],
        capture_output=True, text=True,
    )
    assert solved.returncode == 0, solved.stderr
    cli = json.loads(solved.stdout)
    # The package's numbers are the command's to the bit: the same digits printed.
    assert [(beta, u) for _, beta, u in rows] == [
        (f"{beta:+.4f}", f"{u:.4f}")
        for beta, u in zip(cli["pitch_deviation"], cli["pitch_deviation_u"])
    ]

    # The wire as the example spoke it, in the run's traffic log: the table homed before
    # its first move, every move sent once, every reply logged.
    lines = traffic(run_dir)
    sent = [line["text"] for line in lines if line["device"] == "table" and line["event"] == "sent"]
    assert "1OR\r\n" in sent and sent.index("1OR\r\n") < min(
        i for i, text in enumerate(sent) if text.startswith("1PA")
    )
    moves = [text for text in sent if text.startswith("1PA")]
    assert "1PA-0.5\r\n" in moves and "1PA360\r\n" in moves  # approached from below; closing
    received = [line for line in lines if line["device"] == "ac1" and line["event"] == "received"]
    assert len(received) >= 26 * 2 and all(line["text"].startswith(("4 ", "8 ")) for line in received)
