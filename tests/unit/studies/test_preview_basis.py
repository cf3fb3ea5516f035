"""The cost preview counts what a drive does: a multiscale drive's steps are those of its windows, whose share of
the road depends on the window plan, and the preview builds one engine per set of compiled libraries, not one per
design."""
from __future__ import annotations

import os

import pytest

from vehicle.numerics import drive_rate
from vehicle.results.run import run_scenario
from vehicle.scenario.schema import ScenarioSource, prepare, read_scenario
from vehicle.studies import cost
from tests.helpers import REPO

# two window plans of the quick demo's vehicle and road: dense windows on a short drive (4 windows of 380 m on 5 km,
# 30 % of the road) and sparse ones on a longer drive (4 windows of 230 m on 20 km, 5 % of the road)
DENSE = {"distance": "5 km", "solver": {"mode": "multiscale", "window": "350 m", "spacing": "1.6 km", "warm_up": "30 m"}}
SPARSE = {"distance": "20 km", "solver": {"mode": "multiscale", "window": "200 m", "spacing": "5 km", "warm_up": "30 m"}}


def _source(name: str, **overrides) -> ScenarioSource:
    src = read_scenario(REPO / "scenarios" / "quick_demo.yaml")
    return ScenarioSource(text=src.text, name=name, base_dir=src.base_dir, data={**src.data, **overrides})


@pytest.fixture
def private_record(tmp_path, monkeypatch):
    """The drive-rate record in a folder of the test's own (the compiled libraries still from the suite's cache)."""
    record = tmp_path / drive_rate.RECORD
    monkeypatch.setattr(drive_rate, "_path", lambda: record)
    return record


def test_a_multiscale_preview_from_another_window_plan_s_rate_is_near_its_own_drive(tmp_path, private_record):
    """A rate recorded on dense windows predicts a drive with sparse ones. Counted over the whole road the dense
    drive's rate is ~4x too low for the sparse one (its road is mostly gaps, which cost nothing); counted over the
    windows' steps both plans run at about one rate. Each drive twice, its faster run taken (a loaded machine's
    walls scatter by up to 1.5x from run to run)."""
    best = None
    for k in range(2):
        run_scenario(_source("dense", **DENSE), tmp_path / f"dense{k}.h5")
        rate = drive_rate.read("multiscale")
        assert rate is not None
        best = rate if best is None or rate["steps_per_s"] > best["steps_per_s"] else best
    drive_rate.record_entry(drive_rate.ENTRY["multiscale"], best)
    sparse = prepare(_source("sparse", **SPARSE))
    predicted, basis = cost.per_drive(sparse, probe=False)
    assert "steps of its windows" in basis
    walls = [run_scenario(_source("sparse", **SPARSE), tmp_path / f"sparse{k}.h5")["wall_s"] for k in range(2)]
    ratio = predicted.steps_s / min(walls)
    assert 1 / 1.5 < ratio < 1.5, (predicted.steps_s, walls)


def test_a_whole_road_multiscale_rate_recorded_before_is_neither_read_nor_overwritten(private_record):
    """The entry an earlier hpsim kept under the mode's name counted the whole road's steps: read in the full mode,
    where both counts are the same, and in the multiscale mode neither read nor overwritten (that hpsim may share
    the cache)."""
    old = {"steps_per_s": 1e6, "build_s": 1.0, "dt_s": 0.004, "recorded": "2026-01-01T00:00:00", "load": 0.5}
    drive_rate.record_entry("multiscale", old)
    drive_rate.record_entry("full", old)
    assert drive_rate.read("multiscale") is None
    assert drive_rate.read("full")["steps_per_s"] == 1e6
    assert cost.per_drive(prepare(_source("sparse", **SPARSE)), probe=False) is None
    drive_rate.record("multiscale", 0.004, 200.0, 1.0, 1.0)
    assert drive_rate.read("multiscale")["steps_per_s"] == pytest.approx(50000.0)
    assert drive_rate.read_entry("multiscale") == old


def test_the_preview_builds_one_engine_per_model_structure(private_record):
    """Designs that differ in parameter values share their compiled libraries (the values are inputs of the compiled
    functions; a zero is not a value but switches a mechanism off): the preview builds one engine for all of them.
    A design with another structure (another axle count and strut type) needs its own."""
    drive_rate.record("full", 0.004, 900.0, 2.0, 1.0)        # a rate known: no probe drive
    designs = [prepare(_source(f"d{k}", vehicle={"name": "apc_8x8", "overrides": {
        "charging.fill_pressure_offset": f"{offset} MPa"}})) for k, offset in enumerate((-0.2, 0.1, 0.2, 0.3))]
    assert len({d.model().structure for d in designs}) == 1
    est = cost.estimate(designs, 1, ensemble=1)
    assert est is not None and est.drives == 4 and est.compiles.engine_builds == 1
    other = prepare(_source("other", vehicle={"name": "light_4x4_integrated"}, initial_temperatures="35 degC"))
    assert other.model().structure != designs[0].model().structure
    est = cost.estimate(designs + [other], 1, ensemble=1)
    assert est.drives == 5 and est.compiles.engine_builds == 2
    # on ensemble lanes each structure's engine and lane library are built once too
    est = cost.estimate(designs + [other], 1, ensemble=4)
    assert est.lanes == 4 and est.compiles.engine_builds == 2


def test_a_time_parallel_rate_is_kept_per_process_and_lane_layout():
    """A time-parallel drive's rate depends on its processes and on the segments each steps together on the lane
    library: each layout has its own entry, and a scenario too short for two segments, which drives as a full
    drive, is costed (and recorded) as one."""
    layouts = {(2, None): "time_parallel/2", (2, 4): "time_parallel/2x4", (2, 1): "time_parallel/2",
               ("auto", None): "time_parallel/auto", ("auto", 4): "time_parallel/autox4"}
    for (P, lanes), key in layouts.items():
        solver = {"time_parallel": P, **({"time_parallel_lanes": lanes} if lanes is not None else {})}
        assert drive_rate.mode_of(prepare(_source("tp", distance="20 km", solver=solver)).scenario) == key
    short = prepare(_source("short", distance="500 m", solver={"time_parallel": "auto"}))   # 90 s: one segment
    assert drive_rate.mode_of(short.scenario) == "time_parallel/auto" and cost.rate_mode(short) == "full"
    long = prepare(_source("long", distance="5 km", solver={"time_parallel": "auto"}))    # one segment per CPU
    assert cost.rate_mode(long) == ("time_parallel/auto" if (os.cpu_count() or 1) > 1 else "full")
