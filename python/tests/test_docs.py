"""The ```python test blocks of docs/python.md run as written, from the repository's root."""

from __future__ import annotations

import contextlib
import io
import os
import re

import pytest

from conftest import ROOT

PAGE = ROOT / "docs/python.md"
BLOCKS = re.findall(r"^```python test\n(.*?)^```$", PAGE.read_text(), flags=re.S | re.M)


def test_the_page_has_tested_blocks():
    assert len(BLOCKS) >= 4, "docs/python.md: expected its ```python test blocks"


@pytest.mark.parametrize("k", range(len(BLOCKS)))
def test_block_runs(k, small_run, monkeypatch):
    monkeypatch.chdir(ROOT)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(BLOCKS[k], f"docs/python.md block {k + 1}", "exec"), {"RUN": os.fspath(small_run)})
    assert out.getvalue().strip(), "each block prints what it shows"


def test_the_namespace_is_the_api():
    """dir(cdlab) lists the package's API, not the modules it imports (np, pd, Any)."""
    import cdlab

    public = [n for n in dir(cdlab) if not n.startswith("_")]
    assert sorted(public) == sorted(cdlab.__all__)
    for name in cdlab.__all__:
        assert hasattr(cdlab, name), name
