"""The root of a noisy scalar function of one parameter: its noise floor, and steps on a regression.

A drive's outputs are not smooth in its parameters below some level: seal friction sticks and slips,
so a change of a parameter far below any physical meaning (1e-12 relative) moves the stick-slip
events and, with them, the mean strut temperature rise after 1.5 km by a few millikelvin
(docs/validation.md "Calibration"). A root finder that steps on secants through such noise wanders,
and a tolerance below the noise can only be met by luck. Here:

- `noise_floor` evaluates the function again at rounding-level perturbations of one point,
  x (1 + k eps) with eps = 1e-12 and k = 1, -1, 2, -2, ...: any change beyond the function's smooth
  slope times 1e-12 is noise. The floor is two sample standard deviations of the evaluations
  (the half-width holding about 95 % of them for Gaussian noise). With all `max_runs` = 8
  perturbations (9 evaluations, 8 degrees of freedom) the measured standard deviation is above 0.45 of
  the true one with 99 % probability (chi-square); it stops early, after `min_runs` perturbations,
  when the tolerance is already `clear_factor` times the floor measured so far.
- `regression_root` fits y = a + b ln(x) by least squares to the evaluations at the (up to) three
  distinct points nearest the target (repeated evaluations of a point all count), and returns the
  root of that line: the noise averages out instead of setting the step.

No physics here: the function is handed in.
"""
from __future__ import annotations

import math
from typing import Callable

import numpy as np

PERTURBATION = 1e-12        # relative; ~4500 float64 roundings of the value, far below any physical meaning
FLOOR_SIGMAS = 2.0          # the floor: this many standard deviations of the noise (~95 % of evaluations)


def perturbed(x: float, k: int, eps: float = PERTURBATION) -> float:
    """x changed by a rounding-level amount: the k-th of x (1 + eps), x (1 - eps), x (1 + 2 eps), ..."""
    step = (k + 1) // 2 * (1 if k % 2 else -1)
    return x * (1.0 + step * eps)


def floor_of(ys) -> float:
    """FLOOR_SIGMAS sample standard deviations of repeated evaluations (0 for fewer than two)."""
    ys = np.asarray(ys, float)
    return float(FLOOR_SIGMAS * np.std(ys, ddof=1)) if ys.size > 1 else 0.0


def noise_floor(f: Callable[[float], float], x: float, y0: float, tol: float, *, min_runs: int = 2,
                max_runs: int = 8, clear_factor: float = 5.0, log=None) -> tuple[float, list[tuple[float, float]]]:
    """(floor, [(perturbed x, y), ...]): the noise of f near x, where f(x) = y0 is already known.

    Evaluates f at `perturbed(x, k)` for k = 1 .. max_runs; stops after min_runs when tol is above
    clear_factor times the floor so far (the noise then cannot matter)."""
    samples = []
    for k in range(1, max_runs + 1):
        xk = perturbed(x, k)
        samples.append((xk, float(f(xk))))
        floor = floor_of([y0] + [y for _, y in samples])
        if log is not None:
            log(f"noise probe {k}: x (1 {xk / x - 1:+.0e}) -> {samples[-1][1]:.6g}; floor so far {floor:.3g}")
        if k >= min_runs and tol > clear_factor * floor:
            break
    return floor_of([y0] + [y for _, y in samples]), samples


def regression_root(points, target: float, n_points: int = 3) -> tuple[float, float] | None:
    """(x, slope dy/dln x) where the least-squares line y = a + b ln(x) through the evaluations at the
    n_points distinct x nearest the target crosses it; None with fewer than two distinct x.

    points: (x, y) pairs; repeated x (a point and its noise probes, recorded at the nominal x) count
    once each in the fit, so a point evaluated several times weighs more."""
    by_x: dict[float, list[float]] = {}
    for x, y in points:
        by_x.setdefault(x, []).append(y)
    nearest = sorted(by_x, key=lambda x: abs(np.mean(by_x[x]) - target))[:n_points]
    if len(nearest) < 2:
        return None
    lx = np.array([math.log(x) for x in nearest for _ in by_x[x]])
    y = np.array([v for x in nearest for v in by_x[x]])
    b, a = np.polyfit(lx, y, 1)
    if not math.isfinite(b) or b == 0:
        return None
    return math.exp((target - a) / b), float(b)


def mean_at(points, x: float) -> float:
    """The mean of the evaluations recorded at x."""
    return float(np.mean([y for xi, y in points if xi == x]))
