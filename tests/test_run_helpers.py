"""Shared helpers of the run/sweep/report tests (no tests here).

Until the `terrain` package provides `RoadSpec` and `build_road`, `install_standin_terrain()`
puts a tiny stand-in with the same API into the `terrain` module (tests only): a random road as
a sum of cosines with the ISO 8608 PSD (REFERENCE §5). When terrain has them, it does nothing.
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
TESTS = Path(__file__).resolve().parent
ISO_GD0 = {c: 16e-6 * 4 ** k for k, c in enumerate("ABCDEFGH")}   # m^3 at n0 = 0.1 cycle/m


def install_standin_terrain() -> bool:
    """Return True if the stand-in was installed (terrain lacks RoadSpec/build_road)."""
    import terrain

    if hasattr(terrain, "RoadSpec") and hasattr(terrain, "build_road"):
        return False
    from typing import Any, Literal

    from hpsim.config import Model, Quantity

    class RoadSpec(Model):
        iso_class: Literal["A", "B", "C", "D", "E", "F", "G", "H"] | None = "D"
        gd_n0: Quantity("m**3") | None = None
        waviness: float = 2.0
        length: Quantity("m") = 1000.0
        spacing: Quantity("m") = 0.05
        seed: int = 0
        band: list[float] = [0.011, 2.83]
        track_width: Quantity("m") | None = None
        coherence: bool = True
        events: list[Any] = []
        csv: str | None = None

    class Road:
        """Sum of cosines with the ISO 8608 PSD, tabulated on a grid and interpolated."""

        def __init__(self, spec, n=150):
            rng = np.random.default_rng(spec.seed)
            gd0 = spec.gd_n0 if spec.gd_n0 is not None else ISO_GD0[spec.iso_class]
            edges = np.geomspace(spec.band[0], spec.band[1], n + 1)
            nc = np.sqrt(edges[1:] * edges[:-1])
            amp = np.sqrt(2.0 * gd0 * (nc / 0.1) ** (-spec.waviness) * np.diff(edges))
            k = 2 * np.pi * nc
            self.s = np.arange(-20.0, spec.length + 20.0, spec.spacing)
            self.h = {}
            for j, track in enumerate(("left", "right")):
                phase = rng.uniform(0, 2 * np.pi, n)
                h = np.zeros_like(self.s)
                for a, kk, ph in zip(amp, k, phase):
                    h += a * np.sin(kk * self.s + ph)
                self.h[track] = h

        def evaluate(self, s, track):
            h = np.interp(s, self.s, self.h[track])
            slope = np.interp(s, self.s[:-1] + 0.5 * np.diff(self.s), np.diff(self.h[track]) / np.diff(self.s))
            return h, slope

        def enveloped(self, length):
            return self

    def build_road(spec, base_dir=None):
        return Road(spec)

    terrain.RoadSpec = RoadSpec
    terrain.build_road = build_road
    return True


def hpsim_subprocess(args: list[str], cwd=None, env=None, **kw) -> subprocess.Popen:
    """`hpsim ARGS` in a new Python process, with the stand-in terrain if needed."""
    code = ("import sys; sys.path.insert(0, %r); import test_run_helpers as h; h.install_standin_terrain(); "
            "from vehicle.cli import main; sys.exit(main(%r))" % (str(TESTS), list(args)))
    e = dict(os.environ)
    e.update(env or {})
    return subprocess.Popen([sys.executable, "-c", code], cwd=cwd, env=e, **kw)


def run_hpsim(args: list[str], cwd=None, timeout=300, env=None) -> subprocess.CompletedProcess:
    p = hpsim_subprocess(args, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    out, err = p.communicate(timeout=timeout)
    return subprocess.CompletedProcess(p.args, p.returncode, out, err)
