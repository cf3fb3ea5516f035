"""Figures: road profile and its PSD against the ISO 8608 class bands (matplotlib, Agg backend)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError

from . import iso8608

PROFILE_MAX_POINTS = 20000  # profile overview is drawn as a min/max envelope beyond this
OVERVIEW_CHUNKS = 100       # a long profile's overview: range and RMS over this many chunks
DETAIL_LENGTH_M = 200.0  # length of the zoomed profile panel
# half-width of the Hann window's main lobe in Welch bins (Harris 1978): a bin this close to a band edge mixes
# the power on both sides of it
HANN_MAIN_LOBE_BINS = 2.0


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def draw_class_bands(ax, n_range=iso8608.DEFAULT_BAND_CYCLE_PER_M):
    """Shade the ISO 8608 classes (limits at half/double the geometric mean, w = 2) and label them."""
    n = np.geomspace(*n_range, 50)
    for i, name in enumerate(iso8608.ISO_CLASSES):
        lo, hi = iso8608.class_limits(name)
        g_lo = iso8608.displacement_psd(n, lo)
        g_hi = iso8608.displacement_psd(n, hi)
        ax.fill_between(n, g_lo, g_hi, color="0.85" if i % 2 else "0.93", lw=0, zorder=0)
        ax.text(n[-1] * 1.05, iso8608.displacement_psd(n[-1], iso8608.ISO_CLASS_GD_N0_M3[name]),
                name, va="center", fontsize=8, color="0.35")


def psd_drawn(f: np.ndarray, band=iso8608.DEFAULT_BAND_CYCLE_PER_M) -> np.ndarray:
    """Mask of the Welch bins `f` [cycle/m] whose estimate is drawn: inside the ISO 8608 band, where its classes
    are defined, and at least HANN_MAIN_LOBE_BINS bins from its edges (a bin nearer mixes in the power beyond
    the edge: a generated road has none there, so the estimate falls away)."""
    df = f[1] - f[0] if f.size > 1 else 0.0
    margin = HANN_MAIN_LOBE_BINS * df
    return (f >= band[0] + margin) & (f <= band[1] - margin)


def draw_psd(ax, stats: dict):
    """The Welch PSD of both tracks over the ISO 8608 band, its 1/3-octave means and fit, on the class bands."""
    f = stats["frequency_cycle_per_m"]
    keep = psd_drawn(f)
    lo, hi = iso8608.DEFAULT_BAND_CYCLE_PER_M
    draw_class_bands(ax)
    where = f"{lo:g}-{hi:g} cycle/m"       # the ISO band: the legend says the estimate stops at its edges
    ax.loglog(f[keep], stats["psd_left_m3"][keep], lw=0.7, label=f"left (Welch, {where})")
    ax.loglog(f[keep], stats["psd_right_m3"][keep], lw=0.7, alpha=0.7, label=f"right (Welch, {where})")
    bands = stats["bands"]
    if len(bands["centre_cycle_per_m"]):
        ax.loglog(bands["centre_cycle_per_m"], bands["psd_m3"], "ko", ms=3, label="1/3-octave mean")
    if stats["gd_n0_m3"]:
        fit_lo, fit_hi = stats["fit_band_cycle_per_m"]
        n = np.geomspace(fit_lo, fit_hi, 20)
        ax.loglog(n, iso8608.displacement_psd(n, stats["gd_n0_m3"], stats["waviness"]), "r--",
                  label=f"fit: Gd(n0)={stats['gd_n0_m3'] * 1e6:.4g}e-6 m³, w={stats['waviness']:.3f} "
                        f"(class {stats['iso_class']})")
    pos = np.concatenate([stats["psd_left_m3"][keep], stats["psd_right_m3"][keep]])
    pos = pos[pos > 0]
    if pos.size:  # the class bands and the drawn PSD decide the scale
        g_min = iso8608.displacement_psd(hi, iso8608.class_limits(iso8608.ISO_CLASSES[0])[0])
        ax.set_ylim(min(pos.min(), g_min) / 3.0, pos.max() * 10)
    # the drawn estimate, and room for the class labels right of the band
    ax.set_xlim((f[keep][0] if keep.any() else lo) / 1.2, hi * 1.8)
    ax.set_xlabel("spatial frequency n [cycle/m]")
    ax.set_ylabel("Gd(n) [m³]")
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2, frameon=False)
    ax.grid(True, which="both", lw=0.3)


def _envelope(d, z, npts):
    if d.size <= npts:
        return d, z, z
    step = int(np.ceil(d.size / npts))
    m = d.size // step * step
    zz = z[:m].reshape(-1, step)
    return d[:m:step], zz.min(axis=1), zz.max(axis=1)


def save_psd_plot(stats: dict, path: str | Path, title: str = "") -> None:
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 5.4), layout="constrained")
    draw_psd(ax, stats)
    ax.set_title(title or "Road displacement PSD against ISO 8608 classes", fontsize=10)
    _save(fig, path, plt)


def save_road_plot(road, stats: dict, path: str | Path, title: str = "") -> None:
    plt = _pyplot()
    fig = plt.figure(figsize=(10, 9), layout="constrained")
    ax1 = fig.add_subplot(3, 1, 1)
    d = road.distance_m
    n = min(road.n_points, int(DETAIL_LENGTH_M / road.spacing_m) + 1)
    for (z, name), color in zip(((road.left_m, "left"), (road.right_m, "right")), ("C0", "C1")):
        if d.size <= PROFILE_MAX_POINTS and road.length_m <= 5 * DETAIL_LENGTH_M:
            ax1.plot(d / 1000.0, z, lw=0.5, color=color, label=name)
            continue
        # a long profile: the range (min/max of both tracks) and each track's RMS over each of OVERVIEW_CHUNKS
        # chunks (no peak is lost, changes of roughness along the road show); the first DETAIL_LENGTH_M below
        x, lo, hi = _envelope(d, z, OVERVIEW_CHUNKS)
        step = d.size // x.size
        zz = z[:x.size * step].reshape(-1, step)
        rms = np.sqrt(np.mean((zz - zz.mean(axis=1, keepdims=True)) ** 2, axis=1))
        chunk = d[1] * step
        ax1.fill_between(x / 1000.0, lo, hi, color=color, lw=0, alpha=0.2, step="post",
                         label=f"{name}: min-max per {chunk:.3g} m")
        ax1.step(x / 1000.0, rms, where="post", color=color, lw=1.2, label=f"{name}: RMS per {chunk:.3g} m")
        ax1.step(x / 1000.0, -rms, where="post", color=color, lw=1.2)
    if n < road.n_points and road.length_m > 5 * DETAIL_LENGTH_M:      # a long road: where the detail is
        ax1.axvspan(0, d[n - 1] / 1000.0, color="0.5", alpha=0.25, lw=0, label=f"first {d[n - 1]:.0f} m (below)")
    ax1.set_xlabel("distance [km]")
    ax1.set_ylabel("height [m]")
    ax1.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=3, frameon=False)
    ax1.set_title(title or f"Road profile ({road.length_m / 1000:.3g} km at {road.spacing_m * 1000:.3g} mm)",
                  fontsize=10)
    ax2 = fig.add_subplot(3, 1, 2)
    ax2.set_title(f"the first {d[n - 1]:.0f} m", fontsize=9)
    ax2.plot(d[:n], road.left_m[:n], lw=0.8, label="left")
    ax2.plot(d[:n], road.right_m[:n], lw=0.8, label="right")
    ax2.set_xlabel("distance [m]")
    ax2.set_ylabel("height [m]")
    ax2.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.2), ncol=2, frameon=False)
    ax3 = fig.add_subplot(3, 1, 3)
    draw_psd(ax3, stats)
    _save(fig, path, plt)


def _save(fig, path, plt):
    try:
        fig.savefig(path, dpi=110)
    except (OSError, ValueError) as exc:
        raise UserInputError(f"{path}: cannot write the figure ({exc})") from None
    finally:
        plt.close(fig)
