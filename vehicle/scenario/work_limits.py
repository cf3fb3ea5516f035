"""Work-size checks of a scenario, made before anything is compiled or run (docs/scenarios.md, "Work limits").

The work of a drive is set by its duration T (distance and speed profile), the solver step dt and the output
interval: T/dt solver steps, T/interval stored samples of every stored series. Before the model is built:

- the output interval must be at most the drive's duration (a longer one would store no sample at all);
- `solver.time_parallel: auto` takes at most one segment per MIN_SEGMENT_S of drive (1 on a short drive: "auto"
  falls back to serial instead of refusing).

`estimate()` gives the steps, samples, the size of the results (about one value per station, stored series and
sample) and the wall time; `check()` refuses a run beyond the documented limits (MAX_STEPS, MAX_RESULT_BYTES)
with the figures, and a run expected to take longer than ANNOUNCE_S is announced with them before it starts.

The compiled solver integrates one call of at most MAX_STEPS_PER_CALL steps (or one output interval if that is
longer): a long output interval is integrated one sample per call instead of `solver.samples_per_block`
(whose inputs would otherwise be held in memory for all the steps of the block).
"""
from __future__ import annotations

import math

from hpsim.errors import UserInputError

MAX_STEPS_PER_CALL = 2500              # the default 10 samples of 1 s at 4 ms
MAX_STEPS = 5e9                        # solver steps of one drive (1000 km at 20 km/h at 0.1 ms: 1.8e9)
MAX_RESULT_BYTES = 64 * 2**30          # uncompressed stored values of one results file (64 GiB)
MAX_MEMORY_RESULT_BYTES = 4 * 2**30    # ... of a run kept in memory (the Python API's run_in_memory)
ANNOUNCE_S = 30.0                      # a run expected to take longer is announced with its estimate
# cost model of one core (apc_8x8): microseconds per station and step, and per stored sample with store: all
# (writing and statistics included); benchmarks/drive.py measures them
US_PER_STATION_STEP = 0.9
US_PER_SAMPLE = 250.0


def samples_per_call(steps_per_sample: int, samples_per_block: int) -> int:
    """Samples integrated per compiled call: solver.samples_per_block, fewer when that would exceed
    MAX_STEPS_PER_CALL steps (at least 1)."""
    K, M = int(steps_per_sample), int(samples_per_block)
    return max(1, min(M, MAX_STEPS_PER_CALL // max(K, 1)))


def check_interval(interval_s: float, duration_s: float, distance_m: float, where: str) -> None:
    """The output interval stores at least one sample of the drive."""
    if interval_s > duration_s * (1 + 1e-9):
        raise UserInputError(f"{where}: output.interval ({interval_s:g} s) is longer than the drive "
                             f"({distance_m:g} m take {duration_s:.4g} s at the scenario's speed): no sample would "
                             f"be stored; give at most {_floor_interval(duration_s)}")


def _floor_interval(duration_s: float) -> str:
    return f"{duration_s:.3g} s" if duration_s < 1 else f"{math.floor(duration_s):g} s"


def segments_for(requested: int, auto: bool, duration_s: float, min_segment_s: float) -> int:
    """Time-parallel segments: "auto" takes at most one per min_segment_s of drive (at least 1)."""
    if not auto:
        return requested
    return max(1, min(requested, int(duration_s // min_segment_s)))


def estimate(duration_s: float, dt_s: float, interval_s: float, n_stations: int, values_per_sample: int) -> dict:
    """Steps, stored samples, uncompressed result bytes and expected wall time of a drive."""
    steps = duration_s / dt_s
    samples = duration_s / interval_s
    nbytes = samples * values_per_sample * 8.0
    wall = steps * n_stations * US_PER_STATION_STEP * 1e-6 + samples * US_PER_SAMPLE * 1e-6
    return {"steps": steps, "samples": samples, "bytes": nbytes, "wall_s": wall}


def describe(est: dict) -> str:
    return (f"{est['steps']:.3g} solver steps, {est['samples']:.3g} stored samples, about "
            f"{_size(est['bytes'])} of results and {_duration(est['wall_s'])} of computing")


def check(est: dict, where: str, in_memory: bool = False) -> str | None:
    """Refuse a drive beyond the limits; the announcement (a line) when it will take long, else None."""
    limit = MAX_MEMORY_RESULT_BYTES if in_memory else MAX_RESULT_BYTES
    advice = "lengthen solver.dt or output.interval, store fewer series (output.store) or drive a shorter distance"
    if est["steps"] > MAX_STEPS:
        raise UserInputError(f"{where}: {describe(est)}: more than the limit of {MAX_STEPS:.3g} solver steps; {advice}")
    if est["bytes"] > limit:
        raise UserInputError(f"{where}: {describe(est)}: more than the limit of {_size(limit)} of results"
                             f"{' in memory' if in_memory else ''}; {advice}")
    if est["wall_s"] > ANNOUNCE_S:
        return f"{where}: expect {describe(est)}"
    return None


def _size(n: float) -> str:
    for unit, f in (("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if n >= f:
            return f"{n / f:.3g} {unit}"
    return f"{n:.0f} B"


def _duration(s: float) -> str:
    if s >= 3600:
        return f"{s / 3600:.3g} h"
    if s >= 60:
        return f"{s / 60:.3g} min"
    return f"{s:.2g} s"


def drive_duration_s(speed, distance_m: float) -> float:
    """Duration [s] of a drive of distance_m with a speed profile (vehicle.scenario.speed.SpeedProfile), as the drive
    computes it (t(s) = integral of ds / v)."""
    import numpy as np

    s, t = speed.time_grid(distance_m + 1.0)
    return float(np.interp(distance_m, s, t))


def check_scenario(scenario, duration_s: float, n_stations: int, where: str, in_memory: bool = False) -> dict:
    """`check()` of a validated scenario (vehicle.scenario.schema.Scenario) before its drive is built: its duration,
    step and interval, and about n_stations values per stored series and sample (a multiscale drive integrates only
    its windows). Returns the estimate with its announcement ("announce": a line or None)."""
    solver = scenario.solver
    share = 1.0
    if solver.mode == "multiscale":
        share = min(1.0, (solver.window_m + solver.warm_up_m) / solver.spacing_m)
    est = estimate(duration_s, solver.dt / share, scenario.output.interval, n_stations,
                   n_stations * len(scenario.output.stored()))
    est["announce"] = check(est, where, in_memory)
    return est
