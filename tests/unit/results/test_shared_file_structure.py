"""A study's results files of one vehicle structure share the work of laying out their record variables
(vehicle.results.layout.create_file copies the empty record groups and checkpoint slots of the last file of the same
structure): each file still holds its own attributes and equilibria, and a file of another structure (other chunks,
compression, labels, bin edges) gets its own layout. And a road evaluated in one call gives every point the value it
gets alone (terrain.Road.evaluate works on the stretch a call covers)."""
from __future__ import annotations

import h5py
import numpy as np

from terrain.road import Road
from vehicle.results.layout import EQUILIBRIUM, SCENARIO, STATS, SUMMARY, TIMESERIES, create_file
from vehicle.results.reader import open_results
from vehicle.results.results_file import DriveFile, ResumePoint

STATIONS = ["axle1_left", "axle1_right", "axle2_left", "axle2_right"]
AXLES = ["axle1", "axle2"]


def _parts(title: str, load_N: float, edges=(0.0, 0.1, 0.2)):
    """(info, block, row, state) of a two-axle drive as run_info and Drive.describe shape them."""
    n = len(STATIONS)
    info = {"attrs": {"format": "hpsim-drive", "format_version": 2, "title": title},
            "scenario": {"yaml": f"title: {title}", "resolved_json": "{}", "stations": STATIONS, "axles": AXLES,
                         "distance_m": 100.0},
            "stations": STATIONS, "axles": AXLES,
            "equilibrium": {"before": {"wheel_loads_N": np.full(n, load_N), "temperatures_K": np.full(n, 300.0)}},
            "summary": {"status": "running", "complete": False, "build_s": 0.0},
            "seats": [], "stats_attrs": {"strut_temperature": {"bin_edges_m": np.asarray(edges)}}}
    block = {"t_s": np.array([0.0]), "distance_m": np.array([0.0]), "strut_temperature_K": np.full((n, 1), 300.0)}
    row = {"distance_end_m": 100.0, "duration_s": 1.0, "strut_temperature_K": np.full(n, 300.0)}
    state = {"t_s": 0.0, "s_m": 0.0, "x": np.zeros(5)}
    return info, block, row, state


def _layout(path) -> dict:
    """Every record variable's storage and attributes (dimension-scale references left out)."""
    out = {}
    with h5py.File(path, "r") as f:
        for group in (TIMESERIES, STATS):
            for name, ds in f[group].items():
                attrs = {k: np.asarray(v).tolist() for k, v in ds.attrs.items()
                         if k not in ("DIMENSION_LIST", "REFERENCE_LIST")}
                out[f"{group}/{name}"] = (ds.shape, ds.maxshape, ds.chunks, ds.compression, ds.compression_opts,
                                          ds.fletcher32, attrs)
    return out


def _create(path, parts, compression=4, chunk_rows=32):
    info, block, row, state = parts
    create_file(path, info, block, row, state, set(block), compression, chunk_rows)


def test_files_of_one_structure_keep_their_own_attributes_and_equilibria(tmp_path):
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    _create(a, _parts("first", 1000.0))
    _create(b, _parts("second", 2000.0))
    assert _layout(a) == _layout(b)
    for path, title, load in ((a, "first", 1000.0), (b, "second", 2000.0)):
        with h5py.File(path, "r") as f:
            assert f.attrs["title"] == title and f[SCENARIO].attrs["yaml"] == f"title: {title}"
            assert np.all(f[f"{EQUILIBRIUM}/before/wheel_load"][()] == load)
            assert f[SUMMARY].attrs["status"] == "running"
        with open_results(path, check=False) as r:
            assert r.counts() == (0, 0) and r.state() is None


def test_a_file_of_another_structure_gets_its_own_layout(tmp_path):
    _create(tmp_path / "a.h5", _parts("a", 1.0))
    for name, parts, kw in (("chunks", _parts("b", 1.0), {"chunk_rows": 64}),
                            ("compression", _parts("b", 1.0), {"compression": 0}),
                            ("edges", _parts("b", 1.0, edges=(0.0, 0.05, 0.1, 0.2)), {})):
        path = tmp_path / f"{name}.h5"
        _create(path, parts, **kw)
        with h5py.File(path, "r") as f:
            ds = f[f"{TIMESERIES}/strut_temperature"]
            assert ds.chunks[0] == kw.get("chunk_rows", 32)
            assert ds.compression == ("gzip" if kw.get("compression", 4) else None)
            assert list(f[f"{STATS}/strut_temperature"].attrs["bin_edges_m"]) == list(parts[0]["stats_attrs"]
                                                                                      ["strut_temperature"]
                                                                                      ["bin_edges_m"])


def test_a_copied_layout_takes_a_drive_and_its_checkpoints(tmp_path):
    """The second file of a structure (its layout copied) is written and read like the first."""
    for title in ("first", "second"):
        path = tmp_path / f"{title}.h5"
        info, block, row, state = _parts(title, 1.0)
        DriveFile(path).create(info, block, row, state, set(block), 4, 2)
        rf = DriveFile(path)
        sink = rf.open_sink(ResumePoint.start())
        n = len(STATIONS)
        for k in range(3):                      # blocks of 2 samples: a chunk each, a checkpoint each
            t = np.array([2.0 * k + 1, 2.0 * k + 2])
            sink.samples({"t_s": t, "distance_m": 10 * t, "strut_temperature_K": 300.0 + np.outer(np.arange(n), t)})
            sink.stats([dict(row, distance_end_m=10.0 * (k + 1))])
            sink.checkpoint(dict(state, t_s=float(t[-1])))
        rf.close_sink()
        with open_results(path) as r:
            assert r.counts() == (6, 3) and r.state()["t_s"] == 6.0
            assert np.array_equal(r.series("time"), np.arange(1.0, 7.0))
            assert np.array_equal(r.series("strut_temperature"), 300.0 + np.outer(np.arange(1.0, 7.0),
                                                                                   np.arange(n)))


def test_a_road_gives_each_point_its_value_whatever_else_the_call_holds():
    rng = np.random.default_rng(3)
    road = Road(0.05, rng.normal(0.0, 0.01, 4001), rng.normal(0.0, 0.01, 4001))
    # points on stretches far apart, before the start, past the end, exactly on knots, NaN
    s = np.concatenate([rng.uniform(-5.0, 205.0, 300), [0.0, 0.05, 100.0, road.length_m, np.nan]])
    with np.errstate(invalid="ignore"):             # NaN in, NaN out
        together = road.evaluate(s.reshape(5, -1), "right")
        alone_each = [road.evaluate(sj, "right") for sj in s]
    for j, alone in enumerate(alone_each):
        for whole, one in zip(together, alone):
            assert np.array_equal(whole.reshape(-1)[j], one, equal_nan=True)
            assert np.ndim(one) == 0
    assert together[0].shape == (5, len(s) // 5)
    h, m = road.evaluate(np.zeros((0, 3)), "left")
    assert h.shape == m.shape == (0, 3)
    # the clamped spline through the samples: heights at the knots, zero slope at the ends
    assert np.allclose(road.evaluate(np.arange(4001) * 0.05, "left")[0], road.heights("left"), rtol=0, atol=1e-12)
    assert road.evaluate(np.array([-1.0, road.length_m + 1.0]), "left")[1].tolist() == [0.0, 0.0]
