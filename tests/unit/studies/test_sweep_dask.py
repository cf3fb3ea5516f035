"""`hpsim sweep --scheduler ADDRESS`: the same two-case sweep on a Dask distributed cluster.

Skipped when the optional `dask` extra (distributed) is not installed."""
import csv

import pytest

from vehicle import cli

from .test_sweep import BASE, SWEEP

distributed = pytest.importorskip("distributed")


def test_sweep_runs_on_a_dask_cluster(tmp_path):
    (tmp_path / "base.yaml").write_text(BASE)
    (tmp_path / "sweep.yaml").write_text(SWEEP)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        code = cli.main(["sweep", str(tmp_path / "sweep.yaml"), "--scheduler", cluster.scheduler_address,
                         "-o", str(tmp_path / "out")])
    assert code == 0
    with open(tmp_path / "out" / "summary.csv") as fh:
        rows = {r["case"]: r for r in csv.DictReader(fh)}
    assert len(rows) == 2 and all(r["status"] == "done" for r in rows.values())
    assert all((tmp_path / "out" / f"{name}.h5").exists() for name in rows)
