"""A study case's fixed cost: what a sweep spends per case besides integrating its drive, with and without the
parts its cases share (vehicle.engines.shared_builds), interleaved in one run.

    python benchmarks/case_fixed_cost.py [--cases 8] [--distance 5km] [--vary seed] [--repeats 2] [--lanes K] [--json]

The sweep: the apc_8x8 at 20 km/h on ISO class D roads (4 ms step, output every 1 s, statistics every 1 km), its
cases differing in the road seed (--vary seed: every case its own road) or in the initial temperature (--vary
temperature: one road), run through `hpsim sweep`'s machinery case by case in this process
(vehicle.studies.sweep.run_sweep with workers 1 and no ensemble: one HDF5 file per case, the summary). Two ways,
alternating --repeats times after one warm-up drive (the compile and the roads cached):

  alone    every case builds its model, vehicle check and road, weighs the vehicle before its drive, and the summary
           reads each file through the child-process check (what each case did before the parts were shared);
  shared   the cases share them (a fresh `SharedBuilds` per sweep, as a new worker process starts with);
  lanes    (with --lanes K) shared, and the cases K at a time in lockstep on the ensemble engine
           (vehicle.engines.ensemble): its wall time only (a lane's integration time includes its wait for the
           group's calls).

Printed for each, medians over the repeats: the sweep's wall time, the cases' integration (the solver's block
calls, from each file's summary), and the fixed cost per case = (wall - integration) / cases, split into what
runs inside the drive besides the solver (inputs, outputs, statistics, the step-doubling probe: it grows with the
distance) and what runs outside it (set-up, weighings, files, summary); then the ratio alone / shared of the fixed
cost per case. The same in CPU time (this process and its children, less the CPU time of every call of the
scalar solver: blocks, the drive's last steps and the step-doubling probes), which a loaded machine disturbs
less than wall time. The machine is shared: the ratios are measured in one run, `uptime`'s load printed beside.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BASE = """\
vehicle: {{name: apc_8x8}}
road: {{iso_class: D, seed: 1}}
speed: 20 km/h
distance: {distance}
ambient_temperature: 25 degC
solver: {{dt: 4 ms}}
output: {{interval: 1 s, stats_interval: 1 km}}
"""


def sweep_file(folder: Path, cases: int, distance: str, vary: str) -> Path:
    (folder / "base.yaml").write_text(BASE.format(distance=distance))
    if vary == "seed":
        grid = f"road.seed: [{', '.join(str(k + 1) for k in range(cases))}]"
    else:
        grid = f"initial_temperatures: [{', '.join(f'{20 + 2 * k} degC' for k in range(cases))}]"
    path = folder / "sweep.yaml"
    path.write_text(f"base: base.yaml\ngrid:\n  {grid}\n")
    return path


SOLVER_CPU = [0.0]           # CPU seconds inside the scalar solver's calls (`count_solver_cpu`)


def count_solver_cpu() -> None:
    """Add the thread's CPU time of every scalar solver call to SOLVER_CPU."""
    from vehicle.numerics.solvers import Ros2

    advance = Ros2.advance

    def counted(self, x0, U, p):
        t0 = time.thread_time()
        try:
            return advance(self, x0, U, p)
        finally:
            SOLVER_CPU[0] += time.thread_time() - t0
    Ros2.advance = counted


def cpu_s() -> float:
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def timed_sweep(path: Path, out: Path, shared: bool, lanes: int = 1) -> dict:
    """One sweep (lanes 1: case by case); {wall_s, integration_s, drive_s (the drives' own wall time)} summed over
    its cases."""
    import h5py
    from vehicle.analysis.summary import report
    from vehicle.engines.shared_builds import SharedBuilds
    from vehicle.studies import sweep

    builds = SharedBuilds()
    # alone: no shared parts, and the summary's read check on every file (the per-case path before sharing)
    sweep.process_builds = (lambda: builds) if shared else (lambda: None)
    sweep.report = report if shared else (lambda f, check=True: report(f, check=True))
    t0, c0, s0 = time.perf_counter(), cpu_s(), SOLVER_CPU[0]
    result = sweep.run_sweep(path, output_dir=out, workers=1, ensemble=lanes)
    wall, cpu, solver_cpu = time.perf_counter() - t0, cpu_s() - c0, SOLVER_CPU[0] - s0
    if result["failed"]:
        sys.exit(f"cases failed: {result['failed']}")
    integration = drive = 0.0
    for f in result["finished_files"]:
        with h5py.File(f, "r") as h:
            integration += float(h["summary"].attrs["integration_s"])
            drive += float(h["summary"].attrs["wall_s"])
    return {"wall_s": wall, "integration_s": integration, "drive_s": drive, "cpu_s": cpu, "solver_cpu_s": solver_cpu}


def load() -> float:
    return os.getloadavg()[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=8)
    ap.add_argument("--distance", default="5km")
    ap.add_argument("--vary", choices=("seed", "temperature"), default="seed")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--lanes", type=int, default=0, help="also the shared cases on K ensemble lanes (0: not)")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from vehicle.results.run import run_scenario
    from vehicle.scenario.schema import prepare, read_scenario
    from vehicle.studies.sweep import load_sweep

    count_solver_cpu()
    load_before = load()
    ways = ("alone", "shared") + (("lanes",) if args.lanes > 1 else ())
    runs: dict[str, list[dict]] = {way: [] for way in ways}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = sweep_file(tmp, args.cases, args.distance, args.vary)
        run_scenario(read_scenario(tmp / "base.yaml"), tmp / "warm.h5", progress=False)    # the compile, cached
        for case in load_sweep(path)[2]:
            prepare(case["source"]).road()                                               # the roads, cached
        for r in range(args.repeats):
            for way in ways if r % 2 == 0 else ways[::-1]:
                lanes = args.lanes if way == "lanes" else 1
                runs[way].append(timed_sweep(path, tmp / f"{way}{r}", way != "alone", lanes))
    out = {"cases": args.cases, "distance": args.distance, "vary": args.vary, "repeats": args.repeats,
           "load_before": load_before, "load_after": load(), "cpu_count": os.cpu_count()}
    for way, rows in runs.items():
        n = args.cases
        fixed = [(x["wall_s"] - x["integration_s"]) / n for x in rows]
        out[way] = {"wall_s": statistics.median(x["wall_s"] for x in rows),
                    "integration_s": statistics.median(x["integration_s"] for x in rows),
                    "fixed_per_case_s": statistics.median(fixed),
                    "in_drive_per_case_s": statistics.median((x["drive_s"] - x["integration_s"]) / n for x in rows),
                    "outside_drive_per_case_s": statistics.median((x["wall_s"] - x["drive_s"]) / n for x in rows),
                    "fixed_per_case_each_s": fixed,
                    "cpu_s": statistics.median(x["cpu_s"] for x in rows),
                    "solver_cpu_s": statistics.median(x["solver_cpu_s"] for x in rows),
                    "fixed_cpu_per_case_s": statistics.median((x["cpu_s"] - x["solver_cpu_s"]) / n for x in rows)}
    out["ratio_fixed_alone_to_shared"] = out["alone"]["fixed_per_case_s"] / out["shared"]["fixed_per_case_s"]
    out["ratio_fixed_cpu_alone_to_shared"] = (out["alone"]["fixed_cpu_per_case_s"] /
                                              out["shared"]["fixed_cpu_per_case_s"])
    if "lanes" in out:
        out["ratio_wall_alone_to_lanes"] = out["alone"]["wall_s"] / out["lanes"]["wall_s"]
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{args.cases} cases of {args.distance} (apc_8x8, class D, vary {args.vary}), case by case in one process, "
          f"medians of {args.repeats}; load {load_before:.1f} before, {out['load_after']:.1f} after "
          f"({os.cpu_count()} CPUs)")
    print(f"{'':8s} {'wall':>8s} {'integration':>12s} {'fixed/case':>11s} {'in drive':>9s} {'outside':>8s} "
          f"{'CPU fixed/case':>15s}")
    for way in ways:
        w = out[way]
        if way == "lanes":          # a lane's integration time is its wait for the group's calls: only the wall
            print(f"{way:8s} {w['wall_s']:7.2f}s")
            continue
        print(f"{way:8s} {w['wall_s']:7.2f}s {w['integration_s']:11.2f}s {w['fixed_per_case_s']:10.3f}s "
              f"{w['in_drive_per_case_s']:8.3f}s {w['outside_drive_per_case_s']:7.3f}s "
              f"{w['fixed_cpu_per_case_s']:14.3f}s")
    print(f"fixed cost per case, alone / shared: {out['ratio_fixed_alone_to_shared']:.2f}x in wall time, "
          f"{out['ratio_fixed_cpu_alone_to_shared']:.2f}x in CPU time")
    if "lanes" in out:
        print(f"sweep wall, alone / shared on {args.lanes} lanes: {out['ratio_wall_alone_to_lanes']:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
