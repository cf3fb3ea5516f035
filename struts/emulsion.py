"""The free gas of the integrated strut's emulsion as a state: entrainment, release and dissolution.

seed 001 identifies the emulsion's gas fraction gamma_0 (its eq. 9, the free gas per oil volume at the charge
pressure) per test and finds it doubling from 0.5 to 8 Hz at 50 degC (§4.2, §5.2, Fig. 10a), attributing it to
"the faster oscillation of [the] gas-oil interface ... and the more frequent fluid flow between the two chambers".
Here gamma_0 is a state with three sources and one sink (rates in 1/s, every coefficient an argument):

  release     eta L(T) (q dp)^+ / (p_ref N): the oil, saturated at the gas pocket's pressure p_c (Henry's law,
              dissolved gas volume at p_c per oil volume = Ostwald coefficient L), passes the valves into the
              rod chamber at p_c - dp in compression; the excess L dp / p_ref per unit volume comes out of
              solution (share eta). Zero in rebound, where the flow enters the pocket's chamber from above p_c.
  interface   k_i (nu_ref/nu)^m |a| / g: entrainment at the agitated gas-oil interface, growing with its
              acceleration a (Faraday-type agitation; at the paper's fixed 0.1 m/s peak velocity |a| grows with
              frequency) and easier in a thinner oil (seed 001 §5.2).
  dissolution -gamma_0 L(T) / (L_ref tau_d): bubbles leave the emulsion (dissolving, or rising into the pocket)
              with time constant tau_d; the dissolving part is proportional to solubility (Epstein and
              Plesset 1950, J. Chem. Phys. 18, 1505: dR^2/dt proportional to D L).

The temperature dependence of L is van 't Hoff's: L(T) = L_ref exp(dH/R (1/T_ref - 1/T)). The steady state at a
periodic excitation is gamma_0 = tau_d <sources> L_ref / L over a cycle; it is reached over several tau_d.
The gas that moves between the pocket and the emulsion is not taken off the pocket's mass (at most about 1 %
of it for this strut, the same approximation as the identified model's varying gamma_0).
"""
from __future__ import annotations

from hpsim import symbolic as sym

__all__ = [
    "GAS_CONSTANT_J_PER_MOL_K",
    "STANDARD_GRAVITY_M_S2",
    "solubility_ratio",
    "ostwald_coefficient",
    "release_rate",
    "interface_entrainment_rate",
    "dissolution_rate",
    "interface_acceleration",
    "interface_lag_rate",
]

GAS_CONSTANT_J_PER_MOL_K = 8.314462618   # CODATA 2018
STANDARD_GRAVITY_M_S2 = 9.80665          # ISO 80000-3


def solubility_ratio(T_K, T_ref_K, solution_enthalpy_J_per_mol):
    """L(T)/L(T_ref) [-]: van 't Hoff's temperature dependence of Henry's law, exp(dH/R (1/T_ref - 1/T)).

    (Sander 2015, Atmos. Chem. Phys. 15, 4399, eq. 19); dH > 0 [J/mol]: more soluble when warmer (nitrogen in oils).
    """
    return sym.exp(solution_enthalpy_J_per_mol / GAS_CONSTANT_J_PER_MOL_K * (1.0 / T_ref_K - 1.0 / T_K))


def ostwald_coefficient(T_K, L_ref, T_ref_K, solution_enthalpy_J_per_mol):
    """Ostwald coefficient L [-] (dissolved gas volume at its partial pressure per liquid volume) at T [K]:
    L_ref `solubility_ratio`."""
    return L_ref * solubility_ratio(T_K, T_ref_K, solution_enthalpy_J_per_mol)


def release_rate(q_m3_s, dp_Pa, L, efficiency, p_ref_Pa, emulsion_volume_m3, dp_smoothing_Pa):
    """d gamma_0/dt [1/s] of gas set free by the valve pressure drop (module docstring, "release").

    q [m^3/s] valve flow from the piston chamber to the rod chamber, dp = p_c - p_r [Pa] (q dp >= 0), L the
    Ostwald coefficient, p_ref [Pa] the pressure gamma_0 is referred to, N [m^3] the emulsion volume; the
    compression-only switch is a smooth step of width dp_smoothing [Pa].
    """
    compression = 0.5 * (1.0 + sym.smooth_sign(dp_Pa, dp_smoothing_Pa))
    return efficiency * L * compression * q_m3_s * dp_Pa / (p_ref_Pa * emulsion_volume_m3)


def interface_entrainment_rate(a_m_s2, nu_m2_s, nu_ref_m2_s, coefficient_per_s, viscosity_exponent, a_smoothing):
    """d gamma_0/dt [1/s] of gas entrained at the agitated interface: k_i (nu_ref/nu)^m |a|/g (module docstring).

    a [m/s^2] the interface's acceleration (`interface_acceleration`), |a| smoothed with width a_smoothing
    [m/s^2] (zero at rest), nu [m^2/s] the oil's viscosity.
    """
    viscous = sym.exp(viscosity_exponent * sym.log(nu_ref_m2_s / nu_m2_s))
    return coefficient_per_s * viscous * sym.smooth_abs(a_m_s2, a_smoothing) / STANDARD_GRAVITY_M_S2


def dissolution_rate(gamma0, solubility_ratio_, tau_s):
    """d gamma_0/dt [1/s] of free gas leaving the emulsion: -gamma_0 (L/L_ref)/tau_d (module docstring); the
    solubility ratio L/L_ref from `solubility_ratio`, tau_d [s] at the reference temperature."""
    return -gamma0 * solubility_ratio_ / tau_s


def interface_lag_rate(v_lag_m_s, v_m_s, tau_s):
    """d v_lag/dt [m/s^2] = (v - v_lag)/tau: the interface follows the strut's deflection rate with a lag tau [s]."""
    return (v_m_s - v_lag_m_s) / tau_s


def interface_acceleration(v_lag_m_s, v_m_s, tau_s):
    """a [m/s^2] = (v - v_lag)/tau: the acceleration the interface feels (the lag's rate; d v/dt for omega tau << 1)."""
    return (v_m_s - v_lag_m_s) / tau_s
