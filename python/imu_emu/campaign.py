"""The IMU-selection campaign — units × missions × outage lengths × seeded runs — on one
machine or as tasks on a Dask cluster, merged into ``imu-emu compare``'s median/95 % table.

A campaign is described by a spec dict with the fields of the library's ``CampaignSpec``
(``src/nav/campaign/mod.rs``)::

    spec = {
        "missions": [{"scene": "survey"}, {"scene_file": "examples/rig_aided.toml"}],
        "templates": ["ln200", "stim300", "adis16488"],
        "duration_s": 300, "outages_s": [30, 60], "runs": 20, "seed": 1,
        "aiding": "gnss",           # "auto" (the scene file's [gnss]), "gnss" or "free"
    }

Each task is one seeded run of one unit on one mission with one outage length; its result is
a small summary (the run's error samples). The merge pools the summaries' samples and takes
order statistics, so the table is a function of the *set* of summaries: the same whatever
ran where, in which order — :func:`run_dask` gives exactly :func:`run_local`'s table.
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from typing import Any, Iterable, Optional, Sequence

from . import _native

__all__ = ["Campaign", "CampaignResult", "run_local", "run_dask", "run_task"]


@functools.lru_cache(maxsize=8)
def _campaign(spec_json: str) -> "_native.Campaign":
    # One resolved campaign per spec and process: a worker builds it on its first task only.
    return _native.Campaign(spec_json)


def run_task(spec_json: str, task: tuple) -> str:
    """Runs one task of the campaign ``spec_json`` (JSON text) and returns its summary (JSON
    text). This is the function a Dask worker runs."""
    return _campaign(spec_json).run_task(tuple(task))


def run_tasks(spec_json: str, tasks: Sequence[tuple]) -> list:
    """Runs several tasks in one call (a batch: one scheduler round trip for many runs)."""
    c = _campaign(spec_json)
    return [c.run_task(tuple(t)) for t in tasks]


@dataclass(frozen=True)
class CampaignResult:
    """A merged campaign: its rows and the table, CSV and plot of ``imu-emu compare``."""

    #: One row per (mission, unit, outage length): mission, unit, grade, rate_hz, outage_s,
    #: aided, windows, samples, growth (per point: t and median/p95 of position (m), velocity
    #: (m/s), attitude (rad)).
    rows: list
    rows_json: str
    #: What ``imu-emu compare`` prints above the table (the runs, the notes).
    header: str
    #: The growth plot's subtitle.
    plot_title: str

    @property
    def table(self) -> str:
        """The median/95 % table, as ``imu-emu compare`` prints it."""
        return _native.Campaign.table(self.rows_json)

    @property
    def report(self) -> str:
        """``imu-emu compare``'s whole output: the header, the notes and the table."""
        return self.header + self.table

    @property
    def growth_csv(self) -> str:
        """The growth CSV, as ``imu-emu compare --csv`` writes it."""
        return _native.Campaign.growth_csv(self.rows_json)

    def plot(self, path: str) -> None:
        """The growth plot (PNG or SVG), as ``imu-emu compare --plot`` draws it."""
        _native.Campaign.plot(self.rows_json, str(path), self.plot_title)


class Campaign:
    """A campaign resolved from its spec dict (every refusal raised here)."""

    def __init__(self, spec: dict[str, Any]) -> None:
        self.spec_json = json.dumps(spec, sort_keys=True)
        self._native = _campaign(self.spec_json)

    @property
    def seed(self) -> int:
        """The master seed the runs' seeds derive from."""
        return self._native.seed

    @property
    def notes(self) -> list:
        """Notes for the table's header."""
        return self._native.notes

    def missions(self) -> list:
        """Per mission: its name and its units' (name, rate)."""
        return self._native.missions()

    def tasks(self) -> list:
        """Every task as (mission, unit, outage, run)."""
        return self._native.tasks()

    def merge(self, summaries: Iterable[str]) -> CampaignResult:
        """Merges task summaries (any order, every task once)."""
        return self._result(self._native.merge(list(summaries)))

    def _result(self, rows_json: str) -> CampaignResult:
        return CampaignResult(json.loads(rows_json), rows_json, self._native.header(rows_json),
                              self._native.plot_title())


def run_local(spec: dict[str, Any], threads: int = 1) -> CampaignResult:
    """Runs every task on ``threads`` local threads (``imu-emu compare``'s way) and merges."""
    c = Campaign(spec)
    return c._result(c._native.run_local(threads))


def run_dask(spec: dict[str, Any], client: Any, batch: int = 1) -> CampaignResult:
    """Runs the campaign's tasks on a Dask cluster and merges their summaries.

    ``client`` is a ``distributed.Client`` on any cluster: a ``LocalCluster``, Slurm via
    ``dask_jobqueue.SLURMCluster``, Kubernetes via ``dask_kubernetes`` (docs/python.md).
    ``batch`` runs that many tasks per Dask task (fewer scheduler round trips when runs are
    short). The workers need this package installed; the spec's files must be readable there
    at the same paths."""
    c = Campaign(spec)
    tasks = c.tasks()
    chunks = [tasks[i:i + max(1, batch)] for i in range(0, len(tasks), max(1, batch))]
    futures = client.map(run_tasks, [c.spec_json] * len(chunks), chunks)
    summaries = [s for chunk in client.gather(futures) for s in chunk]
    return c.merge(summaries)
