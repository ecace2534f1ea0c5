#!/usr/bin/env python3
"""Sparse least-squares peer of `polycal solve`: what a lab would write in an afternoon.

    python3 benches/peers/sparse_lsq.py FILE.csv [--faces N] [--sigma S] [--block B]

An independent implementation of the model of docs/FORMAT.md §1 with scipy.sparse (no
code shared with polycal, nor with the dense peer dense_lsq.py beside it):

    reading = α[step mod N] + φ[face] + U[setup, ac] + noise,   Σα = 0,  φ[N] = 0 (Σβ = 0)

Parameters and gauge. The dense peer eliminates Σα = 0 by α[N−1] = −Σ of the others,
which puts N − 1 entries into the design-matrix row of every reading at step N − 1 and
makes the α block of the normal matrix dense. Σα = 0 is a pure gauge (the readings see
only α + U: adding c to every α and −c to every U changes no reading), so this peer fixes
the gauge by α[N−1] = 0 instead and moves to Σα = 0 afterwards, exactly:

    α = α° − ᾱ°,   U = U° + ᾱ°,   ᾱ° = (α°[0] + … + α°[N−2]) / N,

with ° the estimates in the gauge α°[N−1] = 0 (φ does not depend on that gauge). φ[N] = 0
is imposed by leaving φ[N] out. The free parameters are

    θ = φ[1..N−1] | α°[0..N−2] | U°[0..K−1]      (2N − 2 + K, as the dense peer's)

and every reading has at most three non-zeros, φ[face], α°[step mod N] and U°[stream]:
X is built from vectorised COO triplets as CSR, and A = XᵀX is sparse. The model is
written in φ rather than β on purpose: u(φ) is then a diagonal entry of the cofactor,
not the variance of a partial sum of β (the whole β block of the covariance).

Solving. Every reading has exactly one φ, so the φ block of A is diagonal (D: how often
each face is read). With A = [[D, B], [Bᵀ, C]] the peer eliminates φ (the reduced normal
equations of bundle adjustment): S = C − BᵀD⁻¹B, of order N − 1 + K, symmetric positive
definite and as sparse as the autocollimators' face offsets make it (tridiagonal and
cyclic for two adjacent ones, plus K dense rows for U). S is factorised once with
SuperLU (scipy.sparse.linalg.splu) in its symmetric mode (minimum-degree ordering of
Sᵀ + S, pivots on the diagonal: what an SPD matrix calls for); then

    S θc = rc − Wᵀ rφ,   θφ = D⁻¹ (rφ − B θc),   W = D⁻¹B,

for θ = A⁻¹ Xᵀy, refined once with the residual (the normal equations square the
condition number of X, which grows like N²). A design that does not determine every
parameter (a lost harmonic, an unread face or step) makes S singular: SuperLU finds an
exactly zero pivot, or a pivot falls below 1e-10 of S's largest diagonal entry (a sound
design's smallest falls like 1/N²: 1.5e-7 at N = 5760), and the peer refuses it.

Uncertainties. The cofactor Q = A⁻¹ is never formed; what the results need from it is

    Q_cc = S⁻¹,   Q_φφ = D⁻¹ + W S⁻¹ Wᵀ,

- u(φ[f])² = σ² Q_φφ[f, f];
- u(β[f])² = σ² (Q_φφ[f, f] + Q_φφ[f−1, f−1] − 2 Q_φφ[f−1, f]), from β[f] = φ[f] − φ[f−1]
  with φ[0] = φ[N] = 0: the diagonal and the first super-diagonal of Q_φφ;
- u(α[q])² = σ² (S⁻¹[q, q] − 2 h[q] + v) and u(α[N−1])² = σ² v,
  u(U[k])² = σ² (S⁻¹[k, k] + 2 h[k] + v), with h = S⁻¹g, g = 1/N on every α°, v = gᵀh:
  the gauge move above.

S⁻¹ is solved a block of --block columns at a time with the one factorisation (S Z =
I[:, J], never the whole inverse); from each block the peer keeps diag(S⁻¹)[J] and adds
its share of diag(W S⁻¹ Wᵀ) and of the super-diagonal, Σ_{k∈J} W[f, k] (W Z)[f, k] and
Σ_{k∈J} W[f, k] (W Z)[f−1, k] (vectorised over W's non-zeros). That is N − 1 + K
triangular solves of order N − 1 + K in all, and memory O(N·block) beyond the factors.
SuperLU's multi-column solve is limited by the cache: small blocks are fastest (32 by
default; at N = 5760 the whole run takes three times as long with 256 at a time).

σ is the residual RMS √(RSS/dof) when dof > 0, else `--sigma` (else unknown: every u is
null). The JSON on standard output has the field names of `polycal solve --format json`
(docs/FORMAT.md §5.1): faces, readings, dof, residual_rms, pitch_deviation(_u),
face_deviation(_u), encoder_error(_u), setup_error [{setup, ac, value, u}], sigma,
sigma_source.

Input (docs/FORMAT.md §2): UTF-8 CSV, `#` comment lines and blank lines before the
header, columns by header name. Used: step, ac, face, reading and `setup` (optional,
empty or absent = 1); `cycle` must be present. Every row is a reading; `direction`,
`time`, `shift` and the other optional columns are not part of the base model and are
ignored. Validation is minimal (a peer, not a second polycal).
"""

import argparse
import csv
import io
import json
import sys

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

REQUIRED = ("cycle", "step", "ac", "face", "reading")


def read_measurements(path):
    """Returns (setup, step, ac, face, reading) as numpy arrays, one entry per reading."""
    with open(path, encoding="utf-8-sig", newline="") as f:
        lines = f.read().splitlines()
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
    if any(len(r) != len(header) for r in data):
        sys.exit(f"error: {path}: a row does not have as many fields as the header")
    columns = list(zip(*data))  # one tuple of strings per column
    col = {name: columns[i] for i, name in enumerate(header)}

    def ints(name, default=None):
        if name not in col:
            return np.full(len(data), default, dtype=np.int64)
        return np.array([int(v) if v != "" else default for v in col[name]], dtype=np.int64)

    reading = np.array(col["reading"], dtype=float)
    return ints("setup", 1), ints("step"), ints("ac"), ints("face"), reading


def design(step, ac, setup, face, n):
    """The sparse design matrix X (CSR) and the streams [(setup, ac)] of its U columns."""
    m = len(face)
    streams, stream = np.unique(np.stack([setup, ac], axis=1), axis=0, return_inverse=True)
    stream = stream.reshape(-1)
    k = len(streams)
    a0, u0 = n - 1, 2 * n - 2  # first α° column, first U° column
    f = face - 1  # φ[face] is column face − 1; φ[N] = 0 has no column
    q = step % n  # α°[q] is column a0 + q; α°[N−1] = 0 has no column
    rows = np.arange(m)
    has_phi, has_alpha = f < n - 1, q < n - 1
    i = np.concatenate([rows[has_phi], rows[has_alpha], rows])
    j = np.concatenate([f[has_phi], a0 + q[has_alpha], u0 + stream])
    x = sp.csr_matrix((np.ones(len(i)), (i, j)), shape=(m, u0 + k))
    return x, [(int(s), int(a)) for s, a in streams]


def reduce_phi(a, nphi):
    """Splits A = [[D, B], [Bᵀ, C]] (D diagonal: the φ block) and reduces it to φ's Schur
    complement S = C − Bᵀ D⁻¹ B. Returns (d, B, W = D⁻¹B, S), all sparse but d."""
    d = a[:nphi, :nphi].diagonal()  # the φ block is diagonal: one φ per reading
    if np.any(d <= 0):
        sys.exit("error: every face 1..N must be read")
    b = a[:nphi, nphi:].tocsr()
    w = sp.diags(1.0 / d) @ b
    s = (a[nphi:, nphi:] - b.T @ w).tocsc()
    return d, b, w.tocsr(), s


def cofactor_bands(lu, d, w, r, block):
    """diag(Q_φφ), its super-diagonal (entry f: Q_φφ[f−1, f]; entry 0 unused) and
    diag(Q_cc) = diag(S⁻¹), with Q_φφ = D⁻¹ + W S⁻¹ Wᵀ, S⁻¹ solved in column blocks."""
    nphi = w.shape[0]
    q_c = np.empty(r)
    extra = np.zeros(nphi)  # diag(W S⁻¹ Wᵀ)
    extra_up = np.zeros(nphi)  # (W S⁻¹ Wᵀ)[f − 1, f]
    wc = w.tocsc()
    for j0 in range(0, r, block):
        j1 = min(r, j0 + block)
        cols = np.arange(j0, j1)
        rhs = np.zeros((r, j1 - j0))
        rhs[cols, cols - j0] = 1.0
        z = lu.solve(rhs)
        q_c[cols] = z[cols, cols - j0]
        t = w @ z  # (W S⁻¹)[:, J]
        wj = wc[:, j0:j1].tocoo()  # W[:, J]: its rows f, block columns k and values
        extra += np.bincount(wj.row, wj.data * t[wj.row, wj.col], minlength=nphi)
        up = wj.row > 0
        extra_up += np.bincount(
            wj.row[up], wj.data[up] * t[wj.row[up] - 1, wj.col[up]], minlength=nphi
        )
    return 1.0 / d + extra, extra_up, q_c


def solve(setup, step, ac, face, y, faces=None, stated_sigma=None, block=32):
    """The fit of the readings y: the JSON object of `polycal solve --format json`."""
    n = int(faces) if faces else int(face.max())
    m = len(y)
    if n < 3 or face.min() < 1 or face.max() > n or step.min() < 0 or step.max() > n:
        sys.exit(f"error: faces must be 1..N and steps 0..N with N = {n} >= 3")
    x, streams = design(step, ac, setup, face, n)
    k = len(streams)
    nphi = n - 1  # φ[1..N−1]; the reduced unknowns c = α°[0..N−2] | U°[0..K−1]
    r = n - 1 + k
    p = nphi + r
    xt = x.T.tocsr()
    d, b, w, s = reduce_phi((xt @ x).tocsr(), nphi)

    refused = "error: the design does not determine every β, α and U (XᵀX is singular)"
    try:
        # S is symmetric positive definite: a symmetric ordering and pivots on the diagonal
        lu = spla.splu(s, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError:
        sys.exit(refused)
    # the pivots of an SPD matrix are positive; a lost harmonic makes one (nearly) zero
    pivots = lu.U.diagonal()
    if not np.all(pivots > 1e-10 * np.abs(s.diagonal()).max()):
        sys.exit(refused)

    def normal_solve(rhs):
        """θ = A⁻¹ rhs through the reduced system: S θc = rc − Wᵀ rφ, θφ = (rφ − B θc)/d."""
        tc = lu.solve(rhs[nphi:] - w.T @ rhs[:nphi])
        return np.concatenate([(rhs[:nphi] - b @ tc) / d, tc])

    theta = normal_solve(xt @ y)
    residual = y - x @ theta
    # one step of iterative refinement (the normal equations square the condition number)
    theta += normal_solve(xt @ residual)
    residual = y - x @ theta
    rss = float(residual @ residual)
    dof = m - p

    residual_rms = float(np.sqrt(rss / dof)) if dof > 0 else None
    if dof > 0:
        sigma, source = residual_rms, "residual"
    elif stated_sigma is not None:
        sigma, source = float(stated_sigma), "stated"
    else:
        sigma, source = None, None

    # estimates: φ as fitted; the gauge α°[N−1] = 0 moved to Σα = 0
    a0, u0 = nphi, nphi + n - 1
    phi = np.append(theta[:a0], 0.0)
    beta = np.diff(phi, prepend=0.0)
    alpha_mean = theta[a0:u0].sum() / n
    alpha = np.append(theta[a0:u0], 0.0) - alpha_mean
    u_setup = theta[u0:] + alpha_mean
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
    if sigma is None:
        return result

    q_phi, q_phi_up, q_c = cofactor_bands(lu, d, w, r, block)
    # h = Q g with g = 1/N on every α°: only its reduced part is needed, h_c = S⁻¹ g_c
    g = np.zeros(r)
    g[: n - 1] = 1.0 / n
    h = lu.solve(g)
    v = float(g @ h)
    # φ: the diagonal of the φ block; β[f] = φ[f] − φ[f−1] with φ[0] = φ[N] = 0
    var_phi = np.append(q_phi, 0.0)
    var_beta = var_phi + np.concatenate([[0.0], var_phi[:-1]])
    var_beta[1:nphi] -= 2.0 * q_phi_up[1:]
    var_alpha = np.append(q_c[: n - 1] - 2.0 * h[: n - 1] + v, v)
    var_setup = q_c[n - 1 :] + 2.0 * h[n - 1 :] + v
    s2 = sigma * sigma
    result["pitch_deviation_u"] = np.sqrt(s2 * np.maximum(var_beta, 0.0)).tolist()
    result["face_deviation_u"] = np.sqrt(s2 * np.maximum(var_phi, 0.0)).tolist()
    result["encoder_error_u"] = np.sqrt(s2 * np.maximum(var_alpha, 0.0)).tolist()
    for entry, var in zip(result["setup_error"], var_setup):
        entry["u"] = float(np.sqrt(s2 * max(var, 0.0)))
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("file")
    parser.add_argument("--faces", type=int, help="N (default: the largest face)")
    parser.add_argument("--sigma", type=float, help="σ of one reading, used when dof = 0")
    parser.add_argument("--block", type=int, default=32,
                        help="columns of S⁻¹ solved at a time (default 32)")
    args = parser.parse_args()
    result = solve(*read_measurements(args.file), args.faces, args.sigma, args.block)
    json.dump(result, sys.stdout)
    sys.stdout.write("\n")


if __name__ == "__main__":
    main()
