"""Iterations each method needs to bring the distance to the local solutions below given
levels, read from the convergence curves of `cargo bench --bench solvers` (CSV files).
A level not reached by the last point of a curve prints as '>' that cap.

    python3 iterations_to.py A.csv B.csv ...
"""

import csv
import sys
from collections import defaultdict

LEVELS = (3e-4, 1e-4, 3e-5)


def first_below(pts, level):
    for cap, res in pts:
        if res <= level:
            return str(cap)
    return ">" + str(pts[-1][0])


for path in sys.argv[1:]:
    curves = defaultdict(list)
    meta = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            if row["kind"] == "curve":
                curves[(row["method"], int(row["state_step"]))].append((int(row["cap"]), float(row["local_residual"])))
                meta = row
    print(f"{path}: {meta['disks']} disks, friction {meta['mu']}, dt {float(meta['dt_s']) * 1e3:g} ms, {meta['contacts']} contacts")
    print("  " + f"{'method':>12} {'state step':>10} " + " ".join(f"{'to ' + format(l, '.0e'):>8}" for l in LEVELS))
    for (method, step), pts in sorted(curves.items()):
        pts.sort()
        print("  " + f"{method:>12} {step:>10} " + " ".join(f"{first_below(pts, l):>8}" for l in LEVELS))
