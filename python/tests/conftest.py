"""Shared fixtures: the repository's paths and one small run made by the CLI binary."""

from __future__ import annotations

import csv
import json
import os
import subprocess
from pathlib import Path
from typing import Dict, List

import pytest

#: The repository (python/tests/ is two levels below it).
ROOT = Path(__file__).resolve().parents[2]

#: The archived campaign shipped in the repository (assets/results/).
CAMPAIGN = ROOT / "assets" / "results" / "campaign5000"

#: A run small enough for seconds: 100 disks, 0.2 % axial strain, three snapshots.
SMALL_CONFIG = """\
[sample]
disks = 100
[solver]
tol = 1e-3
backend = "cpu"
[test]
strip_thickness = "3 m"
strain_end = 0.002
[output]
series_every = 10
snapshot_every = 0.001
checkpoint_every = 500
"""


def cli_binary() -> Path:
    """The cdlab binary cargo built: $CDLAB_BIN, else target/release/cdlab."""
    return Path(os.environ.get("CDLAB_BIN", ROOT / "target" / "release" / "cdlab"))


def read_csv_exact(path: Path) -> Dict[str, List[str]]:
    """The columns of a CSV file as the text of its cells (compared through float(), which
    gives the same bits as the shortest round-trip form Rust writes)."""
    with path.open(newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    return {name: [r[k] for r in body] for k, name in enumerate(header)}


@pytest.fixture(scope="session")
def small_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The directory of a small biaxial test run by the CLI (CPU backend)."""
    exe = cli_binary()
    if not exe.is_file():
        pytest.fail(f"{exe}: no cdlab binary; build it with `cargo build --release` or set CDLAB_BIN")
    d = tmp_path_factory.mktemp("small")
    cfg = d / "small.toml"
    cfg.write_text(SMALL_CONFIG)
    out = d / "run"
    done = subprocess.run(
        [str(exe), "biaxial", "--quiet", "--no-figures", "--config", str(cfg), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert (out / "summary.json").is_file()
    return out


def load_json(path: Path) -> dict:
    return json.loads(path.read_text())
