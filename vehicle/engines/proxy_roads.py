"""The linear-model proxy's road part (`LinearProxy`), computed once per process for every drive on the same road.

The road under each tyre on the proxy's time grid and its spectrum depend on the road, the drive's time-distance
map, the stations' offsets and the proxy's grid (rate, padding), not on the struts: every design of a study on one
road and speed profile would compute the same arrays. `PROXY_ROADS` keeps them by a key of everything they are
computed from (`proxy_road_key`), so a drive gets what it would have computed alone, bit for bit. An entry holds
the grid (N,), the roads (n, N) and their spectrum (n, L/2 + 1, complex): on a 106 km drive at 20 km/h (N ~ 4.8e5
at 25 Hz, n = 8) about 65 MB, so only two are kept (the oldest dropped first). Drives on threads of one process
(ensemble lanes) ask at once: the first computes, the others wait for it (`ComputedOnce`)."""
from __future__ import annotations

import hashlib
import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from vehicle.engines.control_variate import on_grid_array, road_spectrum

_MISSING = object()


class _Slot:
    """One key's value and the lock its computation holds."""

    def __init__(self):
        self.lock = threading.Lock()
        self.value = _MISSING


class ComputedOnce:
    """At most `size` values by key, each computed once: `get(key, compute)` returns the kept value or computes it.
    Callers of one key at once wait for the one computing it (each key its own lock, so other keys go on); a
    computation that raises leaves no value, and the next caller computes again. size=0 keeps nothing (every `get`
    computes). `computed` counts the computations (what a test observes)."""

    def __init__(self, size: int):
        self.size = int(size)
        self._lock = threading.Lock()
        self._slots: OrderedDict = OrderedDict()
        self.computed = 0

    def get(self, key, compute):
        with self._lock:
            slot = self._slots.get(key)
            if slot is None:
                slot = self._slots[key] = _Slot()
                while len(self._slots) > self.size:
                    self._slots.popitem(last=False)
            else:
                self._slots.move_to_end(key)
        with slot.lock:
            if slot.value is _MISSING:
                slot.value = compute()
                with self._lock:
                    self.computed += 1
            return slot.value

    def clear(self) -> None:
        with self._lock:
            self._slots.clear()


@dataclass(frozen=True)
class ProxyRoad:
    """t (N,) [s]: the proxy's time grid; roads (n, N) [m]: the road under each tyre on it; spectrum: their
    `road_spectrum`. Read-only arrays, shared by the drives that ask for the same key."""

    t: np.ndarray
    roads: np.ndarray
    spectrum: tuple
    stretches: ComputedOnce = field(default_factory=lambda: ComputedOnce(2), compare=False)

    def stretch_spectrum(self, start: int, stop: int) -> tuple:
        """`road_spectrum` of the grid points start..stop-1 (the matched stretch, the same for each design)."""
        return self.stretches.get((int(start), int(stop)),
                                  lambda: _read_only_spectrum(road_spectrum(self.roads[:, start:stop])))


def _read_only_spectrum(spectrum: tuple) -> tuple:
    spectrum[0].setflags(write=False)
    return spectrum


def _station_surface(road, track: str, pass_index: int) -> bytes:
    """What identifies the heights a station reads: the road's store key (derived from everything the road is built
    from: `terrain.store`) with its pass surfaces, or the heights themselves when the road has no key."""
    if road.key is not None:
        return repr((road.key, road.spacing_m, road.passes, track, pass_index)).encode()
    return hashlib.sha256(memoryview(np.ascontiguousarray(road.heights(track, pass_index)))).digest() + \
        repr((road.spacing_m,)).encode()


def proxy_road_key(drive, t_end_s: float, s_m: np.ndarray, rate_hz: float, pad_s: float) -> str:
    """A digest of everything `proxy_road` computes from: the grid (rate, padding, end), the distance at each grid
    time (the drive's time-distance map there), and per station its surface (`_station_surface`) and offset."""
    m = drive.model
    h = hashlib.sha256(repr((float(rate_hz), float(pad_s), float(t_end_s), s_m.size)).encode())
    h.update(memoryview(np.ascontiguousarray(s_m)))
    for i in range(m.n):
        track = "left" if i % 2 == 0 else "right"
        h.update(_station_surface(drive.station_roads[i], track, m.params.station_axle(i)))
        h.update(repr(float(m.a[i])).encode())
    return h.hexdigest()


# the proxy road of the latest drives of this process (about 65 MB each on a 106 km drive: two kept)
PROXY_ROADS = ComputedOnce(2)


def proxy_road(drive, rate_hz: float, pad_s: float, kept: ComputedOnce = PROXY_ROADS) -> ProxyRoad:
    """The road under each tyre of `drive` (its model, station roads, time-distance map and distance) on the grid
    t = -pad_s .. t_end + pad_s at rate_hz (the grid heights linearly interpolated, held at the ends:
    `on_grid_array`), and its spectrum; from `kept` when a drive of this process computed it already."""
    t_end = float(np.interp(drive.settings.distance_m, drive.s_grid, drive.t_grid))
    t = np.arange(-pad_s, t_end + pad_s, 1.0 / rate_hz)
    s = np.interp(t, drive.t_grid, drive.s_grid, left=0.0)

    def compute() -> ProxyRoad:
        m = drive.model
        roads = np.empty((m.n, t.size))
        for i in range(m.n):
            road, track = drive.station_roads[i], ("left" if i % 2 == 0 else "right")
            roads[i] = on_grid_array(road.heights(track, m.params.station_axle(i)), road.spacing_m, s - m.a[i])
        spectrum = _read_only_spectrum(road_spectrum(roads))
        for a in (t, roads):
            a.setflags(write=False)
        return ProxyRoad(t, roads, spectrum)

    return kept.get(proxy_road_key(drive, t_end, s, rate_hz, pad_s), compute)
