"""The outputs of `hpsim optimize`: the Pareto front of a study folder as a summary, CSV files and vehicle files.

    <folder>/optimize.json    the summary (`hpsim optimize --json` prints it; `hpsim report <folder> --html` reads it)
    <folder>/trials.csv       every trial: design, objectives, constraint margins, status and the reason of a failure
    <folder>/pareto.csv       the feasible non-dominated trials, the same columns
    <folder>/pareto/<trial>.yaml   each Pareto design as a vehicle file (`hpsim vehicle check`, `hpsim run`)

The front holds the finished trials whose constraint margins are all >= 0 and that no other such trial dominates
(no worse in every objective, better in one); violated designs stay in trials.csv, marked.
"""
from __future__ import annotations

import csv
import io
import json
import os
from pathlib import Path

import numpy as np
import yaml

from vehicle.scenario.schema import validate_scenario, vehicle_data
from vehicle.studies.optimize_study import Study

SUMMARY = "optimize.json"


def non_dominated(F: np.ndarray) -> list[int]:
    """Indices of the rows of F (n points x m objectives, all minimised) that no other row dominates; of equal
    rows, the first."""
    F = np.asarray(F, float)
    keep = []
    for i in range(len(F)):
        no_worse = np.all(F <= F[i], axis=1)
        better = np.any(F < F[i], axis=1)
        dominated = np.any(no_worse & better)
        duplicate = np.any(np.all(F[:i] == F[i], axis=1))
        if not dominated and not duplicate:
            keep.append(i)
    return keep


def hypervolume_2d(F: np.ndarray, reference) -> float:
    """The area dominated by the points F (n x 2, both minimised) and bounded by `reference` (the worst corner)."""
    F = np.asarray(F, float).reshape(-1, 2)
    F = F[np.all(F < np.asarray(reference, float), axis=1)]
    if not len(F):
        return 0.0
    F = F[non_dominated(F)]
    F = F[np.argsort(F[:, 0])]
    area, y_prev = 0.0, float(reference[1])
    for x, y in F:
        area += (float(reference[0]) - x) * (y_prev - y)
        y_prev = y
    return area


def write_text(path: Path, text: str) -> Path:
    """Write `text` to a temporary name beside `path` and rename it: a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def trial_rows(study: Study, trials) -> list[dict]:
    """Every finished trial of `trials` (Optuna's FrozenTrials): number, status, design {path: value}, objectives,
    constraint margins, feasible, error."""
    rows = []
    for t in trials:
        if not t.state.is_finished():
            continue
        margins = json.loads(t.user_attrs.get("constraint_margins", "[]"))
        done = t.state.name == "COMPLETE"
        rows.append({"trial": t.number, "status": "done" if done else "failed",
                     "design": {d.path: float(t.params[d.path]) for d in study.design if d.path in t.params},
                     "objectives": dict(zip((o.name for o in study.objectives), t.values)) if done else {},
                     "constraints": dict(zip((c.name for c in study.constraints), margins)) if done else {},
                     "feasible": done and all(m >= 0 for m in margins),
                     "error": t.user_attrs.get("error", ""), "seconds": float(t.user_attrs.get("seconds", 0.0))})
    return rows


def front_of(study: Study, rows: list[dict]) -> list[dict]:
    """The feasible non-dominated rows, ordered by the first objective."""
    ok = [r for r in rows if r["feasible"]]
    F = np.array([[r["objectives"][o.name] * (1 if o.goal == "min" else -1) for o in study.objectives] for r in ok],
                 float).reshape(len(ok), len(study.objectives))
    front = [ok[i] for i in non_dominated(F)]
    first = study.objectives[0].name
    return sorted(front, key=lambda r: r["objectives"][first])


def csv_text(study: Study, rows: list[dict]) -> str:
    """Design values with their units, objectives, constraint margins, then status and error."""
    header = (["trial"] + [d.label() for d in study.design] + [o.name for o in study.objectives]
              + [f"margin {c.name}" for c in study.constraints] + ["feasible", "status", "error", "vehicle_file"])
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(header)
    for r in rows:
        w.writerow([r["trial"]] + [repr(r["design"].get(d.path, "")) for d in study.design]
                   + [repr(r["objectives"].get(o.name, "")) for o in study.objectives]
                   + [repr(r["constraints"].get(c.name, "")) for c in study.constraints]
                   + [r["feasible"], r["status"], r["error"], r.get("vehicle_file", "")])
    return out.getvalue().replace("''", "")


def vehicle_file_text(study: Study, design: dict, trial: int) -> str | None:
    """The vehicle of a design (the first case's vehicle with the design applied) as a vehicle file; None for a
    study without scenario cases."""
    if not study.cases:
        return None
    case = study.cases[0]
    src = study.trial_source(case, design, trial)
    data, path = vehicle_data(validate_scenario(src), src)
    others = [d.path for d in study.design if not d.path.startswith(("vehicle.", "struts.", "compensation."))]
    head = [f"# trial {trial} of study {study.name}: {path} with the design",
            *(f"#   {d.path}: {d.override(design[d.path])}" for d in study.design)]
    if others:
        head.append(f"# the scenario keys {', '.join(others)} of the design are not part of a vehicle file")
    return "\n".join(head) + "\n" + yaml.safe_dump(data, sort_keys=False)


def summarise(study: Study, trials, out_dir: Path) -> dict:
    """Write trials.csv, pareto.csv, pareto/<trial>.yaml and optimize.json of `trials` (Optuna's FrozenTrials);
    return the summary."""
    out_dir = Path(out_dir)
    rows = trial_rows(study, trials)
    front = front_of(study, rows)
    folder = out_dir / "pareto"
    folder.mkdir(exist_ok=True)
    for r in front:
        text = vehicle_file_text(study, r["design"], r["trial"])
        if text is not None:
            r["vehicle_file"] = str(write_text(folder / f"{r['trial']:05d}.yaml", text))
    files = {"trials_csv": str(write_text(out_dir / "trials.csv", csv_text(study, rows))),
             "pareto_csv": str(write_text(out_dir / "pareto.csv", csv_text(study, front)))}
    summary = {"study": study.name, "output_dir": str(out_dir), "trials": len(rows),
               "failed": [{"trial": r["trial"], "error": r["error"]} for r in rows if r["status"] == "failed"],
               "violated": [r["trial"] for r in rows if r["status"] == "done" and not r["feasible"]],
               "units": {d.path: d.unit for d in study.design},
               "bounds": {d.path: [d.low, d.high] for d in study.design},
               "log_scale": {d.path: d.log for d in study.design},
               "goals": {o.name: o.goal for o in study.objectives},
               "constraint_bounds": {c.name: {"op": c.op, "bound": c.bound} for c in study.constraints},
               "pareto": [{"trial": r["trial"], "design": r["design"], "objectives": r["objectives"],
                           "constraints": r["constraints"], "vehicle_file": r.get("vehicle_file")} for r in front],
               "all_trials": rows, "files": files}
    summary["files"]["summary"] = str(out_dir / SUMMARY)
    write_text(out_dir / SUMMARY, json.dumps(summary, indent=1) + "\n")
    return summary
