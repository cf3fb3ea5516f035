"""Benchmark of the terrain package: time and peak memory for long roads.

    python benchmarks/road.py [--json] [--length 200km] [--csv] [--casadi]

Stages (class D, two isotropic-coherent tracks, 5 cm spacing, seed 7):
  generate   build_road (streaming FFT generation)
  envelope   Road.enveloped(0.4 m)
  slopes     clamped-spline knot slopes of one track (first `evaluate` call)
  evaluate   Road.evaluate on 1e6 random distances (slopes cached)
  statistics road_statistics (Welch, fits, coherence, IRI of both tracks)
  csv        Road.to_csv (optional, --csv)
  casadi     Road.casadi_function for one track (optional, --casadi)
and the targets for 106 km: generate + envelope < 3 s, evaluate(1e6) < 0.5 s.

Time is wall-clock (best of --repeat runs); peak memory is the tracemalloc peak of the stage
(NumPy reports its buffers to tracemalloc) measured in a separate run, plus the process's
maximum resident set size at the end.
"""
from __future__ import annotations

import argparse
import gc
import json
import os
import resource
import sys
import tempfile
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from terrain import RoadSpec, build_road, road_statistics  # noqa: E402

MB = 1024.0 * 1024.0


def _measure(fn, repeat: int):
    """(best wall time [s], tracemalloc peak [MB], result)."""
    best = float("inf")
    result = None
    for _ in range(repeat):
        result = None
        gc.collect()
        t0 = time.perf_counter()
        result = fn()
        best = min(best, time.perf_counter() - t0)
    result = None
    gc.collect()
    tracemalloc.start()
    tracemalloc.reset_peak()
    result = fn()
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return best, peak / MB, result


def run(length: str, repeat: int, with_csv: bool, with_casadi: bool) -> dict:
    spec = RoadSpec(iso_class="D", length=length, seed=7)
    rows = {}
    t, m, road = _measure(lambda: build_road(spec), repeat)
    rows["generate"] = (t, m)
    t, m, env = _measure(lambda: road.enveloped(0.4), repeat)
    rows["envelope"] = (t, m)
    from terrain.road import clamped_spline_slopes

    t, m, _ = _measure(lambda: clamped_spline_slopes(env.left_m, env.spacing_m), repeat)
    rows["slopes"] = (t, m)
    env.knot_slopes("left")
    s = np.random.default_rng(0).uniform(-10.0, env.length_m + 10.0, 1_000_000)
    t, m, _ = _measure(lambda: env.evaluate(s, "left"), repeat)
    rows["evaluate_1e6"] = (t, m)
    t, m, st = _measure(lambda: road_statistics(road), 1)
    rows["statistics"] = (t, m)
    if with_csv:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "road.csv"
            t, m, _ = _measure(lambda: road.to_csv(path), 1)
            rows["csv_write"] = (t, m)
            rows["csv_size_MB"] = (path.stat().st_size / MB, 0.0)
    if with_casadi:
        t, m, _ = _measure(lambda: road.casadi_function("left"), 1)
        rows["casadi_build"] = (t, m)
    out = {
        "length_m": road.length_m,
        "points": road.n_points,
        "track_arrays_MB": 2 * road.n_points * 8 / MB,
        "stages": {k: {"time_s": round(v[0], 4), "peak_MB": round(v[1], 1)} for k, v in rows.items()},
        "fitted_gd_n0_m3": st["gd_n0_m3"],
        "iso_class": st["iso_class"],
        "max_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "cpu_count": os.cpu_count(),
    }
    return out


def targets(repeat: int) -> dict:
    """Road generation and evaluation on 106 km against their targets: 3 s to generate and envelope, 0.5 s per 1e6 points."""
    spec = RoadSpec(iso_class="D", length="106 km", seed=7)
    best_gen = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        road = build_road(spec).enveloped(0.4)
        best_gen = min(best_gen, time.perf_counter() - t0)
    road.knot_slopes("left")
    s = np.random.default_rng(1).uniform(0.0, road.length_m, 1_000_000)
    best_eval = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        road.evaluate(s, "left")
        best_eval = min(best_eval, time.perf_counter() - t0)
    return {"generate_envelope_106km_s": round(best_gen, 3), "target_s": 3.0, "ok": best_gen < 3.0,
            "evaluate_1e6_s": round(best_eval, 3), "evaluate_target_s": 0.5, "evaluate_ok": best_eval < 0.5}


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", action="store_true", help="print only JSON")
    p.add_argument("--length", default="200 km")
    p.add_argument("--repeat", type=int, default=2, help="timing runs per stage (best is kept)")
    p.add_argument("--csv", action="store_true", help="also time writing the CSV")
    p.add_argument("--casadi", action="store_true", help="also time building a CasADi function")
    args = p.parse_args(argv)
    res = run(args.length, args.repeat, args.csv, args.casadi)
    res["targets_106km"] = targets(args.repeat)
    res["max_rss_MB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    if args.json:
        print(json.dumps(res, indent=2))
        return 0
    print(f"road {res['length_m'] / 1000:.0f} km, {res['points']} points per track "
          f"({res['track_arrays_MB']:.0f} MB for the two tracks), {res['cpu_count']} CPUs")
    print(f"{'stage':>14}  {'time [s]':>9}  {'peak [MB]':>9}")
    for k, v in res["stages"].items():
        print(f"{k:>14}  {v['time_s']:9.3f}  {v['peak_MB']:9.1f}")
    t = res["targets_106km"]
    print(f"106 km generate+envelope: {t['generate_envelope_106km_s']:.3f} s (target < 3 s: "
          f"{'ok' if t['ok'] else 'MISSED'}); evaluate 1e6: {t['evaluate_1e6_s']:.3f} s (target < 0.5 s: "
          f"{'ok' if t['evaluate_ok'] else 'MISSED'})")
    print(f"fitted Gd(n0) {res['fitted_gd_n0_m3']:.4g} m³ (class {res['iso_class']}); "
          f"max RSS {res['max_rss_MB']:.0f} MB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
