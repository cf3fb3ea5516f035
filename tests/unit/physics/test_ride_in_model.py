"""Ride and road-holding metrics accumulated inside the integrator (vehicle.physics.model ride states,
vehicle.engines.full statistics rows) against the same quantities from dense stored series.

The drives run the 8x8 at 36 km/h over a sinusoidal road (2 Hz at the wheels) with output at every
4 ms step. After the start transient the motion is periodic, so the exact ISO 2631-1 weighting of the
seat motion is its Fourier series weighted harmonic by harmonic with the continuous filters
(vehicle.physics.ride). The reference seat accelerations are the second differences of the stored
hull pose (heave, pitch, roll at every step: the trajectory the solver computed; O(h^2), 0.5 % at
10 Hz). The model's filters are driven by the seat velocities (states) and integrated with the 4 ms
explicit trapezoid of the solver's slow block: error below 1 % up to 8 Hz, 1.5 % at 12.5 Hz (the
scheme's discrete transfer function; `test_weighted_rms_of_a_pure_sine_...`). Tolerance 1 % on a_w,
2 % on VDV (fourth power) and absorbed power (a square).

(The stored `hull_acceleration` series, the output function at the samples with its own valve
Newton iterations, differs from the trajectory's second differences by up to 2 % in a_w on the
roll road: the reason the reference is built from the poses.)
"""
from __future__ import annotations

import numpy as np
import pytest

from terrain.road import Road
from vehicle.physics import ride
from vehicle.physics.model import TRAVEL_BINS, VehicleModel
from vehicle.physics.params import load_vehicle
from vehicle.engines.full import Drive
from vehicle.scenario.settings import DriveSettings
from vehicle.scenario.speed import SpeedProfile
from vehicle.results.sinks import MemorySink

SPEED = 10.0            # m/s
WAVELENGTH = 5.0        # m: 2 Hz at 10 m/s
AMPLITUDE = 0.02        # m
INTERVAL = 50.0         # m: statistics rows of 5 s = 10 road periods = 1250 steps
DISTANCE = 250.0


def _sine_road(sign_right: float) -> Road:
    s = np.arange(0.0, DISTANCE + 40.0, 0.05)
    h = AMPLITUDE * np.sin(2 * np.pi * s / WAVELENGTH) * np.clip(s / 10.0, 0.0, 1.0)    # 10 m run-in
    return Road(0.05, h, sign_right * h)


@pytest.fixture(scope="module")
def model():
    return VehicleModel(load_vehicle("apc_8x8"))


def _drive(model, sign_right):
    settings = DriveSettings(distance_m=DISTANCE, speed=SpeedProfile.constant(SPEED), output_interval_s=0.004,
                             samples_per_block=250, stats_interval_m=INTERVAL)
    d = Drive(model, _sine_road(sign_right), settings)
    sink = MemorySink()
    d.run(sink)
    return d, sink


@pytest.fixture(scope="module")
def symmetric(model):
    return _drive(model, 1.0)


@pytest.fixture(scope="module")
def antisymmetric(model):
    return _drive(model, -1.0)


def _window(sink, row_index):
    """Samples strictly inside statistics row `row_index` (its end included): one whole number of periods."""
    t = sink.drive_series("t_s")
    rows = sink.rows
    t1 = sum(r["duration_s"] for r in rows[:row_index + 1])
    t0 = t1 - rows[row_index]["duration_s"]
    k = (t > t0 + 1e-9) & (t <= t1 + 1e-9)
    return k, rows[row_index]["duration_s"]


def _weighted(signal, flt, dt):
    """The periodic signal through a continuous filter, exactly (harmonic by harmonic)."""
    A = np.fft.rfft(signal)
    f = np.fft.rfftfreq(len(signal), dt)
    return np.fft.irfft(A * flt.frequency_response(f), len(signal))


def _seat_signals(model, sink, k):
    """Seat (vertical, lateral) accelerations in window k from the stored pose (central second differences)."""
    h = np.diff(sink.drive_series("t_s")[:2])[0]
    pose = np.stack([sink.drive_series(n) for n in ("heave_m", "pitch_rad", "roll_rad")])
    acc_all = np.full_like(pose, np.nan)
    acc_all[:, 1:-1] = (pose[:, 2:] - 2 * pose[:, 1:-1] + pose[:, :-2]) / h ** 2
    acc = acc_all[:, k]
    assert np.all(np.isfinite(acc))
    roll = sink.drive_series("roll_rad")[k]
    out = {}
    for st in model.params.seats:
        out[st.name] = (ride.seat_vertical_acceleration(acc[0], acc[1], acc[2], st.x_from_cg, st.y_from_cg),
                        ride.seat_lateral_acceleration(acc[2], roll, st.z_from_cg))
    return out


@pytest.mark.parametrize("which", ["symmetric", "antisymmetric"])
def test_in_model_weighting_of_a_periodic_seat_motion(which, request, model):
    """a_w (Wk and Wd), VDV and absorbed power of the statistics rows vs the exact weighting of the stored
    seat accelerations (a 2 Hz road and its harmonics); lateral only on the antisymmetric road (roll)."""
    d, sink = request.getfixturevalue(which)
    dt = d.settings.dt_s
    filters = model.seat_filters
    for row_index in (2, 3):
        k, T = _window(sink, row_index)
        assert abs(k.sum() * dt - T) < 1e-9
        row = sink.rows[row_index]
        for j, (seat, (a_v, a_l)) in enumerate(_seat_signals(model, sink, k).items()):
            aw = _weighted(a_v, filters.vertical, dt)
            ap = _weighted(a_v, filters.power, dt)
            assert np.sqrt(np.mean(aw ** 2)) > 0.1           # a motion worth weighting
            assert row["weighted_rms_acceleration_m_s2"][j] == pytest.approx(np.sqrt(np.mean(aw ** 2)), rel=0.01)
            assert row["vdv_m_s175"][j] == pytest.approx((np.sum(aw ** 4) * dt) ** 0.25, rel=0.02)
            assert row["absorbed_power_W"][j] == pytest.approx(np.mean(ap ** 2), rel=0.02)
            if which == "antisymmetric":
                awl = _weighted(a_l, filters.lateral, dt)
                assert np.sqrt(np.mean(awl ** 2)) > 0.02
                assert row["weighted_rms_lateral_acceleration_m_s2"][j] == pytest.approx(
                    np.sqrt(np.mean(awl ** 2)), rel=0.01)
            else:
                # no roll input: what roll there is grows from rounding (2e-5 rad at most)
                assert row["weighted_rms_lateral_acceleration_m_s2"][j] < 1e-2 * row["weighted_rms_acceleration_m_s2"][j]


def test_weighted_rms_of_a_pure_sine_is_the_standards_factor():
    """A 2 Hz seat acceleration of 1 m/s^2 amplitude (its velocity driving the model's filter equations)
    integrated at the drive's 4 ms with the drive's scheme (explicit trapezoid of the slow block): a_w = |W(2 Hz)| / sqrt(2),
    VDV^4 over whole periods = (3/8) |W|^4 T, absorbed power = |H_ap|^2 / 2; the standard's Wk at 2 Hz is
    0.531 (ISO 2631-1 Table 3, x1000: 531)."""
    filters = ride.SeatFilters.default()
    h, f, T_run, T = 0.004, 2.0, 10.0, 5.0
    n = len(filters.velocity_state_names("s"))
    x = np.zeros(n)
    q = np.zeros(4)
    w = 2 * np.pi * f
    v = lambda t: -np.cos(w * t) / w            # the seat velocity of a = sin(w t), as the model drives them

    def rates(x, t):
        r, quad = filters.rates_from_velocity(list(x), v(t), 0.0, 0.0)
        return np.array(r, float), np.array([quad[k] for k in ("aw2", "aw4", "awl2", "pabs")], float)

    steps_run, steps = int(round(T_run / h)), int(round(T / h))
    for k in range(steps_run + steps):
        t = k * h
        if k == steps_run:
            q[:] = 0.0
        r1, g1 = rates(x, t)
        r2, g2 = rates(x + h * r1, t + h)
        x = x + 0.5 * h * (r1 + r2)
        q = q + 0.5 * h * (g1 + g2)
    W = abs(filters.vertical.frequency_response(f))
    assert W == pytest.approx(0.531, abs=0.005)
    assert np.sqrt(q[0] / T) == pytest.approx(W / np.sqrt(2), rel=5e-3)
    assert q[1] == pytest.approx(3.0 / 8.0 * W ** 4 * T, rel=1e-2)
    assert q[3] / T == pytest.approx(abs(filters.power.frequency_response(f)) ** 2 / 2, rel=1e-2)


def test_dynamic_load_coefficient_and_lift_off_vs_stored_series(symmetric):
    d, sink = symmetric
    F = sink.drive_series("wheel_load")
    for row_index in (2, 3):
        k, _ = _window(sink, row_index)
        dlc = F[:, k].std(axis=1) / F[:, k].mean(axis=1)
        np.testing.assert_allclose(sink.rows[row_index]["dynamic_load_coefficient"], dlc, rtol=0.01)
        lifted = (F[:, k] <= 0).mean(axis=1)
        np.testing.assert_allclose(sink.rows[row_index]["lift_off_share"], lifted, atol=0.01)


def test_travel_histogram_sums_to_the_drive_time_and_brackets_the_travel(symmetric, model):
    d, sink = symmetric
    hist = np.stack([r["strut_travel_histogram_s"] for r in sink.rows])        # (rows, n, bins)
    T = np.array([r["duration_s"] for r in sink.rows])
    assert hist.shape[1:] == (model.n, TRAVEL_BINS)
    np.testing.assert_allclose(hist.sum(axis=2), np.repeat(T[:, None], model.n, axis=1), rtol=1e-9)
    assert sum(T) == pytest.approx(sink.drive_series("t_s")[-1], rel=1e-9)
    x = sink.drive_series("strut_deflection")
    edges = model.travel_bin_edges()
    width = edges[:, 1] - edges[:, 0]
    for row_index in (2, 3):
        k, _ = _window(sink, row_index)
        row = sink.rows[row_index]
        lo, hi = x[:, k].min(axis=1), x[:, k].max(axis=1)
        assert np.all(row["strut_travel_min_m"] <= lo + 1e-12) and np.all(lo - row["strut_travel_min_m"] < width)
        assert np.all(row["strut_travel_max_m"] >= hi - 1e-12) and np.all(row["strut_travel_max_m"] - hi < width)
        # time in each bin: the stored samples counted per bin (each sample stands for one 4 ms step)
        counts = np.array([np.histogram(np.clip(xi, e[0], e[-1]), e)[0] for xi, e in zip(x[:, k], edges)])
        assert np.abs(row["strut_travel_histogram_s"] - counts * d.settings.dt_s).max() < 0.02 * row["duration_s"]


def test_left_right_symmetric_road_gives_equal_left_right_metrics(symmetric, model):
    """The vehicle is left/right symmetric, but a roll of up to 2e-5 rad grows from rounding (stick-slip
    friction amplifies it): left and right agree to 1e-3 (measured 4e-5 in the DLC), not to rounding."""
    _, sink = symmetric
    for row in sink.rows:
        T = row["duration_s"]
        for key in ("dynamic_load_coefficient", "lift_off_share", "end_stop_time_s", "strut_travel_min_m",
                    "strut_travel_max_m"):
            v = np.asarray(row[key])
            np.testing.assert_allclose(v[0::2], v[1::2], rtol=1e-3, atol=1e-3 * T if key.endswith("_s") else 1e-9,
                                       err_msg=key)
        # the time per travel bin moves by a few steps where a strut turns close to a bin edge: compare the bins
        # to 1 % of the interval, and the travel percentiles interpolated in the 11.7 mm bins to 1.5 mm (a change
        # of rounding moved a 95th percentile by 0.53 mm, its bin by 0.5 % of the interval)
        hist = np.asarray(row["strut_travel_histogram_s"])
        p = np.array([ride.travel_percentiles(h, e, (5, 50, 95)) for h, e in zip(hist, model.travel_bin_edges())])
        np.testing.assert_allclose(p[0::2], p[1::2], atol=1.5e-3)
        np.testing.assert_allclose(hist[0::2], hist[1::2], atol=0.01 * T)
