"""The physical seal of the integrated strut: contact pressure over temperature and per-stroke LuGre levels.

The seal's Coulomb level is its contact pressure times the contact area and the friction coefficient. The rubber
seal expands more than the steel rod and its groove, so its interference, hence its contact pressure, rises with
temperature (seed 001 §5.2: "greater contact pressure at the seal-rod interface"); to first order
F_C(T) = F_C,ref (1 + c_T (T - T_ref)). The seal's asymmetric lips (seed 001 Fig. 1c) give each stroke direction
its own level; the LuGre element (`struts.friction.lugre_bristle_rate`, Canudas de Wit et al. 1995) carries the
force through every reversal by its bristle state, so pre-sliding hysteresis and the Stribeck effect follow from
amplitude and velocity and the force has no jump or notch at v = 0.
"""
from __future__ import annotations

from hpsim import symbolic as sym

__all__ = ["contact_coulomb_level", "stroke_level"]


def contact_coulomb_level(F_ref_N, T_K, T_ref_K, coefficient_per_K):
    """Coulomb level [N] at temperature T [K]: F_ref (1 + c_T (T - T_ref)) (module docstring), never below 0."""
    return F_ref_N * sym.fmax(1.0 + coefficient_per_K * (T_K - T_ref_K), 0.0)


def stroke_level(v_m_s, level_compression, level_rebound, eps_m_s):
    """A per-direction level blended by the smooth sign of v [m/s] (width eps): compression for v > 0."""
    w = 0.5 * (1.0 + sym.smooth_sign(v_m_s, eps_m_s))
    return w * level_compression + (1.0 - w) * level_rebound
