"""Tyre enveloping: a moving average over the tyre contact length (REFERENCE §5).

A tyre cannot follow wavelengths shorter than its contact patch; the simplest
model that captures this is the average of the road height over the contact
length L (≈ 0.3-0.45 m for a 14.00R20 tyre, REFERENCE §5). Continuous transfer
function: H(n) = sin(π·n·L) / (π·n·L).

On a grid of spacing Δ the length is honoured exactly (not rounded to a whole
number of samples): L/Δ = (2k+1) + 2f with 0 <= f < 1; the kernel has weight 1 on
the 2k+1 central samples and f on the two next ones, divided by L/Δ. Its exact
transfer function is

    H_d(n) = [ sin(π·n·(2k+1)·Δ) / sin(π·n·Δ) + 2·f·cos(2π·n·(k+1)·Δ) ] / (L/Δ)

which tends to the continuous sinc as Δ → 0 (and equals the discrete moving
average when L/Δ is an odd integer).
"""
from __future__ import annotations

import numpy as np


def contact_kernel(contact_length_m: float, spacing_m: float) -> np.ndarray:
    """Symmetric averaging kernel (odd length, sums to 1) for contact length L on spacing Δ."""
    if not (contact_length_m > 0 and spacing_m > 0):
        raise ValueError("contact length and spacing must be > 0")
    ratio = contact_length_m / spacing_m
    k = int(np.floor((ratio - 1.0) / 2.0 + 1e-9))
    if k < 0:  # shorter than one sample: identity
        return np.ones(1)
    f = max(0.0, (ratio - (2 * k + 1)) / 2.0)
    if f < 1e-9:
        return np.full(2 * k + 1, 1.0 / ratio)
    w = np.ones(2 * k + 3)
    w[0] = w[-1] = f
    return w / ratio


def envelope_transfer(n_cycle_per_m, contact_length_m: float, spacing_m: float | None = None):
    """Gain of the contact-length average: exact discrete H_d(n) if spacing is given, else sinc."""
    n = np.asarray(n_cycle_per_m, dtype=float)
    if spacing_m is None:
        return np.sinc(n * contact_length_m)  # np.sinc(x) = sin(πx)/(πx)
    ratio = contact_length_m / spacing_m
    k = int(np.floor((ratio - 1.0) / 2.0 + 1e-9))
    if k < 0:
        return np.ones_like(n)
    f = max(0.0, (ratio - (2 * k + 1)) / 2.0)
    m = 2 * k + 1
    # sin(π n m Δ)/sin(π n Δ) = m·sinc(n m Δ)/sinc(n Δ), well defined at n = 0
    dirichlet = m * np.sinc(n * m * spacing_m) / np.sinc(n * spacing_m)
    return (dirichlet + 2.0 * f * np.cos(2.0 * np.pi * n * (k + 1) * spacing_m)) / ratio


def envelope_profile(height_m: np.ndarray, contact_length_m: float, spacing_m: float) -> np.ndarray:
    """Average `height_m` (uniform grid) over the contact length; ends padded with the end values."""
    kernel = contact_kernel(contact_length_m, spacing_m)
    if kernel.size == 1:
        return np.array(height_m, dtype=float, copy=True)
    from scipy.ndimage import convolve1d      # here, not at the top: a road from the store needs no SciPy import

    return convolve1d(np.asarray(height_m, dtype=float), kernel, mode="nearest")
