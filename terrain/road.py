"""`Road`: two wheel tracks on a uniform grid, evaluated with NumPy or inside CasADi.

Interpolation: the clamped cubic spline through the samples (end slopes set to
zero), i.e. a cubic Hermite interpolant whose knot slopes solve the spline
equations m[i-1] + 4·m[i] + m[i+1] = 3·(z[i+1] - z[i-1])/Δ. It is C2 inside the
road; outside [0, length] the height is held at the end value with zero slope, so
the road is C1 everywhere (axles behind axle 1 start at negative distance).
NumPy (`evaluate`) and CasADi (`casadi_functions`, a B-spline node) evaluate
the same spline.

Axle k reads the same track at its own distance behind axle 1: s_k = s_1 - a_k
(`evaluate_axles`).

Passes (`terrain.passes`): the k-th wheel over the same ground may meet a compacted, smoother
surface; `evaluate(s, track, pass_index=k)` reads pass k's surface (built once per distinct pass
transform and cached; pass_index 0 and the default pass list give the road as built).
"""
from __future__ import annotations

from functools import cached_property
from pathlib import Path
from typing import Iterable

import numpy as np

from hpsim.errors import UserInputError
from hpsim.threads import beside_map

from .envelope import envelope_profile
from .passes import PassSpec, pass_profile, pass_spec
from .plausibility import check_plausible_tracks
from .profile_io import check_road_points, is_uniform, read_profile_csv, resample, write_profile_csv
from .store import key_of, stored_arrays


TRACKS = ("left", "right")


def track_index(track) -> int:
    """0 for "left"/0, 1 for "right"/1."""
    if isinstance(track, (int, np.integer)) and not isinstance(track, bool) and int(track) in (0, 1):
        return int(track)
    if isinstance(track, str) and track.lower() in TRACKS:
        return TRACKS.index(track.lower())
    raise UserInputError(f"track: {track!r} is not a wheel track; allowed 'left', 'right', 0 or 1")


def clamped_spline_slopes(z: np.ndarray, spacing_m: float) -> np.ndarray:
    """Knot slopes dz/ds of the clamped (zero end slope) cubic interpolating spline on a uniform grid."""
    n = z.size
    if n < 3:
        return np.zeros(n)
    from scipy.linalg import solve_banded    # here, not at the top: a road from the store needs no SciPy import

    ab = np.empty((3, n))
    ab[0] = 1.0
    ab[1] = 4.0
    ab[2] = 1.0
    ab[1, 0] = ab[1, -1] = 1.0  # m[0] = m[n-1] = 0
    ab[0, 1] = 0.0
    ab[2, -2] = 0.0
    rhs = np.empty(n)
    rhs[1:-1] = 3.0 * (z[2:] - z[:-2]) / spacing_m
    rhs[0] = rhs[-1] = 0.0
    return solve_banded((1, 1), ab, rhs, overwrite_ab=True, overwrite_b=True, check_finite=False)


class Road:
    """Left/right track heights [m] at distances i·spacing_m, i = 0..n-1 (distance starts at 0)."""

    def __init__(self, spacing_m: float, left_m, right_m, *, info: dict | None = None, copy: bool = True,
                 passes: list[PassSpec] | None = None, level_m: tuple | None = None, key: str | None = None):
        """copy=False takes over float64 arrays without copying (they become read-only).

        passes: the surface of pass 0, 1, ... (`terrain.passes`; default: the same for every pass);
        level_m: (left, right) persistent level changes inside the profile that the passes leave alone;
        key: the road's key in the road store (`terrain.store`, a random road): what is derived from it (envelopes,
        spline slopes, pass surfaces) is stored there too. None: computed each time.
        """
        left = np.array(left_m, dtype=float, copy=copy or None)
        right = np.array(right_m, dtype=float, copy=copy or None)
        if left.ndim != 1 or left.shape != right.shape or left.size < 2:
            raise ValueError("left_m and right_m must be 1-D arrays of the same length >= 2")
        if not spacing_m > 0:
            raise ValueError(f"spacing_m must be > 0 (got {spacing_m})")
        for a in (left, right):
            a.setflags(write=False)
        self._spacing = float(spacing_m)
        self._z = (left, right)
        self._slopes: list[np.ndarray | None] = [None, None]
        self.info = dict(info or {})
        self.passes = [p if isinstance(p, PassSpec) else PassSpec.model_validate(p) for p in (passes or [])]
        if level_m is not None:
            level_m = tuple(np.asarray(a, dtype=float) for a in level_m)
            if len(level_m) != 2 or any(a.shape != left.shape for a in level_m):
                raise ValueError("level_m must be (left, right) arrays of the profile's length")
        self._level = level_m
        self._pass_cache: dict = {}     # (PassSpec, track) -> (heights, knot slopes)
        self.key = key

    # -- grid -----------------------------------------------------------------
    @property
    def spacing_m(self) -> float:
        return self._spacing

    @property
    def n_points(self) -> int:
        return self._z[0].size

    @property
    def length_m(self) -> float:
        return (self.n_points - 1) * self._spacing

    @cached_property
    def distance_m(self) -> np.ndarray:
        d = np.arange(self.n_points) * self._spacing
        d.setflags(write=False)
        return d

    @property
    def left_m(self) -> np.ndarray:
        return self._z[0]

    @property
    def right_m(self) -> np.ndarray:
        return self._z[1]

    def heights(self, track, pass_index: int = 0) -> np.ndarray:
        """Grid heights [m] of `track` under pass `pass_index` (0: the first wheel over the ground)."""
        k = track_index(track)
        spec = pass_spec(self.passes, pass_index)
        if spec.identity:
            return self._z[k]
        return self._pass_arrays(spec, k)[0]

    def knot_slopes(self, track, pass_index: int = 0) -> np.ndarray:
        """Spline slopes at the grid points (computed once per track and pass surface, O(N))."""
        k = track_index(track)
        spec = pass_spec(self.passes, pass_index)
        if not spec.identity:
            return self._pass_arrays(spec, k)[1]
        if self._slopes[k] is None:
            (m,) = stored_arrays(self._derived_key("slopes", k), ("slopes",),
                                    lambda: (clamped_spline_slopes(self._z[k], self._spacing),))
            m.setflags(write=False)
            self._slopes[k] = m
        return self._slopes[k]

    def _derived_key(self, *operation) -> str | None:
        """The store's key of what `operation` derives from this road (None: not stored)."""
        return None if self.key is None else key_of(self.key, *operation)

    def _pass_arrays(self, spec: PassSpec, k: int):
        key = (spec.factor, spec.smoothing_length, k)
        if key not in self._pass_cache:
            def surface():
                level = None if self._level is None else self._level[k]
                z = pass_profile(self._z[k], self._spacing, spec, level)
                return z, clamped_spline_slopes(z, self._spacing)

            z, m = stored_arrays(self._derived_key("pass", *key), ("heights", "slopes"), surface)
            z.setflags(write=False)
            m.setflags(write=False)
            self._pass_cache[key] = (z, m)
        return self._pass_cache[key]

    @property
    def n_pass_surfaces(self) -> int:
        """Number of distinct entries in the pass list (passes beyond it repeat the last one)."""
        return max(1, len(self.passes))

    # -- evaluation -------------------------------------------------------------
    def evaluate(self, s_m, track, pass_index: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(height [m], slope dz/ds [-]) of `track` at distances `s_m` (any shape), clamped to [0, length].

        pass_index k: the surface the k-th wheel over this ground meets (`terrain.passes`).
        """
        z = self.heights(track, pass_index)
        m = self.knot_slopes(track, pass_index)
        s = np.asarray(s_m, dtype=float)
        x = np.clip(s.reshape(-1), 0.0, self.length_m)
        x /= self._spacing
        i = x.astype(np.intp)
        np.clip(i, 0, self.n_points - 2, out=i)              # NaN in -> NaN out, never a bad index
        t = x - i
        if not i.size:
            return t.reshape(s.shape), t.reshape(s.shape)
        # the Hermite cubic's coefficients per grid interval, on the stretch the points cover only (a block's
        # points lie on a few metres of road), then gathered per point: the same operations in the same order
        lo, hi = int(i.min()), int(i.max()) + 2
        zs, ms = z[lo:hi], m[lo:hi] * self._spacing
        dz = zs[1:] - zs[:-1]
        m0s, m1s = ms[:-1], ms[1:]
        c2s = 3.0 * dz - 2.0 * m0s - m1s                        # the t^2 and t^3 coefficients
        c3s = m0s + m1s - 2.0 * dz
        i -= lo
        z0, m0, c2, c3 = zs.take(i), m0s.take(i), c2s.take(i), c3s.take(i)
        t2 = t * t
        height = z0 + m0 * t
        height += c2 * t2
        height += c3 * (t2 * t)
        slope = (2.0 * c2) * t
        slope += m0
        slope += (3.0 * c3) * t2
        slope /= self._spacing
        if not s.ndim:
            return height[0], slope[0]
        return height.reshape(s.shape), slope.reshape(s.shape)

    def evaluate_axles(self, s_m, offsets_m: Iterable[float], track, passes: bool = False):
        """(height, slope) arrays of shape (n_axles, *shape(s_m)) for axles at s_m - offsets_m[k].

        passes=True: the k-th offset (in the order given) reads pass k's surface.
        """
        s = np.asarray(s_m, dtype=float)
        offsets = list(offsets_m)
        if not passes:
            off = np.asarray(offsets, dtype=float).reshape((-1,) + (1,) * s.ndim)
            return self.evaluate(s[None, ...] - off, track)
        out = [self.evaluate(s - a, track, pass_index=k) for k, a in enumerate(offsets)]
        return np.stack([h for h, _ in out]), np.stack([d for _, d in out])

    def casadi_function(self, track, window_m: tuple[float, float] | None = None, pass_index: int = 0):
        """CasADi Function `s -> (height, slope)` (B-spline node, same spline as `evaluate`).

        With `window_m = (start, end)` only that stretch is put in the function (cheaper to
        build for long roads); inside the window it equals the full-road spline, outside it the
        height is held at the window's end values and the slope is zero.
        """
        import casadi as ca
        from scipy.interpolate import make_interp_spline

        k = track_index(track)
        z = self.heights(k, pass_index)
        lo, hi = 0, self.n_points - 1
        if window_m is not None:
            lo = max(0, int(np.floor(window_m[0] / self._spacing)))
            hi = min(self.n_points - 1, int(np.ceil(window_m[1] / self._spacing)))
            if hi - lo < 3:
                raise UserInputError(f"window {window_m} m: must span at least 3 grid steps inside "
                                     f"[0, {self.length_m}] m")
        m = self.knot_slopes(k, pass_index)
        x = np.arange(lo, hi + 1) * self._spacing
        spl = make_interp_spline(x, z[lo:hi + 1], k=3, bc_type=([(1, m[lo])], [(1, m[hi])]))
        dspl = spl.derivative()  # exact derivative (quadratic B-spline): cheaper than ca.jacobian of the node
        s = ca.MX.sym("s")
        xs = ca.MX.sym("x")
        h = ca.bspline(xs, ca.DM(spl.c.tolist()), [spl.t.tolist()], [3], 1, {})
        n_basis = dspl.t.size - dspl.k - 1  # scipy pads c; casadi wants exactly one per basis function
        dh = ca.bspline(xs, ca.DM(dspl.c[:n_basis].tolist()), [dspl.t.tolist()], [2], 1, {})
        inner = ca.Function("spline", [xs], [h, dh])
        s_lo, s_hi = float(x[0]), float(x[-1])
        # the B-spline is zero outside its knot range [s_lo, s_hi] (ends included): hold the end values
        s_c = ca.fmin(ca.fmax(s, s_lo), s_hi)
        height, slope = inner(s_c)
        inside = ca.logic_and(s >= s_lo, s <= s_hi)
        slope = ca.if_else(inside, slope, 0.0)
        return ca.Function(f"road_{TRACKS[k]}", [s], [height, slope], ["s"], ["height", "slope"])

    def casadi_functions(self, window_m: tuple[float, float] | None = None) -> dict:
        """{"left": f, "right": f}, each a CasADi Function `s -> (height, slope)`; see casadi_function."""
        return {name: self.casadi_function(name, window_m) for name in TRACKS}

    # -- derived roads -----------------------------------------------------------
    def enveloped(self, contact_length_m: float) -> "Road":
        """New Road: both tracks averaged over the tyre contact length (see `terrain.envelope`)."""
        if not contact_length_m > 0:
            raise UserInputError(f"contact length: must be > 0 m (got {contact_length_m} m)")
        info = dict(self.info, contact_length_m=float(contact_length_m))

        def envelopes():
            tracks = beside_map(lambda z: envelope_profile(z, contact_length_m, self._spacing), self._z)
            return tracks + [envelope_profile(a, contact_length_m, self._spacing) for a in self._level or ()]

        key = self._derived_key("envelope", float(contact_length_m))
        names = ("left", "right") + (() if self._level is None else ("level_left", "level_right"))
        arrays = stored_arrays(key, names, envelopes)
        return Road(self._spacing, arrays[0], arrays[1], info=info, copy=False, passes=self.passes,
                    level_m=tuple(arrays[2:]) or None, key=key)

    def prepare(self, pass_indices: Iterable[int] = (0,)) -> "Road":
        """Compute the spline slopes (`knot_slopes`) of both tracks on these passes' surfaces now, the two tracks on
        two threads, instead of on the first `evaluate` of each; returns the road."""
        for k in dict.fromkeys(pass_indices):
            beside_map(lambda track: self.knot_slopes(track, k), (0, 1))
        return self

    # -- files ---------------------------------------------------------------------
    def to_csv(self, path: str | Path) -> None:
        write_profile_csv(path, self.distance_m, self._z[0], self._z[1])

    @classmethod
    def from_crg(cls, path: str | Path, track_width_m: float, spacing_m: float | None = None,
                 length_m: float | None = None, lateral_offset_m: float = 0.0) -> "Road":
        """The left and right tracks of an OpenCRG surface at the vehicle's track width, centred on
        v = lateral_offset_m [m] (positive: left of the reference line; terrain.crg)."""
        from .crg import read_crg

        step, left, right, info = read_crg(path, track_width_m, spacing_m, length_m, lateral_offset_m)
        return cls(step, left, right, info=info, copy=False)

    @classmethod
    def from_csv(cls, path: str | Path, spacing_m: float | None = None,
                 length_m: float | None = None) -> "Road":
        """Read a measured profile; distance shifted to start at 0 and resampled to a uniform grid.

        Refused (UserInputError naming the file and the distance) unless it is a road a vehicle can drive on
        (`terrain.plausibility`).

        spacing_m: target spacing (default: the file's own spacing if uniform, else its median step).
        length_m: keep only the first length_m metres (must not exceed the file's length).
        """
        d, left, right = read_profile_csv(path)
        span = float(d[-1] - d[0])
        if length_m is not None and length_m > span * (1 + 1e-9):
            raise UserInputError(f"{path}: length {length_m} m is longer than the profile in the file "
                                 f"({span} m)")
        uniform = is_uniform(d)
        native = span / (d.size - 1) if uniform else float(np.median(np.diff(d)))
        step = native if spacing_m is None else float(spacing_m)
        use = span if length_m is None else float(length_m)
        if spacing_m is not None:
            check_road_points(use, step, f"{path}: ")
        n = int(np.floor(use / step * (1 + 1e-12))) + 1
        if n < 2:
            raise UserInputError(f"{path}: spacing {step} m leaves fewer than 2 points over {use} m")
        keep_grid = uniform and abs(step - native) <= 1e-9 * native
        if keep_grid:
            left_u, right_u = left[:n], right[:n]
        else:
            left_u = resample(d, left, step, n)
            right_u = resample(d, right, step, n)
        check_plausible_tracks(str(path), step, left_u, right_u, start_m=float(d[0]))
        info = {"source": str(path), "distance_offset_m": float(d[0]), "resampled": not keep_grid}
        return cls(step, left_u, right_u, info=info, copy=keep_grid)  # file columns are strided views
