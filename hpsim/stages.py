"""The stages of a command, timed and logged (logger "hpsim" at DEBUG level: shown by `hpsim -v`).

    road = timed("road", prepared.road)        # logs "stage road: 0.41 s"

A command's stages (reading the scenario, the road, building the model, compiling it, the drive,
the summary) each log one line when they end, so `hpsim -v run` says where the time went. The
line goes through `logging`, never to stdout: the command's output stays what it was.
"""
from __future__ import annotations

import logging
import time
from typing import Any, Callable

LOG = logging.getLogger("hpsim")


def timed(name: str, fn: Callable[..., Any], *args, **kwargs) -> Any:
    """fn(*args, **kwargs), with one DEBUG line "stage <name>: <seconds> s" when it returns."""
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    LOG.debug(f"stage {name}: {time.perf_counter() - t0:.2f} s")
    return out
