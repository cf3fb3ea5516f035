"""Physics of the valve laws (struts/valves.py; REFERENCE §7, seed 001 eq. 12)."""
import casadi as ca
import numpy as np
import pytest
from scipy.optimize import brentq

from struts import valves as V

CD, RHO, PCR, AREA = 0.7, 850.0, 2.0e4, 1.5e-5

VALVE = dict(cd=CD, rho=RHO, p_crit=PCR, bleed_area=AREA,
             check_area_max=1.0e-5, check_dp_crack=0.3e6, check_dp_full=1.0e6,
             relief_comp_area=6e-5, relief_comp_crack=4e6, relief_comp_full=6e6,
             relief_reb_area=6e-5, relief_reb_crack=6e6, relief_reb_full=8e6,
             k_leak=5e-12)
CLOSED = dict(VALVE, relief_comp_crack=1e12, relief_comp_full=2e12, relief_reb_crack=1e12, relief_reb_full=2e12)
# a valve where the blow-off paths are far larger than the bleed (hard for the solver)
WIDE = dict(VALVE, bleed_area=1e-7, relief_comp_area=1e-4, relief_reb_area=1e-4, p_crit=1e3)

Q = np.concatenate([-np.logspace(-7, -2, 301), np.logspace(-7, -2, 301)])


def casadi_eval(fun, *args, symbolic=None, **kwargs):
    """Evaluate fun with the positional args as SX symbols through a casadi.Function."""
    syms = [ca.SX.sym(f"a{i}") for i in range(len(args))]
    f = ca.Function("f", syms, [fun(*syms, **kwargs)])
    return np.array([float(f(*vals)) for vals in zip(*[np.ravel(a) for a in args])])


# --- orifice ------------------------------------------------------------------------------------

def test_orifice_flow_is_odd():
    dp = np.logspace(0, 8, 50)
    np.testing.assert_allclose(V.orifice_flow(-dp, CD, AREA, RHO, PCR), -V.orifice_flow(dp, CD, AREA, RHO, PCR),
                               rtol=1e-15)
    assert V.orifice_flow(0.0, CD, AREA, RHO, PCR) == 0.0


def test_orifice_turbulent_limit_is_bernoulli():
    dp = np.logspace(np.log10(PCR) + 3, 8, 20)          # dp >> p_cr
    q = V.orifice_flow(dp, CD, AREA, RHO, PCR)
    bernoulli = CD * AREA * np.sqrt(2.0 * dp / RHO)
    # q/q_B = (1 + (p_cr/dp)^2)^(-1/4) -> 1
    np.testing.assert_allclose(q, bernoulli, rtol=0.25 * (PCR / dp[0]) ** 2 * 1.01)


def test_orifice_laminar_limit_is_linear():
    dp = np.logspace(-2, np.log10(PCR) - 3, 20)         # dp << p_cr
    q = V.orifice_flow(dp, CD, AREA, RHO, PCR)
    conductance = CD * AREA * np.sqrt(2.0 / RHO) / np.sqrt(PCR)
    np.testing.assert_allclose(q, conductance * dp, rtol=1e-6)


def test_orifice_pressure_drop_is_exact_inverse():
    dp = np.concatenate([-np.logspace(-3, 8.5, 200), [0.0], np.logspace(-3, 8.5, 200)])
    q = V.orifice_flow(dp, CD, AREA, RHO, PCR)
    back = V.orifice_pressure_drop(q, CD, AREA, RHO, PCR)
    np.testing.assert_allclose(back, dp, rtol=1e-12, atol=0.0)
    # and the other way round
    np.testing.assert_allclose(V.orifice_flow(V.orifice_pressure_drop(Q, CD, AREA, RHO, PCR), CD, AREA, RHO, PCR),
                               Q, rtol=1e-12)


# --- valves -------------------------------------------------------------------------------------

def test_check_valve_is_one_way():
    dp = np.linspace(-5e6, 5e6, 2001)
    a = V.check_valve_area(dp, 1e-5, 0.3e6, 1e6)
    assert np.all(a[dp <= 0.3e6] == 0.0)
    np.testing.assert_allclose(a[dp >= 1e6], 1e-5, rtol=0, atol=0)
    assert np.all(np.diff(a) >= 0)


def test_relief_valve_area_ramps_between_crack_and_full():
    dp = np.linspace(-20e6, 20e6, 4001)
    a = V.relief_valve_area(dp, 6e-5, 4e6, 6e6)
    assert np.all(a[dp <= 4e6] == 0.0)
    assert np.all(a[dp >= 6e6] == 6e-5)
    inside = (dp > 4e6) & (dp < 6e6)
    assert np.all((a[inside] > 0) & (a[inside] < 6e-5))
    assert np.all(np.diff(a) >= 0)
    # rebound side: called with -dp
    ar = V.relief_valve_area(-dp, 6e-5, 4e6, 6e6)
    assert np.all(ar[dp >= -4e6] == 0.0) and np.all(ar[dp <= -6e6] == 6e-5)


def test_leakage_is_laminar():
    assert V.leakage_flow(2e6, 5e-12) == pytest.approx(1e-5)
    assert V.leakage_flow(-2e6, 5e-12) == pytest.approx(-1e-5)


@pytest.mark.parametrize("valve", [VALVE, CLOSED, WIDE])
def test_valve_flow_monotonic_and_dissipative(valve):
    dp = np.concatenate([-np.logspace(8, -2, 3000), [0.0], np.logspace(-2, 8, 3000)])
    q = V.valve_flow(dp, **valve)
    assert np.all(np.diff(q) > 0)
    assert np.all(dp * q >= 0)


def test_valve_flow_paths_add():
    """Compression with the relief valve fully open: all areas in parallel through one orifice law."""
    dp = 7e6
    total = VALVE["bleed_area"] + VALVE["check_area_max"] + VALVE["relief_comp_area"]
    expect = V.orifice_flow(dp, CD, total, RHO, PCR) + VALVE["k_leak"] * dp
    assert V.valve_flow(dp, **VALVE) == pytest.approx(expect, rel=1e-14)
    # rebound at the same |dp|: no check valve, rebound relief still partly closed (crack 6, full 8 MPa)
    assert -V.valve_flow(-dp, **VALVE) < V.valve_flow(dp, **VALVE)


@pytest.mark.parametrize("valve", [VALVE, CLOSED, WIDE], ids=["relief-open", "relief-closed", "wide"])
def test_valve_pressure_drop_residual(valve):
    dp = V.valve_pressure_drop(Q, **valve)
    q = V.valve_flow(dp, **valve)
    assert np.max(np.abs(q - Q) / np.abs(Q)) < 1e-8
    assert np.all(np.sign(dp) == np.sign(Q))
    # the relief valves are actually exercised in the relief-open cases
    if valve is not CLOSED:
        assert dp.max() > valve["relief_comp_crack"] and dp.min() < -valve["relief_reb_crack"]


def test_valve_pressure_drop_matches_brentq():
    for q in (-3e-3, -2.5e-4, -1e-6, 1e-6, 2.5e-4, 3e-3):
        ref = brentq(lambda d: V.valve_flow(d, **VALVE) - q, -1e9, 1e9, xtol=1e-9, rtol=1e-14)
        assert V.valve_pressure_drop(q, **VALVE) == pytest.approx(ref, rel=1e-9)


def test_valve_pressure_drop_bleed_only_bound():
    """The bleed-only inverse bounds |dp| from above (every other path adds flow)."""
    bound = V.orifice_pressure_drop(Q, CD, AREA, RHO, PCR)
    dp = V.valve_pressure_drop(Q, **VALVE)
    assert np.all(np.abs(dp) <= np.abs(bound) * (1 + 1e-12))


def test_valve_pressure_drop_warm_start_converges_in_few_steps():
    dp = V.valve_pressure_drop(Q, **VALVE)
    guess = dp * (1.0 + 0.02 * np.cos(np.arange(Q.size)))       # previous-step-like guess, 2 % off
    # 6 steps even when the guess straddles a valve's cracking point (second derivative jumps there)
    dp6 = V.valve_pressure_drop(Q, newton_iterations=6, dp_guess=guess, **VALVE)
    assert np.max(np.abs(V.valve_flow(dp6, **VALVE) - Q) / np.abs(Q)) < 1e-8
    # away from the cracking points 4 steps suffice
    far = (np.abs(np.abs(dp) - 6e6) > 0.3e6) & (np.abs(np.abs(dp) - 4e6) > 0.3e6)
    dp4 = V.valve_pressure_drop(Q[far], newton_iterations=4, dp_guess=guess[far], **VALVE)
    assert np.max(np.abs(V.valve_flow(dp4, **VALVE) - Q[far]) / np.abs(Q[far])) < 1e-8


# --- CasADi -------------------------------------------------------------------------------------

def test_casadi_matches_numpy():
    rng = np.random.default_rng(0)
    dp = rng.uniform(-1e7, 1e7, 40)
    np.testing.assert_allclose(casadi_eval(V.orifice_flow, dp, CD * np.ones(40), AREA * np.ones(40),
                                           RHO * np.ones(40), PCR * np.ones(40)),
                               V.orifice_flow(dp, CD, AREA, RHO, PCR), rtol=1e-13)
    q = rng.uniform(-1e-2, 1e-2, 40)
    np.testing.assert_allclose(casadi_eval(lambda x: V.orifice_pressure_drop(x, CD, AREA, RHO, PCR), q),
                               V.orifice_pressure_drop(q, CD, AREA, RHO, PCR), rtol=1e-13)
    np.testing.assert_allclose(casadi_eval(lambda x: V.check_valve_area(x, 1e-5, 0.3e6, 1e6), dp),
                               V.check_valve_area(dp, 1e-5, 0.3e6, 1e6), rtol=1e-13, atol=1e-20)
    np.testing.assert_allclose(casadi_eval(lambda x: V.relief_valve_area(x, 1e-5, 3e6, 6e6), dp),
                               V.relief_valve_area(dp, 1e-5, 3e6, 6e6), rtol=1e-13, atol=1e-20)
    np.testing.assert_allclose(casadi_eval(lambda x: V.leakage_flow(x, 5e-12), dp), V.leakage_flow(dp, 5e-12))
    np.testing.assert_allclose(casadi_eval(lambda x: V.valve_flow(x, **VALVE), dp), V.valve_flow(dp, **VALVE),
                               rtol=1e-13)


def test_casadi_pressure_drop_unrolls_with_symbolic_parameters():
    """q and the bleed area symbolic: one SX graph, same numbers, derivative = 1/(dq/ddp)."""
    q, a = ca.SX.sym("q"), ca.SX.sym("a")
    dp = V.valve_pressure_drop(q, **dict(VALVE, bleed_area=a))
    f = ca.Function("f", [q, a], [dp, ca.jacobian(dp, q)])
    for qq in Q[::25]:
        dp_c, ddp_dq = (float(v) for v in f(qq, AREA))
        assert dp_c == pytest.approx(float(V.valve_pressure_drop(qq, **VALVE)), rel=1e-12)
        h = 1e-6 * abs(dp_c)
        slope = (V.valve_flow(dp_c + h, **VALVE) - V.valve_flow(dp_c - h, **VALVE)) / (2 * h)
        assert ddp_dq * slope == pytest.approx(1.0, rel=1e-5)
