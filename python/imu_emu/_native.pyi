"""Type stubs of the native module (``python/src/*.rs``); ``imu_emu`` wraps it."""

from typing import Any, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

__version__: str

class ImuEmuError(ValueError):
    """An input or setting the library refused; the message is the library's."""

def simulate(
    scene: Optional[str] = None,
    *,
    scene_file: Optional[str] = None,
    trajectory: Optional[str] = None,
    trajectory_rows: Optional[npt.NDArray[np.float64]] = None,
    motion_def: Optional[str] = None,
    imu: Union[None, str, dict[str, Any]] = None,
    rate: Optional[float] = None,
    duration: Optional[float] = None,
    start: Optional[float] = None,
    seed: Optional[int] = None,
    format: Optional[str] = None,
    protocol_file: Optional[str] = None,
    interpolation: Optional[str] = None,
    stencil: Optional[int] = None,
    quadrature: Optional[int] = None,
    truth: bool = True,
    errors: bool = True,
    pose: bool = False,
) -> dict[str, Any]: ...
def names() -> dict[str, list[str]]: ...
def encode(
    records: npt.NDArray[np.float64],
    protocol: str,
    *,
    rate: Union[None, float, str] = None,
    temperature: float = 25.0,
    gps_time: Optional[tuple[int, float]] = None,
) -> bytes: ...
def decode(
    data: bytes, protocol: str, *, rate: Union[None, float, str] = None, native: bool = False
) -> dict[str, Any]: ...
def analyze(
    records: Optional[npt.NDArray[np.float64]] = None,
    *,
    path: Optional[str] = None,
    format: Optional[str] = None,
    rate: Optional[float] = None,
    imu: Optional[str] = None,
    segment: int = 16384,
    keep_transients: bool = False,
) -> dict[str, Any]: ...
def fit(
    records: Optional[npt.NDArray[np.float64]] = None,
    *,
    path: Optional[str] = None,
    format: Optional[str] = None,
    rate: Optional[float] = None,
    name: Optional[str] = None,
    segment: int = 16384,
    keep_transients: bool = False,
) -> str: ...

class LiveRun:
    def __init__(
        self,
        scene: Optional[str] = None,
        *,
        scene_file: Optional[str] = None,
        trajectory: Optional[str] = None,
        motion_def: Optional[str] = None,
        imu: Union[None, str, dict[str, Any]] = None,
        format: Optional[str] = None,
        sinks: Optional[Sequence[str]] = None,
        speed: float = 1.0,
        rate: Optional[float] = None,
        duration: Optional[float] = None,
        seed: Optional[int] = None,
    ) -> None: ...
    def start(self) -> str: ...
    def stop(self) -> None: ...
    def finished(self) -> bool: ...
    def wait(self, timeout: Optional[float] = None) -> Optional[dict[str, Any]]: ...
    def status(self) -> dict[str, Any]: ...
    def notes(self) -> list[str]: ...

class Campaign:
    """A resolved campaign (`src/nav/campaign/`); pickles as its spec."""

    def __init__(self, spec_json: str) -> None: ...
    @property
    def spec_json(self) -> str: ...
    @property
    def seed(self) -> int: ...
    @property
    def notes(self) -> list[str]: ...
    def missions(self) -> list[tuple[str, list[tuple[str, float]]]]: ...
    def aided(self, mission: int) -> bool: ...
    def tasks(self) -> list[tuple[int, int, int, int]]: ...
    def run_task(self, task: tuple[int, int, int, int]) -> str: ...
    def merge(self, summaries: list[str]) -> str: ...
    def run_local(self, threads: int) -> str: ...
    def header(self, rows_json: str) -> str: ...
    def plot_title(self) -> str: ...
    @staticmethod
    def table(rows_json: str) -> str: ...
    @staticmethod
    def growth_csv(rows_json: str) -> str: ...
    @staticmethod
    def plot(rows_json: str, path: str, what: str) -> None: ...
