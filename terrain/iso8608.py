"""ISO 8608 road classes, the displacement PSD and seeded generation of random profiles.

Displacement PSD (ISO 8608:2016 §5, REFERENCE §5):

    Gd(n) = Gd(n0) · (n / n0)^(-w),   n0 = 0.1 cycle/m, w = 2 (waviness)

n is the spatial frequency [cycle/m]; Gd is one-sided [m²/(cycle/m) = m³].
The classes A..H are given by the *geometric mean* Gd(n0) of each class, the class
limits are at half and double of it (ISO 8608 Table 1). Using the upper limits as
the class value makes the road twice too rough (in Gd) — a common mistake.

Generation: Gaussian white noise (PCG64, `numpy.random.default_rng`) shaped by a
long linear-phase FIR filter whose gain is sqrt(Gd(n)/(2·Δ)) inside the band and
zero outside, applied by FFT overlap-save in fixed blocks (streaming: O(N log M)
time, memory bounded by the block size). Because the noise streams and the block
partition do not depend on the road length, a shorter road with the same
parameters and seed is bit-for-bit the beginning of a longer one.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np

from hpsim.threads import beside_map

N0_CYCLE_PER_M = 0.1  # reference spatial frequency n0 [cycle/m], ISO 8608 §5
WAVINESS_ISO = 2.0  # w for the class definitions, ISO 8608 §5
DEFAULT_BAND_CYCLE_PER_M = (0.011, 2.83)  # ISO 8608 spatial band (wavelengths 91 m .. 0.35 m), REFERENCE §5

# ISO 8608 Table 1 (REFERENCE §5): class -> geometric-mean Gd(n0) [m³]; limits at half / double.
# Each class is a factor 4 rougher than the previous one.
ISO_CLASS_GD_N0_M3: dict[str, float] = {
    "A": 16e-6,
    "B": 64e-6,
    "C": 256e-6,
    "D": 1024e-6,
    "E": 4096e-6,
    "F": 16384e-6,
    "G": 65536e-6,
    "H": 262144e-6,
}
CLASS_LIMIT_FACTOR = 2.0  # lower limit = mean / 2, upper limit = mean * 2 (ISO 8608 Table 1)
ISO_CLASSES = tuple(ISO_CLASS_GD_N0_M3)

# Generation filter: its length in metres is FILTER_CYCLES_AT_NMIN longest wavelengths, so the
# (Hann-windowed) response is smoothed over only ~2/FILTER_CYCLES_AT_NMIN of n_min at the band's low
# edge (for w = 2 the profile variance comes out 0.5 % below ∫Gd dn, 1.1 % with 64 cycles).
FILTER_CYCLES_AT_NMIN = 128
FFT_BLOCK_FACTOR = 4  # overlap-save FFT size = FFT_BLOCK_FACTOR x filter length
MAX_FILTER_TAPS = 2 ** 19 - 1  # memory cap (working set ~250 MB); fewer cycles at n_min beyond it


def class_limits(iso_class: str) -> tuple[float, float]:
    """(lower, upper) Gd(n0) limits [m³] of an ISO 8608 class (A has no lower, H no upper limit in use)."""
    gm = ISO_CLASS_GD_N0_M3[iso_class]
    return gm / CLASS_LIMIT_FACTOR, gm * CLASS_LIMIT_FACTOR


def class_of_gd(gd_n0_m3: float) -> str | None:
    """ISO class whose limits contain Gd(n0) [m³]; open-ended below A and above H; None if not > 0."""
    if not np.isfinite(gd_n0_m3) or gd_n0_m3 <= 0:
        return None
    for name in ISO_CLASSES:
        if gd_n0_m3 < class_limits(name)[1]:
            return name
    return ISO_CLASSES[-1]


def displacement_psd(n_cycle_per_m, gd_n0_m3: float, waviness: float = WAVINESS_ISO,
                     band: tuple[float, float] | None = None):
    """Gd(n) [m³] (ISO 8608 §5); zero outside `band` if given."""
    n = np.asarray(n_cycle_per_m, dtype=float)
    with np.errstate(divide="ignore"):
        g = gd_n0_m3 * (np.where(n > 0, n, np.inf) / N0_CYCLE_PER_M) ** (-waviness)
    if band is not None:
        g = np.where((n >= band[0]) & (n <= band[1]), g, 0.0)
    return g


def band_variance(gd_n0_m3: float, waviness: float, band: tuple[float, float]) -> float:
    """Profile variance [m²] = ∫ Gd(n) dn over the band (analytic)."""
    n1, n2 = band
    if abs(waviness - 1.0) < 1e-12:
        return gd_n0_m3 * N0_CYCLE_PER_M * np.log(n2 / n1)
    p = 1.0 - waviness
    return gd_n0_m3 * N0_CYCLE_PER_M ** waviness * (n2 ** p - n1 ** p) / p


def filter_taps(spacing_m: float, band: tuple[float, float]) -> int:
    """Odd number of taps of the shaping filter (a power of two minus one)."""
    n_needed = FILTER_CYCLES_AT_NMIN / (band[0] * spacing_m)
    return min(int(2 ** int(np.ceil(np.log2(max(n_needed, 64))))) - 1, MAX_FILTER_TAPS)


@dataclass(frozen=True)
class ShapingFilters:
    """Frequency responses (on the overlap-save FFT grid) of the track filters.

    left = h * w1;  right = h_c * w1 + h_i * w2, with H_c = γ·H, H_i = sqrt(1-γ²)·H, where γ(n)
    is the track coherence (normalised real cross-spectrum), so that both tracks have PSD Gd(n)
    and cross-spectrum γ(n)·Gd(n).
    """

    n_taps: int
    fft_size: int
    left: np.ndarray
    right_coherent: np.ndarray | None
    right_independent: np.ndarray | None


def _design_fir(gain: np.ndarray, n_fft_design: int) -> np.ndarray:
    """Zero-phase Hann-windowed FIR (n_fft_design - 1 taps) from a real gain on the rfft grid."""
    h = np.fft.irfft(gain, n_fft_design)
    h = np.fft.fftshift(h)  # centre at n_fft_design // 2
    h *= np.hanning(n_fft_design + 1)[:-1]  # periodic Hann, zero at index 0, peak at the centre
    return h[1:]  # odd length, symmetric about its middle


def shaping_filters(gd_n0_m3: float, waviness: float, spacing_m: float, band: tuple[float, float],
                    coherence: Callable[[np.ndarray], np.ndarray] | None) -> ShapingFilters:
    """Design the filters. `coherence(n)` -> γ(n) in [0, 1]; None means independent tracks."""
    n_taps = filter_taps(spacing_m, band)
    n_design = n_taps + 1
    n = np.fft.rfftfreq(n_design, d=spacing_m)
    gain = np.sqrt(displacement_psd(n, gd_n0_m3, waviness, band) / (2.0 * spacing_m))
    fft_size = FFT_BLOCK_FACTOR * n_design
    taps = {"left": _design_fir(gain, n_design)}
    if coherence is not None:
        gamma = np.clip(coherence(n), 0.0, 1.0)
        taps["right_coherent"] = _design_fir(gain * gamma, n_design)
        taps["right_independent"] = _design_fir(gain * np.sqrt(1.0 - gamma ** 2), n_design)
    spectra = dict(zip(taps, beside_map(lambda h: np.fft.rfft(h, fft_size), taps.values())))
    return ShapingFilters(n_taps, fft_size, spectra["left"], spectra.get("right_coherent"),
                          spectra.get("right_independent"))


def _noise_spectrum(rng: np.random.Generator, tail: np.ndarray, block: int) -> tuple[np.ndarray, np.ndarray]:
    """(segment, its rfft): the overlap-save input segment, the previous segment's tail then `block` new samples."""
    seg = np.concatenate([tail, rng.standard_normal(block)])
    return seg, np.fft.rfft(seg)


def _noise_streams(seed: int, count: int) -> list[np.random.Generator]:
    """Independent PCG64 streams for the white noise, derived from one seed (reproducible anywhere)."""
    children = np.random.SeedSequence(seed).spawn(count)
    return [np.random.default_rng(c) for c in children]


def iter_track_blocks(gd_n0_m3: float, waviness: float, spacing_m: float, n_points: int, seed: int,
                      band: tuple[float, float], coherence: str,
                      coherence_fn: Callable[[np.ndarray], np.ndarray] | None = None,
                      ) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """Yield (start_index, left_block, right_block) covering n_points samples.

    coherence: "identical" (right = left), "independent", or "model" (use coherence_fn(n) -> γ).
    """
    filt = shaping_filters(gd_n0_m3, waviness, spacing_m, band,
                           coherence_fn if coherence == "model" else None)
    m = filt.n_taps
    block = filt.fft_size - m + 1  # new outputs per overlap-save block
    rng1, rng2 = _noise_streams(seed, 2)
    need_w2 = coherence != "identical"
    tails = [rng1.standard_normal(m - 1)] + ([rng2.standard_normal(m - 1)] if need_w2 else [])
    rngs = [rng1, rng2][:len(tails)]
    start = 0
    while start < n_points:
        # each track's noise stream and transform on its own thread (numpy leaves Python's lock)
        (seg1, w1), *second = beside_map(lambda k: _noise_spectrum(rngs[k], tails[k], block), range(len(tails)))
        if coherence == "identical":
            left = np.fft.irfft(w1 * filt.left, filt.fft_size)[m - 1:]
            right = left
        else:
            seg2, w2 = second[0]
            spectra = [w1 * filt.left, w2 * filt.left if coherence == "independent" else
                       w1 * filt.right_coherent + w2 * filt.right_independent]
            left, right = (a[m - 1:] for a in beside_map(lambda w: np.fft.irfft(w, filt.fft_size), spectra))
            tails[1] = seg2[block:]
        tails[0] = seg1[block:]
        take = min(block, n_points - start)
        yield start, left[:take], right[:take]
        start += take


def generate_tracks(gd_n0_m3: float, waviness: float, spacing_m: float, n_points: int, seed: int,
                    band: tuple[float, float] = DEFAULT_BAND_CYCLE_PER_M, coherence: str = "independent",
                    coherence_fn: Callable[[np.ndarray], np.ndarray] | None = None,
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Left and right track heights [m] on a uniform grid of `n_points` samples at `spacing_m`."""
    left = np.empty(n_points)
    right = left if coherence == "identical" else np.empty(n_points)
    for i0, lb, rb in iter_track_blocks(gd_n0_m3, waviness, spacing_m, n_points, seed, band, coherence,
                                        coherence_fn):
        left[i0:i0 + lb.size] = lb
        if right is not left:
            right[i0:i0 + rb.size] = rb
    if right is left:
        right = left.copy()
    return left, right
