#!/usr/bin/env python3
"""Writes the example key comparison of examples/data/kc/ (README.md there): six
laboratories' result files (docs/FORMAT.md §3) of one 12-face polygon and one encoder, and
three repeated results of the pilot (laboratory A at the start, middle and end of the
circulation). Deterministic: run `python3 make.py` in this directory to write them again.

Every laboratory measures the same truth with its own standard uncertainty u (k = 2):
pitch deviations with closed noise, e = sqrt(N/(N-1))·u·(z - mean z), so that Σβ = 0 as a
closure calibration gives; laboratory F is biased by +3u on face 4 and -3u on face 9. The
encoder errors are at 30° steps (laboratory E at 15° steps: its other twelve angles are
in no other result). Four angle blocks (nominal 5°, 15°, 30° and 90°) are measured by
every laboratory but D, which did not measure the 90° block; laboratory E is biased by
+5u on the 30° block. The blocks are drawn from a generator of their own, so that the
polygon's and the encoder's numbers do not depend on them.
"""
import math
import random

FACES = 12
TRUE_BETA = [0.82, -0.35, -0.12, -0.21, 0.58, 0.03, -0.64, 0.27, -0.09, -0.33, 0.41, -0.37]
LABS = {"A": 0.05, "B": 0.08, "C": 0.10, "D": 0.12, "E": 0.15, "F": 0.20}
BIAS = {"F": {4: 3.0, 9: -3.0}}  # in units of the laboratory's u
BLOCK_NOMINAL_DEG = [5, 15, 30, 90]
TRUE_BLOCK = [0.31, -0.12, 0.47, -0.26]  # deviations from nominal, arcsec
BLOCK_U_FACTOR = 1.2  # a block's u, in units of the laboratory's polygon u
BLOCK_BIAS = {"E": {3: 5.0}}  # in units of the block's u
BLOCKS_NOT_MEASURED = {"D": {4}}


def encoder_truth(angle_deg):
    a = math.radians(angle_deg)
    return 0.6 * math.sin(a + 0.4) + 0.35 * math.sin(2 * a + 1.3) + 0.2 * math.sin(3 * a + 2.2)


def write(name, u, rng, blocks_rng, bias=None, encoder_step_deg=30.0, drift=0.0):
    z = [rng.gauss(0.0, 1.0) for _ in range(FACES)]
    mean = sum(z) / FACES
    scale = math.sqrt(FACES / (FACES - 1)) * u
    lines = ["# Example key comparison (examples/data/kc/make.py): laboratory " + name,
             "quantity,index,value,U,u,k"]
    for face in range(1, FACES + 1):
        value = TRUE_BETA[face - 1] + scale * (z[face - 1] - mean)
        value += (bias or {}).get(face, 0.0) * u
        value += drift * (1 if face % 2 else -1)
        lines.append(f"pitch_deviation,{face},{value:.4f},{2 * u:.4f},{u:.4f},2")
    header = "quantity,index,value,U,u,k,angle_deg"
    lines[1] = header
    lines[2:] = [line + "," for line in lines[2:]]
    positions = int(round(360.0 / encoder_step_deg))
    for p in range(positions):
        angle = p * encoder_step_deg
        value = encoder_truth(angle) + rng.gauss(0.0, u)
        lines.append(f"encoder_error,{p},{value:.4f},{2 * u:.4f},{u:.4f},2,{angle:g}")
    # angle blocks: the column nominal_deg after angle_deg (empty on the other rows)
    lines[1] = header + ",nominal_deg"
    lines[2:] = [line + "," for line in lines[2:]]
    block_u = BLOCK_U_FACTOR * u
    for b, (nominal, truth) in enumerate(zip(BLOCK_NOMINAL_DEG, TRUE_BLOCK), start=1):
        value = truth + blocks_rng.gauss(0.0, block_u)
        if b in BLOCKS_NOT_MEASURED.get(name, set()):
            continue
        value += BLOCK_BIAS.get(name, {}).get(b, 0.0) * block_u
        lines.append(f"angle_block,{b},{value:.4f},{2 * block_u:.4f},{block_u:.4f},2,,{nominal}")
    with open(name + ".csv", "w", encoding="utf-8") as f:
        f.write("\n".join(lines) + "\n")


def main():
    rng = random.Random(40)
    blocks_rng = random.Random(42)
    for lab, u in LABS.items():
        write(lab, u, rng, blocks_rng, BIAS.get(lab), 15.0 if lab == "E" else 30.0)
    # The pilot (laboratory A's u) at the start, middle and end: the artefact moved by
    # ±0.12″ (alternating faces) between the middle and the end.
    for repeat, drift in [("pilot-start", 0.0), ("pilot-middle", 0.0), ("pilot-end", 0.12)]:
        write(repeat, LABS["A"], rng, blocks_rng, None, 30.0, drift)


main()
