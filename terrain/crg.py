"""OpenCRG road surfaces (ASAM OpenCRG, *.crg): the left and right wheel tracks of a vehicle driving along the
reference line.

The file is read and evaluated by the OpenCRG C library through its Python bindings `pycrg` (extra `crg`:
pip install -e ".[crg]"), with the file's own modifiers and options, as any OpenCRG tool sees it. The tracks
are the elevations z(u, v) at v = +track/2 (left; OpenCRG's v is positive to the left) and v = -track/2
(right) for u from the start to the end of the reference line at the road's spacing (default: the file's u
increment). The reference line's own elevation (slope) is part of z, so a grade in the file is a slow height
change of both tracks; heights are shifted so that the mean of the two tracks is 0 at the start (the
shift is kept in the road's info as z_offset_m).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError
from hpsim.extras import install_hint

EXTRA_MESSAGE = f"reading OpenCRG files needs the OpenCRG library's Python bindings: {install_hint('crg')}"
SUFFIXES = (".crg",)


def _pycrg():
    try:
        import pycrg
    except ImportError:
        raise UserInputError(EXTRA_MESSAGE) from None
    return pycrg


def is_crg(path) -> bool:
    return Path(str(path)).suffix.lower() in SUFFIXES


def read_crg(path: str | Path, track_width_m: float, spacing_m: float | None = None,
             length_m: float | None = None) -> tuple[float, np.ndarray, np.ndarray, dict]:
    """(spacing [m], left heights [m], right heights [m], info) of the tracks of an OpenCRG file (see the module
    docstring). length_m: only the first length_m metres of the reference line."""
    pycrg = _pycrg()
    path = Path(path)
    if not path.is_file():
        raise UserInputError(f"{path}: no such OpenCRG file")
    try:
        surface = pycrg.RoadSurface.open(str(path))
    except Exception as exc:          # the library's load error: a damaged or unsupported file
        raise UserInputError(f"{path}: not a readable OpenCRG file ({exc})") from None
    with surface:
        u0, u1 = surface.u_range()
        v0, v1 = surface.v_range()
        du = surface.increments()[0]
        half = 0.5 * float(track_width_m)
        if not (v0 <= -half and half <= v1):
            raise UserInputError(f"{path}: the track width {track_width_m:g} m needs the surface from v = {-half:g} to "
                                 f"{half:g} m; the file covers v in [{v0:g}, {v1:g}] m")
        step = float(du) if spacing_m is None else float(spacing_m)
        span = (u1 - u0) if length_m is None else float(length_m)
        if not 0 < span <= (u1 - u0) * (1 + 1e-9):
            raise UserInputError(f"{path}: length {span:g} m is not within the reference line's {u1 - u0:g} m")
        n = int(np.floor(span / step * (1 + 1e-12))) + 1
        if n < 2:
            raise UserInputError(f"{path}: spacing {step:g} m leaves fewer than 2 points over {span:g} m")
        u = u0 + step * np.arange(n)
        left = np.asarray(surface.uv_to_z_many(u, half), float)
        right = np.asarray(surface.uv_to_z_many(u, -half), float)
    if not (np.all(np.isfinite(left)) and np.all(np.isfinite(right))):
        raise UserInputError(f"{path}: the surface has no elevation at some points of the tracks at v = +-{half:g} m")
    offset = 0.5 * (left[0] + right[0])
    info = {"source": str(path), "format": "OpenCRG", "u_start_m": float(u0), "u_end_m": float(u1),
            "u_increment_m": float(du), "v_range_m": [float(v0), float(v1)], "track_width_m": float(track_width_m),
            "z_offset_m": float(offset)}
    return step, left - offset, right - offset, info
