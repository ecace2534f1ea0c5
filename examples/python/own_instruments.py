"""Driving a polycal run with instruments of your own, from Python.

Your software owns the ports (here pyserial); polycal's session (`polycal.Session`)
decides everything else: the approach from the cycle's direction, readings until they
agree, stale and stray replies refused, the check after every cycle and the
re-measurements. It keeps the run directory (measurements.csv, manifest.json,
traffic.jsonl) as `polycal run` does (docs/FORMAT.md §7.6).

The instruments are `polycal sim-lab`'s (the `polycal` on PATH): two simulated ELCOMAT
3000 autocollimators and an SMC100 rotary table on pseudo-terminals, spoken to with their
own commands (docs/FORMAT.md §7.1, §7.2): pyserial does the input and output, polycal's
wire rules decide what to send and which reply to take (§7.7). A 12-face polygon, two cycles with the closing
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


class Port:
    """One instrument's serial line, owned by this program: pyserial reads and writes, and
    polycal's wire rules (`polycal.AcWire`, `polycal.TableWire`, docs/FORMAT.md §7.7)
    decide what is sent, which reply is taken and what is retried — input drained before
    every query, a reply taken only alone, the device brought back in step after a late
    one, a move sent once and watched until the table is ready. Every line sent and
    received goes to the run's traffic log."""

    def __init__(self, session, device, path, baud, xonxoff=False):
        self.session, self.device, self.path = session, device, path
        self.line = serial.Serial(path, baud, timeout=0, xonxoff=xonxoff)
        self.buffer = b""

    def log(self, event, text):
        self.session.traffic(self.device, self.path, event, text)

    def fill(self, seconds):
        """Reads what arrives within `seconds` (at least what is already there)."""
        self.line.timeout = seconds
        first = self.line.read(1)
        if first:
            self.line.timeout = 0
            self.buffer += first + self.line.read(self.line.in_waiting or 1)

    def take_line(self):
        while True:
            ends = [i for i in (self.buffer.find(b"\r"), self.buffer.find(b"\n")) if i >= 0]
            if not ends:
                return None
            end = min(ends)
            line, self.buffer = self.buffer[:end], self.buffer[end + 1:]
            if line:
                return line.decode("ascii", "replace")

    def read_line(self, seconds):
        deadline = time.monotonic() + seconds
        while (line := self.take_line()) is None:
            left = deadline - time.monotonic()
            if left <= 0:
                return None
            self.fill(left)
        return line

    def drain(self):
        """Everything that arrived and was not read, a line not yet ended included."""
        self.fill(0)
        lines = []
        while (line := self.take_line()) is not None:
            lines.append(line)
        if self.buffer:
            lines.append(self.buffer.decode("ascii", "replace"))
            self.buffer = b""
        return lines

    def carry_out(self, wire):
        """Carries out the wire rules' actions until the operation is done; its outcome
        (a `polycal.PolycalError` naming the port when the instrument failed)."""
        while True:
            now, action = self.session.now, wire.poll()
            if action.kind == "done":
                return wire.outcome()
            if action.kind in ("drain", "await_input"):
                if action.kind == "await_input":
                    self.fill(action.seconds)
                lines = self.drain()
                for line in lines:
                    self.log("discarded", line)
                wire.tell(now(), "drained" if action.kind == "drain" else "input", lines=lines)
            elif action.kind == "clear":
                self.line.reset_input_buffer()
                self.buffer = b""
                self.log("clear", "")
                wire.tell(now(), "cleared")
            elif action.kind == "send":
                self.log("sent", action.text)
                self.line.write(action.text.encode("ascii"))
                wire.tell(now(), "sent")
            elif action.kind == "read_line":
                line = self.read_line(action.seconds)
                if line is None:
                    self.log("timeout", f"no complete reply within {action.seconds * 1000:.0f} ms")
                else:
                    self.log("received", line)
                wire.tell(now(), "line", line=line)
            elif action.kind == "wait":
                time.sleep(action.seconds)
                wire.tell(now(), "waited")
            elif action.kind == "note":
                self.log(action.event, action.text)


class Elcomat(Port):
    """A Möller-Wedel ELCOMAT 3000, as the bundled profile `elcomat3000` describes it."""

    def __init__(self, session, device, path):
        super().__init__(session, device, path, 19200)
        # a reply is watched for a line behind it for two replies' time on the line
        self.wire = polycal.AcWire(path, "elcomat3000", alone_wait=0.047)
        self.do("start")

    def do(self, op):
        self.wire.begin(op)
        return self.carry_out(self.wire)

    def identify(self):
        return self.do("identify")

    def measure(self):
        return self.do("measure")


class Smc100(Port):
    """A Newport SMC100, address 1, as the bundled profile `smc100` describes it."""

    def __init__(self, session, path):
        super().__init__(session, "table", path, 57600, xonxoff=True)
        self.wire = polycal.TableWire(path, "smc100", alone_wait=0.026, motion_timeout=60.0)

    def do(self, op, deg=None):
        self.wire.begin(op, deg)
        return self.carry_out(self.wire)

    def start(self):
        self.do("start")  # homed with `1OR` when `1TS` says it is not referenced

    def identify(self):
        return self.do("identify")

    def move(self, deg):
        return self.do("move", deg)

    def position(self):
        return self.do("position")

    def stop(self):
        self.do("stop")


def new_run_dir():
    """A new directory under out/ each run: never one that holds a run already."""
    base = Path("out") / datetime.now().strftime("own-instruments-%Y%m%d-%H%M%S")
    run_dir, n = base, 1
    while run_dir.exists():
        run_dir, n = Path(f"{base}-{n}"), n + 1
    return run_dir


FAILURES = (polycal.PolycalError, serial.SerialException)


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
