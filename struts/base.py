"""What every strut model shares: parameters, gas, oil properties, seal friction, end stops.

`StrutBase` implements the parts of the `struts.protocol.Strut` contract that do not depend on the
strut's layout; `struts.separated.SeparatedStrut` (seed 000) and `struts.integrated.IntegratedStrut`
(seed 001) are siblings that add their own chambers, states and equations.
"""
from __future__ import annotations

from functools import cached_property

from hpsim import symbolic as sym
from hpsim.errors import UserInputError

from . import excitation
from . import friction as fr
from . import gas as gaslaw
from . import maps as mapslaw
from . import oil as oillaw
from . import seal_friction as seal
from . import valves
from .params import REVERSAL_MEMORY_TIME_S, StrutParams

# the gas masses searched for a strut's charge [kg]: 0.1 g to 5 kg of nitrogen spans any vehicle strut's charge (the
# built-in vehicles charge 0.016-0.087 kg: the 8x8 ~0.08 kg, the light 4x4's integrated struts ~0.017 kg)
GAS_MASS_BRACKET_KG = (1e-4, 5.0)


class StrutBase:
    """Shared strut physics; subclasses define the chambers (`equations`, states, statics)."""

    def __init__(self, params: StrutParams, gas_properties=None):
        self.p = params
        self.gas = gas_properties or gaslaw.load_gas("nitrogen")

    @staticmethod
    def check_parameters(params: StrutParams) -> None:
        """Consistency checks a layout needs beyond the parameter schema (UserInputError naming keys)."""

    # --- states both strut types may carry -----------------------------------------------------
    def shared_state_names(self) -> tuple[str, ...]:
        """The optional internal states of the gas and seal models: T_gas (energy-equation gas) and
        z_bristle (LuGre friction), in that order after a strut's own chamber states."""
        names = ()
        if self.p.gas.process == "energy":
            names += ("T_gas",)
        if self.p.friction.model == "lugre":
            names += ("z_bristle",)
        elif self.hysteresis_band:
            names += ("stroke_dir",)
        if self.uses_excitation:
            names += excitation.STATE_NAMES
        return names

    @property
    def hysteresis_band(self) -> bool:
        """Seed 001 eq. 3 band on: a non-zero transition velocity (constant or mapped). The band then carries the
        reversal memory `stroke_dir` (struts.friction.stroke_direction_rate)."""
        f, m = self.p.friction, self.internal_maps
        mapped = m is not None and any(getattr(m, n) is not None for n in
                                       ("transition_velocity_compression", "transition_velocity_rebound"))
        return mapped or not (fr._is_zero(f.hysteresis_velocity_compression)
                              and fr._is_zero(f.hysteresis_velocity_rebound))

    @property
    def uses_excitation(self) -> bool:
        """True when an internal map varies with frequency: the strut then carries the excitation states of
        `struts.excitation` (no other strut does, so their cost falls only on struts that use them)."""
        m = self.internal_maps
        return m is not None and m.uses_frequency

    @property
    def physical(self) -> bool:
        """internals: physical: the internal parameters emerge from the strut's physics (struts.integrated), the
        file's internal_maps are not read."""
        return self.p.internals == "physical"

    @property
    def internal_maps(self):
        """The internal-parameter maps in use (None with internals: physical or without maps)."""
        return None if self.physical else self.p.internal_maps

    # --- internal parameters over temperature and excitation (seed 001 §5.2, struts.maps) -------
    def excitation_frequency(self, states: dict):
        """Equivalent excitation frequency [Hz] from the excitation states (`struts.excitation`); the maps'
        lowest frequency when the strut carries none."""
        m = self.internal_maps
        if m is None:
            return None
        if not self.uses_excitation:
            return m.frequencies[0]
        return excitation.equivalent_frequency(states, m.frequencies[0], m.deflection_floor)

    def internal_parameters(self, T_wall, f_Hz=None) -> dict:
        """The seed 001 §5.2 internal parameters (`struts.maps.INTERNAL_NAMES`, SI) at body temperature T_wall [K]
        and excitation frequency f_Hz [Hz]: the map where the file gives one, else the file's constant."""
        f, v, m = self.p.friction, self.p.valve, self.internal_maps
        cd_check = v.discharge_coefficient if v.check_discharge_coefficient is None else v.check_discharge_coefficient
        out = {
            "gas_fraction": self.p.emulsion.initial_gas_fraction,
            "bleed_discharge_coefficient": v.discharge_coefficient,
            "check_discharge_coefficient": cd_check,
            "coulomb_compression": f.F0_compression,
            "coulomb_rebound": f.F0_rebound,
            "peak_compression": f.breakaway_ratio * f.F0_compression,
            "peak_rebound": f.breakaway_ratio * f.F0_rebound,
            "stribeck_coefficient_compression": 1.0 / f.stribeck_velocity,
            "stribeck_coefficient_rebound": 1.0 / f.stribeck_velocity,
            "transition_velocity_compression": f.hysteresis_velocity_compression,
            "transition_velocity_rebound": f.hysteresis_velocity_rebound,
        }
        if m is not None:
            f_Hz = m.frequencies[0] if f_Hz is None else f_Hz
            for name in m.mapped():
                out[name] = mapslaw.map_value(m, name, T_wall, f_Hz)
        return out

    def memory_rates(self, u, states: dict, internal: dict | None) -> dict:
        """Rates of the reversal memory and the excitation states this strut carries (none for most struts)."""
        rates = {}
        if "stroke_dir" in self.state_names:
            f = self.p.friction
            i = internal or self.internal_parameters(u.T_wall)
            rates["stroke_dir"] = fr.stroke_direction_rate(
                states["stroke_dir"], u.v, i["transition_velocity_compression"], i["transition_velocity_rebound"],
                f.smoothing_velocity,
                REVERSAL_MEMORY_TIME_S if f.reversal_memory_time is None else f.reversal_memory_time)
        if self.uses_excitation:
            rates.update(excitation.rates(u.x, u.v, states, self.internal_maps.excitation_time_constant))
        return rates

    # --- charge -------------------------------------------------------------------------------

    @cached_property
    def charge_gas_mass(self) -> float:
        """Gas mass [kg] from the charge: pressure at full extension at the charge temperature."""
        g, c = self.p.geometry, self.p.charge
        return float(gaslaw.gas_mass(c.pressure, c.temperature, g.gas_volume_extended, self.gas, self.p.gas.eos))

    def gas_mass_for(self, pressure_Pa: float, temperature_K: float) -> float:
        """Gas mass for another fill pressure at full extension and temperature."""
        V_ext = float(self.extended_gas_volume(temperature_K))
        return float(gaslaw.gas_mass(pressure_Pa, temperature_K, V_ext, self.gas, self.p.gas.eos))

    def gas_mass_carrying(self, force_N: float, x, T, process: str | None = None) -> float:
        """Gas mass [kg] whose static gas force (`static_gas_force`) at deflection x [m] and temperature T [K] is
        force_N [N]: the root on the mass, which the force grows with, within GAS_MASS_BRACKET_KG (Brent's method;
        UserInputError when even its upper end does not carry the force). A layout whose static law inverts in closed
        form overrides it (`SeparatedStrut`)."""
        from scipy.optimize import brentq        # here, not at the top: SciPy's optimize package takes ~0.1 s to import

        def residual(m):
            return float(self.static_gas_force(x, T, m, process=process)) - force_N

        lo, hi = GAS_MASS_BRACKET_KG
        if residual(hi) < 0:
            raise UserInputError(f"strut {self.p.name}: {hi:g} kg of gas do not carry {force_N / 1e3:.4g} kN at "
                                 f"{float(x) * 1e3:.4g} mm")
        return float(brentq(residual, lo, hi, xtol=1e-14, rtol=1e-14))

    def extended_gas_volume(self, T_wall, dV_oil=0.0):
        """Gas volume at full extension [m^3]: oil thermal expansion eats gas space (seed 000 eq. 6)."""
        g, o = self.p.geometry, self.p.oil
        expansion = oillaw.thermal_expansion_into_gas(T_wall, g.oil_volume, self.p.charge.temperature, o.expansion)
        return g.gas_volume_extended - expansion - dV_oil


    # --- oil properties -----------------------------------------------------------------------

    @cached_property
    def _walther(self):
        o = self.p.oil
        return oillaw.walther_coefficients(o.viscosity_T1, o.viscosity_nu1, o.viscosity_T2, o.viscosity_nu2)

    def oil_viscosity(self, T_wall):
        A, B = self._walther
        return oillaw.walther_kinematic_viscosity(T_wall, A, B)

    def oil_density(self, T_wall):
        o = self.p.oil
        return oillaw.oil_density(T_wall, o.density, o.reference_temperature, o.expansion)


    def oil_bulk_modulus(self, T_wall):
        o = self.p.oil
        return oillaw.oil_bulk_modulus(T_wall, o.bulk_modulus, o.reference_temperature, o.bulk_modulus_slope)

    # --- valve ----------------------------------------------------------------------------------
    def valve_flow_demand(self, v):
        """Oil flow [m^3/s] the deflection rate v [m/s] forces through the valves (incompressible liquid)."""
        raise NotImplementedError

    def valve_demand(self, u, states: dict):
        """(flow [m^3/s] the valves must pass, keyword arguments of `struts.valves.valve_flow`) at one instant.

        Default: the deflection rate's flow with the oil at the body temperature (seed 000 eq. 2), a function of
        (v, T_wall) only; a strut whose flow balance involves its internal states (the integrated strut with
        quasi-steady chambers, `struts.integrated`) overrides it."""
        return self.valve_flow_demand(u.v), self.valve_arguments(u.T_wall)

    def valve_pressure_drop(self, v, T_wall, dp_guess=None, newton_iterations: int = 40, warm: bool = False,
                            u=None, states: dict | None = None):
        """Eliminates the algebraic dp_valve: solves valve_flow(dp) = A_v v.

        warm=True: a few plain Newton steps from dp_guess (the previous time step's value).
        u, states (StrutInputs and internal states): the flow balance of `valve_demand` at that instant
        instead of (v, T_wall) (needed when it depends on the internal states).
        """
        if u is None:
            q, kw = self.valve_flow_demand(v), self.valve_arguments(T_wall)
        else:
            q, kw = self.valve_demand(u, states)
        if warm:
            return valves.valve_pressure_drop_warm(q, dp_guess, newton_iterations, **kw)
        return valves.valve_pressure_drop(q, newton_iterations=newton_iterations, dp_guess=dp_guess, **kw)


    # --- friction -----------------------------------------------------------------------------

    def friction_viscous(self, T_wall):
        """Viscous seal friction scales with the oil film viscosity (relative to T_ref)."""
        f = self.p.friction
        return f.viscous * self.oil_viscosity(T_wall) / self.oil_viscosity(self.p.oil.reference_temperature)

    def friction_force(self, v, x_rel, p_gas, T_wall, z_bristle=None, stroke_dir=None, internal: dict | None = None):
        """(seal friction [N], dz_bristle/dt or None). internal: the internal parameters of
        `internal_parameters` (per-direction Coulomb, peak, Stribeck and transition values); stroke_dir: the
        reversal memory (replaces sgn(x_rel) in the band)."""
        f = self.p.friction
        f_v = self.friction_viscous(T_wall)
        if internal is not None and f.model == "stribeck":
            i = internal
            return fr.seal_friction(
                v, x_rel, p_gas, F0_comp=i["coulomb_compression"], F0_reb=i["coulomb_rebound"],
                f_p=f.pressure_coefficient, K_brk=i["peak_compression"] / i["coulomb_compression"],
                K_brk_reb=i["peak_rebound"] / i["coulomb_rebound"],
                v_s=1.0 / i["stribeck_coefficient_compression"], v_s_reb=1.0 / i["stribeck_coefficient_rebound"],
                f_v=f_v, eps=f.smoothing_velocity, v_h_comp=i["transition_velocity_compression"],
                v_h_reb=i["transition_velocity_rebound"], eps_x=f.hysteresis_smoothing_displacement,
                stroke_dir=stroke_dir), None
        if f.model == "lugre":
            # per-stroke levels (seed 001 Fig. 11a) at the seal's contact pressure over temperature
            F0 = seal.stroke_level(v, f.F0_compression, f.F0_rebound, f.smoothing_velocity)
            if not fr._is_zero(f.contact_temperature_coefficient):
                F0 = seal.contact_coulomb_level(F0, T_wall, self.p.oil.reference_temperature,
                                                f.contact_temperature_coefficient)
            F_c = fr.coulomb_level(p_gas, F0, f.pressure_coefficient)
            F_s = F_c * f.breakaway_ratio
            dz = fr.lugre_bristle_rate(z_bristle, v, F_c, F_s, f.stribeck_velocity, f.bristle_stiffness,
                                       f.smoothing_velocity)
            return fr.lugre_force(z_bristle, dz, v, f.bristle_stiffness, f.bristle_damping, f_v), dz
        F = fr.seal_friction(
            v, x_rel, p_gas, F0_comp=f.F0_compression, F0_reb=f.F0_rebound, f_p=f.pressure_coefficient,
            K_brk=f.breakaway_ratio, v_s=f.stribeck_velocity, f_v=f_v, eps=f.smoothing_velocity,
            v_h_comp=f.hysteresis_velocity_compression, v_h_reb=f.hysteresis_velocity_rebound,
            eps_x=None if fr._is_zero(f.hysteresis_velocity_compression) and fr._is_zero(f.hysteresis_velocity_rebound)
            else f.hysteresis_smoothing_displacement, stroke_dir=stroke_dir)
        return F, None


    # --- end stops ------------------------------------------------------------------------------

    def end_stop_force(self, x, v):
        """Elastic stops beyond full extension (x < 0) and full compression (x > stroke): (force, damping part)."""
        e, stroke = self.p.end_stops, self.p.geometry.stroke
        pen_c = sym.ramp(x - stroke, e.smoothing)
        pen_r = sym.ramp(-x, e.smoothing)
        engaged = sym.smooth_step(x - stroke, -e.smoothing, e.smoothing) + sym.smooth_step(-x, -e.smoothing, e.smoothing)
        damping = e.damping * engaged * v
        return e.stiffness * (pen_c - pen_r) + damping, damping


    # --- derivative information (for implicit solvers and linearisation) -----------------------
    def force_derivatives(self, u, states: dict, dp_valve=None):
        """(dF/dx [N/m], dF/dv [N s/m]) of the strut force at one instant, symbolic.

        For an incompressible strut the valve pressure drop follows the velocity through the flow
        balance valve_flow(dp) = A_v v, so its part of dF/dv is A_v^2 / (d valve_flow / d dp)
        (implicit-function theorem) rather than a derivative through Newton iterations.
        """
        import casadi as ca

        eq = self.equations(u, states, dp_valve)
        F = eq["force"]
        k = ca.jacobian(F, u.x)
        c = ca.jacobian(F, u.v)
        if not self.compressible:
            q = valves.valve_flow(dp_valve, **self.valve_arguments(u.T_wall))
            Av = self.valve_flow_demand(1.0)
            c = c + ca.jacobian(F, dp_valve) * Av / ca.jacobian(q, dp_valve)
        return k, c
