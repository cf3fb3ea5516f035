"""Discrete road events superposed on a profile: bumps, potholes, steps, ramps, washboard.

Every event starts at `position` [m from the road start] and spans `length` [m]
on the track(s) named by `track` ("left", "right" or "both"). Heights are
positive upwards and added to the profile (a pothole's `depth` is positive and
goes down). Shapes, with u = s - position:

- bump_cosine:    z = h/2·(1 - cos(2π·u/L)) for 0 <= u <= L (C1, peak h at L/2)
- bump_trapezoid: linear up over `ramp_length` (default L/4), flat top h, linear down; base L
- pothole:        flat bottom -d, walls either vertical (edge_length = 0) or linear over edge_length
- step:           z = h for u >= L, half-cosine transition h/2·(1 - cos(π·u/L)) over 0 <= u <= L
                  (L = 0: a sharp step at `position`); the road stays at +h afterwards
- ramp:           z = h·u/L for 0 <= u <= L, h afterwards (a change of level at a constant grade)
- washboard:      z = h/2·(1 - cos(2π·u/λ)) for 0 <= u <= L, L a whole number of wavelengths λ;
                  h is the peak-to-peak corrugation height
"""
from __future__ import annotations

from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, model_validator

from hpsim.config import Model, Quantity

Track = Literal["left", "right", "both"]
WASHBOARD_CYCLE_TOLERANCE = 1e-6  # relative: length / wavelength must be this close to an integer


class _Event(Model):
    position: Quantity("m")
    track: Track = "both"

    @model_validator(mode="after")
    def _check_position(self):
        if self.position < 0:
            raise ValueError(f"position must be >= 0 m (got {self.position} m)")
        return self

    @property
    def end(self) -> float:
        """Distance [m] after which the event no longer changes (a step/ramp keeps its level)."""
        return self.position + self.length


class BumpCosine(_Event):
    type: Literal["bump_cosine"]
    length: Quantity("m")
    height: Quantity("m")

    @model_validator(mode="after")
    def _check(self):
        _positive(self.length, "length")
        return self

    def shape(self, s):
        u = s - self.position
        inside = (u >= 0) & (u <= self.length)
        return np.where(inside, 0.5 * self.height * (1.0 - np.cos(2.0 * np.pi * u / self.length)), 0.0)


class BumpTrapezoid(_Event):
    type: Literal["bump_trapezoid"]
    length: Quantity("m")
    height: Quantity("m")
    ramp_length: Quantity("m") | None = None

    @model_validator(mode="after")
    def _check(self):
        _positive(self.length, "length")
        r = self.ramp
        if not (0 <= r <= 0.5 * self.length):
            raise ValueError(f"ramp_length must be in [0, length/2 = {0.5 * self.length} m] (got {r} m)")
        return self

    @property
    def ramp(self) -> float:
        return 0.25 * self.length if self.ramp_length is None else self.ramp_length

    def shape(self, s):
        return _trapezoid(s, self.position, self.length, self.ramp, self.height)


class Pothole(_Event):
    type: Literal["pothole"]
    length: Quantity("m")
    depth: Quantity("m")
    edge_length: Quantity("m") = 0.0

    @model_validator(mode="after")
    def _check(self):
        _positive(self.length, "length")
        _positive(self.depth, "depth")
        if not (0 <= self.edge_length <= 0.5 * self.length):
            raise ValueError(f"edge_length must be in [0, length/2 = {0.5 * self.length} m] "
                             f"(got {self.edge_length} m)")
        return self

    def shape(self, s):
        return _trapezoid(s, self.position, self.length, self.edge_length, -self.depth)


class Step(_Event):
    type: Literal["step"]
    height: Quantity("m")
    length: Quantity("m") = 0.0

    @model_validator(mode="after")
    def _check(self):
        if self.length < 0:
            raise ValueError(f"length (transition) must be >= 0 m (got {self.length} m)")
        return self

    def shape(self, s):
        u = np.asarray(s, dtype=float) - self.position
        if self.length == 0:
            return np.where(u >= 0, self.height, 0.0)
        x = np.clip(u / self.length, 0.0, 1.0)
        return 0.5 * self.height * (1.0 - np.cos(np.pi * x))


class Ramp(_Event):
    type: Literal["ramp"]
    length: Quantity("m")
    height: Quantity("m")

    @model_validator(mode="after")
    def _check(self):
        _positive(self.length, "length")
        return self

    def shape(self, s):
        u = np.asarray(s, dtype=float) - self.position
        return self.height * np.clip(u / self.length, 0.0, 1.0)


class Washboard(_Event):
    type: Literal["washboard"]
    length: Quantity("m")
    height: Quantity("m")
    wavelength: Quantity("m")

    @model_validator(mode="after")
    def _check(self):
        _positive(self.length, "length")
        _positive(self.height, "height")
        _positive(self.wavelength, "wavelength")
        cycles = self.length / self.wavelength
        whole = round(cycles)
        if whole < 1 or abs(cycles - whole) > WASHBOARD_CYCLE_TOLERANCE * cycles:
            near = max(1, whole) * self.wavelength
            raise ValueError(f"length must be a whole number of wavelengths (got {self.length} m = "
                             f"{cycles:.4g} x {self.wavelength} m; e.g. {near:.6g} m)")
        return self

    def shape(self, s):
        u = s - self.position
        inside = (u >= 0) & (u <= self.length)
        return np.where(inside, 0.5 * self.height * (1.0 - np.cos(2.0 * np.pi * u / self.wavelength)), 0.0)


EventSpec = Annotated[Union[BumpCosine, BumpTrapezoid, Pothole, Step, Ramp, Washboard],
                      Field(discriminator="type")]
EVENT_TYPES = ("bump_cosine", "bump_trapezoid", "pothole", "step", "ramp", "washboard")


def _positive(value: float, name: str) -> None:
    if not value > 0:
        raise ValueError(f"{name} must be > 0 m (got {value} m)")


def _trapezoid(s, start: float, length: float, ramp: float, height: float):
    """0 outside [start, start+length]; linear ramps of `ramp` at both ends (vertical if 0); flat `height`."""
    u = np.asarray(s, dtype=float) - start
    if ramp > 0:
        rise = np.clip(u / ramp, 0.0, 1.0)
        fall = np.clip((length - u) / ramp, 0.0, 1.0)
        return height * np.minimum(rise, fall)
    return np.where((u >= 0) & (u <= length), height, 0.0)


def apply_events(spacing_m: float, left_m: np.ndarray, right_m: np.ndarray, events) -> None:
    """Add each event's shape to the track arrays (grid s_i = i·spacing_m) in place, touching only
    the samples the event covers (a step or ramp keeps its level to the end of the road)."""
    n = left_m.size
    for ev in events:
        i0 = max(0, int(np.floor(ev.position / spacing_m)) - 1)
        persists = isinstance(ev, (Step, Ramp))
        i1 = n if persists else min(n, int(np.ceil(ev.end / spacing_m)) + 2)
        if i0 >= i1:
            continue
        dz = ev.shape(np.arange(i0, i1) * spacing_m)
        if ev.track in ("left", "both"):
            left_m[i0:i1] += dz
        if ev.track in ("right", "both"):
            right_m[i0:i1] += dz
