"""Checks the overlap bound of finished tests (benches/large_bounds.sh).

    python3 benches/large_bounds.py TEST_DIR [TEST_DIR ...]

Reads each test's summary.json and prints one table row per test: disks, friction, the
strain reached, the mean and largest overlap in % of r_min, the mean iterations per
compression step and the wall time. Exits with status 1 when a test's largest overlap
passed the bound, 1% of r_min (docs/method.md), or when a test has no summary.
"""

import json
import os
import sys

# docs/method.md: the lab keeps every overlap within 1% of the smallest radius.
BOUND_REL = 0.01


def row(test_dir):
    with open(os.path.join(test_dir, "summary.json"), encoding="utf-8") as f:
        s = json.load(f)
    return {
        "test": os.path.basename(os.path.normpath(test_dir)),
        "disks": s["disks"],
        "mu": s["mu"],
        "strain": s["strain_final"],
        "mean": s["overlap_mean_rel"],
        "max": s["overlap_max_rel"],
        "iterations": s["iterations_mean"],
        "wall_min": s["wall_time_s"] / 60.0,
    }


def main(dirs):
    if not dirs:
        sys.exit(__doc__)
    print(
        "| test | disks | friction | axial strain reached | mean overlap (% r_min) "
        "| largest overlap (% r_min) | iterations per compression step | wall time (min) |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    failed = []
    for d in dirs:
        try:
            r = row(d)
        except (OSError, ValueError, KeyError) as e:
            print(f"| {d} | no finished test: {e} | | | | | | |")
            failed.append(d)
            continue
        print(
            f"| {r['test']} | {r['disks']} | {r['mu']:g} | {r['strain']:.4f} | {100 * r['mean']:.4f} "
            f"| {100 * r['max']:.3f} | {r['iterations']:.1f} | {r['wall_min']:.1f} |"
        )
        if not r["max"] <= BOUND_REL:
            failed.append(d)
    if failed:
        print(f"past the bound of {100 * BOUND_REL:g}% of r_min or unfinished: {', '.join(failed)}")
        sys.exit(1)
    print(f"every test within {100 * BOUND_REL:g}% of r_min")


if __name__ == "__main__":
    main(sys.argv[1:])
