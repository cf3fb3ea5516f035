"""Parallel in time against the serial run, in one process: wall time and accuracy.

    python benchmarks/time_parallel.py [--scenario scenarios/mileage_106km.yaml] [--segments 2] [--lanes 4] [--baseline]
                                       [--reference-dt 1ms] [--dt STEP] [--json]

Three runs of the same scenario into memory (vehicle.results.run.run_in_memory, what sweeps and UQ use):
  serial         the full drive (compiled ROS2 at the scenario's dt) in this process;
  time_parallel  `solver: {time_parallel: P, time_parallel_lanes: 1}`: P segments in P processes on the scalar
                 engine, a multiscale coarse run predicting the segment starts, the slow-state correction
                 (vehicle.engines.time_parallel);
  lanes          `solver: {time_parallel: P, time_parallel_lanes: --lanes}` (default 4): P x lanes segments, each
                 process running its lanes in lockstep on the lane library (vehicle.numerics.lanes).
Printed: drive wall time of each (the summary's wall_s: without building the model, the same for both) and
their ratio, the sum of the workers' CPU time and the coarse run's wall time. Per axle it prints the final strut
temperature and wheel-load change differences (time-parallel - serial), without the correction for the
temperatures, and the run's own a-posteriori estimate. With --reference-dt it prints every run's largest
per-axle error of the final strut temperature and the load change against the serial run at that step (e.g.
1 ms). On a machine shared with other work the wall ratio understates what P free cores give: the CPU sum says
how much work was done.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", default=str(Path(__file__).resolve().parents[1] / "scenarios/mileage_106km.yaml"))
    ap.add_argument("--segments", type=int, default=2, help="processes of the time-parallel runs (solver.time_parallel)")
    ap.add_argument("--lanes", default="4",
                    help="segments per process of the run on the lane library (solver.time_parallel_lanes, or auto: "
                         "the scenario default); 0: leave that run out")
    ap.add_argument("--distance", default=None, help="override the scenario's distance, e.g. '10 km'")
    ap.add_argument("--baseline", action="store_true",
                    help="also run the baseline engine serially first (benchmarks/baseline_solvers.py, same model)")
    ap.add_argument("--dt", default=None,
                    help="the serial and time-parallel runs' step (default the scenario's; the old engine of "
                         "--baseline keeps the scenario's: today's engine as configured), e.g. '1/260 s' as '3.846153846 ms'")
    ap.add_argument("--reference-dt", default=None,
                    help="also run the full model serially at this step (e.g. 1ms: the issue's tight reference) and "
                         "report every run's final temperatures and load changes against it")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)

    from benchmarks.engine import summarize
    from vehicle.results.run import run_in_memory
    from vehicle.scenario.schema import read_scenario, read_scenario_text
    from vehicle.analysis.summary import report_from

    src = read_scenario(args.scenario)
    data = dict(src.data)
    if args.distance:
        data["distance"] = args.distance

    cpu = {}

    def run(solver_extra, name):
        d = {**data, "solver": {**(data.get("solver") or {}), **solver_extra}}
        s = read_scenario_text(yaml.safe_dump(d), src.name, src.base_dir)
        t0, c0 = time.perf_counter(), time.process_time()
        marks = []
        # the serial drive's CPU time: from its first block to its last (progress is called after each block)
        sink = run_in_memory(s, progress=None if name != "serial" else (lambda *a: marks.append(time.process_time())))
        if marks:
            cpu["serial_drive"] = marks[-1] - marks[0]
        cpu[name] = time.process_time() - c0
        total = time.perf_counter() - t0
        return sink, report_from(sink, src.name), total

    baseline = None
    if args.baseline:
        # the baseline engine (benchmarks/baseline_solvers.py), on the same model and road, serial, no sink (what a drive
        # costs without the results file: the serial and parallel runs below write into memory, a small difference)
        from benchmarks.baseline_solvers import BaselineRos2
        from vehicle.engines.full import Drive
        from vehicle.scenario.schema import prepare

        prep = prepare(read_scenario_text(yaml.safe_dump(data), src.name, src.base_dir))
        model, settings = prep.model(), prep.settings()
        drive = Drive(model, prep.road(), settings, solver=BaselineRos2(settings.dt_s))
        t0 = time.perf_counter()
        res_b = drive.run()
        # per axle final temperature and load change as benchmarks/engine.py summarises its engines
        baseline = summarize(drive, res_b, 0.0, time.perf_counter() - t0)
    step = {"dt": args.dt} if args.dt else {}
    serial, rs, total_s = run(step, "serial")
    par, rp, total_p = run({**step, "time_parallel": args.segments, "time_parallel_lanes": 1}, "parallel")
    lanes = None
    if args.lanes != "0":
        lanes = run({**step, "time_parallel": args.segments,
                     "time_parallel_lanes": args.lanes if args.lanes == "auto" else int(args.lanes)}, "lanes")
    reference = None
    if args.reference_dt:
        # the tight reference: the same drive at a smaller step (second order: 1 ms is 16x tighter than 4 ms)
        ref_sink, rr, _ = run({"dt": args.reference_dt}, "reference")
        reference = {"T": np.array([a["T_end_C"] for a in rr["axles"]]),
                     "dN": np.array([a["dN_pct"] for a in rr["axles"]])}
    ss, sp = serial.summary_attrs(), par.summary_attrs()
    T_s = np.array([a["T_end_C"] for a in rs["axles"]])
    T_p = np.array([a["T_end_C"] for a in rp["axles"]])
    dN_s = np.array([a["dN_pct"] for a in rs["axles"]])
    dN_p = np.array([a["dN_pct"] for a in rp["axles"]])
    vals = par.summary_values()
    out = {"scenario": src.name, "distance_km": rs["distance_km"], "segments": args.segments,
           "serial_wall_s": float(ss["wall_s"]), "parallel_wall_s": float(sp["wall_s"]),
           "speedup": float(ss["wall_s"]) / float(sp["wall_s"]),
           "serial_total_s": total_s, "parallel_total_s": total_p,
           "serial_integration_s": float(ss["integration_s"]),
           "worker_cpu_s": float(sp.get("time_parallel_worker_cpu_s", np.nan)),
           "coarse_s": float(sp.get("time_parallel_coarse_s", np.nan)),
           "serial_cpu_s": cpu["serial"], "parallel_main_cpu_s": cpu["parallel"],
           "serial_drive_cpu_s": cpu.get("serial_drive", np.nan),
           "coarse_cpu_s": float(sp.get("time_parallel_coarse_cpu_s", np.nan)),
           "join_cpu_s": float(sp.get("time_parallel_join_cpu_s", np.nan)),
           "critical_cpu_s": float(sp.get("time_parallel_critical_cpu_s", np.nan)),
           "check_cpu_s": float(sp.get("time_parallel_check_cpu_s", np.nan)),
           "T_end_serial_C": T_s.tolist(), "dT_K": (T_p - T_s).tolist(), "ddN_pp": (dN_p - dN_s).tolist(),
           "coarse_mismatch_K": float(sp.get("time_parallel_coarse_mismatch_K", np.nan)),
           "estimated_error_K": np.asarray(vals.get("estimated_error_axle_temperature", [np.nan]), float).tolist(),
           "estimated_error_pp": np.asarray(vals.get("estimated_error_load_change", [np.nan]), float).tolist(),
           "energy_rel_diff": (rp["energy_dissipated_MJ"] - rs["energy_dissipated_MJ"]) / rs["energy_dissipated_MJ"]}
    if reference is not None:
        def against(T, dN):
            return {"max_temperature_error_K": float(np.max(np.abs(T - reference["T"]))),
                    "max_load_error_pp": float(np.max(np.abs(dN - reference["dN"])))}
        out["reference_dt"] = args.reference_dt
        out["serial_vs_reference"] = against(T_s, dN_s)
        out["parallel_vs_reference"] = against(T_p, dN_p)
        if baseline is not None:
            out["baseline_vs_reference"] = against(np.array(baseline["T_end_K"]) - 273.15, np.array(baseline["dN_pct"]))
    if baseline is not None:
        out.update(baseline_wall_s=baseline["wall_s"], baseline_vs_serial=baseline["wall_s"] / out["serial_wall_s"],
                   baseline_vs_parallel=baseline["wall_s"] / out["parallel_wall_s"])
    if lanes is not None:
        sl, rl = lanes[0].summary_attrs(), lanes[1]
        T_l = np.array([a["T_end_C"] for a in rl["axles"]])
        dN_l = np.array([a["dN_pct"] for a in rl["axles"]])
        vl = lanes[0].summary_values()
        out["lanes"] = {"segments": int(sl.get("time_parallel_segments", 0)),
                        "lanes": int(sl.get("time_parallel_lanes", 1)), "wall_s": float(sl["wall_s"]),
                        "speedup": float(ss["wall_s"]) / float(sl["wall_s"]), "total_s": lanes[2],
                        "worker_cpu_s": float(sl.get("time_parallel_worker_cpu_s", np.nan)),
                        "coarse_s": float(sl.get("time_parallel_coarse_s", np.nan)),
                        "join_s": float(sl.get("time_parallel_join_s", np.nan)),
                        "critical_cpu_s": float(sl.get("time_parallel_critical_cpu_s", np.nan)),
                        "check_cpu_s": float(sl.get("time_parallel_check_cpu_s", np.nan)),
                        "dT_K": (T_l - T_s).tolist(), "ddN_pp": (dN_l - dN_s).tolist(),
                        "estimated_error_K": np.asarray(vl.get("estimated_error_axle_temperature", [np.nan]),
                                                        float).tolist(),
                        "estimated_error_pp": np.asarray(vl.get("estimated_error_load_change", [np.nan]),
                                                         float).tolist(),
                        "energy_rel_diff": (rl["energy_dissipated_MJ"] - rs["energy_dissipated_MJ"])
                        / rs["energy_dissipated_MJ"]}
        if reference is not None:
            out["lanes"]["vs_reference"] = against(T_l, dN_l)
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    print(f"{src.name}: {out['distance_km']:.4g} km, time-parallel P = {args.segments}")
    print(f"  drive wall: serial {out['serial_wall_s']:.1f} s, time-parallel {out['parallel_wall_s']:.1f} s "
          f"-> {out['speedup']:.2f}x (with model build: {total_s:.1f} s vs {total_p:.1f} s)")
    if baseline is not None:
        print(f"  the engine of issue 11's filing, serial, same model: drive wall {out['baseline_wall_s']:.1f} s -> "
              f"{out['baseline_vs_serial']:.2f}x slower than the serial run, {out['baseline_vs_parallel']:.2f}x slower "
              f"than the time-parallel one")
    print(f"  CPU: serial run {out['serial_cpu_s']:.1f} s (build included); time-parallel: workers {out['worker_cpu_s']:.1f} s "
          f"in sum + this process {out['parallel_main_cpu_s']:.1f} s (build, coarse prediction "
          f"{out['coarse_s']:.1f} s wall, join and estimate)")
    print(f"  time-parallel critical path in CPU time (segment 0, or the coarse run {out['coarse_cpu_s']:.1f} s + the "
          f"slowest other segment; + the join {out['join_cpu_s']:.1f} s): {out['critical_cpu_s']:.1f} s, against the serial "
          f"drive's CPU {out['serial_drive_cpu_s']:.1f} s -> {out['serial_drive_cpu_s'] / out['critical_cpu_s']:.2f}x on P free cores")
    if reference is not None:
        parts = [f"{name} {out[key]['max_temperature_error_K']:.3f} K / {out[key]['max_load_error_pp']:.4f} pp"
                 for name, key in (("serial", "serial_vs_reference"), ("time-parallel", "parallel_vs_reference"),
                                   ("old engine", "baseline_vs_reference")) if key in out]
        print(f"  against the serial run at {args.reference_dt} (largest over the axles: final strut temperature, "
              f"load change): " + ", ".join(parts))
    print("  per axle  T_end serial [C]   dT [K]   ddN [pp]   estimate [K]   estimate [pp]")
    for i in range(len(T_s)):
        print(f"  {i + 1:8d}  {T_s[i]:16.3f}  {out['dT_K'][i]:+7.4f}  {out['ddN_pp'][i]:+8.4f}  "
              f"{out['estimated_error_K'][i] if i < len(out['estimated_error_K']) else np.nan:13.4f}  "
              f"{out['estimated_error_pp'][i] if i < len(out['estimated_error_pp']) else np.nan:14.4f}")
    print(f"  largest |dT| {np.max(np.abs(out['dT_K'])):.4f} K, |ddN| {np.max(np.abs(out['ddN_pp'])):.4f} pp; "
          f"coarse prediction mismatch at the segment start (no correction) {out['coarse_mismatch_K']:.3f} K; "
          f"dissipated energy {out['energy_rel_diff'] * 100:+.3f} %")
    if lanes is not None:
        L = out["lanes"]
        print(f"  side by side (drive wall time, against the serial run: largest per-axle |dT| and |ddN|, own estimate)")
        print(f"    {'serial, scalar engine':44s} {out['serial_wall_s']:7.1f} s  1.00x")
        print(f"    {f'time-parallel, {args.segments} segments on the scalar engine':44s} {out['parallel_wall_s']:7.1f} s "
              f"{out['speedup']:5.2f}x  {np.max(np.abs(out['dT_K'])):.4f} K  {np.max(np.abs(out['ddN_pp'])):.4f} pp  "
              f"(estimate {np.nanmax(out['estimated_error_K']):.4f} K, {np.nanmax(out['estimated_error_pp']):.4f} pp)")
        name = f"time-parallel, {L['segments']} segments, {L['lanes']} lanes x {args.segments}"
        print(f"    {name:44s} {L['wall_s']:7.1f} s {L['speedup']:5.2f}x  {np.max(np.abs(L['dT_K'])):.4f} K  "
              f"{np.max(np.abs(L['ddN_pp'])):.4f} pp  (estimate {np.nanmax(L['estimated_error_K']):.4f} K, "
              f"{np.nanmax(L['estimated_error_pp']):.4f} pp)")
        print(f"    lanes: workers' CPU {L['worker_cpu_s']:.1f} s (scalar segments {out['worker_cpu_s']:.1f} s) and "
              f"{L['check_cpu_s']:.1f} s in the join's error checks (scalar {out['check_cpu_s']:.1f} s), coarse "
              f"{L['coarse_s']:.1f} s, join {L['join_s']:.1f} s wall, critical path in CPU {L['critical_cpu_s']:.1f} s "
              f"(scalar segments {out['critical_cpu_s']:.1f} s); dissipated energy {L['energy_rel_diff'] * 100:+.3f} %")
        if "vs_reference" in L:
            print(f"    lanes against the run at {args.reference_dt}: {L['vs_reference']['max_temperature_error_K']:.3f} K / "
                  f"{L['vs_reference']['max_load_error_pp']:.4f} pp")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
