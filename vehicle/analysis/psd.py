"""Response power spectral densities of a drive from its stored time series (scipy.signal.welch).

What a ride engineer reads next to the ISO 2631-1 numbers: where the hull's heave, pitch and roll
accelerations and the strut forces have their power (body modes near 1-2 Hz, wheel hop near 10 Hz).
One-sided Welch estimates (Hann windows, half overlap, mean removed per segment): the integral of a
PSD over frequency is the signal's variance (Parseval), which the tests check.

The series must be stored densely enough: a PSD up to f_max needs samples at least every 1/(2 f_max)
(`output.interval` of the scenario; the default 1 s stores one sample per second, Nyquist 0.5 Hz,
too coarse for any mode). `response_psd` refuses series with a Nyquist frequency below
MIN_NYQUIST_HZ and says which interval to use.
"""
from __future__ import annotations

import numpy as np

from hpsim.errors import UserInputError

MIN_NYQUIST_HZ = 15.0            # above the wheel hop (about 10 Hz) of the shipped vehicles
SEGMENT_S = 20.0                 # Welch segment: 0.05 Hz resolution
SIGNALS = (("heave_acceleration", "m/s^2", "(m/s^2)^2/Hz"), ("pitch_acceleration", "rad/s^2", "(rad/s^2)^2/Hz"),
           ("roll_acceleration", "rad/s^2", "(rad/s^2)^2/Hz"), ("strut_force", "N", "N^2/Hz"))


def welch_psd(x, fs_hz: float, segment_s: float = SEGMENT_S):
    """(f [Hz], one-sided PSD [unit^2/Hz]) of x (..., n) sampled at fs_hz (scipy.signal.welch, Hann, 50 %)."""
    from scipy.signal import welch

    x = np.asarray(x, float)
    nperseg = int(min(x.shape[-1], max(8, round(segment_s * fs_hz))))
    return welch(x, fs=fs_hz, nperseg=nperseg, detrend="constant", axis=-1)


def response_psd(view, segment_s: float = SEGMENT_S, skip_s: float = 5.0) -> dict:
    """PSDs of the stored hull accelerations and strut forces of a results view (file or MemorySink).

    skip_s: leading time left out (the start from rest). Returns {"f_hz", "fs_hz", "duration_s", "psd":
    {signal: array (f,) or (station, f)}, "units": {signal: PSD unit}, "peaks": {signal: [peak
    frequency per row] Hz}, "rms": {signal: [RMS per row]}, "signal_units": {signal: unit of the RMS}}; signals the file does not store are left
    out. UserInputError when the series are too sparse or too short."""
    t = view.series("time")
    if t is None or len(t) < 16:
        raise UserInputError(f"{view.name}: too few stored samples for a PSD (need the time series of a drive "
                             "stored with output.interval <= 0.02 s)")
    t = np.asarray(t, float)
    dt = np.diff(t)
    h = float(np.median(dt))
    if not np.allclose(dt, h, rtol=1e-6, atol=1e-9):
        raise UserInputError(f"{view.name}: the stored samples are not evenly spaced (a resumed run with another "
                             "output.interval?): no PSD")
    fs = 1.0 / h
    if fs / 2 < MIN_NYQUIST_HZ:
        raise UserInputError(f"{view.name}: series stored every {h:.4g} s (Nyquist {fs / 2:.3g} Hz): response PSDs "
                             f"need output.interval <= {1 / (2 * MIN_NYQUIST_HZ):.3g} s; rerun with e.g. "
                             "`output: {interval: 0.01 s}` (a shorter distance keeps the file small)")
    keep = t >= t[0] + skip_s
    if keep.sum() * h < 2 * min(segment_s, 5.0):
        raise UserInputError(f"{view.name}: {keep.sum() * h:.3g} s of series after the first {skip_s:g} s: too short "
                             f"for a PSD with {segment_s:g} s segments")
    out = {"f_hz": None, "fs_hz": fs, "duration_s": float(keep.sum() * h), "psd": {}, "units": {}, "peaks": {},
           "rms": {}, "signal_units": {}}
    for name, signal_unit, unit in SIGNALS:
        x = view.series(name)
        if x is None or len(x) == 0:
            continue
        x = np.asarray(x, float)[keep]
        f, P = welch_psd(x.T, fs, segment_s)          # station-major for the strut forces
        out["f_hz"] = f
        out["psd"][name] = P
        out["units"][name] = unit
        out["signal_units"][name] = signal_unit
        band = f > 0.2                                 # above the drift of the slow states
        rows = np.atleast_2d(P)
        out["peaks"][name] = [float(f[band][np.argmax(r[band])]) for r in rows]
        out["rms"][name] = [float(v) for v in np.atleast_1d(np.std(x, axis=0))]
    if out["f_hz"] is None:
        raise UserInputError(f"{view.name}: stores none of {', '.join(s for s, _, _ in SIGNALS)} "
                             "(output.store)")
    return out
