"""Physics of the seal friction laws (struts/friction.py; REFERENCE §7, seed 001 eq. 2-3, seed 000 §4.1)."""
import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hpsim.errors import UserInputError
from struts import friction as fr

F_C, K_BRK, V_S, F_V, EPS = 1000.0, 1.5, 5e-3, 50.0, 1e-5
SEAL = dict(F0_comp=1200.0, F0_reb=800.0, f_p=1e-4, K_brk=K_BRK, v_s=V_S, f_v=F_V, eps=EPS)
V = np.concatenate([-np.logspace(1, -7, 400), [0.0], np.logspace(-7, 1, 400)])


def casadi_function(fun, n_args, **kwargs):
    syms = [ca.SX.sym(f"a{i}") for i in range(n_args)]
    return ca.Function("f", syms, [fun(*syms, **kwargs)])


# --- Stribeck ---------------------------------------------------------------------------------

def test_stribeck_is_odd_and_dissipative():
    F = fr.stribeck_friction(V, F_C, K_BRK, V_S, F_V, EPS)
    np.testing.assert_allclose(fr.stribeck_friction(-V, F_C, K_BRK, V_S, F_V, EPS), -F, rtol=1e-15)
    assert np.all(fr.friction_power(F, V) >= 0)


def test_stribeck_limits():
    # |v| >> v_s: Coulomb + viscous
    v = np.array([0.2, 0.5, 1.0])
    np.testing.assert_allclose(fr.stribeck_friction(v, F_C, K_BRK, V_S, F_V, EPS), F_C + F_V * v, rtol=1e-8)
    # eps << |v| << v_s: the breakaway level F_C K_brk
    eps = 1e-9
    v = np.array([2e-3, 2e-4]) * V_S
    np.testing.assert_allclose(fr.stribeck_friction(v, F_C, K_BRK, V_S, F_V, eps), F_C * K_BRK, rtol=2e-3)
    # v -> 0: smooth, through zero
    assert fr.stribeck_friction(0.0, F_C, K_BRK, V_S, F_V, EPS) == 0.0


def test_coulomb_level_rises_with_pressure():
    assert fr.coulomb_level(10e6, 500.0, 1e-4) == pytest.approx(1500.0)
    assert fr.coulomb_level(20e6, 500.0, 1e-4) > fr.coulomb_level(10e6, 500.0, 1e-4)


# --- seal friction without band ----------------------------------------------------------------

def test_seal_friction_odd_when_symmetric():
    sym = dict(SEAL, F0_reb=SEAL["F0_comp"])
    for x in (-0.05, 0.0, 0.03):
        F = fr.seal_friction(V, x, 8e6, **sym)
        np.testing.assert_allclose(fr.seal_friction(-V, x, 8e6, **sym), -F, rtol=1e-14, atol=1e-9)


def test_seal_friction_asymmetric():
    v = np.logspace(-6, 0, 100)
    Fc = fr.seal_friction(v, 0.0, 8e6, **SEAL)
    Fr = fr.seal_friction(-v, 0.0, 8e6, **SEAL)
    assert np.all(np.abs(Fc) > np.abs(Fr))
    # far from zero each direction has its own Coulomb level
    for vv, F0 in ((1.0, SEAL["F0_comp"]), (-1.0, SEAL["F0_reb"])):
        F = fr.seal_friction(vv, 0.0, 8e6, **SEAL)
        assert F == pytest.approx(np.sign(vv) * (F0 + 1e-4 * 8e6) + F_V * vv, rel=1e-9)


def test_seal_friction_dissipative_without_band():
    for p in (0.0, 5e6, 50e6):
        for x in (-0.1, 0.0, 0.1):
            assert np.all(fr.friction_power(fr.seal_friction(V, x, p, **SEAL), V) >= 0)


def test_seal_friction_grows_with_pressure():
    v = np.array([-0.1, -1e-3, 1e-3, 0.1])
    F_lo = fr.seal_friction(v, 0.0, 5e6, **SEAL)
    F_hi = fr.seal_friction(v, 0.0, 40e6, **SEAL)
    assert np.all(np.abs(F_hi) > np.abs(F_lo))


# --- hysteresis band (seed 001 eq. 3) ----------------------------------------------------------

def seed001_sharp(v, x, F_c, F_s, k, mu_v, v_h):
    """Seed 001 eq. 2-3 as printed (one parameter set), sharp sign and switches."""
    s = np.sign(v)
    eq2 = mu_v * v + F_c * s + F_s * np.exp(-k * np.abs(v)) * s
    eq3 = mu_v * v + F_c * (2 * v / v_h - s) + F_s * ((1 + np.exp(-k * v_h)) * v / v_h - s)
    return np.where((x * v < 0) & (np.abs(v) < v_h), eq3, eq2)


BAND = dict(SEAL, F0_reb=SEAL["F0_comp"], f_p=0.0, v_h_comp=8e-3, v_h_reb=8e-3, eps_x=1e-5)


def test_band_reproduces_seed001_eq3():
    F_c = BAND["F0_comp"]
    v = np.concatenate([-np.linspace(12e-3, 1e-3, 60), np.linspace(1e-3, 12e-3, 60)])
    v = v[np.abs(np.abs(v) - 8e-3) > 1e-4]        # away from the smoothed band edge
    for x in (-0.02, 0.02):
        F = fr.seal_friction(v, x, 0.0, **BAND)
        ref = seed001_sharp(v, x, F_c, F_c * (K_BRK - 1), 1 / V_S, F_V, 8e-3)
        np.testing.assert_allclose(F, ref, rtol=2e-3, atol=0.5)


def test_band_odd_symmetry_and_continuity():
    x = np.linspace(-0.01, 0.01, 41)[:, None]
    v = np.linspace(-0.02, 0.02, 801)[None, :]
    F = fr.seal_friction(v, x, 0.0, **BAND)
    np.testing.assert_allclose(fr.seal_friction(-v, -x, 0.0, **BAND), -F, rtol=1e-12, atol=1e-8)
    # force keeps its sign through the reversal at x != 0 (no drop to zero as without band)
    F_rev = fr.seal_friction(np.array([-1e-4, 0.0, 1e-4]), 0.02, 0.0, **BAND)
    assert np.all(F_rev > 0.4 * K_BRK * BAND["F0_comp"])


def test_band_off_outside_and_when_zero():
    v = np.concatenate([-np.logspace(0, np.log10(8e-3), 50), np.logspace(np.log10(8e-3), 0, 50)])
    for x in (-0.03, 0.03):
        np.testing.assert_array_equal(fr.seal_friction(v, x, 0.0, **BAND),
                                      fr.seal_friction(v, x, 0.0, **dict(BAND, v_h_comp=0.0, v_h_reb=0.0)))
    # v_h given as symbols with value 0: same as no band
    f = casadi_function(lambda v, x, a, b: fr.seal_friction(v, x, 0.0, **dict(BAND, v_h_comp=a, v_h_reb=b)), 4)
    for vv in (-1e-3, -1e-6, 0.0, 2e-6, 4e-3):
        assert float(f(vv, 0.02, 0.0, 0.0)) == pytest.approx(
            float(fr.seal_friction(vv, 0.02, 0.0, **dict(BAND, v_h_comp=0.0, v_h_reb=0.0))), rel=1e-13, abs=1e-12)


def test_band_requires_eps_x():
    with pytest.raises(UserInputError, match="eps_x"):
        fr.seal_friction(0.0, 0.0, 0.0, **dict(SEAL, v_h_comp=8e-3))


def _loop_integrals(v_h_comp, v_h_reb, F0_reb=SEAL["F0_comp"]):
    """Sinusoid around the mid position: ∮F dv split into |v| < v_h and outside."""
    X, w = 0.02, 2 * np.pi * 0.5
    t = np.linspace(0, 2 * np.pi / w, 400001)
    x, v = X * np.sin(w * t), X * w * np.cos(w * t)
    F = fr.seal_friction(v, x, 5e6, **dict(SEAL, F0_reb=F0_reb, v_h_comp=v_h_comp, v_h_reb=v_h_reb, eps_x=1e-5))
    dv = np.diff(v)
    Fm, vm = 0.5 * (F[1:] + F[:-1]), 0.5 * (v[1:] + v[:-1])
    v_h = max(v_h_comp, v_h_reb, 1e-12)
    inside = np.abs(vm) < v_h
    return np.sum((Fm * dv)[inside]), np.sum((Fm * dv)[~inside]), np.sum(np.abs(Fm * dv))


@pytest.mark.parametrize("v_h", [(8e-3, 8e-3), (6e-3, 12e-3)])
def test_band_loop_area_only_inside_band(v_h):
    inside, outside, scale = _loop_integrals(*v_h, F0_reb=800.0)
    assert abs(inside) > 0.05 * scale
    assert abs(outside) < 1e-4 * scale
    # without band no loop at all
    inside0, outside0, scale0 = _loop_integrals(0.0, 0.0, F0_reb=800.0)
    assert abs(inside0 + outside0) < 1e-4 * scale0


# --- LuGre ---------------------------------------------------------------------------------------

LUGRE = dict(F_c=1000.0, F_s=1500.0, v_s=5e-3, sigma0=1e6)


def lugre_stribeck(v):
    """LuGre steady-state curve g(v) sgn(v) (sigma1 drops out at steady state)."""
    return (LUGRE["F_c"] + (LUGRE["F_s"] - LUGRE["F_c"]) * np.exp(-(v / LUGRE["v_s"]) ** 2)) * np.sign(v)


@pytest.mark.parametrize("v", [-0.05, -4e-3, -5e-4, 5e-4, 2e-3, 0.02])
def test_lugre_steady_state_is_stribeck_curve(v):
    eps = 1e-7
    rhs = lambda t, z: [fr.lugre_bristle_rate(z[0], v, eps=eps, **LUGRE)]
    t_end = 40 * LUGRE["F_s"] / (LUGRE["sigma0"] * abs(v))        # many relaxation lengths
    sol = solve_ivp(rhs, (0, t_end), [0.0], method="LSODA", rtol=1e-10, atol=1e-14)
    z = sol.y[0, -1]
    dz = fr.lugre_bristle_rate(z, v, eps=eps, **LUGRE)
    F = fr.lugre_force(z, dz, v, LUGRE["sigma0"], 300.0, F_V)
    assert F == pytest.approx(lugre_stribeck(v) + F_V * v, rel=1e-6)
    assert abs(z) == pytest.approx(abs(lugre_stribeck(v)) / LUGRE["sigma0"], rel=1e-6)


def test_lugre_presliding_stiffness():
    """Tiny motions (|z| << F_c/sigma0): the bristles act as a spring of stiffness sigma0."""
    X, w, eps = 1e-7, 2 * np.pi, 1e-9        # X sigma0 = 0.1 N << F_c
    rhs = lambda t, z: [fr.lugre_bristle_rate(z[0], X * w * np.cos(w * t), eps=eps, **LUGRE)]
    t = np.linspace(0, 1, 201)
    sol = solve_ivp(rhs, (0, 1), [0.0], t_eval=t, method="LSODA", rtol=1e-10, atol=1e-16)
    x = X * np.sin(w * t)
    F = fr.lugre_force(sol.y[0], 0.0, 0.0, LUGRE["sigma0"], 0.0, 0.0)
    k = np.polyfit(x, F, 1)[0]
    assert k == pytest.approx(LUGRE["sigma0"], rel=1e-3)


def test_friction_power():
    assert fr.friction_power(100.0, 0.2) == pytest.approx(20.0)
    assert fr.friction_power(-100.0, -0.2) == pytest.approx(20.0)


# --- CasADi ---------------------------------------------------------------------------------------

def test_casadi_matches_numpy():
    rng = np.random.default_rng(3)
    v = rng.uniform(-0.03, 0.03, 30)
    x = rng.uniform(-0.02, 0.02, 30)
    p = rng.uniform(1e6, 3e7, 30)
    z = rng.uniform(-1e-3, 1e-3, 30)
    f = casadi_function(fr.stribeck_friction, 6)
    np.testing.assert_allclose([float(f(a, F_C, K_BRK, V_S, F_V, EPS)) for a in v],
                               fr.stribeck_friction(v, F_C, K_BRK, V_S, F_V, EPS), rtol=1e-13)
    for kw in (SEAL, dict(SEAL, v_h_comp=6e-3, v_h_reb=1e-2, eps_x=1e-4)):
        f = casadi_function(lambda a, b, c: fr.seal_friction(a, b, c, **kw), 3)
        np.testing.assert_allclose([float(f(a, b, c)) for a, b, c in zip(v, x, p)],
                                   fr.seal_friction(v, x, p, **kw), rtol=1e-12)
    # all parameters symbolic as well
    names = ["F0_comp", "F0_reb", "f_p", "K_brk", "v_s", "f_v", "eps", "v_h_comp", "v_h_reb", "eps_x"]
    s = [ca.SX.sym(n) for n in names]
    vs, xs, ps = ca.SX.sym("v"), ca.SX.sym("x"), ca.SX.sym("p")
    f = ca.Function("f", [vs, xs, ps] + s, [fr.seal_friction(vs, xs, ps, **dict(zip(names, s)))])
    kw = dict(SEAL, v_h_comp=6e-3, v_h_reb=1e-2, eps_x=1e-4)
    np.testing.assert_allclose([float(f(a, b, c, *[kw[n] for n in names])) for a, b, c in zip(v, x, p)],
                               fr.seal_friction(v, x, p, **kw), rtol=1e-12)
    f = casadi_function(lambda a, b: fr.lugre_bristle_rate(a, b, eps=1e-6, **LUGRE), 2)
    np.testing.assert_allclose([float(f(a, b)) for a, b in zip(z, v)],
                               fr.lugre_bristle_rate(z, v, eps=1e-6, **LUGRE), rtol=1e-12)
    f = casadi_function(fr.lugre_force, 6)
    np.testing.assert_allclose([float(f(a, 0.1, b, 1e6, 300.0, F_V)) for a, b in zip(z, v)],
                               fr.lugre_force(z, 0.1, v, 1e6, 300.0, F_V), rtol=1e-13)
