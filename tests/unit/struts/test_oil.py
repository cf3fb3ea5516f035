"""Physics of the oil and emulsion laws (struts/oil.py; REFERENCE §7, seed 000 eq. 6, seed 001 eq. 8-11)."""
import casadi as ca
import numpy as np
import pytest

from struts import oil

C0 = 273.15
# ISO VG 32 hydraulic oil datasheet points
T40, NU40, T100, NU100 = 40 + C0, 32e-6, 100 + C0, 5.4e-6


def casadi_eval(fun, *args):
    syms = [ca.SX.sym(f"a{i}") for i in range(len(args))]
    f = ca.Function("f", syms, [fun(*syms)])
    return np.array([float(f(*vals)) for vals in zip(*[np.ravel(a) for a in args])])


# --- viscosity ----------------------------------------------------------------------------------

def test_walther_round_trip_iso_vg32():
    A, B = oil.walther_coefficients(T40, NU40, T100, NU100)
    np.testing.assert_allclose(oil.walther_kinematic_viscosity(np.array([T40, T100]), A, B), [NU40, NU100],
                               rtol=1e-12)


def test_walther_is_a_straight_line_on_the_astm_chart():
    """ASTM D341 chart: log10 log10(nu_cSt + 0.7) linear in log10 T, falling (viscosity drops with T)."""
    A, B = oil.walther_coefficients(T40, NU40, T100, NU100)
    assert B > 0
    T = np.linspace(C0 - 10, C0 + 120, 27)
    nu = oil.walther_kinematic_viscosity(T, A, B)
    assert np.all(np.diff(nu) < 0)
    Z = np.log10(np.log10(nu * 1e6 + 0.7))
    slope, icpt = np.polyfit(np.log10(T), Z, 1)
    assert slope == pytest.approx(-B, rel=1e-12) and icpt == pytest.approx(A, rel=1e-12)
    # a VG 32 mineral oil is ~ 300-600 cSt at 0 °C and ~ 10-11 cSt at 75 °C on a D341 chart
    assert 300e-6 < float(oil.walther_kinematic_viscosity(C0, A, B)) < 600e-6
    assert 9e-6 < float(oil.walther_kinematic_viscosity(C0 + 75, A, B)) < 12e-6


# --- density, bulk modulus, thermal expansion -----------------------------------------------

def test_density_falls_with_temperature_at_rate_alpha():
    rho_ref, T_ref, alpha = 850.0, 295.15, 1.07e-3        # seed 001 Table 1
    assert oil.oil_density(T_ref, rho_ref, T_ref, alpha) == rho_ref
    h = 1e-3
    slope = (oil.oil_density(T_ref + h, rho_ref, T_ref, alpha) - oil.oil_density(T_ref - h, rho_ref, T_ref, alpha)) / (2 * h)
    assert slope == pytest.approx(-alpha * rho_ref, rel=1e-6)


def test_bulk_modulus_falls_8_MPa_per_K():
    beta = oil.oil_bulk_modulus(np.array([293.15, 303.15, 323.15]), 1.7e9, 293.15, 8e6)
    np.testing.assert_allclose(np.diff(beta) / np.diff([293.15, 303.15, 323.15]), -8e6, rtol=1e-12)
    assert beta[0] == pytest.approx(1.7e9)


def test_thermal_expansion_conserves_oil_mass_and_feeds_gas_space():
    V_ref, T_ref, beta = 2.14e-3, 293.15, 8e-4           # seed 000 eq. 6 / REFERENCE §1
    T = np.linspace(263.15, 373.15, 12)
    V = oil.oil_volume(T, V_ref, T_ref, beta)
    np.testing.assert_allclose(V - V_ref, oil.thermal_expansion_into_gas(T, V_ref, T_ref, beta), rtol=1e-9,
                               atol=1e-18)
    # with alpha = beta the density law and the volume law keep the oil mass constant
    np.testing.assert_allclose(oil.oil_density(T, 850.0, T_ref, beta) * V, 850.0 * V_ref, rtol=1e-14)
    # seed 000: 54 K warmer -> the gas loses beta V dT ~ 92 cm^3
    assert oil.thermal_expansion_into_gas(T_ref + 54, V_ref, T_ref, beta) == pytest.approx(92.4e-6, rel=1e-3)


# --- emulsion (seed 001 eq. 8-11) -------------------------------------------------------------

P0, G0, N, BETA_H, RHO_H = 2.0e6, 0.006, 1.4, 1.7e9, 850.0


def test_gas_fraction_at_reference_and_compression():
    assert oil.emulsion_gas_fraction(P0, P0, G0, N, BETA_H) == pytest.approx(G0, rel=1e-15)
    p = np.linspace(0.5e6, 20e6, 40)
    g = oil.emulsion_gas_fraction(p, P0, G0, N, BETA_H)
    assert np.all(np.diff(g) < 0)
    # gas part polytropic: (gamma (1 - dp/beta)) p^(1/n) constant
    np.testing.assert_allclose(g * (1 - (p - P0) / BETA_H) * p ** (1 / N), G0 * P0 ** (1 / N), rtol=1e-12)


def test_emulsion_density_conserves_mass():
    """Oil mass rho_h V_h0 in V_h (1 + gamma) at every pressure (gas mass neglected, seed 001 eq. 10)."""
    V_h0 = 1e-3
    p = np.linspace(0.5e6, 30e6, 30)
    g = oil.emulsion_gas_fraction(p, P0, G0, N, BETA_H)
    V_total = (1 - (p - P0) / BETA_H) * V_h0 * (1 + g)
    np.testing.assert_allclose(oil.emulsion_density(p, P0, RHO_H, BETA_H, g) * V_total, RHO_H * V_h0, rtol=1e-14)
    assert oil.emulsion_density(P0, P0, RHO_H, BETA_H, 0.0) == RHO_H


def test_emulsion_bulk_modulus_limits():
    p = 5e6
    assert oil.emulsion_bulk_modulus(p, 0.0, N, BETA_H) == pytest.approx(BETA_H, rel=1e-15)
    assert oil.emulsion_bulk_modulus(p, 1e-9, N, BETA_H) == pytest.approx(BETA_H, rel=1e-6)
    assert oil.emulsion_bulk_modulus(p, 1e9, N, BETA_H) == pytest.approx(N * p, rel=1e-6)
    # a little gas softens the oil drastically: 1 % gas at 5 MPa -> about 30 % of the oil modulus
    assert oil.emulsion_bulk_modulus(p, 0.01, N, BETA_H) < 0.35 * BETA_H


def test_emulsion_bulk_modulus_is_minus_V_dp_dV():
    """Gas (polytropic) and oil (beta_h) compliances in series: beta = -V dp/dV of eq. 8 volumes at p0."""
    V_h0 = 1e-3
    V = lambda p: (1 - (p - P0) / BETA_H) * V_h0 + (P0 / p) ** (1 / N) * G0 * V_h0
    h = 1.0
    beta_fd = -V(P0) * 2 * h / (V(P0 + h) - V(P0 - h))
    assert oil.emulsion_bulk_modulus(P0, G0, N, BETA_H) == pytest.approx(beta_fd, rel=1e-7)


# --- CasADi ------------------------------------------------------------------------------------

def test_casadi_matches_numpy():
    rng = np.random.default_rng(5)
    T = rng.uniform(250, 400, 20)
    p = rng.uniform(0.5e6, 40e6, 20)
    g = rng.uniform(0, 0.1, 20)
    A, B = oil.walther_coefficients(T40, NU40, T100, NU100)
    checks = [
        (lambda t: oil.walther_kinematic_viscosity(t, A, B), (T,), oil.walther_kinematic_viscosity(T, A, B)),
        (lambda t: oil.oil_density(t, 850.0, 293.15, 1e-3), (T,), oil.oil_density(T, 850.0, 293.15, 1e-3)),
        (lambda t: oil.oil_bulk_modulus(t, 1.7e9, 293.15, 8e6), (T,), oil.oil_bulk_modulus(T, 1.7e9, 293.15, 8e6)),
        (lambda t: oil.oil_volume(t, 2e-3, 293.15, 8e-4), (T,), oil.oil_volume(T, 2e-3, 293.15, 8e-4)),
        (lambda t: oil.thermal_expansion_into_gas(t, 2e-3, 293.15, 8e-4), (T,),
         oil.thermal_expansion_into_gas(T, 2e-3, 293.15, 8e-4)),
        (lambda q: oil.emulsion_gas_fraction(q, P0, G0, N, BETA_H), (p,), oil.emulsion_gas_fraction(p, P0, G0, N, BETA_H)),
        (lambda q, x: oil.emulsion_density(q, P0, RHO_H, BETA_H, x), (p, g), oil.emulsion_density(p, P0, RHO_H, BETA_H, g)),
        (lambda q, x: oil.emulsion_bulk_modulus(q, x, N, BETA_H), (p, g), oil.emulsion_bulk_modulus(p, g, N, BETA_H)),
    ]
    for fun, args, expect in checks:
        np.testing.assert_allclose(casadi_eval(fun, *args), expect, rtol=1e-13)
    # Walther coefficients from symbolic datasheet points
    s = [ca.SX.sym(n) for n in ("T1", "n1", "T2", "n2")]
    f = ca.Function("f", s, list(oil.walther_coefficients(*s)))
    np.testing.assert_allclose([float(v) for v in f(T40, NU40, T100, NU100)], [A, B], rtol=1e-13)
