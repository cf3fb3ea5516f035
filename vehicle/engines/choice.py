"""Which engine a scenario's solver section asks for: the one rule, read by the engine builder
(vehicle.engines.build) and by the ensemble's test of which drives can be lanes (vehicle.engines.ensemble)."""
from __future__ import annotations

ENGINE_NAMES = ("full", "multiscale", "time_parallel")


def engine_for(mode: str | None, segments: int) -> str:
    """The engine of solver.mode `mode` (None: "full") run in `segments` time-parallel segments: "time_parallel"
    for a full drive in more than one segment, else the mode."""
    mode = mode or "full"
    return "time_parallel" if mode == "full" and segments > 1 else mode
