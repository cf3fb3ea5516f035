"""The measured speed of drives on this machine, kept in the compile cache (`drive_rate.json`), so that a
study can say what it will cost before it starts (vehicle.studies.cost).

Every completed `hpsim run` (and so every sweep and UQ case) records, per solver mode, the integration
steps per second of wall time of its drive (the simulated time it integrates / dt / the drive's wall, writing the
results included). A multiscale drive integrates only its windows (vehicle.engines.multiscale.integrated_time_s),
a share of the road that depends on its window plan and distance, so its rate counts those steps: a rate counted
over the whole road holds only for drives of the same plan. It is kept under its own key (ENTRY), so that an entry
counted over the whole road (recorded by an earlier hpsim, which may share the cache) is neither read as one nor
overwritten. It also records the rest of a run in a fresh process with the model compiled (`build_s`: reading,
checks, road, model, build, file, summary). That is taken from the first run of a process only, as later ones
reuse the model built in memory, and without the compiler's time (vehicle.numerics.compile_time). A new
process's imports are not in it.
"""
from __future__ import annotations

import json
import math
import os
import time
from pathlib import Path

from vehicle.numerics import compile_time
from vehicle.numerics.codegen import cache_dir

RECORD = "drive_rate.json"
# the record's key of a mode whose steps were once counted over the whole road (see the module docstring); the
# other modes integrate the whole road and are kept under their own name
ENTRY = {"multiscale": "multiscale: steps of the windows"}
_setup_recorded = None         # the process (id) that recorded its first drive's set-up: a forked worker has not


def _path() -> Path:
    return cache_dir() / RECORD


def read(mode: str) -> dict | None:
    """{"steps_per_s", "build_s", "dt_s", "recorded"} of the last drive in this mode, or None."""
    try:
        entry = json.loads(_path().read_text()).get(ENTRY.get(mode, mode))
        ok = (isinstance(entry, dict) and math.isfinite(float(entry["steps_per_s"])) and float(entry["steps_per_s"]) > 0
              and math.isfinite(float(entry["build_s"])) and float(entry["build_s"]) >= 0)
        return entry if ok else None
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def record(mode: str, dt_s: float, simulated_s: float, wall_s: float, build_s: float,
           compiled_s: float | None = None, fresh: bool = False) -> None:
    """Keep the rate of a finished drive (best effort: nothing is kept where the cache cannot be written).
    simulated_s: the simulated time the drive integrated (a multiscale drive: its windows').
    compiled_s: the compiler's seconds inside build_s (None: all this process compiled so far); fresh: build_s is a
    whole set-up even if this process drove before (a study's probe drive)."""
    global _setup_recorded
    if not (dt_s > 0 and simulated_s > 0 and wall_s > 0 and build_s >= 0):
        return
    first, _setup_recorded = fresh or _setup_recorded != os.getpid(), os.getpid()
    compiled_s = compile_time.compiled_s if compiled_s is None else compiled_s
    build_s = max(build_s - compiled_s, 0.0) if first else 0.0
    key = ENTRY.get(mode, mode)
    old = _entries().get(key)
    build = build_s if first else float(old.get("build_s", 0.0) if isinstance(old, dict) else 0.0)
    record_entry(key, {"steps_per_s": simulated_s / dt_s / wall_s, "build_s": build, "dt_s": dt_s,
                       "recorded": time.strftime("%Y-%m-%dT%H:%M:%S"), "load": load_average()})


def _entries() -> dict:
    try:
        data = json.loads(_path().read_text())
        return data if isinstance(data, dict) else {}
    except (OSError, ValueError):
        return {}


def read_entry(key: str):
    """Another measurement kept beside the rates (e.g. a study's time after its drives, vehicle.studies.cost)."""
    return _entries().get(key)


def record_entry(key: str, value) -> None:
    """Keep one entry of the record, the others as they are (best effort: nothing is kept where the cache cannot
    be written)."""
    data = _entries()
    data[key] = value
    try:
        tmp = _path().with_name(f".{RECORD}.{os.getpid()}.tmp")
        tmp.write_text(json.dumps(data))
        tmp.replace(_path())
    except OSError:
        pass


def load_average() -> float | None:
    """The machine's 1-minute load average (runnable processes), or None where the system does not say."""
    try:
        return float(os.getloadavg()[0])
    except (OSError, AttributeError):
        return None


def mode_of(scenario) -> str:
    """The record's key for a scenario (vehicle.scenario.schema.Scenario): full, multiscale, time_parallel/P, or
    time_parallel/PxL with L > 1 segments per process given (solver.time_parallel_lanes: they step together on the
    lane library, so the drive's rate depends on them as on P; "auto" takes one)."""
    solver = scenario.solver
    if solver.mode == "multiscale":
        return "multiscale"
    P, lanes = solver.time_parallel, solver.time_parallel_lanes
    if P in (None, 1):
        return "full"
    return f"time_parallel/{P}" + (f"x{lanes}" if isinstance(lanes, int) and lanes > 1 else "")
