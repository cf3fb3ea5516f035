"""Tyre: point contact (on the enveloped road) with vertical stiffness and damping, no tension."""
from __future__ import annotations

from hpsim import symbolic as sym


def tyre_force(deflection_m, deflection_rate_m_per_s, stiffness_N_per_m, damping_N_s_per_m, smoothing_m):
    """Vertical tyre force [N] >= 0: max(0, k d + c d'), C1-blended over +-k*smoothing (REFERENCE §3).

    deflection d = static + road - wheel (> 0 when pressed). A tyre cannot pull the wheel
    down, so the force is clipped at zero (lift-off).
    """
    raw = stiffness_N_per_m * deflection_m + damping_N_s_per_m * deflection_rate_m_per_s
    return sym.ramp(raw, stiffness_N_per_m * smoothing_m)
