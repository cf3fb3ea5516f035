"""ISO 2631-1 crest factor and MTVV, ISO 2631-5 spinal response and dose (vehicle.physics.shocks)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from vehicle.physics import shocks

FS = 400.0


def test_crest_factor_and_mtvv_of_a_sine_are_sqrt2_and_its_rms():
    """A sine of amplitude A: peak A, RMS A/sqrt(2) -> CF = sqrt(2); every 1 s window over whole periods
    holds the RMS, so MTVV = A/sqrt(2) (hand values)."""
    t = np.arange(0, 20.0, 1 / FS)
    a = 0.8 * np.sin(2 * np.pi * 4.0 * t)
    assert shocks.crest_factor(a) == pytest.approx(math.sqrt(2), rel=1e-4)      # sampling of the peak: 1e-5
    assert shocks.mtvv(a, FS) == pytest.approx(0.8 / math.sqrt(2), rel=1e-9)


def test_one_shock_on_a_sine_gives_the_hand_crest_factor_and_mtvv():
    """Sine A = 0.5 m/s^2 over T = 20 s plus one rectangular shock of height S = 6 m/s^2 and width w = 0.05 s
    at a zero crossing of the sine (the sine is 0 +- A*2*pi*f*w/2 there; the shock dominates):
    RMS^2 = A^2/2 + S^2 w / T (the cross term integrates to ~0 over the odd sine at a zero crossing),
    peak ~ S, MTVV^2 = A^2/2 + S^2 w / 1 s (the window holding the shock)."""
    A, S, w, T, f = 0.5, 6.0, 0.05, 20.0, 2.0
    t = np.arange(0, T, 1 / FS)
    a = A * np.sin(2 * np.pi * f * t)
    i0 = int(10.0 * FS)                                  # t = 10 s: a zero crossing of the 2 Hz sine
    n = int(w * FS)
    a[i0 - n // 2:i0 + n // 2] += S
    rms = math.sqrt(A ** 2 / 2 + S ** 2 * w / T)
    peak = S + A * math.sin(2 * np.pi * f * w / 2)
    assert shocks.crest_factor(a) == pytest.approx(peak / rms, rel=2e-3)
    assert shocks.mtvv(a, FS) == pytest.approx(math.sqrt(A ** 2 / 2 + S ** 2 * w), rel=5e-3)
    assert shocks.crest_factor(a) > shocks.CREST_FACTOR_LIMIT          # this record calls for ISO 2631-1 §6.3


def _annex_test_signal(fs=160.0, T=2.0):
    """The trapezoidal test signal of the ISO 2631-5 filters (up to 2 m/s^2 in 0.05 s, held, down to -2, back
    to 0 at 0.55 s)."""
    t = np.arange(0, T + 0.5 / fs, 1 / fs)
    return np.interp(t, [0, 0.05, 0.2, 0.4, 0.5, 0.55, T], [0, 2, 2, -2, -2, 0, 0])


def _first_extrema(y):
    """The first maximum, the following minimum and the next maximum of a response."""
    i1 = np.argmax(y[: np.argmax(y < -0.5)])
    j = i1 + np.argmin(y[i1:i1 + 80])
    k = j + np.argmax(y[j:j + 80])
    return y[i1], y[j], y[k]


def test_spine_networks_against_the_standard_test_responses():
    """ISO 2631-5:2004's recurrent network (z) and linear model (x, y) on the standard's trapezoidal test
    signal: first maximum, minimum and second maximum of the response, 1.661 / -1.512 / 0.308 m/s^2 (z) and
    3.025 / -4.048 / 2.065 m/s^2 (x, y), within the ISO 8041 tolerance of -11/+12 % (the published values as
    Project Chrono's ISO 2631 unit test checks them). Measured: z 1.651 / -1.489 / 0.313 (within 1.6 %),
    x/y 3.0253 / -4.0480 / 2.0652 (within 0.02 %): besides the standard's tolerance, z is held to 3 % and x/y
    to 0.1 % (the published values have 3-4 digits), so a wrong weight or lag cannot pass."""
    a = _annex_test_signal()
    z = _first_extrema(shocks.spine_response_z(a))
    for got, want in zip(z, (1.661, -1.512, 0.308)):
        assert abs(got - want) <= 0.03 * abs(want), (z, want)
    xy = _first_extrema(shocks.spine_response_xy(a))
    for got, want in zip(xy, (3.025, -4.048, 2.065)):
        assert abs(got - want) <= 1e-3 * abs(want), (xy, want)


def test_the_spine_network_rests_at_zero_and_is_nonlinear():
    a0 = shocks.spine_response_z(np.zeros(800))
    assert np.max(np.abs(a0)) < 0.05                                   # the biases cancel at rest
    small = shocks.spine_response_z(0.1 * _annex_test_signal())
    big = shocks.spine_response_z(10.0 * _annex_test_signal())
    assert np.max(big) / np.max(small) != pytest.approx(100.0, rel=0.05)


def test_dose_formulas_against_hand_values():
    """D = (sum A^6)^(1/6): two peaks of 2 and one of 4 m/s^2 -> (2*64 + 4096)^(1/6); positive peaks between
    zero crossings only for z; the daily dose scales with (t_d/t_m)^(1/6); Sed = m_z D_z with z alone
    (ISO 2631-5 eq. 1, 3-5)."""
    sig = np.array([0, 1, 2, 1, -1, -5, -1, 2, 4, 3, 0.5, -0.5, 2, 0.1, -0.2])
    pz = shocks.response_peaks(sig, positive_only=True)
    np.testing.assert_allclose(pz, [2, 4, 2])
    np.testing.assert_allclose(shocks.response_peaks(sig, positive_only=False), [2, 5, 4, 0.5, 2, 0.2])
    D = shocks.acceleration_dose(pz)
    assert D == pytest.approx((2 * 64 + 4096) ** (1 / 6), rel=1e-12)
    assert shocks.daily_dose(D, 600.0, 600.0 * 64) == pytest.approx(2 * D, rel=1e-12)
    assert shocks.compression_dose_MPa({"z": D}) == pytest.approx(0.032 * D, rel=1e-12)
    sed = shocks.compression_dose_MPa({"z": 10.0, "y": 10.0})
    assert sed == pytest.approx(10 * (0.032 ** 6 + 0.035 ** 6) ** (1 / 6), rel=1e-12)


def test_seat_shocks_flags_a_shocky_record():
    t = np.arange(0, 30.0, 1 / 100.0)
    a = 0.3 * np.sin(2 * np.pi * 3.0 * t)
    calm = shocks.seat_shocks(a, 100.0)
    a[1500:1505] += 15.0
    rough = shocks.seat_shocks(a, 100.0)
    assert calm["a_w_unreliable"] == [] and rough["a_w_unreliable"]
    assert rough["sed_MPa"] > calm["sed_MPa"]
    assert rough["daily_sed_MPa"] == pytest.approx(rough["sed_MPa"] * (8 * 3600 / 30.0) ** (1 / 6), rel=1e-6)


class _Series:
    """A results view of synthetic hull series at 100 Hz."""

    name = "<synthetic>"

    def __init__(self, **data):
        self.data = data

    def series(self, name):
        return self.data.get(name)


def test_seat_signals_follow_the_hull_kinematics_and_skip_the_start():
    """A seat x = 2 m behind and y = 0.5 m left of the CG: a_z = heave'' - 2 pitch'' + 0.5 roll'' (nose up and
    left side up positive, vehicle.physics.hull); lateral reading -z roll'' + g roll; the first 5 s left out;
    series sparser than 30 Hz give nothing."""
    fs = 100.0
    t = np.arange(1, 2001) / fs
    heave, pitch, roll_acc = np.sin(3 * t), 0.1 * np.cos(2 * t), 0.2 * np.sin(5 * t)
    roll = -0.2 / 25 * np.sin(5 * t)
    view = _Series(time=t, heave_acceleration=heave, pitch_acceleration=pitch, roll_acceleration=roll_acc, roll=roll)
    seat = {"name": "s", "x_from_cg": 2.0, "y_from_cg": 0.5, "z_from_cg": 0.4}
    got_fs, sig = shocks.seat_signals(view, [seat])
    keep = t >= t[0] + shocks.START_SKIP_S
    assert got_fs == pytest.approx(fs)
    np.testing.assert_allclose(sig["s"][0], (heave - 2 * pitch + 0.5 * roll_acc)[keep], rtol=1e-12)
    np.testing.assert_allclose(sig["s"][1], (-0.4 * roll_acc + 9.80665 * roll)[keep], rtol=1e-9)
    sparse = _Series(time=t[::5], heave_acceleration=heave[::5], pitch_acceleration=pitch[::5],
                     roll_acceleration=roll_acc[::5], roll=roll[::5])
    assert shocks.seat_signals(sparse, [seat]) is None and shocks.drive_shocks(sparse, [seat]) == {}
