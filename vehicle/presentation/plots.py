"""Figures of drive results: the dashboard of one run (`hpsim plot`) and the comparison of several
runs (`hpsim compare --plot`, sweeps). Matplotlib with the Agg backend (no display needed)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hpsim.errors import UserInputError

from vehicle.physics.outputs import variable_name
from vehicle.analysis.psd import response_psd
from vehicle.analysis.summary import equilibrium_temperature
from vehicle.presentation.report import compare, open_results, report_from

MECHANISMS = (("valve", "valve (damping)"), ("friction", "seal friction"), ("gas", "gas heat"),
              ("end_stop", "end stops"))


def pyplot():
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
    """A time series of the results (vehicle.results.reader.ResultsView), rows covered by the checkpoint."""
    return r.series(name)


def dashboard(path, out: str | Path) -> Path:
    """The dashboard of one run, a panel for each thing the run stored: strut temperatures per axle
    vs distance (with the ambient), hull height change per axle, the change of the static wheel
    loads over the drive, dissipated power by mechanism, and, when the drive's statistics rows
    carry them, ride comfort at the seats and strut travel per interval, and the hull's response PSDs when the
    series are stored densely enough (output.interval <= 1/30 s). `path`: a results file or any
    `vehicle.results.reader.ResultsView` (e.g. in-memory results)."""
    import contextlib

    plt = pyplot()
    out = Path(out)
    view = path if hasattr(path, "series") else None
    with (contextlib.nullcontext(view) if view is not None else open_results(path)) as f:
        path = f.name if view is not None else path
        rep = report_from(f, str(path))
        axles, stations = f.axles, f.stations
        s_km = _series(f, "distance")
        s_km = None if s_km is None else s_km / 1e3
        t_all = _series(f, "time")
        sample_dt = float(np.median(np.diff(t_all))) if t_all is not None and len(t_all) > 1 else 1.0
        T = _series(f, "strut_temperature")
        T_oil = _series(f, "oil_temperature")       # the heat network's oil node (None in older files)
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

        T_stats = f.stats_series("strut_temperature")
        charged = f.equilibrium("charged")
        N_charged = None if charged is None else np.asarray(charged["wheel_load"], float)
        ride_rows = _ride_rows(f)
        psd = _dense_psd(f)

    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    panels = []            # (title, draw(ax)) of the panels that have data: no empty panels

    def temperatures(a):
        if T is not None and s_km is not None:
            x, Ts = s_km, T
        else:                      # time series not stored: the start and the statistics rows
            x = np.concatenate([[0.0], s_stats])
            Ts = np.vstack([np.asarray(equilibrium_temperature(before), float)[None, :], T_stats])
        Tax = 0.5 * (Ts[:, 0::2] + Ts[:, 1::2]) - 273.15
        for k, name in enumerate(axles):
            a.plot(x, Tax[:, k], color=colors[k % len(colors)], label=name, marker="o" if len(x) < 30 else None, ms=3)
        if T is not None and s_km is not None and T_oil is not None and len(T_oil) == len(x):
            Toax = 0.5 * (T_oil[:, 0::2] + T_oil[:, 1::2]) - 273.15
            for k in range(len(axles)):
                a.plot(x, Toax[:, k], color=colors[k % len(colors)], ls=":", lw=1.0)
            a.annotate("dotted: oil", (x[-1], float(np.max(Toax[-1]))), textcoords="offset points", xytext=(-40, 4),
                       fontsize=7, color="0.35")
        a.axhline(rep["ambient_C"], color="0.45", ls="--", lw=1.0)
        a.annotate(f"ambient {rep['ambient_C']:.0f} degC", (x[0], rep["ambient_C"]), textcoords="offset points",
                   xytext=(2, 3), fontsize=7, color="0.35")
        a.set(xlabel="distance [km]", ylabel="strut temperature [degC]",
              title="strut surface (pyrometer) and oil temperature (mean of left/right)")

    if (T is not None and s_km is not None and len(s_km)) or (T_stats is not None and len(T_stats)):
        panels.append(temperatures)

    def heights(a):
        window = int(np.clip(len(s_km) // 10, 1, 600))
        # the drift (heating) is slow, the road's bumps fast: a centred moving mean over about a
        # tenth of the drive (at most 600 samples) shows the drift
        hs = _moving_mean(h, window)
        for k, name in enumerate(axles):
            a.plot(s_km, (hs[:, k] - h_before[k]) * 1e3, color=colors[k % len(colors)], label=name)
        for k, r in enumerate(rep["axles"]):
            if r["dh_mm"] is not None:
                a.plot([s_km[-1]], [r["dh_mm"]], marker="o", color=colors[k % len(colors)], ms=6)
        a.axhline(0, color="k", lw=0.6)
        a.set(xlabel="distance [km]", ylabel="hull height change at the axle [mm]",
              title=f"height change vs before-drive equilibrium\n(moving mean over {window * sample_dt:.0f} s; "
                    "dots: after-drive equilibrium)")
        a.title.set_fontsize(9)

    if h is not None and s_km is not None and len(s_km) > 1:
        panels.append(heights)

    def wheel_loads(a):
        x = np.arange(len(stations))
        if N_after is not None:
            dN, what = N_after - N_before, "after - before the drive"
            base = N_before
        else:
            dN, what = N_before - N_charged, "before the drive - charged"
            base = N_charged
        bars = a.bar(x, dN / 10.0, 0.6, color=[colors[(k // 2) % len(colors)] for k in range(len(stations))])
        for b, d, n0 in zip(bars, dN, base):
            y = b.get_height()
            a.annotate(f"{100 * d / n0:+.2f}%", (b.get_x() + b.get_width() / 2, y), ha="center",
                       va="bottom" if y >= 0 else "top", fontsize=7, xytext=(0, 2 if y >= 0 else -2),
                       textcoords="offset points")
        a.axhline(0, color="k", lw=0.6)
        span = max(np.max(np.abs(dN)) / 10.0, 1.0)
        a.set_ylim(-1.35 * span, 1.35 * span)
        a.set_xticks(x, [s.replace("axle", "A").replace("_left", " L").replace("_right", " R") for s in stations])
        a.set(ylabel="wheel load change [daN]", title=f"static wheel loads: {what}\n"
              f"(loads {base.min() / 10:.0f}-{base.max() / 10:.0f} daN)")
        a.title.set_fontsize(9)

    if N_after is not None or N_charged is not None:
        panels.append(wheel_loads)

    def powers(a):
        for key, label in MECHANISMS:
            if key in power:
                y = power[key] / 1e3
                if power_how.startswith("from"):
                    y = _moving_mean(y, max(1, min(60, len(y) // 20)))
                a.plot(power_x, y, label=label, marker="o" if len(power_x) < 30 else None, ms=3)
        a.set(xlabel="distance [km]", ylabel="dissipated power, all struts [kW]",
              title=f"dissipated power by mechanism ({power_how})")
        a.legend(fontsize=8, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)

    if power and power_x is not None and len(power_x):
        panels.append(powers)

    def comfort(a):
        km, names, aw = ride_rows["km"], ride_rows["seats"], ride_rows["weighted_rms_acceleration_m_s2"]
        for k, name in enumerate(names):
            a.plot(km, aw[:, k], marker="o" if len(km) < 30 else None, ms=3, label=name)
        for lim, text in ((0.315, "not uncomfortable"), (0.63, "a little unc."), (1.0, "fairly unc.")):
            if lim < 1.6 * max(float(np.max(aw)), 0.3):
                a.axhline(lim, color="0.6", lw=0.7, ls=":")
                a.annotate(text, (km[0], lim), fontsize=7, color="0.4", va="bottom")
        a.set(xlabel="distance [km]", ylabel="weighted RMS acceleration a_w [m/s$^2$]",
              title="ride: ISO 2631-1 Wk at the seats, per statistics interval", ylim=(0, None))
        a.legend(fontsize=8, ncol=len(names), loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)

    if ride_rows.get("weighted_rms_acceleration_m_s2") is not None:
        panels.append(comfort)

    def travel(a):
        km = ride_rows["km"]
        lo, hi = ride_rows["strut_travel_min_m"], ride_rows["strut_travel_max_m"]
        for k, name in enumerate(axles):
            c = colors[k % len(colors)]
            a.fill_between(km, 1e3 * np.min(lo[:, 2 * k:2 * k + 2], axis=1), 1e3 * np.max(hi[:, 2 * k:2 * k + 2], axis=1),
                           color=c, alpha=0.25, step="mid")
        stroke = ride_rows.get("stroke_m")
        if stroke:
            for y in (0.0, 1e3 * stroke):
                a.axhline(y, color="k", lw=0.8)
        a.set(xlabel="distance [km]", ylabel="strut deflection [mm]",
              title="strut travel range per interval (0 and the stroke: the end stops)")
        a.title.set_fontsize(9)

    if ride_rows.get("strut_travel_min_m") is not None and ride_rows.get("strut_travel_max_m") is not None:
        panels.append(travel)

    def spectra(a):
        f_hz = psd["f_hz"]
        keep = (f_hz > 0) & (f_hz <= min(psd["fs_hz"] / 2, 30.0))
        for name, label in (("heave_acceleration", "heave"), ("pitch_acceleration", "pitch"),
                            ("roll_acceleration", "roll")):
            if name in psd["psd"]:
                a.semilogy(f_hz[keep], np.atleast_2d(psd["psd"][name])[0][keep],
                           label=f"{label} [{psd['units'][name]}]")
        a.set(xlabel="frequency [Hz]", ylabel="PSD", title=f"hull accelerations: response PSD (Welch, "
              f"{psd['duration_s']:.0f} s at {psd['fs_hz']:.0f} Hz; hpsim report --psd)")
        a.title.set_fontsize(9)
        a.legend(fontsize=8)

    if psd is not None:
        panels.append(spectra)

    n = len(panels)
    ncol = 2 if n <= 4 else 3
    nrow = max(1, -(-n // ncol))
    fig, axs = plt.subplots(nrow, ncol, figsize=(6.5 * ncol if ncol == 2 else 6.0 * ncol, 4.3 * nrow),
                            constrained_layout=True, squeeze=False)
    title = (f"{Path(path).name}: {rep['distance_km']:.2f} km, compensation "
             f"{'on' if rep['compensation'] else 'off'}, {rep['status']}")
    if rep.get("warnings"):
        title += f" - {len(rep['warnings'])} validity warning{'s' if len(rep['warnings']) > 1 else ''} (hpsim report)"
    fig.suptitle(title)
    for a, draw in zip(axs.flat, panels):
        draw(a)
        a.grid(alpha=0.3)
    for a in list(axs.flat)[n:]:
        a.remove()
    if any(d in panels for d in (temperatures, heights)):       # one legend for the axle colours, below the panels
        handles = [plt.Line2D([], [], color=colors[k % len(colors)]) for k in range(len(axles))]
        fig.legend(handles, axles, loc="outside lower center", ncol=len(axles), fontsize=8, frameon=False)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


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


def _history(path) -> dict:
    """Distance [km], mean strut temperature rise [K] and mean hull height change [mm] (moving mean
    over a tenth of the drive) of one run, from its time series or, if not stored, its rows."""
    with open_results(path) as f:
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


def compare_plot(paths, out: str | Path, labels=None) -> Path:
    """Several runs: histories overlaid (mean strut temperature rise and mean hull height change vs
    distance) over grouped bars per axle (wheel-load change, height change, temperature rise)."""
    plt = pyplot()
    cmp = compare(paths)
    runs = cmp["runs"]
    labels = labels or [Path(r["file"]).stem for r in runs]
    n_ax = len(runs[0]["axles"])
    hist = [_history(p) for p in paths]
    tops = [k for k in ("T", "h") if any(k in hh for hh in hist)]
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig = plt.figure(figsize=(max(13, 3 + 1.2 * n_ax * len(runs)), 8.5 if tops else 4.8), constrained_layout=True)
    grid = fig.add_gridspec(2 if tops else 1, 6)
    for j, key in enumerate(tops):
        a = fig.add_subplot(grid[0, j * (6 // len(tops)):(j + 1) * (6 // len(tops))])
        for i, hh in enumerate(hist):
            if key in hh:
                a.plot(*hh[key], color=colors[i % len(colors)], marker="o" if len(hh[key][0]) < 30 else None, ms=3)
        a.axhline(0, color="k", lw=0.6)
        a.set(xlabel="distance [km]", **({"ylabel": "strut temperature rise [K]",
                                          "title": "mean strut temperature rise (all struts)"} if key == "T" else
                                         {"ylabel": "hull height change [mm]",
                                          "title": "mean hull height change vs before-drive equilibrium (moving mean)"}))
        a.grid(alpha=0.3)
    x = np.arange(n_ax)
    w = 0.8 / max(len(runs), 1)
    row = 1 if tops else 0
    for c, (key, ylabel, title) in enumerate((("dN_pct", "wheel load change dN [%]", "load redistribution (after vs before)"),
                                              ("dh_mm", "height change dh [mm]", "height change (after vs before)"),
                                              ("rise_K", "strut temperature rise [K]", "temperature rise over the drive"))):
        panel = fig.add_subplot(grid[row, 2 * c:2 * c + 2])
        for j, r in enumerate(runs):
            if key == "rise_K":
                y = [np.nan if a["T_end_C"] is None or a["T_start_C"] is None else a["T_end_C"] - a["T_start_C"]
                     for a in r["axles"]]
            else:
                y = [np.nan if a[key] is None else a[key] for a in r["axles"]]
            panel.bar(x - 0.4 + w * (j + 0.5), y, w, color=colors[j % len(colors)])
        panel.set_xticks(x, [f"axle {k + 1}" for k in range(n_ax)])
        panel.set(ylabel=ylabel, title=title)
        panel.axhline(0, color="k", lw=0.6)
        panel.grid(alpha=0.3, axis="y")
    handles = [plt.Rectangle((0, 0), 1, 1, color=colors[j % len(colors)]) for j in range(len(runs))]
    warned = [f"{lab} ({len(r['warnings'])} warning{'s' if len(r['warnings']) > 1 else ''})" if r.get("warnings") else lab
              for lab, r in zip(labels, runs)]
    fig.legend(handles, warned, loc="outside lower center", ncol=min(len(runs), 4), fontsize=8, frameon=False)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


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
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
