"""The settings an engine runs with, and their defaults, written once: the drive (`DriveSettings`), the
multiscale window layout (`MultiscaleSettings`) and the time-parallel split (`SEGMENTS_RANGE`,
`resolve_segments`, `resolve_time_parallel_lanes`). The scenario schema (vehicle.scenario.schema) validates the
user's keys and builds these; the engines (vehicle.engines) read them. Why each default is what it is: docs/engines.md."""
from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from hpsim.errors import UserInputError
from hpsim.validators import check_range

from vehicle.scenario.speed import SpeedProfile

DT_RANGE_S = (1e-4, 0.02)                     # solver.dt: 0.1 .. 20 ms
SEGMENTS_RANGE = (1, 64)                      # solver.time_parallel: processes (with 1 lane: one segment each)
TIME_PARALLEL_LANES_RANGE = (1, 16)           # solver.time_parallel_lanes: segments per process, in lockstep
TIME_PARALLEL_LANES_DEFAULT = "auto"          # solver.time_parallel_lanes not given
# "auto": at most this many. 1: one segment per process on the scalar engine, whose step split around the struts
# costs a lane-step's 1.65x only: the lanes' lockstep segments gain less than their joins cost (docs/engines.md,
# "Parallel in time")
TIME_PARALLEL_LANES_AUTO = 1


@dataclass
class DriveSettings:
    distance_m: float
    speed: SpeedProfile
    ambient_K: float = 298.15
    initial_temperatures_K: np.ndarray | float = 298.15
    compensation: bool = False
    dt_s: float = 0.004
    output_interval_s: float = 1.0
    samples_per_block: int = 10
    stats_interval_m: float = 1000.0
    # step-doubling error estimate (vehicle.numerics.error_estimate): tolerance on the relative error of
    # the strut heat, and every how many sample blocks one window is checked (0: no estimate)
    tolerance: float = 0.10
    error_check_every: int = 10

    def validate(self):
        if not self.distance_m > 0:
            raise UserInputError(f"distance: must be > 0 m, got {self.distance_m}")
        check_range("solver.dt", self.dt_s, *DT_RANGE_S, "ms", 1e3)
        k = self.output_interval_s / self.dt_s
        if abs(k - round(k)) > 1e-6 or round(k) < 1:
            raise UserInputError(f"output.interval: must be a whole number of steps of {self.dt_s * 1e3:.4g} ms, "
                                 f"got {self.output_interval_s} s")


@dataclass
class MultiscaleSettings:
    """Window layout of a multiscale drive (scenario `solver:` keys; ranges in vehicle.scenario.schema)."""

    window_m: float = 500.0          # averaged stretch of each window
    spacing_m: float = 5000.0        # one window per this much road (stratum)
    warm_up_m: float = 50.0          # stretch driven before the averaged one (start transient)
    placement: str = "weighted"      # "weighted" (denser where the final slow states remember more), "systematic"
    #                                  (at the start of each stratum) or "stratified" (random in it)
    seed: int = 0                    # of the stratified placement
    control_variate: bool = True     # regression on the road proxy (`road_proxy`, `control_variate`)
    proxy: str = "linear_model"      # the control variate's proxy: "linear_model" (the linearised vehicle's squared
    #                                  strut velocity) or "road_rate" (the band-passed road rate under each tyre)
    paired_windows: bool = True      # windows in pairs, the second from the start the slow model predicts, integrated
    #                                  beside the first and carried to its true start by its linear model (`run`)

    # paired windows: the second of a pair is integrated again from its true start when a strut temperature at its
    # predicted start is further off than this. The carry to the true start is exact to first order; its remainder
    # grows with the offset squared (road seed 0: offsets up to 4.8 K moved the end temperatures by up to 0.045 K
    # against the one-by-one run, with this limit 0.013 K; docs/engines.md, "Paired windows")
    PAIRED_START_TOLERANCE_K = 2.0
    WEIGHT_FLOOR = 0.15      # weighted placement: share of the window density that stays uniform
    # the road proxy of the control variate: the mean square road rate under each tyre in the band where a strut's
    # velocity follows the road (above the body modes, 1-2 Hz, below wheel hop, ~10 Hz: `hpsim modes`). Only
    # the variance of the estimate depends on it (a poor proxy gives beta ~ 0, the plain estimate; docs/engines.md)
    PROXY_BAND_HZ = (1.0, 10.0)
    PROXIES = ("road_rate", "linear_model")
    # the linear-model proxy (`vehicle.engines.linear_proxy`): the vehicle linearised at its standing equilibrium, the seal
    # friction by its describing-function damping at this strut velocity amplitude (prior: 0.1 m/s, plausible
    # 0.03-0.3 m/s), velocities on a grid of LINEAR_PROXY_RATE_HZ (prior: 25 Hz, Nyquist above the wheel hop),
    # transfer functions on LINEAR_PROXY_FREQUENCIES points (docs/engines.md, "Settings")
    LINEAR_PROXY_FRICTION_VELOCITY_M_S = 0.1
    LINEAR_PROXY_V_RANGE_M_S = (0.005, 1.0)   # where the matched amplitude is sought (`LinearProxy.matched_velocity`)
    # V matched to the first window's RMS strut velocity (equivalent linearisation, Roberts & Spanos 1990 ch. 5)
    LINEAR_PROXY_MATCH_RMS = True
    # the control variate regresses each slow state's station pattern on the same pattern of the proxy
    CV_PATTERNS = True
    LINEAR_PROXY_RATE_HZ = 25.0
    LINEAR_PROXY_FREQUENCIES = 1001

    def weighted_windows(self, distance_m: float, first_end_m: float, tau_s: float, t_of_s, s_of_t,
                         t_total_s: float) -> list[tuple[float, float]]:
        """Windows after the first (which ends at first_end_m) placed by the weight of each instant on the final
        slow states: density proportional to WEIGHT_FLOOR + e^{-(t_end - t)/tau} (tau: the slowest decay time of the
        slow states, from the first window), same number of windows as the systematic layout. The variance of
        the final state is sum over windows of (weight x stretch)^2 x (sampling variance), smallest for a density
        proportional to the weight; the floor keeps the early drive sampled (energy totals, long gaps)."""
        span = self.warm_up_m + self.window_m
        n = max(1, int(np.ceil(distance_m / self.spacing_m - 1e-9)))
        if n == 1:
            return []
        t0 = t_of_s(first_end_m)
        tg = np.linspace(t0, t_total_s, 2001)
        dens = self.WEIGHT_FLOOR + np.exp(-(t_total_s - tg) / max(tau_s, 1e-9))
        W = np.concatenate([[0.0], np.cumsum(0.5 * (dens[1:] + dens[:-1]) * np.diff(tg))])
        out, last_end = [], first_end_m
        # strata of equal weight, one window in the middle (by weight) of each; the last strata are the shortest
        for k in range(n - 1):
            t_start = float(np.interp(W[-1] * (k + 0.5) / (n - 1), W, tg))
            c = max(float(s_of_t(t_start)), last_end)
            if c + span > distance_m:
                break
            out.append((c, c + span))
            last_end = c + span
        # the last window ends with the drive: the final state's short memories (the oil-to-wall exchange, ~2 min
        # for the apc strut, what the after-drive loads see) are then simulated, not sampled
        if out:
            before = out[-2][1] if len(out) > 1 else first_end_m
            if distance_m - span >= before:
                out[-1] = (distance_m - span, distance_m)
        return out

    def windows(self, distance_m: float) -> list[tuple[float, float]]:
        """(start, end) of each window (warm-up included) along the drive; the first starts at 0."""
        span = self.warm_up_m + self.window_m
        n = max(1, int(np.ceil(distance_m / self.spacing_m - 1e-9)))
        rng = np.random.default_rng(self.seed)
        out = []
        for k in range(n):
            lo = k * self.spacing_m
            hi = min((k + 1) * self.spacing_m, distance_m)
            if k == 0 or self.placement == "systematic" or hi - lo <= span:
                c = lo
            else:
                c = lo + rng.uniform(0.0, hi - lo - span)
            out.append((c, min(c + span, distance_m)))
        return out


def resolve_segments(value) -> int:
    """solver.time_parallel: an int in SEGMENTS_RANGE or "auto" (one segment per CPU)."""
    if value is None:
        return 1
    if value == "auto":
        return max(1, min(os.cpu_count() or 1, SEGMENTS_RANGE[1]))
    return int(value)


def resolve_time_parallel_lanes(value, workers: int, duration_s: float, min_segment_s: float) -> int:
    """solver.time_parallel_lanes: segments per time-parallel process, run in lockstep on the lane library. An int
    in TIME_PARALLEL_LANES_RANGE as given; "auto" (None: TIME_PARALLEL_LANES_DEFAULT): TIME_PARALLEL_LANES_AUTO
    or one hardware vector of doubles if shorter, at most as many as keep every one of the workers x lanes
    segments at least min_segment_s long."""
    value = TIME_PARALLEL_LANES_DEFAULT if value is None else value
    if value != "auto":
        return int(value)
    from vehicle.numerics.lanes import default_lanes

    fit = int(duration_s // (max(1, workers) * min_segment_s))
    return max(1, min(TIME_PARALLEL_LANES_AUTO, default_lanes(), fit))
