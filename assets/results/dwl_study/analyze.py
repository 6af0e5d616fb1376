#!/usr/bin/env python3
"""Tabulates the DWL study's runs (cand/NAME/n{DISKS}_s{SEED}, see run_variant.py).

usage: [CSV=runs.csv] python3 analyze.py [NAME ...]
Needs numpy, pandas and mcap (pip install numpy pandas mcap). Prints one row per run, the
mean and standard deviation per variant, and the Markdown table of docs/results.md.
"""
import glob, json, os, struct, sys, math
import numpy as np, pandas as pd

def snapshot_phi(mcap_path, want_strain=0.0):
    """Solid fraction of the first compression snapshot: disk area over the strips' box."""
    from mcap.reader import make_reader
    with open(mcap_path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages(topics=["/snapshot"]):
            b = message.data
            n, m, t, strain = struct.unpack_from("<IIdd", b, 0)
            a = np.frombuffer(b, dtype="<f8", count=9 * n, offset=24).reshape(n, 9)
            return float(np.sum(np.pi * a[:, 6] ** 2)), t
    return None, None

def metrics(run):
    s = json.load(open(f"{run}/summary.json"))
    d = pd.read_csv(f"{run}/series.csv")
    c = d[d.phase == "compression"]
    e, s1 = c.strain_axial.values, c.sigma1_pa.values / 1e6
    # windows of 0.002 strain, as the summary's peak
    bins = np.floor(e / 0.002).astype(int)
    g = pd.Series(s1).groupby(bins)
    cnt = g.size()
    wm = g.mean()[cnt >= 0.5 * cnt.median()]
    ipk = wm.idxmax()
    early = wm.loc[0] if 0 in wm.index else np.nan
    after = wm.loc[wm.index > ipk]
    dip = after.min() if len(after) else np.nan
    late = s1[(e >= 0.04) & (e <= 0.06)].mean()
    m02 = (e <= 0.02)
    rate = np.polyfit(e[m02], c.volumetric_strain.values[m02], 1)[0]
    first = c.iloc[0]
    fab = s.get("fabric") or {}
    def ac(k):
        v = fab.get(k) or {}
        return v.get("a_c", np.nan)
    area, _ = snapshot_phi(f"{run}/run.mcap")
    phi = area / (first.height_m * first.width_m) if area else np.nan
    return dict(peak=s["sigma1_peak_mpa"], e_peak=s["strain_peak"], early=early, dip=dip, late=late,
                rate=rate, ac_comp=ac("after_compaction"), ac_conf=ac("after_confinement"),
                hom=fab.get("homogeneity_after_compaction_pct", np.nan),
                z0=first.coordination, iso0=first.isolated_fraction, phi0=phi,
                ovl=s["overlap_max_rel"], it=s["iterations_mean"])

rows = []
cands = sys.argv[1:] or sorted(os.listdir("cand"))
for cnd in cands:
    for run in sorted(glob.glob(f"cand/{cnd}/n*_s*")):
        if not os.path.exists(f"{run}/summary.json"):
            continue
        m = metrics(run); m["cand"] = cnd + ("" if "n2000" in run else "@" + run.split("/")[-1].split("_")[0]); m["run"] = os.path.basename(run); rows.append(m)
t = pd.DataFrame(rows)
pd.set_option("display.width", 250); pd.set_option("display.precision", 4)
print(t.to_string(index=False))
import os as _o
if _o.environ.get("CSV"): t.to_csv(_o.environ["CSV"], index=False, float_format="%.6g")
g = t.groupby("cand")
print(g[["peak", "e_peak", "early", "dip", "late", "rate", "ac_comp", "ac_conf", "hom", "z0", "phi0"]].agg(["mean", "std"]).round(4).to_string())

def pm(col, cand, fmt):
    x = t[t.cand == cand][col].dropna()
    if len(x) == 0:
        return "n/a"
    return (fmt % x.mean()) + " ± " + (fmt % x.std(ddof=1)) if len(x) > 1 else fmt % x.mean()

print()
print("| choice | runs | peak sigma1 (MPa) | strain at peak | first 0.002 (MPa) | dip after peak (MPa) | strain 0.04-0.06 (MPa) | dilation rate, strain 0-0.02 | a_c after compaction / confinement | coordination, solid fraction at compression start |")
print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
for cnd in sorted(set(t.cand), key=lambda c: [x.split('@')[0] for x in cands].index(c.split('@')[0])):
    n = (t.cand == cnd).sum()
    if n == 0:
        continue
    print(f"| {cnd} | {n} | {pm('peak',cnd,'%.2f')} | {pm('e_peak',cnd,'%.4f')} | {pm('early',cnd,'%.2f')} | {pm('dip',cnd,'%.2f')} | {pm('late',cnd,'%.2f')} | {pm('rate',cnd,'%.2f')} | {pm('ac_comp',cnd,'%.3f')} / {pm('ac_conf',cnd,'%.3f')} | {pm('z0',cnd,'%.2f')}, {pm('phi0',cnd,'%.3f')} |")
