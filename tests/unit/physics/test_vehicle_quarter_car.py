"""Linear limit (issue 4): the 2-axle vehicle, linearised, against the analytic quarter car.

Symmetric vehicle (equal loads, CG midway), identical in-phase road input at every wheel: only
bounce is excited and each corner is a quarter car with sprung mass M/4. The struts are made
linear: no seal friction, a laminar bleed orifice only (linear damping: critical Reynolds
number far above the test's flows), polytropic gas (a linear spring for small amplitudes).
The heave transfer function |z/r|(f) must match the 2-DOF analytic one built from the same
parameters: k_s = r^2 dF_gas/dx, c_s = r^2 A_v^2 / (dq/ddp at 0), tyre k_t, c_t.
"""
import math

import numpy as np
import pytest

from terrain import RoadSpec, build_road
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile
from vehicle.physics.model import VehicleModel
from vehicle.physics.params import load_vehicle

from tests.helpers import quarter_car_at_wheel

LINEAR_STRUT = {
    "friction.F0_compression": 0.0, "friction.F0_rebound": 0.0, "friction.pressure_coefficient": 0.0,
    "friction.breakaway_ratio": 1.0, "friction.viscous": 0.0,
    "gas.process": "polytropic", "gas.polytropic_exponent": 1.4,
    "valve.check_area_max": 0.0, "valve.relief_comp_area": 0.0, "valve.relief_reb_area": 0.0,
    "valve.bleed_area": 7.5e-5, "valve.critical_reynolds": 5e4,
}


@pytest.fixture(scope="module")
def setup():
    axles = [{"position": p, "strut": "apc", "unsprung_mass": 450.0, "motion_ratio": 0.7,
              "strut_overrides": LINEAR_STRUT} for p in (0.0, 3.0)]
    params = load_vehicle("apc_8x8", {"axles": axles,
                                      "charging.wheel_loads": ["3300 daN", "3300 daN"],
                                      "charging.heights": ["1480 mm", "1480 mm"]})
    model = VehicleModel(params)
    road = build_road(RoadSpec(flat=True, length=100.0))
    settings = DriveSettings(distance_m=50.0, speed=SpeedProfile.constant(5.0), dt_s=0.001,
                             output_interval_s=0.01, samples_per_block=100,
                             ambient_K=params.charging.temperature,
                             initial_temperatures_K=params.charging.temperature)
    drive = Drive(model, road, settings)
    return model, drive


def analytic_heave(model, drive, f_hz):
    P = model.params
    ks, cs, c_strut = quarter_car_at_wheel(model, P.charging.temperature, drive.gas_masses[0])
    kt, ct = P.tyre.stiffness, P.tyre.damping
    ms, mu = model.M / model.n, model.m_u[0]
    w = 2 * math.pi * f_hz
    S, Tt = ks + 1j * w * cs, kt + 1j * w * ct
    # [ms s^2 + S, -S; -S, mu s^2 + S + Tt] [z; w] = [0; Tt r]
    A = np.array([[-ms * w * w + S, -S], [-S, -mu * w * w + S + Tt]])
    z, _ = np.linalg.solve(A, np.array([0.0, Tt]))
    return abs(z), c_strut


@pytest.mark.parametrize("f_hz", [0.7, 1.2, 3.0, 8.0])
def test_linear_quarter_car_matches_transfer_function(setup, f_hz):
    model, drive = setup
    amp = 1e-3
    st = drive.initial_state()
    x = st.x.copy()
    drive.solver.set_state(st.solver_memory)
    K, M, dt = drive.K, drive.M, drive.settings.dt_s
    periods_settle = 8 if f_hz > 1 else 5
    t_end = max(periods_settle / f_hz, 6.0) + 3.0 / f_hz
    n_calls = int(math.ceil(t_end / (K * M * dt)))
    w = 2 * math.pi * f_hz
    t0, ts, zs = 0.0, [], []
    for _ in range(n_calls):
        t = t0 + dt * np.arange(K * M + 1)
        U = np.zeros((model.nu, t.size))
        U[: model.n] = amp * np.sin(w * t)
        U[model.n: 2 * model.n] = amp * w * np.cos(w * t)
        U[2 * model.n] = 5.0
        U[2 * model.n + 1] = model.params.charging.temperature
        X = drive.solver.advance(x, U, drive.p)
        x = X[:, -1].copy()
        ts.append(t0 + dt * K * np.arange(1, M + 1))
        zs.append(X[model.idx("z")])
        t0 += dt * K * M
    t, z = np.concatenate(ts), np.concatenate(zs)
    last = t > t[-1] - 3.0 / f_hz
    G = np.column_stack([np.sin(w * t[last]), np.cos(w * t[last]), np.ones(last.sum())])
    a, b, _ = np.linalg.lstsq(G, z[last], rcond=None)[0]
    expected, c_strut = analytic_heave(model, drive, f_hz)
    # the damping really is in the linear (laminar) range and the test is not trivially stiff
    assert 5e3 < c_strut < 1e5
    assert math.hypot(a, b) / amp == pytest.approx(expected, rel=0.005)
