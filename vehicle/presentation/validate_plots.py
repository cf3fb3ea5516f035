"""The figure of `hpsim validate` (vehicle.studies.validate): per measured quantity and axle the band of what
the instrument would read, the prediction's own band (a study) and nominal value, and the measurement with its
error bar; one panel per logged series with the prediction overlaid. Drawn from the comparison's dictionary."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vehicle.presentation.plots import pyplot, save_figure

TITLES = {"surface_temperature": "strut surface temperature", "oil_temperature": "oil temperature",
          "height": "hull height", "wheel_load": "wheel load"}
COMPARED = {"change": "change after - before", "after": "after the drive", "before": "before the drive"}
ERROR_BAR_K = 2.0       # the measurement's error bar: +-2 standard uncertainties (about 95 %)


def _panel_points(ax, pts: list[dict], study: bool) -> None:
    xs = np.arange(len(pts))
    labels = [f"axle {p['wheel'] or p['axle']}" for p in pts]
    for i, p in enumerate(pts):
        lo, hi = p["band"]
        ax.fill_between([i - 0.3, i + 0.3], lo, hi, color="tab:blue", alpha=0.25, lw=0,
                        label="instrument would read (5-95 %)" if i == 0 else None)
        if study and None not in p["predicted_band"]:
            ax.plot([i, i], p["predicted_band"], color="tab:blue", lw=5, alpha=0.6, solid_capstyle="butt",
                    label="model prediction (5-95 %)" if i == 0 else None)
        if p["predicted"] is not None:
            ax.plot(i, p["predicted"], marker="_", ms=22, mew=2.5, color="navy",
                    label=("nominal" if p["nominal"] is not None else "median") + " prediction" if i == 0 else None)
        if p.get("measured") is None:
            continue
        ax.errorbar(i + 0.12, p["measured"], yerr=ERROR_BAR_K * p["uncertainty"], fmt="o",
                    color="tab:green" if p["inside"] else "tab:red", capsize=4, ms=6,
                    label=f"measured ± {ERROR_BAR_K:g} u (green inside, red outside)" if i == 0 else None)
    ax.set_xticks(xs, labels)
    ax.set_xlim(-0.6, len(pts) - 0.4)
    ax.grid(axis="y", alpha=0.3)


def _panel_series(ax, s: dict, study: bool) -> None:
    x = np.asarray(s["x"]) / (60.0 if s["x_kind"] == "time" else 1e3)
    if study:
        ax.fill_between(x, s["band"][0], s["band"][1], color="tab:blue", alpha=0.25, lw=0, label="prediction 5-95 %")
    ax.plot(x, s["predicted"], color="navy", lw=1.5, label="prediction")
    ax.errorbar(x, s["measured"], yerr=ERROR_BAR_K * s["uncertainty"], fmt=".", color="tab:green", ms=4,
                elinewidth=0.6, label=f"measured ± {ERROR_BAR_K:g} u")
    ax.set_xlabel("time [min]" if s["x_kind"] == "time" else "distance [km]")
    ax.set_ylabel(f"{TITLES[s['quantity']]} [{s['unit']}]")
    ax.set_title(f"{TITLES[s['quantity']]}, axle {s['wheel'] or s['axle']}: RMS error {s['rms_error']:.3g} "
                 f"{'K' if s['unit'] == 'degC' else s['unit']}", fontsize=10)
    ax.grid(alpha=0.3)


def validation_plot(v: dict, out: str | Path) -> Path:
    """The report figure of a comparison (module docstring)."""
    plt = pyplot()
    groups: dict[tuple, list[dict]] = {}
    for p in v["points"]:
        groups.setdefault((p["quantity"], p["compared"], p["unit"]), []).append(p)
    n = len(groups) + len(v["series"])
    if n == 0:
        raise ValueError("nothing to plot")
    cols = 1 if n == 1 else 2
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(6.4 * cols, 3.9 * rows + 0.9), squeeze=False)
    study = v["kind"] == "study"
    handles = {}
    for ax, ((q, compared, unit), pts) in zip(axes.flat, groups.items()):
        _panel_points(ax, sorted(pts, key=lambda p: (p["axle"], p["wheel"] or "")), study)
        ax.set_title(f"{TITLES[q]}, {COMPARED[compared]}", fontsize=10)
        ax.set_ylabel(f"{'Δ' if compared == 'change' else ''}{TITLES[q].split()[-1]} [{unit}]")
        for h, lab in zip(*ax.get_legend_handles_labels()):
            handles.setdefault(lab, h)
    for ax, s in zip(list(axes.flat)[len(groups):], v["series"]):
        _panel_series(ax, s, study)
        ax.legend(fontsize=8, loc="best")
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    what = f"study of {v['drives']} drives" if study else "one drive"
    cov = v.get("coverage")
    title = (f"{Path(v['measurements']).name} against " if v["measurements"] else "what the instruments would read: ") \
        + f"{Path(v['prediction']).name} ({what})"
    if cov:
        title += f": {cov['inside']} of {cov['points']} inside the 90 % band"
    fig.suptitle(title, fontsize=11)
    if handles:
        fig.legend(list(handles.values()), list(handles), loc="lower center", ncol=min(4, len(handles)), fontsize=8,
                   frameon=False)
    fig.tight_layout(rect=(0, 0.07 if handles else 0, 1, 0.96))
    return save_figure(fig, out)
