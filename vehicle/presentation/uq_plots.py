"""Figures of an uncertainty study (`hpsim uq`, vehicle.studies.uq): prediction bands per axle and the
sensitivity ranking (Sobol' indices or partial rank correlations). Drawn from the study summary."""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np

from vehicle.presentation.plots import pyplot, save_figure

AXLE_PANELS = (("rise_K", "strut temperature rise [K]"), ("dh_mm", "height change dh [mm]"),
               ("dN_pct", "wheel load change dN [%]"))
HEADLINE = ("mean_rise_K", "load_shift_pct")
TOP = 12          # parameters shown per bar chart




def _finite(v) -> bool:
    return v is not None and math.isfinite(v)


def bands_plot(summary: dict, out: str | Path) -> Path:
    """Per axle: the 5-95 % band (bar), the median (dot) and the nominal case (cross) of each quantity;
    for a study without axle outputs one panel per output."""
    plt = pyplot()
    bands, nominal = summary["bands"], summary["nominal"]
    axles = sorted({int(m.group(1)) for k in bands if (m := re.fullmatch(r"axle(\d+)\..+", k))})
    if axles:
        panels = [(q, label, [f"axle{a}.{q}" for a in axles], [f"axle {a}" for a in axles]) for q, label in AXLE_PANELS]
    else:
        panels = [(k, f"{k} [{summary['units'].get(k, '')}]".replace(" []", ""), [k], [k]) for k in bands]
    panels = [p for p in panels if any(k in bands for k in p[2])]
    fig, ax = plt.subplots(1, max(len(panels), 1), figsize=(max(7.0, 4.3 * len(panels)), 4.3), constrained_layout=True,
                           squeeze=False)
    for panel, (q, label, keys, ticks) in zip(ax[0], panels):
        x = np.arange(len(keys))
        for i, k in enumerate(keys):
            b = bands.get(k)
            if b is None:
                continue
            panel.plot([x[i], x[i]], [b["p5"], b["p95"]], color="tab:blue", lw=10, alpha=0.35, solid_capstyle="butt",
                       label="5-95 %" if i == 0 else None)
            panel.plot(x[i], b["p50"], "o", color="tab:blue", label="median" if i == 0 else None)
            if _finite(nominal.get(k)):
                panel.plot(x[i], nominal[k], "x", color="k", ms=8, mew=2, label="nominal" if i == 0 else None)
        panel.set_xticks(x, ticks)
        panel.set_xlim(-0.6, len(keys) - 0.4)
        panel.set_ylabel(label)
        panel.grid(alpha=0.3, axis="y")
        if q in ("dh_mm", "dN_pct"):
            panel.axhline(0, color="k", lw=0.6)
    if panels:
        ax[0][0].legend(fontsize=8)
    extra = [f"{k}: {bands[k]['p50']:.3g} [{bands[k]['p5']:.3g}, {bands[k]['p95']:.3g}] {summary['units'].get(k, '')}"
             for k in HEADLINE if k in bands]
    fig.suptitle(f"prediction bands over the priors: {summary['done']} drives ({summary['method']})"
                 + ("\n" + "\n".join(extra) if extra else ""), fontsize=10)
    return save_figure(fig, Path(out))


def _mark_unresolved(summary: dict, output: str, names: list[str], bars) -> str:
    """Hatch and fade the bars of parameters whose index is not resolved (its interval for all parameters at
    once includes 0: vehicle.studies.confidence, the ranking the text calls noise); the title's note."""
    from vehicle.studies.confidence import ranked

    try:
        _, rows = ranked(summary, output)
    except (KeyError, TypeError):
        return ""
    resolved = {r["parameter"]: r["resolved"] for r in rows}
    noise = [j for j, name in enumerate(names) if not resolved.get(name, False)]
    for container in bars:
        for j in noise:
            container.patches[j].set_hatch("////")
            container.patches[j].set_alpha(0.35)
    if not noise:
        return ""
    if len(noise) == len(names):
        return "\nNOT RESOLVED: every bar is noise at this sample size"
    return "\nhatched, faded: not resolved (noise at this sample size)"


def sensitivity_plot(summary: dict, out: str | Path) -> Path | None:
    """Sobol': first-order and total index bars with their 95 % intervals for the headline outputs, and
    a map of the total indices over every output. Latin hypercube: PRCC tornado and map."""
    table = summary.get("sobol") or summary.get("ranking")
    if not table:
        return None
    plt = pyplot()
    sobol = "sobol" in summary
    outputs = [k for k in table if not table[k]["constant"]]
    if not outputs:
        return None
    bar_outputs = [k for k in HEADLINE if k in outputs] or outputs[:2]
    params = [r["parameter"] for r in table[outputs[0]]["rows"]]
    # too few Latin-hypercube cases for partial correlations (n < parameters + 3): Spearman's instead
    value = "ST" if sobol else ("prcc" if any(_finite(r["prcc"]) for k in outputs for r in table[k]["rows"])
                                else "spearman")
    M = np.array([[r[value] if _finite(r[value]) else np.nan for r in table[k]["rows"]] for k in outputs]).T
    strength = np.array([np.nanmax(np.abs(row)) if np.any(np.isfinite(row)) else -1.0 for row in M])
    order = np.argsort(-strength)[:30]
    n_bar = min(TOP, len(params))
    width = max(10.0, 5.5 * len(bar_outputs))
    bar_h = max(2.8, 1.2 + 0.3 * n_bar)
    map_h = max(2.8, 1.6 + 0.22 * len(order))
    fig = plt.figure(figsize=(width, bar_h + map_h), constrained_layout=True)
    sub = fig.subfigures(2, 1, height_ratios=[bar_h, map_h])
    ax = sub[0].subplots(1, len(bar_outputs), squeeze=False)
    for panel, k in zip(ax[0], bar_outputs):
        _bar_panel(panel, summary, table[k]["rows"], k, value, n_bar)
    if sobol:           # plain patches: a bar container's legend entry would copy a hatched (unresolved) bar
        from matplotlib.patches import Patch

        h = [Patch(color="tab:orange"), Patch(color="tab:blue")]
        sub[0].legend(h, ["total ST", "first order S1"], fontsize=8, loc="outside lower center", ncol=2, frameon=False)
    _index_map(sub[1], M[order], [params[i] for i in order], outputs, value)
    what = "Sobol' indices" if sobol else "rank correlations"
    fig.suptitle(f"{what} over the priors ({summary['done']} drives, N = {summary['samples']})", fontsize=10)
    return save_figure(fig, Path(out))


def _bar_panel(panel, summary: dict, rows: list[dict], k: str, value: str, n_bar: int) -> None:
    """One headline output's bars: Sobol' S1 and ST with their intervals, or the rank correlations; the noise
    marked."""
    sobol = value == "ST"
    key = (lambda r: -(r[value] if _finite(r[value]) else -1)) if sobol else \
        (lambda r: -(abs(r[value]) if _finite(r[value]) else -1))
    rows = sorted(rows, key=key)[:n_bar][::-1]
    y = np.arange(len(rows))
    names = [r["parameter"] for r in rows]
    if sobol:
        bars = [panel.barh(y + 0.2, [r["ST"] for r in rows], 0.4, xerr=[r["ST_conf"] for r in rows],
                           color="tab:orange", label="total ST", capsize=2),
                panel.barh(y - 0.2, [r["S1"] for r in rows], 0.4, xerr=[r["S1_conf"] for r in rows],
                           color="tab:blue", label="first order S1", capsize=2)]
        panel.set_xlabel("Sobol' index (whiskers: 95 % bootstrap interval)")
        ends = [r[i] + sgn * r[i + "_conf"] for r in rows for i in ("S1", "ST") for sgn in (-1, 1)
                if _finite(r[i]) and _finite(r[i + "_conf"])]     # every whisker inside the panel
        panel.set_xlim(min([-0.05] + ends) - 0.05, max([1.05] + ends) + 0.05)
    else:
        v = [r[value] for r in rows]
        bars = [panel.barh(y, v, 0.6, color=["tab:red" if _finite(t) and t > 0 else "tab:blue" for t in v])]
        panel.set_xlabel(("PRCC" if value == "prcc" else "Spearman") + " (red: the output rises with it)")
        panel.set_xlim(-1, 1)
    panel.axvline(0, color="k", lw=0.6)
    panel.set_yticks(y, names, fontsize=7)
    noise = _mark_unresolved(summary, k, names, bars)
    panel.set_title(f"{k} [{summary['units'].get(k, '')}]".replace(" []", "") + noise, fontsize=10)
    panel.grid(alpha=0.3, axis="x")


def _index_map(subfig, M, names: list[str], outputs: list[str], value: str) -> None:
    """The map of `value` (ST, prcc or spearman) of every parameter (rows of M, `names`) for every output."""
    sobol = value == "ST"
    hm = subfig.subplots()
    im = hm.imshow(M, aspect="auto", cmap="viridis" if sobol else "RdBu_r", vmin=0 if sobol else -1, vmax=1,
                   interpolation="nearest")
    hm.set_yticks(np.arange(len(names)), names, fontsize=7)
    hm.set_xticks(np.arange(len(outputs)), outputs, rotation=60, ha="right", fontsize=7)
    hm.set_title({"ST": "total index ST of every output", "prcc": "PRCC of every output",
                  "spearman": "Spearman correlation of every output"}[value], fontsize=9)
    # a colour bar as tall as the map, never a sliver: at most 15 times longer than wide
    subfig.colorbar(im, ax=hm, fraction=0.05, aspect=min(15, max(6, 3 * len(names))),
                    label={"ST": "ST", "prcc": "PRCC", "spearman": "Spearman"}[value])


def study_plots(summary: dict, out_dir: str | Path) -> dict:
    """Both figures into the study folder; returns {name: path}."""
    out_dir = Path(out_dir)
    files = {}
    if summary["bands"]:
        files["bands_plot"] = str(bands_plot(summary, out_dir / "bands.png"))
    name = "sobol.png" if "sobol" in summary else "ranking.png"
    p = sensitivity_plot(summary, out_dir / name)
    if p is not None:
        files["sensitivity_plot"] = str(p)
    return files
