"""The campaign on Dask: tasks on a LocalCluster of two worker processes, merged, give exactly
the table of a single-machine run of the same seeds (and `imu-emu compare`'s)."""

import json
import random

import pytest

import imu_emu
from imu_emu import campaign

# Two templates × two outage lengths × 3 seeded runs, GNSS-aided between outages: 12 tasks of
# a fraction of a second each.
SPEC = {
    "missions": [{"scene": "circle"}],
    "templates": ["stim300", "adis16488"],
    "rate_hz": 100.0,
    "duration_s": 40.0,
    "outages_s": [5.0, 10.0],
    "runs": 3,
    "seed": 7,
    "points": 5,
    "aiding": "gnss",
    "aided_s": 10.0,
}


@pytest.fixture(scope="module")
def local():
    return campaign.run_local(SPEC, threads=2)


def test_dask_table_equals_single_machine(local):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            on_dask = campaign.run_dask(SPEC, client)
            batched = campaign.run_dask(SPEC, client, batch=5)
    assert on_dask.rows_json == local.rows_json
    assert batched.rows_json == local.rows_json
    assert on_dask.table == local.table
    assert len(local.rows) == 4 and all(r["aided"] for r in local.rows)


def test_merge_is_order_free_and_complete(local):
    c = campaign.Campaign(SPEC)
    summaries = [campaign.run_task(c.spec_json, t) for t in c.tasks()]
    random.Random(1).shuffle(summaries)
    assert c.merge(summaries).rows_json == local.rows_json
    with pytest.raises(imu_emu.ImuEmuError, match="merge: no summary of task"):
        c.merge(summaries[1:])


def test_table_is_cli_compare(cli, local, tmp_path):
    out = cli("compare", "--scene", "circle", "--imu", "stim300,adis16488", "--rate", 100,
              "--duration", 40, "--outage", "5,10", "--runs", 3, "--seed", 7, "--points", 5,
              "--gnss", "--aided", 10, "--csv", "g.csv", cwd=tmp_path).stdout.decode()
    assert out == local.report
    assert (tmp_path / "g.csv").read_text() == local.growth_csv


def test_spec_refusals_are_named():
    with pytest.raises(imu_emu.ImuEmuError, match="unknown field `outage`"):
        campaign.Campaign(dict(SPEC, outage=[5.0]))
    with pytest.raises(imu_emu.ImuEmuError, match="no-such-imu"):
        campaign.Campaign(dict(SPEC, templates=["no-such-imu"]))


def test_plot(local, tmp_path):
    assert local.plot_title == "5/10 s outages, GNSS-aided before"
    local.plot(tmp_path / "growth.png")
    assert (tmp_path / "growth.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
