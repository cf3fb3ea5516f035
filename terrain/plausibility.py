"""Is a profile a road a vehicle can drive on? Finite elevations, bounded rises, a bounded range.

Every road source (OpenCRG surface, CSV profile, generated road with its events) passes
`check_plausible_tracks` before anything is driven on it or written from it. A damaged file or
a unit error (millimetres read as metres) is so refused with the file, the track, the distance and
the value, instead of reaching the vehicle model as a wall or a cliff.

The bounds and why:

- every elevation finite (NaN or inf: the file has a hole where a wheel runs);
- the rise within a tyre's contact length (CONTACT_LENGTH_M = 0.3 m, the low end of
  REFERENCE §5's 0.3-0.45 m) at most MAX_RISE_M = 2 m: more than the diameter of a heavy
  vehicle's wheel (a 14.00R20 is 1.24 m across) within the patch a tyre envelopes is a wall, not
  a road. A slope bound of 1 over the contact length would refuse ISO 8608 roads: with w = 2 the
  slope spectrum is white, (2π·n0)²·Gd(n0), so the chord slope over a length L has the variance
  (2π·n0)²·Gd(n0)/(2L), an RMS of 0.42 for class H over 0.3 m;
- range (highest minus lowest point of a track) at most MAX_RANGE_M = 100 m: obstacles stay
  below 1 m and the roughness of ISO 8608 class H spans a few metres, so the rest is grade,
  which a ride model takes as vertical motion only; 100 m is a 1 km climb at 10 %.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hpsim.errors import UserInputError

MAX_RISE_M = 2.0               # elevation change within one tyre contact length [m]
CONTACT_LENGTH_M = 0.3         # tyre contact length the rise is taken over [m] (REFERENCE §5)
MAX_RANGE_M = 100.0            # highest minus lowest elevation of one track [m]
_CHUNK = 1 << 20               # points per block of the rise scan (bounded work memory on long roads)


@dataclass(frozen=True)
class Implausibility:
    """Where and why a track is not a road: the track name, its distance [m], and the reason with the value."""
    track: str
    distance_m: float
    reason: str

    def message(self, source: str, coordinate: str = "") -> str:
        return (f"{source}: not a vehicle road: at {coordinate}{self.distance_m:.6g} m the {self.track} track "
                f"{self.reason}")


def _first_non_finite(z: np.ndarray) -> int | None:
    bad = ~np.isfinite(z)
    return int(np.argmax(bad)) if bad.any() else None


def _first_steep_chord(z: np.ndarray, lag: int, max_rise_m: float) -> int | None:
    """The first i with |z[i + lag] - z[i]| > max_rise_m, scanned in blocks; None if there is none."""
    for start in range(0, z.size - lag, _CHUNK):
        stop = min(start + _CHUNK, z.size - lag)
        steep = np.abs(z[start + lag:stop + lag] - z[start:stop]) > max_rise_m
        if steep.any():
            return start + int(np.argmax(steep))
    return None


def track_implausibility(name: str, spacing_m: float, z_m: np.ndarray, start_m: float = 0.0,
                         contact_length_m: float = CONTACT_LENGTH_M) -> Implausibility | None:
    """The first reason the track `z_m` (heights [m] at start_m + i·spacing_m) is not a road, or None.

    The rise is taken over max(contact_length_m, spacing_m), rounded up to whole grid steps.
    """
    z = np.asarray(z_m, dtype=float)
    i = _first_non_finite(z)
    if i is not None:
        return Implausibility(name, start_m + i * spacing_m, f"has no finite elevation ({z[i]})")
    if z.size < 2:
        return None
    lag = min(z.size - 1, max(1, int(np.ceil(contact_length_m / spacing_m - 1e-9))))
    base = lag * spacing_m
    i = _first_steep_chord(z, lag, MAX_RISE_M)
    if i is not None:
        return Implausibility(name, start_m + i * spacing_m,
                              f"goes from {z[i]:.6g} m to {z[i + lag]:.6g} m within {base:.4g} m (a road rises "
                              f"or falls at most {MAX_RISE_M:g} m within a tyre's contact length)")
    lo, hi = int(np.argmin(z)), int(np.argmax(z))
    if z[hi] - z[lo] > MAX_RANGE_M:
        return Implausibility(name, start_m + hi * spacing_m,
                              f"reaches {z[hi]:.6g} m, {z[hi] - z[lo]:.6g} m above its lowest point at "
                              f"{start_m + lo * spacing_m:.6g} m (a road's elevation range stays within "
                              f"{MAX_RANGE_M:g} m)")
    return None


def check_plausible_tracks(source: str, spacing_m: float, left_m: np.ndarray, right_m: np.ndarray,
                           start_m: float = 0.0, coordinate: str = "") -> None:
    """Raise UserInputError (one line: source, track, distance [m], value) unless both tracks are a road.

    source: the file or spec named in the message; start_m: the distance of the first point, as the
    source counts it (a CSV file's first distance, an OpenCRG file's u at the start); coordinate: the
    distance's name in the message ("u = " for OpenCRG).
    """
    for name, z in (("left", left_m), ("right", right_m)):
        found = track_implausibility(name, spacing_m, z, start_m)
        if found is not None:
            raise UserInputError(found.message(source, coordinate))
