#!/usr/bin/env python3
"""Runs one variant of the DWL study on several samples.

usage: run_variant.py NAME DISKS STRAIN SEEDS [section.key=value ...]
  SEEDS comma-separated; values in TOML syntax (strings quoted, e.g. compaction.sigma_c='"1MPa"').
Writes cand/NAME/config.toml and one run directory per seed, cand/NAME/n{DISKS}_s{SEED}.
The binary is $CDLAB (default target/release/cdlab); the study build's switches
(variants.patch) are environment variables set by the caller, e.g. CDLAB_STUDY_GRAVITY=9.81.
"""
import os, subprocess, sys, time
name, disks, strain, seeds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4].split(",")
cfg = {"solver": {"threads": "1", "backend": '"cpu"'}, "output": {"snapshot_every": "0.01"}}
for kv in sys.argv[5:]:
    k, v = kv.split("=", 1)
    sec, key = k.split(".")
    cfg.setdefault(sec, {})[key] = v
d = f"cand/{name}"
os.makedirs(d, exist_ok=True)
with open(f"{d}/config.toml", "w") as f:
    for sec, kv in cfg.items():
        f.write(f"[{sec}]\n" + "".join(f"{k} = {v}\n" for k, v in kv.items()))
exe = os.environ.get("CDLAB", "target/release/cdlab")
for s in seeds:
    out = f"{d}/n{disks}_s{s}"
    if os.path.exists(f"{out}/summary.json"):
        continue
    t = time.time()
    with open(out + ".log", "w") as log:
        r = subprocess.run([exe, "biaxial", "--config", f"{d}/config.toml", "--disks", disks, "--seed", s,
                            "--strain", strain, "--out", out, "--quiet", "--no-figures", "--force"],
                           stdout=log, stderr=subprocess.STDOUT)
    print(f"{name} seed {s}: exit {r.returncode}, {time.time()-t:.0f} s", flush=True)
