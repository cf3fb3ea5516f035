"""Speed profiles of a drive: constant, tables over distance, recorded drives (CSV) and generated cycles.

The drive is parametrised by distance (`vehicle.engines.full.Drive` integrates t(s) = ∫ ds / v(s)),
so every profile ends as a piecewise-linear table v(s) with v > 0 (`SpeedProfile`, the one speed
profile class of the drive and the scenario; `SpeedTable` is its former name). A stop cannot be v = 0: it is driven at the creeping speed
MIN_SPEED_M_PER_S (0.5 km/h) for the stop's duration, so the time at (near) standstill is kept and
the vehicle creeps v_min * t_stop metres (4 m for a 30 s stop). The longitudinal acceleration the
load transfer needs is that of the motion the drive performs: a(s) = v dv/ds on the table
(`SpeedProfile.acceleration`), which the drive feeds to the model as its longitudinal acceleration, exact for the piecewise-linear v(s).

Sources (the scenario's `speed:` key, docs/scenarios.md):
  "20 km/h"                                    constant
  {profile: [[0 km, 20 km/h], ...]}            table over distance (vehicle.scenario.schema)
  {csv: drive.csv, by: time|distance}          a recorded drive; header names column and unit:
                                               time_s | time_min | time_h | distance_m | distance_km,
                                               and speed_m_s | speed_km_h | speed_mph (or "speed [km/h]")
  {stop_go: {cruise_speed:, stop_duration:, acceleration:, deceleration:, spacing:}}
  {random: {mean:, spread:, correlation_length:, seed:, min:, max:}}
Generated profiles are built for the drive's distance (plus a margin the drive reads beyond it).
"""
from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import StrictInt, field_validator, model_validator

from hpsim.config import Model
from hpsim.errors import UserInputError
from hpsim.files import read_csv_text
from hpsim.units import parse_quantity
from hpsim.validators import in_range, quantity

MIN_SPEED_M_PER_S = 0.5 / 3.6          # creeping speed standing in for a stop (documented choice)
MAX_SPEED_M_PER_S = 150.0 / 3.6        # as the scenario's constant speed
ACCELERATION_RANGE_M_PER_S2 = (0.05, 5.0)
CORRELATION_LENGTH_RANGE_M = (1.0, 100e3)
MARGIN_M = 1000.0                      # generated profiles reach this far beyond the drive
MAX_TABLE_POINTS = 5_000_000
RAMP_SPEED_STEP_M_PER_S = 0.1          # table resolution on acceleration ramps (sampled in speed)
SPREAD_TOLERANCE = 0.02                # relative: a random profile must reach the requested spread


# --- the table ------------------------------------------------------------------------------------
@dataclass
class SpeedProfile:
    """Vehicle speed v(s) [m/s] over distance [m]: a piecewise-linear table (one point: constant), with
    the time of the motion, its acceleration and trip statistics."""

    distances_m: np.ndarray
    speeds_m_per_s: np.ndarray
    description: str = ""

    @classmethod
    def constant(cls, speed_m_per_s: float) -> "SpeedProfile":
        return cls(np.array([0.0]), np.array([float(speed_m_per_s)]), description="constant")

    def __post_init__(self):
        self.distances_m = np.atleast_1d(np.asarray(self.distances_m, float))
        self.speeds_m_per_s = np.atleast_1d(np.asarray(self.speeds_m_per_s, float))
        if self.distances_m.shape != self.speeds_m_per_s.shape:
            raise UserInputError("speed: the profile needs one speed per distance")
        if np.any(self.speeds_m_per_s <= 0):
            raise UserInputError("speed: every speed must be > 0 m/s (the drive is parametrised by distance)")
        if np.any(np.diff(self.distances_m) <= 0):
            raise UserInputError("speed: the profile's distances must increase")

    def speed(self, s_m):
        """Speed [m/s] at distance s_m (held beyond the table's ends)."""
        return np.interp(s_m, self.distances_m, self.speeds_m_per_s)

    def time_grid(self, distance_m: float, ds: float = 1.0):
        """(s, t) table of the motion: t(s) = ∫ ds / v(s), exact for the piecewise-linear v(s).

        The grid is every ds metres plus every table point, and each step integrates 1/v of the
        linear segment exactly (dt = ds ln(v2/v1) / (v2 - v1)), so a fine ramp from a creeping start
        takes the time its acceleration says (a 1 m trapezoid on 1/v overestimates it several times).
        """
        n = max(int(math.ceil(distance_m / ds)), 2)
        d = self.distances_m
        s = np.union1d(np.linspace(0.0, distance_m, n + 1), d[(d > 0.0) & (d < distance_m)])
        v = self.speed(s)
        v1, v2, h = v[:-1], v[1:], np.diff(s)
        dv = v2 - v1
        flat = np.abs(dv) <= 1e-9 * v1
        dt = np.where(flat, h / v1, h * np.log(v2 / v1) / np.where(flat, 1.0, dv))
        return s, np.concatenate([[0.0], np.cumsum(dt)])

    def acceleration(self, s_m):
        """Longitudinal acceleration [m/s^2] a = v dv/ds of the drive's motion at distance s_m (any shape).

        dv/ds is the slope of the table segment containing s (0 before the first and after the last
        point, where the speed is held); at a table point the segment that starts there counts.
        """
        s = np.asarray(s_m, float)
        d, v = self.distances_m, self.speeds_m_per_s
        if d.size < 2:
            return np.zeros_like(s)
        slope = np.diff(v) / np.diff(d)
        k = np.clip(np.searchsorted(d, s, side="right") - 1, 0, d.size - 2)
        inside = (s >= d[0]) & (s < d[-1])
        return np.where(inside, self.speed(s) * slope[k], 0.0)

    def statistics(self, distance_m: float) -> dict:
        """Trip time [s], time-average speed (distance / time) and time-weighted spread [m/s] over [0, distance]."""
        s, t = self.time_grid(distance_m, ds=min(1.0, distance_m / 2))
        v = self.speed(s)
        w = np.diff(t)                                   # time spent on each step
        vm = 0.5 * (v[1:] + v[:-1])
        mean = distance_m / t[-1]
        spread = math.sqrt(max(float(np.sum(w * (vm - mean) ** 2) / t[-1]), 0.0))
        a = self.acceleration(0.5 * (s[1:] + s[:-1]))
        return {"duration_s": float(t[-1]), "mean_speed_m_per_s": mean, "spread_m_per_s": spread,
                "rms_acceleration_m_per_s2": math.sqrt(float(np.sum(w * a * a) / t[-1])),
                "max_abs_acceleration_m_per_s2": float(np.max(np.abs(a))) if a.size else 0.0,
                "time_at_min_speed_s": float(np.sum(w[vm <= MIN_SPEED_M_PER_S * (1 + 1e-9)]))}

    @classmethod
    def from_time_series(cls, t_s, v_m_per_s, min_speed_m_per_s: float = MIN_SPEED_M_PER_S,
                         description: str = "") -> "SpeedProfile":
        """Table over distance from a speed-over-time series (piecewise linear in time).

        Speeds below min_speed are raised to it (a stop becomes creeping for the same time). Each
        time segment is cut into pieces of at most RAMP_SPEED_STEP_M_PER_S and 5 % speed change, so the
        table's time t(s) = ∫ ds/v reproduces the recording's duration closely (a piece
        linear in time is driven linear in distance: ~0.1 % per piece at a 5 % speed change).
        """
        t = np.asarray(t_s, float)
        v = np.maximum(np.asarray(v_m_per_s, float), min_speed_m_per_s)
        step = np.minimum(RAMP_SPEED_STEP_M_PER_S, 0.05 * np.minimum(v[1:], v[:-1]))
        pieces = np.maximum(1, np.ceil(np.abs(np.diff(v)) / step).astype(int))
        if int(np.sum(pieces)) + 1 > MAX_TABLE_POINTS:
            raise UserInputError(f"speed: the recorded drive needs {int(np.sum(pieces)) + 1} table points "
                                 f"(at most {MAX_TABLE_POINTS})")
        tt = [t[:1]]
        for k, n in enumerate(pieces):
            tt.append(np.linspace(t[k], t[k + 1], n + 1)[1:])
        tt = np.concatenate(tt)
        vv = np.interp(tt, t, v)
        s = np.concatenate([[0.0], np.cumsum(np.diff(tt) * 0.5 * (vv[1:] + vv[:-1]))])
        return cls(s, vv, description=description)

    def repeated(self, distance_m: float) -> "SpeedProfile":
        """The table laid end to end until it covers distance_m (a recorded lap driven again)."""
        d, v = self.distances_m, self.speeds_m_per_s
        L = float(d[-1] - d[0])
        n = int(math.ceil(distance_m / L)) + 1
        if n * d.size > MAX_TABLE_POINTS:
            raise UserInputError(f"speed.repeat: {n} repetitions of a {L:.6g} m recording exceed "
                                 f"{MAX_TABLE_POINTS} table points")
        dd = np.concatenate([d[:1]] + [d[1:] + k * L for k in range(n)])
        vv = np.concatenate([v[:1]] + [v[1:]] * n)
        keep = np.concatenate([[True], np.diff(dd) > 0])
        return SpeedProfile(dd[keep], vv[keep], description=self.description + f", repeated every {L:.6g} m")


def constant(speed_m_per_s: float) -> SpeedProfile:
    return SpeedProfile.constant(speed_m_per_s)


SpeedTable = SpeedProfile     # its former name (the table of vehicle.scenario.speed before the two classes merged)


# --- scenario specifications -------------------------------------------------------------------------
def _speed(v, name):
    return in_range(quantity("m/s", v, name), MIN_SPEED_M_PER_S, MAX_SPEED_M_PER_S, "km/h", 3.6, name=name)


class CsvSpeedSpec(Model):
    """A recorded drive: {csv: path, by: time|distance, repeat: false, min_speed: 0.5 km/h}."""

    csv: str
    by: Literal["time", "distance"] | None = None    # default: from the first column's name
    repeat: bool = False
    min_speed: float = MIN_SPEED_M_PER_S

    @field_validator("min_speed", mode="before")
    @classmethod
    def _min(cls, v):
        return _speed(v, "min_speed")


class StopGoSpec(Model):
    """Stop-go cycles: from rest, accelerate to cruise_speed, cruise, brake to a stop, stand (creeping)
    for stop_duration; a stop every `spacing` metres."""

    cruise_speed: float
    stop_duration: float = 30.0
    acceleration: float = 1.0
    deceleration: float = 1.5
    spacing: float
    min_speed: float = MIN_SPEED_M_PER_S

    @field_validator("cruise_speed", "min_speed", mode="before")
    @classmethod
    def _speeds(cls, v, info):
        return _speed(v, info.field_name)

    @field_validator("stop_duration", mode="before")
    @classmethod
    def _stop(cls, v):
        return in_range(quantity("s", v, "stop_duration"), 0.0, 3600.0, "s", name="stop_duration")

    @field_validator("acceleration", "deceleration", mode="before")
    @classmethod
    def _acc(cls, v, info):
        return in_range(quantity("m/s**2", v, info.field_name), *ACCELERATION_RANGE_M_PER_S2, "m/s^2", name=info.field_name)

    @field_validator("spacing", mode="before")
    @classmethod
    def _spacing(cls, v):
        return in_range(quantity("m", v, "spacing"), 1.0, 1e6, "m", name="spacing")

    @model_validator(mode="after")
    def _fits(self):
        if self.cruise_speed <= self.min_speed:
            raise ValueError(f"cruise_speed ({self.cruise_speed * 3.6:.6g} km/h) must exceed min_speed "
                             f"({self.min_speed * 3.6:.6g} km/h)")
        need = self.ramp_distances()
        if sum(need) > self.spacing:
            raise ValueError(f"spacing {self.spacing:.6g} m is shorter than one cycle's acceleration + braking + "
                             f"stop ({need[0]:.4g} + {need[1]:.4g} + {need[2]:.4g} m); raise spacing or the accelerations")
        return self

    def ramp_distances(self) -> tuple[float, float, float]:
        V, v0 = self.cruise_speed, self.min_speed
        return ((V * V - v0 * v0) / (2 * self.acceleration), (V * V - v0 * v0) / (2 * self.deceleration),
                v0 * self.stop_duration)


class RandomSpeedSpec(Model):
    """A smooth random speed over distance: mean (trip average = distance / time), spread (time-weighted
    standard deviation), correlation_length (length scale of the squared-exponential correlation
    exp(-ds^2 / (2 l^2))), seed, clipped to [min, max]."""

    mean: float
    spread: float
    correlation_length: float = 50.0
    seed: StrictInt = 0
    min: float = MIN_SPEED_M_PER_S
    max: float = MAX_SPEED_M_PER_S

    @field_validator("mean", "min", "max", mode="before")
    @classmethod
    def _speeds(cls, v, info):
        return _speed(v, info.field_name)

    @field_validator("spread", mode="before")
    @classmethod
    def _spread(cls, v):
        return in_range(quantity("m/s", v, "spread"), 0.0, MAX_SPEED_M_PER_S, "km/h", 3.6, name="spread")

    @field_validator("correlation_length", mode="before")
    @classmethod
    def _corr(cls, v):
        return in_range(quantity("m", v, "correlation_length"), *CORRELATION_LENGTH_RANGE_M, "m", name="correlation_length")

    @field_validator("seed")
    @classmethod
    def _seed(cls, v):
        if v < 0:
            raise ValueError(f"seed must be an integer >= 0, got {v}")
        return v

    @model_validator(mode="after")
    def _bounds(self):
        if not self.min < self.mean < self.max:
            raise ValueError(f"need min < mean < max, got min {self.min * 3.6:.6g}, mean {self.mean * 3.6:.6g}, "
                             f"max {self.max * 3.6:.6g} km/h")
        return self


GENERATED = {"csv": CsvSpeedSpec, "stop_go": StopGoSpec, "random": RandomSpeedSpec}
SPEED_FORMS = ("a speed such as '20 km/h'", "{profile: [[distance, speed], ...]}", "{csv: path, by: time|distance}",
               "{stop_go: {cruise_speed:, stop_duration:, acceleration:, deceleration:, spacing:}}",
               "{random: {mean:, spread:, correlation_length:, seed:}}")


def parse_speed_spec(value: dict):
    """The scenario's `speed:` mapping (other than `profile`) -> a spec model; ValueError naming the key."""
    from pydantic import ValidationError

    keys = sorted(value)
    if "csv" in value:
        data, kind = value, "csv"
    elif len(keys) == 1 and keys[0] in ("stop_go", "random"):
        kind = keys[0]
        data = value[kind]
        if not isinstance(data, dict):
            raise ValueError(f"{kind}: expected a mapping of settings (see docs/scenarios.md)")
    else:
        raise ValueError(f"unknown form {keys}; allowed: " + "; ".join(SPEED_FORMS))
    try:
        return GENERATED[kind].model_validate(data)
    except ValidationError as exc:
        parts = []
        for err in sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden"):
            loc = ".".join(str(p) for p in err["loc"])
            msg = err["msg"].removeprefix("Value error, ")
            if err["type"] == "extra_forbidden":
                msg = "unknown key (check the spelling)"
            where = (loc or "csv") if kind == "csv" else (f"{kind}.{loc}" if loc else kind)
            parts.append(f"{where}: {msg}")
        raise ValueError("; ".join(parts)) from None


# --- building the tables ----------------------------------------------------------------------------
def build_speed_profile(spec, distance_m: float, base_dir: Path | None = None) -> SpeedProfile:
    """The drive's table for a scenario `speed` value (float, {profile}, or a spec of this module)."""
    if isinstance(spec, (int, float)):
        return constant(float(spec))
    if isinstance(spec, CsvSpeedSpec):
        return read_speed_csv(spec, distance_m, base_dir)
    if isinstance(spec, StopGoSpec):
        return stop_go_profile(spec, distance_m + MARGIN_M)
    if isinstance(spec, RandomSpeedSpec):
        return random_profile(spec, distance_m)
    points = getattr(spec, "profile", None)
    if points is not None:
        d, v = zip(*points)
        return SpeedProfile(np.array(d, float), np.array(v, float), description="profile over distance")
    raise TypeError(f"speed: unsupported specification {spec!r}")


def _ramp(v_from: float, v_to: float, accel: float, s0: float):
    """Distances and speeds of a constant-acceleration ramp (s - s0 = |v^2 - v_from^2| / 2a).

    Sampled in speed with steps of at most RAMP_SPEED_STEP_M_PER_S and 5 % of the speed, so the
    table's own acceleration v dv/ds stays within a few per cent of `accel` even near a stop.
    """
    lo, hi = sorted((v_from, v_to))
    v = [lo]
    while v[-1] < hi:
        v.append(min(hi, v[-1] + min(RAMP_SPEED_STEP_M_PER_S, 0.05 * v[-1])))
    v = np.array(v if v_from <= v_to else v[::-1])
    s = s0 + np.abs(v * v - v_from * v_from) / (2.0 * accel)
    return s, v


def stop_go_profile(spec: StopGoSpec, length_m: float) -> SpeedProfile:
    """Cycles from rest: accelerate, cruise, brake, stand (creep at min_speed for stop_duration)."""
    V, v0 = spec.cruise_speed, spec.min_speed
    d_acc, d_dec, d_stop = spec.ramp_distances()
    cycles = int(math.ceil(length_m / spec.spacing))
    s_acc, v_acc = _ramp(v0, V, spec.acceleration, 0.0)
    s_dec, v_dec = _ramp(V, v0, spec.deceleration, 0.0)
    per_cycle = s_acc.size + s_dec.size + 2
    if cycles * per_cycle > MAX_TABLE_POINTS:
        raise UserInputError(f"speed.stop_go: {cycles} cycles over {length_m / 1e3:.6g} km exceed "
                             f"{MAX_TABLE_POINTS} table points; raise spacing")
    S, Vs = [], []
    for k in range(cycles):
        s0 = k * spec.spacing
        cruise_end = s0 + spec.spacing - d_dec - d_stop
        S += [s0 + s_acc, [cruise_end] if cruise_end > s0 + d_acc else [], cruise_end + s_dec,
              [s0 + spec.spacing]]
        Vs += [v_acc, [V] if cruise_end > s0 + d_acc else [], v_dec, [v0]]
    s = np.concatenate([np.atleast_1d(np.asarray(x, float)) for x in S])
    v = np.concatenate([np.atleast_1d(np.asarray(x, float)) for x in Vs])
    keep = np.concatenate([[True], np.diff(s) > 1e-9])
    return SpeedProfile(s[keep], v[keep], description=(
        f"stop-go: cruise {V * 3.6:.4g} km/h, a stop of {spec.stop_duration:.4g} s every {spec.spacing:.6g} m, "
        f"+{spec.acceleration:.3g}/-{spec.deceleration:.3g} m/s^2"))


def smooth_noise(n_points: int, spacing_m: float, correlation_length_m: float, seed: int) -> np.ndarray:
    """Stationary Gaussian noise on a grid, unit variance, correlation exp(-ds^2 / (2 l^2)).

    White noise convolved with the Gaussian kernel of standard deviation l/sqrt(2) (the convolution
    of two such kernels is the Gaussian correlation of length scale l); seeded PCG64.
    """
    from scipy.ndimage import gaussian_filter1d

    sigma = correlation_length_m / math.sqrt(2.0) / spacing_m
    pad = int(math.ceil(5 * sigma)) + 1
    white = np.random.default_rng(seed).standard_normal(n_points + 2 * pad)
    g = gaussian_filter1d(white, sigma, mode="nearest", truncate=5.0)[pad:pad + n_points]
    # the kernel's gain: sum of squared weights = 1 / (2 sqrt(pi) sigma) for a Gaussian of width sigma
    return g * math.sqrt(2.0 * math.sqrt(math.pi) * sigma)


def random_profile(spec: RandomSpeedSpec, distance_m: float) -> SpeedProfile:
    """A smooth random speed with the requested trip average and spread over [0, distance_m].

    v(s) = clip(mu + sigma g(s), min, max), g = `smooth_noise`. mu and sigma are solved so that over
    the drive the time average (distance / time, with the drive's own trapezoidal t(s)) equals `mean`
    exactly and the time-weighted standard deviation equals `spread`: the realisation is scaled to the
    request. Clipping may make a spread unreachable, which is an error naming the bounds.
    """
    from scipy.optimize import brentq

    ds = min(spec.correlation_length / 10.0, 1.0)      # 1 m: the grid of the drive's own t(s)
    n_drive = int(math.ceil(distance_m / ds)) + 1
    n = n_drive + int(math.ceil(MARGIN_M / ds))
    if n > MAX_TABLE_POINTS:
        raise UserInputError(f"speed.random: {n} table points over {distance_m / 1e3:.6g} km at a correlation "
                             f"length of {spec.correlation_length:.4g} m (at most {MAX_TABLE_POINTS}); "
                             "raise correlation_length")
    s = np.arange(n) * ds
    g = smooth_noise(n, ds, spec.correlation_length, spec.seed)
    g_drive = g[:n_drive]
    g = (g - g_drive.mean()) / max(g_drive.std(), 1e-300)
    lo, hi = spec.min, spec.max

    def stats(mu, sigma):
        v = np.clip(mu + sigma * g[:n_drive], lo, hi)
        dv = np.diff(v)
        flat = np.abs(dv) <= 1e-9 * v[:-1]
        # time on each step, exact for the linear segments (as SpeedTable.time_grid)
        w = np.where(flat, ds / v[:-1], ds * np.log(v[1:] / v[:-1]) / np.where(flat, 1.0, dv))
        T = np.sum(w)
        mean = (s[n_drive - 1]) / T
        vm = 0.5 * (v[1:] + v[:-1])
        return mean, math.sqrt(float(np.sum(w * (vm - mean) ** 2) / T))

    sigma = spec.spread
    mu = spec.mean
    for _ in range(60):
        if sigma == 0.0:
            break
        mu = brentq(lambda m: stats(m, sigma)[0] - spec.mean, lo - 10 * sigma - hi, hi + 10 * sigma + hi,
                    xtol=1e-13, rtol=1e-14)
        got = stats(mu, sigma)[1]
        if abs(got - spec.spread) <= 1e-10 * spec.spread:
            break
        if got <= 0:
            break
        sigma *= spec.spread / got
        if sigma > 100 * (hi - lo):
            break
    mean, spread = stats(mu, sigma)
    if abs(spread - spec.spread) > SPREAD_TOLERANCE * max(spec.spread, 1e-9):
        raise UserInputError(
            f"speed.random: a spread of {spec.spread * 3.6:.4g} km/h around a mean of {spec.mean * 3.6:.4g} km/h "
            f"cannot be reached between min {lo * 3.6:.4g} and max {hi * 3.6:.4g} km/h (clipping leaves "
            f"{spread * 3.6:.4g} km/h); widen [min, max] or lower the spread")
    v = np.clip(mu + sigma * g, lo, hi)
    return SpeedProfile(s, v, description=(
        f"random: mean {spec.mean * 3.6:.4g} km/h (trip average), spread {spec.spread * 3.6:.4g} km/h, "
        f"correlation length {spec.correlation_length:.4g} m, seed {spec.seed}, in [{lo * 3.6:.4g}, {hi * 3.6:.4g}] km/h"))


# --- recorded drives ---------------------------------------------------------------------------------
_UNIT_ALIASES = {"km_h": "km/h", "kmh": "km/h", "kph": "km/h", "m_s": "m/s", "mps": "m/s", "mph": "mph",
                 "s": "s", "sec": "s", "min": "min", "h": "hour", "hr": "hour", "m": "m", "km": "km", "mi": "mile"}
_KIND_UNIT = {"time": "s", "distance": "m", "speed": "m/s"}


def parse_column(name: str, where: str) -> tuple[str, float]:
    """'speed_km_h', 'time_s', 'distance [km]', 'speed (m/s)' -> (kind, factor to SI)."""
    text = name.strip()
    m = re.fullmatch(r"(time|distance|speed)\s*(?:[\[(](.+)[\])]|_(.+))", text, flags=re.IGNORECASE)
    if not m:
        raise UserInputError(f"{where}: column {name!r}: expected time_<unit>, distance_<unit> or speed_<unit> "
                             "(e.g. time_s, distance_km, speed_km_h, or 'speed [km/h]')")
    kind = m.group(1).lower()
    unit = (m.group(2) or m.group(3)).strip()
    unit = _UNIT_ALIASES.get(unit.lower(), unit)
    try:
        factor = parse_quantity(f"1 {unit}", _KIND_UNIT[kind], where=f"{where}: column {name!r}")
    except UserInputError as exc:
        raise UserInputError(str(exc)) from None
    return kind, factor


def speed_columns(header: list[str], where: str) -> tuple[list, list]:
    """(kind, factor) and kind ('time', 'distance', 'speed' or None: ignored) of each header column: columns that
    are not time_/distance_/speed_<unit> (a logger's gear, rpm, ...) are ignored and logged; a kind given twice is
    ambiguous and refused."""
    import logging

    kinds, ignored = [], []
    for h in header:
        if re.match(r"\s*(time|distance|speed)\b|\s*(time|distance|speed)_", h, flags=re.IGNORECASE):
            kinds.append(parse_column(h, where))
        else:
            kinds.append((None, 1.0))
            ignored.append(h.strip())
    names = [k for k, _ in kinds]
    for kind in ("time", "distance", "speed"):
        cols = [h for h, n in zip(header, names) if n == kind]
        if len(cols) > 1:
            raise UserInputError(f"{where}: {len(cols)} {kind} columns {cols}: which one is meant is ambiguous; "
                                 "keep one")
    if ignored:
        logging.getLogger("hpsim").debug(f"{where}: columns ignored: {', '.join(ignored)}")
    return kinds, names


def read_speed_csv(spec: CsvSpeedSpec, distance_m: float, base_dir: Path | None = None) -> SpeedProfile:
    """A recorded drive from a CSV with a header row: (time or distance, speed) columns with units."""
    path = Path(spec.csv).expanduser()
    if not path.is_absolute():
        path = Path(base_dir or Path.cwd()) / path
    where = f"speed.csv {path}"
    try:
        # a regular file of bounded size, BOM and CRLF as spreadsheets write them (hpsim.files)
        text = read_csv_text(path, what="a speed CSV file")
    except UserInputError as exc:
        raise UserInputError(f"speed.csv: {exc}") from None
    rows = [r for r in csv.reader(line for line in text.splitlines() if line.strip() and not line.startswith("#"))]
    if len(rows) < 3:
        raise UserInputError(f"{where}: expected a header row and at least 2 data rows")
    header = rows[0]
    kinds, names = speed_columns(header, where)
    if "speed" not in names or not ({"time", "distance"} & set(names)):
        raise UserInputError(f"{where}: expected a speed column and a time or distance column, got {header}")
    by = spec.by or ("time" if "time" in names else "distance")
    if by not in names:
        raise UserInputError(f"{where}: by: {by} needs a {by}_<unit> column, got {header}")
    i_x, i_v = names.index(by), names.index("speed")
    try:
        data = np.array([[float(r[i_x]), float(r[i_v])] for r in rows[1:]])
    except (ValueError, IndexError):
        bad = next(k for k, r in enumerate(rows[1:], start=2) if not _numeric_row(r, (i_x, i_v)))
        raise UserInputError(f"{where}: line {bad}: expected numbers in columns {header[i_x]!r} and "
                             f"{header[i_v]!r}") from None
    x = data[:, 0] * kinds[i_x][1]
    v = data[:, 1] * kinds[i_v][1]
    if not np.all(np.isfinite(data)):
        raise UserInputError(f"{where}: non-finite values")
    if np.any(np.diff(x) <= 0):
        k = int(np.argmax(np.diff(x) <= 0)) + 3
        raise UserInputError(f"{where}: line {k}: the {by} column must increase")
    if np.any(v < 0) or np.any(v > MAX_SPEED_M_PER_S * (1 + 1e-12)):
        k = int(np.argmax((v < 0) | (v > MAX_SPEED_M_PER_S * (1 + 1e-12)))) + 2
        raise UserInputError(f"{where}: line {k}: speed must be in [0, 150] km/h, got {v[k - 2] * 3.6:.6g} km/h")
    raised = int(np.sum(v < spec.min_speed))
    note = f"recorded drive {path.name} by {by}" + (f", {raised} speeds below {spec.min_speed * 3.6:.3g} km/h "
                                                   "driven at that creeping speed" if raised else "")
    if by == "time":
        table = SpeedTable.from_time_series(x - x[0], v, spec.min_speed, description=note)
    else:
        table = SpeedProfile(x - x[0], np.maximum(v, spec.min_speed), description=note)
    length = float(table.distances_m[-1])
    if length < distance_m:
        if not spec.repeat:
            raise UserInputError(f"{where}: the recorded drive covers {length:.6g} m, the scenario's distance is "
                                 f"{distance_m:.6g} m; shorten the distance or set repeat: true to drive it again")
        table = table.repeated(distance_m + MARGIN_M)
    return table


def _numeric_row(row, cols) -> bool:
    try:
        for c in cols:
            float(row[c])
        return True
    except (ValueError, IndexError):
        return False
