#!/usr/bin/env python3
"""Writes the example history of examples/data/history/: six yearly calibrations of one
24-face polygon (result files, docs/FORMAT.md §3), for `polycal history`.
Deterministic: run `python3 make.py` in this directory to write them again.

The truth: pitch deviations TRUE_BETA (Σ = 0) drifting by 0.03″·cos(2π·k/24) a year from
2019-03-12 (a once-per-turn change of the polygon, closed); every calibration measures it
with u = 0.05″ on every face (U = 0.1″, k = 2), its noise closed as a closure calibration
gives, e = sqrt(N/(N-1))·u·(z - mean z). The encoder errors (15° steps) are stable, with
their own noise and each calibration's zero elsewhere (a constant added).
"""
import math
import random

FACES = 24
U = 0.05
DRIFT = 0.03  # arcsec per year, amplitude
DATES = ["2019-03-12", "2020-03-10", "2021-03-02", "2022-03-15", "2023-03-07", "2024-03-05"]
START = (2019, 3, 12)


def days(date):
    """Days since 1970-01-01 of YYYY-MM-DD."""
    import datetime
    y, m, d = (int(p) for p in date.split("-"))
    return (datetime.date(y, m, d) - datetime.date(1970, 1, 1)).days


def main():
    rng = random.Random(56)
    raw = [0.4 * math.sin(2 * math.pi * k / FACES * 3 + 0.7) + 0.2 * rng.gauss(0, 1) for k in range(FACES)]
    mean = sum(raw) / FACES
    true_beta = [b - mean for b in raw]
    encoder = [0.5 * math.sin(math.radians(15 * p) + 0.3) for p in range(FACES)]
    t0 = days(DATES[0])
    for date in DATES:
        years = (days(date) - t0) / 365.25
        z = [rng.gauss(0.0, 1.0) for _ in range(FACES)]
        zm = sum(z) / FACES
        scale = math.sqrt(FACES / (FACES - 1)) * U
        zero = rng.uniform(-0.3, 0.3)
        lines = [f"# Example history (examples/data/history/make.py): calibration of {date}",
                 "quantity,index,value,U,u,k,angle_deg"]
        for k in range(1, FACES + 1):
            drift = DRIFT * math.cos(2 * math.pi * k / FACES) * years
            value = true_beta[k - 1] + drift + scale * (z[k - 1] - zm)
            lines.append(f"pitch_deviation,{k},{value:.4f},{2 * U:.4f},{U:.4f},2,")
        for p in range(FACES):
            value = encoder[p] + zero + rng.gauss(0.0, U)
            lines.append(f"encoder_error,{p},{value:.4f},{2 * U:.4f},{U:.4f},2,{15 * p:g}")
        with open(date[:4] + ".csv", "w", encoding="utf-8") as f:
            f.write("\n".join(lines) + "\n")


main()
