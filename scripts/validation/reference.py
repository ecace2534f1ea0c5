#!/usr/bin/env python3
"""Reference results for `polycal validate`, computed without polycal.

Writes examples/validation/<case>/: the case's input files, `case.toml` (what the case
runs, its tolerance and the reason for it) and `reference.json` (the reference values,
named as the command's JSON names them).

Independence: this program imports nothing of polycal and calls no polycal program. It
implements the model of docs/FORMAT.md §1 (reading = α[position] + φ[face] + U[setup, ac]
+ noise, Σα = 0 within each coset of table angles, φ[N] = 0), the self-calibration model of
§9.2, the budget of §5.3 (GUM), the comparison of §5.4 and the weighted mean of §12, in
exact rational arithmetic (fractions.Fraction: least squares by Gauss–Jordan on the normal
equations); square roots and Student's t quantiles in decimal arithmetic with 50 digits.
Python's standard library only.

Deterministic: the inputs are drawn with seeded `random.Random` and rounded to 0.001″ (exact
decimals), and nothing depends on the clock, so rerunning it reproduces the committed bytes:

    python3 scripts/validation/reference.py            # rewrite examples/validation/
    python3 scripts/validation/reference.py --check    # status 1 when a byte would change
"""

import hashlib
import json
import os
import random
import sys
from decimal import Decimal, getcontext
from fractions import Fraction as F

GENERATOR = "scripts/validation/reference.py"
GENERATOR_VERSION = "1"
# The day this version of the generator was written: stated in every reference file
# instead of the day it ran, so that a rerun reproduces the committed bytes.
GENERATOR_DATE = "2025-06-01"
getcontext().prec = 50
ROOT = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
OUT = os.path.join(ROOT, "examples", "validation")
EXACT = 1e-12
EXACT_REASON = (
    "the reference is exact (rational arithmetic; square roots to 50 digits); 1e-12 of the "
    "largest value of each list leaves room for the rounding of double precision "
    "(about 1e-16 per operation) amplified by the design's condition, and nothing more"
)


# ---------------------------------------------------------------- exact arithmetic

def dsqrt(x):
    """√x of a Fraction ≥ 0, to 50 digits, as a float (correctly rounded from 50 digits)."""
    if x < 0:
        raise ValueError("negative")
    return float((Decimal(x.numerator) / Decimal(x.denominator)).sqrt())


def invert(a):
    """The inverse of the square Fraction matrix a (Gauss–Jordan, exact)."""
    n = len(a)
    m = [row[:] + [F(int(i == j)) for j in range(n)] for i, row in enumerate(a)]
    for c in range(n):
        p = next(r for r in range(c, n) if m[r][c] != 0)
        m[c], m[p] = m[p], m[c]
        piv = m[c][c]
        m[c] = [v / piv for v in m[c]]
        for r in range(n):
            if r != c and m[r][c] != 0:
                f = m[r][c]
                mr, mc = m[r], m[c]
                m[r] = [x - f * y for x, y in zip(mr, mc)]
    return [row[n:] for row in m]


class Lsq:
    """Exact least squares: rows are ({parameter: coefficient}, y)."""

    def __init__(self, params, rows):
        self.params = list(params)
        index = {p: i for i, p in enumerate(self.params)}
        n = len(self.params)
        a = [[F(0)] * n for _ in range(n)]
        b = [F(0)] * n
        for coef, y in rows:
            items = [(index[p], c) for p, c in coef.items() if c != 0]
            for i, ci in items:
                b[i] += ci * y
                for j, cj in items:
                    a[i][j] += ci * cj
        self.q = invert(a)
        self.theta = [sum(qi[j] * b[j] for j in range(n)) for qi in self.q]
        rss = F(0)
        for coef, y in rows:
            r = y - sum(self.theta[index[p]] * c for p, c in coef.items())
            rss += r * r
        self.index = index
        self.readings = len(rows)
        self.dof = len(rows) - n
        self.rss = rss
        self.sigma2 = rss / self.dof if self.dof > 0 else None

    def value(self, g):
        """The estimate of the linear combination g = {parameter: coefficient}."""
        return sum(self.theta[self.index[p]] * c for p, c in g.items())

    def cofactor(self, g):
        """gᵀ Q g (the variance of g's estimate per unit σ²)."""
        idx = [(self.index[p], c) for p, c in g.items() if c != 0]
        return sum(ci * cj * self.q[i][j] for i, ci in idx for j, cj in idx)

    def u(self, g):
        return dsqrt(self.sigma2 * self.cofactor(g))


def dec(x):
    """An exact decimal Fraction from a number rounded to 0.001."""
    return F(round(x * 1000), 1000)


def text3(x):
    """A Fraction with at most 3 decimals written exactly."""
    v = F(x) * 1000
    assert v.denominator == 1, x
    n = v.numerator
    s = "-" if n < 0 else ""
    n = abs(n)
    return f"{s}{n // 1000}.{n % 1000:03d}"


# ---------------------------------------------------------------- the polygon model

def draw_truth(rng, faces, positions_per_coset, cosets):
    beta = [dec(rng.uniform(-1, 1)) for _ in range(faces)]
    beta[-1] -= sum(beta)
    phi = [sum(beta[: f + 1]) for f in range(faces)]
    alpha = {}
    for c in range(cosets):
        vals = [dec(rng.uniform(-2, 2)) for _ in range(positions_per_coset)]
        vals[-1] -= sum(vals)
        alpha[c] = vals
    return phi, alpha


def polygon_set(seed, faces, offsets, cycles, setups=((1, F(0)),), closing=False,
                directions=None, noise=0.05):
    """Readings of a polygon design: each setup (number, shift in degrees), each cycle,
    each step, each autocollimator at face offset `offsets[ac-1]`."""
    rng = random.Random(seed)
    pitch = F(360, faces)
    cosets = sorted({shift % pitch for _, shift in setups})
    phi, alpha = draw_truth(rng, faces, faces, len(cosets))
    setup_err = {(s, ac): dec(rng.uniform(-5, 5)) for s, _ in setups
                 for ac in range(1, len(offsets) + 1)}
    rows = []
    for s, shift in setups:
        c = cosets.index(shift % pitch)
        m = (shift - shift % pitch) / pitch
        for cycle in range(1, cycles + 1):
            direction = (directions or ["cw"] * cycles)[cycle - 1]
            steps = list(range(faces + (1 if closing else 0)))
            if direction == "ccw":
                steps.reverse()
            for step in steps:
                pos = int((step + m) % faces)
                for ac, off in enumerate(offsets, start=1):
                    face = (step + off) % faces + 1
                    y = alpha[c][pos] + phi[face - 1] + setup_err[(s, ac)]
                    y += dec(rng.gauss(0, noise))
                    rows.append(dict(cycle=cycle, step=step, ac=ac, face=face, reading=y,
                                     direction=direction, setup=s, shift=shift, coset=c,
                                     pos=pos))
    return rows


def polygon_csv(rows, faces, with_shift, with_direction, comment):
    cols = ["cycle", "step", "ac", "face", "reading"]
    if with_direction:
        cols.append("direction")
    if with_shift:
        cols += ["setup", "shift"]
    out = [f"# {comment}", ",".join(cols)]
    for r in rows:
        vals = {"cycle": str(r["cycle"]), "step": str(r["step"]), "ac": str(r["ac"]),
                "face": str(r["face"]), "reading": text3(r["reading"]),
                "direction": r["direction"], "setup": str(r["setup"]),
                "shift": fmt_deg(r["shift"])}
        out.append(",".join(vals[c] for c in cols))
    return "\n".join(out) + "\n"


def fmt_deg(x):
    x = F(x)
    for places in range(0, 13):
        v = x * 10 ** places
        if v.denominator == 1:
            n = v.numerator
            return str(n) if places == 0 else f"{n / 10 ** places:.{places}f}"
    raise ValueError(f"{x} is not a short decimal")


def solve_polygon(rows, faces, nac):
    """The exact fit of the base model; the solve JSON's numbers."""
    pitch = F(360, faces)
    cosets = sorted({r["coset"] for r in rows})
    shifts = {r["coset"]: r["shift"] % pitch for r in rows}
    setups = sorted({r["setup"] for r in rows})
    params = [("phi", f) for f in range(1, faces)]
    for c in cosets:
        params += [("alpha", c, p) for p in range(faces - 1)]
    streams = sorted({(r["setup"], r["ac"]) for r in rows})
    params += [("U",) + s for s in streams]

    def alpha_g(c, p):
        if p < faces - 1:
            return {("alpha", c, p): F(1)}
        return {("alpha", c, q): F(-1) for q in range(faces - 1)}

    def phi_g(f):
        return {("phi", f): F(1)} if f < faces else {}

    lsq_rows = []
    for r in rows:
        g = dict(alpha_g(r["coset"], r["pos"]))
        for k, v in phi_g(r["face"]).items():
            g[k] = g.get(k, 0) + v
        g[("U", r["setup"], r["ac"])] = F(1)
        lsq_rows.append((g, r["reading"]))
    fit = Lsq(params, lsq_rows)

    def beta_g(k):
        g = dict(phi_g(k))
        for key, v in phi_g(k - 1).items() if k > 1 else []:
            g[key] = g.get(key, 0) - v
        return g

    res = {"faces": faces, "readings": fit.readings, "dof": fit.dof}
    res["residual_rms"] = dsqrt(fit.sigma2) if fit.sigma2 is not None else None
    res["pitch_deviation"] = [float(fit.value(beta_g(k))) for k in range(1, faces + 1)]
    res["face_deviation"] = [float(fit.value(phi_g(f))) for f in range(1, faces + 1)]
    enc = []
    for c in cosets:
        for p in range(faces):
            angle = (shifts[c] + p * pitch)
            enc.append((angle, alpha_g(c, p)))
    enc.sort(key=lambda e: e[0])
    res["encoder_error"] = [float(fit.value(g)) for _, g in enc]
    if fit.sigma2 is not None:
        res["pitch_deviation_u"] = [fit.u(beta_g(k)) for k in range(1, faces + 1)]
        res["face_deviation_u"] = [fit.u(phi_g(f)) if f < faces else 0.0
                                   for f in range(1, faces + 1)]
        res["encoder_error_u"] = [fit.u(g) for _, g in enc]
    if len(cosets) > 1:
        res["encoder_angle_deg"] = [float(a) for a, _ in enc]
    res["setup_error"] = []
    for s, ac in streams:
        g = {("U", s, ac): F(1)}
        entry = {"setup": s, "ac": ac, "value": float(fit.value(g))}
        if fit.sigma2 is not None:
            entry["u"] = fit.u(g)
        res["setup_error"].append(entry)
    return fit, res, {"beta": beta_g, "phi": phi_g, "enc": enc}


# ---------------------------------------------------------------- Student's t

def dln(x):
    return Decimal(x).ln()


def lgamma(z):
    """ln Γ(z), z > 0 a Decimal, by Stirling's series after shifting z above 40."""
    z = Decimal(z)
    shift = Decimal(0)
    while z < 40:
        shift += z.ln()
        z += 1
    bern = [Decimal(1) / 6, Decimal(-1) / 30, Decimal(1) / 42, Decimal(-1) / 30,
            Decimal(5) / 66, Decimal(-691) / 2730, Decimal(7) / 6, Decimal(-3617) / 510,
            Decimal(43867) / 798, Decimal(-174611) / 330]
    pi = Decimal("3.14159265358979323846264338327950288419716939937510")
    s = (z - Decimal("0.5")) * z.ln() - z + (2 * pi).ln() / 2
    for k, b in enumerate(bern, start=1):
        s += b / (2 * k * (2 * k - 1) * z ** (2 * k - 1))
    return s - shift


def betainc(a, b, x):
    """The regularized incomplete beta I_x(a, b) by its continued fraction (Lentz)."""
    a, b, x = Decimal(a), Decimal(b), Decimal(x)
    if x <= 0:
        return Decimal(0)
    if x >= 1:
        return Decimal(1)
    if x > (a + 1) / (a + b + 2):
        return 1 - betainc(b, a, 1 - x)
    front = (lgamma(a + b) - lgamma(a) - lgamma(b) + a * x.ln() + b * (1 - x).ln()).exp() / a
    tiny = Decimal("1e-60")
    f, c, d = Decimal(1), Decimal(1), Decimal(0)
    for i in range(0, 2000):
        m = i // 2
        if i == 0:
            num = Decimal(1)
        elif i % 2 == 0:
            num = (m * (b - m) * x) / ((a + 2 * m - 1) * (a + 2 * m))
        else:
            num = -((a + m) * (a + b + m) * x) / ((a + 2 * m) * (a + 2 * m + 1))
        d = 1 + num * d
        d = tiny if abs(d) < tiny else d
        d = 1 / d
        c = 1 + num / c
        c = tiny if abs(c) < tiny else c
        cd = c * d
        f *= cd
        if abs(cd - 1) < Decimal("1e-45"):
            return front * (f - 1)
    raise RuntimeError("continued fraction did not converge")


def t_quantile(p, nu):
    """t with P(|T| ≤ t) = p for ν degrees of freedom (ν a Fraction; None: normal)."""
    p = Decimal(str(p))
    if nu is None:
        # the normal: P(|Z| ≤ z) = I_{z²/(z²+ν)}... take ν = 1e30 instead
        nu = Decimal("1e30")
    else:
        nu = Decimal(nu.numerator) / Decimal(nu.denominator)
    lo, hi = Decimal(0), Decimal(1000)
    for _ in range(200):
        mid = (lo + hi) / 2
        tail = betainc(nu / 2, Decimal("0.5"), nu / (nu + mid * mid))  # P(|T| > t)
        if 1 - tail < p:
            lo = mid
        else:
            hi = mid
        if hi - lo < Decimal("1e-30"):
            break
    return float((lo + hi) / 2)


# ---------------------------------------------------------------- cases

def write_case(name, files, case, reference):
    d = os.path.join(OUT, name)
    os.makedirs(d, exist_ok=True)
    written = {}
    for fname, text in files.items():
        written[fname] = text
    written["case.toml"] = case_toml(name, case)
    ref = {"generator": GENERATOR, "generator_version": GENERATOR_VERSION,
           "generator_sha256": GEN_SHA, "generated": GENERATOR_DATE, "case": name,
           "values": reference}
    written["reference.json"] = json.dumps(ref, indent=1, sort_keys=False) + "\n"
    return {os.path.join(name, k): v for k, v in written.items()}


def toml_str(s):
    return json.dumps(s, ensure_ascii=False)


def case_toml(name, c):
    lines = [f"# Validation case {name}: written by {GENERATOR} (do not edit; rerun it).",
             f"name = {toml_str(name)}",
             f"description = {toml_str(c['description'])}",
             f"evaluation = {toml_str(c['evaluation'])}",
             f"command = {toml_str(c['command'])}",
             f"inputs = [{', '.join(toml_str(i) for i in c['inputs'])}]"]
    for key in ("budget", "sigma", "trials", "seed", "labs"):
        if key in c:
            v = c[key]
            if isinstance(v, str):
                lines.append(f"{key} = {toml_str(v)}")
            elif isinstance(v, list):
                lines.append(f"{key} = [{', '.join(toml_str(i) for i in v)}]")
            else:
                lines.append(f"{key} = {v}")
    lines += [f"tolerance = {c.get('tolerance', EXACT)!r}",
              f"tolerance_kind = {toml_str(c.get('tolerance_kind', 'relative'))}",
              f"tolerance_reason = {toml_str(c.get('tolerance_reason', EXACT_REASON))}",
              f"reference_method = {toml_str(c['method'])}"]
    return "\n".join(lines) + "\n"


LSQ_METHOD = ("exact least squares of the model of docs/FORMAT.md §1 (Σα = 0 per coset, "
              "φ[N] = 0) in rational arithmetic; u = √(RSS/ν · gᵀ(XᵀX)⁻¹g)")


def solve_case(name, description, seed, faces, offsets, cycles, **kw):
    rows = polygon_set(seed, faces, offsets, cycles, **kw)
    shifted = len(kw.get("setups", [(1, 0)])) > 1
    csv = polygon_csv(rows, faces, shifted, True,
                      f"{name}: drawn by {GENERATOR} (seed {seed}), readings to 0.001\"")
    _, res, _ = solve_polygon(rows, faces, len(offsets))
    case = {"description": description, "evaluation": "solve",
            "command": "polycal solve data.csv --format json", "inputs": ["data.csv"],
            "method": LSQ_METHOD}
    return write_case(name, {"data.csv": csv}, case, res)


def case_solve_all():
    out = {}
    out.update(solve_case(
        "solve-paper-design",
        "The reference paper's design (Hsieh et al. 2023, §2–3): a 24-faced polygon, two "
        "adjacent autocollimators (faces p+1 and p+2 at step p), 6 cycles with closing readings.",
        101, 24, [0, 1], 6, closing=True))
    out.update(solve_case(
        "solve-2ac-apart",
        "Two autocollimators three faces apart on an 8-faced polygon, 3 cycles.",
        102, 8, [0, 3], 3))
    out.update(solve_case(
        "solve-3ac",
        "Three autocollimators (faces p+1, p+3, p+6) on a 9-faced polygon, 2 cycles.",
        103, 9, [0, 2, 5], 2))
    out.update(solve_case(
        "solve-4ac-repeats",
        "Four autocollimators on a 7-faced polygon, 5 repeated cycles.",
        104, 7, [0, 1, 3, 4], 5))
    out.update(solve_case(
        "solve-closing",
        "Two adjacent autocollimators on a 10-faced polygon, 2 cycles with the closing reading.",
        105, 10, [0, 1], 2, closing=True))
    out.update(solve_case(
        "solve-bidirectional",
        "Two adjacent autocollimators on an 8-faced polygon, cycles cw, ccw, cw, ccw "
        "(the ccw cycles in falling step order).",
        106, 8, [0, 1], 4, directions=["cw", "ccw", "cw", "ccw"]))
    out.update(solve_case(
        "solve-mountings",
        "Two adjacent autocollimators on an 8-faced polygon in three mountings shifted by "
        "0°, 90° and 225° (whole faces), 2 cycles each.",
        107, 8, [0, 1], 2, setups=[(1, F(0)), (2, F(90)), (3, F(225))]))
    out.update(solve_case(
        "solve-sub-pitch",
        "Two adjacent autocollimators on a 6-faced polygon (60° pitch) in mountings shifted "
        "by 0°, 20° and 40°: three cosets of encoder angles, 2 cycles each.",
        108, 6, [0, 1], 2, setups=[(1, F(0)), (2, F(20)), (3, F(40))]))
    return out


# The budget file (docs/FORMAT.md §5.3) and its components: (toml lines, u as Fraction²
# or exact, dof)
def case_budget():
    comps = [
        ("Repeatability", "A", "normal", "u = 0.012", F(12, 1000) ** 2, F(9), F(1)),
        ("Resolution", "B", "rectangular", "full_width = 0.04", F(4, 100) ** 2 / 12, F(50), F(1)),
        ("Calibration", "B", "normal", "expanded = 0.03\nk = 2", F(15, 1000) ** 2, F(60), F(1)),
        ("Temperature", "B", "triangular", "half_width = 0.05", F(5, 100) ** 2 / 6, F(12), F(2)),
        ("Cosine error", "B", "arcsine", "half_width = 0.02", F(2, 100) ** 2 / 2, None, F(1)),
    ]
    toml = ["# A budget of five components, one of each kind of statement.",
            "p = 0.95", 'dof_policy = "fractional"', ""]
    for name, typ, dist, width, u2, dof, c in comps:
        toml += ["[[component]]", f'name = "{name}"', f'type = "{typ}"',
                 f'distribution = "{dist}"', width, f"sensitivity = {c}"]
        if dof is not None:
            toml.append(f"dof = {dof}")
        toml.append("")
    uc2 = sum(c * c * u2 for _, _, _, _, u2, _, c in comps)
    denom = sum((c * c * u2) ** 2 / dof for _, _, _, _, u2, dof, c in comps if dof is not None)
    nu = uc2 * uc2 / denom
    k = t_quantile("0.95", nu)
    uc = dsqrt(uc2)
    res = {
        "components": [{"u": dsqrt(u2), "contribution": dsqrt(c * c * u2),
                        "dof": float(dof) if dof is not None else None}
                       for _, _, _, _, u2, dof, c in comps],
        "combined_u": uc, "dof_eff": float(nu), "k": k,
        "expanded_u": float(Decimal(k) * (Decimal(uc2.numerator) / Decimal(uc2.denominator)).sqrt()),
    }
    case = {"description": "An uncertainty budget of five components (normal, rectangular, "
            "normal from an expanded U, triangular, arcsine; one sensitivity 2; one infinite ν) "
            "with ν_eff by Welch–Satterthwaite and k = t_0.95(ν_eff) at fractional ν.",
            "evaluation": "budget", "command": "polycal budget budget.toml --format json",
            "inputs": ["budget.toml"],
            "tolerance_reason": EXACT_REASON + "; k by bisection on the regularized incomplete "
            "beta function to 30 digits",
            "method": "GUM 5.1.2 and G.4.1 in rational arithmetic; k = t_p(ν_eff) by inverting "
                      "Student's t (incomplete beta function, 50 digits)"}
    return write_case("budget-welch-satterthwaite", {"budget.toml": "\n".join(toml).rstrip() + "\n"},
                      case, res)


def case_monte_carlo():
    faces, trials = 12, 20000
    rows = polygon_set(201, faces, [0, 1], 1, closing=False)
    csv = polygon_csv(rows, faces, False, False,
                      f"monte-carlo: drawn by {GENERATOR} (seed 201), readings to 0.001\"")
    fit, _, g = solve_polygon(rows, faces, 2)
    assert fit.dof == 0
    sigma = F(5, 100)
    u_read, u_res = F(3, 100), F(2, 100)
    budget = "\n".join([
        "# Normal components only, so that every Monte Carlo result is normal.",
        "p = 0.95", "",
        "[[component]]", 'name = "Noise of every reading"', 'type = "B"', "u = 0.03",
        'acts_on = "each-reading"', "",
        "[[component]]", 'name = "Added to every result"', 'type = "B"', "u = 0.02",
        'acts_on = "result"', ""])

    def u_of(gg, is_zero=False):
        if is_zero:
            return 0.0
        return dsqrt((sigma ** 2 + u_read ** 2) * fit.cofactor(gg) + u_res ** 2)
    ref = {"monte_carlo": {
        "trials": trials,
        "pitch_deviation": {"u": [u_of(g["beta"](k)) for k in range(1, faces + 1)]},
        "face_deviation": {"u": [u_of(g["phi"](f), f == faces) for f in range(1, faces + 1)]},
        "encoder_error": {"u": [u_of(gg) for _, gg in g["enc"]]},
    }}
    bound = 5 / (2 * (trials - 1)) ** 0.5
    case = {"description": "Monte Carlo through the solver (solve --budget --monte-carlo) of "
            "the paper's design on a 12-faced polygon, one cycle (ν = 0, σ stated 0.05″), "
            "with an each-reading and a result component, all normal.",
            "evaluation": "monte-carlo",
            "command": f"polycal solve data.csv --sigma 0.05 --budget budget.toml "
                       f"--monte-carlo {trials} --seed 1 --format json",
            "inputs": ["data.csv", "budget.toml"], "budget": "budget.toml",
            "sigma": 0.05, "trials": trials, "seed": 1,
            "tolerance": float(f"{bound:.4g}"), "tolerance_kind": "relative-each",
            "tolerance_reason": (
                f"the reference is the analytic u of the linear model, √((σ² + u_r²)·Q_jj + "
                f"u_result²), exact; the Monte Carlo's standard deviation of M = {trials} "
                f"normal draws has a relative standard error 1/√(2(M−1)); the tolerance is "
                f"5 of them ({bound:.4g}), a chance of about 6e-7 per value to fail with a "
                f"correct program"),
            "method": "analytic propagation through the exact cofactor matrix (XᵀX)⁻¹"}
    return write_case("monte-carlo-solve", {"data.csv": csv, "budget.toml": budget}, case, ref)


def result_csv(values, us):
    out = ["quantity,index,value,u,U,k"]
    for i, (v, u) in enumerate(zip(values, us), start=1):
        out.append(f"pitch_deviation,{i},{text3(v)},{text3(u)},{text3(2 * u)},2")
    return "\n".join(out) + "\n"


def closed_values(rng, n):
    v = [dec(rng.uniform(-1, 1)) for _ in range(n)]
    v[-1] -= sum(v)
    return v


def chi2_closed(d, var):
    """dᵀ M⁺ d for M = N/(N−1)·P·diag(var)·P, P = I − J/N: solve the bordered system."""
    n = len(d)
    mean = sum(d) / n
    d = [x - mean for x in d]
    s = F(n, n - 1)
    # M = s·(D − (D 1 1ᵀ + 1 1ᵀ D)/n + (Σvar/n²) 1 1ᵀ)
    tr = sum(var)
    m = [[s * ((var[i] if i == j else 0) - (var[i] + var[j]) / n + tr / (n * n))
          for j in range(n)] + [F(1)] for i in range(n)]
    m.append([F(1)] * n + [F(0)])
    inv = invert(m)
    x = [sum(inv[i][j] * d[j] for j in range(n)) for i in range(n)]
    return sum(a * b for a, b in zip(d, x))


def case_compare():
    rng = random.Random(301)
    n = 6
    a = closed_values(rng, n)
    b = [x + dec(rng.gauss(0, 0.05)) for x in a]
    b[-1] -= sum(b)
    ua = [F(rng.randint(20, 60), 1000) for _ in range(n)]
    ub = [F(rng.randint(20, 60), 1000) for _ in range(n)]
    rows = []
    for i in range(n):
        diff = a[i] - b[i]
        ua2 = 4 * (ua[i] ** 2 + ub[i] ** 2)  # U = 2u
        en = float(Decimal(diff.numerator) / Decimal(diff.denominator)
                   / (Decimal(ua2.numerator) / Decimal(ua2.denominator)).sqrt())
        rows.append({"quantity": "pitch_deviation", "index": i + 1, "a": float(a[i]),
                     "b": float(b[i]), "difference": float(diff), "en": en})
    chi2 = chi2_closed([x - y for x, y in zip(a, b)], [x * x + y * y for x, y in zip(ua, ub)])
    ref = {"rows": rows, "max_abs_en": max(abs(r["en"]) for r in rows),
           "vector": {"chi2": float(chi2), "dof": n - 1}}
    case = {"description": "Two results of a 6-faced polygon's pitch deviations compared: En "
            "per row and the closed vector's χ² (each result's covariance taken as closed, "
            "N/(N−1)·P·diag(u²)·P, its pseudo-inverse).",
            "evaluation": "compare", "command": "polycal compare a.csv b.csv --format json",
            "inputs": ["a.csv", "b.csv"],
            "method": "En = (a − b)/√(U_a² + U_b²) and χ² = dᵀM⁺d in rational arithmetic "
                      "(M⁺ from the bordered system [M 1; 1ᵀ 0])"}
    return write_case("compare-en", {"a.csv": result_csv(a, ua), "b.csv": result_csv(b, ub)},
                      case, ref)


def case_kc():
    rng = random.Random(401)
    n, labs = 6, ["A", "B", "C", "D"]
    truth = closed_values(rng, n)
    x, u = {}, {}
    for lab in labs:
        ul = F(rng.randint(15, 60), 1000)
        v = [t + dec(rng.gauss(0, float(ul))) for t in truth]
        v[-1] -= sum(v)
        x[lab], u[lab] = v, [ul] * n
    ref_v, ref_u, chi2, does, ds = [], [], [], {l: [] for l in labs}, {l: [] for l in labs}
    for i in range(n):
        w = {l: 1 / u[l][i] ** 2 for l in labs}
        sw = sum(w.values())
        mean = sum(w[l] * x[l][i] for l in labs) / sw
        ref_v.append(float(mean))
        ref_u.append(dsqrt(1 / sw))
        chi2.append(float(sum(w[l] * (x[l][i] - mean) ** 2 for l in labs)))
        for l in labs:
            ds[l].append(float(x[l][i] - mean))
            does[l].append(2 * dsqrt(u[l][i] ** 2 - 1 / sw))
    ref = {"reference": ref_v, "reference_u": ref_u, "chi2": chi2,
           "degrees_of_equivalence": [{"lab": l, "d": ds[l], "U": does[l]} for l in labs]}
    files = {f"{l}.csv": result_csv(x[l], u[l]) for l in labs}
    case = {"description": "A key comparison of four laboratories' pitch deviations of a "
            "6-faced polygon: the weighted mean per face, its u, Cochran's χ², and the degrees "
            "of equivalence with U = 2·√(u_i² − u_ref²).",
            "evaluation": "kc", "command": "polycal kc A=A.csv B=B.csv C=C.csv D=D.csv --format json",
            "inputs": [f"{l}.csv" for l in labs], "labs": labs,
            "method": "the weighted mean (Cox 2002, procedure A) in rational arithmetic"}
    return write_case("kc-weighted-mean", files, case, ref)


def selfcal_case():
    rng = random.Random(501)
    positions, head_steps, cycles = 12, [0, 1, 3], 2
    e = [dec(rng.uniform(-1, 1)) for _ in range(positions)]
    e[-1] -= sum(e)
    c = [F(0)] + [dec(rng.uniform(-3, 3)) for _ in head_steps[1:]]
    t = {(cy, s): dec(rng.uniform(-2, 2)) for cy in range(1, cycles + 1)
         for s in range(positions)}
    lines = ["# selfcal: drawn by " + GENERATOR + " (seed 501), readings to 0.001\"",
             "cycle,step,head,head_angle,reading"]
    rows = []
    for cy in range(1, cycles + 1):
        for s in range(positions):
            for h, hs in enumerate(head_steps, start=1):
                pos = (s + hs) % positions
                y = t[(cy, s)] + e[pos] + c[h - 1] + dec(rng.gauss(0, 0.05))
                lines.append(f"{cy},{s},{h},{hs * 30},{text3(y)}")
                g = {("t", cy, s): F(1)}
                if pos < positions - 1:
                    g[("e", pos)] = F(1)
                else:
                    for q in range(positions - 1):
                        g[("e", q)] = F(-1)
                if h > 1:
                    g[("c", h)] = F(1)
                rows.append((g, y))
    params = [("t", cy, s) for cy in range(1, cycles + 1) for s in range(positions)]
    params += [("e", q) for q in range(positions - 1)]
    params += [("c", h) for h in range(2, len(head_steps) + 1)]
    fit = Lsq(params, rows)

    def e_g(p):
        if p < positions - 1:
            return {("e", p): F(1)}
        return {("e", q): F(-1) for q in range(positions - 1)}
    ref = {"positions": positions, "heads": len(head_steps), "readings": fit.readings,
           "dof": fit.dof, "residual_rms": dsqrt(fit.sigma2),
           "encoder_error": [float(fit.value(e_g(p))) for p in range(positions)],
           "encoder_error_u": [fit.u(e_g(p)) for p in range(positions)],
           "encoder_angle_deg": [float(p * 30) for p in range(positions)],
           "head_error": [{"head": h, "angle_deg": float(head_steps[h - 1] * 30),
                           "value": float(fit.value({("c", h): F(1)})),
                           "u": fit.u({("c", h): F(1)})}
                          for h in range(2, len(head_steps) + 1)],
           "lost_harmonics": []}
    case = {"description": "Self-calibration of a 12-position disc by three read heads at 0°, "
            "30° and 90° (no harmonic lost), 2 cycles: the model of docs/FORMAT.md §9.2.",
            "evaluation": "selfcal", "command": "polycal selfcal data.csv --format json",
            "inputs": ["data.csv"],
            "method": "exact least squares of reading = t[cycle, step] + e[position] + c[head] "
                      "(Σe = 0, c[1] = 0) in rational arithmetic"}
    return write_case("selfcal-three-heads", {"data.csv": "\n".join(lines) + "\n"}, case, ref)


WITHIN_U = 4.0


def diagnose_set(seed, effect):
    """A 12-faced polygon, two adjacent autocollimators, 4 cycles, a stop every 20 s,
    noise 0.03″, with one known effect added to the readings."""
    faces, rng = 12, random.Random(seed)
    phi, alpha = draw_truth(rng, faces, faces, 1)
    setup_err = {1: dec(rng.uniform(-5, 5)), 2: dec(rng.uniform(-5, 5))}
    rows, lines = [], ["cycle,step,ac,face,reading,time"]
    for cycle in range(1, 5):
        for step in range(faces):
            t = ((cycle - 1) * faces + step) * 20
            for ac, off in ((1, 0), (2, 1)):
                face = (step + off) % faces + 1
                y = alpha[0][step] + phi[face - 1] + setup_err[ac] + dec(rng.gauss(0, 0.03))
                y += effect(cycle, step, ac, F(t))
                rows.append(dict(cycle=cycle, step=step, ac=ac, face=face, reading=y,
                                 direction="cw", setup=1, shift=F(0), coset=0, pos=step))
                lines.append(f"{cycle},{step},{ac},{face},{text3(y)},{t}")
    return rows, "\n".join(lines) + "\n"


def diagnose_cases():
    out = {}
    reason = (f"the data carry one effect of known size; a diagnosis passes when it finds that "
              f"effect alone and its estimate lies within {WITHIN_U:g} of its own standard "
              f"uncertainties u of the truth (a correct estimate with normal errors misses "
              f"that with probability 6e-5; the data are fixed, so the case is deterministic)")
    drift = F(3, 2)  # arcsec per hour on autocollimator 1
    step = F(3, 10)  # arcsec, autocollimator 2 from cycle 3 on
    outlier = F(2)  # arcsec, cycle 2, step 5, autocollimator 1
    kinds = [
        ("diagnose-drift", "a zero drift of autocollimator 1, 1.5″/h",
         lambda c, s, a, t: dec(float(drift * t / 3600)) if a == 1 else F(0),
         {"kind": "drift", "ac": 1, "value": float(drift)}),
        ("diagnose-offset-step", "a jump of 0.3″ in autocollimator 2's zero from cycle 3 on",
         lambda c, s, a, t: step if (a == 2 and c >= 3) else F(0),
         {"kind": "offset-step", "ac": 2, "cycle": 3, "value": float(step)}),
    ]
    for name, what, effect, found in kinds:
        rows, csv = diagnose_set(hash_seed(name), effect)
        case = {"description": f"A 12-faced polygon, two adjacent autocollimators, 4 cycles, "
                f"noise 0.03″, with {what}: diagnose finds it and estimates its size.",
                "evaluation": "diagnose", "command": "polycal diagnose data.csv --format json",
                "inputs": ["data.csv"], "tolerance": WITHIN_U,
                "tolerance_kind": "standard-uncertainties", "tolerance_reason": reason,
                "method": "the effect added by the generator with this size (the truth)"}
        out.update(write_case(name, {"data.csv": csv}, case,
                              {"effects": [found], "adequate": True}))
    rows, csv = diagnose_set(hash_seed("diagnose-clean"), lambda c, s, a, t: F(0))
    _, res, _ = solve_polygon(rows, 12, 2)
    ref = {"effects": [], "adequate": True,
           "after": {k: res[k] for k in ("dof", "residual_rms", "pitch_deviation",
                                         "pitch_deviation_u", "encoder_error",
                                         "encoder_error_u")}}
    case = {"description": "The same design with no effect: diagnose adds none, finds the model "
            "adequate, and its final fit is the base model's exact least squares.",
            "evaluation": "diagnose", "command": "polycal diagnose data.csv --format json",
            "inputs": ["data.csv"], "method": LSQ_METHOD}
    out.update(write_case("diagnose-clean", {"data.csv": csv}, case, ref))
    return out


def hash_seed(name):
    return int(hashlib.sha256(name.encode()).hexdigest()[:8], 16)


def main():
    check = "--check" in sys.argv[1:]
    files = {}
    files.update(case_solve_all())
    files.update(case_budget())
    files.update(case_monte_carlo())
    files.update(case_compare())
    files.update(case_kc())
    files.update(selfcal_case())
    files.update(diagnose_cases())
    changed = []
    for rel, text in sorted(files.items()):
        path = os.path.join(OUT, rel)
        old = open(path, encoding="utf-8").read() if os.path.exists(path) else None
        if old != text:
            changed.append(rel)
            if not check:
                os.makedirs(os.path.dirname(path), exist_ok=True)
                with open(path, "w", encoding="utf-8", newline="\n") as f:
                    f.write(text)
    if check:
        if changed:
            print("would change: " + ", ".join(changed), file=sys.stderr)
            return 1
        return 0
    print(f"{len(files)} files, {len(changed)} changed", file=sys.stderr)
    return 0


with open(os.path.abspath(__file__), "rb") as _f:
    GEN_SHA = hashlib.sha256(_f.read()).hexdigest()

if __name__ == "__main__":
    sys.exit(main())
