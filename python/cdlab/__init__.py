"""Run cdlab tests and read runs, archived tests and campaign reports from Python.

``cdlab.open(path)`` opens a run directory (or its ``run.mcap``) or a test archived by
``cdlab archive``; ``cdlab.report(paths)`` gives the campaign analysis of ``cdlab report``.
``cdlab.run``, ``cdlab.resume``, ``cdlab.prepare`` and ``cdlab.campaign`` run tests through
the library calls of ``cdlab biaxial``, ``cdlab prepare`` and ``cdlab sweep``, without the
GIL, with a progress callback, and stopping at a checkpoint on Ctrl-C (KeyboardInterrupt).
Every file is read and checked by the cdlab library itself (the compiled module
``cdlab._cdlab``): this package only turns what it reads into dicts, NumPy arrays and
pandas DataFrames. Units are SI, and every column name carries its unit as in
``series.csv`` (``sigma1_pa``, ``height_m``; no suffix: dimensionless or a count).

Errors are :class:`CdlabError` or one of its subclasses; ``str(e)`` names the field or
file at fault, and the subclasses carry it as attributes (``FileError.path``,
``InvalidParameterError.field``). See docs/python.md.
"""

from __future__ import annotations

import csv
import io
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, List, Optional, Tuple, Union

# Underscored, as the other imports' names are left out of dir() below: the package's
# namespace is its API.
import numpy as _np
import pandas as _pd

from . import _cdlab
from ._cdlab import (
    CdlabError,
    DamagedRecordError,
    FileError,
    GpuError,
    InvalidParameterError,
    NoAdapterError,
    NumericalError,
    ParseError,
    RunError,
    CampaignError,
    StoppedError,
)

__all__ = [
    "open",
    "report",
    "run",
    "resume",
    "prepare",
    "campaign",
    "Campaign",
    "Test",
    "Snapshot",
    "Report",
    "SERIES_FIELDS",
    "CONTACT_CLASSES",
    "CdlabError",
    "DamagedRecordError",
    "FileError",
    "GpuError",
    "InvalidParameterError",
    "NoAdapterError",
    "NumericalError",
    "ParseError",
    "StoppedError",
    "RunError",
    "CampaignError",
    "PreparedSample",
    "PathLike",
    "ConfigLike",
    "ProgressLike",
]

__version__: str = _cdlab.library_version()


def __dir__() -> List[str]:
    """The package's API (``__all__``): not the modules and typing names it imports."""
    return sorted(set(__all__) | {"__version__", "__doc__", "__name__", "__file__", "__path__"})

PathLike = Union[str, "os.PathLike[str]"]

#: The series columns as ``(name, type, description with unit)``, in ``series.csv``
#: order; type ``"number"`` is float64, ``"integer"`` uint64, ``"string"`` str.
SERIES_FIELDS: List[Tuple[str, str, str]] = list(_cdlab.series_fields())

#: The contact classes of a snapshot, by their code in the ``class`` column.
CONTACT_CLASSES: Tuple[str, ...] = ("open", "zero-force", "rolling", "sliding")

_F64 = _np.dtype("<f8")
_U64 = _np.dtype("<u8")
_U32 = _np.dtype("<u4")


def _column(raw: bytes, dtype: _np.dtype) -> _np.ndarray:
    """A writable native-order array of the little-endian bytes ``raw``."""
    return _np.frombuffer(raw, dtype=dtype).astype(dtype.newbyteorder("="))


class Snapshot:
    """One snapshot of a test: the whole sample at ``time_s`` (s) and axial ``strain``.

    The arrays are built from the record when asked for (``disks()``, ``contacts()``,
    ``arrays()``), so a list of hundreds of snapshots costs nothing until one is used.
    Contact bodies use the generalized numbering: ``j >= n_disks`` is wall
    ``j - n_disks``; the normal points from ``j`` to ``i``.
    """

    def __init__(self, record: "_cdlab.Record", index: int, time_s: float, strain: float):
        self._record = record
        #: Position in the record's list of snapshots.
        self.index: int = index
        #: Simulated time (s).
        self.time_s: float = time_s
        #: Axial strain (0 before the compression).
        self.strain: float = strain

    def __repr__(self) -> str:
        return f"<cdlab.Snapshot {self.index}: t = {self.time_s:g} s, strain {self.strain:g}>"

    def disks(self) -> _pd.DataFrame:
        """The disks, one row each: ``x_m``, ``y_m`` (centre, m), ``theta_rad`` (rotation,
        counterclockwise), ``vx_m_s``, ``vy_m_s`` (m/s), ``w_rad_s`` (rad/s), ``r_m``
        (radius, m), ``dx_m``, ``dy_m`` (displacement since the compression began, m; 0
        before). Every column is float64."""
        cols = self._record.snapshot_disks(self.index)
        return _pd.DataFrame({k: _column(v, _F64) for k, v in cols.items()})

    def contacts(self) -> _pd.DataFrame:
        """The candidate contacts, one row each: ``i``, ``j`` (bodies, uint32), ``nx``,
        ``ny`` (unit normal from j to i), ``f_n_n_m`` (normal force, N/m, compressive
        positive), ``f_t_n_m`` (tangential force along ``(ny, -nx)``, N/m), ``class``
        (uint8 code of :data:`CONTACT_CLASSES`)."""
        cols = self._record.snapshot_contacts(self.index)
        types = {"i": _U32, "j": _U32, "class": _np.dtype("u1")}
        return _pd.DataFrame({k: _column(v, types.get(k, _F64)) for k, v in cols.items()})

    def arrays(self) -> Dict[str, _np.ndarray]:
        """The snapshot as NumPy arrays (SI units): ``positions`` (n, 2) m, ``radii`` (n,)
        m, ``rotations`` (n,) rad, ``velocities`` (n, 2) m/s, ``angular_velocities`` (n,)
        rad/s, ``displacements`` (n, 2) m; ``pairs`` (m, 2) uint32, ``normals`` (m, 2),
        ``forces`` (m, 2) N/m as (normal, tangential), ``classes`` (m,) uint8."""
        d = self._record.snapshot_disks(self.index)
        c = self._record.snapshot_contacts(self.index)

        def f(raw: bytes) -> _np.ndarray:
            return _column(raw, _F64)

        def pair(a: _np.ndarray, b: _np.ndarray) -> _np.ndarray:
            return _np.ascontiguousarray(_np.column_stack([a, b]))

        return {
            "positions": pair(f(d["x_m"]), f(d["y_m"])),
            "radii": f(d["r_m"]),
            "rotations": f(d["theta_rad"]),
            "velocities": pair(f(d["vx_m_s"]), f(d["vy_m_s"])),
            "angular_velocities": f(d["w_rad_s"]),
            "displacements": pair(f(d["dx_m"]), f(d["dy_m"])),
            "pairs": pair(_column(c["i"], _U32), _column(c["j"], _U32)),
            "normals": pair(f(c["nx"]), f(c["ny"])),
            "forces": pair(f(c["f_n_n_m"]), f(c["f_t_n_m"])),
            "classes": _column(c["class"], _np.dtype("u1")),
        }

    def fabric(self) -> Dict[str, Any]:
        """The micromechanical analysis of this snapshot, as ``cdlab fabric`` computes it
        (docs/micromechanics.md): anisotropies ``a_c``, ``a_n``, ``a_t``, ``theta_c_deg``,
        the Love-Weber stress ``sigma1_pa``/``sigma3_pa`` over the sample area ``area_m2``
        of the series row nearest the snapshot, ``q_over_p``, the strong network, the force
        PDF ``pdf`` ((n, 2) array of bin centre of f_n/<f_n>, density) and the orientation
        densities ``rose_all``/``rose_strong`` (1/rad over 18 bins of [0, pi)).
        Raises :class:`CdlabError` when no contact carries force."""
        a = json.loads(self._record.snapshot_fabric_json(self.index))
        a["pdf"] = _np.asarray(a["pdf"], dtype=_np.float64).reshape(-1, 2)
        a["rose_all"] = _np.asarray(a["rose_all"], dtype=_np.float64)
        a["rose_strong"] = _np.asarray(a["rose_strong"], dtype=_np.float64)
        return a


class Test:
    """A run or an archived test, opened by :func:`open`."""

    def __init__(self, record: "_cdlab.Record"):
        self._record = record
        self._series: Optional[_pd.DataFrame] = None
        self._config: Optional[Dict[str, Any]] = None

    def __repr__(self) -> str:
        return f"<cdlab.Test {self.kind} {str(self.path)!r}: {len(self.snapshots)} snapshots>"

    @property
    def path(self) -> Path:
        """The run directory or archived test."""
        return Path(self._record.path)

    @property
    def kind(self) -> str:
        """``"run"`` (read from its record ``run.mcap``) or ``"archived"`` (a directory of
        ``cdlab archive``: configuration, summary, thinned series, at most one snapshot)."""
        return self._record.kind

    @property
    def config(self) -> Dict[str, Any]:
        """The configuration: the sections and keys of the TOML file, SI units (a copy)."""
        if self._config is None:
            self._config = json.loads(self._record.config_json)
        return json.loads(json.dumps(self._config))

    @property
    def summary(self) -> Optional[Dict[str, Any]]:
        """``summary.json`` (checked to be this record's), or None for a test not finished.
        Keys carry their unit (``sigma1_peak_mpa``); JSON null (e.g. no residual) is None."""
        text = self._record.summary_json
        return None if text is None else json.loads(text)

    @property
    def series(self) -> _pd.DataFrame:
        """The time series: the columns of ``series.csv`` (:data:`SERIES_FIELDS`), one row per
        measurement, read from the record (an archived test: its thinned series). float64,
        uint64 and text (``phase``) columns; NaN where the record holds none (a copy)."""
        if self._series is None:
            cols = self._record.series_columns()
            data: Dict[str, Any] = {}
            for name, kind, _ in SERIES_FIELDS:
                raw = cols[name]
                if kind == "string":
                    # pandas' own text dtype (object before pandas 3, str from it on),
                    # as pandas.read_csv gives for series.csv.
                    data[name] = _pd.Series(raw)
                else:
                    data[name] = _column(raw, _U64 if kind == "integer" else _F64)
            self._series = _pd.DataFrame(data)
        return self._series.copy()

    @property
    def snapshots(self) -> List[Snapshot]:
        """The snapshots in record order (an archived test: its last one when it was archived
        with ``--keep-last-snapshot``, else none)."""
        return [Snapshot(self._record, k, t, e) for k, (t, e) in enumerate(self._record.snapshot_times())]

    @property
    def fabric(self) -> Optional[Dict[str, Any]]:
        """The summary's micromechanical states (after compaction, after confinement, at the
        peak, at the end), or None when the test has no summary or its rows no
        micromechanical columns. Per row they are the series' ``a_c`` ... ``rose_max_dev``
        columns; per snapshot :meth:`Snapshot.fabric`."""
        s = self.summary
        return None if s is None else s.get("fabric")

    @property
    def truncated(self) -> Optional[str]:
        """Why the record ends early (a run killed mid-write), None for a complete one."""
        return self._record.truncated

    @property
    def damaged(self) -> Optional[str]:
        """Why the record failed a check; only set when opened with ``allow_damaged``."""
        return self._record.damaged

    @property
    def run_id(self) -> Optional[str]:
        """The record's identity (the summary's ``record_id``); None for an archived test."""
        return self._record.run_id

    @property
    def version(self) -> Optional[str]:
        """The cdlab version that wrote the record; None for an archived test."""
        return self._record.version

    @property
    def backend(self) -> Optional[str]:
        """The backend that wrote the record's last part, when the record says."""
        return self._record.backend


def open(path: PathLike, *, allow_damaged: bool = False) -> Test:  # noqa: A001 (the documented name)
    """Opens a run directory (or its ``run.mcap``) or a test archived by ``cdlab archive``.

    The record is read and checked once, here (chunk and checkpoint CRCs). A record that
    failed a check raises :class:`DamagedRecordError` naming the file, unless
    ``allow_damaged``: then what precedes the damage is read and :attr:`Test.damaged` says
    why. A record merely cut short (a run killed while it wrote) opens, with
    :attr:`Test.truncated` set. A missing or unreadable file raises :class:`FileError`.
    """
    return Test(_cdlab.open_record(os.fspath(path), allow_damaged=allow_damaged))


@dataclass(frozen=True)
class Report:
    """The campaign analysis of :func:`report` (what ``cdlab report`` writes)."""

    #: One row per contact friction (``report.csv``): ``mu``, ``tests``, ``mu_macro`` (tan of
    #: the peak friction angle) and ``mu_macro_se``, the same at the residual, the
    #: Mohr-Coulomb cohesion of the free fit ``cohesion_peak_mpa`` with its error (MPa),
    #: ``dt_ms`` (str: several time steps are joined by ``;``) and ``wall_time_h``.
    fits: _pd.DataFrame
    #: One row per test (``tests.csv``): strengths (MPa), strains, shear bands, stress drops,
    #: overlap, kinetic ratio, time step (ms) and wall time (h); NaN where the summary holds
    #: no figure.
    tests: _pd.DataFrame
    #: ``report.json``: the fits with their points, the friction saturation fits
    #: ``mu_macro_fit``/``mu_macro_res_fit``, the tests that could not be read (``missing``)
    #: and those flagged ``suspect`` (not quasi-static) or ``overlapping``.
    raw: Dict[str, Any]

    @property
    def missing(self) -> List[Tuple[str, str]]:
        """Run directories that could not be read or are unfinished, with the reason."""
        return [(str(p), str(why)) for p, why in self.raw.get("missing", [])]


def report(paths: Union[PathLike, Iterable[PathLike]]) -> Report:
    """The Mohr-Coulomb analysis of the finished tests below ``paths`` (run directories,
    archived tests, or directories holding them, searched recursively), as ``cdlab report``
    computes it. Raises :class:`FileError` for a path that is not a directory and
    :class:`CdlabError` when no finished test is found."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    json_text, fits_csv, tests_csv = _cdlab.campaign_report([os.fspath(p) for p in paths])
    fits = _frame_from_csv(fits_csv, text=("dt_ms",))
    tests = _frame_from_csv(tests_csv, text=("dir",))
    return Report(fits=fits, tests=tests, raw=json.loads(json_text))


def _frame_from_csv(csv_text: str, *, text: Tuple[str, ...] = ()) -> _pd.DataFrame:
    """A DataFrame of a CSV text that cdlab wrote: the ``text`` columns as str, the others as
    int64 when every cell is an integer, else float64 with NaN for an empty cell. Python's
    float() reads Rust's shortest round-trip form back to the same bits, which
    pandas.read_csv does not promise before pandas 3."""
    rows = list(csv.reader(io.StringIO(csv_text)))
    header, body = rows[0], rows[1:]
    data: Dict[str, Any] = {}
    for k, name in enumerate(header):
        cells = [r[k] for r in body]
        if name in text:
            data[name] = _pd.Series(cells)
        elif cells and all(c.lstrip("-").isdigit() for c in cells):
            data[name] = _np.array([int(c) for c in cells], dtype=_np.int64)
        else:
            data[name] = _np.array([float(c) if c else _np.nan for c in cells], dtype=_np.float64)
    return _pd.DataFrame(data, columns=header)


# ---------------------------------------------------------------------------------------
# Running tests: cdlab.run, cdlab.resume, cdlab.prepare, cdlab.campaign.
# ---------------------------------------------------------------------------------------

#: What :func:`run` accepts as a configuration: a dict with the TOML file's sections, keys
#: and unit strings (``{"test": {"sigma3": "1 MPa"}}``), the path of a TOML file, or None
#: (the built-in default configuration).
ConfigLike = Union[None, Dict[str, Any], str, "os.PathLike[str]"]

#: A progress callback: called with a dict at each recorded series row (``event`` "row",
#: ``phase``, ``step``, ``time_s``, ``strain``, ``strain_end``, ``sigma1_pa``,
#: ``sigma3_pa``, ``volumetric_strain``, ``coordination``, ``wall_s``) and at each phase's
#: end (``event`` "phase_end", ``phase``); where ``auto`` left a hardware GPU unused for a
#: small sample, once before the steps (``event`` "note", ``text``). ``True`` draws a tqdm
#: bar (tqdm must be installed); None reports nothing.
ProgressLike = Union[None, bool, Callable[[Dict[str, Any]], Any]]


def _config_args(config: ConfigLike) -> Dict[str, Any]:
    """The configuration as the keyword arguments of the compiled calls."""
    if config is None:
        return {}
    if isinstance(config, dict):
        try:
            text = json.dumps(config, allow_nan=False)
        except (TypeError, ValueError) as e:
            raise ParseError(f"<config dict>: {e}") from None
        return {"config_json": text}
    return {"config_path": os.fspath(config)}


class _TqdmBar:
    """A tqdm bar over the compression's axial strain (the phases before it are shown by
    name), closed when the run ends."""

    def __init__(self) -> None:
        try:
            from tqdm.auto import tqdm
        except ImportError:  # pragma: no cover (depends on the environment)
            raise ImportError("progress=True needs tqdm (`pip install tqdm`); or pass a callable") from None
        self._bar = tqdm(total=1.0, unit="strain", bar_format="{l_bar}{bar}| strain {n:.4f}/{total:.4f} [{elapsed}<{remaining}{postfix}]")

    def __call__(self, event: Dict[str, Any]) -> None:
        if event["event"] == "note":
            self._bar.write(f"note: {event['text']}")
            return
        if event["event"] != "row":
            return
        bar = self._bar
        bar.set_description(event["phase"], refresh=False)
        if event["phase"] == "compression":
            bar.total = event["strain_end"]
            bar.n = min(max(event["strain"], 0.0), event["strain_end"])
        bar.set_postfix_str(f"sigma1 {event['sigma1_pa'] / 1e6:.3f} MPa", refresh=False)
        bar.refresh()

    def close(self) -> None:
        self._bar.close()


def _with_progress(progress: ProgressLike, call: Callable[[Any], Any]) -> Any:
    """Runs ``call(callback)`` with the callback that ``progress`` asks for."""
    if progress is True:
        bar = _TqdmBar()
        try:
            return call(bar)
        finally:
            bar.close()
    if progress is False or progress is None:
        return call(None)
    if not callable(progress):
        raise TypeError(f"progress must be a callable, True or None, not {type(progress).__name__}")
    return call(progress)


def run(
    config: ConfigLike = None,
    out: PathLike = "runs/biaxial",
    *,
    backend: Optional[str] = None,
    progress: ProgressLike = None,
    force: bool = False,
    sample: Optional[PathLike] = None,
) -> Test:
    """Runs a biaxial test into the directory ``out`` and returns it opened (:func:`open`).

    ``config`` is a dict with the TOML file's sections, keys and unit strings, the path of a
    TOML file, or None for the built-in default (``cdlab config --print-default``);
    ``backend`` ("cpu", "gpu" or "auto") replaces its ``solver.backend``. ``force``
    replaces a run already in ``out``. ``sample`` starts from a sample written by
    :func:`prepare` instead of depositing one. A run from the same configuration gives the
    same record, bit for bit on the CPU, as ``cdlab biaxial --config FILE --out DIR``.

    The GIL is released while the test computes. ``progress`` is a callable receiving a dict
    at each recorded row (see :data:`ProgressLike`), or True for a tqdm bar.

    Ctrl-C: cdlab installs no signal handler. Python's pending signals are run at each
    recorded row; a KeyboardInterrupt raised there (or any exception the callback raises)
    stops the test at its next checkpoint and is raised here with attributes ``path`` (the
    run directory) and ``step`` (the checkpoint's step, None if the run had ended):
    ``cdlab.resume(e.path)`` continues it.

    Errors: :class:`InvalidParameterError` (``.field`` names the key) or
    :class:`ParseError` for a bad configuration, :class:`RunError` when ``out`` holds a run
    (``fault`` "Occupied") and ``force`` is false, :class:`GpuError`, :class:`NumericalError`.
    """
    args = _config_args(config)
    smp = None if sample is None else os.fspath(sample)
    d = _with_progress(
        progress,
        lambda cb: _cdlab.run_test(os.fspath(out), backend=backend, force=force, progress=cb, sample=smp, **args),
    )
    return open(d)


def resume(path: PathLike, *, backend: Optional[str] = None, progress: ProgressLike = None) -> Test:
    """Continues the run in ``path`` from its last intact checkpoint to its end (what
    ``cdlab biaxial --resume PATH`` does) and returns it opened. A complete run whose
    summary is missing gets it written again. ``progress`` and Ctrl-C work as in
    :func:`run`. :class:`RunError` says why a directory cannot be resumed (``fault``
    "NoRun", "NoCheckpoint", "Complete", ...)."""
    d = _with_progress(progress, lambda cb: _cdlab.resume_run(os.fspath(path), backend=backend, progress=cb))
    return open(d)


@dataclass(frozen=True)
class PreparedSample:
    """A sample written by :func:`prepare`."""

    #: The sample file.
    path: Path
    #: Number of disks.
    disks: int
    #: Sample width and height at the end of the compaction (m).
    width_m: float
    height_m: float
    #: Wall-clock time of the preparation (s).
    wall_s: float


def prepare(config: ConfigLike = None, out: PathLike = "sample.cdlab", *, progress: ProgressLike = None) -> PreparedSample:
    """Deposits and compacts a sample of ``config`` (dict, TOML path or None, as in
    :func:`run`) and writes it to ``out`` (what ``cdlab prepare`` does); ``cdlab.run(...,
    sample=out)`` starts tests from it."""
    args = _config_args(config)
    p, n, w, h, t = _with_progress(progress, lambda cb: _cdlab.prepare_sample(os.fspath(out), progress=cb, **args))
    return PreparedSample(Path(p), n, w, h, t)


@dataclass(frozen=True)
class Campaign:
    """What :func:`campaign` did in its shard."""

    #: Tests in the whole grid, and in this shard.
    grid: int
    total: int
    #: Tests ended or found finished (failures included).
    ended: int
    #: Tests that failed, as (directory, why).
    failed: List[Tuple[Path, str]]
    #: Tests stopped at a checkpoint (or not begun) by a cancellation.
    stopped: List[Path]
    #: Tests that another process runs.
    elsewhere: List[Path]


def _shard(shard: Union[None, str, Tuple[int, int]]) -> Tuple[int, int]:
    if shard is None:
        return (0, 1)
    if isinstance(shard, str):
        parts = shard.split("/")
        try:
            i, n = (int(p) for p in parts)
        except ValueError:
            raise InvalidParameterError(f"shard: {shard!r} is not I/N with 0 <= I < N") from None
        return (i, n)
    i, n = shard
    return (int(i), int(n))


def campaign(
    sweep: PathLike,
    *,
    jobs: int = 1,
    shard: Union[None, str, Tuple[int, int]] = None,
    dry_run: bool = False,
) -> Campaign:
    """Runs the campaign of the sweep file ``sweep`` (what ``cdlab sweep`` does) with
    ``jobs`` tests at once; ``shard`` ``(I, N)`` or ``"I/N"`` runs only the tests whose index
    in the grid is I modulo N. Finished tests are skipped, interrupted ones resumed.
    Ctrl-C stops the running tests at their checkpoints and raises KeyboardInterrupt; a
    later call continues. Tests that failed are listed in :attr:`Campaign.failed`; a sweep
    file that cannot run raises :class:`CampaignError`."""
    g, total, ended, failed, stopped, elsewhere = _cdlab.run_campaign(
        os.fspath(sweep), jobs=int(jobs), shard=_shard(shard), dry_run=dry_run
    )
    return Campaign(
        g, total, ended, [(Path(d), w) for d, w in failed], [Path(d) for d in stopped], [Path(d) for d in elsewhere]
    )
