"""Results files that xarray reads natively (netCDF-4/CF via HDF5 dimension scales), and the in-memory
sink giving the same datasets: every group opens with named dimensions, coordinates and CF units;
a drive into memory and into a file give identical datasets; files of the previous layout (format 1)
are read through the same interface."""
from __future__ import annotations

import json
from pathlib import Path

import h5py
import numpy as np
import pytest

xr = pytest.importorskip("xarray")
pytest.importorskip("h5netcdf")

from vehicle import cli  # noqa: E402
from vehicle.results.reader import open_results  # noqa: E402
from vehicle.results.run import run_in_memory  # noqa: E402
from vehicle.scenario.schema import read_scenario  # noqa: E402
from vehicle.analysis.summary import report, report_from  # noqa: E402
from vehicle.physics.outputs import VARIABLES, UnknownDriveKey  # noqa: E402
from vehicle.results.variables import file_variables  # noqa: E402
from tests.helpers import REPO, scenario_yaml  # noqa: E402

SCENARIO = scenario_yaml(road={"iso_class": "D", "seed": 4}, distance="0.4 km",
                         initial_temperatures=["40 degC", "35 degC", "30 degC", "25 degC"],
                         output={"interval": "1 s", "stats_interval": "0.1 km", "chunk_samples": 30})
V1_FILE = REPO / "tests" / "data" / "results_v1.h5"   # written by hpsim before format 2
GROUPS = ("timeseries", "stats", "equilibrium/charged", "equilibrium/before", "equilibrium/after", "summary")
TIMING = {"wall_s", "solver_error_cost_pct", "build_s", "integration_s", "finished_at", "created", "history"}
UDUNITS = {"s", "m", "km", "m s-1", "m s-2", "rad", "rad s-2", "K", "Pa", "N", "J", "W", "m3", "1", "m s-1.75"}


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    d = tmp_path_factory.mktemp("xr")
    (d / "drive.yaml").write_text(SCENARIO)
    out = d / "drive.h5"
    assert cli.main(["run", str(d / "drive.yaml"), "-o", str(out), "--no-progress"]) == 0
    memory = run_in_memory(read_scenario(d / "drive.yaml"))
    return out, memory


def _without_timing(ds):
    ds = ds.copy()
    ds.attrs = {k: v for k, v in ds.attrs.items() if k not in TIMING}
    return ds


@pytest.mark.parametrize("group", GROUPS)
def test_every_group_opens_in_xarray_with_named_dims_and_units(runs, group):
    out, _ = runs
    ds = xr.open_dataset(out, group=group, engine="h5netcdf")
    assert not [d for d in ds.dims if str(d).startswith("phony")]
    assert list(ds["station"].values[:2]) == ["axle1_left", "axle1_right"] and list(ds["axle"].values) == [
        "axle1", "axle2", "axle3", "axle4"]
    assert len(ds.data_vars) >= 3
    for name, v in ds.data_vars.items():
        assert v.attrs["units"] in UDUNITS, (group, name, v.attrs)
        assert v.attrs["long_name"]
        assert not name.endswith(("_K", "_m", "_N", "_J", "_W", "_s", "_Pa")), name
        assert set(v.dims) <= {"time", "km", "station", "axle", "seat", "travel_bin", "travel_bin_edge"}
        if "seat" in v.dims:            # the ride metrics: labelled with the vehicle file's seats
            assert list(ds["seat"].values) == ["driver", "rear_crew"]
    if group == "timeseries":
        assert ds["time"].attrs["units"] == "s" and ds["distance"].attrs["units"] == "m"
        assert "distance" in ds.coords and ds["distance"].dims == ("time",)
        assert ds["wheel_load"].dims == ("time", "station") and ds["axle_height_change"].dims == ("time", "axle")
        # one quantity per variable: heave in m s-2, pitch and roll in rad s-2
        assert ds["heave_acceleration"].attrs["units"] == "m s-2" and ds["roll_acceleration"].attrs["units"] == "rad s-2"
        # physics: distance = speed x time at constant speed
        np.testing.assert_allclose(ds["distance"].values, ds["time"].values * 20 / 3.6, rtol=1e-9)
        # the total wheel load is the weight plus the hull's inertia: mean over the drive = static total
        total = ds["wheel_load"].sum("station")
        eq = xr.open_dataset(out, group="equilibrium/before", engine="h5netcdf")
        assert float(total.mean()) == pytest.approx(float(eq["wheel_load"].sum()), rel=0.01)
    if group == "stats":
        np.testing.assert_allclose(ds["km"].values, [0.1, 0.2, 0.3, 0.4])
        assert ds["km"].attrs["units"] == "km"
        # the mean dissipated powers over each interval integrate to the energies of the time series
        ts = xr.open_dataset(out, group="timeseries", engine="h5netcdf")
        E = sum(ds[f"power_{e}"] * ds["duration"] for e in ("valve", "friction", "gas", "end_stop")).sum("km")
        E_ts = sum(ts[f"energy_{e}"].isel(time=-1) for e in ("valve", "friction", "gas", "end_stop"))
        np.testing.assert_allclose(E.values, E_ts.values, rtol=1e-6)


def test_whole_file_as_a_datatree_and_global_attributes(runs):
    out, _ = runs
    tree = xr.open_datatree(out, engine="h5netcdf")
    assert tree.attrs["Conventions"] == "CF-1.8" and tree.attrs["format_version"] == 2
    assert tree.attrs["title"] and "hpsim" in tree.attrs["source"] and "started" in tree.attrs["history"]
    assert json.loads(tree["scenario"].attrs["resolved_json"])["scenario"]["distance"] == 400.0


def test_memory_sink_and_file_give_identical_datasets(runs):
    out, memory = runs
    mem_tree = memory.to_xarray()
    with open_results(out) as r:
        file_tree = r.to_xarray()
    for group in GROUPS + ("scenario",):
        native = _without_timing(xr.open_dataset(out, group=group, engine="h5netcdf").load())
        xr.testing.assert_identical(native, _without_timing(mem_tree[group].to_dataset()))
        xr.testing.assert_identical(native, _without_timing(file_tree[group].to_dataset()))
    assert {k: v for k, v in mem_tree.attrs.items() if k not in TIMING} == \
        {k: v for k, v in file_tree.attrs.items() if k not in TIMING}
    # the same report from memory as from the file
    a, b = report(out), report_from(memory, str(out))
    for k in ("axles", "load_shift_pct", "mean_temperature_rise_K", "distance_km", "energy_dissipated_MJ"):
        assert a[k] == b[k], k


def test_a_drive_key_missing_from_the_table_is_a_clear_error():
    with pytest.raises(UnknownDriveKey, match="vehicle/physics/outputs.py.*'seal_temperature_K'.*add one line"):
        file_variables("seal_temperature_K", (8,), "time", 8, 4)
    # a key with the table's default dim gets it from its width: stations or axles
    assert file_variables("wheel_load", (8,), "time", 8, 4)[0].dims == ("time", "station")
    assert file_variables("axle_height_change_m", (4,), "km", 8, 4)[0].dims == ("km", "axle")
    # every name is unique per quantity: one (units, dims) per variable name across the table
    seen = {}
    for key, entry in VARIABLES.items():
        for v in getattr(entry, "parts", (entry,)):
            assert seen.setdefault(v.name, v.units) == v.units, (key, v.name)


def test_format_1_files_are_read_through_the_same_interface(tmp_path, capsys):
    with h5py.File(V1_FILE, "r") as f:
        assert f.attrs["format_version"] == 1 and "strut_temperature_K" in f["timeseries"]
        T_v1 = f["timeseries/strut_temperature_K"][()]
        acc_v1 = f["timeseries/hull_acceleration"][()]
        N_after_v1 = f["equilibrium/after/wheel_loads_N"][()]
    with open_results(V1_FILE) as r:
        np.testing.assert_array_equal(r.series("strut_temperature"), T_v1)
        np.testing.assert_array_equal(r.series("pitch_acceleration"), acc_v1[:, 1])
        np.testing.assert_array_equal(r.equilibrium("after")["wheel_load"], N_after_v1)
        ds = r.to_xarray(group="timeseries")
        assert ds["wheel_load"].dims == ("time", "station") and ds["wheel_load"].attrs["units"] == "N"
    assert cli.main(["report", str(V1_FILE), "--json"]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["status"] == "complete" and rep["axles"][0]["N_after_daN"] == pytest.approx(
        0.5 * (N_after_v1[0] + N_after_v1[1]) / 10)
    assert cli.main(["plot", str(V1_FILE), "-o", str(tmp_path / "v1.png")]) == 0
    # a format-1 file cannot be resumed into: one line saying so
    import shutil

    copy = tmp_path / "v1.h5"
    shutil.copy(V1_FILE, copy)
    with h5py.File(copy, "r+") as f:
        f["summary"].attrs["status"] = "interrupted"
    assert cli.main(["run", str(tmp_path / "none.yaml"), "-o", str(copy), "--resume", "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "older hpsim" in err and "--overwrite" in err and len(err.strip().splitlines()) == 1
