"""The equivalent linear vehicle at several friction velocity amplitudes from one model
(vehicle.physics.linear.EquivalentLinearVehicles, what the multiscale proxy's matching asks for):

- at each amplitude V it equals `linearise(params, friction_velocity_m_s=V)` bit for bit, though it builds the
  vehicle once and sets V as the struts' friction smoothing in the run parameters;
- the Jacobians read into NumPy buffers (`equilibrium.NumericFunction`, as `linear._model_jacobians` reads them)
  equal CasADi's DM outputs converted element by element,
  at a state away from rest (non-zero valve pressure drops, every sparsity pattern exercised).
"""
from __future__ import annotations

import numpy as np
import pytest

from vehicle.physics import linear
from vehicle.physics.equilibrium import EquilibriumSolver, NumericFunction, charge_gas_masses
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle

MATRICES = ("A", "B_road", "B_rate", "C_tyre", "D_tyre_road", "D_tyre_rate", "C_velocity", "D_velocity_road",
            "D_velocity_rate", "static_wheel_loads_N", "temperatures_K")


@pytest.fixture(scope="module")
def vehicle():
    params = load_vehicle("apc_8x8")
    model = VehicleModel(linear.equivalent_friction_params(params, 0.1))
    gas = charge_gas_masses(VehicleModel(params))
    T = np.array([318.0, 318.0, 313.0, 313.0, 308.0, 308.0, 303.0, 303.0])
    return params, model, gas, T, EquilibriumSolver(model).solve(T, gas)


def test_each_amplitude_equals_its_own_linearisation_bit_for_bit(vehicle):
    params, model, gas, T, eq = vehicle
    family = linear.EquivalentLinearVehicles(model, T, gas, eq)
    damping = []
    for V in (0.1, 0.027, 0.43):
        got = family.at(V)
        alone = linear.linearise(params, T, friction_velocity_m_s=V, gas_masses=gas, equilibrium=eq)
        for name in MATRICES:
            assert np.array_equal(getattr(got, name), getattr(alone, name)), name
        assert got.states == alone.states and got.friction_velocity_m_s == V
        damping.append(np.max(np.linalg.eigvals(got.A).real))
    assert len(set(damping)) == 3                      # V changes the vehicle (c_eq = 4 F_C / (pi V))
    with pytest.raises(ValueError):
        family.at(0.0)


def test_buffered_jacobians_equal_the_dm_outputs_away_from_rest(vehicle):
    params, model, gas, T, eq = vehicle
    J = linear.jacobian_graph(model)
    rng = np.random.default_rng(1)
    x = model.state_at_rest(eq, gas) * (1.0 + 1e-3 * rng.standard_normal(model.nx))
    z = 1e4 * rng.standard_normal(model.nz)
    u = model.input_matrix(1, speed=5.0, ambient=300.0, road=0.01 * rng.standard_normal((model.n, 1)))[:, 0]
    p = model.run_parameters(gas, False)
    got = NumericFunction(J)(x, z, u, p)
    want = [np.asarray(v, float) for v in J(x, z, u, p)]
    assert len(got) == len(want) == J.n_out()
    for g, w in zip(got, want):
        assert g.shape == w.shape and np.array_equal(g, w)
    assert any(np.count_nonzero(w) < w.size for w in want)     # sparse outputs among them
