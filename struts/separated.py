"""The separated strut of seed 000 (Hryciow et al. 2023): gas chamber, floating piston, oil, damping valve.

Implements the `struts.protocol.Strut` contract (inputs `StrutInputs`: deflection, velocity,
body temperature, gas mass, levelling oil) on top of the shared `struts.base.StrutBase`.
"""
from __future__ import annotations


from hpsim import symbolic as sym
from hpsim.errors import UserInputError

from . import gas as gaslaw
from . import valves
from .base import StrutBase
from .protocol import StrutInputs


class SeparatedStrut(StrutBase):
    """Seed 000 strut: gas chamber, floating piston, oil chambers, damping valve.

    Gas volume (seed 000 eq. 4 with eq. 6): V_g = V_g0 - beta_o V_oil (T_wall - T_charge) - A x - dV_oil.
    Gas pressure: energy process -> EOS(T_gas, V_g/m) with the REFERENCE §6 energy equation;
    polytropic process -> p_ext(T_wall) (V_ext/V_g)^n (seed 000 eq. 5, isochoric p_ext with eq. 6).
    Force: F = p_g A + dp_valve A_v + F_friction + F_end_stops.
    """


    @staticmethod
    def check_parameters(params) -> None:
        """valve.oil_model quasi_steady is the integrated layout's reduction (UserInputError)."""
        if params.valve.oil_model == "quasi_steady":
            raise UserInputError(
                f"strut {params.name}: valve.oil_model: quasi_steady is for layout: integrated; a separated strut "
                "takes compressible or incompressible (its algebraic valve pressure drop)")
        if params.internal_maps is not None:
            raise UserInputError(
                f"strut {params.name}: internal_maps (seed 001 §5.2: emulsion, valve and seal parameters over "
                "temperature and frequency) is for layout: integrated")

    # --- structure ------------------------------------------------------------------------
    @property
    def state_names(self) -> tuple[str, ...]:
        own = ("dp_valve",) if self.p.valve.oil_model == "compressible" else ()
        return own + self.shared_state_names()

    @property
    def stiff_state_names(self) -> tuple[str, ...]:
        """Internal states with fast dynamics (time constants far below a millisecond step)."""
        return tuple(n for n in self.state_names if n in ("dp_valve", "z_bristle", "stroke_dir"))

    @property
    def algebraic_names(self) -> tuple[str, ...]:
        return () if self.compressible else ("dp_valve",)

    @property
    def compressible(self) -> bool:
        return self.p.valve.oil_model == "compressible"

    # --- charge and gas volume ---------------------------------------------------------------
    def gas_volume(self, x, T_wall, dV_oil=0.0):
        """Gas volume [m^3] at deflection x (seed 000 eq. 4)."""
        return self.extended_gas_volume(T_wall, dV_oil) - self.p.geometry.gas_area * x

    def gas_pressure(self, x, T_gas, T_wall, m_gas, dV_oil=0.0, process: str | None = None):
        """Gas pressure [Pa]; process None takes the file's. With "polytropic" T_gas is ignored."""
        eos = self.p.gas.eos
        V = self.gas_volume(x, T_wall, dV_oil)
        if (process or self.p.gas.process) == "polytropic":
            V_ext = self.extended_gas_volume(T_wall, dV_oil)
            p_ext = gaslaw.pressure(T_wall, V_ext / m_gas, self.gas, eos)
            return gaslaw.polytropic_pressure(p_ext, V_ext, V, self.p.gas.polytropic_exponent)
        return gaslaw.pressure(T_gas, V / m_gas, self.gas, eos)

    def static_gas_force(self, x, T, m_gas, dV_oil=0.0, process: str | None = None):
        """Gas force [N] at rest with gas and body at temperature T.

        process=None uses the file's: "energy" -> isothermal at T (the gas has had time to
        exchange heat); "polytropic" -> seed 000 eq. 5 from full extension.
        """
        law = self._static_law(process)
        return self.gas_pressure(x, T, T, m_gas, dV_oil, law) * self.p.geometry.gas_area

    def _static_law(self, process: str | None) -> str:
        """The gas law ("energy": isothermal at T; "polytropic") of the static process (None: the file's)."""
        if process is None:
            process = "isothermal" if self.p.gas.process == "energy" else "polytropic"
        if process not in ("isothermal", "polytropic"):
            raise ValueError(f"unknown static process {process!r}")
        return "energy" if process == "isothermal" else "polytropic"

    def gas_mass_carrying(self, force_N: float, x, T, process: str | None = None, dV_oil=0.0) -> float:
        """Gas mass [kg] whose static gas force at deflection x [m] and temperature T [K] is force_N [N]: the
        inverse of `static_gas_force` in closed form. The pressure p = F / A; isothermal, the gas at T fills the gas
        volume V(x) at p: m = V / v(p, T) with v the equation of state's inverse (`gas.specific_volume`);
        polytropic (seed 000 eq. 5), p = p_ext (V_ext / V)^n, so p_ext = p (V / V_ext)^n and m = V_ext / v(p_ext, T)."""
        p = float(force_N) / self.p.geometry.gas_area
        V = float(self.gas_volume(x, T, dV_oil))
        eos = self.p.gas.eos
        if self._static_law(process) == "polytropic":
            V_ext = float(self.extended_gas_volume(T, dV_oil))
            p_ext = gaslaw.polytropic_pressure(p, V, V_ext, self.p.gas.polytropic_exponent)   # back to full extension
            return float(gaslaw.gas_mass(p_ext, T, V_ext, self.gas, eos))
        return float(gaslaw.gas_mass(p, T, V, self.gas, eos))

    # --- oil properties -----------------------------------------------------------------------
    # --- valve ----------------------------------------------------------------------------------
    def valve_arguments(self, T_wall) -> dict:
        """Keyword arguments of struts.valves.valve_flow at body temperature T_wall.

        The laminar/turbulent transition pressure follows the viscosity: at the critical
        Reynolds number Re_c in the bleed orifice of hydraulic diameter d,
        p_crit = rho/2 (Re_c nu / (C_d d))^2.
        """
        v = self.p.valve
        rho = self.oil_density(T_wall)
        nu = self.oil_viscosity(T_wall)
        d_h = sym.sqrt(4.0 * v.bleed_area / 3.141592653589793)
        p_crit = 0.5 * rho * (v.critical_reynolds * nu / (v.discharge_coefficient * d_h)) ** 2
        return dict(
            cd=v.discharge_coefficient, rho=rho, p_crit=p_crit,
            bleed_area=v.bleed_area * v.number_of_orifices,
            check_area_max=v.check_area_max * v.check_number,
            check_dp_crack=v.check_dp_crack, check_dp_full=v.check_dp_full,
            relief_comp_area=v.relief_comp_area, relief_comp_crack=v.relief_comp_crack,
            relief_comp_full=v.relief_comp_full,
            relief_reb_area=v.relief_reb_area, relief_reb_crack=v.relief_reb_crack,
            relief_reb_full=v.relief_reb_full,
            k_leak=v.leakage,
        )

    def valve_flow_demand(self, v):
        """Oil flow [m^3/s] forced through the damping valve (incompressible oil, seed 000 eq. 2)."""
        return self.p.geometry.valve_area * v

    # --- friction -----------------------------------------------------------------------------
    # --- end stops ------------------------------------------------------------------------------
    # --- the equations ----------------------------------------------------------------------------
    def equations(self, u: StrutInputs, states: dict, dp_valve=None) -> dict:
        """All strut equations at one instant.

        Returns a dict with: rates (dict state -> d/dt), residual (valve flow balance, m^3/s
        scaled to Pa-like units), force [N], gas_pressure [Pa], gas_temperature [K],
        gas_force, valve_force, friction_force, end_stop_force [N], and power by mechanism
        [W]: power_valve, power_friction, power_end_stop (dissipated, >= 0) and heat_gas
        (heat flow from gas to wall, net >= 0 over a cycle).
        """
        P = self.p
        A = P.geometry.gas_area
        m_gas = u.m_gas
        V = self.gas_volume(u.x, u.T_wall, u.dV_oil)
        # oil expanding with the body temperature (seed 000 eq. 6) also compresses the gas
        dVdt = -A * u.v - P.geometry.oil_volume * P.oil.expansion * u.dT_wall_rate - u.dV_oil_rate
        rates = {}
        if P.gas.process == "energy":
            T_gas = states["T_gas"]
            p_gas = gaslaw.pressure(T_gas, V / m_gas, self.gas, P.gas.eos)
            rates["T_gas"] = gaslaw.gas_temperature_rate(T_gas, u.T_wall, P.gas.thermal_time_constant,
                                                         V / m_gas, dVdt / m_gas, self.gas, P.gas.eos)
            cv = gaslaw.cv(T_gas, V / m_gas, self.gas, P.gas.eos)
            heat_gas = gaslaw.heat_flow_to_wall(T_gas, u.T_wall, P.gas.thermal_time_constant, m_gas, cv)
        else:
            p_gas = self.gas_pressure(u.x, None, u.T_wall, m_gas, u.dV_oil)
            T_gas = u.T_wall
            heat_gas = 0.0 * u.v  # a reversible polytrope exchanges no net heat over a cycle
        F_fric, dz = self.friction_force(u.v, u.x - u.x_mid, p_gas, u.T_wall, states.get("z_bristle"),
                                         states.get("stroke_dir"))
        if dz is not None:
            rates["z_bristle"] = dz
        rates.update(self.memory_rates(u, states, None))
        F_stop, F_stop_damping = self.end_stop_force(u.x, u.v)
        q = self.valve_flow_demand(u.v)
        vargs = self.valve_arguments(u.T_wall)
        if self.compressible:
            dp_valve = states["dp_valve"]
        q_valve = valves.valve_flow(dp_valve, **vargs)
        if self.compressible:
            rates["dp_valve"] = chamber_pressure_rate(q, q_valve, self.oil_bulk_modulus(u.T_wall),
                                                      P.valve.compliant_oil_volume)
            residual = None
        else:
            residual = q_valve - q
        F_valve = dp_valve * P.geometry.valve_area
        F_gas = p_gas * A
        return dict(
            rates=rates,
            residual=residual,
            force=F_gas + F_valve + F_fric + F_stop,
            gas_pressure=p_gas,
            gas_temperature=T_gas,
            gas_volume=V,
            gas_force=F_gas,
            valve_force=F_valve,
            friction_force=F_fric,
            end_stop_force=F_stop,
            # the valve dissipates dp q_valve; dp (q - q_valve) goes into compressing the oil
            power_valve=dp_valve * q_valve,
            power_friction=F_fric * u.v,
            power_end_stop=F_stop_damping * u.v,
            heat_gas=heat_gas,
            gas_work_rate=-p_gas * dVdt,     # mechanical power into the gas [W]
        )

    def initial_states(self, T_wall, x=None, m_gas=None, dV_oil=0.0, excitation_Hz_m=None) -> dict:
        """States at rest at body temperature T_wall (x, m_gas, dV_oil: not needed here; the
        integrated strut's chamber states depend on them)."""
        out = {}
        if "dp_valve" in self.state_names:
            out["dp_valve"] = 0.0
        if "T_gas" in self.state_names:
            out["T_gas"] = T_wall
        if "z_bristle" in self.state_names:
            out["z_bristle"] = 0.0
        if "stroke_dir" in self.state_names:
            out["stroke_dir"] = 0.0
        return out


def chamber_pressure_rate(q_in_m3_s, q_out_m3_s, bulk_modulus_Pa, volume_m3):
    """d(dp)/dt [Pa/s] of an oil volume with net inflow: beta/V (q_in - q_out) (seed 001 eq. 5-6)."""
    return bulk_modulus_Pa / volume_m3 * (q_in_m3_s - q_out_m3_s)

