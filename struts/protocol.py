"""The strut contract: what the rig (`struts.rig`) and the vehicle (`vehicle.physics.model`) rely on.

A strut model is equations only (PyBaMM-style: a model is equations, parameters fill them). It
names its internal differential states (and which of them are stiff), its algebraic variables,
and returns from `equations(...)` symbolic (CasADi) or numeric (NumPy) expressions for the state
rates, the algebraic residuals, the force and the power dissipated by each mechanism. The rig
and the vehicle both assemble these equations; neither re-implements them.

Inputs from the outside world (`StrutInputs`):
  x        deflection [m], 0 at full extension, > 0 in compression
  v        deflection rate [m/s], > 0 in compression
  T_wall   strut body (oil, cylinder) temperature [K]
  m_gas    gas mass [kg] (constant in a sealed strut, set by the charge)
  dV_oil   oil added to the strut by a levelling system [m^3] (reduces the gas volume)
  dV_oil_rate, dT_wall_rate   their rates (gas-volume work from oil flow and expansion)
  x_mid    centre of the motion (the seed-001 band's former reversal test sgn(x - x_mid); the band now reads the
           reversal memory state stroke_dir, struts.friction.stroke_direction_rate)

Implementations: `struts.separated.SeparatedStrut` (seed 000), `struts.integrated.IntegratedStrut`
(seed 001), siblings on `struts.base.StrutBase`; `struts.model.make_strut` picks one by layout.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

# mechanisms that turn mechanical work into heat, in the order of every energy table
MECHANISMS = ("valve", "friction", "gas", "end_stop")


@dataclass(frozen=True)
class StrutInputs:
    x: object
    v: object
    T_wall: object
    m_gas: object
    dV_oil: object = 0.0
    dV_oil_rate: object = 0.0
    dT_wall_rate: object = 0.0
    x_mid: object = 0.0


@runtime_checkable
class Strut(Protocol):
    """What a strut model provides (see the module docstring)."""

    p: object       # struts.params.StrutParams (or a symbolic copy: parameters as CasADi symbols)
    gas: object     # gas properties (struts.gas)

    @property
    def state_names(self) -> tuple[str, ...]:
        """Internal differential states, e.g. ("T_gas",), ("V_gas", "p_r", "T_gas")."""

    @property
    def stiff_state_names(self) -> tuple[str, ...]:
        """The internal states with time constants far below a solver step (treated implicitly)."""

    @property
    def algebraic_names(self) -> tuple[str, ...]:
        """Algebraic variables (e.g. an incompressible strut's valve pressure drop, or the integrated strut's
        with quasi-steady chambers)."""

    @property
    def compressible(self) -> bool:
        """False when the valve pressure drop is algebraic (`valve_pressure_drop` eliminates it)."""

    def equations(self, u: StrutInputs, states: dict, dp_valve=None) -> dict:
        """rates (dict), residual (or None), force [N], gas_pressure [Pa], gas_temperature [K], and the
        power by mechanism [W]: power_valve, power_friction, power_end_stop (>= 0) and heat_gas (gas -> body),
        gas_work_rate (mechanical power into the gas)."""

    def valve_demand(self, u: StrutInputs, states: dict):
        """(flow [m^3/s] the valves pass, `struts.valves.valve_flow` arguments) of the algebraic valve balance
        valve_flow(dp_valve) = flow at one instant (struts without an algebraic dp_valve: an initial guess)."""

    def valve_pressure_drop(self, v, T_wall, dp_guess=None, newton_iterations: int = 40, warm: bool = False,
                            u: StrutInputs | None = None, states: dict | None = None):
        """dp_valve [Pa] solving the valve balance (of `valve_demand` when u and states are given; warm: a few
        Newton steps from dp_guess, for time stepping)."""

    def force_derivatives(self, u: StrutInputs, states: dict, dp_valve=None):
        """(dF/dx [N/m], dF/dv [N s/m]) at one instant (symbolic; derivative information for solvers)."""

    def initial_states(self, T_wall, x=None, m_gas=None, dV_oil=0.0) -> dict:
        """Internal states at rest."""

    def static_gas_force(self, x, T, m_gas, dV_oil=0.0, process: str | None = None):
        """Force [N] at rest (no friction, no valve) at deflection x and temperature T."""

    def end_stop_force(self, x, v):
        """(force [N], damping part [N]) of the end stops."""

    def extended_gas_volume(self, T_wall, dV_oil=0.0):
        """Gas volume at full extension [m^3]."""

    def gas_mass_for(self, pressure_Pa: float, temperature_K: float) -> float:
        """Gas mass [kg] that has `pressure_Pa` at full extension at `temperature_K`."""

    def gas_mass_carrying(self, force_N: float, x, T, process: str | None = None) -> float:
        """Gas mass [kg] whose static gas force (`static_gas_force`) at deflection x and temperature T is force_N
        (UserInputError when the gas law's range holds none)."""
