"""OpenCRG files the tests write themselves (the documented text format, and pycrg's writer for binary files)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

NAN_TOKEN = "*missing*"        # how an OpenCRG text grid marks a cell without elevation


def write_minimalist(path: Path, z: np.ndarray, du_m: float, dv_m: float, empty_mods: bool = False) -> Path:
    """A minimalist OpenCRG text file (LRFI, 10-character fields): a straight reference line, only the u and v
    increments in $ROAD_CRG and no LONG_SECTION_V_RIGHT/LEFT, so the long sections lie at v = 0, dv, ... .
    NaN cells are written as *missing*; empty_mods: an empty $ROAD_CRG_MODS block (no default modifiers)."""
    lines = ["$CT", "hpsim test surface: a minimalist OpenCRG text file", "$",
             "$ROAD_CRG", f"REFERENCE_LINE_INCREMENT = {du_m}", f"LONG_SECTION_V_INCREMENT = {dv_m}", "$"]
    if empty_mods:
        lines += ["$ROAD_CRG_MODS", "$"]
    lines += ["$KD_Definition", "#:LRFI", *(f"D:long section {k + 1},m" for k in range(z.shape[1])), "$", "$$$$"]
    lines += ["".join(f"{NAN_TOKEN:>10}" if np.isnan(x) else f"{x:10.7f}" for x in row) for row in z]
    path.write_text("\n".join(lines) + "\n")
    return path


def belgian_block_like(seed: int = 0, length_m: float = 10.0, width_m: float = 3.4,
                       spacing_m: float = 0.01) -> tuple[np.ndarray, np.ndarray]:
    """(z [m] of shape (nu, nv), v [m]): a cobbled surface like a proving ground's Belgian block: square setts of
    0.15 m with a random height each (RMS 10 mm), rounded at their edges, on the u and v grid of spacing_m."""
    rng = np.random.default_rng(seed)
    u = np.arange(int(round(length_m / spacing_m)) + 1) * spacing_m
    v = np.linspace(-0.5 * width_m, 0.5 * width_m, int(round(width_m / spacing_m)) + 1)
    sett = 0.15
    iu, iv = np.floor(u / sett).astype(int), np.floor((v - v[0]) / sett).astype(int)
    heights = rng.normal(0.0, 0.010, (iu.max() + 1, iv.max() + 1))
    # the joints between setts: 15 mm lower over the outer 10 % of each sett
    edge_u = np.minimum(u % sett, sett - u % sett) < 0.1 * sett
    edge_v = np.minimum((v - v[0]) % sett, sett - (v - v[0]) % sett) < 0.1 * sett
    z = heights[iu][:, iv] - 0.015 * (edge_u[:, None] | edge_v[None, :])
    return z, v
