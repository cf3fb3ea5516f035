"""The levelling pump's oil volume (vehicle.physics.compensation.pumped_volume_rate): int |q| dt per strut.

- hot struts on a flat road stand far beyond the dead band, and a small flow limit saturates the loop: the pump
  drains at exactly the flow limit for the whole drive, so the moved volume is flow_limit x time, the net added
  volume its negative, and both equal the strut's oil volume state (conservation), in the full and the
  multiscale engines, in the statistics rows (the intervals add up to the total) and in `hpsim report --json`;
- without compensation the pump moves nothing.
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from vehicle.analysis.summary import report_from
from vehicle.physics import compensation as comp
from vehicle.physics.params import load_vehicle
from vehicle.results.run import run_in_memory
from vehicle.scenario.schema import read_scenario_text

FLOW_LIMIT_M3_S = 1e-7
BASE = {"description": "pump oil volume test", "vehicle": {"name": "apc_8x8"}, "road": {"flat": True},
        "speed": "18 km/h", "distance": "600 m", "ambient_temperature": "60 degC",
        "initial_temperatures": "70 degC",
        "compensation": {"enabled": True, "time_constant": "2 s", "flow_limit": f"{FLOW_LIMIT_M3_S} m^3/s"},
        "output": {"interval": "1 s", "stats_interval": "100 m"}}
# at 5 m/s every window starts on a whole output sample (1 s), so the last window ends with the drive
MULTISCALE = {"mode": "multiscale", "window": "100 m", "spacing": "200 m", "warm_up": "20 m",
              "control_variate": False}


def _run(**changes):
    data = {**BASE, **changes}
    sink = run_in_memory(read_scenario_text(yaml.safe_dump(data), "pump.yaml", "."))
    return sink, report_from(sink, "pump")


@pytest.fixture(scope="module")
def full():
    return _run()


def _drive_time_s(sink) -> float:
    return float(sink.drive_series("t_s")[-1])


def test_saturated_loop_moves_flow_limit_times_time(full):
    sink, rep = full
    t_end = _drive_time_s(sink)
    values = sink.summary_values()
    moved, net = np.asarray(values["pump_oil_volume"]), np.asarray(values["oil_added_volume"])
    # the loop is saturated all along: at the smallest deflection error of the drive the flow law gives the limit
    # (its proportional flow A e / tau is many times the limit: tanh = 1 to round-off)
    x_nom = float(load_vehicle("apc_8x8").charging.strut_deflection)
    e_min = float(np.min(np.abs(sink.drive_series("strut_deflection") - x_nom)))
    q = float(comp.oil_flow(x_nom - e_min, x_nom, 4.489e-3, 2.0, 0.015, FLOW_LIMIT_M3_S, 1e-3))
    assert q == pytest.approx(-FLOW_LIMIT_M3_S, rel=1e-9)
    assert moved == pytest.approx(np.full(8, FLOW_LIMIT_M3_S * t_end), rel=1e-6)
    assert net == pytest.approx(-moved, rel=1e-9)                     # all of it drained (hot struts extend)
    # conservation: the net volume is the strut's oil volume state at the end
    assert net == pytest.approx(sink.drive_series("oil_added_m3")[:, -1], rel=1e-9)
    assert sink.drive_series("pump_oil_volume_m3")[:, -1] == pytest.approx(moved, rel=1e-12)
    # the statistics intervals add up to the total, each one flow_limit x its duration
    rows = sink.rows
    assert sum(r["pump_oil_volume_interval_m3"] for r in rows) == pytest.approx(moved, rel=1e-9)
    for r in rows:
        assert r["pump_oil_volume_interval_m3"] == pytest.approx(np.full(8, FLOW_LIMIT_M3_S * r["duration_s"]),
                                                                 rel=1e-6)
    # the report: per axle the two struts' sums, the vehicle's total
    assert [a["pump_oil_volume_m3"] for a in rep["axles"]] == pytest.approx([2 * FLOW_LIMIT_M3_S * t_end] * 4,
                                                                             rel=1e-6)
    assert rep["pump_oil_volume_m3"] == pytest.approx(8 * FLOW_LIMIT_M3_S * t_end, rel=1e-6)
    assert rep["oil_added_m3"] == pytest.approx(-rep["pump_oil_volume_m3"], rel=1e-9)


def test_multiscale_carries_the_pump_volume_across_its_gaps(full):
    sink, rep = _run(solver={**MULTISCALE})
    assert rep["solver_mode"] == "multiscale"
    t_end = _drive_time_s(full[0])
    moved = np.asarray(sink.summary_values()["pump_oil_volume"])
    assert moved == pytest.approx(np.full(8, FLOW_LIMIT_M3_S * t_end), rel=1e-6)
    assert rep["pump_oil_volume_m3"] == pytest.approx(full[1]["pump_oil_volume_m3"], rel=1e-6)
    assert rep["oil_added_m3"] == pytest.approx(full[1]["oil_added_m3"], rel=1e-6)


def test_no_compensation_moves_no_oil():
    sink, rep = _run(compensation={"enabled": False})
    assert np.all(np.asarray(sink.summary_values()["pump_oil_volume"]) == 0.0)
    assert rep["pump_oil_volume_m3"] == 0.0 and rep["oil_added_m3"] == 0.0
    assert all(a["pump_oil_volume_m3"] == 0.0 for a in rep["axles"])
    assert all(np.all(r["pump_oil_volume_interval_m3"] == 0.0) for r in sink.rows)
