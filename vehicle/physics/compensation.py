"""Pressure compensation (levelling) per strut (REFERENCE §9).

A slow loop moves oil into (or out of) the strut to hold its filtered mean deflection at
the nominal value: first-order filter of the deflection, smooth dead band on the error,
proportional oil flow with time constant tau, clipped to the pump's flow limit. Adding oil
takes gas space, so the strut extends.

The pump's cost is the oil volume it moves, int |q| dt per strut (`pumped_volume_rate`): the
loop both adds oil (pumped in against the strut's pressure) and drains it (let out through a
valve back to the reservoir, oil the pump has to lift again later), so a litre out costs as
much as a litre in. The net volume added, int q dt, is the strut's V_oil state.
"""
from __future__ import annotations

from hpsim import symbolic as sym


def filtered_deflection_rate(x_filtered_m, x_m, filter_time_constant_s):
    """d/dt of the low-passed deflection [m/s]."""
    return (x_m - x_filtered_m) / filter_time_constant_s


def dead_band(error_m, half_width_m, smoothing_m):
    """Smooth dead band: 0 inside +-half_width, error -+ half_width outside."""
    return sym.ramp(error_m - half_width_m, smoothing_m) - sym.ramp(-error_m - half_width_m, smoothing_m)


def oil_flow(x_filtered_m, x_nominal_m, gas_area_m2, time_constant_s, half_width_m, flow_limit_m3_s, smoothing_m):
    """Oil flow into the strut [m^3/s]: positive when the strut sits too deep (too compressed).

    Proportional law: q = A e / tau (moves the strut by e in about tau at constant load), with
    a smooth saturation at the flow limit.
    """
    e = dead_band(x_filtered_m - x_nominal_m, half_width_m, smoothing_m)
    q = gas_area_m2 * e / time_constant_s
    return flow_limit_m3_s * sym.tanh(q / flow_limit_m3_s)


def pumped_volume_rate(oil_flow_m3_s):
    """Rate [m^3/s] of the oil volume the loop moves: |q|, into or out of the strut alike.

    Integrated as a quadrature per strut (int |q| dt since the start). It is not smoothed: it
    feeds no other state and no Jacobian, and |q| equals |dV_oil/dt| exactly, so the moved
    volume is at least the net change of V_oil, with equality while the flow keeps its sign.
    """
    return sym.fabs(oil_flow_m3_s)
