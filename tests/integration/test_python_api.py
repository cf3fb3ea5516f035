"""The Python API (issue 9 §4, docs/python.md): Simulation in memory and into HDF5 give identical results,
open_results reads any file into the same object, and the example script runs."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import vehicle
from tests.helpers import REPO

ROOT = REPO
QUICK = ROOT / "scenarios" / "quick_demo.yaml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    sim = vehicle.Simulation(QUICK, overrides={"distance": "250 m", "output.stats_interval": "100 m"})
    mem = sim.run()
    path = tmp_path_factory.mktemp("api") / "run.h5"
    disk = sim.run(out=path)
    yield sim, mem, disk, path
    disk.close()


def test_memory_and_file_give_identical_results(runs):
    _, mem, disk, _ = runs
    a, b = mem.summary(), disk.summary()
    assert a["axles"] == b["axles"] and a["status"] == b["status"] == "complete"
    tm, tf = mem.to_xarray(), disk.to_xarray()
    for group in ("timeseries", "stats", "equilibrium/before", "equilibrium/after"):
        dm, df = tm[group].to_dataset(), tf[group].to_dataset()
        assert set(dm.data_vars) == set(df.data_vars)
        for name in dm.data_vars:
            np.testing.assert_array_equal(dm[name].values, df[name].values, err_msg=f"{group}/{name}")
            assert dm[name].dims == df[name].dims and dm[name].attrs.get("units") == df[name].attrs.get("units")


def test_ride_metrics_in_memory_and_file(runs):
    """The ride metrics are the same read from memory and from the file, per seat and per station, and the
    whole-drive values of /summary (the quadratures since the start) agree with the rows' totals."""
    _, mem, disk, _ = runs
    a, b = mem.ride(), disk.ride()
    assert [s["seat"] for s in a["seats"]] == ["driver", "rear_crew"]
    assert a == b
    hist = disk.stats("strut_travel_histogram")
    assert hist.shape[1:] == (8, len(a["stations"][0]["bin_edges_m"]) - 1)
    total = disk.to_xarray("summary")
    for k, seat in enumerate(a["seats"]):
        assert float(total["weighted_rms_acceleration"][k]) == pytest.approx(seat["weighted_rms_acceleration_m_s2"],
                                                                             rel=1e-9)
        assert str(total["seat"].values[k]) == seat["seat"]
    np.testing.assert_allclose(total["strut_travel_histogram"].values.sum(axis=1), a["duration_s"], rtol=1e-9)


def test_overrides_are_applied_and_validated(runs):
    sim, mem, _, _ = runs
    assert sim.scenario.distance == pytest.approx(250.0)
    assert mem.summary()["planned_distance_km"] == pytest.approx(0.25)
    from hpsim.errors import UserInputError

    with pytest.raises(UserInputError, match="speed"):
        vehicle.Simulation(QUICK, overrides={"speed": "900 km/h"})


def test_open_results_and_report(runs, capsys):
    _, _, _, path = runs
    with vehicle.open_results(path) as res:
        text = res.report()
        assert "axle" in text and text in capsys.readouterr().out
        T = res.series("strut_temperature")
        assert T.shape[1] == 8 and np.all(T > 273.15)


def test_example_script_runs(tmp_path):
    import os

    env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
    res = subprocess.run([sys.executable, str(ROOT / "examples" / "notebook_tour.py"), str(tmp_path)],
                         capture_output=True, text=True, timeout=300, env=env)
    assert res.returncode == 0, res.stderr[-2000:]
    assert (tmp_path / "tour.h5").exists() and (tmp_path / "tour_dashboard.png").stat().st_size > 10_000
