"""The production engine against the baseline engine kept for comparison, on the same model, in one run.

    python benchmarks/engine.py [--distance 10km] [--jacobian-every 1,5] [--no-reference] [--json]
    python benchmarks/engine.py --distance 106km          # the mileage drive (minutes; the 1 ms reference too)

The drive: the apc_8x8 on ISO class D (seed 0) at 20 km/h, 25 degC, output every 1 s, statistics every 1 km
(the mileage scenario's settings; --distance 106km is the mileage drive).

Engines, the ROS2 method at --dt (4 ms) on the same model, road and settings:
  baseline     benchmarks/baseline_solvers.py BaselineRos2: the simplest compiled engine, kept as the yardstick. The
               parameter values are baked into the code, with no common-subexpression elimination, the steps of a
               sample folded, the block outputs evaluated in CasADi's virtual machine.
  current      vehicle.numerics.solvers.Ros2(): the production engine (parameters as inputs, CSE, unrolled steps,
               compiled outputs).
  current_jK   benchmarks/baseline_solvers.py JacobianReuseRos2(dt, K) for each K > 1 of --jacobian-every: W and its
               LU made every K steps.
  reference    Ros2() at --reference-dt (1 ms): the step error is second order, 16x below the 4 ms one.

Per engine: the build (symbolic step, code generation, compilation; cold cache unless --warm-cache), the drive's
wall time (Drive.run: integration plus the per-block work in Python; the engines' drives run block by block in
turn, so that the machine's load weighs on all alike) and the integration time alone. Then the cost of one
step (us/step: the compiled block function on one block of inputs, repeated --repeats times interleaved over the
engines, minimum and median), and the accuracy against the reference: per axle (mean of left and right) the final
strut surface temperature [K] and the standing wheel-load change before -> after the drive [pp], largest error over
the axles. Ratios are baseline / engine. Timings on a shared machine are noisy: only ratios within one run mean
something (the drives run one after the other, the us/step figures interleaved).
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


def scenario_text(distance: str, dt: str) -> str:
    import yaml

    return yaml.safe_dump({"description": "engine benchmark", "vehicle": {"name": "apc_8x8"},
                           "road": {"iso_class": "D", "seed": 0}, "speed": "20 km/h", "distance": distance,
                           "ambient_temperature": "25 degC", "initial_temperatures": "25 degC",
                           "solver": {"dt": dt}, "output": {"interval": "1 s", "stats_interval": "1 km"}})


def build_drive(prep, model, road, solver):
    from vehicle.engines.full import Drive

    t0 = time.perf_counter()
    drive = Drive(model, road, prep.settings(), solver=solver)
    return drive, time.perf_counter() - t0


def run_lockstep(drives: dict) -> dict:
    """Run the drives block by block in turn (one thread each, one running at a time, handing over after every
    block through the drive's progress callback), so that a change of the machine's load in the minutes a long
    drive takes weighs on every engine alike. Returns name -> (DriveResult, wall seconds of its own turns)."""
    import threading

    names = list(drives)
    cond = threading.Condition()
    state = {"turn": names[0]}
    done, spent, started, results = set(), {n: 0.0 for n in names}, {}, {}

    def hand_over(n):
        i = names.index(n)
        for k in range(1, len(names) + 1):
            if names[(i + k) % len(names)] not in done:
                state["turn"] = names[(i + k) % len(names)]
                break
        cond.notify_all()

    def worker(n):
        def progress(*_):
            with cond:
                spent[n] += time.perf_counter() - started[n]
                hand_over(n)
                cond.wait_for(lambda: state["turn"] == n)
                started[n] = time.perf_counter()

        with cond:
            cond.wait_for(lambda: state["turn"] == n)
            started[n] = time.perf_counter()
        try:
            results[n] = drives[n].run(progress=progress)
        finally:
            with cond:
                spent[n] += time.perf_counter() - started[n]
                done.add(n)
                hand_over(n)

    threads = [threading.Thread(target=worker, args=(n,)) for n in names]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {n: (results[n], spent[n]) for n in names}


def summarize(drive, res, build: float, wall: float) -> dict:
    model, solver = drive.model, drive.solver
    before = drive.initial_equilibrium()
    ax = np.array([model.params.station_axle(i) for i in range(model.n)])

    def axle_mean(v):
        v = np.asarray(v, float)
        return np.array([v[ax == k].mean() for k in range(model.params.n_axles)])

    N0, N1 = axle_mean(before.wheel_loads_N), axle_mean(res.after.wheel_loads_N)
    steps = res.state.t_s / solver.dt
    out = {"build_s": build, "wall_s": wall, "integration_s": res.integration_s, "steps": steps,
           "drive_us_per_step": res.integration_s / steps * 1e6,
           "T_end_K": axle_mean(res.state.x[drive.T_index]).tolist(),
           "dN_pct": (100.0 * (N1 - N0) / N0).tolist()}
    if res.solver_error:
        out["error_estimate"] = res.solver_error.get("solver_error_estimate")
    return out


def step_cost(drives: dict, repeats: int) -> dict:
    """us per step of each engine's compiled block function on the same block of inputs, interleaved."""
    any_drive = next(iter(drives.values()))
    st = any_drive.initial_state()
    t_cols = 60.0 + any_drive.settings.dt_s * np.arange(any_drive.K * any_drive.M + 1)
    U = any_drive.inputs(t_cols)
    times = {k: [] for k in drives}
    for _ in range(repeats):
        for k, d in drives.items():
            d.solver.set_state(st.solver_memory)
            t0 = time.perf_counter()
            d.solver.advance(st.x, U, d.p)
            times[k].append((time.perf_counter() - t0) / (d.K * d.M) * 1e6)
    return {k: {"us_per_step_min": float(np.min(v)), "us_per_step_median": float(np.median(v))}
            for k, v in times.items()}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", default="10km")
    ap.add_argument("--dt", default="4ms")
    ap.add_argument("--reference-dt", default="1ms")
    ap.add_argument("--jacobian-every", default="1,5",
                    help="comma-separated steps between two W of the current engine (1: exact W at every step)")
    ap.add_argument("--no-reference", action="store_true")
    ap.add_argument("--repeats", type=int, default=7, help="interleaved repetitions of the us/step measurement")
    ap.add_argument("--warm-cache", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    if not args.warm_cache:
        os.environ["HPSIM_CACHE"] = tempfile.mkdtemp(prefix="hpsim_bench_")
    from benchmarks.baseline_solvers import BaselineRos2, JacobianReuseRos2
    from hpsim.units import parse_quantity
    from vehicle.numerics.solvers import Ros2
    from vehicle.scenario.schema import prepare, read_scenario_text

    dt = parse_quantity(args.dt, "s", where="--dt")
    t0 = time.perf_counter()
    prep = prepare(read_scenario_text(scenario_text(args.distance, args.dt), "engine benchmark", "."))
    model, road = prep.model(), prep.road()
    setup_s = time.perf_counter() - t0
    engines = {"baseline": BaselineRos2(dt)}
    for k in (int(v) for v in args.jacobian_every.split(",")):
        engines["current" if k == 1 else f"current_j{k}"] = Ros2(dt) if k == 1 else JacobianReuseRos2(dt, k)
    out = {"distance_km": prep.scenario.distance / 1e3, "dt_ms": dt * 1e3, "setup_s": setup_s, "engines": {}}
    drives, builds = {}, {}
    for name, solver in engines.items():
        drives[name], builds[name] = build_drive(prep, model, road, solver)
    for name, (res, wall) in run_lockstep(drives).items():
        out["engines"][name] = summarize(drives[name], res, builds[name], wall)
    for name, cost in step_cost(drives, args.repeats).items():
        out["engines"][name].update(cost)
    if not args.no_reference:
        ref_dt = parse_quantity(args.reference_dt, "s", where="--reference-dt")
        ref_drive, ref_build = build_drive(prep, model, road, Ros2(ref_dt))
        ref_res = ref_drive.run()
        out["reference"] = summarize(ref_drive, ref_res, ref_build, ref_res.wall_s)
        out["reference"]["solver"] = f"ROS2 at {ref_dt * 1e3:g} ms"
    base = out["engines"]["baseline"]
    for name, r in out["engines"].items():
        r["speedup_wall"] = base["wall_s"] / r["wall_s"]
        r["speedup_build_plus_wall"] = (base["build_s"] + base["wall_s"]) / (r["build_s"] + r["wall_s"])
        r["speedup_us_per_step"] = base["us_per_step_min"] / r["us_per_step_min"]
        if "reference" in out:
            ref = out["reference"]
            r["max_temperature_error_K"] = float(np.max(np.abs(np.subtract(r["T_end_K"], ref["T_end_K"]))))
            r["max_load_error_pp"] = float(np.max(np.abs(np.subtract(r["dN_pct"], ref["dN_pct"]))))
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        report(out)


def report(out: dict) -> None:
    """The table of a run (also from its --json output: `report(json.load(...))`)."""
    setup_s = out["setup_s"]
    print(f"{out['distance_km']:.6g} km at {out['dt_ms']:g} ms, apc_8x8 ISO D 20 km/h; scenario/model/road set-up "
          f"{setup_s:.1f} s (shared); ratios = baseline / engine, one process")
    print(f"  {'engine':12s} {'build s':>8s} {'wall s':>8s} {'integ s':>8s} {'us/step':>8s} {'(median)':>8s} "
          f"{'x wall':>7s} {'x b+w':>7s} {'x step':>7s} {'dT K':>7s} {'dN pp':>7s}")
    for name, r in out["engines"].items():
        acc = (f" {r['max_temperature_error_K']:7.3f} {r['max_load_error_pp']:7.4f}"
               if "max_temperature_error_K" in r else "")
        print(f"  {name:12s} {r['build_s']:8.2f} {r['wall_s']:8.2f} {r['integration_s']:8.2f} "
              f"{r['us_per_step_min']:8.2f} {r['us_per_step_median']:8.2f} {r['speedup_wall']:7.2f} "
              f"{r['speedup_build_plus_wall']:7.2f} {r['speedup_us_per_step']:7.2f}{acc}")
    if "reference" in out:
        r = out["reference"]
        print(f"  reference    {r['build_s']:8.2f} {r['wall_s']:8.2f} {r['integration_s']:8.2f}   ({r['solver']}; "
              f"T_end {np.round(r['T_end_K'], 3).tolist()} K, dN {np.round(r['dN_pct'], 4).tolist()} %)")


if __name__ == "__main__":
    main()
