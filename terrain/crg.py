"""OpenCRG road surfaces (ASAM OpenCRG, *.crg): the left and right wheel tracks of a vehicle driving along the
reference line.

The file is read and evaluated by the OpenCRG C library through its Python bindings `pycrg` (extra `crg`:
pip install -e ".[crg]"), with the file's own modifiers and options, as any OpenCRG tool sees it. The tracks
are the elevations z(u, v) at v = c + track/2 (left; OpenCRG's v is positive to the left of the reference line)
and v = c - track/2 (right) for u from the start to the end of the reference line at the road's spacing
(default: the file's u increment). `c` is the lateral offset of the vehicle's centre line (default 0: centred
on the reference line); a file whose long sections lie on one side of the reference line (a minimalist file
without LONG_SECTION_V_RIGHT/LEFT covers v from 0 to its width) needs one, e.g. half its width.
The reference line's own elevation (slope) is part of z, so a grade in the file is a slow height change of
both tracks; heights are shifted so that the mean of the two tracks is 0 at the start (the
shift is kept in the road's info as z_offset_m).
"""
from __future__ import annotations

import logging
import os
import stat
import threading
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError
from hpsim.files import kind_of

from .plausibility import check_plausible_tracks

from .profile_io import check_road_points
from hpsim.extras import install_hint

EXTRA_MESSAGE = f"reading OpenCRG files needs the OpenCRG library's Python bindings: {install_hint('crg')}"
SUFFIXES = (".crg",)
LOG = logging.getLogger("hpsim.crg")
# the C library's message levels (crgMsgPrint), as its own lines name them
LIBRARY_LEVELS = {1: "FATAL", 2: "WARNING", 3: "NOTICE", 4: "INFO", 5: "DEBUG"}
# the library's message routing is one global callback: one load at a time owns it
_MESSAGES_LOCK = threading.Lock()


def _pycrg():
    try:
        import pycrg
    except ImportError:
        raise UserInputError(EXTRA_MESSAGE) from None
    return pycrg


def _log_library_message(level: int, text: str) -> None:
    LOG.debug("OpenCRG %s: %s", LIBRARY_LEVELS.get(level, level), text.rstrip())


@contextmanager
def library_messages_logged(pycrg):
    """Inside the block, the OpenCRG library's messages (statistics and warnings, some 40 lines per load) are debug
    records of the "hpsim.crg" logger (hpsim -v shows them), never lines on the terminal. After the block pycrg
    routes them to its "pycrg" logger again; a callback set before with pycrg.set_message_callback is not
    restored (pycrg cannot tell which one is set)."""
    with _MESSAGES_LOCK:
        pycrg.set_message_callback(_log_library_message)
        try:
            yield
        finally:
            pycrg.clear_message_callback()


def _check_regular_file(path: Path) -> None:
    """UserInputError unless path is a regular file: the library opens it by name and would block on a FIFO."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise UserInputError(f"{path}: no such OpenCRG file") from None
    except OSError as exc:
        raise UserInputError(f"{path}: cannot read ({exc.strerror or exc.__class__.__name__})") from None
    if not stat.S_ISREG(mode):
        raise UserInputError(f"{path}: is {kind_of(mode)}, expected an OpenCRG file (a regular file)")


def is_crg(path) -> bool:
    return Path(str(path)).suffix.lower() in SUFFIXES


def track_positions(track_width_m: float, lateral_offset_m: float = 0.0) -> tuple[float, float]:
    """(v of the left track, v of the right track) [m]: the vehicle's centre line at v = lateral_offset_m."""
    half = 0.5 * float(track_width_m)
    return float(lateral_offset_m) + half, float(lateral_offset_m) - half


def _placement_error(path: Path, track_width_m: float, lateral_offset_m: float, v0: float, v1: float) -> str:
    """The one-line refusal of tracks outside the surface, with the lateral offsets that would fit."""
    v_left, v_right = track_positions(track_width_m, lateral_offset_m)
    where = (f"{path}: the tracks at v = {v_right:g} and {v_left:g} m (track {track_width_m:g} m, lateral offset "
             f"{lateral_offset_m:g} m) fall outside the file's v range [{v0:g}, {v1:g}] m")
    half = 0.5 * float(track_width_m)
    if v1 - v0 < 2 * half:
        return f"{where}; the surface is narrower than the track"
    return (f"{where}; a lateral offset from {v0 + half:g} to {v1 - half:g} m keeps both on it (road.lateral_offset, "
            "hpsim road import --lateral-offset)")


def read_crg(path: str | Path, track_width_m: float, spacing_m: float | None = None,
             length_m: float | None = None, lateral_offset_m: float = 0.0) -> tuple[float, np.ndarray, np.ndarray,
                                                                                     dict]:
    """(spacing [m], left heights [m], right heights [m], info) of the tracks of an OpenCRG file (see the module
    docstring). length_m: only the first length_m metres of the reference line; lateral_offset_m: the v of the
    vehicle's centre line (positive: left of the reference line)."""
    pycrg = _pycrg()
    path = Path(path)
    _check_regular_file(path)
    with library_messages_logged(pycrg):
        return _tracks(pycrg, path, track_width_m, spacing_m, length_m, lateral_offset_m)


def _tracks(pycrg, path: Path, track_width_m: float, spacing_m: float | None, length_m: float | None,
            lateral_offset_m: float) -> tuple[float, np.ndarray, np.ndarray, dict]:
    """read_crg's work once the file is known to be a regular file and the library's messages are routed."""
    try:
        surface = pycrg.RoadSurface.open(str(path))
    except Exception as exc:          # the library's load error: a damaged or unsupported file
        raise UserInputError(f"{path}: not a readable OpenCRG file ({exc})") from None
    with surface:
        u0, u1 = surface.u_range()
        v0, v1 = surface.v_range()
        du = surface.increments()[0]
        v_left, v_right = track_positions(track_width_m, lateral_offset_m)
        if not (v0 <= v_right and v_left <= v1):
            raise UserInputError(_placement_error(path, track_width_m, lateral_offset_m, v0, v1))
        step = float(du) if spacing_m is None else float(spacing_m)
        span = (u1 - u0) if length_m is None else float(length_m)
        if not 0 < span <= (u1 - u0) * (1 + 1e-9):
            raise UserInputError(f"{path}: length {span:g} m is not within the reference line's {u1 - u0:g} m")
        check_road_points(span, step, f"{path}: ")       # before the grid is allocated
        n = int(np.floor(span / step * (1 + 1e-12))) + 1
        if n < 2:
            raise UserInputError(f"{path}: spacing {step:g} m leaves fewer than 2 points over {span:g} m")
        u = u0 + step * np.arange(n)
        left = np.asarray(surface.uv_to_z_many(u, v_left), float)
        right = np.asarray(surface.uv_to_z_many(u, v_right), float)
    check_plausible_tracks(str(path), step, left, right, start_m=float(u0), coordinate="u = ")
    offset = 0.5 * (left[0] + right[0])
    info = {"source": str(path), "format": "OpenCRG", "u_start_m": float(u0), "u_end_m": float(u1),
            "u_increment_m": float(du), "v_range_m": [float(v0), float(v1)], "track_width_m": float(track_width_m),
            "lateral_offset_m": float(lateral_offset_m), "z_offset_m": float(offset)}
    return step, left - offset, right - offset, info
