"""An excitation measure a strut can carry on a vehicle: its equivalent frequency (docs/physics.md).

Seed 001 keys its internal parameters on the frequency of a sinusoidal rig test. A drive has no frequency,
so the strut estimates one from its own motion with smooth states that a 4 ms step carries:

  x_m     moving mean of the deflection x:         dx_m/dt = (x - x_m) / (2 tau)
  s_v     mean square of the deflection rate v:    two first-order stages of time constant tau on v^2
  s_x     mean square of the deflection about x_m: two stages on (x - x_m)^2

  omega_eq^2 = (s_v + (omega_0 d_0)^2) / (s_x + d_0^2),   f_eq = omega_eq / (2 pi)

For x = x_0 + A sin(omega t) the mean squares are A^2 omega^2 / 2 and A^2 / 2, so omega_eq = omega exactly,
up to the filters' ripple. That ripple is at 2 omega, attenuated by (1 + (2 omega tau)^2) per stage (0.6 % per
stage at 0.5 Hz with tau = 2 s), plus the moving mean's ripple A / (2 omega tau). On random motion omega_eq is the
"mean-square frequency" sqrt(int omega^2 S(omega) / int S(omega)) of the deflection's spectrum (for Gaussian
motion 2 pi times Rice's rate of up-crossings of the mean), a smooth, bounded quantity. At rest (s_v, s_x << d_0^2) it reads omega_0
(the lowest frequency of the strut's maps, `deflection_floor` d_0): small motions are keyed on the slowest
rig test. The state names are `STATE_NAMES`; all states are >= 0 when started >= 0 (x_m aside), and slow
(tau of seconds): none is stiff.
"""
from __future__ import annotations

import math

from hpsim import symbolic as sym

__all__ = ["STATE_NAMES", "rates", "equivalent_frequency", "steady_states"]

STATE_NAMES = ("exc_xm", "exc_v2a", "exc_v2", "exc_dx2a", "exc_dx2")
_TWO_PI = 2.0 * math.pi
_MEAN_TIME_FACTOR = 2.0     # the moving mean of x averages over twice the mean-square stages' time constant


def rates(x_m, v_m_s, states: dict, tau_s):
    """d/dt of the excitation states (dict by `STATE_NAMES`) at deflection x_m [m] and rate v_m_s [m/s]."""
    dx = x_m - states["exc_xm"]
    return {
        "exc_xm": dx / (_MEAN_TIME_FACTOR * tau_s),
        "exc_v2a": (v_m_s * v_m_s - states["exc_v2a"]) / tau_s,
        "exc_v2": (states["exc_v2a"] - states["exc_v2"]) / tau_s,
        "exc_dx2a": (dx * dx - states["exc_dx2a"]) / tau_s,
        "exc_dx2": (states["exc_dx2a"] - states["exc_dx2"]) / tau_s,
    }


def equivalent_frequency(states: dict, f_rest_Hz, d0_m):
    """f_eq [Hz] = sqrt((s_v + (2 pi f_rest d0)^2) / (s_x + d0^2)) / (2 pi) (module docstring)."""
    w0d0 = _TWO_PI * f_rest_Hz * d0_m
    return sym.sqrt((states["exc_v2"] + w0d0 * w0d0) / (states["exc_dx2"] + d0_m * d0_m)) / _TWO_PI


def steady_states(x_mean_m, amplitude_m=0.0, frequency_Hz=0.0) -> dict:
    """The states' mean values under x = x_mean + A sin(2 pi f t) (rest: A = 0): the rig starts its estimator
    there, so the measure reads the test's frequency from the first cycle."""
    w = _TWO_PI * frequency_Hz
    v2 = 0.5 * (amplitude_m * w) ** 2
    x2 = 0.5 * amplitude_m ** 2
    return {"exc_xm": x_mean_m, "exc_v2a": v2, "exc_v2": v2, "exc_dx2a": x2, "exc_dx2": x2}
