"""Shocks at the seats: ISO 2631-1 crest factor and MTVV, ISO 2631-5 spinal dose (Sed).

ISO 2631-1:1997 says when its basic method (the weighted RMS a_w) is enough:
  * crest factor CF = max |a_w(t)| / a_w (§6.2.1): above 9 the basic method may underestimate the effect
    of the vibration and the additional methods of §6.3 are to be used;
  * maximum transient vibration value MTVV = max over t0 of the running RMS
    a_w(t0) = sqrt(1/tau int_{t0-tau}^{t0} a_w^2 dt) with tau = 1 s (§6.3.1, eq. 2-3, "linear integration");
    MTVV / a_w > 1.5 or VDV / (a_w T^(1/4)) > 1.75 (§6.3.3, eq. 10-11) also call for the additional methods.

ISO 2631-5:2004 (multiple shocks; the lumbar spine of a seated person):
  * the vertical seat acceleration a_z [m/s^2], sampled at 160 Hz, passes through the standard's recurrent
    neural network (Annex A) to the spine's response acceleration a_lz; the lateral and fore-aft ones through
    its second-order linear model (a digital filter at 160 Hz);
  * D_k = (sum_i A_ik^6)^(1/6) over the response peaks A_ik (z: the positive peaks between zero crossings;
    x, y: the peaks of |a_lk|), §5.2 eq. 1 and 3;
  * daily equivalent D_kd = D_k (t_d / t_m)^(1/6) for a daily exposure t_d of the measured period t_m (eq. 4);
  * equivalent static compression dose S_ed = (sum_k (m_k D_kd)^6)^(1/6) [MPa], m_x = 0.015, m_y = 0.035,
    m_z = 0.032 MPa / (m/s^2) (eq. 5). Annex B: S_ed below 0.5 MPa a low, above 0.8 MPa a high probability of
    an adverse health effect (for a daily exposure over a working life).
The vehicle model has no seat cushion: the accelerations are those of the hull at the seat point (the
input the standards assume is at the seat pan), so the numbers describe the hull's shocks, an upper bound for
a seat with a cushion that attenuates above its resonance.
"""
from __future__ import annotations

import math

import numpy as np

from vehicle.physics import ride

MTVV_WINDOW_S = 1.0                 # ISO 2631-1 §6.3.1: tau = 1 s
CREST_FACTOR_LIMIT = 9.0            # ISO 2631-1 §6.2.1
MTVV_RATIO_LIMIT = 1.5              # ISO 2631-1 §6.3.3 eq. 10
VDV_RATIO_LIMIT = 1.75              # ISO 2631-1 §6.3.3 eq. 11
ISO2631_5_FS_HZ = 160.0             # ISO 2631-5:2004 Annex A: the network and the x/y model run at 160 Hz
DOSE_COEFFICIENTS_MPA = {"x": 0.015, "y": 0.035, "z": 0.032}     # m_k [MPa/(m/s^2)], ISO 2631-5 eq. 5
SED_BANDS_MPA = ((0.5, "low probability of an adverse health effect"),
                 (0.8, "moderate probability of an adverse health effect"),
                 (math.inf, "high probability of an adverse health effect"))     # ISO 2631-5:2004 Annex B
REFERENCE_DAILY_EXPOSURE_S = 8 * 3600.0   # t_d: the 8 h working day of ISO 2631-1 Annex B (a user choice)

# ISO 2631-5:2004 Annex A, eq. A.1-A.3: the recurrent network of the vertical spinal response.
# Rows 0-3: weights of the last 4 outputs, rows 4-11: of the last 8 inputs, row 12: biases (7 hidden units).
_WZ_HIDDEN = np.array([
    [0.00130, 0.01841, -0.00336, 0.01471, 0.00174, 0.00137, 0.00145],
    [-0.00646, -0.00565, -0.00539, 0.01544, -0.00542, 0.00381, 0.00497],
    [-0.00091, -0.02073, 0.00708, -0.00091, 0.00255, -0.00216, 0.01001],
    [0.00898, -0.02626, 0.00438, -0.00595, -0.00774, -0.00034, 0.01280],
    [0.00201, 0.00579, 0.00330, -0.00065, -0.00459, -0.00417, -0.00468],
    [0.00158, 0.00859, 0.00166, 0.00490, -0.00546, 0.00057, -0.00797],
    [0.00361, 0.00490, 0.00452, 0.00079, -0.00604, -0.00638, -0.00529],
    [0.00167, -0.00098, 0.00743, 0.00795, -0.01095, 0.00627, -0.00341],
    [-0.00078, -0.00261, 0.00771, 0.00600, -0.00908, 0.00504, 0.00135],
    [-0.00405, -0.00210, 0.00520, 0.00176, -0.00465, -0.00198, 0.00451],
    [-0.00563, 0.00218, -0.00105, 0.00195, 0.00296, -0.00190, 0.00306],
    [-0.00372, 0.00037, -0.00045, -0.00197, 0.00289, -0.00448, 0.00216],
    [-0.31088, -0.95883, -0.67105, 0.14423, 0.04063, 0.07029, 1.03300]])
_WZ_OUTPUT = np.array([57.96539, 52.32773, 49.78227, 53.16885, 56.02619, -27.79550, 72.34446])
_WZ_OUTPUT_BIAS = 21.51959
# ISO 2631-5:2004 Annex A: the x and y spinal response, a second-order model as a digital filter at 160 Hz
_WXY_B = (0.0192752, 0.00433451, -0.0167763)
_WXY_A = (1.0, -1.957115, 0.963949)


# --- ISO 2631-1: crest factor and MTVV ----------------------------------------------------------------
def weighted_acceleration(a_m_s2, fs_hz: float, weighting: str = "Wk") -> np.ndarray:
    """The frequency-weighted acceleration a_w(t) [m/s^2] of a signal sampled at fs_hz (ISO 2631-1 Annex A,
    vehicle.physics.ride.iso2631_weighting, discretised with the bilinear transform; the 100 Hz band limit
    only when the sampling resolves it)."""
    from scipy.signal import cont2discrete, dlsim

    flt = ride.iso2631_weighting(weighting, upper_band_limit=fs_hz > 4 * 100.0)
    A, B, C, D = flt.state_space()
    Ad, Bd, Cd, Dd, _ = cont2discrete((A, B, C, D), 1.0 / fs_hz, method="bilinear")
    _, y, _ = dlsim((Ad, Bd, Cd, Dd, 1.0 / fs_hz), np.asarray(a_m_s2, float))
    return y[:, 0]


def crest_factor(a_w) -> float:
    """CF = max |a_w(t)| / a_w, the peak over the RMS of the weighted signal (ISO 2631-1 §6.2.1)."""
    a = np.asarray(a_w, float)
    rms = math.sqrt(float(np.mean(a * a)))
    return float(np.max(np.abs(a))) / rms if rms > 0 else math.nan


def running_rms(a_w, fs_hz: float, tau_s: float = MTVV_WINDOW_S) -> np.ndarray:
    """sqrt(1/tau int_{t0-tau}^{t0} a_w^2 dt) at every sample t0 with a full window behind it (ISO 2631-1
    eq. 2, linear integration; rectangle rule on the samples)."""
    a = np.asarray(a_w, float)
    n = max(1, int(round(tau_s * fs_hz)))
    if len(a) < n:
        return np.array([])
    c = np.concatenate([[0.0], np.cumsum(a * a)])
    return np.sqrt(np.maximum(c[n:] - c[:-n], 0.0) / n)


def mtvv(a_w, fs_hz: float, tau_s: float = MTVV_WINDOW_S) -> float:
    """MTVV = max over t0 of the running RMS (ISO 2631-1 eq. 3); NaN for a signal shorter than tau."""
    r = running_rms(a_w, fs_hz, tau_s)
    return float(np.max(r)) if len(r) else math.nan


# --- ISO 2631-5: spinal response, acceleration dose, Sed ---------------------------------------------
def resample(a, fs_hz: float, fs_out_hz: float = ISO2631_5_FS_HZ) -> np.ndarray:
    """The signal at fs_out_hz by linear interpolation (the ride model's series hold no content above the
    160 Hz grid's Nyquist frequency; with fs_hz below 160 Hz the missing content stays missing)."""
    a = np.asarray(a, float)
    if abs(fs_hz - fs_out_hz) < 1e-9 * fs_out_hz:
        return a
    t = np.arange(len(a)) / fs_hz
    return np.interp(np.arange(0.0, t[-1] + 0.5 / fs_out_hz, 1.0 / fs_out_hz), t, a)


def spine_response_z(a_z_160hz) -> np.ndarray:
    """The lumbar spine's vertical response acceleration a_lz [m/s^2] to the seat's vertical acceleration
    a_z [m/s^2] sampled at 160 Hz: ISO 2631-5:2004 Annex A's recurrent network,
    a_lz(t) = sum_j W_j tanh(sum_k w_kj a_lz(t-k) [k=1..4] + sum_k w_(4+k)j a_z(t-k) [k=1..8] + w_13j) + W_8,
    started from rest (eight zero inputs and outputs before the first sample)."""
    a = np.concatenate([np.zeros(8), np.asarray(a_z_160hz, float)])
    n = len(a)
    # the input part of every hidden unit at once: sum_k a(t-k) w_(4+k) for k = 1..8
    lagged = np.stack([a[8 - k:n - k] for k in range(1, 9)], axis=1)          # (n-8, 8)
    drive = (lagged @ _WZ_HIDDEN[4:12] + _WZ_HIDDEN[12]).tolist()             # (n-8, 7)
    # the recurrence on plain floats (1.6x faster than NumPy calls on 7-vectors)
    w1, w2, w3, w4 = (_WZ_HIDDEN[i].tolist() for i in range(4))
    W, units, tanh = _WZ_OUTPUT.tolist(), range(7), math.tanh
    y1 = y2 = y3 = y4 = 0.0               # a_lz(t-1) .. a_lz(t-4), from rest
    out = []
    for d in drive:
        y = _WZ_OUTPUT_BIAS
        for j in units:
            y += W[j] * tanh(d[j] + y1 * w1[j] + y2 * w2[j] + y3 * w3[j] + y4 * w4[j])
        out.append(y)
        y4, y3, y2, y1 = y3, y2, y1, y
    return np.array(out)


def spine_response_xy(a_160hz) -> np.ndarray:
    """The lumbar spine's fore-aft or lateral response acceleration [m/s^2] to the seat's acceleration
    [m/s^2] at 160 Hz (ISO 2631-5:2004 Annex A, the linear model as its digital filter)."""
    from scipy.signal import lfilter

    return lfilter(_WXY_B, _WXY_A, np.asarray(a_160hz, float))


def response_peaks(a_l, positive_only: bool) -> np.ndarray:
    """The peaks of a response between consecutive zero crossings: the largest value of each positive
    stretch (positive_only, the z axis) or the largest |value| of every stretch (x, y) (ISO 2631-5 §5.2)."""
    a = np.asarray(a_l, float)
    if len(a) == 0:
        return np.array([])
    sign = np.sign(a)
    starts = np.concatenate([[0], np.flatnonzero(sign[1:] != sign[:-1]) + 1])
    peaks = np.maximum.reduceat(a if positive_only else np.abs(a), starts)
    if positive_only:
        peaks = peaks[sign[starts] > 0]
    return peaks[peaks > 0]


def acceleration_dose(peaks_m_s2) -> float:
    """D_k = (sum_i A_ik^6)^(1/6) [m/s^2] (ISO 2631-5 eq. 1 and 3)."""
    p = np.asarray(peaks_m_s2, float)
    return float(np.sum(p ** 6) ** (1.0 / 6.0)) if len(p) else 0.0


def daily_dose(dose_m_s2: float, measured_s: float, daily_s: float) -> float:
    """D_kd = D_k (t_d / t_m)^(1/6): the dose of a day of t_d of the same driving (ISO 2631-5 eq. 4)."""
    return float(dose_m_s2) * (float(daily_s) / float(measured_s)) ** (1.0 / 6.0)


def compression_dose_MPa(doses_m_s2: dict) -> float:
    """S_ed = (sum_k (m_k D_k)^6)^(1/6) [MPa] over the axes given ({"x"|"y"|"z": D_k}; ISO 2631-5 eq. 5)."""
    return float(sum((DOSE_COEFFICIENTS_MPA[k] * d) ** 6 for k, d in doses_m_s2.items()) ** (1.0 / 6.0))


def sed_band(sed_MPa: float) -> str:
    for limit, text in SED_BANDS_MPA:
        if sed_MPa < limit:
            return text
    return SED_BANDS_MPA[-1][1]


def seat_shocks(a_z_m_s2, fs_hz: float, a_y_m_s2=None, daily_s: float = REFERENCE_DAILY_EXPOSURE_S) -> dict:
    """Every shock number of one seat from its vertical (and lateral) acceleration [m/s^2] at fs_hz.

    Returns crest_factor, mtvv_m_s2, mtvv_ratio (MTVV / a_w), a_w (the same signal's weighted RMS), the
    ISO 2631-5 doses D_z (D_y) [m/s^2] over the signal and per day of daily_s, Sed of the drive and daily
    Sed [MPa], and `a_w_unreliable` with the reasons (ISO 2631-1 §6.2.1, §6.3.3)."""
    a_z = np.asarray(a_z_m_s2, float)
    duration = len(a_z) / fs_hz
    aw = weighted_acceleration(a_z, fs_hz, "Wk")
    a_w = math.sqrt(float(np.mean(aw * aw)))
    cf, m = crest_factor(aw), mtvv(aw, fs_hz)
    out = {"duration_s": duration, "fs_hz": float(fs_hz), "a_w_m_s2": a_w, "crest_factor": cf, "mtvv_m_s2": m,
           "mtvv_ratio": m / a_w if a_w > 0 else math.nan}
    doses = {"z": acceleration_dose(response_peaks(spine_response_z(resample(a_z, fs_hz)), True))}
    if a_y_m_s2 is not None:
        doses["y"] = acceleration_dose(response_peaks(spine_response_xy(resample(a_y_m_s2, fs_hz)), False))
    daily = {k: daily_dose(d, duration, daily_s) for k, d in doses.items()}
    out.update({f"dose_{k}_m_s2": d for k, d in doses.items()})
    out.update({f"daily_dose_{k}_m_s2": d for k, d in daily.items()})
    out["sed_MPa"] = compression_dose_MPa(doses)
    out["daily_sed_MPa"] = compression_dose_MPa(daily)
    out["daily_exposure_s"] = float(daily_s)
    out["sed_assessment"] = sed_band(out["daily_sed_MPa"])
    reasons = []
    if cf > CREST_FACTOR_LIMIT:
        reasons.append(f"crest factor {cf:.1f} > {CREST_FACTOR_LIMIT:g}")
    if out["mtvv_ratio"] > MTVV_RATIO_LIMIT:
        reasons.append(f"MTVV/a_w {out['mtvv_ratio']:.2f} > {MTVV_RATIO_LIMIT:g}")
    out["a_w_unreliable"] = reasons
    return out


# --- from a drive's stored series ---------------------------------------------------------------------
MIN_SAMPLE_RATE_HZ = 30.0     # the Wk weighting's main band reaches ~20 Hz; sparser series miss the shocks
START_SKIP_S = 5.0            # the drive's start from standing (a transient of several m/s^2 as the road
                              # profile comes under the wheels), left out as in vehicle.analysis.psd


def seat_signals(view, seats, skip_s: float = START_SKIP_S) -> tuple[float, dict] | None:
    """(sample rate [Hz], {seat name: (vertical, lateral) acceleration [m/s^2]}) at the seats from the stored
    hull accelerations (vehicle.physics.ride.seat_vertical_acceleration / seat_lateral_acceleration); None when
    the series are missing, uneven or sparser than MIN_SAMPLE_RATE_HZ. seats: the resolved vehicle's seats
    (dicts with name, x_from_cg, y_from_cg, z_from_cg in m); the first skip_s of the drive left out."""
    t = view.series("time")
    parts = [view.series(n) for n in ("heave_acceleration", "pitch_acceleration", "roll_acceleration")]
    roll = view.series("roll")
    if t is None or len(t) < 16 or any(p is None for p in parts) or not seats:
        return None
    dt = np.diff(np.asarray(t, float))
    h = float(np.median(dt))
    if h <= 0 or not np.allclose(dt, h, rtol=1e-6, atol=1e-9) or 1.0 / h < MIN_SAMPLE_RATE_HZ:
        return None
    keep = np.asarray(t, float) >= float(t[0]) + skip_s
    if keep.sum() < 2 * MTVV_WINDOW_S / h:
        return None
    heave, pitch, roll_acc = (np.asarray(p, float)[keep] for p in parts)
    roll = None if roll is None else np.asarray(roll, float)[keep]
    out = {}
    for s in seats:
        az = ride.seat_vertical_acceleration(heave, pitch, roll_acc, s["x_from_cg"], s["y_from_cg"])
        ay = None if roll is None else ride.seat_lateral_acceleration(roll_acc, roll, s.get("z_from_cg", 0.0))
        out[s["name"]] = (np.asarray(az, float), ay)
    return 1.0 / h, out


def drive_shocks(view, seats, daily_s: float = REFERENCE_DAILY_EXPOSURE_S) -> dict:
    """{seat name: seat_shocks(...)} of a drive's stored series ({} when they are too sparse: the numbers need
    output.interval <= 1/MIN_SAMPLE_RATE_HZ; the first START_SKIP_S of the drive left out)."""
    sig = seat_signals(view, seats)
    if sig is None:
        return {}
    fs, per_seat = sig
    return {name: seat_shocks(az, fs, ay, daily_s) for name, (az, ay) in per_seat.items()}
