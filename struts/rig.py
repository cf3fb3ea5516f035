"""The strut test rig: what a lab does with an Instron or a shaker.

- `characteristic`: quasi-static force-deflection curve F(x) at a fill pressure and temperature.
- `static_point`: static deflection and local stiffness at a given load.
- `cycle_test`: displacement-driven sinusoid from the gas state at rest; force-displacement
  and force-velocity loops, energy per cycle E = closed integral of F dx (seed 000 eq. 7),
  split by mechanism (valve, friction, gas heat exchange, end stops).

The strut is held at the rig temperature (body = wall temperature constant); the gas
exchanges heat with it through the thermal time constant.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import casadi as ca
import numpy as np
from scipy.optimize import brentq

from hpsim.errors import UserInputError

from . import emulsion
from .maps import validity_warnings
from .model import MECHANISMS, StrutInputs, make_strut
from .params import StrutParams

# Ranges a rig can do: the checks give clear messages rather than solver failures.
_MAX_FREQUENCY_HZ = 50.0
# Work size: a cycle test stores 400 samples per cycle and reaches its periodic loop within a few
# cycles; 1000 cycles (400 000 samples) per test and 10 000 cycles per command bound the memory
# (tens of MB) and the time (minutes) a valid-looking command line can ask for.
MAX_CYCLES = 1000
MAX_CYCLES_PER_COMMAND = 10_000


def check_cycle_work(n_tests: int, cycles) -> None:
    """Refuse more cycles than MAX_CYCLES per test or MAX_CYCLES_PER_COMMAND in all, before any work."""
    if int(cycles) > MAX_CYCLES:
        raise UserInputError(f"--cycles: {cycles} cycles per test, at most {MAX_CYCLES} "
                             "(the loop is periodic after a few cycles)")
    if n_tests * int(cycles) > MAX_CYCLES_PER_COMMAND:
        raise UserInputError(f"--cycles: {n_tests} tests x {cycles} cycles = {n_tests * int(cycles)} cycles, "
                             f"at most {MAX_CYCLES_PER_COMMAND} in one command")


def _gas_mass(strut, p0_Pa):
    p = strut.p
    if p0_Pa is None:
        p0_Pa = p.charge.pressure
    # the fill pressure is stated at full extension at the charge temperature (seed 000 §2)
    return strut.gas_mass_for(p0_Pa, p.charge.temperature)


def characteristic(params: StrutParams, *, p0_Pa=None, T_K=None, process=None, n_points=200) -> dict:
    """Quasi-static F(x) over the stroke: dict with x_m, force_N, gas_pressure_Pa."""
    strut = make_strut(params)
    T = params.charge.temperature if T_K is None else T_K
    m_gas = _gas_mass(strut, p0_Pa)
    x = np.linspace(0.0, params.geometry.stroke, n_points)
    F = np.asarray(strut.static_gas_force(x, T, m_gas, process=process), dtype=float)
    return {"x_m": x, "force_N": F, "gas_pressure_Pa": F / params.geometry.gas_area,
            "temperature_K": T, "p0_Pa": params.charge.pressure if p0_Pa is None else p0_Pa}


def static_point(params: StrutParams, load_N: float, *, p0_Pa=None, T_K=None, process=None) -> dict:
    """Static deflection [m] and local stiffness dF/dx [N/m] at `load_N`."""
    strut = make_strut(params)
    T = params.charge.temperature if T_K is None else T_K
    m_gas = _gas_mass(strut, p0_Pa)
    stroke = params.geometry.stroke

    def f(x):
        return float(strut.static_gas_force(x, T, m_gas, process=process)) - load_N

    F_lo, F_hi = f(0.0) + load_N, f(stroke) + load_N
    if not (F_lo <= load_N <= F_hi):
        raise UserInputError(
            f"--load: {load_N / 1e3:.4g} kN is outside what the strut carries at this fill and temperature "
            f"({F_lo / 1e3:.4g} kN at full extension to {F_hi / 1e3:.4g} kN at full compression)")
    x = brentq(f, 0.0, stroke, xtol=1e-12)
    h = 1e-6
    k = (f(min(x + h, stroke)) - f(max(x - h, 0.0))) / (min(x + h, stroke) - max(x - h, 0.0))
    V = float(strut.gas_volume(x, T))
    return {
        "static_deflection_m": x,
        "stiffness_N_per_m": k,
        "gas_pressure_Pa": load_N / params.geometry.gas_area,
        "gas_temperature_K": T,
        "gas_volume_m3": V,
        "gas_mass_kg": m_gas,
    }


@dataclass
class CycleResult:
    amplitude_m: float
    frequency_Hz: float
    mean_m: float
    cycles: int
    t_s: np.ndarray = field(repr=False)
    x_m: np.ndarray = field(repr=False)
    v_m_per_s: np.ndarray = field(repr=False)
    force_N: np.ndarray = field(repr=False)
    components_N: dict = field(repr=False)
    gas_pressure_Pa: np.ndarray = field(repr=False)
    gas_temperature_K: np.ndarray = field(repr=False)
    energy_per_cycle_J: float = 0.0
    energy_by_mechanism_J: dict = field(default_factory=dict)
    work_in_J: float = 0.0
    heat_out_J: float = 0.0
    peak_force_compression_N: float = 0.0
    peak_force_rebound_N: float = 0.0
    # first harmonic of the last cycle's force: F ~ F_mean + k_eq (x - mean) + c_eq v (c_eq = E / (pi omega A^2))
    equivalent_stiffness_N_per_m: float = 0.0
    equivalent_damping_N_s_per_m: float = 0.0
    # the seed 001 §5.2 internal parameters at the run's body temperature and frequency (struts.maps), the strut's
    # own excitation measure over the last cycle (None without frequency maps) and the maps' validity warnings
    internal: dict = field(default_factory=dict)
    excitation_frequency_Hz: float | None = None
    warnings: list = field(default_factory=list)
    # the strut's internal states over the last cycle (name -> samples), e.g. the emulsion's gas_fraction
    states: dict = field(default_factory=dict, repr=False)
    # the rod-side chamber pressure over the last cycle (integrated struts; the gas pressure for the others)
    rod_chamber_pressure_Pa: np.ndarray | None = field(default=None, repr=False)

    def summary(self) -> dict:
        return {
            "amplitude_m": self.amplitude_m,
            "frequency_Hz": self.frequency_Hz,
            "mean_m": self.mean_m,
            "energy_per_cycle_J": self.energy_per_cycle_J,
            "energy_by_mechanism_J": dict(self.energy_by_mechanism_J),
            "peak_force_compression_N": self.peak_force_compression_N,
            "peak_force_rebound_N": self.peak_force_rebound_N,
            "equivalent_stiffness_N_per_m": self.equivalent_stiffness_N_per_m,
            "equivalent_damping_N_s_per_m": self.equivalent_damping_N_s_per_m,
            "internal": dict(self.internal),
            "excitation_frequency_Hz": self.excitation_frequency_Hz,
        }


def equivalent_stiffness_damping(t_s, force_N, amplitude_m, frequency_Hz) -> tuple[float, float]:
    """(k_eq [N/m], c_eq [N s/m]): the first harmonic of one period of F(t) under x = mean + A sin(omega t):
    k_eq = (2/T) int F sin / A, c_eq = (2/T) int F cos / (A omega) (so c_eq = loop energy / (pi omega A^2)).
    t_s, force_N: one period sampled uniformly, the end point included."""
    w = 2.0 * math.pi * frequency_Hz
    t, F = np.asarray(t_s)[:-1], np.asarray(force_N)[:-1]
    return (float(2.0 * np.mean(F * np.sin(w * t)) / amplitude_m),
            float(2.0 * np.mean(F * np.cos(w * t)) / (amplitude_m * w)))


def check_cycle_arguments(params: StrutParams, amplitude, frequency, mean, cycles):
    stroke = params.geometry.stroke
    if not amplitude > 0:
        raise UserInputError(f"--amplitude: must be > 0 m, got {amplitude} m")
    if not 0 < frequency <= _MAX_FREQUENCY_HZ:
        raise UserInputError(f"--frequency: must be in (0, {_MAX_FREQUENCY_HZ}] Hz, got {frequency} Hz")
    if mean - amplitude < -1e-12 or mean + amplitude > stroke + 1e-12:
        raise UserInputError(
            f"--mean/--amplitude: mean ± amplitude = [{(mean - amplitude) * 1e3:.4g}, {(mean + amplitude) * 1e3:.4g}] mm "
            f"leaves the stroke [0, {stroke * 1e3:.4g}] mm")
    if int(cycles) < 1:
        raise UserInputError(f"--cycles: must be >= 1, got {cycles}")
    check_cycle_work(1, cycles)


def cycle_test(params: StrutParams, amplitude_m: float, frequency_Hz: float, mean_m: float, *,
               cycles: int = 3, T_K: float | None = None, p0_Pa: float | None = None,
               samples_per_cycle: int = 400, rtol: float = 1e-9,
               gas_fraction_start: float | None = None) -> CycleResult:
    """Displacement-driven sinusoid x(t) = mean + A sin(2 pi f t), starting from rest.

    The gas starts at the rig temperature at the mean position. The DAE (gas temperature
    state, valve pressure drop as algebraic variable) and the energy quadratures are
    integrated with IDAS; the last cycle gives the loop and the energy per cycle.
    An emulsion with a free-gas state (internals: physical) starts at gas_fraction_start, by default at its
    steady state under this excitation (`steady_gas_fraction`: a rig test on a running strut, as in seed 001).
    """
    check_cycle_arguments(params, amplitude_m, frequency_Hz, mean_m, cycles)
    strut = make_strut(params)
    T = params.charge.temperature if T_K is None else T_K
    m_gas = _gas_mass(strut, p0_Pa)
    omega = 2.0 * math.pi * frequency_Hz
    period = 1.0 / frequency_Hz

    t = ca.SX.sym("t")
    x_t = mean_m + amplitude_m * ca.sin(omega * t)
    v_t = amplitude_m * omega * ca.cos(omega * t)
    names = strut.state_names
    xs = ca.SX.sym("xs", len(names))
    # quadratures: valve, friction, gas loop work, end stop, work in, heat from gas to wall
    energies = ca.SX.sym("E", len(MECHANISMS) + 2)
    dp_scale = 1e6
    algebraic = not strut.compressible
    z = ca.SX.sym("z", 1 if algebraic else 0)  # dp_valve / 1 MPa when the oil is incompressible
    inputs = StrutInputs(x=x_t, v=v_t, T_wall=T, m_gas=m_gas, x_mid=mean_m)
    eq = strut.equations(inputs, {n: xs[i] for i, n in enumerate(names)}, z * dp_scale if algebraic else None)
    rates = [eq["rates"][n] for n in names]
    # the gas's share of the loop is its own loop work -closed integral p dV (= heat to the wall
    # once the cycle is periodic); the end stops' share is their whole force times velocity
    powers = [eq["power_valve"], eq["power_friction"], eq["gas_work_rate"], eq["end_stop_force"] * v_t,
              eq["force"] * v_t, eq["heat_gas"]]
    dae = {"t": t, "x": ca.vertcat(xs, energies), "ode": ca.vertcat(*rates, *powers)}
    if algebraic:
        q_scale = params.geometry.valve_area * max(amplitude_m * omega, 1e-3)
        dae.update(z=z, alg=eq["residual"] / q_scale)
    n_out = int(cycles) * samples_per_cycle + 1
    grid = np.linspace(0.0, cycles * period, n_out)
    opts = {"reltol": rtol, "abstol": 1e-10, "max_num_steps": 500000}
    if algebraic:
        opts["calc_ic"] = True
    integ = ca.integrator("rig", "idas" if algebraic else "cvodes", dae, 0.0, grid[1:], opts)
    start = strut.initial_states(T, x=mean_m, m_gas=m_gas, excitation_Hz_m=(frequency_Hz, amplitude_m))
    if "gas_fraction" in start:
        start["gas_fraction"] = (steady_gas_fraction(params, amplitude_m, frequency_Hz, mean_m, T_K=T, p0_Pa=p0_Pa)
                                 if gas_fraction_start is None else gas_fraction_start)
    x0 = [float(v) for v in start.values()] + [0.0] * (len(MECHANISMS) + 2)
    args = {"x0": x0}
    z0 = np.zeros((0, 1))
    if algebraic:
        z0 = np.array([[float(strut.valve_pressure_drop(amplitude_m * omega, T, newton_iterations=40)) / dp_scale]])
        args["z0"] = z0
    try:
        sol = integ(**args)
    except RuntimeError as exc:
        raise RuntimeError(f"rig integration failed at A={amplitude_m} m, f={frequency_Hz} Hz: {exc}") from None
    X = np.hstack([np.asarray(x0, float).reshape(-1, 1), np.asarray(sol["xf"])])
    Z = np.hstack([z0, np.asarray(sol["zf"]).reshape(z0.shape[0], -1)]) if algebraic else np.zeros((0, n_out))
    outs = ca.Function("outs", [t, xs, z], [eq["force"], eq["gas_force"], eq["valve_force"],
                                            eq["friction_force"], eq["end_stop_force"],
                                            eq["gas_pressure"], eq["gas_temperature"],
                                            eq.get("rod_chamber_pressure", eq["gas_pressure"])])
    nx = len(names)
    vals = outs.map(n_out)(grid, X[:nx, :] if nx else np.zeros((0, n_out)), Z)
    F, Fg, Fv, Ff, Fs, pg, Tg, pr = (np.asarray(v, float).ravel() for v in vals)
    E = X[nx:, :]
    last = slice(n_out - samples_per_cycle - 1, n_out)
    dE = E[:, -1] - E[:, n_out - samples_per_cycle - 1]
    by_mech = {m: float(dE[i]) for i, m in enumerate(MECHANISMS)}
    x_arr = mean_m + amplitude_m * np.sin(omega * grid)
    v_arr = amplitude_m * omega * np.cos(omega * grid)
    k_eq, c_eq = equivalent_stiffness_damping(grid[last], F[last], amplitude_m, frequency_Hz)
    f_eq = None
    if getattr(strut, "uses_excitation", False):
        f_eq = float(np.mean(np.asarray(strut.excitation_frequency(
            {n: X[i, last] for i, n in enumerate(names)}), float)))
    internal = {k: float(v) for k, v in strut.internal_parameters(T, frequency_Hz).items()}
    if "gas_fraction" in names:
        internal["gas_fraction"] = float(np.mean(X[names.index("gas_fraction"), last]))
    res = CycleResult(
        amplitude_m=amplitude_m, frequency_Hz=frequency_Hz, mean_m=mean_m, cycles=int(cycles),
        t_s=grid[last], x_m=x_arr[last], v_m_per_s=v_arr[last], force_N=F[last],
        components_N={"gas": Fg[last], "valve": Fv[last], "friction": Ff[last], "end_stop": Fs[last]},
        gas_pressure_Pa=pg[last], gas_temperature_K=Tg[last],
        energy_per_cycle_J=float(dE[len(MECHANISMS)]),
        energy_by_mechanism_J=by_mech,
        work_in_J=float(dE[len(MECHANISMS)]),
        # heat leaving the strut's fluids in the last cycle: valve + friction + gas to wall
        heat_out_J=float(dE[0] + dE[1] + dE[len(MECHANISMS) + 1] + dE[3]),
        # peaks per stroke direction: the largest force while compressing (v > 0) and the
        # smallest while extending (v < 0), where the resisting forces subtract from the gas force
        peak_force_compression_N=float(np.max(F[last][v_arr[last] > 0])),
        peak_force_rebound_N=float(np.min(F[last][v_arr[last] < 0])),
        equivalent_stiffness_N_per_m=k_eq, equivalent_damping_N_s_per_m=c_eq,
        internal=internal, excitation_frequency_Hz=f_eq,
        warnings=validity_warnings(getattr(strut, "internal_maps", params.internal_maps), T, frequency_Hz,
                                   f"strut {params.name}"),
        states={n: X[i, last].copy() for i, n in enumerate(names)},
        rod_chamber_pressure_Pa=pr[last],
    )
    return res


def steady_gas_fraction(params: StrutParams, amplitude_m: float, frequency_Hz: float, mean_m: float, *,
                        T_K: float | None = None, p0_Pa: float | None = None) -> float:
    """The emulsion's free-gas fraction [-] at its periodic steady state under a rig sinusoid (internals: physical).

    Its rate is the sources (release, interface entrainment) minus gamma_0 L / (L_ref tau_d) (`struts.emulsion`), and
    the sources barely depend on gamma_0, so the steady state is tau_d (L_ref/L) times their mean over a cycle: one
    cycle with the dissolution off measures that mean (after one cycle to settle the chambers and the seal).
    """
    e = params.emulsion
    held = params.with_overrides({"emulsion": {"dissolution_time": 1e12}})
    r = cycle_test(held, amplitude_m, frequency_Hz, mean_m, cycles=2, T_K=T_K, p0_Pa=p0_Pa,
                   gas_fraction_start=e.initial_gas_fraction)
    g = r.states["gas_fraction"]
    sources = (g[-1] - g[0]) * frequency_Hz
    T = params.charge.temperature if T_K is None else T_K
    ratio = emulsion.solubility_ratio(T, e.ostwald_reference_temperature, e.solution_enthalpy)
    return float(e.dissolution_time * sources / ratio)
