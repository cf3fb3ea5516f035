"""Identification of seed 001's internal parameters from rig loops, as the paper fitted its measurements.

Seed 001 §4.2 and §5.2 fit its parametric model (eq. 1-12) to each test (body temperature, sinusoid of one
frequency at 0.1 m/s peak velocity) and report the internal parameters of its Figs. 10-11. `identify_loop`
does the same to one loop of `struts.rig.cycle_test`, in three steps that each use one of the model's own
relations on the loop's signals (deflection x, deflection rate v, pressures p_c and p_r, seal friction f =
F - p_c A_c + p_r (A_c - A_r), seed 001 eq. 1, which is how the paper obtained its friction):

1. gas fraction gamma_0 (eq. 4, 8-10): the emulsion's mass is conserved, so with the polytropic gas volume
   V_g(p_c) (eq. 4) and the chamber volumes of eq. 5-7 the residual
   (V_c(x) - V_g(p_c)) / nu(p_c) + V_r(x) / nu(p_r) - N is zero at every sample; gamma_0 minimises its squares;
2. discharge coefficients C_b, C_v (eq. 12): the flow into the rod chamber q = (rho_r/rho_m)(A_a v + V_r kappa_r
   dp_r/dt) (eq. 6) against eq. 12 at the loop's dp, least squares over the loop;
3. friction (eq. 2-3): Coulomb and peak levels, Stribeck coefficients and transition velocities per stroke, least
   squares of `struts.friction.seal_friction` against f.

The model identified is the paper's: polytropic gas, the eq. 2-3 friction, constant internal parameters
(`PAPER_MODEL`, the overrides that turn a strut file into it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from . import friction as fr
from . import valves
from .model import make_strut
from .params import StrutParams

# the overrides that make a strut file seed 001's identified model (eq. 1-12 with constant internal parameters)
PAPER_MODEL = {"internals": "identified", "gas": {"process": "polytropic"}, "friction": {"model": "stribeck"}}

FRICTION_NAMES = ("coulomb_compression", "coulomb_rebound", "peak_compression", "peak_rebound",
                  "stribeck_coefficient_compression", "stribeck_coefficient_rebound",
                  "transition_velocity_compression", "transition_velocity_rebound")
IDENTIFIED_NAMES = ("gas_fraction", "bleed_discharge_coefficient", "check_discharge_coefficient") + FRICTION_NAMES


@dataclass
class Loop:
    """One rig loop's signals, uniformly sampled over a period (end point included)."""

    T_K: float
    frequency_Hz: float
    mean_m: float
    t_s: np.ndarray = field(repr=False)
    x_m: np.ndarray = field(repr=False)
    v_m_per_s: np.ndarray = field(repr=False)
    p_c_Pa: np.ndarray = field(repr=False)
    p_r_Pa: np.ndarray = field(repr=False)
    friction_N: np.ndarray = field(repr=False)

    @classmethod
    def from_cycle(cls, result, T_K: float) -> "Loop":
        """The loop of a `struts.rig.CycleResult` of an integrated strut."""
        return cls(T_K=T_K, frequency_Hz=result.frequency_Hz, mean_m=result.mean_m, t_s=result.t_s,
                   x_m=result.x_m, v_m_per_s=result.v_m_per_s, p_c_Pa=np.asarray(result.gas_pressure_Pa),
                   p_r_Pa=np.asarray(result.rod_chamber_pressure_Pa),
                   friction_N=np.asarray(result.components_N["friction"]))


def paper_model(params: StrutParams) -> StrutParams:
    """The strut file as seed 001's identified model (`PAPER_MODEL`)."""
    return params.with_overrides(PAPER_MODEL)


def _mass_residual(strut, loop: Loop, gamma0: float) -> np.ndarray:
    """Emulsion-mass residual [m^3 at p0] of step 1 (module docstring) at each sample."""
    P, T = strut.p, loop.T_K
    m_gas = strut.charge_gas_mass
    p_ext, V_ext = strut._polytropic_reference(T, m_gas, 0.0)
    n = P.gas.polytropic_exponent
    V_g = V_ext * (p_ext / loop.p_c_Pa) ** (1.0 / n)
    g = P.geometry
    V_c = g.piston_chamber_oil_volume + g.gas_volume_extended - strut.piston_area * loop.x_m \
        - strut._thermal_gas_volume_loss(T, 0.0)
    V_r = g.rod_chamber_volume + strut.annulus_area * loop.x_m
    nu_c = strut.emulsion(loop.p_c_Pa, T, gamma0)["nu"]
    nu_r = strut.emulsion(loop.p_r_Pa, T, gamma0)["nu"]
    return (V_c - V_g) / nu_c + V_r / nu_r - strut.emulsion_volume_charged


def identify_gas_fraction(strut, loop: Loop) -> float:
    """gamma_0 [-] minimising the emulsion-mass residual over the loop (step 1)."""
    res = minimize_scalar(lambda g: float(np.sum(_mass_residual(strut, loop, g) ** 2)),
                          bounds=(0.0, 0.2), method="bounded", options={"xatol": 1e-9})
    return float(res.x)


def _rod_chamber_flow(strut, loop: Loop, gamma0: float):
    """(q [m^3/s] c -> r, rho_m [kg/m^3]) from the rod chamber's continuity (seed 001 eq. 6) over the loop."""
    T = loop.T_K
    em_c = strut.emulsion(loop.p_c_Pa, T, gamma0)
    em_r = strut.emulsion(loop.p_r_Pa, T, gamma0)
    period = 1.0 / loop.frequency_Hz
    dt = period / (len(loop.t_s) - 1)
    # periodic central difference (the samples span one period, the end point repeating the start)
    p = loop.p_r_Pa[:-1]
    dp_r = np.append((np.roll(p, -1) - np.roll(p, 1)) / (2.0 * dt), 0.0)
    dp_r[-1] = dp_r[0]
    V_r = strut.p.geometry.rod_chamber_volume + strut.annulus_area * loop.x_m
    rho_m = 0.5 * (em_c["rho"] + em_r["rho"])
    q = em_r["rho"] / rho_m * (strut.annulus_area * loop.v_m_per_s + V_r * em_r["kappa"] * dp_r)
    return q, rho_m


def identify_discharge_coefficients(strut, loop: Loop, gamma0: float) -> tuple[float, float]:
    """(C_b, C_v) [-]: eq. 12 against the rod chamber's flow over the loop (step 2)."""
    q, rho_m = _rod_chamber_flow(strut, loop, gamma0)
    dp = loop.p_c_Pa - loop.p_r_Pa
    scale = float(np.max(np.abs(q)))

    def residual(c):
        kw = strut._valve_kwargs(rho_m, loop.T_K, {"bleed_discharge_coefficient": c[0],
                                                   "check_discharge_coefficient": c[1]})
        return (valves.valve_flow(dp, **kw) - q) / scale

    sol = least_squares(residual, x0=[0.65, 0.6], bounds=([0.05, 0.05], [1.0, 1.0]), xtol=1e-12, ftol=1e-12)
    return float(sol.x[0]), float(sol.x[1])


def _friction_model(strut, loop: Loop, values) -> np.ndarray:
    i = dict(zip(FRICTION_NAMES, values))
    f = strut.p.friction
    return fr.seal_friction(
        loop.v_m_per_s, loop.x_m - loop.mean_m, 0.0, F0_comp=i["coulomb_compression"], F0_reb=i["coulomb_rebound"],
        f_p=0.0, K_brk=i["peak_compression"] / i["coulomb_compression"],
        K_brk_reb=i["peak_rebound"] / i["coulomb_rebound"],
        v_s=1.0 / i["stribeck_coefficient_compression"], v_s_reb=1.0 / i["stribeck_coefficient_rebound"],
        f_v=strut.friction_viscous(loop.T_K), eps=f.smoothing_velocity,
        v_h_comp=i["transition_velocity_compression"], v_h_reb=i["transition_velocity_rebound"],
        eps_x=f.hysteresis_smoothing_displacement)


def identify_friction(strut, loop: Loop) -> dict:
    """Seed 001 eq. 2-3 per stroke fitted to the loop's friction (step 3): `FRICTION_NAMES` -> value (SI)."""
    fN = loop.friction_N
    v = loop.v_m_per_s
    comp, reb = v > 0, v < 0
    F_c0 = float(np.median(np.abs(fN[comp]))) if comp.any() else 100.0
    F_r0 = float(np.median(np.abs(fN[reb]))) if reb.any() else 100.0
    x0 = np.array([F_c0, F_r0, 1.3 * F_c0, 1.3 * F_r0, 40.0, 40.0, 0.012, 0.012])
    lower = np.array([1.0, 1.0, 1.0, 1.0, 0.1, 0.1, 1e-4, 1e-4])
    upper = np.array([1e5, 1e5, 1e5, 1e5, 1e4, 1e4, 0.5, 0.5])
    scale = max(float(np.max(np.abs(fN))), 1.0)

    def residual(p):
        # peaks are kept above the Coulomb levels by parametrising their excess
        values = p.copy()
        values[2] = p[0] + p[2]
        values[3] = p[1] + p[3]
        return (_friction_model(strut, loop, values) - fN) / scale

    start = x0.copy()
    start[2], start[3] = 0.3 * F_c0, 0.3 * F_r0
    sol = least_squares(residual, x0=start, bounds=(lower * 0.0 + [1, 1, 0, 0, 0.1, 0.1, 1e-4, 1e-4], upper),
                        x_scale=np.abs(start) + 1e-3, xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=4000)
    values = sol.x.copy()
    values[2] = sol.x[0] + sol.x[2]
    values[3] = sol.x[1] + sol.x[3]
    return dict(zip(FRICTION_NAMES, (float(v) for v in values)))


def identify_loop(params: StrutParams, loop: Loop) -> dict:
    """Seed 001's internal parameters (`IDENTIFIED_NAMES`, SI) of one loop (module docstring).

    params: the strut file (its geometry, charge, oil and Table 1 values); the identification uses it as the
    paper's model (`paper_model`)."""
    strut = make_strut(paper_model(params))
    gamma0 = identify_gas_fraction(strut, loop)
    cb, cv = identify_discharge_coefficients(strut, loop, gamma0)
    out = {"gas_fraction": gamma0, "bleed_discharge_coefficient": cb, "check_discharge_coefficient": cv}
    out.update(identify_friction(strut, loop))
    return out
