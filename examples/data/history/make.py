#!/usr/bin/env python3
"""Writes the example history of examples/data/history/: six yearly calibrations of one
24-face polygon (result files, docs/FORMAT.md §3), for `polycal history`.
Deterministic: run `python3 make.py` in this directory to write them again.

The truth: pitch deviations TRUE_BETA (Σ = 0) drifting by 0.03″·cos(2π·k/24) a year from
2019-03-12 (a once-per-turn change of the polygon, closed); every calibration measures it
with u = 0.05″ on every face (U = 0.1″, k = 2), its noise closed as a closure calibration
gives, e = sqrt(N/(N-1))·u·(z - mean z). The encoder errors (15° steps) are stable, with
their own noise and each calibration's zero elsewhere (a constant added).

It also writes run-2026-11-03.csv: a measurement run (docs/FORMAT.md §2) of the same polygon
on 2026-11-03, its truth the drifted pitch deviations of that day, for `polycal report
--history` (the run as the standard's newest calibration): two autocollimators at faces 1
and 2, 6 cycles of 24 steps, reading = α[step] + φ[face] + s[ac] + noise (σ = 0.05″),
φ[f] = β[1] + … + β[f].
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
    run("2026-11-03", true_beta, encoder, t0)


def run(date, true_beta, encoder, t0):
    """A closure run of the polygon on `date` (its own random stream: the yearly files
    above do not change with it)."""
    rng = random.Random(20261103)
    years = (days(date) - t0) / 365.25
    beta = [true_beta[k - 1] + DRIFT * math.cos(2 * math.pi * k / FACES) * years for k in range(1, FACES + 1)]
    phi = []
    total = 0.0
    for b in beta:
        total += b
        phi.append(total)
    phi[-1] = 0.0
    setup = {1: 0.8, 2: -0.5}
    lines = [f"# Example run (examples/data/history/make.py): the history's polygon measured on {date}",
             f"# date_of_measurement: {date}",
             "cycle,step,ac,face,reading,direction,setup,time,encoder"]
    for cycle in range(1, 7):
        for step in range(FACES):
            for ac, offset in ((1, 0), (2, 1)):
                face = (step + offset) % FACES + 1
                reading = encoder[step] + phi[face - 1] + setup[ac] + rng.gauss(0.0, 0.05)
                time = ((cycle - 1) * FACES + step) * 20
                lines.append(f"{cycle},{step},{ac},{face},{reading:.6f},cw,1,{time},{15 * step}")
    with open(f"run-{date}.csv", "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


main()
