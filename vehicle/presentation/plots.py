"""Figures of drive results: the dashboard of one run (`hpsim plot`) and the comparison of several
runs (`hpsim compare --plot`, sweeps). Matplotlib with the Agg backend (no display needed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vehicle.presentation.report import compare, open_results, report_from

MECHANISMS = (("valve", "valve (damping)"), ("friction", "seal friction"), ("gas", "gas heat"),
              ("end_stop", "end stops"))


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _moving_mean(y: np.ndarray, window: int) -> np.ndarray:
    """Centred moving mean along axis 0 (edges: shorter windows)."""
    if window <= 1 or len(y) < 3:
        return y
    window = min(window, len(y))
    kernel = np.ones(window)
    y2 = y if y.ndim == 2 else y[:, None]
    num = np.stack([np.convolve(y2[:, j], kernel, mode="same") for j in range(y2.shape[1])], axis=1)
    den = np.convolve(np.ones(len(y)), kernel, mode="same")[:, None]
    out = num / den
    return out if y.ndim == 2 else out[:, 0]


def _series(r, name):
    """A time series of the results (vehicle.runs.reader.ResultsView), rows covered by the checkpoint."""
    return r.series(name)


def dashboard(path: str | Path, out: str | Path) -> Path:
    """2 x 2 figure: strut temperature and height change per axle vs distance, wheel loads
    before/after, dissipated power by mechanism vs distance."""
    plt = _plt()
    out = Path(out)
    with open_results(path) as f:
        rep = report_from(f, str(path))
        axles, stations = f.axles, f.stations
        s_km = _series(f, "distance")
        s_km = None if s_km is None else s_km / 1e3
        t_all = _series(f, "time")
        sample_dt = float(np.median(np.diff(t_all))) if t_all is not None and len(t_all) > 1 else 1.0
        T = _series(f, "strut_temperature")
        h = _series(f, "axle_height_change")
        before, after = f.equilibrium("before"), f.equilibrium("after")
        N_before = np.asarray(before["wheel_load"], float)
        N_after = np.asarray(after["wheel_load"], float) if after is not None else None
        h_before = np.asarray(before["axle_height_change"], float)
        s_stats = f.stats_series("km")
        n_rows = 0 if s_stats is None else len(s_stats)
        power = {}
        if n_rows >= 2:
            for key, _ in MECHANISMS:
                P = f.stats_series(f"power_{key}")
                if P is not None:
                    power[key] = P.sum(axis=1)
            power_x = s_stats
            power_how = "per statistics interval"
        else:
            power_x = None
            t = _series(f, "time")
            for key, _ in MECHANISMS:
                E = _series(f, f"energy_{key}")
                if E is not None and t is not None and len(t) >= 2:
                    power[key] = np.gradient(E.sum(axis=1), t)
            power_x = s_km
            power_how = "from the energy time series"

    fig, ax = plt.subplots(2, 2, figsize=(13, 8.5), constrained_layout=True)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    title = (f"{Path(path).name}: {rep['distance_km']:.2f} km, compensation "
             f"{'on' if rep['compensation'] else 'off'}, {rep['status']}")
    fig.suptitle(title)
    # temperatures
    a = ax[0, 0]
    if T is not None and s_km is not None:
        Tax = 0.5 * (T[:, 0::2] + T[:, 1::2]) - 273.15
        for k, name in enumerate(axles):
            a.plot(s_km, Tax[:, k], color=colors[k % len(colors)], label=name)
    a.set(xlabel="distance [km]", ylabel="strut temperature [degC]", title="strut temperature (mean of left/right)")
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    # height change
    a = ax[0, 1]
    window_s = None
    if h is not None and s_km is not None and len(s_km) > 1:
        # the drift (heating) is slow, the road's bumps fast: a centred moving mean over about a
        # tenth of the drive (at most 600 samples) shows the drift
        window = int(np.clip(len(s_km) // 10, 1, 600))
        hs = _moving_mean(h, window)
        window_s = window * sample_dt
        for k, name in enumerate(axles):
            a.plot(s_km, (hs[:, k] - h_before[k]) * 1e3, color=colors[k % len(colors)], label=name)
    for k, r in enumerate(rep["axles"]):
        if r["dh_mm"] is not None and s_km is not None and len(s_km):
            a.plot([s_km[-1]], [r["dh_mm"]], marker="o", color=colors[k % len(colors)], ms=6)
    a.set(xlabel="distance [km]", ylabel="hull height change at the axle [mm]",
          title="height change vs before-drive equilibrium\n"
                + (f"(moving mean over {window_s:.0f} s; " if window_s else "(")
                + "dots: after-drive equilibrium)")
    a.title.set_fontsize(9)
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    # wheel loads
    a = ax[1, 0]
    x = np.arange(len(stations))
    w = 0.38
    a.bar(x - w / 2, N_before / 10.0, w, label="before drive")
    if N_after is not None:
        a.bar(x + w / 2, N_after / 10.0, w, label="after drive")
        for xi, nb, na in zip(x, N_before, N_after):
            a.annotate(f"{100 * (na - nb) / nb:+.1f}%", (xi + w / 2, na / 10.0), ha="center", va="bottom", fontsize=7)
    a.set_xticks(x, [s.replace("axle", "A").replace("_left", " L").replace("_right", " R") for s in stations])
    lo = min(N_before.min(), N_after.min() if N_after is not None else np.inf) / 10.0
    hi = max(N_before.max(), N_after.max() if N_after is not None else -np.inf) / 10.0
    a.set_ylim(lo - 0.15 * (hi - lo + 50), hi + 0.25 * (hi - lo + 50))
    a.set(ylabel="wheel load [daN]", title="wheel loads, static equilibrium before / after the drive")
    a.grid(alpha=0.3, axis="y")
    a.legend(fontsize=8)
    # dissipated power
    a = ax[1, 1]
    if power and power_x is not None:
        for key, label in MECHANISMS:
            if key in power:
                y = power[key] / 1e3
                if power_how.startswith("from"):
                    y = _moving_mean(y, max(1, min(60, len(y) // 20)))
                a.plot(power_x, y, label=label, marker="o" if len(power_x) < 30 else None, ms=3)
    a.set(xlabel="distance [km]", ylabel="dissipated power, all struts [kW]",
          title=f"dissipated power by mechanism ({power_how})")
    a.grid(alpha=0.3)
    a.legend(fontsize=8)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def compare_plot(paths, out: str | Path, labels=None) -> Path:
    """Grouped bars per axle: wheel-load change, height change and end temperature of each run."""
    plt = _plt()
    cmp = compare(paths)
    runs = cmp["runs"]
    labels = labels or [Path(r["file"]).stem for r in runs]
    n_ax = len(runs[0]["axles"])
    fig, ax = plt.subplots(1, 3, figsize=(max(12, 3 + 1.2 * n_ax * len(runs)), 4.5), constrained_layout=True)
    x = np.arange(n_ax)
    w = 0.8 / max(len(runs), 1)
    for panel, (key, ylabel) in zip(ax, (("dN_pct", "wheel load change dN [%]"), ("dh_mm", "height change dh [mm]"),
                                         ("T_end_C", "strut temperature at the end [degC]"))):
        for j, (r, lab) in enumerate(zip(runs, labels)):
            y = [np.nan if a[key] is None else a[key] for a in r["axles"]]
            panel.bar(x - 0.4 + w * (j + 0.5), y, w, label=lab)
        panel.set_xticks(x, [f"axle {k + 1}" for k in range(n_ax)])
        panel.set_ylabel(ylabel)
        panel.axhline(0, color="k", lw=0.6)
        panel.grid(alpha=0.3, axis="y")
    ax[0].set_title("load redistribution (after vs before drive)")
    ax[1].set_title("height change")
    ax[2].set_title("temperatures")
    ax[0].legend(fontsize=8)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
