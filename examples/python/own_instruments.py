"""Driving a polycal run with instruments of your own, from Python.

Your software owns the ports (here pyserial); polycal's session (`polycal.Session`)
decides everything else: the approach from the cycle's direction, readings until they
agree, stale and stray replies refused, the check after every cycle and the
re-measurements. It keeps the run directory (measurements.csv, manifest.json,
traffic.jsonl) as `polycal run` does (docs/FORMAT.md §7.6).

The instruments are `polycal sim-lab`'s (the `polycal` on PATH): two simulated ELCOMAT
3000 autocollimators and an SMC100 rotary table on pseudo-terminals, spoken to with their
own commands (docs/FORMAT.md §7.1, §7.2). A 12-face polygon, two cycles with the closing
step; the run goes to a new directory under out/ of the current directory, and the
solved pitch deviations β are printed. Run from the repository's root after
`pip install ./python pyserial`:

    python examples/python/own_instruments.py
"""

import json
import subprocess
import time
from datetime import datetime
from pathlib import Path

import serial  # pyserial

import polycal

FACES, CYCLES = 12, 2


class Failure(Exception):
    """An instrument that did not answer as its protocol says."""


class Port:
    """One instrument's serial line: every line sent and received goes to the run's
    traffic log. A query drains pending input first, then takes exactly one reply line."""

    def __init__(self, session, device, path, baud, command_end, reply_end, xonxoff=False):
        self.session, self.device, self.path = session, device, path
        self.command_end, self.reply_end = command_end, reply_end
        self.line = serial.Serial(path, baud, timeout=1.0, xonxoff=xonxoff)

    def send(self, command):
        text = command + self.command_end
        self.session.traffic(self.device, self.path, "sent", text)
        self.line.write(text.encode("ascii"))

    def query(self, command):
        self.line.reset_input_buffer()  # a late reply to an earlier query is not this one's
        self.send(command)
        raw = self.line.read_until(self.reply_end.encode("ascii"))
        if not raw.endswith(self.reply_end.encode("ascii")):
            self.session.traffic(self.device, self.path, "timeout", "no complete reply within 1000 ms")
            raise Failure(f"no reply to {command!r}")
        reply = raw.decode("ascii", "replace").rstrip("\r\n")
        self.session.traffic(self.device, self.path, "received", reply)
        return reply


class Elcomat(Port):
    """Möller-Wedel ELCOMAT 3000: `d` identifies, `a` measures (`4 <sss> <x> <y>`)."""

    def __init__(self, session, device, path):
        super().__init__(session, device, path, 19200, "\n", "\r")
        self.send("s")  # stop any stream

    def identify(self):
        return self.query("d").removeprefix("8 ")

    def measure(self):
        kind, status, x, y = self.query("a").split()
        if kind != "4" or status[-1] not in "13":
            raise Failure(f"measurement {kind} {status}: X not valid")
        return int(status), float(x), float(y) if status[-1] in "23" else None


class Smc100(Port):
    """Newport SMC100, address 1: `1TS` state, `1OR` home, `1PA` move, `1TP` position."""

    def __init__(self, session, path):
        super().__init__(session, "table", path, 57600, "\r\n", "\r\n", xonxoff=True)

    def state(self):
        reply = self.query("1TS")  # 1TS<error bits><state>
        errors, state = reply[3:7], reply[7:9]
        if errors != "0000" or state in ("3C", "3D", "3E", "14"):
            raise Failure(f"controller state {reply}")
        return state

    def wait_ready(self, seconds=60.0):
        deadline = time.monotonic() + seconds
        while self.state() not in ("32", "33", "34"):  # ready
            if time.monotonic() > deadline:
                raise Failure("not ready in time")
            time.sleep(0.02)

    def start(self):
        if self.state() in ("0A", "0B", "0C", "0D", "0E", "0F", "10", "11"):
            self.send("1OR")  # not referenced: home it before the first move
        self.wait_ready()

    def identify(self):
        return self.query("1VE").removeprefix("1VE").strip()

    def move(self, deg):
        self.wait_ready()
        self.send(f"1PA{deg:.6f}".rstrip("0").rstrip("."))  # sent once, never again
        self.wait_ready()
        return self.position()

    def position(self):
        return float(self.query("1TP").removeprefix("1TP"))

    def stop(self):
        self.send("1ST")


def new_run_dir():
    """A new directory under out/ each run: never one that holds a run already."""
    base = Path("out") / datetime.now().strftime("own-instruments-%Y%m%d-%H%M%S")
    run_dir, n = base, 1
    while run_dir.exists():
        run_dir, n = Path(f"{base}-{n}"), n + 1
    return run_dir


FAILURES = (Failure, ValueError, serial.SerialException)


def drive(session, acs, table):
    """Carries out what the session asks until it is over; returns its outcome."""
    while True:
        action = session.poll()
        if action.kind == "finished":
            return action.outcome
        if action.kind == "halt":  # the session ends without completing: stop the table
            try:
                table.stop()
            except FAILURES:
                pass
            continue
        try:
            if action.kind == "move":
                session.moved(table.move(action.to_deg))
            elif action.kind == "position":
                session.position(table.position())
            elif action.kind == "read":
                session.read(*acs[action.ac - 1].measure())
            elif action.kind == "wait":
                time.sleep(max(0.0, action.until_seconds - session.now()))
                session.waited()
            elif action.kind == "remount":
                session.remounted(False)  # one mounting in this run
        except FAILURES as e:
            session.failed(str(e))  # the session ends, naming the instrument


def main():
    lab = subprocess.Popen(
        ["polycal", "sim-lab", "--faces", str(FACES), "--cycles", str(CYCLES), "--closing",
         "--time-scale", "0.1", "--format", "json"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        paths = json.loads(lab.stdout.readline() or "null")
        if not paths:
            raise SystemExit(f"polycal sim-lab did not start: {lab.communicate()[1]}")
        run_dir = new_run_dir()
        session = polycal.Session(
            run_dir, faces=FACES, cycles=CYCLES, closing=True,
            ports={"ac1": paths["ac1"], "ac2": paths["ac2"], "table": paths["table"]},
        )
        acs = [Elcomat(session, f"ac{j}", paths[f"ac{j}"]) for j in (1, 2)]
        table = Smc100(session, paths["table"])
        try:
            table.start()
            session.begin([ac.identify() for ac in acs], table.identify())
        except FAILURES as e:
            session.failed(str(e))
        drive(session, acs, table)
        outcome = session.finish()
        print(f"run directory {run_dir}: {outcome}, {session.refused} replies refused")
        if outcome != "completed":
            raise SystemExit(1)
    finally:
        lab.stdin.close()  # sim-lab stops when its standard input closes
        try:
            lab.wait(timeout=10)
        except subprocess.TimeoutExpired:
            lab.kill()

    result = polycal.solve(run_dir / "measurements.csv")
    print("face  β/″       u(β)/″")
    for face, (beta, u) in enumerate(zip(result.pitch_deviation, result.pitch_deviation_u), 1):
        print(f"{face:>4}  {beta:+.4f}  {u:.4f}")


if __name__ == "__main__":
    main()
