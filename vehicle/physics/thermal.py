"""Lumped thermal node per strut (REFERENCE §8): C dT/dt = P_diss - h A (T - T_amb) - radiation.

Convection: forced convection over a cylinder in cross flow (Churchill & Bernstein 1977,
Incropera eq. 7.54) at the air speed seen in the wheel bay, added to a natural-convection
coefficient; radiation to ambient with emissivity eps (Stefan-Boltzmann).
"""
from __future__ import annotations

from hpsim import symbolic as sym

STEFAN_BOLTZMANN = 5.670374419e-8  # W/(m^2 K^4), CODATA 2018


def churchill_bernstein_h(air_speed_m_per_s, diameter_m, k_air, nu_air, prandtl):
    """Mean forced-convection coefficient [W/(m^2 K)] of a cylinder in cross flow.

    Nu = 0.3 + 0.62 Re^(1/2) Pr^(1/3) / (1 + (0.4/Pr)^(2/3))^(1/4) (1 + (Re/282000)^(5/8))^(4/5)
    (Churchill & Bernstein 1977). Re -> 0 leaves the conduction term 0.3, which the natural
    convection coefficient dominates anyway.
    """
    Re = sym.fabs(air_speed_m_per_s) * diameter_m / nu_air
    Nu = 0.3 + 0.62 * sym.sqrt(Re) * prandtl ** (1.0 / 3.0) / (1.0 + (0.4 / prandtl) ** (2.0 / 3.0)) ** 0.25 \
        * (1.0 + (Re / 282000.0) ** 0.625) ** 0.8
    return Nu * k_air / diameter_m


def heat_loss(T_K, T_amb_K, h_conv, area_m2, emissivity):
    """Heat flow [W] from the strut to ambient: convection + radiation."""
    radiation = emissivity * STEFAN_BOLTZMANN * area_m2 * (T_K ** 4 - T_amb_K ** 4)
    return h_conv * area_m2 * (T_K - T_amb_K) + radiation


def temperature_rate(T_K, P_dissipated_W, T_amb_K, h_conv, area_m2, emissivity, capacity_J_per_K):
    """dT/dt [K/s] of the lumped node."""
    return (P_dissipated_W - heat_loss(T_K, T_amb_K, h_conv, area_m2, emissivity)) / capacity_J_per_K


def convection_coefficient(heat, vehicle_speed_m_per_s):
    """Total convective h [W/(m^2 K)] at a vehicle speed: natural + forced (wheel-bay air speed)."""
    forced = churchill_bernstein_h(heat.air_speed_ratio * vehicle_speed_m_per_s, heat.diameter,
                                   heat.air_conductivity, heat.air_kinematic_viscosity, heat.air_prandtl)
    return heat.convection_multiplier * (heat.natural_convection + forced)
