#!/usr/bin/env python3
"""Dense least-squares peer of `polycal solve`: what a lab would write in an afternoon.

    python3 benches/peers/dense_lsq.py FILE.csv [--faces N] [--sigma S] [--covariance-out C.npy]

An independent implementation of the model of docs/FORMAT.md §1, with plain numpy dense
linear algebra (no code shared with polycal):

    reading = α[step mod N] + φ[face] + U[setup, ac] + noise,   Σα = 0,  φ[N] = 0 (Σβ = 0)

The constraints are eliminated by parametrisation: the free parameters are
φ[1..N−1] (φ[N] = 0), α[0..N−2] (α[N−1] = −Σ of the others) and one U per
(setup, ac) stream — 2N − 2 + K columns, so dof = readings − (2N − 2 + K). The
design matrix X is built dense, the normal matrix XᵀX is factorised by Cholesky
(which also refuses a design that does not determine every parameter) and inverted;
θ = (XᵀX)⁻¹ Xᵀy, refined once with the residual (the normal equations square the
condition number of X, which grows like N²: the refinement brings the estimates from
~1e-8″ to ~1e-12″ of an SVD solution at N = 1440 for two matrix-vector products).
The covariance of the full vector [β (N), α (N), U (K)] is
σ²·T (XᵀX)⁻¹ Tᵀ, with T the linear map from the free parameters (β[f] = φ[f] − φ[f−1]);
T is applied with np.diff and sums instead of a dense product.

σ is the residual RMS √(RSS/dof) when dof > 0, else `--sigma` (else unknown: every u
is null). The JSON on standard output has the field names of `polycal solve --format
json` (docs/FORMAT.md §5.1): faces, readings, dof, residual_rms, pitch_deviation(_u),
face_deviation(_u), encoder_error(_u), setup_error [{setup, ac, value, u}], sigma,
sigma_source. `--covariance-out` writes the full covariance matrix (order β, α, U) as
a .npy file.

Input (docs/FORMAT.md §2): UTF-8 CSV, `#` comment lines and blank lines before the
header, columns by header name. Used: cycle, step, ac, face, reading and `setup`
(optional, empty or absent = 1). The format has no exclusion/status column: every row
is a reading. `direction`, `time` and the other optional columns are not part of the
base model and are ignored. Validation is minimal (a peer, not a second polycal).
"""

import argparse
import csv
import io
import json
import sys

import numpy as np

REQUIRED = ("cycle", "step", "ac", "face", "reading")


def read_measurements(path):
    """Returns (setup, step, ac, face, reading) as numpy arrays, one entry per reading."""
    with open(path, encoding="utf-8-sig", newline="") as f:
        text = f.read()
    lines = text.splitlines()
    start = 0
    while start < len(lines) and (lines[start].startswith("#") or not lines[start].strip()):
        start += 1
    rows = [r for r in csv.reader(io.StringIO("\n".join(lines[start:]))) if any(r)]
    if not rows:
        sys.exit(f"error: {path}: no header")
    header, data = rows[0], rows[1:]
    missing = [c for c in REQUIRED if c not in header]
    if missing:
        sys.exit(f"error: {path}: missing columns {missing}")
    if not data:
        sys.exit(f"error: {path}: no readings")
    col = {name: header.index(name) for name in header}

    def ints(name, default=None):
        if name not in col:
            return np.full(len(data), default, dtype=np.int64)
        i = col[name]
        return np.array([int(r[i]) if r[i] != "" else default for r in data], dtype=np.int64)

    reading = np.array([float(r[col["reading"]]) for r in data])
    return ints("setup", 1), ints("step"), ints("ac"), ints("face"), reading


def solve(setup, step, ac, face, y, faces=None, stated_sigma=None):
    n = int(faces) if faces else int(face.max())
    m = len(y)
    if n < 3 or face.min() < 1 or face.max() > n or step.min() < 0 or step.max() > n:
        sys.exit(f"error: faces must be 1..N and steps 0..N with N = {n} >= 3")
    streams = sorted(set(zip(setup.tolist(), ac.tolist())))
    k = len(streams)
    stream_of = {s: i for i, s in enumerate(streams)}
    stream = np.array([stream_of[s] for s in zip(setup.tolist(), ac.tolist())])

    # free parameters: φ[1..N−1] | α[0..N−2] | U[0..K−1]
    p = 2 * n - 2 + k
    a0, u0 = n - 1, 2 * n - 2
    rows = np.arange(m)
    x = np.zeros((m, p))
    f = face - 1  # φ[face], 0-based column; φ[N] = 0 has no column
    x[rows[f < n - 1], f[f < n - 1]] = 1.0
    q = step % n  # α[step mod N]; α[N−1] = −(α[0] + … + α[N−2])
    x[rows[q < n - 1], a0 + q[q < n - 1]] = 1.0
    x[np.ix_(rows[q == n - 1], np.arange(a0, u0))] = -1.0
    x[rows, u0 + stream] = 1.0

    normal = x.T @ x
    try:
        np.linalg.cholesky(normal)
    except np.linalg.LinAlgError:
        sys.exit("error: the design does not determine every β, α and U (XᵀX is singular)")
    cofactor_free = np.linalg.inv(normal)
    theta = cofactor_free @ (x.T @ y)
    residual = y - x @ theta
    # one step of iterative refinement: the normal equations square the condition
    # number of X (~N² for this model), which costs ~1e-8″ at N = 1440 without it
    theta += cofactor_free @ (x.T @ residual)
    residual = y - x @ theta
    rss = float(residual @ residual)
    dof = m - p
    del x, normal

    residual_rms = float(np.sqrt(rss / dof)) if dof > 0 else None
    if dof > 0:
        sigma, source = residual_rms, "residual"
    elif stated_sigma is not None:
        sigma, source = float(stated_sigma), "stated"
    else:
        sigma, source = None, None

    # full vector [β (N), α (N), U (K)] = T θ, applied along an axis
    def expand(a, axis):
        a = np.moveaxis(a, axis, 0)
        phi = a[:a0]
        zero = np.zeros((1,) + a.shape[1:])
        beta = np.diff(phi, axis=0, prepend=zero, append=zero)
        alpha = np.concatenate([a[a0:u0], -a[a0:u0].sum(axis=0, keepdims=True)])
        return np.moveaxis(np.concatenate([beta, alpha, a[u0:]]), 0, axis)

    full = expand(theta, 0)
    cofactor = expand(expand(cofactor_free, 0), 1)
    beta, alpha, u_setup = full[:n], full[n : 2 * n], full[2 * n :]
    phi = np.append(theta[:a0], 0.0)
    var_phi = np.append(np.diag(cofactor_free)[:a0], 0.0)
    result = {
        "faces": n,
        "readings": m,
        "dof": dof,
        "residual_rms": residual_rms,
        "pitch_deviation": beta.tolist(),
        "pitch_deviation_u": None,
        "face_deviation": phi.tolist(),
        "face_deviation_u": None,
        "encoder_error": alpha.tolist(),
        "encoder_error_u": None,
        "setup_error": [
            {"setup": s, "ac": a, "value": float(v), "u": None}
            for (s, a), v in zip(streams, u_setup)
        ],
        "sigma": sigma,
        "sigma_source": source,
    }
    covariance = None
    if sigma is not None:
        covariance = sigma**2 * cofactor
        u = np.sqrt(np.diag(covariance))
        result["pitch_deviation_u"] = u[:n].tolist()
        result["face_deviation_u"] = (sigma * np.sqrt(var_phi)).tolist()
        result["encoder_error_u"] = u[n : 2 * n].tolist()
        for entry, ui in zip(result["setup_error"], u[2 * n :]):
            entry["u"] = float(ui)
    return result, covariance


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("file")
    parser.add_argument("--faces", type=int, help="N (default: the largest face)")
    parser.add_argument("--sigma", type=float, help="σ of one reading, used when dof = 0")
    parser.add_argument("--covariance-out", help="write the covariance (β, α, U) as .npy")
    args = parser.parse_args()
    result, covariance = solve(*read_measurements(args.file), args.faces, args.sigma)
    if args.covariance_out and covariance is not None:
        np.save(args.covariance_out, covariance)
    json.dump(result, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
