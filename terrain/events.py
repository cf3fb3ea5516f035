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
from hpsim.errors import UserInputError

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
LEVEL_EVENTS = (Step, Ramp)   # persistent changes of level (not roughness: passes leave them alone)


# --- random populations --------------------------------------------------------------------------
DISTRIBUTIONS = ("fixed", "uniform", "normal", "lognormal")


class Distribution(Model):
    """A positive random length [m]: fixed, uniform [lo, hi], normal (mean, sd; redrawn below zero)
    or lognormal (median, sigma of ln). YAML: "5 cm" | {uniform: [3 cm, 8 cm]} |
    {normal: {mean: 5 cm, sd: 1 cm}} | {lognormal: {median: 5 cm, sigma: 0.4}}."""

    kind: Literal["fixed", "uniform", "normal", "lognormal"]
    a: float                 # fixed value, lower bound, mean or median [m]
    b: float = 0.0           # upper bound, sd [m] or sigma [-]

    @model_validator(mode="before")
    @classmethod
    def _parse(cls, v):
        from hpsim.units import parse_quantity

        if isinstance(v, dict) and "kind" in v:
            return v
        if not isinstance(v, dict):
            return {"kind": "fixed", "a": parse_quantity(v, "m", where="expected a length")}
        if len(v) != 1 or next(iter(v)) not in DISTRIBUTIONS:
            raise ValueError(f"expected a length or one of {{{', '.join(k + ': ...' for k in DISTRIBUTIONS)}}}, "
                             f"got keys {sorted(v)}")
        kind, arg = next(iter(v.items()))
        m = lambda x, what: parse_quantity(x, "m", where=f"{kind}: {what}")   # noqa: E731
        if kind == "fixed":
            return {"kind": kind, "a": m(arg, "value")}
        if kind == "uniform":
            if not isinstance(arg, (list, tuple)) or len(arg) != 2:
                raise ValueError("uniform: expected [low, high]")
            return {"kind": kind, "a": m(arg[0], "low"), "b": m(arg[1], "high")}
        if not isinstance(arg, dict):
            raise ValueError(f"{kind}: expected a mapping")
        if kind == "normal":
            if set(arg) != {"mean", "sd"}:
                raise ValueError("normal: expected {mean: ..., sd: ...}")
            return {"kind": kind, "a": m(arg["mean"], "mean"), "b": m(arg["sd"], "sd")}
        if set(arg) != {"median", "sigma"}:
            raise ValueError("lognormal: expected {median: ..., sigma: ...} (sigma: standard deviation of ln)")
        return {"kind": kind, "a": m(arg["median"], "median"), "b": float(arg["sigma"])}

    @model_validator(mode="after")
    def _check(self):
        if not self.a > 0 or (self.kind == "uniform" and not self.b >= self.a):
            raise ValueError(f"{self.kind}: values must be > 0 m (and low <= high), got {self.a:g}, {self.b:g}")
        if self.kind in ("normal", "lognormal") and not 0 <= self.b <= (10.0 if self.kind == "lognormal" else 1e3):
            raise ValueError(f"{self.kind}: spread must be >= 0, got {self.b:g}")
        return self

    def sample(self, rng: np.random.Generator, n: int) -> np.ndarray:
        if self.kind == "fixed":
            return np.full(n, self.a)
        if self.kind == "uniform":
            return rng.uniform(self.a, self.b, n)
        if self.kind == "lognormal":
            return self.a * np.exp(self.b * rng.standard_normal(n))
        out = self.a + self.b * rng.standard_normal(n)
        bad = out <= 0
        while np.any(bad):                          # truncated at zero: redraw
            out[bad] = self.a + self.b * rng.standard_normal(int(np.sum(bad)))
            bad = out <= 0
        return out

    def mean(self) -> float:
        """Mean [m] (the normal's truncation ignored: it is negligible for sd << mean)."""
        return {"fixed": self.a, "uniform": 0.5 * (self.a + self.b), "normal": self.a,
                "lognormal": self.a * float(np.exp(0.5 * self.b ** 2))}[self.kind]


class EventPopulation(Model):
    """Random potholes or bumps: a Poisson process of `density` events per metre ("2 /km") over
    [start, end] (default: the whole road), each with its own length and depth/height drawn from
    their distributions, on one wheel track chosen at random (track: random, default) or on
    left/right/both. `seed` (default: derived from the road's seed and the population's index)."""

    type: Literal["pothole", "bump_cosine", "bump_trapezoid"]
    density: Quantity("1/m")
    length: Distribution
    depth: Distribution | None = None         # potholes
    height: Distribution | None = None        # bumps
    # pothole walls (0: vertical) / trapezoid ramps (0: the default L/4) as a fraction of the length
    edge_fraction: float = 0.0
    track: Literal["left", "right", "both", "random"] = "random"
    start: Quantity("m") = 0.0
    end: Quantity("m") | None = None
    seed: int | None = None

    @model_validator(mode="after")
    def _check(self):
        if not 0 <= self.density <= MAX_EVENT_DENSITY_PER_M:
            raise ValueError(f"density must be in [0, {MAX_EVENT_DENSITY_PER_M * 1e3:g}] /km, got {self.density * 1e3:g} /km")
        need, other = ("depth", "height") if self.type == "pothole" else ("height", "depth")
        if getattr(self, need) is None or getattr(self, other) is not None:
            raise ValueError(f"a {self.type} population needs `{need}` (and no `{other}`)")
        if not 0 <= self.edge_fraction <= 0.5:
            raise ValueError(f"edge_fraction must be in [0, 0.5], got {self.edge_fraction:g}")
        if self.start < 0 or (self.end is not None and self.end <= self.start):
            raise ValueError(f"need 0 <= start < end, got start {self.start:g} m, end {self.end}")
        if self.seed is not None and self.seed < 0:
            raise ValueError("seed must be an integer >= 0")
        return self

    def realise(self, road_length_m: float, rng: np.random.Generator) -> list:
        """Concrete events (Pothole / BumpCosine / BumpTrapezoid) inside [start, min(end, road length)]."""
        end = road_length_m if self.end is None else min(self.end, road_length_m)
        span = max(end - self.start, 0.0)
        count = int(rng.poisson(self.density * span))
        if count > MAX_POPULATION_EVENTS:
            raise UserInputError(f"{self.type} population: {count} events (at most {MAX_POPULATION_EVENTS:,}); "
                                 "lower the density")
        lengths = np.minimum(self.length.sample(rng, count), span)
        sizes = (self.depth or self.height).sample(rng, count)
        positions = self.start + rng.uniform(0.0, 1.0, count) * (span - lengths)
        tracks = (rng.choice(["left", "right"], count) if self.track == "random" else [self.track] * count)
        out = []
        for x, L, h, tr in sorted(zip(positions, lengths, sizes, tracks)):
            if self.type == "pothole":
                out.append(Pothole(type="pothole", position=x, length=L, depth=h, edge_length=self.edge_fraction * L,
                                   track=tr))
            elif self.type == "bump_cosine":
                out.append(BumpCosine(type="bump_cosine", position=x, length=L, height=h, track=tr))
            else:
                out.append(BumpTrapezoid(type="bump_trapezoid", position=x, length=L, height=h,
                                         ramp_length=self.edge_fraction * L if self.edge_fraction > 0 else None,
                                         track=tr))
        return out


MAX_EVENT_DENSITY_PER_M = 1.0          # 1000 /km: beyond that it is roughness, not events
MAX_POPULATION_EVENTS = 2_000_000


def population_rng(road_seed: int, index: int, seed: int | None) -> np.random.Generator:
    """The population's own PCG64 stream: its `seed`, else one derived from the road's seed and its index
    (independent of the ISO noise streams, which use SeedSequence(road_seed).spawn)."""
    entropy = [seed] if seed is not None else [road_seed, 0x5E7E, index]
    return np.random.default_rng(np.random.SeedSequence(entropy))


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
