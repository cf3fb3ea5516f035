"""The figure of an optimisation study (`hpsim optimize`, vehicle.studies.optimize_pareto): the front in objective
space with the dominated and violated trials faint, and the designs in parallel coordinates."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from vehicle.presentation.plots import pyplot


def _scaled(value: float, low: float, high: float, log: bool) -> float:
    """A design value as a fraction of its range (of its logarithm for log: true)."""
    if log:
        return (math.log(value) - math.log(low)) / (math.log(high) - math.log(low))
    return (value - low) / (high - low)


def _objective_axis(summary: dict, name: str) -> str:
    return f"{name} ({summary['goals'][name]})"


def pareto_plot(summary: dict, out: str | Path) -> Path:
    """pareto.png: left the first two objectives (one objective: against the trial number), right the design of
    every feasible trial as a line over its normalised ranges, the front's lines coloured by the first objective."""
    plt = pyplot()
    rows = summary["all_trials"]
    goals = list(summary["goals"])
    front = {r["trial"] for r in summary["pareto"]}
    done = [r for r in rows if r["status"] == "done"]
    fig, (ax, pc) = plt.subplots(1, 2, figsize=(12.5, 5), gridspec_kw={"width_ratios": [1, 1.3]})

    def xy(subset):
        if len(goals) > 1:
            return [r["objectives"][goals[0]] for r in subset], [r["objectives"][goals[1]] for r in subset]
        return [r["trial"] for r in subset], [r["objectives"][goals[0]] for r in subset]

    dominated = [r for r in done if r["feasible"] and r["trial"] not in front]
    violated = [r for r in done if not r["feasible"]]
    on_front = [r for r in summary["all_trials"] if r["trial"] in front]
    if dominated:
        ax.scatter(*xy(dominated), s=14, color="0.6", alpha=0.45, label=f"dominated ({len(dominated)})")
    if violated:
        ax.scatter(*xy(violated), s=18, marker="x", color="tab:red", alpha=0.4,
                   label=f"constraint violated ({len(violated)})")
    if on_front:
        fx, fy = xy(sorted(on_front, key=lambda r: r["objectives"][goals[0]]))
        ax.plot(fx, fy, "o-", color="tab:blue", ms=5, lw=1.2, label=f"Pareto front ({len(on_front)})")
    if len(goals) > 1:
        ax.set_xlabel(_objective_axis(summary, goals[0]))
        ax.set_ylabel(_objective_axis(summary, goals[1]))
        extra = f"; not shown: {', '.join(goals[2:])}" if len(goals) > 2 else ""
        ax.set_title(f"objective space{extra}", fontsize=10)
    else:
        ax.set_xlabel("trial")
        ax.set_ylabel(_objective_axis(summary, goals[0]))
        ax.set_title("objective by trial", fontsize=10)
    if dominated or violated or on_front:
        ax.legend(fontsize=8, loc="best", framealpha=0.85)
    ax.grid(alpha=0.3)

    paths = list(summary["bounds"])
    x = np.arange(len(paths))
    for r in [r for r in done if r["feasible"] and r["trial"] not in front]:
        pc.plot(x, [_scaled(r["design"][p], *summary["bounds"][p], summary["log_scale"][p]) for p in paths],
                color="0.6", alpha=0.3, lw=0.8)
    if on_front:
        values = np.array([r["objectives"][goals[0]] for r in on_front], float)
        lo, hi = float(values.min()), float(values.max())
        cmap = plt.get_cmap("viridis")
        for r, v in zip(on_front, values):
            pc.plot(x, [_scaled(r["design"][p], *summary["bounds"][p], summary["log_scale"][p]) for p in paths],
                    color=cmap((v - lo) / (hi - lo) if hi > lo else 0.5), lw=1.8, marker="o", ms=4)
        sm = plt.cm.ScalarMappable(cmap=cmap, norm=plt.Normalize(lo, hi))
        fig.colorbar(sm, ax=pc, label=f"front: {goals[0]}")
    pc.set_xticks(x)
    pc.set_xticklabels([_short(p, summary["units"].get(p, ""), summary["bounds"][p]) for p in paths], fontsize=7)
    pc.set_ylim(-0.05, 1.05)
    pc.set_xlim(-0.4, len(paths) - 0.6)
    pc.set_ylabel("fraction of the range\n(log ranges: of the logarithm)")
    pc.set_title("designs: front coloured, other feasible trials grey", fontsize=10)
    pc.grid(alpha=0.3, axis="y")
    fig.suptitle(f"hpsim optimize {summary['study']}: {summary['trials']} trials", fontsize=11)
    fig.tight_layout()
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out


def _short(path: str, unit: str, bounds) -> str:
    """The key's last two parts and its range, on three lines."""
    name = ".".join(path.split(".")[-2:])
    return f"{name}\n[{bounds[0]:.3g}, {bounds[1]:.3g}]\n{unit}".rstrip()
