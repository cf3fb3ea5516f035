"""The section of `hpsim report DIR --html` for an optimisation study folder (`hpsim optimize`, optimize.json):
the Pareto front as a table, its figure, and the trials that failed or broke a constraint."""
from __future__ import annotations

import json
from pathlib import Path

from vehicle.presentation.html_report import Document, Section, Table, _fmt, _png_figure, provenance
from vehicle.presentation.optimize_plots import pareto_plot

MAX_FAILED_ROWS = 20


def is_optimize_folder(path) -> bool:
    """A folder written by `hpsim optimize` (it holds optimize.json)."""
    return Path(path).is_dir() and (Path(path) / "optimize.json").exists()


def optimize_document(folder: Path) -> Document:
    summary = json.loads((Path(folder) / "optimize.json").read_text())
    units, goals = summary.get("units", {}), summary.get("goals", {})
    design = list(units)
    headers = (["trial"] + [f"{k} [{units[k]}]" if units[k] else k for k in design]
               + [f"{k} ({g})" for k, g in goals.items()] + [f"margin {k}" for k in summary.get("constraint_bounds", {})]
               + ["vehicle file"])
    rows = [[r["trial"]] + [_fmt(r["design"].get(k), ".4g") for k in design]
            + [_fmt(r["objectives"].get(k), ".4g") for k in goals]
            + [_fmt(r["constraints"].get(k), ".3g") for k in summary.get("constraint_bounds", {})]
            + [Path(r["vehicle_file"]).name if r.get("vehicle_file") else ""] for r in summary["pareto"]]
    front = Section("Pareto front", paragraphs=[("", f"{len(summary['pareto'])} of {summary['trials']} finished "
                                                     f"trials are on the front: feasible, and no other feasible trial "
                                                     "is as good in every objective and better in one.")],
                    tables=[Table(headers, rows, f"{folder / 'pareto.csv'}; each design as a vehicle file in "
                                                 f"{folder / 'pareto'}", (len(headers) - 1,))])
    fig = _png_figure(lambda out: pareto_plot(summary, out), "The front in objective space (dominated trials grey, "
                                                             "violated red) and the designs over their ranges")
    if fig:
        front.figures.append(fig)
    sections = [front]
    failed, violated = summary.get("failed", []), summary.get("violated", [])
    if failed or violated:
        other = Section("Failed and violating trials")
        if violated:
            other.paragraphs.append(("", f"{len(violated)} trial(s) broke a constraint and are kept out of the front: "
                                         f"{', '.join(map(str, violated[:40]))}{' ...' if len(violated) > 40 else ''}"))
        if failed:
            other.tables.append(Table(["trial", "reason"], [[f["trial"], f["error"]] for f in failed[:MAX_FAILED_ROWS]],
                                      f"{len(failed)} trial(s) failed" + (f" (the first {MAX_FAILED_ROWS} shown)"
                                                                         if len(failed) > MAX_FAILED_ROWS else ""),
                                      (1,)))
        sections.append(other)
    text = (Path(folder) / "optimize.json").read_text()
    return Document(f"hpsim optimize: {summary.get('study', Path(folder).name)}",
                    [f"Multi-objective design study in {folder}: {summary['trials']} trials over "
                     f"{', '.join(design)}."], sections, provenance(text, "", "", str(folder)))
