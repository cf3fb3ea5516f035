"""The linearised vehicle (vehicle.physics.linear, `hpsim vehicle response`).

Quarter car: the symmetric 2-axle vehicle with linear struts (as tests/test_vehicle_quarter_car.py)
under in-phase road input at every wheel is the 2-DOF quarter car: its heave and tyre-load
transfer functions and its bounce / wheel-hop eigenvalues are analytic.
8x8: the responses must be the modal sum over the eigenvalues of its linearisation, obey Newton's
law (the tyre-load changes accelerate the masses), excite no roll from a symmetric input, and
reach the static and the blocked-wheel limits.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from struts import friction as fr
from struts.params import load_strut
from vehicle.physics import linear
from vehicle.physics.params import load_vehicle

from tests.helpers import quarter_car_at_wheel

from .test_vehicle_quarter_car import LINEAR_STRUT


@pytest.fixture(scope="module")
def quarter():
    axles = [{"position": p, "strut": "apc", "unsprung_mass": 450.0, "motion_ratio": 0.7,
              "strut_overrides": LINEAR_STRUT} for p in (0.0, 3.0)]
    params = load_vehicle("apc_8x8", {"axles": axles, "charging.wheel_loads": ["3300 daN", "3300 daN"],
                                      "charging.heights": ["1480 mm", "1480 mm"]})
    return linear.linearise(params)


def _quarter_car(lin):
    """(k_s, c_s, k_t, c_t, m_s, m_u) at the wheel, from the strut's own laws at the equilibrium."""
    m = lin.model
    P = m.params
    from vehicle.physics.equilibrium import charge_gas_masses
    ks, cs, _ = quarter_car_at_wheel(m, lin.temperatures_K[0], charge_gas_masses(m)[0])
    return ks, cs, P.tyre.stiffness, P.tyre.damping, m.M / m.n, m.m_u[0]


def test_quarter_car_transfer_functions(quarter):
    ks, cs, kt, ct, ms, mu = _quarter_car(quarter)
    f = np.array([0.3, 0.8, 1.2, 2.0, 5.0, 9.0, 20.0])
    resp = linear.frequency_response(quarter, np.ones(quarter.model.n), f)
    for k, fk in enumerate(f):
        w = 2 * math.pi * fk
        S, Tt = ks + 1j * w * cs, kt + 1j * w * ct
        A = np.array([[-ms * w * w + S, -S], [-S, -mu * w * w + S + Tt]])
        z, wheel = np.linalg.solve(A, np.array([0.0, Tt]))
        assert resp["heave_acc"][k] == pytest.approx(-w * w * z, rel=1e-6)
        np.testing.assert_allclose(resp["tyre_load"][:, k], Tt * (1.0 - wheel), rtol=1e-6)
    np.testing.assert_allclose(np.abs(resp["pitch_acc"]) + np.abs(resp["roll_acc"]), 0.0, atol=1e-8)


def test_quarter_car_eigenvalues(quarter):
    """Bounce and in-phase wheel hop are the roots of the quarter car's characteristic polynomial."""
    ks, cs, kt, ct, ms, mu = _quarter_car(quarter)
    # det [[ms s^2 + cs s + ks, -(cs s + ks)], [-(cs s + ks), mu s^2 + (cs + ct) s + ks + kt]]
    a = np.polymul([ms, cs, ks], [mu, cs + ct, ks + kt])
    b = np.polymul([cs, ks], [cs, ks])
    roots = np.roots(np.polysub(a, np.concatenate([[0, 0], b])))
    eig = quarter.eigenvalues
    for r in roots:
        assert np.min(np.abs(eig - r)) < 1e-6 * abs(r)
    names = {md.name for md in linear.modes(quarter)}
    assert {"bounce", "pitch", "roll"} <= names


@pytest.fixture(scope="module")
def apc():
    return linear.linearise(load_vehicle("apc_8x8"), friction_velocity_m_s=0.1)


def test_8x8_response_is_the_modal_sum_of_its_eigenvalues(apc):
    lam, Phi = np.linalg.eig(apc.A)
    Psi = np.linalg.inv(Phi)
    wts = linear.axle_road_weights(apc, 1)
    f = np.array([0.5, 1.1, 1.9, 4.0, 8.0, 15.0])
    resp = linear.frequency_response(apc, wts, f)
    iz = apc.index("dz")
    for k, fk in enumerate(f):
        s = 2j * math.pi * fk
        b = (apc.B_road + s * apc.B_rate) @ wts
        X = Phi @ ((Psi @ b) / (s - lam))
        assert resp["heave_acc"][k] == pytest.approx(s * X[iz], rel=1e-8)
    # the oscillatory modes are stable, and the heave response peaks at a hull mode
    assert np.all(lam.real < 0)
    fine = np.linspace(0.3, 4.0, 371)
    peak = fine[np.argmax(np.abs(linear.frequency_response(apc, np.ones(apc.model.n), fine)["heave_acc"]))]
    hull = [md for md in linear.modes(apc) if md.name in ("bounce", "pitch")]
    assert min(abs(peak - md.frequency_hz) for md in hull) < 0.35


def test_8x8_newton_symmetry_and_limits(apc):
    m = apc.model
    P = m.params
    wts = linear.axle_road_weights(apc, 0)
    f = np.array([1e-3, 0.7, 1.5, 3.0, 8.0, 60.0])
    resp = linear.frequency_response(apc, wts, f)
    # Newton: the summed tyre-load change accelerates hull and wheels; same for the pitch moment
    s = 2j * math.pi * f
    X = np.linalg.solve(s[:, None, None] * np.eye(len(apc.A)) - apc.A,
                        ((apc.B_road[None] + s[:, None, None] * apc.B_rate[None]) @ wts)[..., None])[..., 0]
    wheel_acc = s[:, None] * X[:, [apc.index(f"dw[{i}]") for i in range(m.n)]]
    total = m.M * resp["heave_acc"] + wheel_acc @ m.m_u
    np.testing.assert_allclose(resp["tyre_load"].sum(axis=0), total, rtol=1e-6, atol=1e-6 * np.abs(total).max())
    lever = -(m.a - m.a_cg)
    pitch = P.hull.pitch_inertia * resp["pitch_acc"] + (wheel_acc * m.m_u) @ lever
    np.testing.assert_allclose(resp["tyre_load"].T @ lever, pitch, rtol=1e-6, atol=1e-6 * np.abs(pitch).max())
    # a symmetric input excites no roll
    assert np.max(np.abs(resp["roll_acc"])) < 1e-9 * np.max(np.abs(resp["pitch_acc"]))
    # static limit: the hull follows, its acceleration vanishes and the weight is unchanged
    assert abs(resp["heave_acc"][0]) < 1e-4
    assert abs(resp["tyre_load"][:, 0].sum()) < 1e-3 * abs(resp["tyre_load"][0, 0])
    # blocked wheel: far above wheel hop the excited tyre only sees the road
    kt, ct = P.tyre.stiffness, P.tyre.damping
    assert abs(resp["tyre_load"][0, -1]) == pytest.approx(abs(kt + 2j * math.pi * 60.0 * ct), rel=0.05)
    assert set(resp["seat_acc"]) == {st.name for st in P.seats}


def test_equivalent_friction_is_the_describing_function():
    """The equivalent-linear strut's friction slope at rest equals the first harmonic of the seal
    friction law at the velocity amplitude V: 2 (F_C,comp + F_C,reb) / (pi V)."""
    V, p = 0.1, 8e6
    P = load_vehicle("apc_8x8")
    f0 = load_strut("apc").friction
    eq = linear.equivalent_friction_params(P, V)
    f1 = load_strut(eq.axles[0].strut, eq.axles[0].strut_overrides).friction

    def law(fp, v):
        return fr.seal_friction(v, 0.0, p, F0_comp=fp.F0_compression, F0_reb=fp.F0_rebound, f_p=fp.pressure_coefficient,
                                K_brk=fp.breakaway_ratio, v_s=fp.stribeck_velocity, f_v=fp.viscous,
                                eps=fp.smoothing_velocity)

    h = 1e-6
    slope = (law(f1, h) - law(f1, -h)) / (2 * h)
    psi = np.linspace(0, 2 * np.pi, 200001)
    first_harmonic = np.trapezoid(law(f0, V * np.sin(psi)) * np.sin(psi), psi) / (np.pi * V)
    coulomb = 2 * (f0.F0_compression + f0.F0_rebound + 2 * f0.pressure_coefficient * p) / (np.pi * V)
    assert slope == pytest.approx(coulomb, rel=1e-6)
    assert slope == pytest.approx(first_harmonic, rel=0.01)
