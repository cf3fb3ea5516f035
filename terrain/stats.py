"""Road statistics: Welch PSD, fitted Gd(n0) and w with standard errors, ISO class, RMS, coherence, IRI.

PSD: Welch, Hann window, 50 % overlap, one-sided [m³ = m²/(cycle/m)]. The segment is
long enough that the lowest fitted frequency is >= MIN_BINS_AT_FIT_LO bins (the
Hann window's smoothing bias on an n^-2 spectrum is then < 1 %).

Fit (ISO 8608 §5 form Gd(n) = Gd(n0)·(n/n0)^-w): the Welch bins are averaged in
1/3-octave bands inside the fit band; ln(band mean) is fitted by weighted
Gauss-Newton to ln(Gd(n0)·mean_band (n/n0)^-w) (the model averaged over the same
bins, so no band-centre bias), each band weighted by 1/var(ln P_band) with

    var(P_band)/P_band² = (1/K_eff) · Σ_jk P_j·P_k·r(|j-k|) / (Σ_j P_j)²

K_eff = K / (1 + 2·c²·(1 - 1/K)) for K segments (c = overlap correlation of the
window, 1/6 for Hann at 50 %; Welch 1967), r(d) = correlation of Welch bins d apart
(4/9, 1/36 for Hann). The two tracks are averaged (their correlation, γ², reduces
the gain). The returned standard errors (of ln Gd(n0) and of w) are the
inverse-Fisher ones of this weighted fit; tests use them as their tolerance.

IRI (Sayers 1995, ASTM E1926): the "golden car" quarter-car at 80 km/h over the
profile averaged over 250 mm; IRI = mean |ż_s - ż_u| / v [m/m], reported in m/km.
Simulated as an exact (first-order-hold) discrete filter, initialised on the
grade of the first 11 m as in the standard.
"""
from __future__ import annotations

import numpy as np
from scipy import signal

from hpsim.errors import UserInputError

from . import iso8608
from .envelope import envelope_profile

DEFAULT_FIT_BAND = (0.02, 2.0)  # cycle/m: inside the ISO band 0.011-2.83 with margin for its edges
BANDS_PER_OCTAVE = 3
MIN_BINS_AT_FIT_LO = 16
MIN_PSD_POINTS = 32          # two Welch segments of the shortest (16 points)
COHERENCE_AT = iso8608.N0_CYCLE_PER_M  # 0.1 cycle/m

# IRI golden car (Sayers 1995), per unit sprung mass
IRI_K_TYRE = 653.0  # kt/ms [1/s²]
IRI_K_SUSP = 63.3  # ks/ms [1/s²]
IRI_C_SUSP = 6.0  # cs/ms [1/s]
IRI_MU = 0.15  # mu/ms [-]
IRI_SPEED = 80.0 / 3.6  # m/s
IRI_BASELENGTH = 0.25  # m, moving average of the profile
IRI_LEADIN = 11.0  # m, the initial state follows the profile's grade over this length


def _window_correlations(nperseg: int) -> tuple[float, np.ndarray]:
    """(overlap correlation c at 50 %, bin correlation r(d) for d = 0..2) of the Hann window."""
    w = signal.get_window("hann", nperseg)
    w2 = w * w
    c = float(np.sum(w[: nperseg - nperseg // 2] * w[nperseg // 2:]) / np.sum(w2))
    t = np.arange(nperseg)
    r = np.array([abs(np.sum(w2 * np.exp(-2j * np.pi * d * t / nperseg))) ** 2 for d in range(3)])
    return c, r / r[0]


def choose_nperseg(n_points: int, spacing_m: float, fit_lo: float) -> int:
    want = MIN_BINS_AT_FIT_LO / (fit_lo * spacing_m)
    nperseg = int(2 ** int(np.ceil(np.log2(want))))
    while nperseg > n_points and nperseg > 16:
        nperseg //= 2
    return nperseg


def welch_spectra(left: np.ndarray, right: np.ndarray, spacing_m: float, nperseg: int):
    """(n [cycle/m], G_LL, G_RR, G_LR) one-sided Welch estimates (Hann, 50 % overlap)."""
    kw = dict(fs=1.0 / spacing_m, window="hann", nperseg=nperseg, noverlap=nperseg // 2,
              detrend="constant", scaling="density")
    f, pll = signal.welch(left, **kw)
    _, prr = signal.welch(right, **kw)
    _, plr = signal.csd(left, right, **kw)
    return f, pll, prr, plr


def octave_bands(lo: float, hi: float, per_octave: int = BANDS_PER_OCTAVE) -> np.ndarray:
    """Log-spaced band edges from lo to hi, about 1/per_octave octave wide."""
    count = max(1, int(np.round(np.log2(hi / lo) * per_octave)))
    return np.geomspace(lo, hi, count + 1)


def band_average(f, p, edges, k_eff, r):
    """Per band: (bin index arrays, mean P, relative variance of the mean)."""
    idx, mean, relvar = [], [], []
    for a, b in zip(edges[:-1], edges[1:]):
        j = np.nonzero((f >= a) & (f < b))[0]
        if j.size == 0:
            continue
        pj = p[j]
        s = pj.sum()
        if not s > 0:
            continue
        acc = np.sum(pj * pj) * r[0]
        for d in (1, 2):
            if j.size > d:
                acc += 2.0 * np.sum(pj[:-d] * pj[d:]) * r[d]
        v = acc / (s * s) / k_eff
        idx.append(j)
        mean.append(s / j.size)
        relvar.append(v)
    return idx, np.array(mean), np.array(relvar)


def coherence_se(gamma, relvar_track):
    """Standard error of a band-averaged coherence estimate: (1 - γ²)/sqrt(2·n_eff).

    n_eff = 1/relvar of one track's band mean is the number of independent complex spectral
    samples in the band; the normalised co-spectrum behaves like a correlation coefficient
    estimated from 2·n_eff real pairs (Fisher: se ≈ (1 - ρ²)/sqrt(n)).
    """
    g = np.nan_to_num(np.asarray(gamma, dtype=float))
    return (1.0 - g * g) * np.sqrt(np.asarray(relvar_track) / 2.0)


def fit_power_law(f, idx, band_mean, band_relvar):
    """Weighted Gauss-Newton fit of ln(band mean) -> (Gd(n0), w, se of ln Gd(n0), se of w)."""
    if len(idx) < 2:
        return np.nan, np.nan, np.nan, np.nan
    x = [np.log(f[j] / iso8608.N0_CYCLE_PER_M) for j in idx]
    y = np.log(band_mean) + 0.5 * band_relvar  # E[ln P̂] ≈ ln P - var/2
    wts = 1.0 / band_relvar
    xc = np.array([xi.mean() for xi in x])
    w = -np.polyfit(xc, y, 1, w=np.sqrt(wts))[0]
    a = np.average(y + w * xc, weights=wts)
    for _ in range(20):
        model = np.empty(len(x))
        dmodel = np.empty(len(x))
        for i, xi in enumerate(x):
            e = np.exp(-w * (xi - xi.max()))
            model[i] = np.log(e.mean()) - w * xi.max()
            dmodel[i] = -np.sum(e * xi) / e.sum()
        res = y - (a + model)
        jac = np.column_stack([np.ones(len(x)), dmodel])
        jtw = jac.T * wts
        info = jtw @ jac
        step = np.linalg.solve(info, jtw @ res)
        a += step[0]
        w += step[1]
        if np.max(np.abs(step)) < 1e-12:
            break
    cov = np.linalg.inv(info)
    return float(np.exp(a)), float(w), float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))


def iri_m_per_km(height_m: np.ndarray, spacing_m: float) -> float:
    """International Roughness Index [m/km] of one track (golden car, see module docstring)."""
    z = np.asarray(height_m, dtype=float)
    if z.size < 3:
        return float("nan")
    # Sayers' start: the car already moves along the grade of the first 11 m (state x0 = (z0, g·v,
    # z0, g·v)). A constant grade gives no relative motion, so by linearity this equals removing
    # the grade line and starting at rest.
    k = int(round(IRI_LEADIN / spacing_m))
    grade = (z[k] - z[0]) / (k * spacing_m) if 0 < k < z.size else 0.0
    z = z - z[0] - grade * spacing_m * np.arange(z.size)
    if spacing_m < IRI_BASELENGTH:
        z = envelope_profile(z, IRI_BASELENGTH, spacing_m)
    # states: z_s, v_s, z_u, v_u; input: profile height y; output v_s - v_u
    a = np.array([[0.0, 1.0, 0.0, 0.0],
                  [-IRI_K_SUSP, -IRI_C_SUSP, IRI_K_SUSP, IRI_C_SUSP],
                  [0.0, 0.0, 0.0, 1.0],
                  [IRI_K_SUSP / IRI_MU, IRI_C_SUSP / IRI_MU, -(IRI_K_SUSP + IRI_K_TYRE) / IRI_MU,
                   -IRI_C_SUSP / IRI_MU]])
    b = np.array([[0.0], [0.0], [0.0], [IRI_K_TYRE / IRI_MU]])
    c = np.array([[0.0, 1.0, 0.0, -1.0]])
    d = np.zeros((1, 1))
    ad, bd, cd, dd, _ = signal.cont2discrete((a, b, c, d), spacing_m / IRI_SPEED, method="foh")
    zeros, poles, gain = signal.ss2zpk(ad, bd, cd, dd)
    sos = signal.zpk2sos(zeros, poles, gain)
    rel_velocity = signal.sosfilt(sos, z)
    return float(np.mean(np.abs(rel_velocity)) / IRI_SPEED * 1000.0)


def _finite(x):
    """float, or None for NaN/inf (JSON has no NaN)."""
    return float(x) if x is not None and np.isfinite(x) else None


def _check_long_enough(road) -> None:
    """UserInputError when the profile is too short for two Welch segments."""
    dx = road.spacing_m
    if road.n_points < MIN_PSD_POINTS:
        raise UserInputError(f"road profile: {road.n_points} points ({(road.n_points - 1) * dx:.6g} m at {dx:.6g} m); "
                             f"its spectrum needs at least {MIN_PSD_POINTS} (two Welch segments of "
                             f"{MIN_PSD_POINTS // 2}): give a longer profile")


def _track_fits(f, tracks_in: dict, edges, k_eff, r, dx: float, iri: bool) -> tuple[dict, dict]:
    """Per track (name -> (its PSD, its profile)): the power-law fit, its class, RMS and IRI; and the relative
    variances of its band averages."""
    tracks, track_relvar = {}, {}
    for name, (p, z) in tracks_in.items():
        j, pm, rv = band_average(f, p, edges, k_eff, r)
        track_relvar[name] = rv
        g1, w1, sg1, sw1 = fit_power_law(f, j, pm, rv)
        tracks[name] = {"gd_n0_m3": _finite(g1), "gd_n0_rel_se": _finite(sg1), "waviness": _finite(w1),
                        "waviness_se": _finite(sw1), "iso_class": iso8608.class_of_gd(g1),
                        "rms_m": float(np.std(z)), "iri_m_per_km": iri_m_per_km(z, dx) if iri else None}
    return tracks, track_relvar


def _coherence_at_n0(f, pll, prr, plr) -> float | None:
    """The coherence of the two tracks in the 1/3-octave band centred on COHERENCE_AT (0.1 cycle/m)."""
    a, b = COHERENCE_AT * 2.0 ** (-1.0 / 6.0), COHERENCE_AT * 2.0 ** (1.0 / 6.0)
    j = np.nonzero((f >= a) & (f < b))[0]
    denom = np.sqrt(pll[j].sum() * prr[j].sum()) if j.size else 0.0
    return float(np.real(plr[j].sum()) / denom) if denom > 0 else None


def _bands(f, idx, pmean, relvar, gamma_band, left_relvar) -> dict:
    """The fit band's octave bands: centre frequencies, mean PSD of both tracks, its relative standard error, the
    coherence and its standard error."""
    return {
        "centre_cycle_per_m": np.array([np.exp(np.mean(np.log(f[j]))) for j in idx]),
        "psd_m3": pmean,
        "rel_se": np.sqrt(relvar),
        "coherence": gamma_band,
        "coherence_se": coherence_se(gamma_band, left_relvar) if len(idx) == len(left_relvar)
        else np.full(len(idx), np.nan),
    }


def road_statistics(road, fit_band: tuple[float, float] = DEFAULT_FIT_BAND, nperseg: int | None = None,
                    iri: bool = True) -> dict:
    """Statistics of a Road (see module docstring). Scalars first, then arrays for plots."""
    dx = road.spacing_m
    left, right = road.left_m, road.right_m
    _check_long_enough(road)
    nyq = 0.5 / dx
    lo, hi = fit_band
    hi = min(hi, 0.5 * nyq)
    if nperseg is None:
        nperseg = choose_nperseg(road.n_points, dx, lo)
    lo = max(lo, MIN_BINS_AT_FIT_LO / (nperseg * dx))
    f, pll, prr, plr = welch_spectra(left, right, dx, nperseg)
    k = 1 + (road.n_points - nperseg) // (nperseg // 2)
    c, r = _window_correlations(nperseg)
    k_eff = k / (1.0 + 2.0 * c * c * (1.0 - 1.0 / k)) if k > 1 else 1.0
    edges = octave_bands(lo, hi) if hi > lo else np.array([lo, lo])

    with np.errstate(invalid="ignore", divide="ignore"):
        gamma_bins = np.real(plr) / np.sqrt(pll * prr)
    both = 0.5 * (pll + prr)
    idx, pmean, relvar = band_average(f, both, edges, k_eff, r)
    with np.errstate(invalid="ignore", divide="ignore"):          # a flat track: no coherence (NaN), no warning
        gamma_band = np.array([np.real(plr[j].sum()) / np.sqrt(pll[j].sum() * prr[j].sum()) for j in idx])
    # averaging the two tracks halves the variance only for independent tracks: factor (1 + γ²)/2
    relvar = relvar * 0.5 * (1.0 + np.nan_to_num(gamma_band) ** 2)
    gd, w, se_gd, se_w = fit_power_law(f, idx, pmean, relvar)

    tracks, track_relvar = _track_fits(f, {"left": (pll, left), "right": (prr, right)}, edges, k_eff, r, dx, iri)
    coh01 = _coherence_at_n0(f, pll, prr, plr)

    rms = float(np.sqrt(0.5 * (np.var(left) + np.var(right))))
    iri_mean = _finite(0.5 * (tracks["left"]["iri_m_per_km"] + tracks["right"]["iri_m_per_km"])) if iri else None
    return {
        "gd_n0_m3": _finite(gd),
        "gd_n0_rel_se": _finite(se_gd),
        "waviness": _finite(w),
        "waviness_se": _finite(se_w),
        "iso_class": iso8608.class_of_gd(gd),
        "rms_m": rms,
        "coherence_at_0p1_cycle_per_m": coh01,
        "iri_m_per_km": iri_mean,
        "length_m": road.length_m,
        "spacing_m": dx,
        "fit_band_cycle_per_m": [float(edges[0]), float(edges[-1])],
        "welch_segments": int(k),
        "welch_segments_effective": float(k_eff),
        "segment_length_m": nperseg * dx,
        "tracks": tracks,
        "bands": _bands(f, idx, pmean, relvar, gamma_band, track_relvar["left"]),
        "frequency_cycle_per_m": f,
        "psd_left_m3": pll,
        "psd_right_m3": prr,
        "coherence": gamma_bins,
    }
