"""Reads a cdlab run's record (run.mcap) with the `mcap` package (pip install mcap).

Usage: python3 examples/read_run.py out/biaxial/run.mcap
Prints the configuration's friction and confining stress, the number of series rows, the
last row's axial stress, and the size of the last snapshot.
"""

import json
import struct
import sys

from mcap.reader import make_reader

path = sys.argv[1] if len(sys.argv) > 1 else "out/biaxial/run.mcap"
rows, config, snapshot = [], None, None
with open(path, "rb") as f:
    # Chunks are zstd-compressed; the reader decompresses them (zstandard package).
    for schema, channel, message in make_reader(f).iter_messages():
        if channel.topic == "/config":
            config = json.loads(message.data)["config"]
        elif channel.topic == "/series":
            rows.append(json.loads(message.data))
        elif channel.topic == "/snapshot":
            snapshot = message.data

# A row holds the fields of series.csv; stresses in Pa, strains as fractions.
print(f"friction {config['test']['mu']}, confining stress {config['test']['sigma3'] / 1e6} MPa")
print(f"series rows {len(rows)}")
last = rows[-1]
print(f"last sigma_1 {last['sigma1_pa']!r} Pa at axial strain {last['strain_axial']:.4f}")
# cdlab.Snapshot.v1 starts with u32 disks, u32 contacts, f64 time (s), f64 strain.
disks, contacts, time_s, strain = struct.unpack_from("<IIdd", snapshot, 0)
print(f"last snapshot: {disks} disks, {contacts} contacts at t = {time_s:.3f} s")
