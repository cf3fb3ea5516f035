"""Where a drive ends (vehicle.engines.drive_end): at the scenario's distance, for every speed source and engine.

The speed profile's distance -> time map is integrated in floating point, and a fixed-step solver cannot stop
between steps: the drive ends at the step nearest where its distance reaches the scenario's distance, so its end
sample lies within half a step's travel of it. The statistics' last interval closes there and is labelled with
the scenario's distance; no interval is a rounding sliver (shorter than the distance the vehicle covers in one
output interval at its top speed, unless the scenario's distance itself leaves such a remainder).
"""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from vehicle.engines.build import build_engine
from vehicle.engines.drive_end import DriveEnd
from vehicle.engines.ensemble import run_lockstep
from vehicle.results.run import final_info, run_in_memory, run_info
from vehicle.results.sinks import MemorySink
from vehicle.scenario.schema import prepare, read_scenario_text

DISTANCE_M = 2000.0
STATS_M = 500.0
DT_S = 0.004
PROFILE = {"profile": [["0 km", "15 km/h"], ["1 km", "25 km/h"], ["2 km", "25 km/h"]]}
SPEEDS = {"constant": "20 km/h", "profile": PROFILE,
          "random": {"random": {"mean": "20 km/h", "spread": "3 km/h", "correlation_length": "200 m", "seed": 2,
                                     "max": "28 km/h"}}}
V_MAX_M_PER_S = 30 / 3.6          # above every source's top speed


def _source(speed, solver: dict | None = None):
    data = {"description": "drive end", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 3},
            "speed": speed, "distance": "2 km", "ambient_temperature": "25 degC",
            "initial_temperatures": ["45 degC", "40 degC", "35 degC", "30 degC"],
            "solver": {"dt": "4 ms", **(solver or {})},
            "output": {"interval": "1 s", "stats_interval": "0.5 km"}}
    return read_scenario_text(yaml.safe_dump(data), "end.yaml", ".")


def _assert_rows_end_at_the_distance(sink: MemorySink):
    ends = np.array([r["distance_end_m"] for r in sink.rows])
    durations = np.array([r["duration_s"] for r in sink.rows])
    assert ends[-1] == DISTANCE_M
    np.testing.assert_array_equal(ends, STATS_M * np.arange(1, len(ends) + 1))
    # each interval is 500 m long: driven in at least 500 m / v_max (a sliver lasts a fraction of a step)
    assert np.all(durations >= STATS_M / V_MAX_M_PER_S)
    # the last checkpoint: the drive's own distance within half a step's travel of the scenario's
    assert abs(sink.checkpoints[-1]["s_m"] - DISTANCE_M) <= 0.5 * DT_S * V_MAX_M_PER_S


@pytest.mark.parametrize("source", sorted(SPEEDS))
def test_the_full_drive_ends_at_its_distance_for_every_speed_source(source):
    _assert_rows_end_at_the_distance(run_in_memory(_source(SPEEDS[source])))


def test_the_time_parallel_drive_ends_at_its_distance():
    _assert_rows_end_at_the_distance(run_in_memory(_source(PROFILE, {"time_parallel": 2,
                                                                     "time_parallel_lanes": 1})))


def test_the_multiscale_drive_carries_its_slow_states_to_its_distance():
    """Its rows are its windows (each at least one output interval long); its final state is at the distance."""
    sink = run_in_memory(_source(PROFILE, {"mode": "multiscale", "window": "200 m", "spacing": "500 m",
                                           "warm_up": "30 m"}))
    assert all(r["duration_s"] >= 1.0 for r in sink.rows)
    assert sink.rows[-1]["distance_end_m"] <= DISTANCE_M
    assert abs(sink.checkpoints[-1]["s_m"] - DISTANCE_M) <= 0.5 * DT_S * V_MAX_M_PER_S


def test_an_ensemble_lane_ends_at_its_distance():
    def lane(speed, make_solver):
        prep = prepare(_source(speed))
        model, drive = build_engine(prep, make_solver)
        sink = MemorySink("lane")
        sink.start(run_info(prep.source, prep, model, drive, drive.initial_equilibrium()))
        res = drive.run(sink)
        sink.finish(final_info(drive, res, *sink.counts(), res.wall_s))
        return sink
    out = run_lockstep(lane, [("profile", (PROFILE,)), ("constant", (SPEEDS["constant"],))], 2)
    for tag in ("profile", "constant"):
        _assert_rows_end_at_the_distance(out["cases"][tag])


def test_the_end_is_the_step_nearest_the_distance_map_time():
    """A map that misses a whole step count by float rounding (106 km at 20 km/h: 19080.0000000226 s) ends on
    that step with no partial interval; 0.6 of a step past a whole sample takes one step more."""
    end = DriveEnd.of(106e3, 19080.0000000226, DT_S, 250)
    assert (end.whole_samples, end.tail_steps) == (19080, 0)
    end = DriveEnd.of(2e3, 327.0 + 0.6 * DT_S, DT_S, 250)
    assert (end.whole_samples, end.tail_steps) == (327, 1)
    assert end.steps_left(300.0) == (27, 1)
    assert end.steps_left(end.time_s) == (0, 0)


def test_no_multiscale_window_runs_past_the_drives_end():
    """A window integrates whole output samples from its start; the last one, starting off the sample grid
    (1530 m at 20 km/h: 275.4 s; systematic placement keeps it there), must stop at or before the drive's end (360 s) and leave the rest to the
    slow model, not integrate up to one output interval beyond it (the slow states then too warm)."""
    sink = run_in_memory(_source("20 km/h", {"mode": "multiscale", "window": "470 m", "spacing": "510 m",
                                             "warm_up": "30 m", "placement": "systematic"}))
    assert sink.rows[-1]["distance_end_m"] <= DISTANCE_M + 0.5 * DT_S * V_MAX_M_PER_S
    assert abs(sink.checkpoints[-1]["s_m"] - DISTANCE_M) <= 0.5 * DT_S * V_MAX_M_PER_S
