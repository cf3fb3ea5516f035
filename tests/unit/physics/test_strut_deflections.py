"""`VehicleModel.strut_deflections` (every station in one array operation: the drive's stroke check and error
estimate call it on every block) gives `station_motion`'s deflection of each station (hull.py's station
displacement and strut deflection) bit for bit, on a block of states and on one state."""
from __future__ import annotations

import numpy as np
import pytest

from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle


class _Named:
    def __init__(self, X, layout):
        self.X, self.layout = X, layout

    def __getitem__(self, name):
        return self.X[self.layout.index(name)]


@pytest.mark.parametrize("vehicle", ["apc_8x8", "truck_6x6", "light_4x4_integrated"])
def test_strut_deflections_equal_each_stations_motion(vehicle):
    model = VehicleModel(load_vehicle(vehicle))
    X = np.random.default_rng(7).normal(scale=0.05, size=(model.nx, 6))
    each = np.array([model.station_motion(_Named(X, model.layout), i)[0] for i in range(model.n)])
    together = model.strut_deflections(X)
    assert together.shape == (model.n, 6)
    np.testing.assert_array_equal(together, each)
    np.testing.assert_array_equal(model.strut_deflections(X[:, 2]), each[:, 2])
    # a pure heave of the hull by dz compresses every strut by its motion ratio times -dz (the wheels held)
    heave = np.zeros(model.nx)
    heave[model.layout.index("z")] = 0.01
    np.testing.assert_allclose(model.strut_deflections(heave) - model.strut_deflections(np.zeros(model.nx)),
                               -0.01 * model.r, rtol=1e-12)
