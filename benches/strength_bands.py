"""Collects the strength-band study's tests (benches/strength_bands.sh) into one CSV.

    python3 benches/strength_bands.py CAMPAIGN_DIR OUT.csv

One row per finished test (its summary.json, whose checksum cdlab checked when the sweep
skipped or finished it), sorted by friction and seed; then prints, per friction, the mean
and the sample standard deviation of the peak and residual sigma1.
"""

import csv
import json
import os
import statistics
import sys

COLUMNS = [
    "seed",
    "mu",
    "sigma3_mpa",
    "dt_ms",
    "sigma1_peak_mpa",
    "strain_peak",
    "sigma1_residual_mpa",
    "volumetric_strain_final",
    "overlap_max_rel",
    "iterations_mean",
    "version",
]


def main(campaign, out):
    rows = []
    for name in sorted(os.listdir(campaign)):
        path = os.path.join(campaign, name, "summary.json")
        if not name.startswith("seed") or not os.path.exists(path):
            continue
        with open(path, encoding="utf-8") as f:
            s = json.load(f)
        seed = int(name[len("seed"):].split("_")[0])
        dt = s.get("dt_s")
        rows.append(
            {
                "seed": seed,
                "mu": s["mu"],
                "sigma3_mpa": s["sigma3_mpa"],
                "dt_ms": None if dt is None else dt * 1e3,
                **{k: s.get(k) for k in COLUMNS[4:]},
            }
        )
    if not rows:
        sys.exit(f"no finished test in {campaign}")
    rows.sort(key=lambda r: (r["mu"], r["seed"]))
    tmp = out + ".tmp"
    with open(tmp, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS, lineterminator="\n")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r[k] is None else r[k]) for k in COLUMNS})
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, out)
    print("| friction | tests | peak sigma1 (MPa) | strain at peak | residual sigma1 (MPa) |")
    print("|---|---|---|---|---|")
    for mu in sorted({r["mu"] for r in rows}):
        mine = [r for r in rows if r["mu"] == mu]

        def band(key):
            v = [r[key] for r in mine if r[key] is not None]
            if len(v) < 2:
                return "-"
            return f"{statistics.mean(v):.3f} +- {statistics.stdev(v):.3f}"

        print(
            f"| {mu} | {len(mine)} | {band('sigma1_peak_mpa')} | {band('strain_peak')} "
            f"| {band('sigma1_residual_mpa')} |"
        )


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
