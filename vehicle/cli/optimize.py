"""`hpsim optimize`: multi-objective design of struts, vehicle and compensation (docs/optimize.md).

    hpsim optimize STUDY.yaml -o DIR [--trials N] [--workers K] [--scheduler ADDRESS] [--ensemble K] [--yes] [--json]

Exit codes: 0 done, 2 user error (one line naming the key), 3 every trial failed, 130 interrupted (run the same
command again: the study resumes from DIR/study.db, no finished trial runs again).
"""
from __future__ import annotations

import logging
import time
from pathlib import Path

from hpsim.errors import UserInputError
from hpsim.validators import check_count
from hpsim.outputs import check_output_dir

from vehicle.cli.options import add_ensemble


def register(sub):
    p = sub.add_parser("optimize", help="multi-objective design: Optuna (NSGA-II, TPE) over scenario keys, "
                                        "objectives and constraints from the cases' reports; the Pareto front")
    p.add_argument("study", help="study YAML file: base, cases, design, objectives, constraints (docs/optimize.md)")
    p.add_argument("-o", "--output-dir", default=None,
                   help="study folder: study.db (resumable), trials/, trials.csv, pareto.csv, pareto.png, pareto/ "
                        "(default: the study file's name)")
    p.add_argument("--trials", type=int, default=None,
                   help="the number of trials to finish (default: the study file's trials); a larger number "
                        "continues a finished study")
    p.add_argument("--workers", type=int, default=None, help="parallel local processes (default: CPU count)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the trials on an existing Dask distributed cluster (needs the 'dask' extra)")
    add_ensemble(p, "trials (their drives)")
    p.add_argument("--storage", default=None, metavar="URL",
                   help="an Optuna database URL (e.g. postgresql://host/db) to share the study between processes or "
                        "machines (default: SQLite in DIR/study.db)")
    p.add_argument("--yes", action="store_true",
                   help="start without asking (at a terminal a study estimated above 5 min asks first)")
    p.add_argument("--json", action="store_true", help="print the front as JSON only")
    p.set_defaults(func=cmd_optimize)


def cmd_optimize(args):
    from hpsim.tables import print_json

    from vehicle.api import optimize

    from vehicle.engines.ensemble import check_lanes

    check_count("--workers", args.workers)
    check_count("--trials", args.trials)
    check_lanes(args.ensemble)
    out = args.output_dir if args.output_dir is not None else Path(args.study).stem
    check_output_dir(out, "-o/--output-dir" if args.output_dir is not None else "output folder (the study file's name)")
    log = (lambda m: None) if args.json else logging.getLogger("hpsim").info
    summary = optimize(args.study, out, trials=args.trials, workers=args.workers, scheduler=args.scheduler,
                       storage=args.storage, ensemble=args.ensemble, log=log,
                       before_start=lambda n: _preview(args, n))
    drives_done = time.perf_counter()
    public = {"trials": summary["trials"], "pareto": summary["pareto"], "failed": summary["failed"],
              "violated": summary["violated"], "units": summary["units"], "files": summary["files"]}
    if args.json:
        print_json(public)
    else:
        print(format_front(summary))
    if summary["trials"]:
        from vehicle.studies import cost

        cost.record_finish("hpsim optimize", time.perf_counter() - drives_done)
    return 3 if summary["trials"] and len(summary["failed"]) == summary["trials"] else 0


def _preview(args, n_trials: int) -> None:
    """The number of drives and the estimated wall time (vehicle.studies.cost); asks at a terminal when long."""
    from vehicle.scenario.schema import prepare
    from vehicle.studies import cost
    from vehicle.studies.optimize_study import load_study

    prepared = [prepare(c.source) for c in load_study(args.study, check=False).cases]
    try:
        from vehicle.cli.stages import command_wall_s

        est = cost.estimate(prepared * n_trials, args.workers, cluster=bool(args.scheduler),
                            ensemble=args.ensemble, elapsed_s=command_wall_s(), what="hpsim optimize")
    except UserInputError as exc:       # the rate probe cannot drive this case's mode on its short stretch
        logging.getLogger("hpsim").info(f"hpsim optimize: no cost estimate ({exc})")
        est = None
    cost.confirm(est, "hpsim optimize", args.yes)


def format_front(s: dict) -> str:
    from hpsim.tables import format_table

    lines = []
    if s["pareto"]:
        design = list(s["pareto"][0]["design"])
        objectives = list(s["goals"])
        headers = (["trial"] + [f"{k} [{s['units'][k]}]" if s["units"].get(k) else k for k in design]
                   + [f"{k} ({s['goals'][k]})" for k in objectives])
        rows = [[r["trial"]] + [f"{r['design'][k]:.4g}" for k in design] + [f"{r['objectives'][k]:.4g}"
                                                                              for k in objectives] for r in s["pareto"]]
        lines.append(format_table(headers, rows))
    else:
        lines.append("no feasible finished trial: the front is empty")
    lines.append(f"{s['trials']} trials finished: {len(s['pareto'])} on the front, {len(s['violated'])} violating a "
                 f"constraint, {len(s['failed'])} failed")
    for f in s["failed"][:3]:
        lines.append(f"  trial {f['trial']} failed: {f['error']}")
    for name, path in s["files"].items():
        lines.append(f"{name}: {path}")
    return "\n".join(lines)

