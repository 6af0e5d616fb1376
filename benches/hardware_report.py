#!/usr/bin/env python3
"""report.json and report.md of a hardware check (benches/hardware_check.sh).

Reads what the check left in its directory: parts.tsv (each part's exit status and wall
time), info.json (`cdlab info --json`), nvidia-smi.csv, bench_*/bench.json (`cdlab bench`)
and the tests' series (series.csv, or series.csv.tmp of a run stopped at its limit) and
summaries. Standard library only: the check runs on machines with nothing installed.
"""

import csv
import json
import os
import sys


def read(path):
    try:
        with open(path, encoding="utf-8") as f:
            return f.read()
    except OSError:
        return None


def series(run_dir):
    """Rows of a run's series, as dicts of floats (phase kept as text)."""
    for name in ("series.csv", "series.csv.tmp"):
        text = read(os.path.join(run_dir, name))
        if text:
            rows = []
            for r in csv.DictReader(text.splitlines()):
                row = {}
                for k, v in r.items():
                    if k is None:
                        continue
                    try:
                        row[k] = float(v)
                    except (TypeError, ValueError):
                        row[k] = v
                rows.append(row)
            return rows
    return []


def phases(rows):
    """Per phase: steps, wall seconds, steps per second, iterations, overlaps, strain."""
    out = {}
    prev = None
    for r in rows:
        p = r.get("phase")
        s = out.setdefault(
            p,
            {"steps": 0, "wall_s": 0.0, "iter_sum": 0.0, "overlap_max_rel": 0.0, "rows": 0},
        )
        if prev is not None:
            ds = r["step"] - prev["step"]
            dw = r["wall_s"] - prev["wall_s"]
            if ds > 0 and dw >= 0:
                s["steps"] += ds
                s["wall_s"] += dw
                s["iter_sum"] += r.get("iterations", 0.0) * ds
        s["rows"] += 1
        s["overlap_max_rel"] = max(s["overlap_max_rel"], r.get("overlap_max_rel", 0.0))
        s["last_strain"] = r.get("strain_axial")
        s["last_sigma1_mpa"] = r.get("sigma1_pa", 0.0) / 1e6
        s["last_contacts"] = r.get("n_contacts")
        prev = r
    for s in out.values():
        s["steps_per_s"] = s["steps"] / s["wall_s"] if s["wall_s"] > 0 else None
        s["ms_per_step"] = 1e3 * s["wall_s"] / s["steps"] if s["steps"] > 0 else None
        s["iterations_per_step"] = s["iter_sum"] / s["steps"] if s["steps"] > 0 else None
        del s["iter_sum"]
    return out


def main(out):
    report = {"parts": [], "bench": [], "tests": {}}
    for line in (read(os.path.join(out, "parts.tsv")) or "").splitlines()[1:]:
        name, rc, secs, limit = line.split("\t")
        report["parts"].append(
            {"part": name, "rc": int(rc), "seconds": float(secs), "limit_s": float(limit)}
        )
    info = read(os.path.join(out, "info.json"))
    try:
        report["info"] = json.loads(info) if info else None
    except ValueError:
        report["info"] = info
    report["nvidia_smi"] = read(os.path.join(out, "nvidia-smi.csv"))
    report["cores"] = (read(os.path.join(out, "cores.txt")) or "").strip()
    for b in ("bench", "bench_gpu", "bench_cpu", "bench_cpu_pinned", "bench_baseline"):
        text = read(os.path.join(out, b, "bench.json"))
        if text:
            for c in json.loads(text):
                c["binary"] = {"bench_baseline": "baseline", "bench_cpu_pinned": "checked, pinned"}.get(b, "checked")
                report["bench"].append(c)
    for name in sorted(os.listdir(out)):
        d = os.path.join(out, name)
        if name.startswith("test") and os.path.isdir(d):
            summary = read(os.path.join(d, "summary.json"))
            log = read(os.path.join(out, name + ".log")) or ""
            report["tests"][name] = {
                "phases": phases(series(d)),
                "summary": json.loads(summary) if summary else None,
                "log_tail": log.splitlines()[-6:],
                # The backend's account of each phase (`PHASE: GPU ...` lines).
                "activity": [l for l in log.splitlines() if ": GPU " in l],
            }
    with open(os.path.join(out, "report.json"), "w", encoding="utf-8") as f:
        json.dump(report, f, indent=1)
    md = ["# cdlab hardware check", ""]
    if report["nvidia_smi"]:
        md += ["```", report["nvidia_smi"].strip(), "```", ""]
    md += [f"CPU cores: {report['cores']}", "", "| part | exit | wall (s) | limit (s) |", "|---|---|---|---|"]
    md += [f"| {p['part']} | {p['rc']} | {p['seconds']:.1f} | {p['limit_s']:.0f} |" for p in report["parts"]]
    md += [
        "",
        "## cdlab bench (tolerance 1e-4, 5 warm-up and 10 measured steps)",
        "",
        "| binary | backend | method | disks | contacts | check every | iterations/step | ms/step | host recording ms/step | recording threads | sweep_all | device ms/step (solve) | device detection / coloring / deep / integration ms/step | ns/update | colors | dispatches/step | empty dispatches/step | submissions/step | waits/window |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for c in report["bench"]:
        # Older binaries' bench.json lacks the newer fields.
        every = c.get("check_every", "-")
        empty = c.get("empty_dispatches_per_step")
        waits = c.get("readbacks_per_window")
        if waits is None:
            waits = c.get("readbacks_per_step", 0.0) * 10
        ph = c.get("device_phases_ms_per_step")
        phase_ms = "-" if not ph else " / ".join(
            format(ph[k], ".3f") for k in ("detection", "coloring", "deep_updates", "integration")
        )
        md.append(
            f"| {c['binary']} | {c['backend']} | {c.get('method', 'colored-gs')} | {c['disks']} | {c['contacts']} | {every} | {c['iterations_per_step']:.1f} "
            f"| {c['ms_per_step']:.2f} | {c.get('host_record_ms_per_step', float('nan')):.2f} | {c.get('record_threads', '-')} | {c.get('sweep_all', '-')} | {c.get('device_ms_per_step')} ({c.get('device_solve_ms_per_step')}) | {phase_ms} | {c['ns_per_contact_update']:.2f} | {c['colors_per_step']:.1f} "
            f"| {c['dispatches_per_step']:.0f} | {'-' if empty is None else format(empty, '.0f')} "
            f"| {c['submissions_per_step']:.2f} | {waits:.2f} |"
        )
    md += [
        "",
        "## Tests",
        "",
        "| test | phase | steps | wall (s) | ms/step | iterations/step | largest overlap (% r_min) | last strain | last sigma1 (MPa) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]

    def fmt(v, spec):
        return "-" if v is None else format(v, spec)

    for name, t in report["tests"].items():
        for p, s in t["phases"].items():
            md.append(
                f"| {name} | {p} | {s['steps']:.0f} | {s['wall_s']:.1f} | {fmt(s['ms_per_step'], '.2f')} "
                f"| {fmt(s['iterations_per_step'], '.1f')} | {100 * s['overlap_max_rel']:.3f} "
                f"| {fmt(s['last_strain'], '.4f')} | {s['last_sigma1_mpa']:.2f} |"
            )
    # The crossover's tests (CDLAB_HW_CROSSOVER): one row per sample, its compression on
    # each backend, and each part's wall time.
    walls = {p["part"]: p for p in report["parts"]}
    samples = sorted(
        {n[len("test_x_"):].rsplit("_", 1)[0] for n in report["tests"] if n.startswith("test_x_")},
        key=lambda n: (len(n), n),
    )
    if samples:
        md += [
            "",
            "## Crossover: compression ms/step (iterations/step), part's wall time",
            "",
            "| sample | GPU | CPU, 2 threads | CPU, all threads |",
            "|---|---|---|---|",
        ]
        for sample in samples:
            cells = []
            for kind in ("gpu", "cpu2", "cpu"):
                name = f"test_x_{sample}_{kind}"
                c = report["tests"].get(name, {}).get("phases", {}).get("compression")
                part = walls.get(name)
                wall = "-" if part is None else f"{part['seconds']:.1f} s" + (" (stopped)" if part["rc"] else "")
                cells.append(
                    "-" if c is None
                    else f"{fmt(c['ms_per_step'], '.2f')} ({fmt(c['iterations_per_step'], '.1f')}), {wall}"
                )
            md.append(f"| {sample} | " + " | ".join(cells) + " |")
    for name, t in report["tests"].items():
        if t.get("activity"):
            md += ["", f"`{name}`, where the time went, by phase:", "", "```"] + t["activity"] + ["```"]
        md += ["", f"`{name}` log, last lines:", "", "```"] + t["log_tail"] + ["```"]
    with open(os.path.join(out, "report.md"), "w", encoding="utf-8") as f:
        f.write("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main(sys.argv[1])
