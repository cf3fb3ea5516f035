"""What a speed profile asks of the vehicle: its longitudinal acceleration and jerk, checked before a drive.

The drive feeds the profile's acceleration a = v dv/ds (vehicle.scenario.speed.SpeedProfile.acceleration) to the model
as the longitudinal load transfer. A step in a table (5 -> 150 km/h within 0.1 m: about 870 g) or a random profile
with a correlation length of a metre asks for accelerations no vehicle makes, and the drive then fails far from the
cause (a non-finite state, oil at 281 degC). So before anything runs:

- |a| over the drive must not exceed the scenario's `max_acceleration` (default 1 g = 9.80665 m/s^2, a wheeled
  vehicle's braking limit on dry road; raise it for a test of a harder manoeuvre), and
- the jerk (the change of a from one table segment to the next over the time between their middles) must not exceed
  `max_jerk` (default MAX_JERK_M_PER_S3 = 50 m/s^3: a hard brake application takes a tenth of a second or more to
  reach 1 g; the generated stop-go ramps of 1-1.5 m/s^2 have at most 15 m/s^3).

The message gives the figure, where it is and what to change.
"""
from __future__ import annotations

import numpy as np

from hpsim.errors import UserInputError

G_M_PER_S2 = 9.80665
MAX_ACCELERATION_M_PER_S2 = G_M_PER_S2         # default max_acceleration: 1 g
MAX_JERK_M_PER_S3 = 50.0                       # default max_jerk
ACCELERATION_RANGE_M_PER_S2 = (0.1, 100.0)     # what max_acceleration may be set to
JERK_RANGE_M_PER_S3 = (0.1, 1e4)
# the scenario keys: (unit parsed, range, unit shown)
PROFILE_LIMIT_RANGES = {"max_acceleration": ("m/s**2", *ACCELERATION_RANGE_M_PER_S2, "m/s^2"),
                        "max_jerk": ("m/s**3", *JERK_RANGE_M_PER_S3, "m/s^3")}


def segment_accelerations(profile, distance_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(middle distance [m], largest |a| [m/s^2], time at the middle [s]) of each table segment within the drive;
    a = v dv/ds is largest at a segment's faster end."""
    d, v = profile.distances_m, profile.speeds_m_per_s
    if d.size < 2:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    inside = d[:-1] < distance_m
    slope = np.diff(v) / np.diff(d)
    a = np.maximum(np.abs(v[:-1]), np.abs(v[1:])) * np.abs(slope)
    mid = 0.5 * (d[:-1] + d[1:])
    s, t = profile.time_grid(float(min(distance_m, d[-1])) + 1.0)
    return mid[inside], a[inside], np.interp(mid[inside], s, t)


def check_profile(profile, distance_m: float, max_acceleration: float | None = None, max_jerk: float | None = None,
                  where: str = "speed") -> None:
    """UserInputError when the profile's acceleration or jerk over [0, distance_m] exceeds the limits (None: the
    defaults)."""
    max_acceleration = MAX_ACCELERATION_M_PER_S2 if max_acceleration is None else max_acceleration
    max_jerk = MAX_JERK_M_PER_S3 if max_jerk is None else max_jerk
    mid, a, t = segment_accelerations(profile, distance_m)
    if a.size and np.max(a) > max_acceleration * (1 + 1e-9):
        k = int(np.argmax(a))
        raise UserInputError(
            f"{where}: the profile asks for a longitudinal acceleration of {a[k]:.4g} m/s^2 ({a[k] / G_M_PER_S2:.3g} g) "
            f"at {mid[k]:.6g} m, more than max_acceleration {max_acceleration:.4g} m/s^2 "
            f"({max_acceleration / G_M_PER_S2:.3g} g); smooth the profile (a gentler ramp, a longer correlation_length) "
            "or raise max_acceleration")
    signed = _signed(profile, mid)
    if signed.size > 1:
        dt = np.diff(t)
        jerk = np.abs(np.diff(signed)) / np.maximum(dt, 1e-12)
        if np.max(jerk) > max_jerk * (1 + 1e-9):
            k = int(np.argmax(jerk))
            raise UserInputError(
                f"{where}: the profile's acceleration changes by {abs(signed[k + 1] - signed[k]):.3g} m/s^2 within "
                f"{dt[k]:.3g} s at {mid[k + 1]:.6g} m (jerk {jerk[k]:.4g} m/s^3), more than max_jerk "
                f"{max_jerk:.4g} m/s^3; smooth the profile or raise max_jerk")


def _signed(profile, mid: np.ndarray) -> np.ndarray:
    """The signed acceleration at the segment middles."""
    return np.asarray(profile.acceleration(mid), float) if mid.size else mid
