"""The weighing as a measurement (issue 10 §4): bands of standing wheel loads and heights under seal friction.

Checks: the breakaway levels are the friction law's zero-velocity limit; one station (statically
determinate) against the closed-form isothermal ideal-gas hand calculation; the 8x8 band contains
the frictionless equilibrium, collapses to it without friction and scales with the friction; a
2-axle vehicle's axle loads are determinate (zero band) while its wheel loads are not; the bands
are the extremes over every friction vertex; the after-minus-before band definition.
"""
import itertools

import numpy as np
import pytest

from struts import friction as fr
from struts.model import make_strut
from struts.params import load_strut
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY, load_vehicle
from vehicle.physics.weighing import (WeighingSolver, band_datasets, band_extremes, difference_bands,
                                      static_friction_limits, station_problem)

NO_FRICTION = {"friction.F0_compression": 0.0, "friction.F0_rebound": 0.0, "friction.pressure_coefficient": 0.0}
HOT = np.array([81.8, 81.8, 76.3, 76.3, 80.3, 80.3, 77.1, 77.1]) + 273.15


def _vehicle(strut_overrides=None, **overrides):
    if strut_overrides:
        P = load_vehicle("apc_8x8")
        axles = [{**a.model_dump(), "strut_overrides": strut_overrides} for a in P.axles]
        overrides = {"axles": axles, **overrides}
    return VehicleModel(load_vehicle("apc_8x8", overrides or None))


@pytest.fixture(scope="module")
def apc():
    model = _vehicle()
    return model, WeighingSolver(model), charge_gas_masses(model)


def test_breakaway_levels_are_the_zero_velocity_limit_of_the_seal_friction_law():
    f = load_strut("apc", {"friction.F0_rebound": "1200 N"}).friction
    p = 9.1e6
    F_reb, F_comp = static_friction_limits(f, p)
    kw = dict(F0_comp=f.F0_compression, F0_reb=f.F0_rebound, f_p=f.pressure_coefficient, K_brk=f.breakaway_ratio,
              v_s=f.stribeck_velocity, f_v=0.0, eps=1e-15)
    assert fr.seal_friction(1e-10, 0.0, p, **kw) == pytest.approx(F_comp, rel=1e-6)
    assert fr.seal_friction(-1e-10, 0.0, p, **kw) == pytest.approx(-F_reb, rel=1e-6)
    assert F_comp > F_reb > 0


def test_one_station_matches_the_isothermal_ideal_gas_hand_calculation():
    """Quarter car: r (F_gas + f) = M g, f = +-K (F0 + f_p p), p V = m R T, V = V_ext - A x.

    Closed form: p = (M g / r -+ K F0) / (A +- K f_p); the hull moves by -(x - x_ref)/r; the wheel
    load is (M + m_u) g whatever the friction (statically determinate).
    """
    strut = make_strut(load_strut("apc", {"gas.eos": "ideal"}))
    f, g = strut.p.friction, strut.p.geometry
    M, m_u, r, k_t, x_ref, T = 4300.0, 450.0, 0.7, 1.0e6, 0.112, 298.15
    m_gas = strut.gas_mass_for(5.4e6, T)
    V_ext = float(strut.extended_gas_volume(T))
    R = strut.gas.R                     # J/(kg K), ideal gas
    problem = station_problem(strut, M, m_u, r, k_t, x_ref)
    F_load = M * GRAVITY / r

    def hull(p):
        x = (V_ext - m_gas * R * T / p) / g.gas_area
        return -(x - x_ref) / r

    p_nom = F_load / g.gas_area
    p_high = (F_load - f.breakaway_ratio * f.F0_compression) / (g.gas_area + f.breakaway_ratio * f.pressure_coefficient)
    p_low = (F_load + f.breakaway_ratio * f.F0_rebound) / (g.gas_area - f.breakaway_ratio * f.pressure_coefficient)
    q0 = np.array([hull(p_nom), 0.0])
    ex = band_extremes(problem, [T, m_gas, 0.0], q0)
    W = (M + m_u) * GRAVITY
    assert ex.nominal[0] == pytest.approx(W, rel=1e-12)
    assert ex.low[0] == pytest.approx(W, rel=1e-12) and ex.high[0] == pytest.approx(W, rel=1e-12)
    assert ex.nominal[1] == pytest.approx(hull(p_nom), abs=1e-9)
    assert ex.high[1] == pytest.approx(hull(p_high), abs=1e-9)
    assert ex.low[1] == pytest.approx(hull(p_low), abs=1e-9)
    # about +-r F_static / (r^2 k_strut): a few millimetres to centimetres for this strut
    assert 0.005 < ex.high[1] - ex.nominal[1] < 0.05


def test_band_contains_the_frictionless_equilibrium_and_the_weight_is_always_carried(apc):
    model, solver, masses = apc
    b = solver.bands(HOT, masses)
    eq = EquilibriumSolver(model).solve(HOT, masses)
    assert np.allclose(b["wheel_loads"]["nominal"], eq.wheel_loads_N, rtol=0, atol=1e-6)
    assert np.allclose(b["axle_heights"]["nominal"], eq.axle_height_change_m, rtol=0, atol=1e-12)
    for key in ("wheel_loads", "axle_loads", "station_heights", "axle_heights"):
        assert np.all(b[key]["low"] < b[key]["nominal"]) and np.all(b[key]["nominal"] < b[key]["high"]), key
    # the total load is statically determinate: every friction state carries the weight
    pr = solver.problem
    c = np.concatenate([HOT, masses, np.zeros(model.n)])
    q0 = np.concatenate([[eq.heave_m, eq.pitch_rad, eq.roll_rad], eq.wheel_displacement_m])
    u = np.array([1, -1, -1, 1, 1, 1, -1, 0.3])
    y = np.asarray(pr.outputs(pr.solve(u, c, q0), u, c)).ravel()
    assert np.sum(y[:model.n]) == pytest.approx(model.params.total_weight(), rel=1e-10)


def test_band_collapses_without_friction_and_scales_with_it():
    masses = None
    widths = []
    for scale in (0.0, 0.5, 1.0):
        f = load_strut("apc").friction
        model = _vehicle({"friction.F0_compression": scale * f.F0_compression,
                          "friction.F0_rebound": scale * f.F0_rebound,
                          "friction.pressure_coefficient": scale * f.pressure_coefficient})
        masses = charge_gas_masses(model) if masses is None else masses
        b = WeighingSolver(model).bands(HOT, masses)
        widths.append(np.concatenate([b[k]["high"] - b[k]["low"] for k in ("wheel_loads", "axle_heights")]))
        if scale == 0.0:
            for k in ("wheel_loads", "axle_loads"):
                assert np.allclose(b[k]["low"], b[k]["nominal"], rtol=0, atol=1e-6)
                assert np.allclose(b[k]["high"], b[k]["nominal"], rtol=0, atol=1e-6)
            for k in ("station_heights", "axle_heights"):
                assert np.allclose(b[k]["high"] - b[k]["low"], 0.0, atol=1e-10)
    # nearly linear in the friction: half the friction, half the band (within the gas law's curvature)
    assert np.allclose(widths[1], 0.5 * widths[2], rtol=0.03)


def test_indeterminate_hull_wheel_loads_carry_a_band_of_the_order_of_the_seal_force(apc):
    model, solver, masses = apc
    b = solver.bands(model.params.charging.temperature, masses)
    half = 0.5 * (b["wheel_loads"]["high"] - b["wheel_loads"]["low"])
    r_F = model.r * b["static_friction_N"]["compression"]      # seal force at the wheel
    # 8 supports, 3 hull DOF: friction patterns outside the rigid-body modes go into the loads
    assert np.all(half > 0.5 * r_F) and np.all(half < 3.0 * r_F)
    axle_half = 0.5 * (b["axle_loads"]["high"] - b["axle_loads"]["low"])
    assert np.all(axle_half > 0.2 * r_F[::2])                 # 4 axles, 2 balances: indeterminate too


def test_two_axle_vehicle_axle_loads_are_determinate_and_wheel_loads_are_not():
    P = load_vehicle("apc_8x8")
    axles = [{**P.axles[0].model_dump(), "position": p} for p in (0.0, 3.0)]
    model = VehicleModel(load_vehicle("apc_8x8", {"axles": axles, "charging.wheel_loads": ["3300 daN", "3400 daN"],
                                                  "charging.heights": ["1480 mm", "1485 mm"]}))
    masses = charge_gas_masses(model)
    b = WeighingSolver(model).bands([300.0, 330.0, 310.0, 290.0], masses)
    # vertical force and pitch moment fix both axle loads: no band
    assert np.allclose(b["axle_loads"]["high"], b["axle_loads"]["nominal"], rtol=0, atol=1e-5)
    assert np.allclose(b["axle_loads"]["low"], b["axle_loads"]["nominal"], rtol=0, atol=1e-5)
    # the warp (diagonal) mode is free: the wheel loads are not
    assert np.all(b["wheel_loads"]["high"] - b["wheel_loads"]["low"] > 500.0)


def test_bands_are_the_extremes_over_every_friction_vertex(apc):
    model, solver, masses = apc
    pr = solver.problem
    c = np.concatenate([HOT, masses, np.zeros(model.n)])
    eq = solver.frictionless.solve(HOT, masses)
    q0 = np.concatenate([[eq.heave_m, eq.pitch_rad, eq.roll_rad], eq.wheel_displacement_m])
    ex = band_extremes(pr, c, q0)
    Y = []
    for v in itertools.product((-1.0, 1.0), repeat=model.n):
        u = np.array(v)
        Y.append(np.asarray(pr.outputs(pr.solve(u, c, q0), u, c)).ravel())
    Y = np.array(Y)
    assert np.allclose(ex.high, Y.max(axis=0), rtol=0, atol=1e-6)
    assert np.allclose(ex.low, Y.min(axis=0), rtol=0, atol=1e-6)
    # interior friction states stay inside
    rng = np.random.default_rng(4)
    for _ in range(20):
        u = rng.uniform(-1, 1, model.n)
        y = np.asarray(pr.outputs(pr.solve(u, c, q0), u, c)).ravel()
        assert np.all(y <= ex.high + 1e-6) and np.all(y >= ex.low - 1e-6)


def test_solving_many_friction_states_together_is_solving_each_alone_bit_for_bit(apc):
    """`solve_many` (all rows' Newton steps at once, mapped) gives each row what its own `solve` gives, exactly: the
    corners of the box, which take different numbers of steps, and interior states."""
    model, solver, masses = apc
    pr = solver.problem
    c = np.concatenate([HOT, masses, np.full(model.n, 2e-6)])
    eq = solver.frictionless.solve(HOT, masses, np.full(model.n, 2e-6))
    q0 = np.concatenate([[eq.heave_m, eq.pitch_rad, eq.roll_rad], eq.wheel_displacement_m])
    U = np.array(list(itertools.product((-1.0, 1.0), repeat=model.n))[::5]
                 + list(np.random.default_rng(7).uniform(-1, 1, (6, model.n))) + [np.zeros(model.n)])
    Q = pr.solve_many(U, c, q0)
    alone = np.array([pr.solve(u, c, q0) for u in U])
    assert np.array_equal(Q, alone)
    assert not np.array_equal(alone[0], alone[-1])       # the states stand differently


def test_difference_band_combines_independent_weighings():
    before = {"axle_loads_low_N": [9.0], "axle_loads_high_N": [11.0], "axle_loads_nominal_N": [10.0],
              "axle_height_change_low_m": [-0.001], "axle_height_change_high_m": [0.002]}
    after = {"axle_loads_low_N": [10.5], "axle_loads_high_N": [12.0], "axle_loads_nominal_N": [11.0],
             "axle_height_change_low_m": [0.050], "axle_height_change_high_m": [0.060]}
    d = difference_bands(before, after)
    # low = after_low - before_high, high = after_high - before_low (not a difference of bands)
    assert d["dN_band_pct"][0] == pytest.approx([100 * (10.5 - 11.0) / 10.0, 100 * (12.0 - 9.0) / 10.0])
    assert d["dh_band_mm"][0] == pytest.approx([48.0, 61.0])


def test_drive_like_use_before_and_after_and_cooling_at_rest_narrows_the_band(apc):
    model, solver, masses = apc
    T0 = model.params.charging.temperature
    before, after = solver.bands(T0, masses), solver.bands(HOT, masses)
    d = difference_bands(band_datasets(before), band_datasets(after))
    dN = 100 * (after["axle_loads"]["nominal"] - before["axle_loads"]["nominal"]) / before["axle_loads"]["nominal"]
    dh = 1e3 * (after["axle_heights"]["nominal"] - before["axle_heights"]["nominal"])
    assert np.all(d["dN_band_pct"][:, 0] < dN) and np.all(dN < d["dN_band_pct"][:, 1])
    assert np.all(d["dh_band_mm"][:, 0] < dh) and np.all(dh < d["dh_band_mm"][:, 1])
    # standing while cooling by 5 K: the seals pick up the lost gas force, the lower edge moves up
    cooled = solver.bands(HOT, masses, temperatures_at_stop_K=HOT + 5.0)
    assert np.all(cooled["settling_force_N"] > 0)
    assert np.all(cooled["axle_heights"]["low"] > after["axle_heights"]["low"])
    for k in ("wheel_loads", "axle_loads", "axle_heights"):    # a sub-band of the full one
        assert np.all(cooled[k]["low"] >= after[k]["low"] - 1e-9) and np.all(cooled[k]["high"] <= after[k]["high"] + 1e-9)
    # cooling far beyond the band width leaves every seal at its compression edge: no band left
    settled = solver.bands(HOT, masses, temperatures_at_stop_K=HOT + 100.0)
    for k in ("wheel_loads", "axle_heights"):
        assert np.allclose(settled[k]["low"], settled["compression_edge"][k], atol=1e-6)
        assert np.allclose(settled[k]["high"], settled["compression_edge"][k], atol=1e-6)
