"""Figures of drive results: the dashboard of one run (`hpsim plot`) and the comparison of several
runs (`hpsim compare --plot`, sweeps). Matplotlib with the Agg backend (no display needed)."""
from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from hpsim.errors import UserInputError
from hpsim.outputs import atomic_output

from vehicle.physics.outputs import variable_name
from vehicle.physics.ride import COMFORT_BANDS
from vehicle.analysis.psd import response_psd
from vehicle.analysis.ride_metrics import axle_rows
from vehicle.analysis.summary import equilibrium_temperature
from vehicle.presentation.report import compare, open_results, report_from

MECHANISMS = (("valve", "valve (damping)"), ("friction", "seal friction"), ("gas", "gas heat"),
              ("end_stop", "end stops"))


def pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, out: str | Path, dpi: int = 110) -> Path:
    """Write `fig` to `out` whole or not at all (hpsim.outputs.atomic_output) and close it; returns `out`."""
    out = Path(out)
    try:
        with atomic_output(out) as tmp:
            fig.savefig(tmp, dpi=dpi)
    finally:
        pyplot().close(fig)
    return out


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
    """A time series of the results (vehicle.results.reader.ResultsView), rows covered by the checkpoint."""
    return r.series(name)


def _dashboard_data(f, path) -> SimpleNamespace:
    """Everything the dashboard draws, read from a results view (file or memory)."""
    d = SimpleNamespace(name=Path(str(path)).name, rep=report_from(f, str(path)), axles=f.axles, stations=f.stations)
    s_km = _series(f, "distance")
    d.s_km = None if s_km is None else s_km / 1e3
    t_all = _series(f, "time")
    d.sample_dt = float(np.median(np.diff(t_all))) if t_all is not None and len(t_all) > 1 else 1.0
    d.T, d.T_oil = _series(f, "strut_temperature"), _series(f, "oil_temperature")   # T_oil: None in older files
    d.h = _series(f, "axle_height_change")
    d.before, after = f.equilibrium("before"), f.equilibrium("after")
    d.N_before = np.asarray(d.before["wheel_load"], float)
    d.N_after = np.asarray(after["wheel_load"], float) if after is not None else None
    d.h_before = np.asarray(d.before["axle_height_change"], float)
    d.s_stats = f.stats_series("km")
    n_rows = 0 if d.s_stats is None else len(d.s_stats)
    d.power = {}
    if n_rows >= 2:
        for key, _ in MECHANISMS:
            P = f.stats_series(f"power_{key}")
            if P is not None:
                d.power[key] = P.sum(axis=1)
        d.power_x, d.power_how = d.s_stats, "per statistics interval"
    else:
        for key, _ in MECHANISMS:
            E = _series(f, f"energy_{key}")
            if E is not None and t_all is not None and len(t_all) >= 2:
                d.power[key] = np.gradient(E.sum(axis=1), t_all)
        d.power_x, d.power_how = d.s_km, "from the energy time series"
    d.T_stats = f.stats_series("strut_temperature")
    charged = f.equilibrium("charged")
    d.N_charged = None if charged is None else np.asarray(charged["wheel_load"], float)
    d.ride_rows = _ride_rows(f)
    d.psd = _dense_psd(f)
    return d


def _colors():
    return pyplot().rcParams["axes.prop_cycle"].by_key()["color"]


def _panel_temperatures(a, d):
    colors = _colors()
    if d.T is not None and d.s_km is not None:
        x, Ts = d.s_km, d.T
    else:                      # time series not stored: the start and the statistics rows
        x = np.concatenate([[0.0], d.s_stats])
        Ts = np.vstack([np.asarray(equilibrium_temperature(d.before), float)[None, :], d.T_stats])
    Tax = 0.5 * (Ts[:, 0::2] + Ts[:, 1::2]) - 273.15
    for k, name in enumerate(d.axles):
        a.plot(x, Tax[:, k], color=colors[k % len(colors)], label=f"{name} surface", marker="o" if len(x) < 30 else None,
               ms=3)
    if d.T is not None and d.s_km is not None and d.T_oil is not None and len(d.T_oil) == len(x):
        Toax = 0.5 * (d.T_oil[:, 0::2] + d.T_oil[:, 1::2]) - 273.15
        for k in range(len(d.axles)):
            a.plot(x, Toax[:, k], color=colors[k % len(colors)], ls=":", lw=1.0)
        a.plot([], [], color="0.4", ls=":", lw=1.0, label="oil (dotted)")
    amb = d.rep["ambient_C"]
    a.axhline(amb, color="0.45", ls="--", lw=1.0)
    a.annotate(f"ambient {amb:.0f} degC", (1.0, amb), xycoords=("axes fraction", "data"), textcoords="offset points",
               xytext=(-4, 3), ha="right", fontsize=7, color="0.35")
    a.set(xlabel="distance [km]", ylabel="strut temperature [degC]",
          title="strut surface (pyrometer) and oil temperature (mean of left/right)")
    a.title.set_fontsize(9)
    a.legend(fontsize=7, ncol=min(len(d.axles) + 1, 5), loc="upper center", bbox_to_anchor=(0.5, -0.16),
             frameon=False, handlelength=1.5, columnspacing=1.0)


def _panel_heights(a, d):
    colors = _colors()
    window = int(np.clip(len(d.s_km) // 10, 1, 600))
    # the drift (heating) is slow, the road's bumps fast: a centred moving mean over about a tenth of the
    # drive (at most 600 samples) shows the drift
    hs = _moving_mean(d.h, window)
    for k, name in enumerate(d.axles):
        a.plot(d.s_km, (hs[:, k] - d.h_before[k]) * 1e3, color=colors[k % len(colors)], label=name)
    for k, r in enumerate(d.rep["axles"]):
        if r["dh_mm"] is not None:
            a.plot([d.s_km[-1]], [r["dh_mm"]], marker="o", color=colors[k % len(colors)], ms=6)
    a.axhline(0, color="k", lw=0.6)
    a.set(xlabel="distance [km]", ylabel="hull height change at the axle [mm]",
          title=f"height change vs before-drive equilibrium\n(moving mean over {window * d.sample_dt:.0f} s; "
                "dots: after-drive equilibrium)")
    a.title.set_fontsize(9)
    a.legend(fontsize=7, ncol=len(d.axles), loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)


def _panel_wheel_loads(a, d):
    """Per axle: the change of the static wheel load [%] (bar) and the band two weighings with seal friction
    can give (vehicle.physics.weighing; whisker), left and right as dots."""
    colors = _colors()
    x = np.arange(len(d.axles))
    if d.N_after is not None:
        dN, base, what = d.N_after - d.N_before, d.N_before, "after - before the drive"
    else:
        dN, base, what = d.N_before - d.N_charged, d.N_charged, "before the drive - charged"
    pct = 100.0 * dN / base
    ax_pct = 0.5 * (pct[0::2] + pct[1::2])
    a.bar(x, ax_pct, 0.55, color=[colors[k % len(colors)] for k in range(len(x))], alpha=0.85)
    a.plot(np.repeat(x, 2) + np.tile([-0.12, 0.12], len(x)), pct, "k.", ms=4, label="left / right wheel")
    lows, highs = [], []
    for k, row in enumerate(d.rep["axles"]):
        band = row.get("dN_band_pct") if d.N_after is not None else None
        if band and None not in band:
            a.plot([k, k], band, color="0.2", lw=1.2)
            a.plot([k - 0.1, k + 0.1, np.nan, k - 0.1, k + 0.1], [band[0], band[0], np.nan, band[1], band[1]],
                   color="0.2", lw=1.2)
            lows.append(band[0])
            highs.append(band[1])
        top = max(ax_pct[k], np.max(pct[2 * k:2 * k + 2]), band[1] if band and None not in band else -np.inf)
        a.annotate(f"{ax_pct[k]:+.2f}%", (k, top), ha="center", va="bottom", fontsize=7,
                   xytext=(0, 3), textcoords="offset points")
    if lows:
        a.plot([], [], color="0.2", lw=1.2, label="weighing band (seal friction)")
    a.axhline(0, color="k", lw=0.6)
    span = max(np.max(np.abs(np.concatenate([pct, lows, highs]))), 0.05)
    a.set_ylim(-1.2 * span, 1.3 * span)
    a.set_xticks(x, list(d.axles))
    a.set(ylabel="static wheel load change [%]", title=f"static wheel loads: {what}\n"
          f"(loads {base.min() / 10:.0f}-{base.max() / 10:.0f} daN)")
    a.title.set_fontsize(9)
    a.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, frameon=False)


def _panel_powers(a, d):
    styles = {"valve": "-", "friction": "--", "gas": "-.", "end_stop": ":"}
    for key, label in MECHANISMS:
        if key in d.power:
            y = d.power[key] / 1e3
            if d.power_how.startswith("from"):
                y = _moving_mean(y, max(1, min(60, len(y) // 20)))
            if not np.any(np.abs(y) > 1e-9):
                label += " (zero)"           # a flat zero line lies on the axis: say so in the legend
            a.plot(d.power_x, y, label=label, ls=styles[key], lw=1.6, marker="o" if len(d.power_x) < 30 else None,
                   ms=3, clip_on=False)
    a.set(xlabel="distance [km]", ylabel="dissipated power, all struts [kW]",
          title=f"dissipated power by mechanism ({d.power_how})")
    a.title.set_fontsize(9)
    lo, hi = a.get_ylim()
    a.set_ylim(min(lo, -0.04 * hi), hi)           # a zero line above the axis, not on it
    a.legend(fontsize=7, ncol=4, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)


def _panel_comfort(a, d):
    rr = d.ride_rows
    km, names, aw = rr["km"], rr["seats"], rr["weighted_rms_acceleration_m_s2"]
    for k, name in enumerate(names):
        a.plot(km, aw[:, k], marker="o" if len(km) < 30 else None, ms=3, label=name)
    # ISO 2631-1 Annex C (vehicle.physics.ride.COMFORT_BANDS): each band's name under its upper limit, inside the
    # band it names (so never above the axes)
    for _, lim, text in COMFORT_BANDS:
        if lim < 1.6 * max(float(np.max(aw)), 0.3):
            a.axhline(lim, color="0.6", lw=0.7, ls=":")
            a.annotate(text, (1.0, lim), xycoords=("axes fraction", "data"), fontsize=7, color="0.4", va="top",
                       ha="right", xytext=(-3, -1), textcoords="offset points")
    a.set(xlabel="distance [km]", ylabel="weighted RMS acceleration a_w [m/s$^2$]",
          title="ride: ISO 2631-1 Wk at the seats, per statistics interval", ylim=(0, None))
    a.title.set_fontsize(9)
    a.legend(fontsize=7, ncol=len(names), loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)


def _panel_travel(a, d):
    """Per axle (worst of left and right): the deflection's 1-99 % band (thick), min-max (thin) and median
    (dot) over the drive, against the stroke (0 and the stroke: the end stops)."""
    colors = _colors()
    rows = axle_rows(d.rep.get("ride") or {}, d.axles)
    stations = (d.rep.get("ride") or {}).get("stations") or []
    for k, row in enumerate(rows):
        c = colors[k % len(colors)]
        lo, hi = row.get("strut_travel_min_m"), row.get("strut_travel_max_m")
        if lo is not None and hi is not None:
            a.plot([k, k], [1e3 * lo, 1e3 * hi], color=c, lw=1.5, solid_capstyle="butt")
        p1, p99 = row.get("strut_travel_p1_m"), row.get("strut_travel_p99_m")
        if p1 is not None and p99 is not None:
            a.plot([k, k], [1e3 * p1, 1e3 * p99], color=c, lw=9, alpha=0.6, solid_capstyle="butt")
        meds = [s.get("strut_travel_p50_m") for s in stations[2 * k:2 * k + 2] if s.get("strut_travel_p50_m") is not None]
        if meds:
            a.plot([k], [1e3 * float(np.mean(meds))], "o", color="k", ms=4)
    a.plot([], [], color="0.5", lw=9, alpha=0.6, label="1-99 %")
    a.plot([], [], color="0.5", lw=1.5, label="min-max")
    a.plot([], [], "ko", ms=4, label="median")
    stroke = d.ride_rows.get("stroke_m")
    if stroke:
        for y, text in ((0.0, "full extension"), (1e3 * stroke, "full compression")):
            a.axhline(y, color="k", lw=0.8)
            a.annotate(text, (1.0, y), xycoords=("axes fraction", "data"), ha="right", fontsize=7, color="0.3",
                       va="bottom" if y > 0 else "top", xytext=(-3, 1 if y > 0 else -1), textcoords="offset points")
        a.set_ylim(-0.08 * 1e3 * stroke, 1.08 * 1e3 * stroke)
    a.set_xticks(range(len(rows)), list(d.axles)[:len(rows)])
    a.set_xlim(-0.6, len(rows) - 0.4)
    a.set(ylabel="strut deflection [mm] (0: full extension)",
          title="strut travel over the drive per axle\n(worst of left/right)")
    a.title.set_fontsize(9)
    a.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.1), frameon=False)


def _panel_spectra(a, d):
    psd = d.psd
    f_hz = psd["f_hz"]
    keep = (f_hz > 0) & (f_hz <= min(psd["fs_hz"] / 2, 30.0))
    for name, label in (("heave_acceleration", "heave"), ("pitch_acceleration", "pitch"),
                        ("roll_acceleration", "roll")):
        if name in psd["psd"]:
            a.semilogy(f_hz[keep], np.atleast_2d(psd["psd"][name])[0][keep], label=f"{label} [{psd['units'][name]}]")
    a.set_xlim(0, float(f_hz[keep][-1]))
    a.set(xlabel="frequency [Hz]", ylabel="PSD", title=f"hull accelerations: response PSD\n(Welch, "
          f"{psd['duration_s']:.0f} s at {psd['fs_hz']:.0f} Hz; hpsim report --psd)")
    a.title.set_fontsize(9)
    a.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)


def _dashboard_panels(d) -> list:
    """The panels that have data, in order (no empty panels)."""
    panels = []
    if (d.T is not None and d.s_km is not None and len(d.s_km)) or (d.T_stats is not None and len(d.T_stats)):
        panels.append(_panel_temperatures)
    if d.h is not None and d.s_km is not None and len(d.s_km) > 1:
        panels.append(_panel_heights)
    if d.N_after is not None or d.N_charged is not None:
        panels.append(_panel_wheel_loads)
    if d.power and d.power_x is not None and len(d.power_x):
        panels.append(_panel_powers)
    if d.ride_rows.get("weighted_rms_acceleration_m_s2") is not None:
        panels.append(_panel_comfort)
    if any(r.get("strut_travel_max_m") is not None for r in ((d.rep.get("ride") or {}).get("stations") or [])):
        panels.append(_panel_travel)
    if d.psd is not None:
        panels.append(_panel_spectra)
    return panels


def dashboard_figure(path):
    """The dashboard of one run as a matplotlib figure (see `dashboard`)."""
    import contextlib

    plt = pyplot()
    view = path if hasattr(path, "series") else None
    with (contextlib.nullcontext(view) if view is not None else open_results(path)) as f:
        d = _dashboard_data(f, f.name if view is not None else path)
    panels = _dashboard_panels(d)
    n = len(panels)
    ncol = 2 if n <= 4 else 3
    nrow = max(1, -(-n // ncol))
    fig, axs = plt.subplots(nrow, ncol, figsize=(6.5 * ncol if ncol == 2 else 6.0 * ncol, 4.6 * nrow),
                            layout="constrained", squeeze=False)
    rep = d.rep
    title = (f"{d.name}: {rep['distance_km']:.2f} km, compensation "
             f"{'on' if rep['compensation'] else 'off'}, {rep['status']}")
    if rep.get("warnings"):
        title += f" - {len(rep['warnings'])} validity warning{'s' if len(rep['warnings']) > 1 else ''} (hpsim report)"
    fig.suptitle(title)
    for a, draw in zip(axs.flat, panels):
        draw(a, d)
        a.grid(alpha=0.3)
    for a in list(axs.flat)[n:]:
        a.remove()
    return fig


def dashboard(path, out: str | Path) -> Path:
    """The dashboard of one run, a panel for each thing the run stored.

    The panels: strut temperatures per axle vs distance (with the ambient), hull height change per axle, the
    change of the static wheel loads over the drive with the weighing bands, and dissipated power by mechanism.
    When the drive's statistics rows carry them, ride comfort at the seats and the strut travel per axle against
    the stroke follow, and the hull's response PSDs when the series are stored densely enough (output.interval <= 1/30 s). `path`: a
    results file or any `vehicle.results.reader.ResultsView` (e.g. in-memory results)."""
    return save_figure(dashboard_figure(path), out)


def _dense_psd(f):
    """The response PSDs of the run when its stored series are dense enough for them (vehicle.analysis.psd; the
    default 1 s output interval is not: then None and the dashboard has no spectrum panel)."""
    try:
        return response_psd(f)
    except UserInputError:          # too sparse, too short or unevenly spaced: the run has no spectrum to show
        return None


def _ride_rows(f) -> dict:
    """Per-interval ride statistics of a results view, when the drive stored them."""
    import json

    out = {"km": f.stats_series("km")}
    if out["km"] is None or len(out["km"]) == 0:
        return {}
    for key in ("weighted_rms_acceleration_m_s2", "strut_travel_min_m", "strut_travel_max_m"):
        a = f.stats_series(variable_name(key))
        out[key] = None if a is None or len(a) == 0 else np.asarray(a, float)
    resolved = json.loads(f.scenario_attrs["resolved_json"])
    seats = [s["name"] for s in resolved.get("vehicle", {}).get("seats", [])]
    aw = out["weighted_rms_acceleration_m_s2"]
    if aw is not None:
        out["seats"] = seats if len(seats) == aw.shape[1] else [f"seat {k + 1}" for k in range(aw.shape[1])]
    strokes = {s["geometry"]["stroke"] for s in resolved.get("struts", {}).values()}
    out["stroke_m"] = strokes.pop() if len(strokes) == 1 else None
    return out


def _history(path, check: bool = True) -> dict:
    """Distance [km], mean strut temperature rise [K] and mean hull height change [mm] (moving mean
    over a tenth of the drive) of one run, from its time series or, if not stored, its rows. check: as
    `open_results`."""
    with open_results(path, check=check) as f:
        before = f.equilibrium("before")
        T0 = np.asarray(equilibrium_temperature(before), float)
        s = f.series("distance")
        T = f.series("strut_temperature")
        h = f.series("axle_height_change")
        out = {}
        if T is not None and s is not None and len(s):
            out["T"] = (s / 1e3, np.mean(T - T0, axis=1))
        else:
            km, Ts = f.stats_series("km"), f.stats_series("strut_temperature")
            if km is not None and len(km):
                out["T"] = (np.concatenate([[0.0], km]), np.concatenate([[0.0], np.mean(Ts - T0, axis=1)]))
        if h is not None and s is not None and len(s) > 1:
            hm = np.mean(h - np.asarray(before["axle_height_change"], float), axis=1)
            out["h"] = (s / 1e3, 1e3 * _moving_mean(hm, int(np.clip(len(s) // 10, 1, 600))))
        return out


# Above this many runs the comparison puts the runs along the x axis (one line per axle) instead of one bar per run
# and axle: a figure of fixed size, and colours that stay tellable apart (a sequential map, not a 10-colour cycle).
MANY_RUNS = 8
MAX_WIDTH_IN = 22.0          # the bar figure's width cap: 2420 px at save_figure's 110 dpi
MAX_RUN_TICKS = 20           # run labels per axis before they are thinned (rotated 7 pt labels in ~4.5 in)
AXLE_PANELS = (("dN_pct", "wheel load change dN [%]", "load redistribution (after vs before)"),
               ("dh_mm", "height change dh [mm]", "height change (after vs before)"),
               ("rise_K", "strut temperature rise [K]", "temperature rise over the drive"))


def _axle_values(run, key, n_ax) -> list:
    """One per-axle quantity of a compared run (`AXLE_PANELS` keys), NaN where a value or the axle is missing (a
    vehicle of fewer axles: nothing drawn on the axles it lacks)."""
    if key == "rise_K":
        y = [np.nan if a["T_end_C"] is None or a["T_start_C"] is None else a["T_end_C"] - a["T_start_C"]
             for a in run["axles"]]
    else:
        y = [np.nan if a[key] is None else a[key] for a in run["axles"]]
    return y + [np.nan] * (n_ax - len(y))


def _history_panels(fig, grid, hist, tops, style) -> list:
    """The top row: the runs' histories (temperature rise, height change vs distance), run i drawn with style(i, n)."""
    axes = []
    for j, key in enumerate(tops):
        a = fig.add_subplot(grid[0, j * (6 // len(tops)):(j + 1) * (6 // len(tops))])
        for i, hh in enumerate(hist):
            if key in hh:
                a.plot(*hh[key], **style(i, len(hh[key][0])))
        a.axhline(0, color="k", lw=0.6)
        a.set(xlabel="distance [km]", **({"ylabel": "strut temperature rise [K]",
                                          "title": "mean strut temperature rise (all struts)"} if key == "T" else
                                         {"ylabel": "hull height change [mm]",
                                          "title": "mean hull height change vs before-drive\nequilibrium (moving mean)"}))
        a.title.set_fontsize(10)
        a.grid(alpha=0.3)
        axes.append(a)
    return axes


def _compare_bars(plt, cmp, hist, tops, warned):
    """Few runs: histories in the colour cycle, each its own dash, over grouped bars per axle (one bar per run)."""
    runs, n_ax = cmp["runs"], cmp["n_axles"]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    width = min(MAX_WIDTH_IN, max(13, 3 + 1.2 * n_ax * len(runs)))
    fig = plt.figure(figsize=(width, 8.5 if tops else 4.8), constrained_layout=True)
    grid = fig.add_gridspec(2 if tops else 1, 6)

    def style(i, n_points):       # identical runs stay visible: each its own dash, the first ones wider below
        return dict(color=colors[i % len(colors)], marker="o" if n_points < 30 else None, ms=3,
                    ls=("-", "--", "-.", ":")[i % 4], lw=max(0.9, 2.6 - 0.5 * i), zorder=2 + i)

    _history_panels(fig, grid, hist, tops, style)
    x = np.arange(n_ax)
    w = 0.8 / max(len(runs), 1)
    for c, (key, ylabel, title) in enumerate(AXLE_PANELS):
        panel = fig.add_subplot(grid[1 if tops else 0, 2 * c:2 * c + 2])
        for j, r in enumerate(runs):
            panel.bar(x - 0.4 + w * (j + 0.5), _axle_values(r, key, n_ax), w, color=colors[j % len(colors)])
        panel.set_xticks(x, [f"axle {k + 1}" for k in range(n_ax)])
        panel.set(ylabel=ylabel, title=title)
        panel.title.set_fontsize(10)
        panel.axhline(0, color="k", lw=0.6)
        panel.grid(alpha=0.3, axis="y")
    handles = [plt.Line2D([], [], color=colors[j % len(colors)], ls=("-", "--", "-.", ":")[j % 4],
                          lw=max(0.9, 2.6 - 0.5 * j), marker="s", ms=7) for j in range(len(runs))]
    fig.legend(handles, warned, loc="outside lower center", ncol=min(len(runs), 4), fontsize=8, frameon=False)
    return fig


def _run_ticks(n: int) -> np.ndarray:
    """The run indices that get a label: all up to MAX_RUN_TICKS, else every k-th; the last run always (it takes the
    place of a k-th one closer than k to it, so no two labels crowd)."""
    step = int(np.ceil(n / MAX_RUN_TICKS))
    ticks = np.arange(0, n, step)
    return ticks if ticks[-1] == n - 1 else np.append(ticks[:-1] if n - 1 - ticks[-1] < step else ticks, n - 1)


def _short(label: str, chars: int = 22) -> str:
    return label if len(label) <= chars else label[:chars - 1] + "…"


def _compare_lines(plt, cmp, hist, tops, warned):
    """Many runs, in a fixed-size figure: histories thin in a sequential colour map (colour bar: run) over the
    per-axle quantities against the run, one line per axle."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    runs, n_ax, n = cmp["runs"], cmp["n_axles"], len(cmp["runs"])
    fig = plt.figure(figsize=(15, 9.5 if tops else 5.5), constrained_layout=True)
    grid = fig.add_gridspec(2 if tops else 1, 6, height_ratios=[1, 1.15] if tops else None)
    cmap = plt.get_cmap("viridis").resampled(n)
    ticks = _run_ticks(n)
    tick_labels = [_short(warned[i]) for i in ticks]
    top = _history_panels(fig, grid, hist, tops,
                          lambda i, n_points: dict(color=cmap(i), lw=0.8, alpha=0.9, zorder=2))
    if top:
        bar = fig.colorbar(ScalarMappable(Normalize(-0.5, n - 0.5), cmap), ax=top, pad=0.01, aspect=30)
        bar.set_label("run")
        bar.set_ticks(ticks, labels=tick_labels, fontsize=7)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    x = np.arange(n)
    for c, (key, ylabel, title) in enumerate(AXLE_PANELS):
        panel = fig.add_subplot(grid[1 if tops else 0, 2 * c:2 * c + 2])
        y = np.array([_axle_values(r, key, n_ax) for r in runs], float)
        for k in range(n_ax):
            panel.plot(x, y[:, k], color=colors[k % len(colors)], marker="o", ms=3, lw=1,
                       ls=("-", "--", "-.", ":")[(k // len(colors)) % 4], label=f"axle {k + 1}")
        panel.set_xticks(ticks, tick_labels, rotation=90, fontsize=7)
        panel.set_xlim(-0.5, n - 0.5)
        panel.set(xlabel="run", ylabel=ylabel, title=title)
        panel.title.set_fontsize(10)
        panel.axhline(0, color="k", lw=0.6)
        panel.grid(alpha=0.3)
    fig.legend(*panel.get_legend_handles_labels(), loc="outside lower center", ncol=min(n_ax, 8), fontsize=8,
               frameon=False)
    return fig


def compare_plot(paths, out: str | Path, labels=None, check: bool = True) -> Path:
    """Several runs: histories overlaid (mean strut temperature rise and mean hull height change vs distance) over
    the per-axle wheel-load change, height change and temperature rise: grouped bars (one per run) for up to
    MANY_RUNS runs, beyond that a line per axle against the run. check: as `compare`."""
    plt = pyplot()
    cmp = compare(paths, check=check)
    runs = cmp["runs"]
    labels = labels or [Path(r["file"]).stem for r in runs]
    hist = [_history(p, check=False) for p in paths]          # `compare` checked every file
    tops = [k for k in ("T", "h") if any(k in hh for hh in hist)]
    warned = [f"{lab} ({len(r['warnings'])} warning{'s' if len(r['warnings']) > 1 else ''})" if r.get("warnings") else lab
              for lab, r in zip(labels, runs)]
    draw = _compare_bars if len(runs) <= MANY_RUNS else _compare_lines
    fig = draw(plt, cmp, hist, tops, warned)
    same = "" if len({json.dumps(r["axles"], sort_keys=True) for r in runs}) > 1 else " (identical results)"
    flagged = [lab for lab, r in zip(labels, runs) if r.get("warnings")] if draw is _compare_lines else []
    note = f"\nwith warnings: {', '.join(flagged[:6])}{', ...' if len(flagged) > 6 else ''}" if flagged else ""
    fig.suptitle(f"{len(runs)} runs compared: temperatures, heights and load changes{same}{note}")
    return save_figure(fig, out)


def psd_plot(psd: dict, out: str | Path, stations=None, title: str = "") -> Path:
    """Response PSDs (vehicle.analysis.psd.response_psd): hull heave, pitch and roll acceleration and the strut
    forces (one curve per station), log-log, with the peak frequency marked."""
    plt = pyplot()
    out = Path(out)
    f = psd["f_hz"]
    sel = f > 0
    names = [n for n in ("heave_acceleration", "pitch_acceleration", "roll_acceleration", "strut_force")
             if n in psd["psd"]]
    fig, axs = plt.subplots(1, len(names), figsize=(4.6 * len(names), 4.0), constrained_layout=True, squeeze=False)
    for a, name in zip(axs[0], names):
        P = np.atleast_2d(psd["psd"][name])
        labels = stations if P.shape[0] > 1 and stations is not None else [None] * P.shape[0]
        for row, lab in zip(P, labels):
            a.loglog(f[sel], row[sel], lw=0.9, label=lab)
        for fp in sorted(set(round(v, 2) for v in psd["peaks"][name]))[:3]:
            a.axvline(fp, color="0.5", lw=0.7, ls=":")
        peaks = psd["peaks"][name]
        where = f"{peaks[0]:.2f}" if len(peaks) == 1 else f"{min(peaks):.2f}-{max(peaks):.2f}"
        a.set(xlabel="frequency [Hz]", ylabel=f"PSD [{psd['units'][name]}]",
              title=f"{name.replace('_', ' ')}, peak {where} Hz")
        a.title.set_fontsize(9)
        a.grid(alpha=0.3, which="both")
        if P.shape[0] > 1 and stations is not None:
            a.legend(fontsize=6, ncol=2, frameon=False)
    fig.suptitle(title or f"response PSDs (Welch, {psd['duration_s']:.0f} s at {psd['fs_hz']:.0f} Hz)")
    return save_figure(fig, out)
