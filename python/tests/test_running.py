"""cdlab.run, cdlab.resume and cdlab.prepare: the same records as the CLI, Ctrl-C that leaves
a resumable record, and configuration errors that name the field."""

from __future__ import annotations

import _thread
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

import cdlab
from conftest import SMALL_CONFIG, cli_binary, load_json, read_csv_exact

#: SMALL_CONFIG as the dict a Python user writes (same keys, same unit strings); written
#: out rather than parsed so that these tests run on Python 3.9 and 3.10 (no tomllib).
SMALL_DICT = {
    "sample": {"disks": 100},
    "solver": {"tol": 1e-3, "backend": "cpu"},
    "test": {"strip_thickness": "3 m", "strain_end": 0.002},
    "output": {"series_every": 10, "snapshot_every": 0.001, "checkpoint_every": 500},
}


@pytest.mark.skipif(sys.version_info < (3, 11), reason="tomllib is Python 3.11+")
def test_small_dict_is_small_config():
    import tomllib

    assert tomllib.loads(SMALL_CONFIG) == SMALL_DICT

#: Summary entries that differ between two runs of the same test: wall-clock time, the
#: record's random identity, and the checksum over them.
UNSTABLE = {"wall_time_s", "steps_per_second", "record_id", "checksum"}


def stable(summary: dict) -> dict:
    return {k: v for k, v in summary.items() if k not in UNSTABLE}


def assert_same_series(a, b):
    """series.csv of two runs equal cell for cell, except the wall-clock column."""
    ca, cb = read_csv_exact(a / "series.csv"), read_csv_exact(b / "series.csv")
    assert list(ca) == list(cb)
    assert len(ca["step"]) > 10
    for name in ca:
        if name != "wall_s":
            assert ca[name] == cb[name], name


@pytest.mark.parametrize("form", ["dict", "toml"])
def test_run_from_python_equals_cli_run(small_run, tmp_path, form):
    if form == "dict":
        config = SMALL_DICT
    else:
        config = tmp_path / "small.toml"
        config.write_text(SMALL_CONFIG)
    rows = []
    t = cdlab.run(config, tmp_path / "run", progress=rows.append)
    assert isinstance(t, cdlab.Test) and t.kind == "run"
    assert_same_series(small_run, tmp_path / "run")
    assert stable(t.summary) == stable(load_json(small_run / "summary.json"))
    # The callback saw every recorded row, in order, with its documented keys.
    seen = [r for r in rows if r["event"] == "row"]
    assert [r["step"] for r in seen] == [int(s) for s in read_csv_exact(small_run / "series.csv")["step"]]
    assert set(seen[-1]) >= {"phase", "step", "strain", "strain_end", "sigma1_pa", "sigma3_pa", "wall_s"}
    assert seen[-1]["strain_end"] == 0.002
    assert [r["phase"] for r in rows if r["event"] == "phase_end"] == ["compaction", "confinement", "compression"]


def test_run_into_an_occupied_directory_needs_force(small_run, tmp_path):
    out = tmp_path / "run"
    cdlab.run(SMALL_DICT, out)
    with pytest.raises(cdlab.RunError) as e:
        cdlab.run(SMALL_DICT, out)
    assert e.value.fault == "Occupied"
    # In the package's terms, not the command line's.
    msg = str(e.value)
    assert "force=True" in msg and "cdlab.resume(" in msg and "--" not in msg, msg
    assert cdlab.run(SMALL_DICT, out, force=True).summary is not None


def test_a_value_of_the_wrong_type_in_a_dict_names_its_key(tmp_path):
    """Issue 36, item 17: a negative disk count was a ParseError naming line 2 of a TOML
    text the user never wrote, in Rust's words ("expected usize")."""
    bad = {**SMALL_DICT, "sample": {"disks": -5}}
    with pytest.raises(cdlab.InvalidParameterError) as e:
        cdlab.run(bad, tmp_path / "run")
    assert e.value.field == "sample.disks" and e.value.value == "-5"
    msg = str(e.value)
    assert "whole number" in msg and "usize" not in msg and "line" not in msg, msg


@pytest.fixture
def python_sigint():
    """Python's own SIGINT handler, as an interactive session has it. A process started in
    the background by a non-interactive shell inherits SIGINT ignored, and Python then
    installs no handler: a SIGINT would do nothing, whatever cdlab does."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


def interrupt_at_confinement(how):
    """A progress callback that interrupts the run at its first confinement row: by raising
    KeyboardInterrupt itself, by raising SIGINT (Python's own handler turns it into
    KeyboardInterrupt), or by `_thread.interrupt_main()`, which only marks SIGINT pending as
    a signal from outside would: its handler then runs when cdlab runs Python's pending
    signals after the callback returns."""

    def callback(event):
        if event["event"] == "row" and event["phase"] == "confinement":
            if how == "raise":
                raise KeyboardInterrupt
            if how == "sigint":
                signal.raise_signal(signal.SIGINT)
            else:
                _thread.interrupt_main()

    return callback


@pytest.mark.parametrize("how", ["raise", "sigint", "interrupt_main"])
def test_keyboard_interrupt_leaves_a_record_resume_finishes(small_run, tmp_path, how, python_sigint):
    out = tmp_path / "run"
    with pytest.raises(KeyboardInterrupt) as e:
        cdlab.run(SMALL_DICT, out, progress=interrupt_at_confinement(how))
    # Stopped at a checkpoint in the confinement (steps 3000 to 5000 of this test).
    assert e.value.path == str(out)
    assert isinstance(e.value.step, int) and 3000 < e.value.step < 5000
    assert not (out / "summary.json").exists()
    part = cdlab.open(out)
    assert part.summary is None and part.series["step"].iloc[-1] <= e.value.step

    rows = []
    t = cdlab.resume(e.value.path, progress=rows.append)
    assert rows and all(r["step"] > e.value.step for r in rows if r["event"] == "row")
    # The resumed test is the uninterrupted one (the CLI's), bit for bit.
    assert stable(t.summary) == stable(load_json(small_run / "summary.json"))
    assert_same_series(small_run, out)
    with pytest.raises(cdlab.RunError) as again:
        cdlab.resume(out)
    assert again.value.fault == "Complete"


def test_sigint_while_the_run_computes_without_a_callback(small_run, tmp_path, python_sigint):
    """SIGINT from another thread while the GIL is released and no Python code runs: only
    cdlab's check of Python's pending signals between rows can turn it into the stop."""
    out = tmp_path / "run"

    def send_sigint_once_the_record_exists():
        # Waits for the run's record file (not for a time): the run is then computing.
        for _ in range(200_000):
            if (out / "run.mcap").exists():
                os.kill(os.getpid(), signal.SIGINT)
                return
            time.sleep(0.0005)

    sender = threading.Thread(target=send_sigint_once_the_record_exists)
    sender.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            cdlab.run(SMALL_DICT, out)
    finally:
        sender.join()
    assert e.value.path == str(out) and e.value.step > 0
    assert not (out / "summary.json").exists()
    t = cdlab.resume(out)
    assert stable(t.summary) == stable(load_json(small_run / "summary.json"))
    assert_same_series(small_run, out)


def test_other_callback_exceptions_stop_the_run_and_propagate(tmp_path):
    def boom(event):
        if event["event"] == "row" and event["phase"] == "confinement":
            raise ValueError("stop here")

    with pytest.raises(ValueError, match="stop here") as e:
        cdlab.run(SMALL_DICT, tmp_path / "run", progress=boom)
    assert e.value.step is not None and e.value.step > 0


@pytest.mark.parametrize(
    "section, key, value, kind",
    [
        ("sample", "disks", 5, cdlab.InvalidParameterError),
        ("test", "sigma3", "-1 MPa", cdlab.CdlabError),
        ("sample", "disks", -3, cdlab.InvalidParameterError),
        ("sample", "diskz", 300, cdlab.InvalidParameterError),
    ],
)
def test_bad_config_dict_names_the_field(tmp_path, section, key, value, kind):
    config = {s: dict(v) for s, v in SMALL_DICT.items()}
    config[section][key] = value
    with pytest.raises(kind) as e:
        cdlab.run(config, tmp_path / "run")
    assert f"{section}.{key}" in str(e.value) or key in str(e.value), str(e.value)
    if kind is cdlab.InvalidParameterError:
        assert e.value.field == f"{section}.{key}"
    assert not (tmp_path / "run" / "run.mcap").exists()


def test_prepare_then_run_from_the_sample_equals_the_cli(tmp_path):
    sample = tmp_path / "s.cdlab"
    p = cdlab.prepare(SMALL_DICT, sample)
    assert p.path == sample and sample.is_file() and p.disks == 100
    assert p.width_m > 0 and p.height_m > 0
    t = cdlab.run(SMALL_DICT, tmp_path / "py", sample=sample)
    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL_CONFIG)
    done = subprocess.run(
        [str(cli_binary()), "biaxial", "--quiet", "--no-figures", "--config", str(cfg), "--sample", str(sample),
         "--out", str(tmp_path / "cli")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    assert_same_series(tmp_path / "cli", tmp_path / "py")
    assert stable(t.summary) == stable(load_json(tmp_path / "cli" / "summary.json"))


def test_campaign_shards_split_the_grid(tmp_path):
    (tmp_path / "base.toml").write_text(SMALL_CONFIG)
    out = tmp_path / "campaign"
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(f'base = "base.toml"\nout = "{out}"\nmu = [0.3, 0.5]\nsigma3 = ["1 MPa"]\nseeds = [1]\n')
    plan = cdlab.campaign(sweep, dry_run=True)
    assert (plan.grid, plan.total) == (2, 2)
    first = cdlab.campaign(sweep, shard="0/2")
    assert (first.grid, first.total, first.ended, first.failed) == (2, 1, 1, [])
    second = cdlab.campaign(sweep, jobs=2, shard=(1, 2))
    assert (second.total, second.ended, second.failed) == (1, 1, [])
    finished = sorted(p.parent.name for p in out.rglob("summary.json"))
    assert len(finished) == 2, finished
    # Both shards done: the whole grid is found finished, nothing runs again.
    again = cdlab.campaign(sweep)
    assert (again.total, again.ended, again.failed) == (2, 2, [])
    with pytest.raises(cdlab.InvalidParameterError):
        cdlab.campaign(sweep, shard="2/2")
