"""A study case's fixed cost: what a sweep spends per case besides integrating its drive, with and without the
parts its cases share (vehicle.engines.shared_builds), interleaved in one run.

    python benchmarks/case_fixed_cost.py [--cases 8] [--distance 5km] [--vary seed] [--repeats 2] [--json]

The sweep: the apc_8x8 at 20 km/h on ISO class D roads (4 ms step, output every 1 s, statistics every 1 km), its
cases differing in the road seed (--vary seed: every case its own road) or in the initial temperature (--vary
temperature: one road), run through `hpsim sweep`'s machinery case by case in this process
(vehicle.studies.sweep.run_sweep with workers 1 and no ensemble: one HDF5 file per case, the summary). Two ways,
alternating --repeats times after one warm-up drive (the compile and the roads cached):

  alone    every case builds its model, vehicle check and road, weighs the vehicle before its drive, and the summary
           reads each file through the child-process check (what each case did before the parts were shared);
  shared   the cases share them (a fresh `SharedBuilds` per sweep, as a new worker process starts with).

Printed for each, medians over the repeats: the sweep's wall time, the cases' integration (the solver's block
calls, from each file's summary), and the fixed cost per case = (wall - integration) / cases, split into what
runs inside the drive besides the solver (inputs, outputs, statistics, the step-doubling probe: it grows with the
distance) and what runs outside it (set-up, weighings, files, summary); then the ratio alone / shared of the fixed
cost per case. The machine is shared: the ratio is measured in one run, `uptime`'s load printed beside it.
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


def timed_sweep(path: Path, out: Path, shared: bool) -> dict:
    """One sweep case by case; {wall_s, integration_s, drive_s (the drives' own wall time)} summed over its cases."""
    import h5py
    from vehicle.analysis.summary import report
    from vehicle.engines.shared_builds import SharedBuilds
    from vehicle.studies import sweep

    builds = SharedBuilds()
    # alone: no shared parts, and the summary's read check on every file (the per-case path before sharing)
    sweep.process_builds = (lambda: builds) if shared else (lambda: None)
    sweep.report = report if shared else (lambda f, check=True: report(f, check=True))
    t0 = time.perf_counter()
    result = sweep.run_sweep(path, output_dir=out, workers=1, ensemble=1)
    wall = time.perf_counter() - t0
    if result["failed"]:
        sys.exit(f"cases failed: {result['failed']}")
    integration = drive = 0.0
    for f in result["finished_files"]:
        with h5py.File(f, "r") as h:
            integration += float(h["summary"].attrs["integration_s"])
            drive += float(h["summary"].attrs["wall_s"])
    return {"wall_s": wall, "integration_s": integration, "drive_s": drive}


def load() -> float:
    return os.getloadavg()[0]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=8)
    ap.add_argument("--distance", default="5km")
    ap.add_argument("--vary", choices=("seed", "temperature"), default="seed")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from vehicle.results.run import run_scenario
    from vehicle.scenario.schema import prepare, read_scenario
    from vehicle.studies.sweep import load_sweep

    load_before = load()
    runs: dict[str, list[dict]] = {"alone": [], "shared": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        path = sweep_file(tmp, args.cases, args.distance, args.vary)
        run_scenario(read_scenario(tmp / "base.yaml"), tmp / "warm.h5", progress=False)    # the compile, cached
        for case in load_sweep(path)[2]:
            prepare(case["source"]).road()                                               # the roads, cached
        for r in range(args.repeats):
            for way in ("alone", "shared") if r % 2 == 0 else ("shared", "alone"):
                runs[way].append(timed_sweep(path, tmp / f"{way}{r}", way == "shared"))
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
                    "fixed_per_case_each_s": fixed}
    out["ratio_fixed_alone_to_shared"] = out["alone"]["fixed_per_case_s"] / out["shared"]["fixed_per_case_s"]
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{args.cases} cases of {args.distance} (apc_8x8, class D, vary {args.vary}), case by case in one process, "
          f"medians of {args.repeats}; load {load_before:.1f} before, {out['load_after']:.1f} after "
          f"({os.cpu_count()} CPUs)")
    print(f"{'':8s} {'wall':>8s} {'integration':>12s} {'fixed/case':>11s} {'in drive':>9s} {'outside':>8s}")
    for way in ("alone", "shared"):
        w = out[way]
        print(f"{way:8s} {w['wall_s']:7.2f}s {w['integration_s']:11.2f}s {w['fixed_per_case_s']:10.3f}s "
              f"{w['in_drive_per_case_s']:8.3f}s {w['outside_drive_per_case_s']:7.3f}s")
    print(f"fixed cost per case, alone / shared: {out['ratio_fixed_alone_to_shared']:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
