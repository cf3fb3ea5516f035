"""The strut heat network (issue 10 §1-2; vehicle.physics.thermal): steady state against hand-computed
resistances, energy conservation over a drive, collapse to the single lumped node, stiffness, and the
per-axle heat environment."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import brentq, fsolve

from hpsim.errors import UserInputError
from struts.model import make_strut
from struts.params import load_strut
from terrain import RoadSpec, build_road
from vehicle.physics import thermal
from vehicle.physics.params import load_vehicle
from vehicle.results.sinks import MemorySink

from tests.helpers import make_drive

SIGMA = 5.670374419e-8
T_AMB = 298.15


@pytest.fixture(scope="module")
def heat():
    return load_vehicle("apc_8x8").heat


@pytest.fixture(scope="module")
def strut():
    return make_strut(load_strut("apc"))


def _oil_props(strut, T_oil, T_wall):
    """Oil properties as the model passes them: at the oil temperature."""
    return float(strut.oil_viscosity(T_oil)), float(strut.oil_density(T_oil)), strut.p.oil.expansion


def _prandtl_shape(heat, strut):
    """The model's Pr of the natural-convection shape factor: the oil at its reference temperature."""
    return float(thermal.oil_prandtl(heat, strut.oil_viscosity(strut.p.oil.reference_temperature), strut.p.oil.density))


def _rates(heat, env, strut, T, speed, v, P_valve, P_fric, Q_gas, P_stop=0.0):
    flows = thermal.network_flows(heat, env, T[0], T[1], T[2], T_AMB, speed, v, *_oil_props(strut, T[0], T[1]),
                                  _prandtl_shape(heat, strut))
    return np.array([float(r) for r in thermal.network_rates(heat, flows, P_valve, P_fric, P_stop, Q_gas)]), flows


def test_steady_state_matches_hand_computed_resistances(heat, strut):
    """Valve + gas heat into the oil, friction into the wall: at steady state the oil-wall, wall-surface and
    surface-air differences follow from resistances written out here by hand (not with thermal.py's helpers)."""
    env = thermal.station_environment(heat)
    P_valve, P_fric, Q_gas, speed, v = 150.0, 60.0, 10.0, 20 / 3.6, 0.15
    T = fsolve(lambda T: _rates(heat, env, strut, T, speed, v, P_valve, P_fric, Q_gas)[0] * 1e4,
               np.full(3, T_AMB + 40.0), xtol=1e-13)
    T_oil, T_wall, T_s = T
    # outside: Churchill-Bernstein at air_speed_ratio x 5.56 m/s over the 0.13 m cylinder + 5 W/m2K natural; radiation
    # to the ambient with the view factor
    Re = heat.air_speed_ratio * speed * heat.diameter / heat.air_kinematic_viscosity
    Pr = heat.air_prandtl
    Nu = 0.3 + 0.62 * Re ** 0.5 * Pr ** (1 / 3) / (1 + (0.4 / Pr) ** (2 / 3)) ** 0.25 * (1 + (Re / 282000) ** 0.625) ** 0.8
    h_out = heat.natural_convection + Nu * heat.air_conductivity / heat.diameter
    A = heat.surface_area

    def q_out(Ts):
        return h_out * A * (Ts - T_AMB) + heat.emissivity * env.view_factor * SIGMA * A * (Ts ** 4 - T_AMB ** 4)

    # wall: cylindrical shell from the 0.11 m bore to the 0.13 m outside, area-equivalent length
    L = A / (math.pi * heat.diameter)
    R_wall = math.log(heat.diameter / heat.bore_diameter) / (2 * math.pi * heat.wall_conductivity * L)
    assert R_wall == pytest.approx(8.0e-4, rel=0.02)          # REFERENCE §10: < 0.01 K/W
    total = P_valve + P_fric + Q_gas
    # all heat leaves through the surface and the mounts: total = q_out(Ts) + G (T_wall - T_amb)
    Ts_hand = brentq(lambda Ts: q_out(Ts) + heat.mount_conductance * (Ts + q_out(Ts) * R_wall - T_AMB) - total,
                     T_AMB, T_AMB + 300)
    Tw_hand = Ts_hand + q_out(Ts_hand) * R_wall
    # oil side: Churchill-Chu natural convection mixed (n = 3) with Dittus-Boelter at the strut velocity
    nu, rho, beta = _oil_props(strut, T_oil, T_wall)
    alpha = heat.oil_conductivity / (rho * heat.oil_specific_heat)
    dT = T_oil - T_wall
    Ra = 9.80665 * beta * math.sqrt(dT ** 2 + 0.1 ** 2) * heat.oil_column_height ** 3 / (nu * alpha)
    Pr_o = nu / alpha
    Pr_ref = strut.oil_viscosity(strut.p.oil.reference_temperature) * strut.p.oil.density * heat.oil_specific_heat \
        / heat.oil_conductivity
    h_nat = (0.825 + 0.387 * Ra ** (1 / 6) / (1 + (0.492 / Pr_ref) ** (9 / 16)) ** (8 / 27)) ** 2 \
        * heat.oil_conductivity / heat.oil_column_height
    Re_o = math.sqrt(v ** 2 + 1e-6) * heat.bore_diameter / nu
    h_f = 0.023 * Re_o ** 0.8 * Pr_o ** 0.4 * heat.oil_conductivity / heat.bore_diameter
    R_oil = 1.0 / ((h_nat ** 3 + h_f ** 3) ** (1 / 3) * heat.oil_film_multiplier * heat.wetted_area)
    assert T_s == pytest.approx(Ts_hand, abs=1e-6)
    assert T_wall == pytest.approx(Tw_hand, abs=1e-6)
    assert T_oil - T_wall == pytest.approx((P_valve + Q_gas) * R_oil, rel=1e-6)
    # the oil is several kelvin above the surface the pyrometer sees; the wall barely differs from it
    assert 3.0 < T_oil - T_s < 20.0 and 0 < T_wall - T_s < 0.5


def test_oil_film_coefficient_lies_in_the_reference_prior(heat, strut):
    """REFERENCE §10: oil-side film coefficient 60-150 W/m2K (natural convection plus laminar stroking)."""
    for T_oil, dT, v in ((330.0, 5.0, 0.05), (350.0, 10.0, 0.15), (320.0, 15.0, 0.3)):
        h = float(thermal.oil_film_coefficient(heat, T_oil, T_oil - dT, v, *_oil_props(strut, T_oil, T_oil - dT)))
        assert 60.0 < h < 150.0
    # the shape factor's Pr at the reference temperature (the model's run constant) against the exact one
    Pr_ref = _prandtl_shape(heat, strut)
    for T_oil in (293.15, 333.15, 373.15):
        props = _oil_props(strut, T_oil, T_oil - 10.0)
        exact = float(thermal.oil_film_coefficient(heat, T_oil, T_oil - 10.0, 0.0, *props))
        assert float(thermal.oil_film_coefficient(heat, T_oil, T_oil - 10.0, 0.0, *props, Pr_ref)) == \
            pytest.approx(exact, rel=0.025)     # 2.2 % at 100 degC, inside the oil film prior (0.6-1.5)
    # stroking adds to natural convection
    h0 = float(thermal.oil_film_coefficient(heat, 340.0, 330.0, 0.0, *_oil_props(strut, 340.0, 330.0)))
    h1 = float(thermal.oil_film_coefficient(heat, 340.0, 330.0, 0.5, *_oil_props(strut, 340.0, 330.0)))
    assert h1 > h0


def test_network_collapses_to_the_single_node_as_internal_resistances_vanish(heat, strut):
    """Oil film and wall conduction -> infinite conductance, no mounts, view factor 1: the three nodes move as
    the old lumped node C dT/dt = P - hA (T - T_amb) - eps sigma A (T^4 - T_amb^4) on the same input."""
    stiff = heat.model_copy(update={"oil_film_multiplier": 1e4, "wall_conductivity": 1e6, "mount_conductance": 0.0,
                                    "view_factor": 1.0})
    env = thermal.station_environment(stiff)
    speed, v = 20 / 3.6, 0.15

    def power(t):          # a varying dissipation, split between the mechanisms
        P = 300.0 + 100.0 * math.sin(t / 900.0)
        return 0.6 * P, 0.3 * P, 0.1 * P     # valve, friction, gas

    def network(t, T, h=stiff, e=env):
        Pv, Pf, Qg = power(t)
        return _rates(h, e, strut, T, speed, v, Pv, Pf, Qg)[0]

    h_conv = float(thermal.convection_coefficient(heat, speed))

    def single(t, T):
        return [float(thermal.temperature_rate(T[0], sum(power(t)), T_AMB, h_conv, heat.surface_area,
                                               heat.emissivity, heat.capacity))]

    t_end = 4 * 3600.0
    t_eval = np.linspace(0, t_end, 41)
    net = solve_ivp(network, (0, t_end), np.full(3, T_AMB), method="Radau", t_eval=t_eval, rtol=1e-9, atol=1e-9)
    one = solve_ivp(single, (0, t_end), [T_AMB], method="Radau", t_eval=t_eval, rtol=1e-9, atol=1e-9)
    assert one.y[0, -1] - T_AMB > 30.0
    for k in range(3):
        np.testing.assert_allclose(net.y[k], one.y[0], atol=0.02)
    # ...while the shipped resistances (with the same environment) separate the oil from the surface
    real = heat.model_copy(update={"mount_conductance": 0.0, "view_factor": 1.0})
    full = solve_ivp(lambda t, T: network(t, T, real, thermal.station_environment(real)), (0, t_end),
                     np.full(3, T_AMB), method="Radau", t_eval=t_eval, rtol=1e-9, atol=1e-9)
    assert full.y[0, -1] - full.y[2, -1] > 3.0


def test_fastest_time_constant_is_far_above_the_step(heat, strut):
    """The network's states are explicit (slow) states of the 4 ms ROS2 step: its fastest eigenvalue must be
    far below 1/step (thermal.py docstring: tau_min ~ 4 s, the wall-surface pair)."""
    env = thermal.station_environment(heat)
    T0 = np.array([340.0, 330.0, 329.5])
    J = np.empty((3, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = 1e-4
        J[:, k] = (_rates(heat, env, strut, T0 + d, 5.5, 0.15, 0, 0, 0)[0]
                   - _rates(heat, env, strut, T0 - d, 5.5, 0.15, 0, 0, 0)[0]) / 2e-4
    lam = np.linalg.eigvals(J)
    assert np.all(lam.real < 0)
    tau_min = 1.0 / np.max(-lam.real)
    assert 1.0 < tau_min < 20.0          # ~4 s: 1000 steps of 4 ms (and not absurdly slow)


def test_energy_is_conserved_over_a_drive():
    """Dissipated (valve + friction + gas + end stops) = stored in the oil, wall and surface nodes + lost to
    the air and the mounts, within integration error. Ambient 20 K below the struts: the losses are large."""
    d = make_drive(distance_m=150.0, initial_temperatures_K=T_AMB + 20.0, ambient_K=T_AMB, output_interval_s=0.1)
    m, P = d.model, d.model.params
    x0 = d.initial_state().x.copy()
    rec = MemorySink()
    res = d.run(rec)
    x1 = res.state.x
    dissipated = sum(np.sum(x1[m.energy_index[e]] - x0[m.energy_index[e]]) for e in ("valve", "friction", "gas",
                                                                                      "end_stop"))
    C = dict(zip(thermal.NODES, thermal.capacities(P.heat)))
    stored = sum(C[nd] * np.sum(x1[d.node_index[nd]] - x0[d.node_index[nd]]) for nd in thermal.NODES)
    t = np.concatenate([[0.0], rec.drive_series("t_s")])
    speed = np.concatenate([[rec.drive_series("speed_m_per_s")[0]], rec.drive_series("speed_m_per_s")])
    Ts = np.hstack([x0[d.T_index][:, None], rec.drive_series("strut_temperature_K")])
    Tw = np.hstack([x0[d.T_wall_index][:, None], rec.drive_series("wall_temperature_K")])
    env = thermal.station_environment(P.heat)
    h = np.array([float(thermal.convection_coefficient(P.heat, s, env.air_speed_ratio)) for s in speed])
    loss = thermal.heat_loss(Ts, T_AMB, h, P.heat.surface_area, P.heat.emissivity, env.view_factor) \
        + P.heat.mount_conductance * (Tw - T_AMB)
    lost = float(np.sum(np.trapezoid(loss, t, axis=1)))
    assert dissipated > 2e4 and lost > 5e3 and abs(stored) > 5e3
    print(f"dissipated {dissipated:.1f} J, stored {stored:.1f} J, lost {lost:.1f} J, "
          f"residual {(dissipated - stored - lost) / dissipated:.2e}")
    assert dissipated == pytest.approx(stored + lost, rel=1e-5)     # ~5e-9 measured


def test_per_axle_environment_overrides_and_validation():
    base = load_vehicle("apc_8x8")
    P = load_vehicle("apc_8x8", {"axles": [dict(a) for a in _axles_with_heat(
        {3: {"heat_source": "150 W", "ambient_offset": "5 K", "view_factor": 0.3},
         1: {"film_coefficient": "25 W/(m^2*K)"}})]})
    envs = [thermal.station_environment(P.heat, ax.heat) for ax in P.axles]
    assert envs[0] == thermal.station_environment(base.heat)         # defaults identical for all axles
    assert envs[2] == envs[0]
    assert envs[3].heat_source == 150.0 and envs[3].ambient_offset == 5.0 and envs[3].view_factor == 0.3
    assert envs[3].air_speed_ratio == base.heat.air_speed_ratio
    assert envs[1].film_coefficient == 25.0
    assert float(thermal.convection_coefficient(P.heat, 10.0, envs[1].air_speed_ratio, envs[1].film_coefficient)) == 25.0
    for bad, word in (({"air_speed_ratio": 0.1, "film_coefficient": 20.0}, "not both"),
                      ({"view_factor": 1.5}, "view_factor"), ({"heat_source": "-5 W"}, "heat_source"),
                      ({"ambient_offset": "400 K"}, "ambient_offset"), ({"bogus": 1}, "bogus")):
        with pytest.raises(UserInputError, match=word):
            load_vehicle("apc_8x8", {"axles": _axles_with_heat({0: bad})})


def _axles_with_heat(per_axle: dict) -> list:
    from hpsim.config import load_yaml
    from vehicle.physics.params import vehicle_file

    axles = load_yaml(vehicle_file("apc_8x8"))["axles"]
    return [{**a, "heat": per_axle[k]} if k in per_axle else a for k, a in enumerate(axles)]


def test_a_local_heat_source_warms_only_its_axle():
    """Per-station environment in the model: a 300 W source on axle 4 heats its surfaces; the rest stay
    identical (flat road, all struts alike)."""
    road = build_road(RoadSpec(flat=True, length=400.0))
    over = {"axles": _axles_with_heat({3: {"heat_source": "300 W"}})}
    d = make_drive(distance_m=300.0, road=road, overrides=over, output_interval_s=0.5)
    res = d.run()
    T = res.state.x[d.T_index] - T_AMB
    assert np.all(T[6:] > 0.2 + np.max(T[:6]))
    np.testing.assert_allclose(T[:6], T[0], atol=1e-6)


def test_scenario_overrides_reach_an_axles_heat_environment():
    """A scenario sets one axle's environment by dotted override; a bad value names the key and its range."""
    from vehicle.scenario.schema import prepare, read_scenario_text

    text = """\
description: per-axle heat
vehicle: {name: apc_8x8, overrides: {axles.3.heat.heat_source: 150 W, axles.0.heat: {view_factor: 0.3}}}
road: {iso_class: D, seed: 1}
speed: 20 km/h
distance: 0.1 km
ambient_temperature: 25 degC
"""
    V = prepare(read_scenario_text(text, "s.yaml", ".")).vehicle
    assert V.axles[3].heat.heat_source == 150.0 and V.axles[0].heat.view_factor == 0.3
    assert V.axles[1].heat is None and V.axles[2].heat is None
    with pytest.raises(UserInputError, match=r"axles.3.heat: view_factor must be in \[0, 1\]"):
        prepare(read_scenario_text(text.replace("heat_source: 150 W", "view_factor: 1.5"), "s.yaml", "."))
