"""Sweep scaling: the same cases run with 1 and with 2 workers.

    python benchmarks/sweep_scaling.py [--cases 4] [--distance 2km] [--workers 2] [--json]

The cases are the apc_8x8 on ISO class D roads that differ only in the road seed, so they share
one compiled model (compiled once before timing; each worker process still loads it). They run
through `hpsim sweep`'s machinery (vehicle.studies.sweep.run_sweep: local processes, one HDF5 file
per case, the summary), first with one worker, then with --workers. Printed: wall time of each,
the speed-up and the efficiency per worker = T(1 worker) / (k x T(k workers)); 1.0 is perfect.
The machine's cores are shared with whatever else runs: repeat the measurement before trusting
a difference of a few per cent.

JSON keys: cases, distance_km, workers, wall_1_s, wall_k_s, speedup, efficiency_per_worker,
case_s_1 (mean seconds per case with one worker), case_s_k, cpu_count.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

BASE = """\
vehicle: {{name: apc_8x8}}
road: {{iso_class: D, seed: 0}}
speed: 20 km/h
distance: {distance}
ambient_temperature: 25 degC
output: {{interval: 1 s, stats_interval: 1 km}}
"""


def timed_sweep(sweep: Path, out: Path, workers: int) -> tuple[float, dict]:
    from vehicle.studies.sweep import run_sweep

    t0 = time.perf_counter()
    result = run_sweep(sweep, output_dir=out, workers=workers)
    wall = time.perf_counter() - t0
    if result["failed"]:
        sys.exit(f"cases failed: {result['failed']}")
    return wall, result


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=4)
    ap.add_argument("--distance", default="2km")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from hpsim.units import parse_quantity
    from vehicle.results.run import run_scenario

    distance_m = parse_quantity(args.distance, "m", where="--distance")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "base.yaml").write_text(BASE.format(distance=args.distance))
        seeds = ", ".join(str(k + 1) for k in range(args.cases))
        (tmp / "sweep.yaml").write_text(f"base: base.yaml\ngrid:\n  road.seed: [{seeds}]\n")
        run_scenario(tmp / "base.yaml", tmp / "warm.h5", progress=False)   # compile once (cached)
        wall_1, r1 = timed_sweep(tmp / "sweep.yaml", tmp / "w1", 1)
        wall_k, rk = timed_sweep(tmp / "sweep.yaml", tmp / f"w{args.workers}", args.workers)
    speedup = wall_1 / wall_k
    out = {"cases": args.cases, "distance_km": distance_m / 1e3, "workers": args.workers,
           "wall_1_s": wall_1, "wall_k_s": wall_k, "speedup": speedup,
           "efficiency_per_worker": speedup / args.workers,
           "case_s_1": sum(float(c["wall_s"]) for c in r1["cases"]) / args.cases,
           "case_s_k": sum(float(c["wall_s"]) for c in rk["cases"]) / args.cases,
           "cpu_count": os.cpu_count()}
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(f"{args.cases} cases of {distance_m / 1e3:g} km (apc_8x8, class D), {os.cpu_count()} CPUs")
        print(f"1 worker : {wall_1:7.1f} s wall ({out['case_s_1']:.1f} s per case inside the drive)")
        print(f"{args.workers} workers: {wall_k:7.1f} s wall ({out['case_s_k']:.1f} s per case inside the drive)")
        print(f"speed-up {speedup:.2f}x, efficiency per worker {out['efficiency_per_worker']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
