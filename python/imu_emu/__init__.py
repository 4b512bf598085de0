"""imu-emu for Python: the imu-emu engine's IMU records, frames, analysis and live emulator.

Every function runs the Rust library (the same code as the ``imu-emu`` command line) with
the GIL released, and returns numpy arrays, plain dicts or bytes. Errors are raised as
:class:`ImuEmuError` with the library's message (the text the CLI prints).

Conventions (``docs/signals.md``): NED local level, body x forward / y right / z down,
attitude as roll, pitch, yaw in degrees, SI units in every array.
"""

from __future__ import annotations

import os
import tomllib
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import ImuEmuError

__all__ = [
    "ImuEmuError",
    "Records",
    "Result",
    "Emulator",
    "simulate",
    "encode",
    "decode",
    "analyze",
    "fit",
    "names",
    "COLUMNS",
    "STAGES",
]

__version__ = _native.__version__

#: Columns of a record row, in order (the CSV and binary record contract).
COLUMNS = (
    "t",
    "gyro_x", "gyro_y", "gyro_z",
    "accel_x", "accel_y", "accel_z",
    "dtheta_x", "dtheta_y", "dtheta_z",
    "dv_x", "dv_y", "dv_z",
)

#: The error stage kinds, in the order of the injected-error columns.
STAGES = (
    "vibration", "size_effect", "scale_factor", "bias", "misalignment", "noise", "quantization",
)

PathLike = Union[str, "os.PathLike[str]"]


@dataclass(frozen=True)
class Records:
    """IMU records: ``rows`` is the (n, 13) array in :data:`COLUMNS` order; the named
    attributes are views into it (no copies)."""

    rows: np.ndarray

    @property
    def t(self) -> np.ndarray:
        """Record times t_k (s), the end of each interval."""
        return self.rows[:, 0]

    @property
    def gyro(self) -> np.ndarray:
        """Interval-mean angular rates Δθ/Δt (rad/s), (n, 3)."""
        return self.rows[:, 1:4]

    @property
    def accel(self) -> np.ndarray:
        """Interval-mean specific forces Δv/Δt (m/s²), (n, 3)."""
        return self.rows[:, 4:7]

    @property
    def dtheta(self) -> np.ndarray:
        """Angle increments Δθ over each interval (rad), (n, 3); no coning compensation."""
        return self.rows[:, 7:10]

    @property
    def dv(self) -> np.ndarray:
        """Velocity increments Δv over each interval (m/s), (n, 3); no sculling compensation."""
        return self.rows[:, 10:13]

    def __len__(self) -> int:
        return self.rows.shape[0]


@dataclass(frozen=True)
class Result:
    """What :func:`simulate` returns."""

    #: The IMU's records after its error model.
    records: Records
    #: The error-free records on the same time grid (``None`` with ``truth=False``).
    truth: Optional[Records]
    #: Per stage kind (:data:`STAGES`), the error it injected into each record:
    #: ``{"bias": {"gyro": (n, 3), "accel": (n, 3)}, …}`` (``None`` with ``errors=False``).
    errors: Optional[dict]
    #: The injected errors as ``--truth-errors`` writes them: (n, 1 + 42), t first.
    error_rows: Optional[np.ndarray]
    #: The main output's bytes as ``imu-emu generate`` writes them: CSV text, binary records
    #: or a protocol's frames (``format=``).
    output: bytes
    #: IMU rate (Hz), master seed and template name of the run.
    rate: float
    seed: int
    imu: str
    warnings: list = field(default_factory=list)
    #: With ``pose=True``: the truth trajectory at t₀ + k/rate, k = 0 … n (one more row than
    #: the records: record k covers (t_{k-1}, t_k]) as ``{"t", "lat", "lon" (deg), "h" (m),
    #: "v_ned" (n+1, 3) m/s, "rpy" (n+1, 3) deg}`` — the arrays ``trajectory=`` takes.
    pose: Optional[dict] = None


_TRAJECTORY_KEYS = ("t", "lat", "lon", "h", "v_ned", "rpy")


def _trajectory_rows(traj: Mapping[str, Any]) -> np.ndarray:
    missing = [k for k in _TRAJECTORY_KEYS if k not in traj]
    if missing:
        raise ImuEmuError(
            "trajectory arrays: missing " + ", ".join(f"`{k}`" for k in missing)
            + " (expected t, lat, lon, h, v_ned (n, 3), rpy (n, 3))"
        )
    extra = sorted(set(traj) - set(_TRAJECTORY_KEYS))
    if extra:
        raise ImuEmuError(
            "trajectory arrays: unknown key " + ", ".join(f"`{k}`" for k in extra)
            + " (expected t, lat, lon, h, v_ned, rpy)"
        )
    t = np.asarray(traj["t"], dtype=float)
    n = t.shape[0] if t.ndim == 1 else -1
    cols = []
    for k, width in (("t", 1), ("lat", 1), ("lon", 1), ("h", 1), ("v_ned", 3), ("rpy", 3)):
        a = np.asarray(traj[k], dtype=float)
        want = (n,) if width == 1 else (n, 3)
        if a.shape != want:
            raise ImuEmuError(
                f"trajectory arrays: `{k}` has shape {a.shape}, expected {want} "
                f"(n = {n} samples of `t`)"
            )
        cols.append(a.reshape(n, width))
    return np.ascontiguousarray(np.hstack(cols))


def simulate(
    scene: Optional[str] = None,
    *,
    scene_file: Optional[PathLike] = None,
    trajectory: Union[None, PathLike, Mapping[str, Any]] = None,
    motion_def: Optional[PathLike] = None,
    imu: Union[None, str, PathLike, Mapping[str, Any]] = None,
    rate: Optional[float] = None,
    duration: Optional[float] = None,
    start: Optional[float] = None,
    seed: Optional[int] = None,
    format: Optional[str] = None,
    protocol_file: Optional[PathLike] = None,
    interpolation: Optional[str] = None,
    stencil: Optional[int] = None,
    quadrature: Optional[int] = None,
    truth: bool = True,
    errors: bool = True,
    pose: bool = False,
) -> Result:
    """Simulates one IMU on a motion, as ``imu-emu generate`` does.

    The motion is one of: ``scene`` (a built-in scene name, :func:`names`), ``scene_file``
    (a TOML scene file; the other arguments override its keys), ``trajectory`` (a trajectory
    CSV file, or a mapping of arrays ``t`` (s), ``lat``, ``lon`` (deg), ``h`` (m), ``v_ned``
    (n, 3) m/s, ``rpy`` (n, 3) roll, pitch, yaw in degrees — checked as a file's rows are) or
    ``motion_def`` (a gnss-ins-sim motion definition or native mission file).

    ``imu`` is a template name (``"stim300"``, ``"ln200:typical"``), a template file, or a
    dict with a template file's keys (``templates/README.md``). ``rate`` (Hz),
    ``duration``/``start`` (s) and ``seed`` as the CLI flags; ``format`` (``csv``, ``bin`` or a
    protocol name) decides :attr:`Result.output`.

    Returns the records, the error-free truth and the error each stage injected; with the same
    arguments and seed, ``records.rows`` holds exactly the numbers ``imu-emu generate`` writes.
    """
    traj_path = None
    rows = None
    if isinstance(trajectory, Mapping):
        rows = _trajectory_rows(trajectory)
    elif trajectory is not None:
        traj_path = os.fspath(trajectory)
    if isinstance(imu, os.PathLike):
        imu = os.fspath(imu)
    d = _native.simulate(
        scene,
        scene_file=None if scene_file is None else os.fspath(scene_file),
        trajectory=traj_path,
        trajectory_rows=rows,
        motion_def=None if motion_def is None else os.fspath(motion_def),
        imu=imu,
        rate=rate,
        duration=duration,
        start=start,
        seed=seed,
        format=format,
        protocol_file=None if protocol_file is None else os.fspath(protocol_file),
        interpolation=interpolation,
        stencil=stencil,
        quadrature=quadrature,
        truth=truth,
        errors=errors,
        pose=pose,
    )
    err = None
    err_rows = d.get("errors")
    if err_rows is not None:
        err = {}
        for i, k in enumerate(STAGES):
            base = 1 + 6 * i
            err[k] = {"gyro": err_rows[:, base:base + 3], "accel": err_rows[:, base + 3:base + 6]}
    return Result(
        records=Records(d["records"]),
        truth=Records(d["truth"]) if "truth" in d else None,
        errors=err,
        error_rows=err_rows,
        output=d["output"],
        rate=d["rate"],
        seed=d["seed"],
        imu=d["imu"],
        warnings=list(d["warnings"]),
        pose=_pose(d["pose"]) if "pose" in d else None,
    )


def _pose(a: np.ndarray) -> dict:
    return dict(t=a[:, 0], lat=a[:, 1], lon=a[:, 2], h=a[:, 3], v_ned=a[:, 4:7], rpy=a[:, 7:10])


def _rows(records: Any) -> np.ndarray:
    if isinstance(records, Result):
        records = records.records
    if isinstance(records, Records):
        records = records.rows
    return np.ascontiguousarray(np.asarray(records, dtype=float))


def encode(
    records: Any,
    protocol: str,
    *,
    rate: Union[None, float, str] = None,
    temperature: float = 25.0,
    gps_time: Optional[tuple] = None,
) -> bytes:
    """Encodes records ((n, 13) rows, :class:`Records` or a :class:`Result`) as frames of
    ``protocol`` (a built-in name or a spec file), as ``generate --format`` writes them from
    the first frame on. ``rate`` (Hz or ``"nominal"``) sets the frame rate of rate-dependent
    fields; ``temperature`` (°C) fills a temperature field; ``gps_time`` = (week, seconds of
    week) of t = 0 for GPS-time fields."""
    return _native.encode(
        _rows(records), os.fspath(protocol), rate=rate, temperature=temperature, gps_time=gps_time
    )


def decode(
    data: Union[bytes, bytearray, memoryview],
    protocol: str,
    *,
    rate: Union[None, float, str] = None,
    native: bool = False,
) -> dict:
    """Decodes a byte stream of ``protocol`` frames as ``imu-emu decode`` does.

    Returns ``{"columns": [...], "values": (frames, columns) array (NaN where a frame has no
    value), "message": message index per frame, "messages": names, "stats": {frames,
    check_failures, counter_gaps, …}}``. The columns are the record contract (:data:`COLUMNS`)
    then the frame's other fields, or the protocol's own fields with ``native=True``.
    ``rate`` (Hz or ``"nominal"``) as ``decode --rate``. Raises :class:`ImuEmuError` when no
    frame decodes."""
    return _native.decode(bytes(data), os.fspath(protocol), rate=rate, native=native)


def _input(records: Any):
    if isinstance(records, (str, os.PathLike)):
        return None, os.fspath(records)
    return _rows(records), None


def analyze(
    records: Any,
    *,
    format: Optional[str] = None,
    rate: Optional[float] = None,
    imu: Optional[str] = None,
    segment: int = 16384,
    keep_transients: bool = False,
) -> dict:
    """Statistics, octave Allan deviation with its 68 % χ² band, Welch PSD and the fitted IEEE
    terms (Q, N, B, K, R) of each of the six channels, as ``imu-emu analyze`` computes them.

    ``records``: rows (t, gyro, accel first), :class:`Records`, a :class:`Result`, or a
    recording file (``format``: csv, bin or a protocol name; default by extension). ``imu``
    (a template name or file) adds ``"template"``: per sensor, axis and term the specified
    and fitted values, the acceptance band and the verdict.

    Transients (knocks, spikes: a step beyond 20 times its channel's step RMS) are left out of
    every statistic with 1 s on each side, as the CLI does, unless ``keep_transients``;
    ``"transients"`` is None or ``{"handling": "left out" | "kept" | "heavy-tailed",
    "threshold", "left_out": samples, "list": [{"first", "last", "channel", "step", "z"}]}``."""
    rows, path = _input(records)
    return _native.analyze(rows, path=path, format=format, rate=rate, imu=imu, segment=segment,
                           keep_transients=keep_transients)


def fit(
    records: Any,
    *,
    format: Optional[str] = None,
    rate: Optional[float] = None,
    name: Optional[str] = None,
    segment: int = 16384,
    keep_transients: bool = False,
) -> dict:
    """Fits an IMU template to a static recording, as ``imu-emu fit`` does (transients left
    out unless ``keep_transients``, as in :func:`analyze`).

    Returns ``{"toml": the template file's text (loadable by ``imu=``), "template": the same
    as a dict (pass it as ``simulate(imu=...)``)}``."""
    rows, path = _input(records)
    text = _native.fit(rows, path=path, format=format, rate=rate, name=name, segment=segment,
                       keep_transients=keep_transients)
    return {"toml": text, "template": tomllib.loads(text)}


def names() -> dict:
    """The built-in ``scenes``, ``templates`` and ``protocols``."""
    return _native.names()


class Emulator:
    """The live emulator: a paced run of frames to pseudo-terminals, UDP, serial devices or
    files, as ``imu-emu run`` does, on a thread of its own.

    Use it as a context manager: the run starts on entry (every refusal raised there) and is
    stopped on exit::

        with imu_emu.Emulator("static", imu="stim300", format="stim300",
                              sinks=["udp:127.0.0.1:9000"]) as emu:
            ...                      # frames arrive at 127.0.0.1:9000 in real time
        print(emu.report["summary"])

    ``sinks`` are the CLI's sink addresses (``pty:/tmp/imu``, ``udp:HOST:PORT``,
    ``serial:/dev/ttyUSB0``, ``file:PATH``, each optionally ``,protocol=NAME``); without them
    the scene file's, else one pty (its path in :meth:`notes`). ``speed`` is the factor of real
    time. The other arguments are :func:`simulate`'s (the default IMU and format are
    ``ln200``, as ``imu-emu run``'s)."""

    def __init__(
        self,
        scene: Optional[str] = None,
        *,
        scene_file: Optional[PathLike] = None,
        trajectory: Optional[PathLike] = None,
        motion_def: Optional[PathLike] = None,
        imu: Union[None, str, PathLike, Mapping[str, Any]] = None,
        format: Optional[str] = None,
        sinks: Optional[Sequence[str]] = None,
        speed: float = 1.0,
        rate: Optional[float] = None,
        duration: Optional[float] = None,
        seed: Optional[int] = None,
    ) -> None:
        f = (lambda p: None if p is None else os.fspath(p))
        if isinstance(imu, os.PathLike):
            imu = os.fspath(imu)
        self._run = _native.LiveRun(
            scene,
            scene_file=f(scene_file),
            trajectory=f(trajectory),
            motion_def=f(motion_def),
            imu=imu,
            format=format,
            sinks=None if sinks is None else list(sinks),
            speed=speed,
            rate=rate,
            duration=duration,
            seed=seed,
        )
        #: The run's description (``imu-emu run --describe``), once started.
        self.description: Optional[str] = None
        #: The end-of-run report, once stopped: ended, stopped, frames, summary.
        self.report: Optional[dict] = None

    def start(self) -> "Emulator":
        """Builds and starts the run (raises :class:`ImuEmuError` if it is refused)."""
        self.description = self._run.start()
        return self

    def stop(self, timeout: Optional[float] = None) -> Optional[dict]:
        """Stops the run and waits for it to end; returns the report."""
        self._run.stop()
        self.report = self._run.wait(timeout)
        return self.report

    def wait(self, timeout: Optional[float] = None) -> Optional[dict]:
        """Waits for the run to end by itself (its duration); ``None`` after ``timeout`` s."""
        r = self._run.wait(timeout)
        if r is not None:
            self.report = r
        return r

    def status(self) -> dict:
        """The run's figures now: started, elapsed_s, per stream frames and skipped."""
        return self._run.status()

    def notes(self) -> list:
        """What the run announced (e.g. ``pty /dev/pts/7``)."""
        return self._run.notes()

    def __enter__(self) -> "Emulator":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()
