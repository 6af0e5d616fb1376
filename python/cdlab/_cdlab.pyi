"""Type hints of the compiled module ``cdlab._cdlab`` (python/src/lib.rs).

Arrays come as little-endian bytes; ``cdlab`` wraps them as NumPy arrays.
"""

from typing import Any, Callable, Dict, List, Optional, Tuple, Union

class CdlabError(Exception):
    """Base class of every error cdlab raises; ``str(e)`` names the field or file at fault."""

class InvalidParameterError(CdlabError):
    """A parameter outside its allowed range."""

    field: str
    value: str
    allowed: str

class ParseError(CdlabError):
    """A file that cannot be parsed."""

    path: str
    line: int

class NumericalError(CdlabError):
    """A time step that produced a non-finite value or too large an overlap."""

    step: int

class GpuError(CdlabError):
    """A GPU adapter or device failure."""

class NoAdapterError(GpuError):
    """No GPU adapter on this machine."""

class FileError(CdlabError):
    """A file or directory that cannot be read or is not what it should be."""

    path: str

class DamagedRecordError(FileError):
    """A run record whose content failed a check (chunk or checkpoint CRC, bad message)."""

    reason: str

class StoppedError(CdlabError):
    """A run stopped by a signal."""

    signal: int
    step: int

class RunError(CdlabError):
    """A run directory or file that cannot be used as asked."""

    path: str
    #: NoRun, Occupied, NoCheckpoint, Complete, Unfinished, OtherSettings, Damaged or NotRegular.
    fault: str

class CampaignError(CdlabError):
    """A campaign that cannot run as asked (sweep file, grid, failed tests)."""

    path: str

class Record:
    """A run or an archived test read whole by :func:`open_record`."""

    @property
    def path(self) -> str: ...
    @property
    def kind(self) -> str: ...
    @property
    def config_json(self) -> str: ...
    @property
    def summary_json(self) -> Optional[str]: ...
    @property
    def truncated(self) -> Optional[str]: ...
    @property
    def damaged(self) -> Optional[str]: ...
    @property
    def run_id(self) -> Optional[str]: ...
    @property
    def version(self) -> Optional[str]: ...
    @property
    def backend(self) -> Optional[str]: ...
    def series_columns(self) -> Dict[str, Union[bytes, List[str]]]: ...
    def snapshot_times(self) -> List[Tuple[float, float]]: ...
    def snapshot_disks(self, index: int) -> Dict[str, bytes]: ...
    def snapshot_contacts(self, index: int) -> Dict[str, bytes]: ...
    def snapshot_fabric_json(self, index: int) -> str: ...

def open_record(path: str, allow_damaged: bool = False) -> Record: ...
def campaign_report(paths: List[str]) -> Tuple[str, str, str]: ...
def series_fields() -> List[Tuple[str, str, str]]: ...
def library_version() -> str: ...

_Callback = Optional[Callable[[Dict[str, Any]], Any]]

def run_test(
    out: str,
    config_json: Optional[str] = None,
    config_path: Optional[str] = None,
    backend: Optional[str] = None,
    force: bool = False,
    progress: _Callback = None,
    sample: Optional[str] = None,
) -> str: ...
def resume_run(path: str, backend: Optional[str] = None, progress: _Callback = None) -> str: ...
def prepare_sample(
    out: str,
    config_json: Optional[str] = None,
    config_path: Optional[str] = None,
    progress: _Callback = None,
) -> Tuple[str, int, float, float, float]: ...
def run_campaign(
    sweep: str, jobs: int = 1, shard: Tuple[int, int] = (0, 1), dry_run: bool = False
) -> Tuple[int, int, int, List[Tuple[str, str]], List[str], List[str]]: ...
