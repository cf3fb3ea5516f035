"""The command's own wall time, for the line `hpsim run` ends with: the time printed is the command's.

`command_wall_s()` counts from the process start (Linux: /proc/self/stat, so the imports count too),
else from the first import of the command line package; a command called inside a longer-lived process (`main`
from Python, a test) counts from its call (`command_called`).
"""
from __future__ import annotations

import math
import os
import time

_IMPORTED = time.perf_counter()


def _process_age_s() -> float | None:
    """Seconds since this process started (Linux /proc), or None where that is not known."""
    try:
        with open("/proc/self/stat") as fh:
            start_ticks = int(fh.read().rsplit(")", 1)[1].split()[19])
        with open("/proc/uptime") as fh:
            uptime_s = float(fh.read().split()[0])
        return uptime_s - start_ticks / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError):
        return None


_AGE_AT_IMPORT = _process_age_s()
_CALLED_AT: float | None = None        # perf_counter() when a command was called inside a longer-lived process
_PROCESS_IS_COMMAND = False            # the `hpsim` console script: the command's time is the process's


def process_is_the_command() -> None:
    """This process runs one command (`vehicle.cli.entry`): its time counts from the process start."""
    global _PROCESS_IS_COMMAND
    _PROCESS_IS_COMMAND = True


def command_called() -> None:
    """A command starts now: inside a process that does other work too (not `process_is_the_command`), its wall time
    counts from here."""
    global _CALLED_AT
    if not _PROCESS_IS_COMMAND:
        _CALLED_AT = time.perf_counter()


def command_wall_s() -> float:
    """Wall seconds since the command started."""
    if _CALLED_AT is not None:
        return time.perf_counter() - _CALLED_AT
    since_import = time.perf_counter() - _IMPORTED
    return since_import + (_AGE_AT_IMPORT or 0.0)


def tenths_down(seconds: float) -> str:
    """Seconds to one decimal, rounded down: a time printed as the command ends never exceeds the time passed (the
    process ends right after it: `vehicle.cli.entry`), and two times keep their order (the drive within the
    command)."""
    return f"{math.floor(seconds * 10.0) / 10.0:.1f}"
