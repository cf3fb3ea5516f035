"""Hydraulic oil and gas-oil emulsion properties (REFERENCE §7; seed 000 eq. 6; seed 001 eq. 8-11, Table 1).

Pure functions of NumPy values or CasADi SX/MX symbols (math through `hpsim.symbolic`), SI
units (K, Pa, m^3, kg/m^3, m^2/s); every coefficient is an argument.
"""
from __future__ import annotations

import math

from hpsim import symbolic as sym

__all__ = [
    "walther_kinematic_viscosity",
    "walther_coefficients",
    "andrade_kinematic_viscosity",
    "viscosity_extrapolation_range",
    "oil_density",
    "oil_bulk_modulus",
    "oil_volume",
    "thermal_expansion_into_gas",
    "emulsion_gas_fraction",
    "emulsion_density",
    "emulsion_bulk_modulus",
]

_LN10 = math.log(10.0)      # mathematical constant (10**y = exp(y ln 10))
_CST_PER_M2_S = 1.0e6       # unit conversion: 1 m^2/s = 1e6 cSt (mm^2/s)
_WALTHER_SHIFT_CST = 0.7    # the 0.7 cSt of the ASTM D341 Walther equation (part of the law)


def _pow10(y):
    return sym.exp(_LN10 * y)


# --- viscosity --------------------------------------------------------------------------------

def walther_kinematic_viscosity(T_K, A, B):
    """Kinematic viscosity [m^2/s] from Walther / ASTM D341: log10 log10(nu + 0.7) = A - B log10 T (nu cSt, T K).

    REFERENCE §7. A, B dimensionless (from `walther_coefficients`); valid for nu >~ 2 cSt,
    the range of the simple D341 form.
    """
    nu_cSt = _pow10(_pow10(A - B * sym.log10(T_K))) - _WALTHER_SHIFT_CST
    return nu_cSt / _CST_PER_M2_S


def walther_coefficients(T1_K, nu1_m2_s, T2_K, nu2_m2_s):
    """Walther coefficients (A, B) through two datasheet points (T [K], nu [m^2/s]), e.g. 40 °C and 100 °C.

    Solves log10 log10(nu_i + 0.7) = A - B log10 T_i (nu in cSt) for i = 1, 2 (ASTM D341, REFERENCE §7).
    """
    Z1 = sym.log10(sym.log10(nu1_m2_s * _CST_PER_M2_S + _WALTHER_SHIFT_CST))
    Z2 = sym.log10(sym.log10(nu2_m2_s * _CST_PER_M2_S + _WALTHER_SHIFT_CST))
    L1, L2 = sym.log10(T1_K), sym.log10(T2_K)
    B = (Z1 - Z2) / (L2 - L1)
    A = Z1 + B * L1
    return A, B


def andrade_kinematic_viscosity(T_K, T1_K, nu1_m2_s, T2_K, nu2_m2_s):
    """Kinematic viscosity [m^2/s] from Andrade's law ln nu = a + b / T through the same two datasheet points.

    A second standard extrapolation of liquid viscosity (E. N. da C. Andrade, Nature 125, 309, 1930): between
    the points it and Walther agree closely; how far apart they drift outside shows how uncertain an
    extrapolation of the two points is.
    """
    b = sym.log(nu1_m2_s / nu2_m2_s) / (1.0 / T1_K - 1.0 / T2_K)
    return nu1_m2_s * sym.exp(b * (1.0 / T_K - 1.0 / T1_K))


def viscosity_extrapolation_range(T1_K, nu1_m2_s, T2_K, nu2_m2_s, rel_disagreement):
    """(T_low, T_high) [K]: the temperatures beyond the datasheet points (T1 < T2) where the Walther and the
    Andrade extrapolations through them first differ by `rel_disagreement` (relative to Walther).

    Inside, the two laws agree better than that, so an extrapolation error of that size is the most the
    missing data can hide; floats only (a bisection on the monotone gap, 1 mK)."""
    A, B = walther_coefficients(T1_K, nu1_m2_s, T2_K, nu2_m2_s)

    def gap(T):
        w = float(walther_kinematic_viscosity(T, A, B))
        return abs(w - float(andrade_kinematic_viscosity(T, T1_K, nu1_m2_s, T2_K, nu2_m2_s))) / w

    def edge(inside, outside):
        if gap(outside) < rel_disagreement:
            return outside
        while abs(outside - inside) > 1e-3:
            mid = 0.5 * (inside + outside)
            inside, outside = (mid, outside) if gap(mid) < rel_disagreement else (inside, mid)
        return inside

    return edge(T1_K, max(T1_K - 200.0, 1.0)), edge(T2_K, T2_K + 300.0)


# --- density, bulk modulus, thermal expansion ------------------------------------------------

def oil_density(T_K, rho_ref, T_ref_K, alpha_per_K):
    """Oil density [kg/m^3]: rho = rho_ref / (1 + alpha (T - T_ref)) (seed 001 eq. 10, Table 1: alpha = 0.00107 1/K)."""
    return rho_ref / (1.0 + alpha_per_K * (T_K - T_ref_K))


def oil_bulk_modulus(T_K, beta_ref_Pa, T_ref_K, slope_Pa_per_K):
    """Oil bulk modulus [Pa] falling linearly with temperature: beta = beta_ref - slope (T - T_ref).

    Seed 001 eq. 9 (beta_h = beta_h0 - zeta dT) and Table 1 (zeta = 8 MPa/K); REFERENCE §7.
    """
    return beta_ref_Pa - slope_Pa_per_K * (T_K - T_ref_K)


def oil_volume(T_K, V_ref_m3, T_ref_K, beta_per_K):
    """Oil volume [m^3] at temperature T: V = V_ref (1 + beta (T - T_ref)) (seed 000 eq. 6)."""
    return V_ref_m3 * (1.0 + beta_per_K * (T_K - T_ref_K))


def thermal_expansion_into_gas(T_K, V_oil_ref_m3, T_ref_K, beta_per_K):
    """Oil volume gain [m^3] since T_ref = the gas volume lost to it: V_ref beta (T - T_ref) (seed 000 eq. 6, seed 001 eq. 4)."""
    return V_oil_ref_m3 * beta_per_K * (T_K - T_ref_K)


# --- gas-oil emulsion (seed 001 eq. 8-11) ----------------------------------------------------

def emulsion_gas_fraction(p_Pa, p0_Pa, gamma0, n, beta_h_Pa):
    """Gas volume fraction gamma = V_gas / V_oil [-] of the emulsion at pressure p (seed 001 eq. 8-9).

    gamma = (p0/p)^(1/n) gamma0 / (1 - (p - p0)/beta_h): entrapped gas polytropic (exponent n),
    oil linearly compressible (bulk modulus beta_h [Pa]); gamma0 at the reference pressure p0 [Pa].
    """
    gas = gamma0 * sym.exp(sym.log(p0_Pa / p_Pa) / n)
    oil = 1.0 - (p_Pa - p0_Pa) / beta_h_Pa
    return gas / oil


def emulsion_density(p_Pa, p0_Pa, rho_h_kg_m3, beta_h_Pa, gamma):
    """Emulsion density [kg/m^3]: rho = rho_h / ((1 - (p - p0)/beta_h) (1 + gamma)) (seed 001 eq. 10).

    Gas mass neglected; rho_h the oil density at p0 (and the temperature, `oil_density`);
    gamma the gas fraction at p (`emulsion_gas_fraction`).
    """
    return rho_h_kg_m3 / ((1.0 - (p_Pa - p0_Pa) / beta_h_Pa) * (1.0 + gamma))


def emulsion_bulk_modulus(p_Pa, gamma, n, beta_h_Pa):
    """Effective bulk modulus [Pa] of the emulsion: beta = n (1 + gamma) p beta_h / (n p + gamma beta_h) (seed 001 eq. 11).

    Gas and oil compliances in series: -> beta_h as gamma -> 0, -> n p as gamma -> infinity.
    """
    return n * (1.0 + gamma) * p_Pa * beta_h_Pa / (n * p_Pa + gamma * beta_h_Pa)
