#!/usr/bin/env python3
"""Benchmark (not a test): the IMU-selection campaign on Dask — runs per second on 1 and 2
workers of a LocalCluster, against the same tasks run in-process, and where the time goes:
the run itself (simulate + navigate, in Rust), the per-worker campaign build, and the
per-task overhead of Dask (scheduling, pickling, the summary's transfer).

    python scripts/campaign_bench.py [--runs 8] [--duration 120]

Needs the Python package and distributed (docs/python.md). Prints a Markdown table."""

import argparse
import json
import os
import statistics
import sys
import time

import distributed

from imu_emu import campaign

p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
p.add_argument("--runs", type=int, default=8, help="seeded runs per (unit, outage)")
p.add_argument("--duration", type=float, default=120.0, help="mission span (s)")
p.add_argument("--batch", type=int, default=1, help="tasks per Dask task")
a = p.parse_args()

SPEC = {
    "missions": [{"scene": "survey"}],
    "templates": ["ln200", "stim300", "adis16488"],
    "rate_hz": 200.0,
    "duration_s": a.duration,
    "outages_s": [30.0],
    "runs": a.runs,
    "seed": 1,
    "points": 20,
    "aiding": "gnss",
    "aided_s": 30.0,
}


def timed_task(spec_json, task):
    t0 = time.perf_counter()
    s = campaign.run_task(spec_json, task)
    return s, time.perf_counter() - t0


t0 = time.perf_counter()
c = campaign.Campaign(SPEC)
build = time.perf_counter() - t0
tasks = c.tasks()
print(f"campaign: {len(tasks)} tasks (3 units × 1 outage × {a.runs} runs), survey, "
      f"{a.duration:g} s at 200 Hz, GNSS-aided; build {build * 1e3:.1f} ms", file=sys.stderr)

# In-process, one task after another: the run itself.
t0 = time.perf_counter()
per = []
sizes = []
for t in tasks:
    s, dt = timed_task(c.spec_json, t)
    per.append(dt)
    sizes.append(len(s))
serial = time.perf_counter() - t0
rows = [("in-process, 1 thread", serial, len(tasks) / serial, None)]

reference = c.merge([campaign.run_task(c.spec_json, t) for t in tasks]).rows_json
for workers in (1, 2):
    with distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        # Warm the workers (import, campaign build) outside the timing, as a long campaign
        # amortises them.
        client.run(lambda s: campaign.Campaign(json.loads(s)) and None, c.spec_json)
        t0 = time.perf_counter()
        r = campaign.run_dask(SPEC, client, batch=a.batch)
        wall = time.perf_counter() - t0
        assert r.rows_json == reference, "the Dask table differs from the in-process one"
        rows.append((f"Dask LocalCluster, {workers} worker(s)", wall, len(tasks) / wall, workers))

mean = statistics.mean(per)
print(f"| how | wall (s) | runs/s | per run: wall × workers / runs (ms) |")
print(f"|---|---|---|---|")
for how, wall, rps, w in rows:
    per_run = wall * (w or 1) / len(tasks) * 1e3
    print(f"| {how} | {wall:.2f} | {rps:.2f} | {per_run:.1f} |")
print()
print(f"run itself (Rust: simulate + navigate one task): mean {mean * 1e3:.1f} ms, "
      f"min {min(per) * 1e3:.1f} ms, max {max(per) * 1e3:.1f} ms")
print(f"campaign build (once per worker and spec): {build * 1e3:.1f} ms")
print(f"summary size: {statistics.mean(sizes) / 1e3:.1f} kB of JSON per task")
for how, wall, rps, w in rows[1:]:
    overhead = wall * w / len(tasks) - mean
    print(f"{how}: overhead per run ≈ {overhead * 1e3:.1f} ms "
          f"({overhead / mean * 100:.1f} % of the run)")
print(f"cores here: {os.cpu_count()}")
