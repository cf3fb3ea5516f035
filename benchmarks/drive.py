"""Timing and accuracy of a drive, full mode and multiscale mode, against a tight reference.

    python benchmarks/drive.py --distance 5km [--window 200m --spacing 1km] [--json] [--warm-cache]
    python benchmarks/drive.py --scenario scenarios/mileage_106km.yaml --no-reference
    python benchmarks/drive.py --scenario scenarios/mileage_106km.yaml --no-reference --road-seed 1 \
        --full-cache full_seed1.json --proxy road_rate     # the full run once per scenario and seed, then reused

The drive: the apc_8x8 on ISO class D (seed 0) at 20 km/h, 25 degC, struts starting at ambient
(or the given scenario). Three runs in one process, through the scenario machinery `hpsim run` uses
(vehicle.scenario.schema.prepare -> Drive / MultiscaleDrive, no results file):
  full        the production solver (compiled ROS2) at 4 ms (or the scenario's dt);
  multiscale  `solver: {mode: multiscale}` with --window / --spacing / --warm-up;
  reference   the full model with ROS2 at 1 ms (--reference-dt): the step's own error is second order,
              so 1 ms is ~16x tighter than 4 ms (skip with --no-reference; with --scenario the
              full run is then the reference of the multiscale run).
A cold compilation cache (so the first build includes generating and compiling the C code) unless
--warm-cache. Per axle (mean of left and right): the final strut temperature [K] and the wheel-load
change before -> after the drive [pp]; the errors are the largest over the axles. Timings on a
shared 2-core machine are noisy: compare the ratios of one run.

JSON keys per mode (full, multiscale, reference): build_s, wall_s, integration_s, rtf (simulated
seconds per second of integration), T_end_K (per axle), dN_pct (per axle), and for full and
multiscale max_temperature_error_K, max_load_error_pp against the reference; multiscale also
estimated_error_K / estimated_error_pp (its own a-posteriori estimate, a 95 % interval) and covered_km.
projected_106km: the 106 km mileage drive's integration time at the full run's rate (full: 19080 s /
rtf; multiscale: the share of the road the multiscale run drove, at the same rate). drive_s: the drive's
wall time without the build (set-up, compilation). A short --distance gives short windows whose warm-up and per-window work weigh more: the
multiscale speed-up measured there is not the 106 km one (run --scenario scenarios/mileage_106km.yaml).
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

MILEAGE_S = 106e3 / (20 / 3.6)      # 19080 s of driving in the 106 km test


def scenario_data(args) -> dict:
    import yaml

    if args.scenario:
        data = yaml.safe_load(Path(args.scenario).read_text())
        data.setdefault("solver", {})
        return data
    return {"description": "benchmark", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 0},
            "speed": "20 km/h", "distance": args.distance, "ambient_temperature": "25 degC",
            "solver": {"dt": args.dt}, "output": {"interval": "1 s", "stats_interval": "1 km"}}


def run(data: dict, base_dir: str) -> dict:
    import yaml

    from vehicle.engines.build import build_engine
    from vehicle.scenario.schema import prepare, read_scenario_text

    t0 = time.perf_counter()
    prep = prepare(read_scenario_text(yaml.safe_dump(data), "benchmark", base_dir))
    model, drive = build_engine(prep)
    build = time.perf_counter() - t0
    res = drive.run()
    wall = time.perf_counter() - t0
    before = drive.initial_equilibrium()
    n = model.n
    ax = np.array([model.params.station_axle(i) for i in range(n)])

    def axle_mean(v):
        v = np.asarray(v, float)
        return np.array([v[ax == k].mean() for k in range(model.params.n_axles)])

    N0, N1 = axle_mean(before.wheel_loads_N), axle_mean(res.after.wheel_loads_N)
    out = {"build_s": build, "wall_s": wall, "drive_s": res.wall_s, "integration_s": res.integration_s,
           "simulated_s": res.state.t_s, "rtf": res.state.t_s / max(res.integration_s, 1e-9),
           "T_end_K": axle_mean(res.state.x[drive.T_index]).tolist(),
           "dN_pct": (100.0 * (N1 - N0) / N0).tolist()}
    est = getattr(drive, "estimate", None)
    if est:
        out["estimated_error_K"] = float(np.max(est["axle_temperature_K"]))
        out["estimated_error_pp"] = float(np.max(est["load_change_pct"]))
        out["covered_km"] = est["covered_m"] / 1e3
        out["windows"] = est["n_windows"]
        out["control_variate"] = bool(est.get("control_variate", False))
    return out


def errors(run_: dict, ref: dict) -> dict:
    return {"max_temperature_error_K": float(np.max(np.abs(np.subtract(run_["T_end_K"], ref["T_end_K"])))),
            "max_load_error_pp": float(np.max(np.abs(np.subtract(run_["dN_pct"], ref["dN_pct"]))))}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", default="5km")
    ap.add_argument("--scenario", help="a scenario file instead of the built-in drive (e.g. the 106 km mileage test)")
    ap.add_argument("--dt", default="4ms")
    ap.add_argument("--reference-dt", default="1ms")
    ap.add_argument("--no-reference", action="store_true")
    ap.add_argument("--window", default=None, help="multiscale window (default: 500 m, or distance/25)")
    ap.add_argument("--spacing", default=None, help="multiscale spacing (default: 5 km, or distance/5)")
    ap.add_argument("--warm-up", default="50m")
    ap.add_argument("--no-control-variate", action="store_true", help="multiscale without the road-proxy regression")
    ap.add_argument("--road-seed", type=int, default=None, help="the road's random seed (overrides the scenario's)")
    ap.add_argument("--full-cache", default=None,
                    help="JSON file of the full run's result: read if it exists (the full run skipped), else written "
                         "after the run (compare multiscale settings against one full run; same scenario and seed)")
    ap.add_argument("--proxy", default=None, help="multiscale control-variate proxy (solver.proxy)")
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--warm-cache", action="store_true")
    args = ap.parse_args(argv)
    from hpsim.units import parse_quantity

    if not args.warm_cache:
        os.environ["HPSIM_CACHE"] = tempfile.mkdtemp(prefix="hpsim_bench_")
    base_dir = str(Path(args.scenario).resolve().parent) if args.scenario else "."
    data = scenario_data(args)
    if args.road_seed is not None:
        data["road"] = {**data.get("road", {}), "seed": args.road_seed}
    distance = parse_quantity(data["distance"], "m", where="distance")
    window = args.window or (f"{max(50.0, min(500.0, distance / 25)):.0f} m")
    spacing = args.spacing or (f"{min(5000.0, distance / 5):.0f} m")
    out = {"distance_km": distance / 1e3}
    cache = Path(args.full_cache) if args.full_cache else None
    if cache is not None and cache.exists():
        cached = json.loads(cache.read_text())
        if cached.get("scenario") != data:
            sys.exit(f"{cache}: the cached full run is of another scenario or road seed")
        out["full"] = cached["full"]
        out["full_cached"] = str(cache)
    else:
        out["full"] = run(data, base_dir)
        if cache is not None:
            cache.write_text(json.dumps({"scenario": data, "full": out["full"]}, indent=1))
    ms_data = {**data, "solver": {**data["solver"], "mode": "multiscale", "window": window, "spacing": spacing,
                                  "warm_up": args.warm_up, "control_variate": not args.no_control_variate,
                                  **({"proxy": args.proxy} if args.proxy else {})}}
    out["multiscale"] = run(ms_data, base_dir)
    out["multiscale"]["layout"] = {"window": window, "spacing": spacing, "warm_up": args.warm_up}
    if not args.no_reference:
        ref_data = {**data, "solver": {**data["solver"], "dt": args.reference_dt}}
        out["reference"] = run(ref_data, base_dir)
        out["reference"]["solver"] = f"ROS2 at {args.reference_dt}"
        ref = out["reference"]
    else:
        ref = out["full"]
    out["full"].update(errors(out["full"], ref))
    out["multiscale"].update(errors(out["multiscale"], ref))
    out["reference_is"] = "full mode" if args.no_reference else f"ROS2 at {args.reference_dt}"
    # the 106 km test: full at the full run's rate; multiscale: the share of the road this layout drives
    share = out["multiscale"]["covered_km"] / out["distance_km"]
    # the windows run the same engine: the share of the road they drive at the full run's rate (per-window
    # overheads, small for 500 m windows, aside)
    out["projected_106km"] = {"full_integration_s": MILEAGE_S / out["full"]["rtf"],
                              "multiscale_integration_s": share * MILEAGE_S / out["full"]["rtf"]}
    out["speedup_multiscale_vs_full_here"] = (out["full"]["integration_s"]
                                              / max(out["multiscale"]["integration_s"], 1e-9))
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{out['distance_km']:.6g} km, errors against {out['reference_is']} (largest over the axles)")
    for mode in ("full", "multiscale", "reference"):
        r = out.get(mode)
        if r is None:
            continue
        line = (f"  {mode:10s} build {r['build_s']:6.2f} s  drive {r['drive_s']:7.2f} s  wall {r['wall_s']:7.2f} s  integration "
                f"{r['integration_s']:7.2f} s  rtf {r['rtf']:7.0f}")
        if "max_temperature_error_K" in r and mode != "reference":
            line += f"  dT {r['max_temperature_error_K']:.3f} K  dN {r['max_load_error_pp']:.4f} pp"
        if "estimated_error_K" in r:
            line += (f"  (stated: {r['estimated_error_K']:.3f} K, {r['estimated_error_pp']:.4f} pp; "
                     f"{r['windows']} windows, {r['covered_km']:.3g} km in full)")
        print(line)
    p = out["projected_106km"]
    print(f"  speed-up of the multiscale run here: {out['speedup_multiscale_vs_full_here']:.1f}x; projected 106 km "
          f"integration: full {p['full_integration_s']:.1f} s, multiscale {p['multiscale_integration_s']:.1f} s "
          f"({out['multiscale']['layout']['window']} windows every {out['multiscale']['layout']['spacing']})")


if __name__ == "__main__":
    main()
