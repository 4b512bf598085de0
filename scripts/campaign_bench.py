#!/usr/bin/env python3
"""Benchmark (not a test): the IMU-selection campaign on Dask — runs per second on 1 and 2
workers of a LocalCluster, against the same tasks run in-process, and where the time goes:
the run itself (simulate + navigate, in Rust), the per-worker campaign build, and the
per-task overhead of Dask (scheduling, pickling, the summary's transfer).

    python scripts/campaign_bench.py [--runs 8] [--duration 120]

Needs the Python package and distributed (docs/python.md). Prints a Markdown table."""

import argparse
import os
import statistics
import sys
import time

import distributed

from imu_emu import campaign

def timed_task(spec_json, task):
    t0 = time.perf_counter()
    s = campaign.run_task(spec_json, task)
    return s, time.perf_counter() - t0


def main():
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
    rows = [("in-process, 1 thread", serial, 1, statistics.mean(per))]

    summaries = [campaign.run_task(c.spec_json, t) for t in tasks]
    t0 = time.perf_counter()
    reference = c.merge(summaries).rows_json
    merge = time.perf_counter() - t0
    for workers in (1, 2):
        with distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster, \
                distributed.Client(cluster) as client:
            # Warm the workers (import, campaign build) outside the timing, as a long campaign
            # amortises them.
            client.run(campaign.Campaign, SPEC)
            t0 = time.perf_counter()
            futures = client.map(timed_task, [c.spec_json] * len(tasks), tasks)
            done = client.gather(futures)
            wall = time.perf_counter() - t0
            merged = c.merge([d[0] for d in done]).rows_json
            assert merged == reference, "the Dask table differs from the in-process one"
            run = statistics.mean(d[1] for d in done)
            rows.append((f"Dask LocalCluster, {workers} worker(s)", wall, workers, run))

    print("| how | wall (s) | runs/s | worker time per run (ms) | run itself (ms) "
          "| overhead per run (ms) |")
    print("|---|---|---|---|---|---|")
    for how, wall, w, run in rows:
        per_run = wall * w / len(tasks)
        print(f"| {how} | {wall:.2f} | {len(tasks) / wall:.2f} | {per_run * 1e3:.1f} "
              f"| {run * 1e3:.1f} | {(per_run - run) * 1e3:.1f} |")
    print()
    print(f"run itself in-process (simulate + navigate one task, Rust): mean "
          f"{statistics.mean(per) * 1e3:.1f} ms, min {min(per) * 1e3:.1f}, max {max(per) * 1e3:.1f}")
    print(f"campaign build (once per worker and spec): {build * 1e3:.1f} ms")
    print(f"summary: {statistics.mean(sizes) / 1e3:.1f} kB of JSON per task; merging "
          f"{len(tasks)} summaries: {merge * 1e3:.1f} ms")
    print(f"cores here: {os.cpu_count()}, load average {os.getloadavg()[0]:.1f} at the end")


if __name__ == "__main__":
    main()
