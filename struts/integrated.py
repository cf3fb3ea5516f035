"""The integrated hydropneumatic strut of seed 001 (Yin et al. 2023): shared gas-oil chamber.

Two chambers coupled by bleed orifices, check valves and leakage past the guide rings.

  c  piston-side chamber: free nitrogen on top of a gas-oil emulsion, pressure p_c
  r  annular rod-side chamber: emulsion only, pressure p_r
Force (seed 001 eq. 1): F = p_c A_c - p_r (A_c - A_r) + f, with f the asymmetric seal friction
with hysteresis band (seed 001 eq. 2-3, `struts.friction.seal_friction`), plus the end stops.

States (same interface as `struts.model.SeparatedStrut`):
  V_gas  free-gas volume before the oil's thermal expansion and levelling oil are taken off:
         V_g = V_gas - alpha V_oil (T_wall - T_charge) - dV_oil (seed 001 eq. 4). Seed 001 eq. 5
         is written for V_g; p_c follows from it algebraically: polytropic p_c = p_ext (V_ext/V_g)^n
         (seed 001 eq. 4, p_ext the gas pressure at full extension at T_wall, isochoric from the
         charge) or the equation of state at the gas temperature state (energy process,
         REFERENCE §6). With V_g as the state both are explicit (no inversion of the BWR equation)
         and a change of body temperature acts on the pressure at once, as in the separated strut.
  p_r    rod-side chamber pressure (seed 001 eq. 6).
  T_gas  gas temperature (energy process only); z_bristle (LuGre friction only); stroke_dir (the seal band's
         reversal memory, `struts.friction.stroke_direction_rate`, with a band); exc_* (the excitation measure of
         `struts.excitation`, only with frequency-dependent internal maps).

Internal parameters (seed 001 §5.2, `struts.maps`, `StrutBase.internal_parameters`): the gas fraction gamma_0,
the bleed and check discharge coefficients and the friction's per-stroke Coulomb, peak, Stribeck and transition
values are the file's constants or, with `internal_maps:`, functions of T_wall and the excitation frequency.
A gas fraction that follows the excitation changes the emulsion's compressibility and density at once. The slow
change of the emulsion's volume it implies (N (gamma_1 - gamma_0) ((p0/p)^(1/n) - 1) / (1 + gamma): about 1 cm^3
from 0.6 to 1.2 % at the rig's 2.4 MPa, 3 cm^3 at 20 MPa, against a free-gas volume of about 0.4 L) is not moved
into the gas balance.
Both V_gas and p_r are stiff (time constants ~ 0.1-2 ms): `stiff_state_names`. With quasi-steady chambers
(below) p_r is not a state.

Emulsion (seed 001 eq. 8-10, `struts.oil`): the liquid in each chamber is oil with entrained gas
of volume fraction gamma(p) (eq. 9) and density rho(p) = rho_h / ((1 - (p - p0)/beta_h)(1 + gamma))
(eq. 10). That is a specific volume nu(p) = rho_h/rho = (1 - (p - p0)/beta_h) + gamma0 (p0/p)^(1/n)
(the oil and gas volumes of eq. 8 per unit oil volume). The chamber compliance is V (-nu'/nu),
the exact derivative of the eq. 8 volumes, 1/beta = (1/beta_h + a gamma/(n p)) / (a (1 + gamma)),
a = 1 - (p - p0)/beta_h. Seed 001 eq. 11 is the same with a -> 1 in the oil term (differs by
(p - p0)/beta_h < 0.5 %). Using the exact derivative makes the continuity equations conserve the
emulsion mass exactly, so the strut returns to the same static state after any motion and stores
no energy over a closed cycle (eq. 11 would let the chamber pressures drift slowly over the
~1e5 cycles of a drive).

Continuity (seed 001 eq. 5-7), mass flow m_dot = rho_mean q from c to r, q the volumetric flow of
seed 001 eq. 12 at the mean emulsion density (bleed orifices, check valves opening for p_c > p_r,
leakage; `struts.valves.valve_flow` with the check-valve area weighted by C_v/C_b).

  chamber c:  V_e = V_c0 + V_gas,0 - A_c x - V_gas (emulsion volume), V_e/beta_c dp_c/dt + dV_e/dt = -m_dot/rho_c
  chamber r:  V_r = V_r0 + (A_c - A_r) x,                   V_r/beta_r dp_r/dt + dV_r/dt = +m_dot/rho_r
with dp_c/dt = b dV_g/dt + a_th along the gas process (polytropic: b = -n p_c/V_g, a_th = 0;
energy: b = ((dp/dv)_T - T (dp/dT)_v^2/c_v)/m, a_th = (dp/dT)_v (T_w - T)/tau).

Energy: power_valve = dp q (bleed + check + leakage), power_friction = f v, power_end_stop = end
stop damping force times v, heat_gas = heat flow gas -> wall (0 for the polytropic gas). The
gas_work_rate is the mechanical power into the compressible contents (free gas and emulsion of both
chambers) = (p_c A_c - p_r (A_c - A_r)) v + p_c r_ext - power_valve, where r_ext is the oil volume
pushed into chamber c by thermal expansion and levelling. So force x velocity = power_valve +
power_friction + gas_work_rate + end stop power at every instant. Over a periodic cycle the
gas_work_rate integrates to the gas heat loss (0 for the polytropic gas, up to the O((dp/beta)^2)
difference between dp q and the exact flow dissipation).

Quasi-steady chambers (valve.oil_model: quasi_steady, the yin2023 default). The pressure difference
p_c - p_r relaxes through the valves with the time constant tau = C_eff / (dq/d dp) (`chamber_time_constant`;
C_eff ~ C_r = V_r kappa, the rod chamber's emulsion compliance, in series with chamber c's gas and emulsion).
It is 0.1-2 ms for this strut (longest at large rebound flows, where the orifice conductance dq/d dp = q/(2 dp) is
smallest). With a small parameter eps = C_r (singular perturbation) the fast variable is dp = p_c - p_r. At
leading order its rate term C_r d(dp)/dt is dropped while the common-mode storage is kept, i.e. the emulsion of
both chambers is compressed at p_c:
  dV_gas/dt = (A_r v + C b r_ext - C a_th) / (C b - 1),   C = (V_e + V_r) kappa(p_c)
(chamber c's equation with both chambers' compliance and no valve flow: the strut is one chamber for its
volume). The valves pass what chamber r takes in,
  q = (A_c - A_r) v + C_r dp_c/dt,   dp_c/dt = b (dV_gas/dt - r_ext) + a_th,
with dp the algebraic variable of valve_flow(dp) = q (seed 001 eq. 12 at the emulsion density at p_c) and
p_r = p_c - dp. States: V_gas (and T_gas, z_bristle); dp_valve algebraic, eliminated by warm Newton on the
vehicle as the separated strut's is (`valve_demand`). Properties: the slow manifold is the static curve (dV_gas/dx
is the slope of the static V_g(x), so no pumping, the gas and emulsion store reversibly). The dissipation is
power_valve = dp (A_c - A_r) v (force work minus that reversible storage: the energy balance of the reduced model
closes exactly). It differs from the orifice's dp q by the chamber-r compression flow, a fraction
C_r |b| A_r / ((A_c - A_r)(1 + C |b|)) of it (0.3 % at the rig's 3 MPa, 2 % at 22 MPa). Validity: omega tau << 1
at the frequencies of the motion. The rig loops agree with the compressible chambers within 0.3 % in energy and
1.5 % of the force range at 10 mm up to 8 Hz (omega tau <= 0.05). At 20 mm and 8 Hz (omega tau 0.1, peak flow
1 m/s) the force differs by 15 % of its range around the reversals. Lost: the emulsion's pressure-difference
hysteresis of seed 001 §5.1, an O(omega tau) effect. Why it exists: a 4 ms vehicle step cannot follow a
0.1-2 ms relaxation; the compressible chambers' ROS2 stages overshoot it and the drive leaves physics
(docs/physics.md, "The integrated strut on the vehicle").

Static state (rest, p_c = p_r = p): free gas V_g(p) plus the emulsion of both chambers fill the
strut: V_g = V_ext - A_r x - N (nu(p)/nu(p0) - 1), N = V_c0 + V_r0 the emulsion volume at the
charge. Solved by Newton on V_g (fixed iteration count, works on CasADi symbols too); the static
force is p A_r.
"""
from __future__ import annotations


from hpsim import symbolic as sym
from hpsim.errors import UserInputError

from . import emulsion
from . import excitation
from . import gas as gaslaw
from . import oil as oillaw
from . import orifice
from . import valves
from .base import StrutBase
from .protocol import StrutInputs
from .params import StrutParams

_STATIC_NEWTON_ITERATIONS = 8   # quadratic convergence from the incompressible-liquid start
_PI = 3.141592653589793
# the emulsion's own states with internals: physical (struts.emulsion): free-gas fraction gamma_0, interface lag
EMULSION_STATE_NAMES = ("gas_fraction", "v_lag")
# width of the smoothed |a| of the interface entrainment: far below the rig's 0.3-5 m/s^2, zero at rest
_ACCELERATION_SMOOTHING_M_S2 = 0.01


class IntegratedStrut(StrutBase):
    """Seed 001 integrated strut: the `struts.protocol.Strut` contract with two emulsion chambers."""

    @staticmethod
    def check_parameters(params: StrutParams) -> None:
        """Geometry consistency of an integrated strut file (UserInputError naming the keys)."""
        g = params.geometry
        src = f"strut {params.name}"
        if not g.rod_area > 0 or not g.piston_area > g.rod_area:
            raise UserInputError(
                f"{src}: geometry.piston_area ({g.piston_area} m^2) must be > geometry.rod_area ({g.rod_area} m^2) > 0 "
                "for layout: integrated")
        if abs(g.gas_area - g.rod_area) > 1e-6 * g.rod_area:
            raise UserInputError(
                f"{src}: geometry.gas_area ({g.gas_area} m^2) must equal geometry.rod_area ({g.rod_area} m^2) for "
                "layout: integrated (the rod displaces the gas)")
        annulus = g.piston_area - g.rod_area
        if abs(g.valve_area - annulus) > 1e-6 * annulus:
            raise UserInputError(
                f"{src}: geometry.valve_area ({g.valve_area} m^2) must equal piston_area - rod_area ({annulus} m^2) "
                "for layout: integrated (the annulus volume crosses the valves)")
        if not g.piston_chamber_oil_volume > 0 or not g.rod_chamber_volume > 0:
            raise UserInputError(
                f"{src}: geometry.piston_chamber_oil_volume ({g.piston_chamber_oil_volume} m^3) and "
                f"geometry.rod_chamber_volume ({g.rod_chamber_volume} m^3) must be > 0 for layout: integrated")
        if params.valve.oil_model == "incompressible":
            raise UserInputError(
                f"{src}: valve.oil_model: incompressible is for layout: separated; an integrated strut takes "
                "compressible (chamber pressures as states, seed 001 eq. 5-7) or quasi_steady (their relaxation "
                "through the valves taken as instantaneous, the emulsion compressibility kept)")
        if params.internals == "physical":
            e = params.emulsion
            missing = [f"emulsion.{k}" for k in ("ostwald_reference_temperature", "release_efficiency",
                                                 "dissolution_time", "interface_time") if getattr(e, k) is None]
            if params.valve.check_critical_reynolds is not None and params.valve.check_hydraulic_diameter is None:
                missing.append("valve.check_hydraulic_diameter")
            if missing:
                raise UserInputError(f"{src}: internals: physical needs {', '.join(missing)} (the emulsion's free-gas "
                                     "dynamics, struts/emulsion.py; docs/physics.md)")
        if g.piston_chamber_oil_volume <= annulus * g.stroke:
            raise UserInputError(
                f"{src}: geometry.piston_chamber_oil_volume ({g.piston_chamber_oil_volume} m^3) must exceed the volume "
                f"moved to the rod side over the stroke, (piston_area - rod_area) stroke = {annulus * g.stroke:.4g} m^3")

    # --- structure ------------------------------------------------------------------------
    @property
    def quasi_steady(self) -> bool:
        """valve.oil_model quasi_steady: the chamber-pressure relaxation through the valves taken as
        instantaneous (module docstring, "Quasi-steady chambers"); p_r is then p_c - dp_valve, not a state."""
        return self.p.valve.oil_model == "quasi_steady"

    @property
    def state_names(self) -> tuple[str, ...]:
        own = ("V_gas",) if self.quasi_steady else ("V_gas", "p_r")
        if self.physical:
            own += EMULSION_STATE_NAMES
        return own + self.shared_state_names()

    @property
    def stiff_state_names(self) -> tuple[str, ...]:
        """Compressible chambers: V_gas and p_r (the relaxation through the valves, 0.01-1 ms). Quasi-steady:
        V_gas, which then carries the gas spring (coupled to the stiff wheel station, as the separated strut's
        gas spring is through its stiffness), and z_bristle for the LuGre seal."""
        return tuple(n for n in self.state_names if n in ("V_gas", "p_r", "z_bristle", "stroke_dir", "v_lag"))

    @property
    def algebraic_names(self) -> tuple[str, ...]:
        return ("dp_valve",) if self.quasi_steady else ()

    @property
    def compressible(self) -> bool:
        return not self.quasi_steady

    @property
    def piston_area(self) -> float:
        return self.p.geometry.piston_area

    @property
    def rod_area(self) -> float:
        return self.p.geometry.rod_area

    @property
    def annulus_area(self) -> float:
        return self.p.geometry.piston_area - self.p.geometry.rod_area

    @property
    def emulsion_volume_charged(self) -> float:
        """N [m^3]: emulsion in both chambers at full extension and the charge pressure."""
        g = self.p.geometry
        return g.piston_chamber_oil_volume + g.rod_chamber_volume

    # --- gas volume -----------------------------------------------------------------------------
    def gas_volume(self, x, T_wall, dV_oil=0.0):
        """Free-gas volume [m^3] at rest at deflection x with the liquid taken as incompressible:
        V_ext - A_r x (seed 001 eq. 4, 7). `static_state` adds the emulsion compression."""
        return self.extended_gas_volume(T_wall, dV_oil) - self.rod_area * x

    def _thermal_gas_volume_loss(self, T_wall, dV_oil):
        """alpha V_oil (T - T_charge) + dV_oil [m^3]: liquid volume added to chamber c (seed 001 eq. 4)."""
        return self.p.geometry.gas_volume_extended - self.extended_gas_volume(T_wall, dV_oil)

    def _polytropic_reference(self, T_wall, m_gas, dV_oil):
        """(p_ext [Pa], V_ext [m^3]): gas state at full extension at T_wall (isochoric from the charge)."""
        V_ext = self.extended_gas_volume(T_wall, dV_oil)
        return gaslaw.pressure(T_wall, V_ext / m_gas, self.gas, self.p.gas.eos), V_ext

    # --- emulsion (seed 001 eq. 8-10) -------------------------------------------------------------
    def _oil_state(self, T_wall):
        o = self.p.oil
        rho_h = oillaw.oil_density(T_wall, o.density, o.reference_temperature, o.expansion)
        beta_h = self.oil_bulk_modulus(T_wall)
        return rho_h, beta_h

    def emulsion(self, p, T_wall, gamma0=None) -> dict:
        """Emulsion properties at pressure p [Pa] and body temperature T_wall [K].

        gamma (eq. 9), rho [kg/m^3] (eq. 10) and nu = V/V(p0) [-] (relative volume of a fixed mass).
        The compressibility kappa = -d ln nu/dp [1/Pa] is the exact derivative of the eq. 8 volumes;
        1/kappa is seed 001 eq. 11 up to O((p - p0)/beta_h)).
        gamma0: the gas fraction at p0 (default: the file's emulsion.initial_gas_fraction; a map's value at
        the excitation, seed 001 Fig. 10a).
        """
        n = self.p.gas.polytropic_exponent
        p0 = self.p.charge.pressure
        g0 = self.p.emulsion.initial_gas_fraction if gamma0 is None else gamma0
        rho_h, beta_h = self._oil_state(T_wall)
        gamma = oillaw.emulsion_gas_fraction(p, p0, g0, n, beta_h)
        rho = oillaw.emulsion_density(p, p0, rho_h, beta_h, gamma)
        a = 1.0 - (p - p0) / beta_h
        kappa = (1.0 / beta_h + a * gamma / (n * p)) / (a * (1.0 + gamma))
        nu = rho_h / (rho * (1.0 + g0))
        return {"gamma": gamma, "rho": rho, "nu": nu, "kappa": kappa}

    # --- static state ---------------------------------------------------------------------------
    def _gas_law(self, V_g, T, m_gas, process, ref):
        """(p [Pa], dp/dV_g [Pa/m^3]) of the free gas at rest: isothermal at T or polytropic from ref."""
        if process == "isothermal":
            v = V_g / m_gas
            return (gaslaw.pressure(T, v, self.gas, self.p.gas.eos),
                    gaslaw.dp_dv_at_constant_T(T, v, self.gas, self.p.gas.eos) / m_gas)
        p_ext, V_ext = ref
        n = self.p.gas.polytropic_exponent
        p = gaslaw.polytropic_pressure(p_ext, V_ext, V_g, n)
        return p, -n * p / V_g

    def static_state(self, x, T, m_gas, dV_oil=0.0, process: str | None = None, gamma0=None):
        """(p [Pa], V_g [m^3]) at rest at deflection x, body and gas at temperature T.

        process=None uses the file's: "energy" -> isothermal at T, "polytropic" -> from full
        extension (seed 001 eq. 4). Solves V_g + N (nu(p(V_g)) - 1) = V_ext - A_r x by Newton.
        """
        if process is None:
            process = "isothermal" if self.p.gas.process == "energy" else "polytropic"
        if process not in ("isothermal", "polytropic"):
            raise ValueError(f"unknown static process {process!r}")
        ref = self._polytropic_reference(T, m_gas, dV_oil)
        target = self.gas_volume(x, T, dV_oil)
        N = self.emulsion_volume_charged
        V = target
        for _ in range(_STATIC_NEWTON_ITERATIONS):
            p, dp_dV = self._gas_law(V, T, m_gas, process, ref)
            em = self.emulsion(p, T, gamma0)
            residual = V - target + N * (em["nu"] - 1.0)
            slope = 1.0 - N * em["nu"] * em["kappa"] * dp_dV
            V = V - residual / slope
        p, _ = self._gas_law(V, T, m_gas, process, ref)
        return p, V

    def static_gas_force(self, x, T, m_gas, dV_oil=0.0, process: str | None = None):
        """Force [N] at rest: p A_r (seed 001 eq. 1 with p_c = p_r = p, no friction)."""
        p, _ = self.static_state(x, T, m_gas, dV_oil, process)
        return p * self.rod_area

    def initial_states(self, T_wall, x=None, m_gas=None, dV_oil=0.0, excitation_Hz_m=None) -> dict:
        """States at rest at deflection x [m] (required), gas mass m_gas [kg] (default: the charge),
        oil added dV_oil [m^3], gas and body at T_wall: the static state (`static_state`). excitation_Hz_m
        (frequency [Hz], amplitude [m]) of a rig sinusoid about x: the excitation states start at its mean
        squares (`struts.excitation.steady_states`) and the emulsion at its gas fraction; default: at rest."""
        if x is None:
            raise ValueError("IntegratedStrut.initial_states needs the deflection x (its chamber states depend on it)")
        m = self.charge_gas_mass if m_gas is None else m_gas
        f_Hz, amp = excitation_Hz_m if excitation_Hz_m is not None else (None, 0.0)
        gamma0 = self.internal_parameters(T_wall, f_Hz)["gas_fraction"]
        p, V_g = self.static_state(x, T_wall, m, dV_oil, gamma0=gamma0)
        out = {"V_gas": V_g + self._thermal_gas_volume_loss(T_wall, dV_oil), "p_r": p, "stroke_dir": 0.0,
               "gas_fraction": gamma0, "v_lag": 0.0}
        if self.uses_excitation:
            out.update(excitation.steady_states(x, amp, f_Hz if f_Hz is not None else 0.0))
        if "T_gas" in self.state_names:
            out["T_gas"] = T_wall
        if "z_bristle" in self.state_names:
            out["z_bristle"] = 0.0
        return {k: out[k] for k in self.state_names}

    # --- valves (seed 001 eq. 12) ------------------------------------------------------------------
    def _internal(self, u: StrutInputs, states: dict) -> dict | None:
        """Internal parameters at this instant (maps at T_wall and the excitation states' frequency), or None
        when the file has no maps (the constants are then read where they are used)."""
        if self.internal_maps is None:
            return None
        return self.internal_parameters(u.T_wall, self.excitation_frequency(states))

    def _gas_fraction(self, internal: dict | None, states: dict):
        """gamma_0 at this instant: the emulsion state (internals: physical), the map's value, or None (the file's)."""
        if self.physical:
            return states["gas_fraction"]
        return internal and internal["gas_fraction"]

    def emulsion_rates(self, u: StrutInputs, states: dict, q, dp) -> dict:
        """Rates of the emulsion's free-gas fraction and the interface lag (internals: physical; `struts.emulsion`).

        q [m^3/s] the valve flow c -> r and dp = p_c - p_r [Pa] at this instant."""
        e, P = self.p.emulsion, self.p
        ratio = emulsion.solubility_ratio(u.T_wall, e.ostwald_reference_temperature, e.solution_enthalpy)
        L = e.ostwald_coefficient * ratio
        a = emulsion.interface_acceleration(states["v_lag"], u.v, e.interface_time)
        nu, nu_ref = self.oil_viscosity(u.T_wall), self.oil_viscosity(P.oil.reference_temperature)
        gamma0 = states["gas_fraction"]
        rate = (emulsion.release_rate(q, dp, L, e.release_efficiency, P.charge.pressure,
                                      self.emulsion_volume_charged, P.valve.check_dp_crack)
                + emulsion.interface_entrainment_rate(a, nu, nu_ref, e.interface_entrainment,
                                                      e.entrainment_viscosity_exponent, _ACCELERATION_SMOOTHING_M_S2)
                + emulsion.dissolution_rate(gamma0, ratio, e.dissolution_time))
        return {"gas_fraction": rate, "v_lag": emulsion.interface_lag_rate(states["v_lag"], u.v, e.interface_time)}

    def _valve_kwargs(self, rho, T_wall, internal: dict | None = None) -> dict:
        """Keyword arguments of struts.valves.valve_flow for the bleed orifices + check valves + leakage.

        One discharge coefficient per call: the check-valve area is weighted by C_v/C_b (the
        orifice law depends on C_d A only). Laminar/turbulent transition as in the separated strut.
        internal: the mapped discharge coefficients (seed 001 Fig. 10b), else the file's constants.
        """
        v = self.p.valve
        i = internal or self.internal_parameters(T_wall)
        cd = i["bleed_discharge_coefficient"]
        cd_check = i["check_discharge_coefficient"]
        rho_oil, _ = self._oil_state(T_wall)
        nu = self.oil_viscosity(T_wall)
        d_h = sym.sqrt(4.0 * v.bleed_area / _PI)
        p_crit = orifice.critical_pressure(rho_oil, nu, v.critical_reynolds, cd, d_h)
        own_check = {}
        if self.physical and v.check_critical_reynolds is not None:
            # the check valves' small opening has its own Reynolds number (struts.orifice), at their own C_d
            own_check = {"check_p_crit": orifice.critical_pressure(rho_oil, nu, v.check_critical_reynolds, cd_check,
                                                                   v.check_hydraulic_diameter)}
        return dict(
            cd=cd, rho=rho, p_crit=p_crit,
            bleed_area=v.bleed_area * v.number_of_orifices,
            check_area_max=v.check_area_max * v.check_number * cd_check / cd,
            check_dp_crack=v.check_dp_crack, check_dp_full=v.check_dp_full,
            relief_comp_area=v.relief_comp_area, relief_comp_crack=v.relief_comp_crack,
            relief_comp_full=v.relief_comp_full,
            relief_reb_area=v.relief_reb_area, relief_reb_crack=v.relief_reb_crack,
            relief_reb_full=v.relief_reb_full,
            k_leak=v.leakage,
            **own_check,
        )

    def valve_arguments_for(self, rho, T_wall, internal: dict | None = None) -> dict:
        """Keyword arguments of struts.valves.valve_flow at emulsion density rho [kg/m^3] and body temperature T_wall
        [K], with the discharge coefficients of `internal` (bleed_discharge_coefficient, check_discharge_coefficient;
        default: the file's): seed 001 eq. 12 as the identification (`struts.identify`) evaluates it."""
        return self._valve_kwargs(rho, T_wall, internal)

    def valve_arguments(self, T_wall) -> dict:
        rho_oil, _ = self._oil_state(T_wall)
        return self._valve_kwargs(rho_oil, T_wall)

    def valve_flow_demand(self, v):
        """Flow [m^3/s] through the valves with incompressible liquid: (A_c - A_r) v."""
        return self.annulus_area * v

    # valve_pressure_drop (inherited): with (v, T_wall) only, the quasi-steady p_c - p_r of incompressible
    # liquid at the oil density (an initial guess); with (u, states) the quasi-steady flow balance of
    # `valve_demand` (chambers quasi_steady)

    # --- the equations ----------------------------------------------------------------------------
    def _gas_side(self, u: StrutInputs, states: dict) -> dict:
        """Chamber c's gas at one instant: p_c [Pa], T_gas [K], V_g [m^3], the gas process's dp_c/dt =
        b dV_g/dt + a_th (b [Pa/m^3], a_th [Pa/s]), heat_gas [W] and the liquid r_ext [m^3/s] pushed in by the
        oil's thermal expansion and levelling (seed 000 eq. 6)."""
        P = self.p
        m_gas = u.m_gas
        V_g = states["V_gas"] - self._thermal_gas_volume_loss(u.T_wall, u.dV_oil)
        r_ext = P.geometry.oil_volume * P.oil.expansion * u.dT_wall_rate + u.dV_oil_rate
        if P.gas.process == "energy":
            T_gas = states["T_gas"]
            v_spec = V_g / m_gas
            p_c = gaslaw.pressure(T_gas, v_spec, self.gas, P.gas.eos)
            p_T = gaslaw.dp_dT_at_constant_v(T_gas, v_spec, self.gas, P.gas.eos)
            p_v = gaslaw.dp_dv_at_constant_T(T_gas, v_spec, self.gas, P.gas.eos)
            cv = gaslaw.cv(T_gas, v_spec, self.gas, P.gas.eos)
            tau = P.gas.thermal_time_constant
            b = (p_v - T_gas * p_T * p_T / cv) / m_gas
            a_th = p_T * (u.T_wall - T_gas) / tau
            heat_gas = gaslaw.heat_flow_to_wall(T_gas, u.T_wall, tau, m_gas, cv)
        else:
            p_ext, V_ext = self._polytropic_reference(u.T_wall, m_gas, u.dV_oil)
            p_c = gaslaw.polytropic_pressure(p_ext, V_ext, V_g, P.gas.polytropic_exponent)
            T_gas = u.T_wall
            b = -P.gas.polytropic_exponent * p_c / V_g
            a_th = 0.0 * u.v
            heat_gas = 0.0 * u.v  # a reversible polytrope exchanges no net heat over a cycle
        return dict(p_c=p_c, T_gas=T_gas, V_g=V_g, b=b, a_th=a_th, heat_gas=heat_gas, r_ext=r_ext)

    def _chamber_volumes(self, u: StrutInputs, V_gas):
        """(V_e, V_r) [m^3]: emulsion volumes of chamber c (seed 001 eq. 5) and chamber r (eq. 6-7)."""
        g = self.p.geometry
        return (g.piston_chamber_oil_volume + g.gas_volume_extended - self.piston_area * u.x - V_gas,
                g.rod_chamber_volume + self.annulus_area * u.x)

    def _quasi_steady_balance(self, u: StrutInputs, states: dict) -> dict:
        """The reduced volume balance (module docstring, "Quasi-steady chambers"): dV_gas/dt with the emulsion of
        both chambers at p_c, the valve flow q [m^3/s] (c -> r) it implies and the emulsion at p_c."""
        gs = self._gas_side(u, states)
        internal = self._internal(u, states)
        em = self.emulsion(gs["p_c"], u.T_wall, self._gas_fraction(internal, states))
        V_e, V_r = self._chamber_volumes(u, states["V_gas"])
        C_c, C_r = V_e * em["kappa"], V_r * em["kappa"]
        C = C_c + C_r
        b, a_th, r_ext = gs["b"], gs["a_th"], gs["r_ext"]
        dV_gas = (self.rod_area * u.v + C * b * r_ext - C * a_th) / (C * b - 1.0)
        dp_c = b * (dV_gas - r_ext) + a_th
        q = self.annulus_area * u.v + C_r * dp_c
        return dict(gs, em=em, dV_gas=dV_gas, dp_c=dp_c, q=q, C_r=C_r, internal=internal)

    def valve_demand(self, u: StrutInputs, states: dict):
        """Quasi-steady chambers: (q = (A_c - A_r) v + C_r dp_c/dt [m^3/s], valve_flow arguments at the emulsion
        density at p_c). Compressible chambers: the incompressible-liquid demand (an initial guess only)."""
        if not self.quasi_steady:
            return super().valve_demand(u, states)
        bal = self._quasi_steady_balance(u, states)
        return bal["q"], self._valve_kwargs(bal["em"]["rho"], u.T_wall, bal["internal"])

    def chamber_time_constant(self, u: StrutInputs, states: dict, dp=None):
        """tau = C_eff / (dq/d dp) [s]: the relaxation time of the chamber-pressure difference through the valves
        (C_eff = C_r C_c' / (C_r + C_c'), C_c' = C_c + V_g/(-b V_g) the compliance of chamber c with its gas), at the
        pressure drop dp (default: the quasi-steady one of `valve_demand`). The quasi-steady reduction needs
        omega tau << 1 at the frequencies of the motion (module docstring)."""
        import casadi as ca

        gs = self._gas_side(u, states)
        internal = self._internal(u, states)
        em = self.emulsion(gs["p_c"], u.T_wall, self._gas_fraction(internal, states))
        V_e, V_r = self._chamber_volumes(u, states["V_gas"])
        C_r, C_c = V_r * em["kappa"], V_e * em["kappa"] - 1.0 / gs["b"]
        if dp is None:
            q, kw = self.valve_demand(u, states) if self.quasi_steady else \
                (self.annulus_area * u.v, self._valve_kwargs(em["rho"], u.T_wall, internal))
            dp = valves.valve_pressure_drop(q, newton_iterations=60, **kw)
        d = ca.SX.sym("dp")
        kw = self._valve_kwargs(em["rho"], u.T_wall, internal)
        G = ca.Function("G", [d], [ca.jacobian(valves.valve_flow(d, **kw), d)])(dp)
        return float(C_r * C_c / (C_r + C_c) / G)

    def force_derivatives(self, u, states: dict, dp_valve=None):
        """(dF/dx, dF/dv): compressible chambers as `StrutBase`; quasi-steady chambers with dp following (x, v)
        through the flow balance valve_flow(dp) = q(x, v, states) (implicit-function theorem)."""
        if not self.quasi_steady:
            return super().force_derivatives(u, states, dp_valve)
        import casadi as ca

        F = self.equations(u, states, dp_valve)["force"]
        q_dem, kw = self.valve_demand(u, states)
        dq_ddp = ca.jacobian(valves.valve_flow(dp_valve, **kw), dp_valve)
        dF_ddp = ca.jacobian(F, dp_valve)
        k = ca.jacobian(F, u.x) + dF_ddp * ca.jacobian(q_dem, u.x) / dq_ddp
        c = ca.jacobian(F, u.v) + dF_ddp * ca.jacobian(q_dem, u.v) / dq_ddp
        return k, c

    def equations(self, u: StrutInputs, states: dict, dp_valve=None) -> dict:
        """All strut equations at one instant (see the module docstring). dp_valve: the algebraic valve
        pressure drop p_c - p_r [Pa] with quasi-steady chambers; ignored with compressible ones."""
        if self.quasi_steady:
            return self._equations_quasi_steady(u, states, dp_valve)
        A_c, A_a = self.piston_area, self.annulus_area
        V_gas, p_r = states["V_gas"], states["p_r"]
        gs = self._gas_side(u, states)
        p_c, T_gas, V_g, b, a_th, heat_gas, r_ext = (gs[k] for k in ("p_c", "T_gas", "V_g", "b", "a_th", "heat_gas",
                                                                       "r_ext"))
        rates = {}
        internal = self._internal(u, states)
        g0 = self._gas_fraction(internal, states)
        em_c = self.emulsion(p_c, u.T_wall, g0)
        em_r = self.emulsion(p_r, u.T_wall, g0)
        rho_mean = 0.5 * (em_c["rho"] + em_r["rho"])
        dp = p_c - p_r
        q = valves.valve_flow(dp, **self._valve_kwargs(rho_mean, u.T_wall, internal))   # seed 001 eq. 12, c -> r
        m_dot = rho_mean * q
        # chamber c (seed 001 eq. 5): emulsion volume and its compliance
        V_e, V_r = self._chamber_volumes(u, V_gas)
        C_c = V_e * em_c["kappa"]
        dV_gas = (A_c * u.v - m_dot / em_c["rho"] + C_c * b * r_ext - C_c * a_th) / (C_c * b - 1.0)
        rates["V_gas"] = dV_gas
        # chamber r (seed 001 eq. 6-7)
        rates["p_r"] = (m_dot / em_r["rho"] - A_a * u.v) / (V_r * em_r["kappa"])
        return self._outputs(u, states, rates, p_c, p_r, T_gas, V_g, dV_gas - r_ext, heat_gas, r_ext, q, dp * q,
                             residual=None, internal=internal, dp=dp)

    def _equations_quasi_steady(self, u: StrutInputs, states: dict, dp_valve) -> dict:
        """Quasi-steady chambers (module docstring): V_gas from the reduced volume balance, p_r = p_c - dp_valve with
        dp_valve algebraic (residual: valve_flow(dp_valve) - q, q from the balance)."""
        bal = self._quasi_steady_balance(u, states)
        p_c = bal["p_c"]
        q = valves.valve_flow(dp_valve, **self._valve_kwargs(bal["em"]["rho"], u.T_wall, bal["internal"]))
        rates = {"V_gas": bal["dV_gas"]}
        # the reduced model's dissipation: force work minus the reversible storage (gas and emulsion at p_c)
        power_valve = dp_valve * self.annulus_area * u.v
        return self._outputs(u, states, rates, p_c, p_c - dp_valve, bal["T_gas"], bal["V_g"],
                             bal["dV_gas"] - bal["r_ext"], bal["heat_gas"], bal["r_ext"], bal["q"], power_valve,
                             residual=q - bal["q"], internal=bal["internal"], dp=dp_valve)

    def _outputs(self, u, states, rates, p_c, p_r, T_gas, V_g, dV_g, heat_gas, r_ext, q, power_valve, residual,
                 internal=None, dp=None):
        """Gas temperature, emulsion and friction rates, forces and powers shared by both chamber treatments."""
        P = self.p
        if self.physical:
            rates.update(self.emulsion_rates(u, states, q, dp))
        if P.gas.process == "energy":
            rates["T_gas"] = gaslaw.gas_temperature_rate(T_gas, u.T_wall, P.gas.thermal_time_constant,
                                                         V_g / u.m_gas, dV_g / u.m_gas, self.gas, P.gas.eos)
        F_fric, dz = self.friction_force(u.v, u.x - u.x_mid, p_r, u.T_wall, states.get("z_bristle"),
                                         states.get("stroke_dir"), internal)
        if dz is not None:
            rates["z_bristle"] = dz
        rates.update(self.memory_rates(u, states, internal))
        F_stop, F_stop_damping = self.end_stop_force(u.x, u.v)
        F_gas = p_c * self.rod_area
        F_valve = (p_c - p_r) * self.annulus_area
        F_fluid = F_gas + F_valve          # = p_c A_c - p_r (A_c - A_r), seed 001 eq. 1
        return dict(
            rates={n: rates[n] for n in self.state_names},
            residual=residual,
            force=F_fluid + F_fric + F_stop,
            gas_pressure=p_c,
            rod_chamber_pressure=p_r,
            gas_temperature=T_gas,
            gas_volume=V_g,
            gas_force=F_gas,
            valve_force=F_valve,
            friction_force=F_fric,
            end_stop_force=F_stop,
            valve_flow=q,
            power_valve=power_valve,
            power_friction=F_fric * u.v,
            power_end_stop=F_stop_damping * u.v,
            heat_gas=heat_gas,
            gas_work_rate=F_fluid * u.v + p_c * r_ext - power_valve,
        )
