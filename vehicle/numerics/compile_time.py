"""How long compiling the vehicle model will take, said before it starts.

The compiler's time grows with the size of the generated C. Every batch of builds records its
rate, bytes of C per second of one compiler, in the cache (`compile_rate.json` beside the
libraries); the next estimate divides the C to build by that rate and by the compilers that run at
once. Before any record: DEFAULT_BYTES_PER_S, the rate of the idle 2-core development machine compiling
the main job's three libraries together.
"""
from __future__ import annotations

import json
import logging
import math
import os
from pathlib import Path

LOG = logging.getLogger("hpsim")
RECORD = "compile_rate.json"
DEFAULT_BYTES_PER_S = 7.0e4
compiled_s = 0.0            # compiler wall time spent in this process (a drive's set-up without it: drive_rate)
compiled_libraries = 0      # libraries this process started to compile (a study's preview counts its own)


def _rate(cache: Path) -> float:
    try:
        rate = float(json.loads((cache / RECORD).read_text())["bytes_per_s"])
        return rate if math.isfinite(rate) and rate > 0 else DEFAULT_BYTES_PER_S
    except (OSError, ValueError, KeyError, TypeError):
        return DEFAULT_BYTES_PER_S


def estimate_s(sizes: list[int], width: int, cache: Path) -> float:
    """Seconds to compile C sources of these sizes [bytes] on `width` compilers at once (the longest lane)."""
    lanes = [0.0] * max(1, min(width, len(sizes)))
    for n in sorted(sizes, reverse=True):           # as the builds are handed out: the biggest first
        lanes[lanes.index(min(lanes))] += n
    return max(lanes) / _rate(cache)


def announce(sizes: list[int], width: int, cache: Path) -> None:
    """The one line before a compile (INFO: shown unless -q); counts the libraries in `compiled_libraries`."""
    global compiled_libraries
    compiled_libraries += len(sizes)
    LOG.info(f"compiling the vehicle model (first run only, ~{max(1, round(estimate_s(sizes, width, cache)))} s)")


def add_compiled_s(seconds: float) -> None:
    """Count `seconds` of compiler wall time into `compiled_s`."""
    global compiled_s
    compiled_s += max(seconds, 0.0)


def record(sizes: list[int], width: int, seconds: float, cache: Path) -> None:
    """Keep the measured rate for the next estimate (best effort: a cache that cannot be written keeps none), and
    count the time (`add_compiled_s`)."""
    add_compiled_s(seconds)
    lanes = max(1, min(width, len(sizes)))
    longest = estimate_s(sizes, lanes, cache) * _rate(cache)        # the bytes of the longest lane
    if seconds <= 0 or longest <= 0:
        return
    try:
        tmp = cache / f".{RECORD}.{os.getpid()}.tmp"
        tmp.write_text(json.dumps({"bytes_per_s": longest / seconds, "sizes": sizes, "seconds": seconds}))
        tmp.replace(cache / RECORD)
    except OSError:
        pass
