#!/usr/bin/env bash
# The strength-band study of docs/validation.md ("Strength bands from seed statistics"):
# runs the sweep assets/bands/sweep.toml (ten 1000-disk samples at contact friction 0.1,
# 0.3 and 3, 8 MPa, to axial strain 0.1; one test per core) into out/strength_bands, then
# writes each test's strength to assets/results/strength_bands.csv and prints the mean and
# standard deviation per friction. tests/strength.rs checks single runs against that file.
#
#   benches/strength_bands.sh [CDLAB]
#
# CDLAB is the binary (default target/release/cdlab). On 2 cores the study takes about
# 15 minutes (a test takes about 40 s at friction 0.1 and 0.3, 55 s at 3); run again, the
# sweep skips the finished tests.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN="${1:-target/release/cdlab}"
"$BIN" sweep assets/bands/sweep.toml
python3 benches/strength_bands.py out/strength_bands assets/results/strength_bands.csv
