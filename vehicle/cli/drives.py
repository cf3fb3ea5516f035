"""`hpsim vehicle ...`, `hpsim run`, `report`, `compare`, `sweep`, `plot` (registered by vehicle.cli).

Exit codes: 0 done, 2 user error (bad argument/file; one line, no traceback), 3 simulation
stopped (solver failure; what was written is kept), 130 interrupted (Ctrl-C; resumable).
"""
from __future__ import annotations

import logging
import re
import sys
from pathlib import Path

from hpsim.errors import UserInputError
from hpsim.outputs import check_figure_file, check_output_dir, check_output_file


def register(sub):
    # hpsim vehicle equilibrium
    pv = sub.add_parser("vehicle", help="vehicle tools (static equilibrium)")
    vsub = pv.add_subparsers(dest="vehicle_command", required=True, parser_class=type(pv))
    pe = vsub.add_parser("equilibrium", help="static equilibrium of the charged vehicle at given strut temperatures")
    pe.add_argument("--vehicle", default="apc_8x8", help="built-in vehicle name or path to a vehicle file (default apc_8x8)")
    pe.add_argument("--temperatures", default=None,
                    help="strut temperatures, comma separated: one for all struts, one per axle or one per strut "
                         "(axle-major, left first), e.g. 25degC or 40degC,35degC,30degC,25degC "
                         "(default: the charging temperature)")
    pe.add_argument("--json", action="store_true", help="print JSON only")
    pe.set_defaults(func=cmd_equilibrium)
    pe._negative_number_matcher = re.compile(r"^-\.?\d")   # "--temperatures -20degC" is a value
    from . import response

    response.register(vsub)

    pr = sub.add_parser("run", help="run a scenario file, writing HDF5 results as it goes")
    pr.add_argument("scenario", help="scenario YAML file (see docs/scenarios.md)")
    pr.add_argument("-o", "--output", default=None, help="HDF5 output file (default: <scenario name>.h5 here)")
    pr.add_argument("--resume", action="store_true", help="continue an interrupted or crashed run in --output")
    pr.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    pr.add_argument("--no-progress", action="store_true", help="no progress bar")
    pr.add_argument("--time-parallel", default=None, metavar="P",
                    help="split the drive in time into P segments run in P processes at once, joined with a "
                         "correction of the slow states (overrides solver.time_parallel; auto: one per CPU)")
    pr.set_defaults(func=cmd_run)

    pp = sub.add_parser("report", help="per-axle summary of a results file")
    pp.add_argument("results", help="HDF5 file written by `hpsim run`")
    pp.add_argument("--json", action="store_true", help="print JSON only")
    pp.add_argument("--psd", default=None, metavar="PNG",
                    help="response PSDs (hull heave/pitch/roll acceleration, strut forces; Welch) to this figure, "
                         "peak frequencies in the table / JSON; needs series stored with output.interval <= 1/30 s, e.g. 0.02 s")
    pp.set_defaults(func=cmd_report)

    pc = sub.add_parser("compare", help="compare results files side by side (load redistribution, heights, temperatures)")
    pc.add_argument("results", nargs="+", help="HDF5 files written by `hpsim run`")
    pc.add_argument("--json", action="store_true", help="print JSON only")
    pc.add_argument("--plot", default=None, metavar="PNG", help="grouped bar chart to this file")
    pc.set_defaults(func=cmd_compare)

    ps = sub.add_parser("sweep", help="run a base scenario over a grid or list of overrides (parallel)")
    ps.add_argument("sweep", help="sweep YAML file (see docs/scenarios.md)")
    ps.add_argument("-o", "--output-dir", default=None, help="folder for the case files, summary.csv and plots "
                                                             "(default: the sweep file's output_dir)")
    ps.add_argument("--workers", type=int, default=None, help="parallel local processes (default: CPU count)")
    ps.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="run the cases on an existing Dask distributed cluster (needs the 'dask' extra)")
    ps.add_argument("--json", action="store_true", help="print the summary as JSON only")
    ps.add_argument("--overwrite", action="store_true",
                    help="run again the cases whose results were made from another definition (changed overrides, "
                         "base scenario or input files); without it such a sweep is refused")
    ps.set_defaults(func=cmd_sweep)

    pl = sub.add_parser("plot", help="dashboard figure of a results file")
    pl.add_argument("results", help="HDF5 file written by `hpsim run`")
    pl.add_argument("-o", "--output", default=None, help="PNG file (default: <results>.png)")
    pl.set_defaults(func=cmd_plot)


# --- vehicle equilibrium ---------------------------------------------------------------------------
def strut_temperatures(P, text):
    """--temperatures: one, one per axle or one per strut (default: the charging temperature) [K]."""
    import numpy as np

    from hpsim.units import parse_quantity_list

    if text is None:
        return np.full(P.n_stations, P.charging.temperature)
    T = P.per_station(parse_quantity_list(text, "K", where="--temperatures"), f"--temperatures ({text!r})")
    if np.any(T <= 0) or np.any(T > 273.15 + 250):
        raise UserInputError(f"--temperatures: {text!r} must be in (-273.15, 250] degC")
    return T


def cmd_equilibrium(args):
    from hpsim.tables import format_table, print_json

    from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses, equilibrium_table
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle

    P = load_vehicle(args.vehicle)
    T = strut_temperatures(P, args.temperatures)
    model = VehicleModel(P)
    eq = EquilibriumSolver(model).solve(T, charge_gas_masses(model))
    table = equilibrium_table(model, eq)
    if args.json:
        print_json(table)
        return 0
    print(f"{P.name}: static equilibrium at strut temperatures "
          f"{', '.join(f'{t - 273.15:.1f}' for t in T)} degC (changes against the charged state)")
    rows = [[a["axle"], f"{a['dh_mm']:+.2f}", f"{a['N_left_daN']:.0f}", f"{a['N_right_daN']:.0f}",
             f"{a['N_mean_daN']:.0f}", f"{a['dN_pct']:+.2f}"] for a in table["axles"]]
    print(format_table(["axle", "dh [mm]", "N left [daN]", "N right [daN]", "N mean [daN]", "dN [%]"], rows))
    print(f"pitch {table['pitch_mrad']:+.3f} mrad, roll {table['roll_mrad']:+.3f} mrad, "
          f"total load {table['total_load_N'] / 10:.0f} daN")
    return 0


# --- run -------------------------------------------------------------------------------------------
def cmd_run(args):
    from vehicle.presentation.report import format_report, report
    from vehicle.runs.results import RunInterrupted, run_scenario

    scen = Path(args.scenario)
    out = Path(args.output) if args.output is not None else Path(scen.stem + ".h5")
    check_output_file(out if args.output is None else args.output, "-o/--output", make_parents=True)  # before any work
    if args.resume and not scen.exists() and out.exists():
        scen_arg = None        # resume from the scenario stored in the file
    else:
        scen_arg = scen
    if args.time_parallel is not None:
        scen_arg = _with_time_parallel(scen, args.time_parallel)
    try:
        summary = run_scenario(scen_arg, out, resume=args.resume, overwrite=args.overwrite,
                               progress=not args.no_progress and getattr(args, "verbosity", 0) >= 0,
                               log=logging.getLogger("hpsim").info)
    except RunInterrupted as exc:
        sys.stderr.write(f"hpsim run: {exc}\n")
        return 130
    print(format_report(report(out)))
    print(f"wrote {out} ({summary.get('wall_s', 0.0):.1f} s wall)")
    return 0


def _with_time_parallel(scen: Path, value: str):
    """The scenario with solver.time_parallel set from --time-parallel (checked here: int in range or auto)."""
    from vehicle.runs.scenario import apply_overrides, read_scenario
    from vehicle.runs.time_parallel import SEGMENTS_RANGE

    lo, hi = SEGMENTS_RANGE
    v = value.strip().lower()
    if v != "auto":
        try:
            v = int(v)
        except ValueError:
            v = None
        if v is None or not lo <= v <= hi:
            raise UserInputError(f"--time-parallel: must be an integer in [{lo}, {hi}] (segments) or auto, got {value!r}")
    src = read_scenario(scen)
    src.data = apply_overrides(src.data, {"solver.time_parallel": v}, str(scen))
    return src


def cmd_report(args):
    from hpsim.tables import print_json

    from vehicle.presentation.report import format_report, report

    rep = report(args.results)
    if args.psd:
        from vehicle.presentation.plots import psd_plot
        from vehicle.presentation.report import format_psd
        from vehicle.runs.psd import response_psd

        from vehicle.runs.reader import open_results

        check_figure_file(args.psd, "--psd", make_parents=True)
        with open_results(args.results) as r:
            psd = response_psd(r)
            stations = r.stations
        figure = psd_plot(psd, args.psd, stations, f"{Path(args.results).name}: response PSDs (Welch, "
                                                   f"{psd['duration_s']:.0f} s at {psd['fs_hz']:.0f} Hz)")
        rep["psd"] = {"figure": str(figure), "fs_hz": psd["fs_hz"], "duration_s": psd["duration_s"],
                      "peaks_hz": psd["peaks"], "rms": psd["rms"], "units": psd["units"], "signal_units": psd["signal_units"]}
    if args.json:
        print_json(rep)
    else:
        print(format_report(rep))
        if args.psd:
            print()
            print(format_psd(rep["psd"]))
    return 0


def cmd_compare(args):
    from hpsim.tables import print_json

    from vehicle.presentation.report import compare, format_compare

    if args.plot:
        check_figure_file(args.plot, "--plot", make_parents=True)
    cmp = compare(args.results)
    if args.plot:
        from vehicle.presentation.plots import compare_plot

        compare_plot(args.results, args.plot)
    if args.json:
        print_json(cmp)
    else:
        print(format_compare(cmp))
        if args.plot:
            print(f"wrote {args.plot}")
    return 0


def cmd_plot(args):
    from vehicle.presentation.plots import dashboard

    out = Path(args.output) if args.output is not None else Path(args.results).with_suffix(".png")
    check_figure_file(out if args.output is None else args.output, "-o/--output", make_parents=True)
    dashboard(args.results, out)
    print(f"wrote {out}")
    return 0


def cmd_sweep(args):
    from hpsim.tables import print_json

    from vehicle.presentation.plots import compare_plot
    from vehicle.presentation.report import format_summary
    from vehicle.runs.sweep import run_sweep

    if args.workers is not None and args.workers < 1:
        raise UserInputError(f"--workers: must be >= 1, got {args.workers}")
    check_output_dir(Path(args.sweep).stem if args.output_dir is None else args.output_dir,
                     "-o/--output-dir" if args.output_dir is not None else "output folder (the sweep file's name)")
    result = run_sweep(args.sweep, output_dir=args.output_dir, workers=args.workers, scheduler=args.scheduler,
                       log=(lambda m: None) if args.json else logging.getLogger("hpsim").info,
                       overwrite=args.overwrite)
    if result["finished_files"]:
        result["plots"].append(str(compare_plot(result["finished_files"], Path(result["output_dir"]) / "compare.png",
                                                labels=result["finished_labels"])))
    if args.json:
        print_json(result)
    else:
        print(format_summary(result))
    return 3 if result["failed"] else 0
