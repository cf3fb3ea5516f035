"""Timing and accuracy of a drive: the apc_8x8 on ISO class D at 20 km/h.

    python benchmarks/drive.py --distance 5km [--json] [--warm-cache]

Times the production solver (compiled ROS2, 4 ms) with a cold compilation cache (so build_s
includes generating and compiling the C code; --warm-cache reuses ~/.cache/hpsim), then runs
the same drive with the reference: the same DAE integrated with an 8x smaller step and a fully
converged valve Newton solve (the step-converged solution; the independent IDAS reference,
vehicle.numerics.solvers.IdasReference, agrees with it but needs ~10 s of wall time per simulated second,
too slow for kilometres). Reports the final strut temperature and after-drive wheel-load errors.

JSON keys: distance_km, simulated_s, build_s, wall_s, rtf, ref_max_temperature_error_K,
ref_max_load_error_pct, plus projected_106km_wall_s = build_s + 19080 s / rtf (the target is <= 60 s).
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def run(distance_m: float, dt: float, newton_iterations: int | None = None):
    from terrain import RoadSpec, build_road
    from vehicle.runs.drive import Drive, DriveSettings, SpeedProfile
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle

    t0 = time.perf_counter()
    model = VehicleModel(load_vehicle("apc_8x8"))
    if newton_iterations is not None:
        base = type(model).eliminate_valves
        model.eliminate_valves = lambda x, iterations=newton_iterations: base(model, x, iterations)
    road = build_road(RoadSpec(iso_class="D", length=distance_m + 50.0, seed=0))
    settings = DriveSettings(distance_m=distance_m, speed=SpeedProfile.constant(20 / 3.6), dt_s=dt,
                             ambient_K=298.15, initial_temperatures_K=298.15)
    drive = Drive(model, road, settings)
    build = time.perf_counter() - t0
    res = drive.run()
    wall = time.perf_counter() - t0
    return drive, res, build, wall


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", default="5km")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--warm-cache", action="store_true")
    ap.add_argument("--dt", default="4ms")
    args = ap.parse_args(argv)
    from hpsim.units import parse_quantity

    distance = parse_quantity(args.distance, "m", where="--distance")
    dt = parse_quantity(args.dt, "s", where="--dt")
    if not args.warm_cache:
        os.environ["HPSIM_CACHE"] = tempfile.mkdtemp(prefix="hpsim_bench_")
    drive, res, build, wall = run(distance, dt)
    ref_drive, ref, _, ref_wall = run(distance, dt / 8, newton_iterations=4)
    T = res.state.x[drive.T_index]
    T_ref = ref.state.x[ref_drive.T_index]
    N, N_ref = res.after.wheel_loads_N, ref.after.wheel_loads_N
    rtf = res.state.t_s / res.integration_s
    out = {
        "distance_km": distance / 1e3,
        "simulated_s": res.state.t_s,
        "build_s": build,
        "wall_s": wall,
        "integration_s": res.integration_s,
        "rtf": rtf,
        "projected_106km_wall_s": build + 19080.0 / rtf,
        "ref_max_temperature_error_K": float(np.max(np.abs(T - T_ref))),
        "ref_max_load_error_pct": float(np.max(np.abs(N - N_ref) / N_ref) * 100),
        "temperature_rise_K": float(np.mean(T - 298.15)),
        "reference": f"same DAE, ROS2 at dt/8 = {dt / 8 * 1e3:.3g} ms with a converged valve Newton",
        "reference_wall_s": ref_wall,
    }
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        for k, v in out.items():
            print(f"{k:32s} {v}")


if __name__ == "__main__":
    main()
