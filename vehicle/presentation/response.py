"""`hpsim vehicle response`: the linearised vehicle's modes and road responses as a table, JSON and a figure
(the numbers from vehicle.physics.linear)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from hpsim.tables import format_table

from vehicle.physics import linear
from vehicle.presentation.plots import pyplot, save_figure


def response_report(lin: linear.LinearVehicle, f_hz) -> dict:
    """Modes and, per axle (road input there, both tracks in phase), the responses over f_hz."""
    f = np.asarray(f_hz, float)
    mode_list = linear.modes(lin)
    summ = linear.mode_summary(mode_list)
    axles = []
    for k in range(lin.model.params.n_axles):
        r = linear.frequency_response(lin, linear.axle_road_weights(lin, k), f)
        axles.append({"axle": k + 1,
                      "heave_acc_per_m": np.abs(r["heave_acc"]), "pitch_acc_per_m": np.abs(r["pitch_acc"]),
                      "roll_acc_per_m": np.abs(r["roll_acc"]),
                      "seat_acc_per_m": {name: np.abs(v) for name, v in r["seat_acc"].items()},
                      "tyre_load_N_per_m": np.abs(r["tyre_load"]),
                      "dynamic_tyre_load_per_m": np.abs(r["tyre_load"]) / lin.static_wheel_loads_N[:, None]})
    return {"vehicle": lin.model.params.name, "notes": list(lin.notes),
            "friction_velocity_m_s": lin.friction_velocity_m_s,
            "temperatures_K": lin.temperatures_K, "stations": list(lin.model.station_names),
            "modes": [m.as_dict() for m in mode_list],
            "summary": {k: (v.as_dict() if isinstance(v, linear.Mode) else list(v)) for k, v in summ.items()},
            "overdamped_modes": int(np.sum(np.abs(lin.eigenvalues.imag) <= 1e-9)),
            "f_hz": f, "axles": axles}


def _peak(f, y):
    k = int(np.argmax(y))
    return float(y[k]), float(f[k])


def format_response(rep: dict) -> str:
    f = rep["f_hz"]
    T = rep["temperatures_K"]
    lines = [f"{rep['vehicle']} linearised at its standing equilibrium (strut temperatures "
             f"{min(T) - 273.15:.1f}-{max(T) - 273.15:.1f} degC)"]
    lines += [f"  - {n}" for n in rep["notes"][1:]]
    modes = rep["modes"]
    lines.append("")
    lines.append(format_table(["mode", "f [Hz]", "damping ratio"],
                              [[m["name"], f"{m['frequency_hz']:.2f}", f"{m['damping_ratio']:.3f}"] for m in modes])
                 if modes else "no oscillatory modes")
    if rep["overdamped_modes"]:
        lines.append(f"(and {rep['overdamped_modes']} overdamped modes: real eigenvalues)")
    seats = list(rep["axles"][0]["seat_acc_per_m"]) if rep["axles"] else []
    headers = ["axle", "heave acc", "pitch acc"] + seats + ["tyre load (left)"]
    rows = []
    for a in rep["axles"]:
        row = [a["axle"]]
        for y, scale, fmt in ((a["heave_acc_per_m"], 1e-3, ".3g"), (a["pitch_acc_per_m"], 1e-3, ".3g"),
                              *((a["seat_acc_per_m"][s], 1e-3, ".3g") for s in seats),
                              (a["tyre_load_N_per_m"][2 * (a["axle"] - 1)], 1e-6, ".3g")):
            g, fp = _peak(f, y)
            row.append(f"{format(g * scale, fmt)} @ {fp:.2f} Hz")
        rows.append(row)
    lines.append("")
    lines.append(f"peak response to road input at one axle (both tracks in phase), {f[0]:.3g}-{f[-1]:.3g} Hz, per mm "
                 "of road: accelerations in m/s^2 (pitch rad/s^2), tyre load in kN")
    lines.append(format_table(headers, rows))
    return "\n".join(lines)


STYLES = ("-", "--", "-.", ":")


def response_plot(rep: dict, out: str | Path) -> Path:
    """Magnitudes vs frequency: hull heave and pitch, seats, the excited tyre's dynamic load; one curve per
    excited axle; thin lines at the hull modes."""
    plt = pyplot()
    f = rep["f_hz"]
    seats = list(rep["axles"][0]["seat_acc_per_m"]) if rep["axles"] else []
    panels = [("heave_acc_per_m", "hull heave acceleration\n[m/s$^2$ per mm of road]", 1e-3),
              ("pitch_acc_per_m", "hull pitch acceleration\n[rad/s$^2$ per mm of road]", 1e-3)]
    panels += [(("seat", s), f"{s} seat vertical acceleration\n[m/s$^2$ per mm of road]", 1e-3) for s in seats[:2]]
    panels.append(("tyre", "dynamic load of the excited tyre\n[share of its static load per mm]", 1e-3))
    ncol = 2 if len(panels) <= 4 else 3
    nrow = -(-len(panels) // ncol)
    fig, axs = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 3.6 * nrow), constrained_layout=True, squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    hull_modes = [m for m in rep["modes"] if m["name"] in ("bounce", "pitch", "roll")]
    for ax, (key, label, scale) in zip(axs.flat, panels):
        for j, a in enumerate(rep["axles"]):
            if key == "tyre":
                y = a["dynamic_tyre_load_per_m"][2 * (a["axle"] - 1)]
            elif isinstance(key, tuple):
                y = a["seat_acc_per_m"][key[1]]
            else:
                y = a[key]
            # identical curves (symmetric axles) stay apart: each axle its own dash, the first ones wider below
            ax.loglog(f, y * scale, color=colors[j % len(colors)], ls=STYLES[j % len(STYLES)],
                      lw=2.6 - 0.5 * min(j, 3), zorder=2 + j, label=f"road input at axle {a['axle']}")
        for m in hull_modes:
            ax.axvline(m["frequency_hz"], color="0.6", lw=0.7, ls=":")
        ax.set(xlabel="frequency [Hz]", ylabel=label)
        ax.grid(alpha=0.3, which="both")
    spare = list(axs.flat)[len(panels):]
    if spare:                       # the modes: frequency against damping ratio
        ax = spare[0]
        for m in rep["modes"]:
            hull = m["name"] in ("bounce", "pitch", "roll")
            ax.plot(m["frequency_hz"], m["damping_ratio"], "o" if hull else ".", color="C3" if hull else "0.4")
            if hull:
                ax.annotate(m["name"], (m["frequency_hz"], m["damping_ratio"]), textcoords="offset points",
                            xytext=(5, 4), fontsize=8)
        ax.set(xlabel="natural frequency [Hz]", ylabel="damping ratio", title="modes (wheel modes: dots)", xlim=(0, None))
        ax.title.set_fontsize(9)
        ax.grid(alpha=0.3, which="both")
        for ax in spare[1:]:
            ax.set_visible(False)
    handles, labels = axs.flat[0].get_legend_handles_labels()
    handles.append(plt.Line2D([], [], color="0.6", lw=0.7, ls=":"))
    labels.append("hull modes")
    fig.legend(handles, labels, loc="outside lower center", ncol=len(labels), fontsize=8, frameon=False)
    modes_text = ", ".join(f"{m['name']} {m['frequency_hz']:.2f} Hz" for m in hull_modes)
    V = rep["friction_velocity_m_s"]
    fig.suptitle(f"{rep['vehicle']}: linearised road response ({modes_text}; friction "
                 + (f"equivalent linear at {V * 1e3:.0f} mm/s)" if V else "at rest)"), fontsize=10)
    return save_figure(fig, out)
