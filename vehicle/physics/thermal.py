"""Strut heat: a thermal network per strut (docs/physics.md "Strut heat network").

Nodes (states of the vehicle model, per station i):
  T_oil      the oil (capacity C_oil): heated by the damping valve and by the gas, whose own
             temperature state (the strut's T_gas, energy-equation gas model, REFERENCE §6)
             relaxes to the oil through the floating piston with the strut file's
             gas.thermal_time_constant; the strut sees T_oil as its `StrutInputs.T_wall`
             (oil expansion, viscosity, the gas's heat-exchange partner)
  T_wall     the steel that the oil wets: the bore side of the cylinder wall with the piston,
             rod and end caps (capacity C_wall); heated by seal friction (the seal rubs on it)
             and by the end stops (their bumpers sit on the cylinder ends: our choice, the
             end-stop power is ~0 on the mileage road); loses heat into the mounts
  T_surface  the outer skin of the cylinder (capacity C_surface): what a pyrometer reads; loses
             heat to the local air (convection) and surroundings (radiation)

Heat flows [W]:
  oil -> wall      h_oil A_wet (T_oil - T_wall), h_oil = natural convection in the oil
                   (Churchill & Chu 1975, vertical surface, Incropera eq. 9.26) mixed with the
                   forced part from stroking (Dittus & Boelter 1930, Incropera eq. 8.60, the oil
                   column moving at the strut velocity along the bore) as
                   h = (h_nat^3 + h_forced^3)^(1/3) (Churchill 1977 mixed convection, Incropera
                   eq. 9.38, n = 3); times oil_film_multiplier (prior: the correlations are
                   extrapolated to an oscillating laminar flow with valve jets)
  wall -> surface  conduction through the cylindrical shell, R = ln(r_o/r_i) / (2 pi k L)
                   (Incropera eq. 3.33), L = A_surface / (pi D) (the area-equivalent length)
  wall -> mounts   G_mount (T_wall - T_local): the hull and wheel-carrier eyes, whose large
                   steel masses sit at the local air temperature
  surface -> air   h_out A (T_s - T_local) + eps sigma F A (T_s^4 - T_local^4): forced convection
                   over a cylinder in cross flow (Churchill & Bernstein 1977, Incropera eq. 7.54)
                   at air_speed_ratio x vehicle speed plus natural convection (or a given film
                   coefficient), radiation with view factor F to the ambient (the rest of the
                   hemisphere sees the tyre, the arch and the hull, taken at the strut's own
                   temperature: no net exchange)
  external         a local heat source [W] (engine, exhaust, brakes) onto the surface

Stiffness: the network's states are slow states of the ROS2 solver (explicit trapezoid, W = I).
With the apc_8x8 defaults the fastest eigenvalue is the wall-surface pair,
lambda = (1/C_wall + 1/C_surface) / R_shell = (1/25.2k + 1/6.3k)/8.1e-4 ~ 0.24 1/s (tau ~ 4 s,
1000 steps of 4 ms); the oil node's tau = C_oil/(h_oil A_wet) ~ 3.5k/(110 x 0.2) ~ 160 s.
Even with heat.capacity at 2 kJ/K (the tests' fast-heating override) tau_min ~ 0.2 s, 50 steps:
far inside the explicit method's stability (h lambda < 2). tests/test_thermal_network.py checks
the fastest time constant of the shipped network.
"""
from __future__ import annotations

from types import SimpleNamespace

from hpsim import symbolic as sym

STEFAN_BOLTZMANN = 5.670374419e-8  # W/(m^2 K^4), CODATA 2018
GRAVITY = 9.80665                  # m/s^2, standard gravity
PI = 3.141592653589793
# numerical smoothing (not physics): |dT| in the Rayleigh number and |v| in the Reynolds number
# are sqrt(x^2 + eps^2), which keeps their derivatives finite at zero
DT_SMOOTHING_K = 0.1
V_SMOOTHING_M_S = 1e-3


# --- outside: air ---------------------------------------------------------------------------
def churchill_bernstein_h(air_speed_m_per_s, diameter_m, k_air, nu_air, prandtl):
    """Mean forced-convection coefficient [W/(m^2 K)] of a cylinder in cross flow.

    Nu = 0.3 + 0.62 Re^(1/2) Pr^(1/3) / (1 + (0.4/Pr)^(2/3))^(1/4) (1 + (Re/282000)^(5/8))^(4/5)
    (Churchill & Bernstein 1977). Re -> 0 leaves the conduction term 0.3, which the natural
    convection coefficient dominates anyway.
    """
    Re = sym.fabs(air_speed_m_per_s) * diameter_m / nu_air
    Nu = 0.3 + 0.62 * sym.sqrt(Re) * prandtl ** (1.0 / 3.0) / (1.0 + (0.4 / prandtl) ** (2.0 / 3.0)) ** 0.25 \
        * (1.0 + (Re / 282000.0) ** 0.625) ** 0.8
    return Nu * k_air / diameter_m


def heat_loss(T_K, T_amb_K, h_conv, area_m2, emissivity, view_factor=1.0):
    """Heat flow [W] from a surface to ambient: convection + radiation (view factor to the ambient)."""
    radiation = emissivity * view_factor * STEFAN_BOLTZMANN * area_m2 * (T_K ** 4 - T_amb_K ** 4)
    return h_conv * area_m2 * (T_K - T_amb_K) + radiation


def temperature_rate(T_K, P_dissipated_W, T_amb_K, h_conv, area_m2, emissivity, capacity_J_per_K):
    """dT/dt [K/s] of a single lumped node (the network's limit when its
    internal resistances vanish, tests/test_thermal_network.py)."""
    return (P_dissipated_W - heat_loss(T_K, T_amb_K, h_conv, area_m2, emissivity)) / capacity_J_per_K


def convection_coefficient(heat, vehicle_speed_m_per_s, air_speed_ratio=None, film_coefficient=None):
    """Outside convective h [W/(m^2 K)] at a vehicle speed: natural + forced (wheel-bay air speed
    = air_speed_ratio x vehicle speed), or a given film coefficient; times convection_multiplier."""
    if film_coefficient is not None:
        return heat.convection_multiplier * film_coefficient
    ratio = heat.air_speed_ratio if air_speed_ratio is None else air_speed_ratio
    forced = churchill_bernstein_h(ratio * vehicle_speed_m_per_s, heat.diameter,
                                   heat.air_conductivity, heat.air_kinematic_viscosity, heat.air_prandtl)
    return heat.convection_multiplier * (heat.natural_convection + forced)


# --- inside: oil ----------------------------------------------------------------------------
def churchill_chu_h(dT_K, length_m, k, nu, alpha, beta, prandtl_shape=None):
    """Natural convection [W/(m^2 K)] on a vertical surface of height L, all Rayleigh numbers
    (Churchill & Chu 1975; Incropera eq. 9.26):
    Nu = (0.825 + 0.387 Ra^(1/6) / (1 + (0.492/Pr)^(9/16))^(8/27))^2, Ra = g beta |dT| L^3/(nu alpha).

    prandtl_shape: the Pr of the weak shape factor (1 + (0.492/Pr)^(9/16))^(8/27), 1.008-1.02 for an
    oil's Pr = 60-350; default nu/alpha. The vehicle passes the oil's Pr at its reference temperature
    (a run constant: the factor is then computed once per run instead of twice per step and station;
    h differs from the exact factor's by at most 2.2 % over 20-100 degC, far inside the oil film
    prior; tests/test_thermal_network.py). Ra^(1/6) is computed as (Ra^2)^(1/12): |dT| smoothed
    without a square root. Both save powers in the compiled step."""
    Pr = nu / alpha if prandtl_shape is None else prandtl_shape
    Ra2 = (GRAVITY * beta * length_m ** 3 / (nu * alpha)) ** 2 * (dT_K * dT_K + DT_SMOOTHING_K ** 2)
    Nu = (0.825 + 0.387 * Ra2 ** (1.0 / 12.0) / (1.0 + (0.492 / Pr) ** (9.0 / 16.0)) ** (8.0 / 27.0)) ** 2
    return Nu * k / length_m


def dittus_boelter_h(speed_m_per_s, diameter_m, k, nu, alpha):
    """Forced convection [W/(m^2 K)] of a flow at `speed` in a duct of hydraulic diameter D
    (Dittus & Boelter 1930, heating of the wall: Nu = 0.023 Re^0.8 Pr^0.4; Incropera eq. 8.60).
    Stated for Re > 1e4: the stroking flow (Re ~ 1e3) is outside it, covered by the oil film prior.
    Re^0.8 Pr^0.4 = (v^2 D^2 / (nu alpha))^0.4: one power, |v| smoothed."""
    v2 = speed_m_per_s * speed_m_per_s + V_SMOOTHING_M_S ** 2
    return 0.023 * (v2 * diameter_m * diameter_m / (nu * alpha)) ** 0.4 * k / diameter_m


def mixed_convection_h(h_natural, h_forced):
    """(h_n^3 + h_f^3)^(1/3) (Churchill 1977; Incropera eq. 9.38, n = 3)."""
    return (h_natural ** 3 + h_forced ** 3) ** (1.0 / 3.0)


def oil_prandtl(heat, nu_oil, rho_oil):
    """Prandtl number of the oil: nu rho c_p / k."""
    return nu_oil * rho_oil * heat.oil_specific_heat / heat.oil_conductivity


def oil_film_coefficient(heat, T_oil_K, T_wall_K, strut_velocity_m_s, nu_oil, rho_oil, beta_oil,
                         prandtl_shape=None):
    """Oil-side film coefficient [W/(m^2 K)]: natural convection mixed with the stroking flow; the oil
    properties (nu_oil, rho_oil from the strut file) at the bulk oil temperature, not the film's (a few
    kelvin apart, within the oil film prior; the strut's valve already evaluates them there).
    prandtl_shape: see churchill_chu_h."""
    alpha = heat.oil_conductivity / (rho_oil * heat.oil_specific_heat)
    h_nat = churchill_chu_h(T_oil_K - T_wall_K, heat.oil_column_height, heat.oil_conductivity, nu_oil, alpha,
                            beta_oil, prandtl_shape)
    h_forced = dittus_boelter_h(strut_velocity_m_s, heat.bore_diameter, heat.oil_conductivity, nu_oil, alpha)
    return heat.oil_film_multiplier * mixed_convection_h(h_nat, h_forced)


def shell_resistance(r_inner_m, r_outer_m, conductivity, length_m):
    """Conduction resistance [K/W] of a cylindrical shell: ln(r_o/r_i) / (2 pi k L) (Incropera eq. 3.33)."""
    return sym.log(r_outer_m / r_inner_m) / (2.0 * PI * conductivity * length_m)


def wall_resistance(heat):
    """The strut's wall -> surface resistance [K/W] (bore to outer diameter, area-equivalent length)."""
    length = heat.surface_area / (PI * heat.diameter)
    return shell_resistance(0.5 * heat.bore_diameter, 0.5 * heat.diameter, heat.wall_conductivity, length)


def capacities(heat):
    """(C_oil, C_wall, C_surface) [J/K]: heat.capacity split by oil_capacity_fraction and, of the
    steel, surface_capacity_fraction."""
    C_oil = heat.capacity * heat.oil_capacity_fraction
    steel = heat.capacity - C_oil
    C_surface = steel * heat.surface_capacity_fraction
    return C_oil, steel - C_surface, C_surface


# --- the environment of a station --------------------------------------------------------------
ENVIRONMENT_KEYS = ("air_speed_ratio", "film_coefficient", "ambient_offset", "view_factor", "heat_source")


def station_environment(heat, axle_heat=None) -> SimpleNamespace:
    """The heat environment of a station: the vehicle's default (`heat`) with the axle's overrides
    (`axles[k].heat`, vehicle.physics.params.AxleHeat; None fields keep the default). A film
    coefficient (given by the axle or by default) replaces natural + forced outside convection;
    an axle giving air_speed_ratio uses the correlation even if the default gives a film coefficient."""
    env = {k: getattr(heat, k) for k in ENVIRONMENT_KEYS}
    if axle_heat is not None:
        for k in ENVIRONMENT_KEYS:
            v = getattr(axle_heat, k)
            if v is not None:
                env[k] = v
        if axle_heat.air_speed_ratio is not None and axle_heat.film_coefficient is None:
            env["film_coefficient"] = None
    return SimpleNamespace(**env)


# --- the network ---------------------------------------------------------------------------------
def network_flows(heat, env, T_oil, T_wall, T_surface, T_ambient, vehicle_speed, strut_velocity,
                  nu_oil, rho_oil, beta_oil, prandtl_shape=None) -> dict:
    """Internal and external heat flows [W] of one strut's network (module docstring)."""
    T_local = T_ambient + env.ambient_offset
    h_oil = oil_film_coefficient(heat, T_oil, T_wall, strut_velocity, nu_oil, rho_oil, beta_oil, prandtl_shape)
    h_out = convection_coefficient(heat, vehicle_speed, env.air_speed_ratio, env.film_coefficient)
    return dict(
        oil_to_wall=h_oil * heat.wetted_area * (T_oil - T_wall),
        wall_to_surface=(T_wall - T_surface) / wall_resistance(heat),
        wall_to_mounts=heat.mount_conductance * (T_wall - T_local),
        surface_to_air=heat_loss(T_surface, T_local, h_out, heat.surface_area, heat.emissivity, env.view_factor),
        external=env.heat_source + 0.0 * T_surface,
        h_oil=h_oil, h_out=h_out,
    )


def network_rates(heat, flows: dict, power_valve, power_friction, power_end_stop, heat_gas):
    """(dT_oil/dt, dT_wall/dt, dT_surface/dt) [K/s] from the heat flows and the strut's powers [W]:
    valve and gas heat into the oil, seal friction and end stops into the wall."""
    C_oil, C_wall, C_surface = capacities(heat)
    dT_oil = (power_valve + heat_gas - flows["oil_to_wall"]) / C_oil
    dT_wall = (power_friction + power_end_stop + flows["oil_to_wall"] - flows["wall_to_surface"]
               - flows["wall_to_mounts"]) / C_wall
    dT_surface = (flows["wall_to_surface"] + flows["external"] - flows["surface_to_air"]) / C_surface
    return dT_oil, dT_wall, dT_surface


def heat_lost(flows: dict):
    """Heat leaving the strut [W]: to the air and the mounts, less the local source."""
    return flows["surface_to_air"] + flows["wall_to_mounts"] - flows["external"]


NODES = ("oil", "wall", "surface")
