"""Identification of seed 001's internal parameters from rig loops, as the paper fitted its measurements.

Seed 001 §4.2 and §5.2 fit its parametric model (eq. 1-12) to each test (body temperature, sinusoid of one
frequency at 0.1 m/s peak velocity) and report the internal parameters of its Figs. 10-11. `identify_loop`
does the same to one loop of `struts.rig.cycle_test`, in three steps that each use one of the model's own
relations on the loop's signals (deflection x, deflection rate v, pressures p_c and p_r, seal friction f =
F - p_c A_c + p_r (A_c - A_r), seed 001 eq. 1, which is how the paper obtained its friction):

1.-2. gas fraction gamma_0 and discharge coefficients C_b, C_v together (eq. 6, 8-12): the flow into the rod
   chamber, q = (rho_r/rho_m)(A_a v + V_r kappa_r dp_r/dt) by its continuity (eq. 6), against eq. 12 at the
   loop's dp, least squares over the loop. The gas fraction gamma_0 acts through the compressibility kappa_r (eq. 11), i.e. through
   the pressure-difference hysteresis, as the paper identified it from the hysteresis at higher frequency. The gas
   law is not used, so a strut whose gas does not follow eq. 4 is identified all the same. The loops must come from
   chambers with their pressures as states (eq. 5-7 as written: `--chambers compressible`);
3. friction (eq. 2-3): Coulomb and peak levels, Stribeck coefficients and transition velocities per stroke, least
   squares of `struts.friction.seal_friction` against f.

The model identified is the paper's: polytropic gas, the eq. 2-3 friction, constant internal parameters
(`PAPER_MODEL`, the overrides that turn a strut file into it).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from . import friction as fr
from . import valves
from .model import make_strut
from .params import StrutParams

# the overrides that make a strut file seed 001's identified model (eq. 1-12 with constant internal parameters)
PAPER_MODEL = {"internals": "identified", "gas.process": "polytropic", "friction.model": "stribeck"}

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


def paper_model_at(params: StrutParams, T_K: float, f_Hz: float, values: dict | None = None) -> StrutParams:
    """Seed 001's model of one test: the internal parameters held constant (a one-point map) at `values`
    (`IDENTIFIED_NAMES` -> SI; default: the file's maps or constants at T_K [K] and f_Hz [Hz]), as the paper
    simulated each test with the parameters it identified for it."""
    base = paper_model(params)
    if values is None:
        values = make_strut(base).internal_parameters(T_K, f_Hz)
    one_point = {n: {"values": [[float(values[n])]], "sources": [["identified"]],
                     "legend": {"identified": "one test's identified value"}} for n in IDENTIFIED_NAMES}
    return base.with_overrides({"internal_maps": None}).with_overrides(
        {"internal_maps": {"temperatures": [float(T_K)], "frequencies": [float(f_Hz)], **one_point}})


def _rod_chamber_balance(strut, loop: Loop, values) -> np.ndarray:
    """Relative misfit of the rod chamber's continuity (seed 001 eq. 6, 12) over the loop at (gamma_0, C_b, C_v):
    eq. 12's flow at the loop's dp against (rho_r/rho_m)(A_a v + V_r kappa_r dp_r/dt)."""
    gamma0, cb, cv = values
    T = loop.T_K
    em_c = strut.emulsion(loop.p_c_Pa, T, gamma0)
    em_r = strut.emulsion(loop.p_r_Pa, T, gamma0)
    period = 1.0 / loop.frequency_Hz
    dt = period / (len(loop.t_s) - 1)
    # periodic central difference (the samples span one period, the end point repeating the start)
    p = loop.p_r_Pa[:-1]
    dp_r = (np.roll(p, -1) - np.roll(p, 1)) / (2.0 * dt)
    dp_r = np.append(dp_r, dp_r[0])
    V_r = strut.p.geometry.rod_chamber_volume + strut.annulus_area * loop.x_m
    rho_m = 0.5 * (em_c["rho"] + em_r["rho"])
    q = em_r["rho"] / rho_m * (strut.annulus_area * loop.v_m_per_s + V_r * em_r["kappa"] * dp_r)
    kw = strut.valve_arguments_for(rho_m, T, {"bleed_discharge_coefficient": cb, "check_discharge_coefficient": cv})
    return (valves.valve_flow(loop.p_c_Pa - loop.p_r_Pa, **kw) - q) / float(np.max(np.abs(q)))


def identify_emulsion_and_valves(strut, loop: Loop) -> tuple[float, float, float]:
    """(gamma_0, C_b, C_v) [-] fitted together to the rod chamber's continuity over the loop (steps 1-2 of the
    module docstring). gamma_0 acts through the emulsion's compressibility, C_b and C_v through eq. 12."""
    sol = least_squares(lambda c: _rod_chamber_balance(strut, loop, c), x0=[0.006, 0.65, 0.6],
                        bounds=([0.0, 0.05, 0.05], [0.5, 1.0, 1.0]), x_scale=[0.006, 0.65, 0.6],
                        xtol=1e-14, ftol=1e-14, gtol=1e-14)
    return float(sol.x[0]), float(sol.x[1]), float(sol.x[2])


# width of sgn(x - mean) in the fitted band: the loop is sampled, not integrated, so the reversal test can be sharp
# (the rig's band reads its reversal memory, which is +-1 wherever the band acts)
_REVERSAL_SHARPNESS_M = 1e-7


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
        eps_x=_REVERSAL_SHARPNESS_M)


def identify_friction(strut, loop: Loop) -> dict:
    """Seed 001 eq. 2-3 per stroke fitted to the loop's friction (step 3): `FRICTION_NAMES` -> value (SI).

    Least squares from several starts (Stribeck coefficients and transition velocities spanning the paper's
    ranges: the cost has local minima where a weak Stribeck term trades against the band), the best one kept.
    The peaks are parametrised by their excess over the Coulomb levels, so they stay above them."""
    fN = loop.friction_N
    v = loop.v_m_per_s
    F_c0 = float(np.median(np.abs(fN[v > 0]))) if np.any(v > 0) else 100.0
    F_r0 = float(np.median(np.abs(fN[v < 0]))) if np.any(v < 0) else 100.0
    scale = max(float(np.max(np.abs(fN))), 1.0)

    def values_of(p):
        values = p.copy()
        values[2] = p[0] + p[2]
        values[3] = p[1] + p[3]
        return values

    def residual(p):
        return (_friction_model(strut, loop, values_of(p)) - fN) / scale

    lower = [1.0, 1.0, 0.0, 0.0, 0.1, 0.1, 1e-4, 1e-4]
    upper = [1e5, 1e5, 1e5, 1e5, 1e4, 1e4, 0.5, 0.5]
    best = None
    for k0, vh0 in _FRICTION_STARTS:
        start = np.array([F_c0, F_r0, 0.3 * F_c0, 0.3 * F_r0, k0, k0, vh0, vh0])
        sol = least_squares(residual, x0=start, bounds=(lower, upper), x_scale=np.abs(start),
                            xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=4000)
        if best is None or sol.cost < best.cost:
            best = sol
    return dict(zip(FRICTION_NAMES, (float(x) for x in values_of(best.x))))


# starts of the friction fit: Stribeck coefficient [s/m] and transition velocity [m/s] (seed 001 Fig. 11c-d ranges)
_FRICTION_STARTS = tuple((k, vh) for k in (2.0, 20.0, 80.0) for vh in (0.008, 0.03))


def identify_loop(params: StrutParams, loop: Loop) -> dict:
    """Seed 001's internal parameters (`IDENTIFIED_NAMES`, SI) of one loop (module docstring).

    params: the strut file (its geometry, charge, oil and Table 1 values); the identification uses it as the
    paper's model (`paper_model`)."""
    strut = make_strut(paper_model(params))
    gamma0, cb, cv = identify_emulsion_and_valves(strut, loop)
    out = {"gas_fraction": gamma0, "bleed_discharge_coefficient": cb, "check_discharge_coefficient": cv}
    out.update(identify_friction(strut, loop))
    return out


def identify_rig(params: StrutParams, temperatures_K, frequencies_Hz, peak_velocity_m_s: float, mean_m: float, *,
                 cycles: int = 3, p0_Pa: float | None = None) -> list[dict]:
    """Seed 001's tests and identification: at each body temperature and frequency a sinusoid of the given peak
    velocity about mean_m on the rig (`struts.rig.cycle_test`, the strut as the file says), its last loop identified
    (`identify_loop`). Rows: temperature_K, frequency_Hz, amplitude_m, identified (`IDENTIFIED_NAMES` -> SI) and the
    strut's own mean free-gas fraction over the loop (state_gas_fraction; None without the emulsion state)."""
    from .rig import cycle_test

    rows = []
    for T in temperatures_K:
        for f in frequencies_Hz:
            A = peak_velocity_m_s / (2.0 * np.pi * f)
            r = cycle_test(params, A, f, mean_m, cycles=cycles, T_K=T, p0_Pa=p0_Pa)
            g = r.states.get("gas_fraction")
            rows.append({"temperature_K": float(T), "frequency_Hz": float(f), "amplitude_m": float(A),
                         "identified": identify_loop(params, Loop.from_cycle(r, T)),
                         "state_gas_fraction": None if g is None else float(np.mean(g))})
    return rows
