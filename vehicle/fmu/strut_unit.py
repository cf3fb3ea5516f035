"""One strut with its heat network, driven at its ends: the model inside the strut FMU (docs/fmu.md).

The strut's equations (`struts.model`) and the vehicle's heat network per strut (`vehicle.physics.thermal`: oil,
wall and surface nodes, the gas coupled to the oil) assembled as the vehicle assembles them for one station
(`vehicle.physics.model.VehicleModel.equations`), with the deflection, its rate, the ambient temperature and the
air speed over the strut as inputs instead of the hull and the wheel. It offers what the compiled ROS2 solver
(`vehicle.numerics.solvers.Ros2`) needs of a model (nx, nu, np, n_memory, n_stiff, structure, ode_function,
jacobian_function, indicator_quadrature_indices). So the FMU steps with the same compiled step as a drive: the
valve pressure drop eliminated by one warm Newton step per stage from the previous step's value (the solver's
memory), the stiff strut states (compressible valve chamber, LuGre bristles) linearly implicit, the gas and heat
nodes and the energy quadratures by the explicit trapezoid.

Parameters p = (gas mass [kg], motion centre [m], start temperature [K], theta): theta is every non-zero number
of the strut file and of the vehicle file's `heat` section as a symbol (`hpsim.parameters`), so a parameter
change needs no new C. The gas mass is calculated from the charge (`run_parameters_function`: Newton on the
gas density, the symbolic twin of `struts.gas.gas_mass`).
"""
from __future__ import annotations

from functools import cached_property

import casadi as ca

from hpsim.parameters import ParameterVector, symbolic_copy
from struts.gas import dp_dv_at_constant_T, pressure
from struts.model import StrutInputs, make_strut
from vehicle.physics import thermal
from vehicle.physics.model import Layout

# inputs u: (name, unit, description)
INPUTS = (
    ("deflection", "m", "strut deflection, 0 at full extension, > 0 in compression"),
    ("deflection_rate", "m/s", "deflection rate, > 0 in compression; within a communication step the deflection "
                               "is extrapolated with it"),
    ("ambient_temperature", "K", "air temperature around the strut"),
    ("air_speed", "m/s", "air speed across the strut (forced convection on the outer surface)"),
)
# an input extrapolated within a communication step with the rate given by another input
RATE_OF = {"deflection": "deflection_rate"}
RUN_PARAMETERS = (
    ("gas_mass", "kg", "gas mass, calculated from charge.pressure at charge.temperature at full extension "
                       "(seed 000 §2)"),
    ("motion_centre", "m", "centre of the motion (the friction hysteresis band, seed 001 eq. 2-3)"),
    ("T_start", "K", "temperature of the gas, oil, wall and surface at the start"),
)
ENERGIES = (("valve", "valve dissipation"), ("friction", "seal friction dissipation"),
            ("gas", "heat from the gas to the oil"), ("end_stop", "end-stop damping dissipation"),
            ("work", "work done on the strut (force x deflection rate)"),
            ("lost", "heat the strut gave to the air and the mounts"))
GAS_MASS_NEWTON_ITERATIONS = 30       # Newton on the BWR density from the ideal gas: converged to rounding


def gas_mass_symbolic(p_Pa, T_K, V_m3, gas, eos: str):
    """Gas mass [kg] of volume V at (p, T): the density of pressure(T, 1/rho) = p by Newton from the ideal gas
    (struts.gas.gas_mass, which brackets the same root in NumPy; BWR nitrogen is monotonic in rho for T >= 150 K)."""
    rho = p_Pa / (gas.R * T_K)
    if eos != "ideal":
        for _ in range(GAS_MASS_NEWTON_ITERATIONS):
            v = 1.0 / rho
            slope = -v * v * dp_dv_at_constant_T(T_K, v, gas, eos)
            rho = rho - (pressure(T_K, v, gas, eos) - p_Pa) / slope
    return V_m3 * rho


class StrutUnit:
    """The strut FMU's model (module docstring): `params` a StrutParams, `heat` a vehicle Heat section."""

    n_run = len(RUN_PARAMETERS)

    def __init__(self, params, heat, name: str = "strut"):
        self.params, self.heat, self.name = params, heat, name
        self.strut = make_strut(params)
        self.parameters = ParameterVector()
        sym_params = symbolic_copy(params, self.parameters, "strut")
        self.sym_heat = symbolic_copy(heat, self.parameters, "heat")
        self.sym_strut = make_strut(sym_params, check=False)
        L = Layout()
        st = self.strut
        for nm in st.stiff_state_names:
            L.add(nm)
        self.n_stiff = len(L)
        for nm in st.state_names:
            if nm not in st.stiff_state_names:
                L.add(nm)
        for node in thermal.NODES:
            L.add(f"T_{node}")
        for e, _ in ENERGIES:
            L.add(f"E_{e}")
        self.layout = L
        self.nx = len(L)
        self.nu = len(INPUTS)
        self.n_memory = 0 if st.compressible else 1
        self.np = self.n_run + len(self.parameters)

    @property
    def structure(self) -> str:
        return f"strut_{self.parameters.structure}"

    def indicator_quadrature_indices(self) -> list[int]:
        return []

    def initial_memory(self):
        return [0.0] * self.n_memory

    @cached_property
    def symbols(self):
        p = ca.vertcat(ca.SX.sym("p_run", self.n_run), self.parameters.symbols)
        return ca.SX.sym("x", self.nx), ca.SX.sym("memory", self.n_memory), ca.SX.sym("u", self.nu), p

    def _inputs(self, X, u, p):
        """(StrutInputs, internal states) from named states X, inputs u and parameters p."""
        sin = StrutInputs(x=u[0], v=u[1], T_wall=X["T_oil"], m_gas=p[0], x_mid=p[1])
        return sin, {nm: X[nm] for nm in self.strut.state_names}

    def _valve(self, sin, internal, memory, iterations: int, warm: bool = True):
        if self.strut.compressible:
            return None
        return self.sym_strut.valve_pressure_drop(sin.v, sin.T_wall, dp_guess=memory[0] if warm else None,
                                                  newton_iterations=iterations, warm=warm, u=sin, states=internal)

    def equations(self, x, memory, u, p, iterations: int = 1):
        """(rates in layout order, dp_valve, the strut's equations, the heat flows) at one instant."""
        strut, heat = self.sym_strut, self.sym_heat
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        sin, internal = self._inputs(X, u, p)
        dp = self._valve(sin, internal, memory, iterations)
        eq = strut.equations(sin, internal, dp)
        # as for a vehicle station (VehicleModel.equations), the air speed given directly (ratio 1)
        env = thermal.station_environment(heat)
        env.air_speed_ratio = 1.0
        T_oil, T_wall, T_surf = (X[f"T_{node}"] for node in thermal.NODES)
        Pr_shape = thermal.oil_prandtl(heat, strut.oil_viscosity(strut.p.oil.reference_temperature), strut.p.oil.density)
        flows = thermal.network_flows(heat, env, T_oil, T_wall, T_surf, u[2], u[3], sin.v, strut.oil_viscosity(T_oil),
                                      strut.oil_density(T_oil), strut.p.oil.expansion, Pr_shape)
        dT = thermal.network_rates(heat, flows, eq["power_valve"], eq["power_friction"], eq["power_end_stop"],
                                   eq["heat_gas"])
        rates = dict(eq["rates"])
        rates.update({f"T_{node}": r for node, r in zip(thermal.NODES, dT)})
        rates.update(E_valve=eq["power_valve"], E_friction=eq["power_friction"], E_gas=eq["heat_gas"],
                     E_end_stop=eq["power_end_stop"], E_work=eq["force"] * sin.v, E_lost=thermal.heat_lost(flows))
        return [rates[nm] for nm in self.layout.names], dp, eq, flows

    @cached_property
    def ode_function(self):
        """f(x, memory, u, p) -> (dx/dt, new memory): the explicit-ODE form (valve eliminated)."""
        x, mem, u, p = self.symbols
        ode, dp, _, _ = self.equations(x, mem, u, p)
        new_mem = dp if dp is not None else ca.SX(0, 1)
        return ca.Function("f_ode", [x, mem, u, p], [ca.vertcat(*ode), new_mem])

    @cached_property
    def jacobian_function(self):
        """J(x, memory, u, p) of the stiff block (the strut's stiff internal states), by CasADi AD."""
        x, mem, u, p = self.symbols
        f, _ = self.ode_function(x, mem, u, p)
        return ca.Function("J_stiff", [x, mem, u, p], [ca.jacobian(f[:self.n_stiff], x[:self.n_stiff])])

    # --- what the FMU shows ------------------------------------------------------------------
    def outputs(self) -> list[tuple[str, str, str]]:
        """(name, unit, description) of the outputs, in the order of `output_function`."""
        out = [("force", "N", "strut force, > 0 pushing the ends apart"),
               ("force_gas", "N", "gas spring force"), ("force_valve", "N", "valve (damping) force"),
               ("force_friction", "N", "seal friction force"), ("force_end_stop", "N", "end-stop force"),
               ("gas_pressure", "Pa", "gas pressure"), ("valve_pressure_drop", "Pa",
                                                         "pressure difference across the damping valves"),
               ("gas_volume", "m**3", "gas volume"), ("T_gas", "K", "gas temperature")]
        out += [(f"T_{node}", "K", text) for node, text in zip(
            thermal.NODES, ("oil temperature (the strut body seen by the gas, valve and seals)",
                            "temperature of the steel the oil wets (cylinder bore, piston, rod)",
                            "outer surface temperature (what a pyrometer reads)"))]
        out += [("power_valve", "W", "power dissipated in the valves"),
                ("power_friction", "W", "power dissipated by seal friction"),
                ("heat_gas", "W", "heat flow from the gas to the oil"),
                ("power_end_stop", "W", "power dissipated by the end-stop damping"),
                ("heat_lost", "W", "heat flow from the strut to the air and the mounts")]
        out += [(f"E_{e}", "J", f"{text} since the start") for e, text in ENERGIES]
        out += [("end_stop_compression", "1", "1 while the deflection is beyond the stroke (bump stop), else 0"),
                ("end_stop_extension", "1", "1 while the deflection is below 0 (rebound stop), else 0")]
        return out

    def output_function(self) -> ca.Function:
        """y(x, memory, u, p): the outputs (the valve solved by 4 warm Newton steps, as a drive's outputs)."""
        x, mem, u, p = self.symbols
        _, dp, eq, flows = self.equations(x, mem, u, p, iterations=4)
        X = {nm: x[k] for k, nm in enumerate(self.layout.names)}
        stroke = self.sym_strut.p.geometry.stroke
        values = [eq["force"], eq["gas_force"], eq["valve_force"], eq["friction_force"], eq["end_stop_force"],
                  eq["gas_pressure"], 0.0 if dp is None else dp, eq.get("gas_volume", 0.0), eq["gas_temperature"],
                  *(X[f"T_{node}"] for node in thermal.NODES),
                  eq["power_valve"], eq["power_friction"], eq["heat_gas"], eq["power_end_stop"],
                  thermal.heat_lost(flows), *(X[f"E_{e}"] for e, _ in ENERGIES),
                  ca.if_else(u[0] > stroke, 1.0, 0.0), ca.if_else(u[0] < 0.0, 1.0, 0.0)]
        if self.strut.compressible:
            values[6] = X["dp_valve"]
        return ca.Function("y", [x, mem, u, p], [ca.vertcat(*values)])

    def run_parameters_function(self) -> ca.Function:
        """theta-dependent run parameters: p -> (gas mass [kg]) from the charge."""
        *_, p = self.symbols
        sp = self.sym_strut.p
        V_ext = self.sym_strut.extended_gas_volume(sp.charge.temperature)
        m = gas_mass_symbolic(sp.charge.pressure, sp.charge.temperature, V_ext, self.sym_strut.gas, sp.gas.eos)
        return ca.Function("run", [p], [ca.vertcat(m)])

    def initial_function(self) -> ca.Function:
        """z0(p, u) = (x, memory): at rest at the input deflection, every node at T_start, the valve at the
        pressure drop of the input deflection rate (cold Newton, 40 steps)."""
        x, mem, u, p = self.symbols
        T0 = p[2]
        states = self.sym_strut.initial_states(T0, x=u[0], m_gas=p[0])
        X = dict(states)
        X.update({f"T_{node}": T0 for node in thermal.NODES})
        X.update({f"E_{e}": 0.0 for e, _ in ENERGIES})
        x0 = ca.vertcat(*[X[nm] for nm in self.layout.names])
        XS = {nm: x0[k] for k, nm in enumerate(self.layout.names)}
        sin, internal = self._inputs(XS, u, p)
        dp = self._valve(sin, internal, mem, 40, warm=False)
        return ca.Function("init", [p, u], [ca.vertcat(x0, *([] if dp is None else [dp]))])

    def default_parameters(self, motion_centre_m: float, T_start_K: float) -> list[float]:
        """p with the file's values (the gas mass slot is calculated by the FMU at initialisation)."""
        m = float(self.strut.charge_gas_mass)
        return [m, float(motion_centre_m), float(T_start_K), *self.parameters.numeric()]
