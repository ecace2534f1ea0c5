#!/usr/bin/env bash
# Copies the seed corpora of the cargo-fuzz targets from the repository's example and
# test files (the same seeds as the CI harness, tests/sweeps/fuzz/seeds.rs) into
# fuzz/corpus/TARGET/seed-*. Run it again when those files change; libFuzzer's own
# additions to fuzz/corpus are not kept in git (fuzz/.gitignore).
set -euo pipefail
cd "$(dirname "$0")/.."
seed() { # TARGET FILE...
    local target=$1
    shift
    mkdir -p "fuzz/corpus/$target"
    for file in "$@"; do
        cp "$file" "fuzz/corpus/$target/seed-$(basename "$file")"
    done
}
seed measurement examples/data/polygon24-2ac-6cycles.csv \
    examples/data/polygon24-shift-angle-5setups.csv tests/data/measurement/good_*.csv \
    tests/fixtures/expected/sim-bare.file.bare.csv \
    tests/fixtures/expected/sim-setups.file.setups.csv \
    tests/fixtures/expected/sim-subpitch.file.subpitch.csv
seed selfcal tests/data/selfcal/good_3heads.csv \
    tests/fixtures/expected/sim-selfcal.file.selfcal.csv \
    tests/fixtures/expected/sim-selfcal-12.file.selfa12.csv
seed results examples/data/polygon24-shift-angle.result.csv tests/data/results/two-ac-24.csv \
    tests/data/results/two-ac-24-no-angle.csv tests/data/results/selfcal-168.csv \
    tests/data/results/setup-a.csv tests/data/results/setup-b.csv \
    tests/fixtures/inputs/result-a.csv tests/fixtures/inputs/result-b.csv
seed budget examples/budgets/*.toml
seed instrument_budget examples/budgets/instrument.toml examples/budgets/selfcal.toml \
    examples/budgets/paper-table1.toml
seed truth examples/data/polygon24-2ac-6cycles.truth.json \
    tests/fixtures/expected/sim-bare.file.bare.json \
    tests/fixtures/expected/sim-drift.file.drift.json \
    tests/fixtures/expected/sim-subpitch.file.subpitch.json
seed selfcal_truth tests/fixtures/expected/sim-selfcal.file.selfcal.json \
    examples/data/selfa-168.truth.json
seed meta examples/report/meta.toml
seed designs examples/designs.toml
# Reply lines of docs/FORMAT.md §7.1–7.2, without their terminators.
mkdir -p fuzz/corpus/replies
n=0
for reply in "8 ELCOMAT 3000 S/N 12" "4 003 12.345000 -1.234000" "4 001 -0.5 0.0" \
    "2 003 1.0 2.0" "1TS000033" "1TS00000A" "1TS000128" "1TP45" "1TP51.428571" "1TE@" \
    "1TEC" "1VESMC_CC - Controller-driver version 3.0.1"; do
    n=$((n + 1))
    printf '%s' "$reply" > "fuzz/corpus/replies/seed-$n"
done
