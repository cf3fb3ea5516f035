"""Road statistics: honesty of the fit's standard errors (Monte Carlo), IRI against the quarter-car response."""
from __future__ import annotations

import numpy as np
import pytest

from terrain import Road, RoadSpec, build_road, road_statistics
from terrain import stats
from terrain.envelope import envelope_transfer


def test_standard_errors_are_honest():
    """The tolerances of the PSD tests are multiples of the fit's standard errors, so check them:
    over 16 independent 10 km class C roads the scatter of ln Gd(n0) and of w must agree with
    the predicted se. With 16 samples a sample standard deviation is known to ±18 % (1σ);
    accept a ratio between 0.5 and 1.6 (a wrong variance model, e.g. ignoring the Hann bin
    correlation, would be off by a factor ~1.4-2)."""
    lg, w, se_g, se_w = [], [], [], []
    for seed in range(100, 116):
        st = road_statistics(build_road(RoadSpec(iso_class="C", length="10 km", seed=seed)), iri=False)
        lg.append(np.log(st["gd_n0_m3"] / 256e-6))
        w.append(st["waviness"])
        se_g.append(st["gd_n0_rel_se"])
        se_w.append(st["waviness_se"])
    r_g = np.std(lg, ddof=1) / np.mean(se_g)
    r_w = np.std(w, ddof=1) / np.mean(se_w)
    assert 0.5 < r_g < 1.6, r_g
    assert 0.5 < r_w < 1.6, r_w
    # and no bias: the mean of 16 is within 4 standard errors of the truth
    assert abs(np.mean(lg)) < 4 * np.mean(se_g) / 4.0
    assert abs(np.mean(w) - 2.0) < 4 * np.mean(se_w) / 4.0


def _golden_car_gain(n):
    """|d(z_s - z_u)/dt| per unit profile amplitude at spatial frequency n (continuous 2-DOF model,
    Sayers 1995 golden car, at 80 km/h), from the complex frequency response."""
    s = 2j * np.pi * n * stats.IRI_SPEED
    k1, k2, c, mu = stats.IRI_K_TYRE, stats.IRI_K_SUSP, stats.IRI_C_SUSP, stats.IRI_MU
    a = np.array([[s * s + c * s + k2, -(c * s + k2)], [-(c * s + k2), mu * s * s + c * s + k2 + k1]])
    zs, zu = np.linalg.solve(a, np.array([0.0, k1]))
    return abs(s * (zs - zu))


@pytest.mark.parametrize("wavelength, spacing", [(15.0, 0.05), (2.5, 0.05), (5.0, 0.25), (1.2, 0.02)])
def test_iri_of_a_sinusoid_matches_the_frequency_response(wavelength, spacing):
    """For z = a·sin(2πs/λ): IRI = (2/π)·a·|H(n)|·|MA_250mm(n)| / v (mean of |sin| is 2/π)."""
    amp = 0.005
    s = np.arange(int(3000 / spacing) + 1) * spacing
    z = amp * np.sin(2 * np.pi * s / wavelength)
    n = 1.0 / wavelength
    ma = envelope_transfer(n, stats.IRI_BASELENGTH, spacing) if spacing < stats.IRI_BASELENGTH else 1.0
    want = 2 / np.pi * amp * _golden_car_gain(n) * abs(ma) / stats.IRI_SPEED * 1000.0
    got = stats.iri_m_per_km(z, spacing)
    assert got == pytest.approx(want, rel=0.01)  # the start-up transient decays within ~30 m of 3 km


def test_iri_zero_on_flat_and_on_a_grade_and_scales_linearly():
    s = np.arange(20001) * 0.05
    assert stats.iri_m_per_km(np.zeros_like(s), 0.05) == 0.0
    assert stats.iri_m_per_km(0.01 * s, 0.05) < 1e-3  # a constant grade is not roughness (after start-up)
    road = build_road(RoadSpec(iso_class="B", length="2 km", seed=8))
    a = stats.iri_m_per_km(road.left_m, 0.05)
    assert stats.iri_m_per_km(3.0 * road.left_m, 0.05) == pytest.approx(3.0 * a, rel=1e-9)


def test_iri_of_random_road_matches_spectral_prediction():
    """Gaussian profile: IRI = sqrt(2/π)·σ_y/v with σ_y² = ∫ Gd(n)·|H(n)·MA(n)|² dn (random-vibration
    theory). Over 20 km the estimate scatters by ~2 %; allow 6 %."""
    road = build_road(RoadSpec(iso_class="D", length="20 km", seed=12))
    n = np.geomspace(0.011, 2.83, 4000)
    gains = np.array([_golden_car_gain(x) for x in n]) * envelope_transfer(n, 0.25, 0.05)
    var = np.trapezoid(1024e-6 * (n / 0.1) ** -2 * gains ** 2, n)
    want = np.sqrt(2 / np.pi) * np.sqrt(var) / stats.IRI_SPEED * 1000.0
    st = road_statistics(road)
    assert st["iri_m_per_km"] == pytest.approx(want, rel=0.06)


def test_statistics_of_a_flat_road_do_not_crash():
    road = Road(0.05, np.zeros(20001), np.zeros(20001))
    st = road_statistics(road)
    assert st["gd_n0_m3"] is None and st["iso_class"] is None and st["rms_m"] == 0.0


def test_short_measured_profile_uses_shorter_segments():
    road = build_road(RoadSpec(iso_class="D", length="300 m", seed=1))
    st = road_statistics(road, iri=False)
    assert st["segment_length_m"] <= 300 and st["fit_band_cycle_per_m"][0] > 0.02
    assert st["iso_class"] in ("C", "D", "E")
