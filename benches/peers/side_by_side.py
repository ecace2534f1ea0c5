#!/usr/bin/env python3
"""polycal against its two least-squares peers, side by side (speed and agreement).

    cargo build --release
    python3 -m pip install --user -r benches/peers/requirements.txt
    python3 benches/peers/side_by_side.py [--polycal target/release/polycal] [--runs 5]
                                          [--faces 360,1440,5760] [--dense-max-faces N]
                                          [--slow S] [--peer-threads T] [--keep DIR]

For every design (N faces × 6 cycles with closing readings, two adjacent
autocollimators) it simulates the file with

    polycal simulate --faces N --cycles 6 --closing --seed 1 --out FILE -q

then runs `polycal solve FILE --format json` and both peers, `python3 dense_lsq.py FILE`
(dense numpy) and `python3 sparse_lsq.py FILE` (scipy.sparse), as whole processes, --runs
times each (median wall time; parsing, start-up and JSON output included; a program whose
first run takes longer than --slow seconds is run only once). It checks that each peer
gives polycal's estimates and standard uncertainties (pitch_deviation, face_deviation,
encoder_error, setup errors and their u, dof, residual_rms) to an ABSOLUTE tolerance of
--tol arcsec (default 1e-6″; the largest relative difference is printed too), and prints
a table: design, readings, polycal s, then one line per peer: its s, runs, the ratio
peer/polycal and the largest differences.

The dense peer is skipped, with the reason on its line, for a design with more than
--dense-max-faces faces (default: no limit; it is O(N³) work) or one that would need
more than --mem-fraction of the available memory (MemAvailable of /proc/meminfo; it
holds the readings × (2N − 2 + K) design matrix and a few (2N + K)² matrices: ~10 GiB at
N = 5760). The sparse peer needs O(N) memory and always runs. Standard library only.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PEERS = (("dense", os.path.join(HERE, "dense_lsq.py")),
         ("sparse", os.path.join(HERE, "sparse_lsq.py")))
VECTORS = ("pitch_deviation", "face_deviation", "encoder_error")


def available_bytes():
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    return None


def peer_bytes(faces, cycles=6, autocollimators=2):
    readings = cycles * (faces + 1) * autocollimators
    params = 2 * faces - 2 + autocollimators
    full = 2 * faces + autocollimators
    # X, XᵀX and its inverse, the expanded covariance (twice, while it is built)
    return 8 * (readings * params + 2 * params * params + 2 * full * full)


def timed(cmd, runs, slow=None, env=None):
    """Median wall time of `runs` runs (one only when the first takes longer than `slow`
    seconds), the number of runs made and the JSON of the last."""
    times, out = [], None
    for _ in range(runs):
        start = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, env=env)
        times.append(time.perf_counter() - start)
        if done.returncode != 0:
            sys.exit(f"{' '.join(cmd)} failed ({done.returncode}): {done.stderr.strip()}")
        out = done.stdout
        if slow is not None and times[0] > slow:
            break
    return statistics.median(times), len(times), json.loads(out)


def pairs(a, b):
    """(name, polycal value, peer value) for every compared number."""
    yield "dof", a["dof"], b["dof"]
    yield "residual_rms", a["residual_rms"], b["residual_rms"]
    for name in VECTORS:
        for suffix in ("", "_u"):
            key = name + suffix
            va, vb = a[key], b[key]
            if va is None or vb is None:
                yield key, va, vb
                continue
            if len(va) != len(vb):
                yield key + " length", len(va), len(vb)
                continue
            for x, y in zip(va, vb):
                yield key, x, y
    sa, sb = a["setup_error"], b["setup_error"]
    if len(sa) != len(sb):
        yield "setup_error length", len(sa), len(sb)
        return
    for x, y in zip(sa, sb):
        if (x["setup"], x["ac"]) != (y["setup"], y["ac"]):
            yield "setup_error stream", str((x["setup"], x["ac"])), str((y["setup"], y["ac"]))
        yield "setup_error", x["value"], y["value"]
        yield "setup_error_u", x["u"], y["u"]


def compare(a, b, tol):
    """Largest absolute difference of estimates and of u, largest relative, failures."""
    worst = {"estimate": 0.0, "u": 0.0, "relative": 0.0}
    failures = []
    for name, x, y in pairs(a, b):
        if isinstance(x, str) or x is None or y is None:
            if x != y:
                failures.append(f"{name}: {x} vs {y}")
            continue
        d = abs(x - y)
        family = "u" if name.endswith("_u") or name == "residual_rms" else "estimate"
        worst[family] = max(worst[family], d)
        scale = max(abs(x), abs(y))
        if scale > 0:
            worst["relative"] = max(worst["relative"], d / scale)
        if d > tol:
            failures.append(f"{name}: {x!r} vs {y!r} (|Δ| = {d:.3g})")
    return worst, failures


def dense_skip_reason(faces, cycles, args, avail):
    """Why the dense peer does not run on this design, or None."""
    if args.dense_max_faces is not None and faces > args.dense_max_faces:
        return f"skipped: more than --dense-max-faces {args.dense_max_faces} faces"
    need = peer_bytes(faces, cycles)
    if avail is not None and need > args.mem_fraction * avail:
        return (
            f"skipped: needs ~{need / 2**30:.1f} GiB, more than {args.mem_fraction:g} of the "
            f"{avail / 2**30:.1f} GiB available"
        )
    return None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--polycal", default="target/release/polycal")
    parser.add_argument("--python", default=sys.executable, help="interpreter for the peers")
    parser.add_argument("--faces", default="360,1440,5760", help="comma-separated N")
    parser.add_argument("--cycles", type=int, default=6)
    parser.add_argument("--runs", type=int, default=5, help="runs per program (median)")
    parser.add_argument(
        "--slow",
        type=float,
        default=60.0,
        help="a program whose first run takes longer than this (s) is run once (default 60)",
    )
    parser.add_argument("--tol", type=float, default=1e-6, help="absolute tolerance, arcsec")
    parser.add_argument(
        "--mem-fraction",
        type=float,
        default=0.6,
        help="skip the dense peer where it needs more than this fraction of MemAvailable",
    )
    parser.add_argument(
        "--dense-max-faces",
        type=int,
        help="skip the dense peer above this many faces (default: no limit)",
    )
    parser.add_argument(
        "--peer-threads",
        type=int,
        help="OPENBLAS_NUM_THREADS/OMP_NUM_THREADS for the peers (default: numpy's own)",
    )
    parser.add_argument("--keep", help="directory for the simulated files (default: temporary)")
    args = parser.parse_args()
    if not os.path.exists(args.polycal):
        sys.exit(f"{args.polycal} not found: run `cargo build --release` or give --polycal")

    workdir = args.keep or tempfile.mkdtemp(prefix="polycal-peer-")
    os.makedirs(workdir, exist_ok=True)
    avail = available_bytes()
    peer_env = None
    if args.peer_threads:
        peer_env = dict(os.environ)
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            peer_env[name] = str(args.peer_threads)
    header = (
        f"{'design':<24} {'readings':>8} {'polycal s':>9}  {'peer':<6} {'peer s':>8} {'runs':>4}"
        f" {'peer/polycal':>12} {'max|Δ| est':>10} {'max|Δ| u':>9} {'max rel':>8}  agree"
    )
    threads = args.peer_threads or "numpy's default"
    limit = args.dense_max_faces if args.dense_max_faces is not None else "none"
    print(
        f"median of {args.runs} whole-process runs each (1 when the first takes > {args.slow:g} s);"
        f" peer BLAS threads: {threads}; agreement: absolute {args.tol:g}″;"
        f" dense peer: --dense-max-faces {limit}, --mem-fraction {args.mem_fraction:g}"
    )
    print(header)
    print("-" * len(header))
    failed = False
    for faces in (int(x) for x in args.faces.split(",")):
        design = f"{faces} faces x {args.cycles} closing"
        path = os.path.join(workdir, f"n{faces}.csv")
        subprocess.run(
            [args.polycal, "simulate", "--faces", str(faces), "--cycles", str(args.cycles),
             "--closing", "--seed", "1", "--out", path, "-q"],
            check=True,
        )
        t_polycal, _, a = timed(
            [args.polycal, "solve", path, "--format", "json"], args.runs, args.slow
        )
        lead = f"{design:<24} {a['readings']:>8} {t_polycal:>9.4f}"
        for name, script in PEERS:
            skip = dense_skip_reason(faces, args.cycles, args, avail) if name == "dense" else None
            if skip:
                print(f"{lead}  {name:<6} {skip}", flush=True)
                lead = " " * len(lead)
                continue
            t_peer, n_peer, b = timed([args.python, script, path], args.runs, args.slow, peer_env)
            worst, failures = compare(a, b, args.tol)
            ok = not failures
            failed |= not ok
            print(
                f"{lead}  {name:<6} {t_peer:>8.3f} {n_peer:>4} {t_peer / t_polycal:>12.1f}"
                f" {worst['estimate']:>10.2e} {worst['u']:>9.2e} {worst['relative']:>8.1e}"
                f"  {'yes' if ok else 'NO'}",
                flush=True,
            )
            lead = " " * len(lead)
            for line in failures[:10]:
                print(f"    {name}: {line}")
    if not args.keep:
        for name in os.listdir(workdir):
            os.remove(os.path.join(workdir, name))
        os.rmdir(workdir)
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
