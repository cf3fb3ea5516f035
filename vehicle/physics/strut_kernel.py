"""One station's strut part of the equations as one function of its own inputs: the "strut kernel".

The stations of a vehicle are the same strut equations on different data. The ROS2 step computes this part of
every station with one code over lanes of stations (`vehicle.numerics.split_step`; docs/engines.md, "Lanes across
struts"), and the rest of the step (hull, tyres, wheels, energies, ride filters, the LU of W) around it.

The kernel of station i (`kernel`), per stage of the step:
  inputs   `input_names(strut)`: the strut's deflection x [m] and velocity v [m/s], the heat network's temperatures
           T_oil, T_wall, T_surface [K], the oil added V_oil [m^3] and its flow q_oil [m^3/s] (levelling), the
           valve's warm start dp_guess [Pa], the ambient temperature T_amb [K], the speed [m/s], then the strut's
           internal states;
  parameters the station's gas mass m_gas [kg] and the compensation's mid deflection x_mid [m]
           (`VehicleModel.station_run_parameters`), then the model's parameter vector p;
  outputs  `output_names(strut, jacobian)`: the valve pressure drop dp [Pa] (one warm-started Newton step, as
           `VehicleModel.eliminate_valves`), the strut force [N], the internal states' rates, the four
           dissipated powers [W], the heat network's node rates [K/s] and, with jacobian=True, the strut's
           stiffness [N/m] and damping [N s/m] for the stiff Jacobian (`VehicleModel.stiff_jacobian`).
The same functions compute the part inside `VehicleModel.equations` (`strut_part`), so the kernel is the model's
physics, not a copy of it.
"""
from __future__ import annotations

import casadi as ca

from struts.model import StrutInputs
from vehicle.physics import thermal

KERNEL_INPUTS = ("x", "v", "T_oil", "T_wall", "T_surface", "V_oil", "q_oil", "dp_guess", "T_amb", "speed")
# the station's run parameters (`VehicleModel.strut_inputs`): constant during a run, so they enter the kernel with
# its parameters (what depends on them and the parameters only is computed once per run, not at every step)
STATION_PARAMETERS = ("m_gas", "x_mid")
POWERS = ("power_valve", "power_friction", "heat_gas", "power_end_stop")
NODE_RATES = tuple(f"dT_{node}" for node in thermal.NODES)
STIFFNESS = ("ks", "cs")


def input_names(strut) -> tuple:
    """Names of the kernel's inputs for `strut` (module docstring)."""
    return KERNEL_INPUTS + tuple(strut.state_names)


def output_names(strut, jacobian: bool) -> tuple:
    """Names of the kernel's outputs for `strut`; jacobian: with its stiffness and damping."""
    return ("dp", "force", *strut.state_names, *POWERS, *NODE_RATES) + (STIFFNESS if jacobian else ())


def valve_drop(strut, sin: StrutInputs, internal: dict, dp_guess, iterations: int = 1):
    """The valve pressure drop [Pa] of an incompressible strut by `iterations` Newton steps from the warm start
    dp_guess on its flow balance (`strut.valve_pressure_drop`): what `VehicleModel.eliminate_valves` computes for
    each such station, and the kernel at each stage."""
    return strut.valve_pressure_drop(sin.v, sin.T_wall, dp_guess=dp_guess, newton_iterations=iterations, warm=True,
                                     u=sin, states=internal)


def strut_part(K, i: int, sin: StrutInputs, internal: dict, dp, T_oil, T_wall, T_surface, T_amb, speed) -> tuple:
    """(the strut's equations `strut.equations`, the node rates of its heat network) of station i: the struts
    library's gas law, valves, friction and end stops, then vehicle.physics.thermal's network fed by what they
    dissipate. K: the model's symbolic kinematics (`VehicleModel.sym`)."""
    P = K.params
    strut = K.struts[i]
    eq = strut.equations(sin, internal, dp)
    # oil properties at the oil temperature (the strut's own valve terms evaluate the same expressions: shared
    # in the compiled step); the Prandtl number of the natural-convection shape factor at the oil's reference
    # temperature (a run constant, thermal.churchill_chu_h)
    Pr_shape = thermal.oil_prandtl(P.heat, strut.oil_viscosity(strut.p.oil.reference_temperature),
                                   strut.p.oil.density)
    flows = thermal.network_flows(P.heat, thermal.station_environment(P.heat, P.axles[P.station_axle(i)].heat),
                                  T_oil, T_wall, T_surface, T_amb, speed, sin.v, strut.oil_viscosity(T_oil),
                                  strut.oil_density(T_oil), strut.p.oil.expansion, Pr_shape)
    rates = thermal.network_rates(P.heat, flows, eq["power_valve"], eq["power_friction"], eq["power_end_stop"],
                                  eq["heat_gas"])
    return eq, rates


def kernel(model, i: int, jacobian: bool) -> ca.Function:
    """Station i's kernel as an SX function (kernel inputs, [m_gas; x_mid; p]) -> kernel outputs (p: the model's
    parameter vector, `model.symbols[3]`): the calls `VehicleModel.eliminate_valves`, `equations` and
    `stiff_jacobian` make for that station."""
    K = model.sym
    strut = K.struts[i]
    p = model.symbols[3]
    s = {nm: ca.SX.sym(nm) for nm in input_names(strut) + STATION_PARAMETERS}
    internal = {nm: s[nm] for nm in strut.state_names}
    sin = StrutInputs(x=s["x"], v=s["v"], T_wall=s["T_oil"], m_gas=s["m_gas"], dV_oil=s["V_oil"],
                      dV_oil_rate=s["q_oil"], dT_wall_rate=0.0, x_mid=s["x_mid"])
    dp = valve_drop(strut, sin, internal, s["dp_guess"])
    eq, node_rates = strut_part(K, i, sin, internal, dp, s["T_oil"], s["T_wall"], s["T_surface"], s["T_amb"],
                                s["speed"])
    outs = [dp, eq["force"], *[eq["rates"][nm] for nm in strut.state_names], *[eq[k] for k in POWERS], *node_rates]
    if jacobian:
        outs += list(model._strut_stiffness_damping(i, s["x"], s["v"], s["T_oil"], s["m_gas"], s["V_oil"], dp,
                                                     [internal[nm] for nm in strut.state_names]))
    return ca.Function(f"strut_kernel_{i}", [ca.vertcat(*[s[nm] for nm in input_names(strut)]),
                                              ca.vertcat(*[s[nm] for nm in STATION_PARAMETERS], p)],
                       [ca.vertcat(*outs)])



def kernel_inputs(model, x, memory, u, p) -> list:
    """The kernel inputs of every station at state x, valve warm starts `memory`, inputs u (lists in
    `input_names` order, one per station)."""
    X = {nm: x[k] for k, nm in enumerate(model.layout.names)}
    iu = model.input_index
    out = []
    for i in range(model.n):
        sin, internal = model.strut_inputs(X, i, p, model.sym)
        out.append([sin.x, sin.v, X[f"T_oil[{i}]"], X[f"T_wall[{i}]"], X[f"T_surface[{i}]"], sin.dV_oil,
                    sin.dV_oil_rate, memory[model._z_index[i]], u[iu["ambient"]], u[iu["speed"]],
                    *[internal[nm] for nm in model.sym.struts[i].state_names]])
    return out


def parts_from_outputs(model, outputs: list[dict]) -> list[tuple]:
    """Per station, (the strut's equations, its node rates) as `strut_part` gives them, read from kernel outputs
    (name -> value, one dict per station): what `VehicleModel.equations(strut_parts=...)` takes. The gas pressure
    and temperature are outputs only, not part of the step: NaN here."""
    parts = []
    for i, o in enumerate(outputs):
        names = model.sym.struts[i].state_names
        eq = {"force": o["force"], "rates": {nm: o[nm] for nm in names}, "residual": None,
              "gas_pressure": ca.SX.nan, "gas_temperature": ca.SX.nan, **{k: o[k] for k in POWERS}}
        parts.append((eq, tuple(o[nm] for nm in NODE_RATES)))
    return parts


def applies(model) -> bool:
    """Whether the kernel describes the stations' strut part: every strut's valve is eliminated (an algebraic
    pressure drop: incompressible oil) and the stiff Jacobian is the structural one (no stiff internal states,
    `VehicleModel.jacobian_function`)."""
    return not model.has_stiff_strut_states and all(not st.compressible for st in model.struts)
