"""Drives of the 8x8 (issue 4): energy balance, symmetry, levelling, heat node, step convergence."""
import numpy as np
import pytest

from struts import gas as gaslaw
from terrain import RoadSpec, build_road
from vehicle.physics import thermal
from vehicle.physics.model import ENERGY_TERMS
from vehicle.physics.params import GRAVITY, load_vehicle
from vehicle.results.sinks import MemorySink

from tests.helpers import make_drive


def _mechanical_energy(drive, x):
    m = drive.model
    P = m.params
    ke = 0.5 * m.M * x[m.idx("dz")] ** 2 + 0.5 * P.hull.pitch_inertia * x[m.idx("dtheta")] ** 2 \
        + 0.5 * P.hull.roll_inertia * x[m.idx("dphi")] ** 2
    pe = m.M * GRAVITY * x[m.idx("z")]
    for i in range(m.n):
        ke += 0.5 * m.m_u[i] * x[m.idx(f"dw[{i}]")] ** 2
        pe += m.m_u[i] * GRAVITY * x[m.idx(f"w[{i}]")]
    return ke + pe


def _gas_internal_energy(drive, x):
    m = drive.model
    U = 0.0
    for i in range(m.n):
        s = m.struts[i]
        V = float(s.gas_volume(m.strut_deflections(x)[i], x[m.idx(f"T_oil[{i}]")], x[m.idx(f"V_oil[{i}]")]))
        mg = drive.gas_masses[i]
        U += mg * float(gaslaw.internal_energy(x[m.idx(f"T_gas[{i}]")], V / mg, s.gas, s.p.gas.eos))
    return U


@pytest.fixture(scope="module")
def drive_d():
    d = make_drive(distance_m=300.0)
    rec = MemorySink()
    x0 = d.initial_state().x.copy()
    res = d.run(rec)
    return d, rec, x0, res


def _balance(d, x0, x1):
    m = d.model
    E = {e: np.sum(x1[m.energy_index[e]] - x0[m.energy_index[e]]) for e in ENERGY_TERMS}
    dmech = _mechanical_energy(d, x1) - _mechanical_energy(d, x0)
    mech_residual = E["road_work"] + E["longitudinal_work"] - (dmech + E["tyre_work"] + E["strut_work"])
    dU = _gas_internal_energy(d, x1) - _gas_internal_energy(d, x0)
    strut_residual = E["strut_work"] - (E["valve"] + E["friction"] + E["end_stop"] + E["gas"] + dU)
    return E, mech_residual, strut_residual


def test_energy_balance_road_work_equals_dissipated_plus_stored(drive_d):
    """Work done by the road on the tyres = change of hull+wheel energy + work into the tyres
    + work into the struts; and the struts' work = valve + friction + end-stop dissipation +
    heat from the gas + change of the gas internal energy (first law, REFERENCE §6).

    Both hold exactly for the ODE; the fixed-step solver meets them to its discretisation
    error, which must shrink at second order when the step is halved."""
    d, rec, x0, res = drive_d
    E, mech, strut = _balance(d, x0, res.state.x)
    scale = E["strut_work"] + E["tyre_work"]
    assert scale > 1e4   # the road did real work (tens of kJ over 300 m of class D)
    assert abs(mech) < 5e-3 * scale
    # the gas energy equation is the least resolved part at 4 ms (its heat share is ~20 % low,
    # but that share is < 0.5 % of the dissipation): the strut balance closes to 1 % here
    assert abs(strut) < 1e-2 * E["strut_work"]
    assert E["valve"] > 0 and E["friction"] > 0
    # the gas follows the oil node of the heat network (C_oil ~ 3.5 kJ/K warms ~3 K here): while the oil
    # warms the gas takes heat from it, about its sensible heat m c dT_oil (bounded with c < 2 cv)
    m = d.model
    x1 = res.state.x
    sensible = sum(d.gas_masses[i] * float(gaslaw.cv(x1[m.idx(f"T_gas[{i}]")], 1e-2, m.struts[i].gas, "ideal"))
                   * (x1[m.idx(f"T_oil[{i}]")] - x0[m.idx(f"T_oil[{i}]")]) for i in range(m.n))
    assert sensible > 0
    assert E["gas"] > -2.0 * sensible
    # second-order convergence of the mechanical balance residual
    d2 = make_drive(distance_m=300.0, dt_s=0.002)
    x0_2 = d2.initial_state().x.copy()
    res2 = d2.run()
    E2, mech2, strut2 = _balance(d2, x0_2, res2.state.x)
    assert abs(mech2) < abs(mech) / 2.5
    assert abs(strut2) < abs(strut) / 4
    # the same two runs: the dissipated energy per strut converges with the step
    for e in ("valve", "friction"):
        assert E[e] == pytest.approx(E2[e], rel=0.01)


@pytest.mark.parametrize("anti", [0.0, 0.5])
def test_energy_balance_closes_with_a_variable_speed(anti):
    """Braking and accelerating (0.5-1.7 m/s^2) do work on the hull through the pitch moment m h a_x
    and, with an anti-dive/anti-squat linkage, through its forces (E longitudinal_work): with it
    counted the mechanical balance residual falls at second order with the step, to a small fraction
    of that work (measured, anti 0: 700 J of work, residual -183 J at 2 ms, -20 J at 1 ms; without the
    term the residual would stay near -700 J)."""
    from vehicle.engines.full import Drive
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile
    from vehicle.physics.model import VehicleModel

    road = build_road(RoadSpec(iso_class="D", length=320.0, seed=3))
    profile = SpeedProfile(np.array([0.0, 60.0, 120.0, 180.0, 240.0, 300.0]),
                           np.array([20.0, 8.0, 30.0, 6.0, 25.0, 10.0]) / 3.6)
    overrides = {"longitudinal.anti_dive": anti, "longitudinal.anti_squat": anti} if anti else None
    model = VehicleModel(load_vehicle("apc_8x8", overrides))
    out = {}
    for dt in (0.002, 0.001):
        d = Drive(model, road, DriveSettings(distance_m=300.0, speed=profile, dt_s=dt))
        x0 = d.initial_state().x.copy()
        res = d.run()
        out[dt] = _balance(d, x0, res.state.x)
    E2, mech2, _ = out[0.002]
    E1, mech1, _ = out[0.001]
    W = E1["longitudinal_work"]
    assert abs(W) > 1e-3 * (E1["strut_work"] + E1["tyre_work"])    # the term is not negligible
    assert abs(mech1) < 0.1 * abs(W)
    assert abs(mech1) < abs(mech2) / 2.5
    assert E2["longitudinal_work"] == pytest.approx(W, rel=0.02)


def test_longitudinal_work_is_zero_at_constant_speed(drive_d):
    d, rec, x0, res = drive_d
    m = d.model
    assert np.all(res.state.x[m.energy_index["longitudinal_work"]] == x0[m.energy_index["longitudinal_work"]])


def test_wheel_loads_sum_to_weight_on_average(drive_d):
    d, rec, x0, res = drive_d
    loads = rec.drive_series("wheel_load")
    W = d.model.params.total_weight()
    # instantaneous sums oscillate with the hull's vertical acceleration; their mean is the weight
    assert np.mean(np.sum(loads, axis=0)) == pytest.approx(W, rel=5e-3)


def test_symmetric_vehicle_on_identical_tracks_never_rolls():
    """Left = right road, symmetric vehicle: the roll stays at round-off.

    At the production step (4 ms) round-off asymmetry (the order of the sparse elimination is
    not mirror-symmetric) can be amplified at stiff contact events to ~1e-5 rad (0.05 mm at the
    track edge); at 1 ms it stays at round-off level."""
    road = build_road(RoadSpec(iso_class="D", length=260.0, seed=5, coherence="identical"))
    for dt, limit in ((0.001, 1e-12), (0.004, 1e-4)):
        d = make_drive(distance_m=200.0, road=road, dt_s=dt)
        rec = MemorySink()
        d.run(rec)
        assert np.max(np.abs(rec.drive_series("roll_rad"))) < limit
        T = rec.drive_series("strut_temperature_K")
        assert np.max(np.abs(T[0::2] - T[1::2])) < 1e3 * limit   # left = right, axle by axle
        assert np.max(np.abs(rec.drive_series("heave_m"))) > 1e-4      # while the hull does move


def test_per_km_statistics_are_consistent_with_the_energy_quadratures(drive_d):
    d, rec, x0, res = drive_d
    rows = rec.rows
    assert rows and rows[-1]["distance_end_m"] == pytest.approx(300.0)
    m = d.model
    total_valve = sum(r["power_valve_W"] * r["duration_s"] for r in rows)
    assert total_valve == pytest.approx(res.state.x[m.energy_index["valve"]] - x0[m.energy_index["valve"]], rel=1e-9)


def test_compensation_holds_the_nominal_deflection_after_heating():
    road = build_road(RoadSpec(flat=True, length=1000.0))
    results = {}
    for on in (False, True):
        d = make_drive(distance_m=800.0, road=road, compensation=on, initial_temperatures_K=298.15 + 45.0,
                       ambient_K=298.15 + 45.0)
        rec = MemorySink()
        res = d.run(rec)
        results[on] = (d, rec, res)
    x_nom = results[True][0].model.x_charged
    band = results[True][0].model.params.compensation.dead_band
    defl_off = results[False][1].drive_series("strut_deflection")[:, -1]
    defl_on = results[True][1].drive_series("strut_deflection")[:, -1]
    assert np.all(np.abs(defl_off - x_nom) > 2 * band)        # hot sealed struts extend a lot
    assert np.all(np.abs(defl_on - x_nom) < band + 2e-3)      # levelling brings them back
    assert np.all(results[True][1].drive_series("oil_added_m3")[:, -1] < 0)   # by draining oil
    # and the after-drive heights stay near the charged heights
    assert np.max(np.abs(results[True][2].after.axle_height_change_m)) < np.max(
        np.abs(results[False][2].after.axle_height_change_m)) / 3


def test_heat_node_steady_state_is_ambient_plus_power_over_hA():
    heat = load_vehicle("apc_8x8").heat
    h = float(thermal.convection_coefficient(heat, 5.0))
    P, T_amb = 400.0, 298.15
    # no radiation: exact first-order lag to T_amb + P / (h A)
    T = T_amb
    dt = 10.0
    for _ in range(20000):   # 55 h: ~45 time constants C/(hA)
        T += dt * thermal.temperature_rate(T, P, T_amb, h, heat.surface_area, 0.0, heat.capacity)
    assert T == pytest.approx(T_amb + P / (h * heat.surface_area), rel=1e-6)
    # with radiation the steady state is cooler, and balances exactly
    T_r = T
    for _ in range(20000):
        T_r += dt * thermal.temperature_rate(T_r, P, T_amb, h, heat.surface_area, heat.emissivity, heat.capacity)
    assert T_r < T
    assert thermal.heat_loss(T_r, T_amb, h, heat.surface_area, heat.emissivity) == pytest.approx(P, rel=1e-6)


def test_forced_convection_grows_with_speed():
    heat = load_vehicle("apc_8x8").heat
    hs = [float(thermal.convection_coefficient(heat, v)) for v in (0.0, 2.0, 5.0, 10.0)]
    assert hs[0] == pytest.approx(heat.natural_convection + 0.3 * heat.air_conductivity / heat.diameter)
    assert all(b > a for a, b in zip(hs, hs[1:]))
