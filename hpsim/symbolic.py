"""Math that works on NumPy values and CasADi symbols alike.

Physics functions in `struts`, `terrain` and `vehicle` use these instead of
`np.*` or `ca.*` directly, so the same equation can be evaluated numerically
(tests, tables) or assembled into a CasADi DAE. Also the smooth approximations
of non-smooth laws (sign, abs, max, step) that implicit and explicit integrators
handle well.
"""
from __future__ import annotations

import casadi as ca
import numpy as np

_CASADI = (ca.SX, ca.MX, ca.DM)


def is_symbolic(*values) -> bool:
    return any(isinstance(v, _CASADI) for v in values)


def exp(x):
    return ca.exp(x) if is_symbolic(x) else np.exp(x)


def log(x):
    return ca.log(x) if is_symbolic(x) else np.log(x)


def log10(x):
    return ca.log10(x) if is_symbolic(x) else np.log10(x)


def sqrt(x):
    return ca.sqrt(x) if is_symbolic(x) else np.sqrt(x)


def tanh(x):
    return ca.tanh(x) if is_symbolic(x) else np.tanh(x)


def fabs(x):
    return ca.fabs(x) if is_symbolic(x) else np.abs(x)


def fmax(a, b):
    return ca.fmax(a, b) if is_symbolic(a, b) else np.maximum(a, b)


def fmin(a, b):
    return ca.fmin(a, b) if is_symbolic(a, b) else np.minimum(a, b)


def if_else(cond, a, b):
    """cond ? a : b (both branches are evaluated)."""
    if is_symbolic(cond, a, b):
        return ca.if_else(cond, a, b)
    return np.where(cond, a, b)


def vertcat(*xs):
    if is_symbolic(*xs):
        return ca.vertcat(*xs)
    return np.concatenate([np.atleast_1d(np.asarray(x, dtype=float)).ravel() for x in xs])


# --- smooth approximations -------------------------------------------------------------

def smooth_sign(x, eps):
    """sgn(x) ~ x / sqrt(x^2 + eps^2): odd, C-infinity, |.| < 1 (REFERENCE §7)."""
    return x / sqrt(x * x + eps * eps)


def smooth_abs(x, eps):
    """|x| ~ sqrt(x^2 + eps^2) - eps: even, zero at zero."""
    return sqrt(x * x + eps * eps) - eps


def smooth_pos(x, eps):
    """max(x, 0) ~ (x + sqrt(x^2 + eps^2)) / 2."""
    return 0.5 * (x + sqrt(x * x + eps * eps))


def smooth_step(x, x0, x1):
    """0 below x0, 1 above x1, C1 cubic in between (x1 > x0)."""
    s = (x - x0) / (x1 - x0)
    s = fmin(fmax(s, 0.0), 1.0)
    return s * s * (3.0 - 2.0 * s)


def ramp(x, eps):
    """max(x, 0) with a C1 quadratic blend on [-eps, eps]; exactly 0 below -eps and x above eps.

    Unlike `smooth_pos` it leaves no tail, so a contact law built on it is exactly inactive
    away from contact (end stops, tyre lift-off, dead bands).
    """
    return if_else(x <= -eps, 0.0 * x, if_else(x >= eps, x, (x + eps) * (x + eps) / (4.0 * eps)))


def interp_linear(x, xs, ys):
    """Piecewise-linear interpolation of the points (xs[k], ys[k]) at x, held constant outside [xs[0], xs[-1]].

    y = ys[0] + sum_k (ys[k+1] - ys[k]) / (xs[k+1] - xs[k]) clip(x - xs[k], 0, xs[k+1] - xs[k]): only
    fmin/fmax, so x, xs and ys may be NumPy values or CasADi symbols (xs strictly increasing).
    """
    y = ys[0] + 0.0 * x
    for k in range(len(xs) - 1):
        h = xs[k + 1] - xs[k]
        y = y + (ys[k + 1] - ys[k]) / h * fmin(fmax(x - xs[k], 0.0), h)
    return y


def interp_bilinear(x, y, xs, ys, table):
    """Piecewise-bilinear interpolation of table[i][j] at (xs[i], ys[j]), clamped outside the grid
    (`interp_linear` along y per row, then along x); NumPy- and CasADi-friendly."""
    rows = [interp_linear(y, ys, row) for row in table]
    return interp_linear(x, xs, rows)
