"""`hpsim uq`: prediction bands and sensitivity indices over the parameter priors (docs/uq.md).

    hpsim uq SCENARIO.yaml --samples N [--method sobol|lhs] [--workers K] [--scheduler ADDRESS]
             [-o DIR] [--parameters a,b,c] [--seed S] [--distance D] [--groups none|section]
             [--per-axle-struts] [--list] [--json]

Exit codes: 0 done, 2 user error, 3 some cases failed (bands from the others; Sobol' indices
need every case), 130 interrupted (re-run the same command to resume).
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

from hpsim.errors import UserInputError
from hpsim.validators import check_count

from vehicle.cli.options import add_ensemble


def register(sub):
    p = sub.add_parser("uq", help="uncertainty quantification: draw the parameter priors, run the drives, "
                                  "report per-axle bands and Sobol' indices")
    p.add_argument("scenario", help="scenario YAML file; the priors come from its vehicle and strut files")
    p.add_argument("--samples", type=int, default=None,
                   help="sobol: base sample N, a power of 2 (N x (parameters + 2) drives); lhs: the number of drives")
    p.add_argument("--method", default="sobol", choices=["sobol", "lhs"],
                   help="sobol: Saltelli design, first-order and total indices; lhs: Latin hypercube, rank "
                        "correlations (default sobol)")
    p.add_argument("--seed", type=int, default=0, help="seed of the design (default 0)")
    p.add_argument("-o", "--output-dir", default=None,
                   help="study folder: samples.csv, cases/, bands.csv, sobol.csv, summary.json, plots "
                        "(default <scenario name>_uq); a re-run with the same settings resumes")
    p.add_argument("--parameters", default=None, metavar="A,B,...",
                   help="draw only these priors: full names (see --list), endings such as tyre.stiffness, "
                        "or globs such as 'struts.all.valve.*'; the others stay at their values")
    p.add_argument("--distance", default=None, help="override the scenario's distance (e.g. 5km) for quick studies")
    p.add_argument("--groups", default="none", choices=["none", "section"],
                   help="section: Sobol' indices per file section (tyre, heat, valve, ...), N x (sections + 2) "
                        "drives (default none)")
    p.add_argument("--per-axle-struts", action="store_true",
                   help="draw the strut priors for each axle separately (default: one draw for all struts "
                        "of the same type)")
    p.add_argument("--workers", type=int, default=None, help="parallel local processes (default: CPU count)")
    p.add_argument("--scheduler", default=None, metavar="ADDRESS",
                   help="run the drives on an existing Dask distributed cluster (needs the 'dask' extra)")
    add_ensemble(p)
    p.add_argument("--list", action="store_true",
                   help="list the priors, the number of drives and their estimated wall time, run nothing")
    p.add_argument("--yes", action="store_true",
                   help="start without asking (at a terminal a study estimated above 5 min asks first)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON only")
    p.set_defaults(func=cmd_uq)


def cmd_uq(args):
    from hpsim.tables import print_json

    from vehicle.studies.uq import run_scenario_study

    check_count("--workers", args.workers)
    from vehicle.engines.ensemble import check_lanes

    check_lanes(args.ensemble)
    patterns = [s.strip() for s in args.parameters.split(",") if s.strip()] if args.parameters is not None else None
    if patterns == []:
        raise UserInputError(f"--parameters: {args.parameters!r} names no prior; give names, endings or globs "
                             "(see --list)")
    if args.output_dir is not None and not args.output_dir.strip():
        raise UserInputError("-o/--output-dir: empty path; give a folder name")
    from vehicle.studies.uq import check_seed

    check_seed(args.seed)
    if args.distance is not None:
        from hpsim.units import parse_quantity

        parse_quantity(args.distance, "m", where="--distance")
    if args.list:
        return _list(args, patterns)
    if args.samples is None:
        raise UserInputError("--samples: give the sample size (e.g. --samples 16 for sobol), or --list to see the priors")
    log = (lambda m: None) if args.json else (lambda m: print(m, file=sys.stderr, flush=True))
    from vehicle.studies import cost

    summary = run_scenario_study(args.scenario, samples=args.samples, method=args.method, seed=args.seed,
                                 output_dir=args.output_dir, workers=args.workers, scheduler=args.scheduler,
                                 parameters=patterns, distance=args.distance, groups=args.groups,
                                 per_axle_struts=args.per_axle_struts, log=log, ensemble=args.ensemble,
                                 before_start=lambda cases: _preview(args, cases))
    drives_done = time.perf_counter()
    from vehicle.presentation.uq_plots import study_plots

    summary["files"].update(study_plots(summary, Path(summary["study"])))
    from vehicle.studies.confidence import ranked

    summary["influence_confidence"] = {k: dict(zip(("index", "rows"), ranked(summary, k)))
                                       for k in summary.get("most_influential") or {}}
    if args.json:
        print_json(summary)
    else:
        print(format_study(summary))
    if summary["ran_now"]:
        cost.record_finish("hpsim uq", time.perf_counter() - drives_done)
    return 3 if summary["failed"] or not summary["nominal_done"] else 0


def _preview(args, cases: list, probe: bool = True):
    """The number of drives and the estimated wall time of the prepared cases (vehicle.studies.cost); asks at a
    terminal when long."""
    from vehicle.cli.stages import command_wall_s
    from vehicle.studies import cost

    est = cost.estimate(cases, args.workers, cluster=bool(args.scheduler), probe=probe, ensemble=args.ensemble,
                        elapsed_s=command_wall_s(), what="hpsim uq")
    cost.confirm(est, "hpsim uq", args.yes)
    return est


def _list(args, patterns) -> int:
    from hpsim.tables import format_table, print_json

    from vehicle.scenario.schema import ScenarioSource, read_scenario
    from vehicle.studies.uq import check_settings, n_cases, scenario_parameters, select

    src = read_scenario(args.scenario)
    if args.distance is not None:
        src = ScenarioSource(text=src.text, name=src.name, base_dir=src.base_dir, data={**src.data, "distance": args.distance})
    params, notes, _ = scenario_parameters(src, per_axle_struts=args.per_axle_struts)
    params = select(params, patterns)
    draws = len({p.section for p in params}) if args.groups == "section" else len(params)
    runs = est = None
    if args.samples is not None:
        check_settings(args.method, args.samples, args.groups, len(params))
        runs = n_cases(args.method, args.samples, draws) + 1
        from vehicle.cli.stages import command_wall_s
        from vehicle.scenario.schema import prepare
        from vehicle.studies import cost

        est = cost.estimate([prepare(src)] * runs, args.workers, cluster=bool(args.scheduler), probe=False,
                            ensemble=args.ensemble, elapsed_s=command_wall_s(), what="hpsim uq")
    if args.json:
        print_json({"parameters": [p.describe() for p in params], "notes": notes, "drives": runs,
                    "estimated_wall_s": None if est is None else est.wall_s,
                    "estimated_drives_s": None if est is None else est.drives_s})
        return 0
    grouped = args.groups == "section"
    rows = [[p.name, f"{p.prior.to_unit(p.prior.value):.4g} {p.prior.unit}".strip(), p.prior.describe()]
            + ([p.section] if grouped else []) for p in params]
    print(format_table(["parameter", "value", "prior"] + (["group"] if grouped else []), rows))
    for n in notes:
        print(f"note: {n}")
    if runs is not None:
        print(f"{len(params)} parameters" + (f" in {draws} groups" if args.groups == "section" else "") +
              f": {args.method} with --samples {args.samples} runs {runs} drives (nominal included)")
        print(est.line("estimate") if est is not None else "estimate: no drive recorded on this machine yet in this "
              "solver mode (any hpsim run records the rate; without --list the study measures it first)")
    else:
        print(f"{len(params)} parameters: sobol runs N x {draws + 2} + 1 drives, lhs N + 1")
    return 0


def format_study(s: dict) -> str:
    from hpsim.tables import format_table

    lines = []
    b = s["bands"]
    axles = sorted({int(k.split(".")[0][4:]) for k in b if k.startswith("axle")})
    if axles:
        def cell(k):
            v = b.get(k)
            return "-" if v is None else f"{v['p50']:+.2f} [{v['p5']:+.2f}, {v['p95']:+.2f}]"

        def nom(k):
            v = s["nominal"].get(k)
            return "-" if v is None else f"{v:+.2f}"

        rows = [[a, nom(f"axle{a}.rise_K"), cell(f"axle{a}.rise_K"), nom(f"axle{a}.dh_mm"), cell(f"axle{a}.dh_mm"),
                 nom(f"axle{a}.dN_pct"), cell(f"axle{a}.dN_pct")] for a in axles]
        lines.append(format_table(["axle", "rise nominal [K]", "rise 50 % [5 %, 95 %] [K]", "dh nominal [mm]",
                                   "dh 50 % [5 %, 95 %] [mm]", "dN nominal [%]", "dN 50 % [5 %, 95 %] [%]"], rows))
    rest = [k for k in b if not k.startswith("axle")]
    if rest:
        rows = [[k, s["units"].get(k, ""), "-" if s["nominal"].get(k) is None else f"{s['nominal'][k]:.4g}",
                 f"{b[k]['p5']:.4g}", f"{b[k]['p50']:.4g}", f"{b[k]['p95']:.4g}"] for k in rest]
        lines.append(format_table(["output", "unit", "nominal", "5 %", "50 %", "95 %"], rows))
    lines.append(f"{s['done']} of {s['cases']} cases ({s['method']}, N = {s['samples']}, seed {s['seed']})"
                 + (f"; FAILED: {', '.join(s['failed'][:5])}" + (" ..." if len(s["failed"]) > 5 else "")
                    if s["failed"] else ""))
    if "sensitivity" in s:
        lines.append(f"sensitivity: {s['sensitivity']['skipped']}")
    top = s.get("most_influential") or {}
    from vehicle.studies.confidence import influence_line

    for k in [k for k in ("mean_rise_K", "load_shift_pct") if k in top] or list(top)[:3]:
        lines.append(influence_line(s, k))
    for name, path in s["files"].items():
        lines.append(f"{name}: {path}")
    return "\n".join(lines)
