"""Reading the archived tests shipped in assets/results/ gives their files' values."""

from __future__ import annotations

import math
import sys

import numpy as np
import pytest

import cdlab
from conftest import CAMPAIGN, load_json, read_csv_exact

AT_8_MPA = sorted(CAMPAIGN.glob("*_s8MPa"))


def test_the_campaign_ships_thirteen_tests_at_8_mpa():
    assert len(AT_8_MPA) == 13, AT_8_MPA


@pytest.mark.parametrize("test_dir", AT_8_MPA[:3], ids=lambda p: p.name)
def test_summary_and_series_are_the_files_values(test_dir):
    t = cdlab.open(test_dir)
    assert t.kind == "archived"
    assert t.summary == load_json(test_dir / "summary.json")
    assert t.summary["sigma3_mpa"] == 8.0

    csv = read_csv_exact(test_dir / "series_thinned.csv")
    s = t.series
    # Every column of series.csv, in its order; these tests were archived before the
    # deep-contact and micromechanical columns existed, which read with their defaults
    # (the record's: 0 and NaN).
    assert list(s.columns) == [f[0] for f in cdlab.SERIES_FIELDS]
    assert [c for c in s.columns if c in csv] == list(csv)
    later = [c for c in s.columns if c not in csv]
    assert later[0] == "deep_contacts" and (s["deep_contacts"] == 0).all()
    assert all(s[c].isna().all() for c in later[1:])
    assert len(s) == len(csv["time_s"]) > 100
    for name, kind, _ in cdlab.SERIES_FIELDS:
        if name not in csv:
            continue
        if kind == "string":
            assert list(s[name]) == csv[name], name
        elif kind == "integer":
            assert s[name].dtype == np.uint64
            assert list(s[name]) == [int(v) for v in csv[name]], name
        else:
            assert s[name].dtype == np.float64
            want = np.array([float(v) for v in csv[name]])
            assert np.array_equal(s[name].to_numpy(), want, equal_nan=True), name
    # An archived test keeps no record: no snapshot unless archived with its last one.
    assert t.snapshots == []
    assert t.run_id is None and t.truncated is None


def test_units_are_those_of_the_files():
    """sigma3 of the series is in Pa, the summary's in MPa, the config's in Pa."""
    t = cdlab.open(AT_8_MPA[0])
    assert t.config["test"]["sigma3"] == 8e6
    assert np.allclose(t.series["sigma3_pa"], 8e6)
    comp = t.series[t.series["phase"] == "compression"]
    peak_pa = comp["sigma1_pa"].max()
    # The summary's peak is a moving average over 0.002 strain: close to, not above, the
    # largest row (in MPa against Pa: a unit slip would be a factor 1e6).
    assert 0.8 * peak_pa / 1e6 < t.summary["sigma1_peak_mpa"] <= peak_pa / 1e6


@pytest.mark.skipif(sys.version_info < (3, 11), reason="tomllib is Python 3.11+")
def test_config_is_the_archived_toml():
    import tomllib

    d = AT_8_MPA[1]
    toml = tomllib.loads((d / "config.toml").read_text())
    cfg = cdlab.open(d).config
    for section, keys in toml.items():
        for key, value in keys.items():
            got = cfg[section][key]
            if isinstance(value, float):
                assert math.isclose(got, value, rel_tol=0, abs_tol=0), (section, key)
            else:
                assert got == value, (section, key)
