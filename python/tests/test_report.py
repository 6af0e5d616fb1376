"""cdlab.report gives the campaign analysis that cdlab report shipped in assets/results/."""

from __future__ import annotations

import numpy as np
import pytest

import cdlab
from conftest import CAMPAIGN, read_csv_exact


def test_fits_and_tests_are_the_shipped_report():
    r = cdlab.report(CAMPAIGN)
    want = read_csv_exact(CAMPAIGN.parent / "campaign5000_report.csv")
    assert list(r.fits.columns) == list(want)
    assert len(r.fits) == 13
    for name in ["mu", "mu_macro", "mu_macro_se", "mu_macro_res", "cohesion_peak_mpa"]:
        assert np.array_equal(r.fits[name].to_numpy(), np.array([float(v) for v in want[name]])), name
    assert list(r.fits["tests"]) == [int(v) for v in want["tests"]]

    tests = read_csv_exact(CAMPAIGN.parent / "campaign5000_tests.csv")
    assert list(r.tests.columns) == list(tests)
    assert len(r.tests) == len(tests["mu"]) == 65
    for name in ["mu", "sigma3_mpa", "sigma1_peak_mpa", "strain_peak"]:
        assert np.array_equal(r.tests[name].to_numpy(), np.array([float(v) for v in tests[name]])), name
    # The saturation fit of the macroscopic friction against the contact friction.
    assert set(r.raw["mu_macro_fit"]) >= {"a", "b", "c"}


def test_report_of_a_file_raises_naming_it(tmp_path):
    f = tmp_path / "not_a_dir.txt"
    f.write_text("x")
    with pytest.raises(cdlab.FileError) as e:
        cdlab.report([f])
    assert e.value.path == str(f)
    assert str(f) in str(e.value)


def test_report_without_a_finished_test_raises(tmp_path):
    with pytest.raises(cdlab.CdlabError, match="no finished test"):
        cdlab.report(tmp_path)
