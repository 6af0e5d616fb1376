"""Convergence curves of the solvers on contact problems kept from real tests.

Reads the CSV files written by `cargo bench --bench solvers` (one per run directory) and
draws, for each file, the distance of the impulses to their local solutions (the measure
common to every method, `solver::space::local_residual`) against the iterations, one line
per method and kept problem.

    python3 plot_curves.py OUT.png A.csv B.csv ...
"""

import csv
import sys
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

COLORS = {"colored-gs": "C0", "gs": "C1", "jacobi": "C2", "anderson-gs": "C3", "apgd": "C4"}


def load(path):
    curves = defaultdict(list)
    meta = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            if row["kind"] != "curve":
                continue
            key = (row["method"], int(row["state_step"]))
            curves[key].append((int(row["cap"]), float(row["local_residual"]), float(row["change"])))
            meta = {k: row[k] for k in ("disks", "mu", "dt_s")}
    return meta, curves


def main():
    out, files = sys.argv[1], sys.argv[2:]
    fig, axes = plt.subplots(2, len(files), figsize=(4.2 * len(files), 6.4), sharey="row", sharex=True, squeeze=False)
    for col, path in enumerate(files):
        meta, curves = load(path)
        first = {}
        for (method, step), pts in sorted(curves.items()):
            pts.sort()
            label = method if method not in first else None
            first.setdefault(method, step)
            for row, k in ((0, 1), (1, 2)):
                axes[row][col].loglog(
                    [p[0] for p in pts],
                    [max(p[k], 1e-12) for p in pts],
                    color=COLORS.get(method, "k"),
                    alpha=1.0 if label else 0.45,
                    label=label,
                )
        axes[0][col].set_title(f"{meta['disks']} disks, friction {meta['mu']}, dt {float(meta['dt_s']) * 1e3:g} ms", fontsize=9)
        axes[1][col].set_xlabel("iterations")
        for row in (0, 1):
            axes[row][col].grid(True, which="both", alpha=0.3)
    axes[0][0].set_ylabel("distance to the local solutions")
    axes[1][0].set_ylabel("change over the iteration (own test)")
    axes[0][0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main()
