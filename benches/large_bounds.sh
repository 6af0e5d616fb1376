#!/usr/bin/env bash
# The overlap bound at the sizes users run (docs/results.md, "The overlap bound at scale"):
# DWL and DWH whole (5000 disks, 8 MPa, friction 0.3 and 3, built-in settings) and a
# 50,000-disk test (friction 0.3, 8 MPa) to axial strain 0.02 from a sample this script
# prepares; then benches/large_bounds.py checks that every test kept its largest overlap
# within 1% of r_min and prints each one's iterations per step and wall time. It fails
# (exit 1) if a test passed the bound.
#
#   benches/large_bounds.sh [CDLAB] [OUT]
#
# CDLAB is the binary (default target/release/cdlab), OUT the directory (default
# out/large_bounds). Run again, it skips the finished tests, resumes an interrupted one from
# its last checkpoint, and keeps the prepared sample. On 2 cores (2026-11-28): 7 min for DWL,
# 14 min for DWH, and for the 50,000-disk part 6-14 min of preparation and 16-22 min of
# test.
set -euo pipefail
cd "$(dirname "$0")/.."
BIN="${1:-target/release/cdlab}"
OUT="${2:-out/large_bounds}"
mkdir -p "$OUT"

run() {
    local dir="$OUT/$1"
    shift
    if [ -f "$dir/summary.json" ]; then
        echo "$dir: finished before"
    elif [ -d "$dir" ] && "$BIN" biaxial --resume "$dir" --quiet --no-figures; then
        echo "$dir: resumed and finished"
    else
        "$BIN" biaxial --out "$dir" --force --quiet --no-figures "$@"
    fi
}

run dwl --disks 5000 --mu 0.3 --sigma3 8MPa
[ -f "$OUT/s50000.sample" ] || "$BIN" prepare --disks 50000 --output "$OUT/s50000.sample"
run n50000 --sample "$OUT/s50000.sample" --mu 0.3 --sigma3 8MPa --strain 0.02
run dwh --disks 5000 --mu 3 --sigma3 8MPa
python3 benches/large_bounds.py "$OUT/dwl" "$OUT/n50000" "$OUT/dwh"
