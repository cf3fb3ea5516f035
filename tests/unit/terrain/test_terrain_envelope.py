"""Tyre enveloping filter: attenuation of sinusoids and of a random road against the analytic transfer function."""
from __future__ import annotations

import numpy as np
import pytest

from terrain import Road, RoadSpec, build_road, road_statistics
from terrain.envelope import contact_kernel, envelope_profile, envelope_transfer


def _amplitude(s, z, n):
    """Least-squares amplitude of the sinusoid of frequency n in z(s)."""
    a = np.column_stack([np.sin(2 * np.pi * n * s), np.cos(2 * np.pi * n * s), np.ones_like(s)])
    c, *_ = np.linalg.lstsq(a, z, rcond=None)
    return np.hypot(c[0], c[1])


@pytest.mark.parametrize("contact, spacing", [(0.35, 0.05), (0.40, 0.05), (0.30, 0.02), (0.45, 0.1)])
def test_sinusoid_attenuation_equals_discrete_transfer_function(contact, spacing):
    """A sinusoid through the filter keeps its frequency and is scaled by exactly H_d(n)
    (the filter is linear, symmetric: zero phase). Away from the ends (edge padding) the
    amplitude agrees with the closed form to round-off."""
    kern = contact_kernel(contact, spacing)
    assert kern.sum() == pytest.approx(1.0, abs=1e-14)
    np.testing.assert_allclose(kern, kern[::-1])
    s = np.arange(20001) * spacing
    inner = slice(200, -200)
    for wavelength in (0.2, 0.31, 0.45, 0.7, 1.0, 2.5, 10.0):
        n = 1.0 / wavelength
        if n >= 0.499 / spacing:  # at or above Nyquist the sampled wave is not a sinusoid of n
            continue
        z = np.sin(2 * np.pi * n * s + 0.3)
        out = envelope_profile(z, contact, spacing)
        h = envelope_transfer(n, contact, spacing)
        np.testing.assert_allclose(out[inner], h * z[inner], atol=1e-12)
        assert _amplitude(s[inner], out[inner], n) == pytest.approx(abs(h), abs=1e-12)


def test_discrete_transfer_tends_to_the_continuous_sinc():
    """H_d -> sin(π n L)/(π n L) as the grid gets finer; the error shrinks like (n·Δ)²."""
    n = np.array([0.5, 1.0, 2.0, 2.5])
    exact = envelope_transfer(n, 0.4)
    errors = [np.max(np.abs(envelope_transfer(n, 0.4, dx) - exact)) for dx in (0.02, 0.01, 0.005)]
    assert errors[0] < 0.02
    assert errors[1] < errors[0] / 3.0 and errors[2] < errors[1] / 3.0


def test_moving_average_zero_at_contact_length_wavelength():
    """With L an odd number of samples the wave of length L (and L/2) is removed entirely."""
    contact, dx = 0.35, 0.05  # 7 samples
    s = np.arange(4001) * dx
    for wavelength in (contact, contact / 2):
        z = np.sin(2 * np.pi * s / wavelength)
        assert np.max(np.abs(envelope_profile(z, contact, dx)[50:-50])) < 1e-12


def test_long_waves_and_constants_pass_unchanged():
    s = np.arange(10001) * 0.05
    z = 0.02 + 0.001 * s  # a grade: averaged symmetric kernel keeps it exactly
    np.testing.assert_allclose(envelope_profile(z, 0.37, 0.05)[20:-20], z[20:-20], atol=1e-14)
    assert envelope_transfer(0.011, 0.4, 0.05) == pytest.approx(1.0, abs=1e-3)


def test_enveloped_random_road_psd_ratio_is_transfer_squared():
    """Welch PSD ratio enveloped/raw equals |H_d(n)|² bin by bin (same data, so no sampling noise
    beyond the Welch window's smoothing; 2 % allowed where |H|² > 0.05)."""
    road = build_road(RoadSpec(iso_class="D", length="10 km", seed=4))
    env = road.enveloped(0.4)
    assert isinstance(env, Road) and env.info["contact_length_m"] == 0.4
    a = road_statistics(road, iri=False)
    b = road_statistics(env, iri=False)
    f = a["frequency_cycle_per_m"]
    h2 = envelope_transfer(f, 0.4, road.spacing_m) ** 2
    sel = (f > 0.05) & (f < 2.5) & (h2 > 0.05)
    np.testing.assert_allclose(b["psd_left_m3"][sel] / a["psd_left_m3"][sel], h2[sel], rtol=0.02)
    # short waves strongly attenuated: at n = 2 cycle/m (0.5 m) the gain is |sinc(0.8)| ≈ 0.23
    assert abs(envelope_transfer(2.0, 0.4)) == pytest.approx(abs(np.sin(0.8 * np.pi) / (0.8 * np.pi)))
    assert np.std(env.left_m) < np.std(road.left_m)
