"""Static equilibrium and charging of the 8x8 (issue 4): conservation, moments, exact charging."""
import numpy as np
import pytest

from hpsim.errors import UserInputError
from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses, equilibrium_table
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import GRAVITY, load_vehicle


@pytest.fixture(scope="module")
def model():
    return VehicleModel(load_vehicle("apc_8x8"))


@pytest.fixture(scope="module")
def solver(model):
    return EquilibriumSolver(model)


def test_charging_reproduces_requested_loads_and_heights_exactly(model, solver):
    masses = charge_gas_masses(model)
    eq = solver.solve(model.params.charging.temperature, masses)
    assert np.allclose(eq.wheel_loads_N, model.charged_wheel_loads, rtol=0, atol=1e-6)
    assert abs(eq.heave_m) < 1e-12 and abs(eq.pitch_rad) < 1e-12 and abs(eq.roll_rad) < 1e-12
    assert np.allclose(eq.strut_deflections_m, model.params.charging.strut_deflection, atol=1e-12)


def test_loads_sum_to_weight_and_moments_balance_for_uneven_heating(model, solver):
    masses = charge_gas_masses(model)
    rng = np.random.default_rng(1)
    T = 298.15 + rng.uniform(0.0, 60.0, model.n)
    eq = solver.solve(T, masses)
    W = model.params.total_weight()
    assert np.sum(eq.wheel_loads_N) == pytest.approx(W, rel=1e-10)
    # moments of the wheel loads about the CG of the whole vehicle vanish
    a_cg_total = (model.M * model.a_cg + np.sum(model.m_u * model.a)) / (model.M + np.sum(model.m_u))
    # the unsprung masses move with their stations: small-angle moment balance about the total CG
    assert np.sum(eq.wheel_loads_N * (model.a - a_cg_total)) == pytest.approx(0.0, abs=1e-6 * W)
    assert np.sum(eq.wheel_loads_N * model.y) == pytest.approx(0.0, abs=1e-6 * W)
    # the uneven heating actually moved the loads
    assert np.max(np.abs(eq.wheel_loads_N - model.charged_wheel_loads)) > 10.0


def test_uniform_heating_raises_the_hull_and_keeps_it_level_sideways(model, solver):
    masses = charge_gas_masses(model)
    eq0 = solver.solve(298.15, masses)
    eq = solver.solve(298.15 + 50.0, masses)
    # hotter gas and expanded oil: every strut extends, the hull rises at every axle
    assert np.all(eq.axle_height_change_m > eq0.axle_height_change_m + 0.02)
    assert abs(eq.roll_rad) < 1e-12
    table = equilibrium_table(model, eq)
    assert table["total_load_N"] == pytest.approx(model.params.total_weight(), rel=1e-10)
    assert [a["axle"] for a in table["axles"]] == [1, 2, 3, 4]


def test_one_hot_strut_takes_more_load_and_lifts_its_corner(model, solver):
    masses = charge_gas_masses(model)
    T = np.full(model.n, 298.15)
    T[0] += 40.0    # axle 1 left
    eq = solver.solve(T, masses)
    dN = eq.wheel_loads_N - model.charged_wheel_loads
    assert dN[0] > 0 and dN[1] < 0     # diagonal load transfer: hot corner heavier
    assert eq.roll_rad > 0             # left side up


@pytest.mark.parametrize("override,needle", [
    ({"hull.pitch_inertia": "-5 kg*m^2"}, "pitch_inertia"),
    ({"axles": [{"position": "0 m", "unsprung_mass": "-450 kg", "motion_ratio": 0.7},
                {"position": "3 m", "unsprung_mass": "450 kg", "motion_ratio": 0.7}]}, "unsprung_mass"),
    ({"track": "abc"}, "track"),
    ({"tyre.stiffness": "-1 MN/m"}, "tyre"),
    ({"hull": {"pitch_inertia": "1e5 kg*m^2", "roll_inertia": "2e4 kg*m^2", "mases": 3}}, "hull.mases"),
])
def test_bad_vehicle_files_fail_with_a_clear_message(override, needle):
    with pytest.raises(UserInputError) as exc:
        load_vehicle("apc_8x8", override)
    msg = str(exc.value)
    assert "apc_8x8.yaml" in msg and needle in msg


def test_missing_key_names_file_and_key(tmp_path):
    import yaml
    from vehicle.physics.params import vehicle_file

    data = yaml.safe_load(vehicle_file("apc_8x8").read_text())
    del data["tyre"]["damping"]
    path = tmp_path / "broken.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(UserInputError) as exc:
        load_vehicle(str(path))
    assert "broken.yaml" in str(exc.value) and "tyre.damping" in str(exc.value) and "Field required" in str(exc.value)


def test_a_strut_that_cannot_carry_its_load_is_reported():
    # the stroke of the strut cannot reach the charging deflection
    params = load_vehicle("apc_8x8", {"charging.strut_deflection": "300 mm"})
    with pytest.raises(UserInputError, match="outside the stroke"):
        charge_gas_masses(VehicleModel(params))
    # loads lighter than the unsprung mass cannot be carried by a gas spring
    params = load_vehicle("apc_8x8", {"charging.wheel_loads": ["300 daN", "3290 daN", "3420 daN", "3470 daN"]})
    with pytest.raises(UserInputError, match="unsprung weight"):
        charge_gas_masses(VehicleModel(params))


def test_gravity_constant_is_standard():
    assert GRAVITY == 9.80665


def test_numeric_function_is_the_casadi_evaluation_bit_for_bit(model, solver):
    """The statics functions on NumPy buffers (NumericFunction) give exactly what calling the Function gives, for a
    dense vector, a sparse Jacobian and on another thread (each thread its own buffers)."""
    import threading

    from vehicle.physics.equilibrium import NumericFunction

    masses = charge_gas_masses(model)
    rng = np.random.default_rng(3)
    points = [(rng.normal(0.0, 0.01, 3 + model.n), 290.0 + rng.uniform(0.0, 50.0, model.n),
               masses * rng.uniform(0.95, 1.05, model.n), rng.uniform(0.0, 1e-5, model.n), rng.normal(0.0, 2.0))
              for _ in range(4)]
    F, J = NumericFunction(solver.F), NumericFunction(solver.Jf)
    assert not solver.Jf.sparsity_out(0).is_dense()          # the scatter of a sparse result is exercised
    for args in points:
        assert np.array_equal(F(*args)[0], np.asarray(solver.F(*args)))
        assert np.array_equal(J(*args)[0], np.asarray(solver.Jf(*args)))
    seen = {}

    def on_thread():
        seen["J"] = [J(*args)[0] for args in points]

    worker = threading.Thread(target=on_thread)
    worker.start()
    worker.join()
    assert all(np.array_equal(a, np.asarray(solver.Jf(*args))) for a, args in zip(seen["J"], points))


def _charged_with(P, fill_pressure_offset_Pa):
    return VehicleModel(P.model_copy(update={"charging": P.charging.model_copy(
        update={"fill_pressure_offset": fill_pressure_offset_Pa})}))


def test_statics_functions_are_shared_by_vehicles_whose_standing_reads_the_same_numbers():
    """Designs that differ only in what the standing vehicle does not feel (the fill pressure sets the gas masses,
    fed to the functions) share one build of the statics functions, and it is instruction for instruction the
    build each would make alone; a vehicle with another tyre stiffness gets its own."""
    from vehicle.physics import equilibrium, weighing

    P = load_vehicle("apc_8x8")
    designs = [_charged_with(P, dp) for dp in (-0.3e6, 0.2e6, 0.4e6)]
    solvers = [EquilibriumSolver(m) for m in designs]
    problems = [weighing.WeighingSolver(m).problem for m in designs]
    assert solvers[1].F is solvers[2].F and solvers[1].Jf is solvers[2].Jf and problems[1] is problems[2]
    for m, s, pr in zip(designs, solvers, problems):
        alone = equilibrium.equilibrium_functions(m)
        assert all(s_f.serialize() == alone[k].serialize() for k, s_f in (("F", s.F), ("Jf", s.Jf), ("out", s.out)))
        own = weighing.weighing_problem(m)
        assert pr.residual.serialize() == own.residual.serialize() and pr.sens.serialize() == own.sens.serialize()
    stiffer = P.tyre.model_copy(update={"stiffness": 1.3 * P.tyre.stiffness})
    stiff_tyre = VehicleModel(P.model_copy(update={"charging": designs[2].params.charging, "tyre": stiffer}))
    other = EquilibriumSolver(stiff_tyre)
    assert other.F is not solvers[2].F
    masses = charge_gas_masses(stiff_tyre)
    assert not np.allclose(other.solve(320.0, masses).wheel_displacement_m,
                           solvers[2].solve(320.0, masses).wheel_displacement_m, rtol=0, atol=1e-9)
