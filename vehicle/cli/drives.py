"""`hpsim vehicle ...`, `hpsim run`, `report`, `compare`, `sweep`, `plot` (registered by vehicle.cli).

Exit codes: 0 done, 2 user error (bad argument/file; one line, no traceback), 3 simulation
stopped (solver failure; what was written is kept), 130 interrupted (Ctrl-C; resumable).
"""
from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from hpsim.errors import UserInputError
from hpsim.validators import check_count
from hpsim.outputs import check_figure_file, check_output_dir, check_output_file

from vehicle.cli import response, vehicles
from .options import add_ensemble, add_overwrite
from .stages import command_wall_s, tenths_down


def register(sub):
    _register_vehicle(sub)
    _register_run(sub)
    _register_reading(sub)
    _register_sweep(sub)
    _register_figures(sub)


def _register_vehicle(sub):
    """hpsim vehicle: equilibrium, response, new, check."""
    pv = sub.add_parser("vehicle", help="vehicle tools (new, check, equilibrium, response)")
    vsub = pv.add_subparsers(dest="vehicle_command", required=True, parser_class=type(pv))
    pe = vsub.add_parser("equilibrium", help="static equilibrium of the charged vehicle at given strut temperatures")
    pe.add_argument("--vehicle", default="apc_8x8", help="built-in vehicle name or path to a vehicle file (default apc_8x8)")
    pe.add_argument("--temperatures", default=None,
                    help="strut temperatures, comma separated: one for all struts, one per axle or one per strut "
                         "(axle-major, left first), e.g. 25degC or 40degC,35degC,30degC,25degC "
                         "(default: the charging temperature)")
    pe.add_argument("--json", action="store_true", help="print JSON only")
    pe.set_defaults(func=cmd_equilibrium)
    response.register(vsub)
    vehicles.register(vsub)


def _register_run(sub):
    """hpsim run: one drive into a results file."""
    pr = sub.add_parser("run", help="run a scenario file, writing HDF5 results as it goes")
    pr.add_argument("scenario", help="scenario YAML file (see docs/scenarios.md)")
    pr.add_argument("-o", "--output", default=None, help="HDF5 output file (default: <scenario name>.h5 here)")
    pr.add_argument("--resume", action="store_true", help="continue an interrupted or crashed run in --output")
    pr.add_argument("--overwrite", action="store_true", help="replace an existing output file")
    pr.add_argument("--no-progress", action="store_true", help="no progress bar")
    pr.add_argument("--time-parallel", default=None, metavar="P",
                    help="split the drive in time into segments run in P processes at once (each running "
                         "solver.time_parallel_lanes segments in lockstep, default 4), joined with a correction of "
                         "the slow states (overrides solver.time_parallel; auto: one process per CPU)")
    pr.set_defaults(func=cmd_run)


def _register_reading(sub):
    """hpsim report and hpsim compare: what reads results files."""
    pp = sub.add_parser("report", help="per-axle summary of a results file (or a shareable HTML/PDF report, also "
                                       "of a sweep or UQ study folder)")
    pp.add_argument("results", help="HDF5 file written by `hpsim run`, or (with --html/--pdf) a sweep or UQ study folder")
    pp.add_argument("--html", default=None, metavar="FILE",
                    help="one self-contained HTML file (figures embedded; needs jinja2: pip install -e \".[report]\")")
    pp.add_argument("--pdf", default=None, metavar="FILE", help="the same report as a PDF")
    pp.add_argument("--json", action="store_true", help="print JSON only")
    pp.add_argument("--psd", default=None, metavar="PNG",
                    help="response PSDs (hull heave/pitch/roll acceleration, strut forces; Welch) to this figure, "
                         "peak frequencies in the table / JSON; needs series stored with output.interval <= 1/30 s, e.g. 0.02 s")
    add_overwrite(pp)
    pp.set_defaults(func=cmd_report)

    pc = sub.add_parser("compare", help="compare results files side by side (load redistribution, heights, temperatures)")
    pc.add_argument("results", nargs="+", help="HDF5 files written by `hpsim run`")
    pc.add_argument("--json", action="store_true", help="print JSON only")
    pc.add_argument("--plot", default=None, metavar="PNG", help="grouped bar chart to this file")
    add_overwrite(pc)
    pc.set_defaults(func=cmd_compare)



def _register_sweep(sub):
    """hpsim sweep: a base scenario over a grid or list of overrides."""
    ps = sub.add_parser("sweep", help="run a base scenario over a grid or list of overrides (parallel)")
    ps.add_argument("sweep", help="sweep YAML file (see docs/scenarios.md)")
    ps.add_argument("-o", "--output-dir", default=None, help="folder for the case files, summary.csv and plots "
                                                             "(default: the sweep file's output_dir)")
    ps.add_argument("--workers", type=int, default=None, help="parallel local processes (default: CPU count)")
    ps.add_argument("--scheduler", default=None, metavar="ADDRESS",
                    help="run the cases on an existing Dask distributed cluster (needs the 'dask' extra)")
    add_ensemble(ps)
    ps.add_argument("--json", action="store_true", help="print the summary as JSON only")
    ps.add_argument("--yes", action="store_true",
                    help="start without asking (at a terminal a sweep estimated above 5 min asks first)")
    ps.add_argument("--overwrite", action="store_true",
                    help="run again the cases whose results were made from another definition (changed overrides, "
                         "base scenario or input files); without it such a sweep is refused")
    ps.set_defaults(func=cmd_sweep)

def _register_figures(sub):
    """hpsim animate and hpsim plot: figures of one results file."""
    pa = sub.add_parser("animate", help="side-view movie of a drive (hull, wheels and struts over the road)")
    pa.add_argument("results", help="HDF5 file written by `hpsim run` with its series stored (output.interval)")
    pa.add_argument("-o", "--output", required=True, help="movie file: .gif (Pillow) or .mp4 (needs ffmpeg)")
    pa.add_argument("--from", dest="start", default=None, metavar="DISTANCE", help="start of the span, e.g. 10km")
    pa.add_argument("--to", dest="end", default=None, metavar="DISTANCE", help="end of the span, e.g. 10.2km")
    pa.add_argument("--fps", type=float, default=None, help="frames per second of driving (default 20: real time)")
    add_overwrite(pa)
    pa.set_defaults(func=cmd_animate)

    pl = sub.add_parser("plot", help="dashboard figure of a results file")
    pl.add_argument("results", help="HDF5 file written by `hpsim run`")
    pl.add_argument("-o", "--output", default=None, help="PNG file (default: <results>.png)")
    add_overwrite(pl)
    pl.set_defaults(func=cmd_plot)


# --- vehicle equilibrium ---------------------------------------------------------------------------
def cmd_equilibrium(args):
    from hpsim.tables import format_table, print_json

    from vehicle.physics.equilibrium import EquilibriumSolver, charge_gas_masses, equilibrium_table
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle

    P = load_vehicle(args.vehicle)
    T = response.strut_temperatures(P, args.temperatures)
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
    from vehicle.results.run import RunInterrupted, run_scenario

    scen = Path(args.scenario)
    out = Path(args.output) if args.output is not None else Path(scen.stem + ".h5")
    check_output_file(out if args.output is None else args.output, "-o/--output", make_parents=True,  # before any work
                      inputs=[scen])
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
    if getattr(args, "verbosity", 0) < 0:          # -q: only the path written
        print(out)
        return 0
    print(format_report(report(out, check=False)))      # written by this process just now
    print(f"wrote {out} (the command {tenths_down(command_wall_s())} s wall, the drive "
          f"{tenths_down(summary.get('wall_s', 0.0))} s)")
    return 0


def _with_time_parallel(scen: Path, value: str):
    """The scenario with solver.time_parallel set from --time-parallel (checked here: int in range or auto)."""
    from vehicle.scenario.schema import apply_overrides, read_scenario
    from vehicle.engines.time_parallel import SEGMENTS_RANGE

    lo, hi = SEGMENTS_RANGE
    v = value.strip().lower()
    if v != "auto":
        try:
            v = int(v)
        except ValueError:
            v = None
        if v is None or not lo <= v <= hi:
            raise UserInputError(f"--time-parallel: must be an integer in [{lo}, {hi}] (processes) or auto, got {value!r}")
    src = read_scenario(scen)
    src.data = apply_overrides(src.data, {"solver.time_parallel": v}, str(scen))
    return src


def cmd_report(args):
    from hpsim.tables import print_json

    from vehicle.presentation.report import format_report, report

    if args.html or args.pdf:
        return _shareable_report(args)
    if Path(args.results).is_dir():
        raise UserInputError(f"{args.results}: a folder: its report needs --html FILE or --pdf FILE (a sweep or UQ "
                             "study folder); the text report reads one results file")
    rep = report(args.results)
    if args.psd:
        from vehicle.presentation.plots import psd_plot
        from vehicle.presentation.report import format_psd
        from vehicle.analysis.psd import response_psd

        from vehicle.results.reader import open_results

        check_figure_file(args.psd, "--psd", make_parents=True, inputs=[args.results], overwrite=args.overwrite)
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


def _shareable_report(args):
    from vehicle.presentation.html_report import document, write_html, write_pdf

    for value, flag, suffix in ((args.html, "--html", (".html", ".htm")), (args.pdf, "--pdf", (".pdf",))):
        if value is not None:
            check_output_file(Path(value), flag, make_parents=True, inputs=[args.results], overwrite=args.overwrite)
            if Path(value).suffix.lower() not in suffix:
                raise UserInputError(f"{flag}: {value!r} must end in {' or '.join(suffix)}")
    if not Path(args.results).exists():
        raise UserInputError(f"{args.results}: no such results file or study folder")
    from vehicle.presentation.optimize_report import is_optimize_folder, optimize_document

    doc = optimize_document(Path(args.results)) if is_optimize_folder(args.results) else document(args.results)
    if args.html:
        print(f"wrote {write_html(doc, args.html)}")
    if args.pdf:
        print(f"wrote {write_pdf(doc, args.pdf)}")
    return 0


def cmd_compare(args):
    from hpsim.tables import print_json

    from vehicle.presentation.report import compare, format_compare

    if args.plot:
        check_figure_file(args.plot, "--plot", make_parents=True, inputs=args.results, overwrite=args.overwrite)
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
    check_figure_file(out if args.output is None else args.output, "-o/--output", make_parents=True,
                      inputs=[args.results], overwrite=args.overwrite)
    dashboard(args.results, out)
    print(f"wrote {out}")
    return 0


def _sweep_preview(args, prepared) -> None:
    """The number of drives and the estimated wall time of a sweep (vehicle.studies.cost), before it starts."""
    from vehicle.cli.stages import command_wall_s
    from vehicle.studies import cost

    cost.confirm(cost.estimate(prepared, args.workers, cluster=bool(args.scheduler), ensemble=args.ensemble,
                               elapsed_s=command_wall_s(), what="hpsim sweep"),
                 "hpsim sweep", args.yes)


def cmd_animate(args):
    from hpsim.units import parse_quantity

    from vehicle.presentation.animation import FPS, animate

    start = None if args.start is None else parse_quantity(args.start, "m", where="--from")
    end = None if args.end is None else parse_quantity(args.end, "m", where="--to")
    fps = FPS if args.fps is None else args.fps
    if not 0 < fps <= 100:
        raise UserInputError(f"--fps: must be in (0, 100] frames per second, got {args.fps}")
    check_output_file(Path(args.output), "-o/--output", make_parents=True, inputs=[args.results],
                      overwrite=args.overwrite)
    res = animate(args.results, args.output, start, end, fps, progress=getattr(args, "verbosity", 0) >= 0)
    print(f"wrote {res['file']} ({res['frames']} frames at {res['fps']:.3g} per second, {res['duration_s']:.2f} s, "
          f"{res['writer']})")
    return 0


def cmd_sweep(args):
    from hpsim.tables import print_json

    from vehicle.presentation.plots import compare_plot
    from vehicle.presentation.report import format_summary
    from vehicle.studies.sweep import run_sweep

    check_count("--workers", args.workers)
    check_output_dir(Path(args.sweep).stem if args.output_dir is None else args.output_dir,
                     "-o/--output-dir" if args.output_dir is not None else "output folder (the sweep file's name)")
    from vehicle.engines.ensemble import check_lanes

    check_lanes(args.ensemble)
    result = run_sweep(args.sweep, output_dir=args.output_dir, workers=args.workers, scheduler=args.scheduler,
                       ensemble=args.ensemble, log=(lambda m: None) if args.json else logging.getLogger("hpsim").info,
                       before_start=lambda prepared: _sweep_preview(args, prepared), overwrite=args.overwrite)
    drives_done = time.perf_counter()
    if result["finished_files"]:
        # every finished file was read whole by this command (a case complete from before, by its report) or written
        # whole by its worker: no child-process read check again
        result["plots"].append(str(compare_plot(result["finished_files"], Path(result["output_dir"]) / "compare.png",
                                                labels=result["finished_labels"], check=False)))
    if args.json:
        print_json(result)
    elif getattr(args, "verbosity", 0) < 0 and not result["failed"]:     # -q: only what was written
        print(result["summary_csv"])
    else:
        print(format_summary(result))
    if result["finished_files"]:
        from vehicle.studies import cost

        cost.record_finish("hpsim sweep", time.perf_counter() - drives_done)
    return 3 if result["failed"] else 0
