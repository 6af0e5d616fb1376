"""Errors are cdlab.CdlabError subclasses that name the file or field at fault."""

from __future__ import annotations

import json
import shutil
import struct

import pytest

import cdlab


def middle_chunk(data: bytes) -> range:
    """The byte range of the content of the record's middle chunk. Only the record framing
    of the MCAP format is walked (8-byte magic, then opcode u8 and length u64 LE per record;
    0x06 a chunk), to put the damage where the reader must find it, whatever the sizes of
    this run's chunks."""
    chunks, p = [], 8
    while p + 9 <= len(data):
        op = data[p]
        n = struct.unpack_from("<Q", data, p + 1)[0]
        if op == 0x06:
            chunks.append(range(p + 9, p + 9 + n))
        if op == 0x0F:  # data end
            break
        p += 9 + n
    assert len(chunks) >= 3, f"{len(chunks)} chunks"
    return chunks[len(chunks) // 2]


def copy_run(src, dst):
    shutil.copytree(src, dst)
    return dst


def test_a_damaged_record_raises_naming_the_file(small_run, tmp_path):
    run = copy_run(small_run, tmp_path / "run")
    mcap = run / "run.mcap"
    data = bytearray(mcap.read_bytes())
    # One byte in the middle of a chunk's compressed records, whose CRC then fails.
    chunk = middle_chunk(bytes(data))
    data[chunk.start + len(chunk) // 2] ^= 0xFF
    mcap.write_bytes(bytes(data))
    with pytest.raises(cdlab.DamagedRecordError) as e:
        cdlab.open(run)
    assert isinstance(e.value, cdlab.FileError) and isinstance(e.value, cdlab.CdlabError)
    assert e.value.path == str(mcap)
    assert str(mcap) in str(e.value)
    # What precedes the damage can still be read, on request.
    t = cdlab.open(run, allow_damaged=True)
    assert t.damaged is not None
    assert len(t.series) < len(cdlab.open(small_run).series)


def test_a_record_cut_short_opens_with_what_it_holds(small_run, tmp_path):
    run = copy_run(small_run, tmp_path / "run")
    (run / "summary.json").unlink()
    mcap = run / "run.mcap"
    data = mcap.read_bytes()
    # Cut inside the middle chunk, as a run killed while it wrote the chunk leaves it.
    chunk = middle_chunk(data)
    mcap.write_bytes(data[: chunk.start + len(chunk) // 2])
    t = cdlab.open(run)
    assert t.truncated is not None and t.damaged is None
    assert 0 < len(t.series) < len(cdlab.open(small_run).series)
    assert t.summary is None


def test_a_file_that_is_not_a_record_raises_naming_it(tmp_path):
    f = tmp_path / "run.mcap"
    f.write_bytes(b"this is not an MCAP file" * 10)
    with pytest.raises(cdlab.FileError) as e:
        cdlab.open(tmp_path)
    assert e.value.path == str(f)


def test_a_missing_path_raises_naming_it(tmp_path):
    p = tmp_path / "nothing here"
    with pytest.raises(cdlab.FileError) as e:
        cdlab.open(p)
    assert e.value.path == str(p)


def test_a_damaged_summary_raises_naming_it(small_run, tmp_path):
    run = copy_run(small_run, tmp_path / "run")
    (run / "summary.json").write_text('{"version": "0.1.0", "disks": ')
    with pytest.raises(cdlab.FileError) as e:
        cdlab.open(run)
    assert e.value.path == str(run / "summary.json")


def test_a_summary_changed_after_writing_raises_naming_it(small_run, tmp_path):
    run = copy_run(small_run, tmp_path / "run")
    s = (run / "summary.json").read_text()
    key = '"sigma1_peak_mpa": '
    at = s.index(key) + len(key)
    digit = "1" if s[at] != "1" else "2"
    (run / "summary.json").write_text(s[:at] + digit + s[at + 1 :])
    with pytest.raises(cdlab.FileError, match="checksum") as e:
        cdlab.open(run)
    assert e.value.path == str(run / "summary.json")


def test_a_stale_summary_raises_naming_it(small_run, tmp_path):
    run = copy_run(small_run, tmp_path / "run")
    s = json.loads((run / "summary.json").read_text())
    s["record_id"] = "0" * 32
    # Another record's summary, whole: its checksum is its own (none, as before summaries
    # had one), so only its record_id gives it away.
    del s["checksum"]
    (run / "summary.json").write_text(json.dumps(s))
    with pytest.raises(cdlab.FileError, match="stale") as e:
        cdlab.open(run)
    assert e.value.path == str(run / "summary.json")


def test_a_bad_archived_configuration_names_the_field(tmp_path):
    from conftest import CAMPAIGN

    d = tmp_path / "archived"
    shutil.copytree(CAMPAIGN / "seed1_mu0.01_s8MPa", d)
    cfg = d / "config.toml"
    text = cfg.read_text()
    assert "\nmu = 0.01\n" in text
    cfg.write_text(text.replace("\nmu = 0.01\n", "\nmu = -1.0\n"))
    with pytest.raises(cdlab.InvalidParameterError) as e:
        cdlab.open(d)
    assert e.value.field == "test.mu"
    assert str(cfg) in str(e.value) or "test.mu" in str(e.value)
    assert e.value.value == "-1"


def test_a_configuration_that_does_not_parse_names_file_and_line(tmp_path):
    from conftest import CAMPAIGN

    d = tmp_path / "archived"
    shutil.copytree(CAMPAIGN / "seed1_mu0.01_s8MPa", d)
    cfg = d / "config.toml"
    lines = cfg.read_text().splitlines()
    lines[2] = "r_min = = 0.5"
    cfg.write_text("\n".join(lines) + "\n")
    with pytest.raises(cdlab.ParseError) as e:
        cdlab.open(d)
    assert e.value.path == str(cfg)
    assert e.value.line == 3
