"""Longitudinal dynamics (issue 10 §3) and per-axle tyres (issue 12 §4).

Steady braking on a flat road: the settled wheel loads keep their sum (the weight) and their moment
changes by the inertial pitch moment m_total h_total a_x (whole-vehicle statics, Gillespie 1992 §2),
which for two axles is the classic dN = m a h / L; the hull pitches nose down; an anti-dive
linkage that takes the whole pitch moment leaves the struts as they stood. The drive feeds the
speed profile's acceleration and each axle's pass surface to the model.
"""
import numpy as np
import pytest

from terrain import RoadSpec, build_road
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY, load_vehicle
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.results.sinks import MemorySink
from vehicle.scenario.speed import SpeedProfile
from tests.helpers import REPO

T0 = 298.15
BRAKING = -2.5      # m/s^2


def _total_cg_height(P) -> float:
    """m_total h_total from the parameter file alone: sprung CG height and wheel centres at the loaded radius."""
    moment = P.sprung_mass() * P.hull.cg_height
    for k, axle in enumerate(P.axles):
        tyre = P.axle_tyre(k)
        h_w = tyre.radius - P.charging.wheel_loads[k] / tyre.stiffness
        moment += 2 * axle.unsprung_mass * h_w
    return moment / (P.total_weight() / GRAVITY)


def _settled(overrides=None, acceleration=BRAKING):
    model = VehicleModel(load_vehicle("apc_8x8", overrides))
    masses = charge_gas_masses(model)
    solver = EquilibriumSolver(model)
    return model, solver.solve(T0, masses), solver.solve(T0, masses, acceleration_m_s2=acceleration)


def test_steady_braking_shifts_the_loads_forward_by_the_inertial_moment():
    model, stand, brake = _settled()
    P = model.params
    dN = brake.wheel_loads_N - stand.wheel_loads_N
    m_total = P.total_weight() / GRAVITY
    h = _total_cg_height(P)
    # vertical balance: the weight is unchanged; moment balance: sum dN_i (a_i - a_cg) = m a h (+ a rearward)
    assert np.sum(brake.wheel_loads_N) == pytest.approx(P.total_weight(), rel=1e-12)
    assert np.sum(dN * (model.a - model.a_cg)) == pytest.approx(m_total * BRAKING * h, rel=1e-9)
    # nose down, front axles heavier, rear lighter, left = right
    assert brake.pitch_rad < stand.pitch_rad - 1e-3
    axle_dN = dN[0::2] + dN[1::2]
    assert axle_dN[0] > 0 and axle_dN[-1] < 0 and np.all(np.diff(axle_dN) < 0)
    np.testing.assert_allclose(dN[0::2], dN[1::2], rtol=1e-9)
    assert abs(brake.roll_rad) < 1e-12
    # accelerating: the moment reverses, the nose rises (the split over the four axles is not the mirror
    # image: the gas springs stiffen as they compress)
    _, _, accel = _settled(acceleration=-BRAKING)
    assert np.sum((accel.wheel_loads_N - stand.wheel_loads_N) * (model.a - model.a_cg)) == pytest.approx(
        -m_total * BRAKING * h, rel=1e-9)
    assert accel.pitch_rad > stand.pitch_rad + 1e-3


def test_two_axle_vehicle_has_the_classic_load_transfer_m_a_h_over_L():
    L = 3.2
    axle = {"strut": "apc", "unsprung_mass": "450 kg", "motion_ratio": 0.7}
    over = {"axles": [{"position": "0 m", **axle}, {"position": f"{L} m", **axle}],
            "charging": {"wheel_loads": ["3300 daN", "3500 daN"], "heights": ["1480 mm", "1490 mm"]},
            "longitudinal": {"drive_distribution": None, "brake_distribution": None}}
    model, stand, brake = _settled(over)
    P = model.params
    m_total = P.total_weight() / GRAVITY
    dN_front = np.sum((brake.wheel_loads_N - stand.wheel_loads_N)[:2])
    dN_rear = np.sum((brake.wheel_loads_N - stand.wheel_loads_N)[2:])
    assert dN_front == pytest.approx(-m_total * BRAKING * _total_cg_height(P) / L, rel=1e-9)
    assert dN_rear == pytest.approx(-dN_front, rel=1e-9)


def test_full_anti_dive_leaves_the_struts_as_they_stood():
    model, stand, brake = _settled({"longitudinal": {"anti_dive": 1.0}})
    P = model.params
    # the linkage takes the whole pitch moment: the struts keep their forces and deflections
    np.testing.assert_allclose(brake.strut_forces_N, stand.strut_forces_N, rtol=1e-9)
    np.testing.assert_allclose(brake.strut_deflections_m, stand.strut_deflections_m, atol=1e-9)
    # ... yet the tyres carry the same load transfer (it is whole-vehicle statics)
    dN = brake.wheel_loads_N - stand.wheel_loads_N
    assert np.sum(dN * (model.a - model.a_cg)) == pytest.approx(P.total_weight() / GRAVITY * BRAKING
                                                                 * _total_cg_height(P), rel=1e-9)
    # half the anti-dive: half the pitch on the struts (linear statics about the standing state)
    _, _, half = _settled({"longitudinal": {"anti_dive": 0.5}})
    _, _, none = _settled()
    pitch_none = none.pitch_rad - stand.pitch_rad
    pitch_full = brake.pitch_rad - stand.pitch_rad       # the hull only sinks on the tyres' compliance
    # with the struts as they stood the hull follows the wheels, which sink into their tyres by dN / k_t
    kt = model.params.tyre.stiffness
    dw = brake.wheel_displacement_m - stand.wheel_displacement_m
    np.testing.assert_allclose(dw, -dN / kt, rtol=1e-6, atol=1e-12)
    assert pitch_full == pytest.approx(-(dw[-1] - dw[0]) / (model.a[-1] - model.a[0]), rel=1e-6)
    assert abs(pitch_full) < 0.2 * abs(pitch_none)
    assert half.pitch_rad - stand.pitch_rad == pytest.approx(0.5 * (pitch_none + pitch_full), rel=0.02)
    # anti-squat does nothing under braking
    _, _, squat = _settled({"longitudinal": {"anti_squat": 1.0}})
    np.testing.assert_allclose(squat.wheel_loads_N, none.wheel_loads_N, rtol=1e-9)


def test_anti_pitch_needs_forces_on_two_axles():
    from hpsim.errors import UserInputError

    with pytest.raises(UserInputError, match="brake_distribution"):
        load_vehicle("apc_8x8", {"longitudinal": {"anti_dive": 0.3, "brake_distribution": [1, 0, 0, 0]}})
    with pytest.raises(UserInputError, match="drive_distribution"):
        load_vehicle("apc_8x8", {"longitudinal": {"drive_distribution": [1, 1]}})


def _braking_profile(v0, v1, decel):
    v = np.linspace(v0, v1, 400)
    return SpeedProfile((v0 ** 2 - v ** 2) / (2 * decel), v)


def test_a_drive_braking_on_a_flat_road_settles_to_the_static_load_transfer():
    model = VehicleModel(load_vehicle("apc_8x8"))
    decel = -BRAKING
    speed = _braking_profile(14.0, 4.0, decel)
    length = float(speed.distances_m[-1])
    road = build_road(RoadSpec(flat=True, length=length + 30.0))
    rec = MemorySink()
    d = Drive(model, road, DriveSettings(distance_m=length - 1.0, speed=speed, output_interval_s=0.1))
    # the inputs carry the profile's acceleration (within the table's piecewise-linear v(s))
    t = np.linspace(0.0, 2.0, 5)
    U = d.inputs(t)
    np.testing.assert_allclose(U[model.input_index["acceleration"]], BRAKING, rtol=0.02)
    d.run(rec)
    N = np.concatenate([b["wheel_load"] for b in rec.blocks], axis=1)
    pitch = np.concatenate([b["pitch_rad"] for b in rec.blocks])
    t = np.concatenate([b["t_s"] for b in rec.blocks])
    late = t > t[-1] - 0.5            # after ~3 s of braking: the body has settled
    N_late = N[:, late].mean(axis=1)
    masses = d.gas_masses
    stand = EquilibriumSolver(model).solve(T0, masses)
    dN = N_late - stand.wheel_loads_N
    W = model.params.total_weight()
    h = _total_cg_height(model.params)
    a = float(np.mean(speed.acceleration(d.distance_at(t[late]))))
    # whole-vehicle statics hold whatever the seal friction holds in the struts
    assert abs(np.sum(dN)) < 2e-3 * W
    assert np.sum(dN * (model.a - model.a_cg)) == pytest.approx(W / GRAVITY * a * h, rel=0.03)
    assert np.mean(pitch[late]) < stand.pitch_rad - 1e-3      # nose down


def test_constant_speed_feeds_no_acceleration_and_variable_speed_does(tmp_path):
    from vehicle.scenario.schema import prepare, read_scenario_text

    from pathlib import Path

    # the shipped variable-speed scenario, shortened (its speed is built for the drive's distance)
    path = REPO / "scenarios" / "mileage_106km_variable_speed.yaml"
    text = path.read_text().replace("distance: 106 km", "distance: 2 km")
    assert "distance: 2 km" in text
    prep = prepare(read_scenario_text(text, "v.yaml", tmp_path))
    model = VehicleModel(prep.vehicle)
    road = prep.road()
    t = np.linspace(0.0, 300.0, 3001)
    for profile, moving in ((SpeedProfile.constant(20 / 3.6), False), (prep.speed_profile, True)):
        d = Drive(model, road, DriveSettings(distance_m=1000.0, speed=profile))
        acc = d.inputs(t)[model.input_index["acceleration"]]
        if moving:
            assert np.sqrt(np.mean(acc ** 2)) > 0.05 and np.max(np.abs(acc)) < 3.0
            np.testing.assert_allclose(acc, profile.acceleration(d.distance_at(t)), rtol=1e-12)
        else:
            assert np.all(acc == 0.0)


def test_following_axles_read_their_own_pass_surface():
    spec = RoadSpec(iso_class="D", length="300 m", seed=5, passes=[{"factor": 1.0}, {"factor": 0.5}])
    road = build_road(spec)
    model = VehicleModel(load_vehicle("apc_8x8", {"tyre.contact_length": 0.0}))
    d = Drive(model, road, DriveSettings(distance_m=100.0, speed=SpeedProfile.constant(5.0)))
    t = np.linspace(2.0, 10.0, 50)
    U = d.inputs(t)
    s = d.distance_at(t)
    h = U[model.input_index["road"]]
    for i in range(model.n):
        track = "left" if i % 2 == 0 else "right"
        k = model.params.station_axle(i)
        z_first, _ = road.evaluate(s - model.a[i], track)           # the surface as built (pass 0)
        np.testing.assert_allclose(h[i], z_first * (1.0 if k == 0 else 0.5), rtol=1e-12, atol=1e-15)


def test_an_axle_with_stiffer_tyres_deflects_them_less_by_the_ratio():
    base = load_vehicle("apc_8x8")
    P = load_vehicle("apc_8x8", {"axles.0.tyre.stiffness": "2 MN/m"})     # a scenario's vehicle.overrides key
    assert P.axle_tyre(0).stiffness == 2e6 and P.axle_tyre(1).stiffness == base.tyre.stiffness
    assert P.axle_tyre(0).damping == base.tyre.damping          # the keys not given stay the vehicle's
    stiff, ref = VehicleModel(P), VehicleModel(base)
    ratio = base.tyre.stiffness / 2e6
    np.testing.assert_allclose(stiff.tyre_static_deflection[:2], ratio * ref.tyre_static_deflection[:2], rtol=1e-12)
    np.testing.assert_allclose(stiff.tyre_static_deflection[2:], ref.tyre_static_deflection[2:], rtol=1e-12)
    # the standing vehicle: tyre deflection = load / own stiffness, loads as charged
    eq = EquilibriumSolver(stiff).solve(P.charging.temperature, charge_gas_masses(stiff))
    defl = stiff.tyre_static_deflection - eq.wheel_displacement_m
    np.testing.assert_allclose(defl * np.array([t.stiffness for t in stiff.tyre]), eq.wheel_loads_N, rtol=1e-9)
    assert defl[0] == pytest.approx(ratio * defl[2] * eq.wheel_loads_N[0] / eq.wheel_loads_N[2], rel=1e-9)
    # the model's equations and stiff Jacobian use the axle's tyre: the wheel-hop row of axle 1
    import casadi as ca
    J = stiff.jacobian_function
    x0 = stiff.state_at_rest(eq, charge_gas_masses(stiff))
    p = stiff.run_parameters(charge_gas_masses(stiff), False)
    Jn = np.asarray(ca.DM(J(x0, stiff.initial_memory(), stiff.input_matrix(1)[:, 0], p)))
    Je = np.asarray(ca.DM(stiff.exact_stiff_jacobian_function(x0, stiff.initial_memory(),
                                                              stiff.input_matrix(1)[:, 0], p)))
    w, dw = stiff.idx("w[0]"), stiff.idx("dw[0]")
    assert Jn[dw, w] == pytest.approx(Je[dw, w], rel=1e-9)
    assert Jn[dw, w] < Jn[stiff.idx("dw[4]"), stiff.idx("w[4]")]     # stiffer tyre: larger restoring rate


@pytest.mark.parametrize("tyre,needle", [({"stiffness": "-1 MN/m"}, "axles.0.tyre"),
                                         ({"stifness": "1 MN/m"}, "stifness")])
def test_bad_axle_tyre_names_the_axle(tyre, needle):
    from hpsim.errors import UserInputError

    base = load_vehicle("apc_8x8")
    axles = [a.model_dump(exclude_none=True) for a in base.axles]
    axles[0]["tyre"] = tyre
    with pytest.raises(UserInputError, match=needle):
        load_vehicle("apc_8x8", {"axles": axles})


def test_a_dotted_override_into_a_list_needs_a_valid_index():
    from hpsim.errors import UserInputError

    assert load_vehicle("apc_8x8", {"axles.3.tyre.damping": "3 kN*s/m"}).axle_tyre(3).damping == 3000.0
    with pytest.raises(UserInputError, match=r"axles.4.tyre.damping: .* index 0..3"):
        load_vehicle("apc_8x8", {"axles.4.tyre.damping": "3 kN*s/m"})
