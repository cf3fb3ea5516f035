"""Orifice discharge as a function of the Reynolds number (viscosity, hence temperature, acting through physics).

The damping valves' law `struts.valves.orifice_flow`, q = C_d A sqrt(2/rho) dp / (dp^2 + p_cr^2)^(1/4), is a
discharge coefficient that depends on the Reynolds number of the jet: with the flow number
lambda = (d_h / nu) sqrt(2 |dp| / rho) (Borutzky, Barnard and Thoma 2002, Simul. Model. Pract. Theory 10, 141-152)
the effective coefficient is

    C_d,eff = C_d (1 + (lambda_cr / lambda)^4)^(-1/4),   lambda_cr = Re_cr / C_d,

laminar (C_d,eff proportional to lambda, flow linear in dp) below the critical flow number and the turbulent
C_d above it. p_cr is the pressure drop at lambda = lambda_cr. A warmer, thinner oil lowers p_cr and raises
C_d,eff at a given pressure drop: the temperature dependence of the check valve's coefficient that seed 001 §5.2
identified ("attributed to the decreased fluid viscosity") follows from its small opening's Reynolds number.
Pure functions of NumPy values or CasADi symbols, SI units.
"""
from __future__ import annotations

from hpsim import symbolic as sym

__all__ = ["critical_pressure", "flow_number", "discharge_coefficient"]


def critical_pressure(rho_kg_m3, nu_m2_s, critical_reynolds, cd, hydraulic_diameter_m):
    """p_cr [Pa] = rho/2 (Re_cr nu / (C_d d_h))^2: the pressure drop of the laminar-turbulent transition.

    At it the jet's Reynolds number C_d d_h sqrt(2 dp/rho) / nu equals Re_cr (Merritt 1967, Hydraulic Control
    Systems §3.2; Borutzky et al. 2002).
    """
    return 0.5 * rho_kg_m3 * (critical_reynolds * nu_m2_s / (cd * hydraulic_diameter_m)) ** 2


def flow_number(dp_Pa, rho_kg_m3, nu_m2_s, hydraulic_diameter_m):
    """lambda [-] = (d_h / nu) sqrt(2 |dp| / rho): the Reynolds number of the ideal jet (Borutzky et al. 2002)."""
    return hydraulic_diameter_m / nu_m2_s * sym.sqrt(2.0 * sym.fabs(dp_Pa) / rho_kg_m3)


def discharge_coefficient(dp_Pa, cd, p_crit_Pa):
    """C_d,eff [-] = C_d (dp^2 / (dp^2 + p_cr^2))^(1/4): the coefficient of `struts.valves.orifice_flow` at dp.

    Equal to C_d (1 + (lambda_cr/lambda)^4)^(-1/4) (module docstring); -> C_d for |dp| >> p_cr, -> 0 linearly in
    lambda in the laminar limit.
    """
    d2 = dp_Pa * dp_Pa
    return cd * sym.sqrt(sym.sqrt(d2 / (d2 + p_crit_Pa * p_crit_Pa)))
