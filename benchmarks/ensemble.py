"""The ensemble engine (vector lanes across cases) against the scalar engine, side by side in one run.

    python benchmarks/ensemble.py [--distance 2km] [--lanes 4] [--isa avx2] [--cases mileage] [--no-callgrind] [--json]

The drive: the mileage scenario's settings (apc_8x8, ISO class D, 4 ms step, output every 1 s, statistics every
1 km) over --distance, in `lanes` cases that differ in initial temperature, road seed and (--cases mixed, the
default) speed, 18-24 km/h; --cases mileage: all at the mileage test's 20 km/h, as the cases of a study of the
mileage test are. With mixed speeds a lane whose drive ends first is masked until the slowest one ends (it costs
as much as a used lane): the ensemble's figures then include that waste, as a study's group of unlike drives does.

Three engines are compared. `libm_block` is the scalar engine without vehicle.numerics.vector_math: CasADi's C
calling the C library's exp/log/pow/tanh. `Ros2` is the production scalar engine (each case on its own, its calls
batched into vector calls). The ensemble (`vehicle.engines.ensemble`) runs the cases in lockstep through
`vehicle.numerics.lanes`. Printed for each:

  instructions per lane-step   callgrind's count of the block function alone on one block of 250 steps (the
                               scalar engine's block for one case, the lanes' block for all lanes, divided by the
                               lanes): independent of the machine's load (valgrind runs AVX2, not AVX-512);
  us per lane-step             CPU time of the same block call, repeated and interleaved (minimum of --repeats);
  drive CPU s / wall s         the drives themselves (run_case into HDF5 files: set-up, integration, outputs,
                               statistics, files), the scalar cases one after the other, then the ensemble;
                               CPU time of this process (all threads), wall time;
  drives per hour              study throughput on this machine's 2 workers, from the drives' CPU time per case
                               for the 106 km mileage drive: a fixed part per case plus a part per km, fitted
                               to the drives over --distance and over a quarter of it;
  largest difference           of every time series and statistics row of each lane's file against the scalar
                               run of the same case (relative; 0 = bit for bit).
The machine is shared: wall times are noisy, the instruction counts are not; ratios measured in one run only.
"""
from __future__ import annotations

import argparse
import ctypes
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
MILEAGE_KM = 106.0


def scenario_text(i: int, distance: str, cases: str = "mixed") -> str:
    import yaml

    speed = 18 + 2 * (i % 4) if cases == "mixed" else 20
    return yaml.safe_dump({"description": f"ensemble benchmark case {i}", "vehicle": {"name": "apc_8x8"},
                           "road": {"iso_class": "D", "seed": i}, "speed": f"{speed} km/h",
                           "distance": distance, "ambient_temperature": "25 degC",
                           "initial_temperatures": f"{25 + 3 * i} degC", "solver": {"dt": "4 ms"},
                           "output": {"interval": "1 s", "stats_interval": "1 km"}})


def block_inputs(lanes: int):
    """One block (250 steps x 10 samples) of inputs for `lanes` cases: (model, scalar Ros2 bound, z0, U, P) with
    z0 (nz, lanes), U (nu, n+1, lanes), P (np, lanes)."""
    from terrain import RoadSpec, build_road
    from vehicle.numerics.solvers import Ros2
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle
    from vehicle.engines.full import Drive
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile

    model = VehicleModel(load_vehicle("apc_8x8"))
    road = build_road(RoadSpec(iso_class="D", length=600.0, seed=0))
    z0, U, P, drive = [], [], [], None
    for i in range(lanes):
        s = DriveSettings(distance_m=500.0, speed=SpeedProfile.constant((18 + 2 * (i % 4)) / 3.6),
                          initial_temperatures_K=298.15 + 3 * i, error_check_every=0)
        drive = Drive(model, road, s, solver=Ros2(0.004))
        st = drive.initial_state()
        z0.append(np.concatenate([st.x, drive.solver.memory]))
        U.append(drive.inputs(0.004 * np.arange(drive.K * drive.M + 1)))
        P.append(drive.p)
    return model, drive.solver, np.stack(z0, 1), np.stack(U, 2), np.stack(P, 1)


def libm_block(model, solver):
    """The scalar block function without vehicle.numerics.vector_math: (function, library).

    CasADi's C calls the C library's exp, log, pow and tanh; the compiler flags are the production engine's."""
    import casadi as ca

    from vehicle.numerics.codegen import casadi_c, compile_c

    graph = solver.block_function(model, solver.K, solver.M)
    code = casadi_c([graph], f"{graph.name()}.c")
    lib, error = compile_c(code, f"{graph.name()}_libm")
    if lib is None:
        raise RuntimeError(error)
    return ca.external(graph.name(), str(lib)), str(lib)


def per_step(model, solver, z0, U, P, lanes: int, isa: str, repeats: int) -> dict:
    """CPU time per lane-step of the scalar block (one case per call) and the lanes' block (all lanes per call),
    interleaved; and the largest difference of the states after one block."""
    from vehicle.engines.ensemble import lane_stepper

    stepper = lane_stepper(model, solver.dt, lanes, isa)
    K, M = solver.K, solver.M
    libm_fn, libm_lib = libm_block(model, solver)
    Ul = np.ascontiguousarray(U.transpose(1, 0, 2))
    best = {"scalar": np.inf, "lanes": np.inf, "libm": np.inf}
    for _ in range(repeats):
        t0 = time.process_time()
        for i in range(lanes):
            libm_fn(z0[:, i], U[:, :, i], P[:, i])
        best["libm"] = min(best["libm"], (time.process_time() - t0) / (lanes * K * M))
        t0 = time.process_time()
        Zs = [np.asarray(solver.fn(z0[:, i], U[:, :, i], P[:, i])) for i in range(lanes)]
        best["scalar"] = min(best["scalar"], (time.process_time() - t0) / (lanes * K * M))
        t0 = time.process_time()
        Zl = stepper.advance(z0, Ul, P, K, M)
        best["lanes"] = min(best["lanes"], (time.process_time() - t0) / (lanes * K * M))
    diff = max(float(np.max(np.abs(Zl[:, :, i].T - Zs[i]))) for i in range(lanes))
    return {"scalar_us": best["scalar"] * 1e6, "lanes_us": best["lanes"] * 1e6, "libm_us": best["libm"] * 1e6,
            "libm_library": libm_lib, "libm_name": libm_fn.name(), "block_max_abs_difference": diff,
            "library": str(stepper.library), "scalar_name": solver.fn.name(), "lanes_name": stepper.name,
            "K": K, "M": M, "vector_width": stepper.vector_width}


def callgrind_child(argv) -> None:
    """(Under valgrind.) Load one library and call its block function once on the saved inputs."""
    kind, lib, name, data = argv
    d = np.load(data)
    if kind == "scalar":
        import casadi as ca

        fn = ca.external(name, lib)
        fn(d["z0"][:, 0], d["U"][:, :, 0], d["P"][:, 0])
    else:
        f = getattr(ctypes.CDLL(lib), name)
        z0, U, P = (np.ascontiguousarray(d[k]) for k in ("z0", "Ul", "P"))
        Z = np.empty((int(d["M"]), z0.shape[0], z0.shape[1]))
        f(*(a.ctypes.data_as(ctypes.c_void_p) for a in (z0, U, P, Z)), ctypes.c_int(int(d["M"])),
          ctypes.c_int(int(d["K"])))


def callgrind(kind: str, lib: str, name: str, data: Path) -> int | None:
    """Instructions executed inside `name` and what it calls (its inclusive count) in one block call, by
    callgrind (everything collected, the function's line read from callgrind_annotate); None without valgrind."""
    out = data.with_suffix(f".{kind}.callgrind")
    cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", sys.executable, __file__,
           "--callgrind-child", kind, lib, name, str(data)]
    try:
        subprocess.run(cmd, check=True, capture_output=True, timeout=1800)
        text = subprocess.run(["callgrind_annotate", "--inclusive=yes", "--threshold=100", str(out)], check=True,
                              capture_output=True, text=True, timeout=600).stdout
    except (OSError, subprocess.SubprocessError):
        return None
    # the lanes' exported block function does not show under its name (its frames are attributed to the step it
    # calls): its count is that of the foreign-function call into it (ctypes' own instructions: a few hundred)
    target = name if kind == "scalar" else "ffi_call"
    for line in text.splitlines():
        parts = line.split()      # "56,981,490 ( 9.89%)  ???:ffi_call [...]": the percentage may hold a space
        if len(parts) >= 3 and any(p.endswith(f":{target}") for p in parts[1:4]):
            return int(parts[0].replace(",", ""))
    return None


def libm_solver_class():
    """`Ros2` whose block function is `libm_block`'s (the engine before vehicle.numerics.vector_math: a call of the
    C library per exp/log/pow/tanh); its error probes and outputs are today's."""
    from vehicle.numerics.solvers import Ros2

    class LibmRos2(Ros2):
        def block_graph(self, model, steps_per_sample, samples_per_call):
            return None

        def bind(self, model, steps_per_sample, samples_per_call):
            self.K, self.M = int(steps_per_sample), int(samples_per_call)
            self.nx, self.nmem = model.nx, model.n_memory
            self.fn, _ = libm_block(model, self)
            self.memory = model.initial_memory()
            return self

    return LibmRos2


def drives(distance: str, lanes: int, isa: str, folder: Path, cases: str = "mixed") -> dict:
    """The cases on the engine before vehicle.numerics.vector_math (C library calls), on today's scalar engine, one
    after the other, then in one ensemble: CPU and wall seconds, per-case results, the largest relative difference
    of the files (ensemble against today's scalar engine)."""
    from vehicle.engines.ensemble import run_lockstep
    from vehicle.studies.sweep import run_case

    base = str(Path(__file__).resolve().parents[1] / "scenarios")
    items = {kind: [(f"{kind}{i}", (scenario_text(i, distance, cases), f"case {i}", base, str(folder / f"{kind}{i}.h5")))
                    for i in range(lanes)] for kind in ("s", "e", "m")}
    out = {}
    libm = libm_solver_class()
    c0, w0 = time.process_time(), time.perf_counter()
    res = [run_case(*args, make_solver=libm) for _, args in items["m"]]
    out["libm"] = {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0,
                   "status": [r["status"] for r in res]}
    c0, w0 = time.process_time(), time.perf_counter()
    res = [run_case(*args) for _, args in items["s"]]
    out["scalar"] = {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0,
                     "status": [r["status"] for r in res]}
    c0, w0 = time.process_time(), time.perf_counter()
    r = run_lockstep(run_case, items["e"], lanes, isa=isa)
    out["ensemble"] = {"cpu_s": time.process_time() - c0, "wall_s": time.perf_counter() - w0,
                       "integration_s": r["integration_s"], "status": [v["status"] for v in r["cases"].values()]}
    out["largest_relative_difference"] = max(_file_difference(folder / f"s{i}.h5", folder / f"e{i}.h5")
                                             for i in range(lanes))
    return out


def _file_difference(a: Path, b: Path) -> float:
    import h5py

    worst = 0.0
    with h5py.File(a, "r") as fa, h5py.File(b, "r") as fb:
        def visit(name, obj):
            nonlocal worst
            if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and name.split("/")[0] in ("timeseries", "stats"):
                x, y = obj[()], fb[name][()]
                if x.shape != y.shape:
                    worst = np.inf
                    return
                differ = ~((x == y) | (np.isnan(x) & np.isnan(y)))
                if np.any(differ):
                    worst = max(worst, float(np.max(np.abs(x - y)[differ] / np.maximum(np.abs(x)[differ], 1e-300))))
        fa.visititems(visit)
    return worst


def main() -> None:
    if len(sys.argv) > 1 and sys.argv[1] == "--callgrind-child":
        callgrind_child(sys.argv[2:])
        return
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--distance", default="2 km")
    ap.add_argument("--lanes", type=int, default=None, help="default: one vector of --isa (8 with AVX-512, 4 with AVX2)")
    ap.add_argument("--isa", default=None, help="sse2, avx2 or avx512 (default: vehicle.numerics.lanes.default_isa)")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2, help="workers of the throughput figure (default 2)")
    ap.add_argument("--cases", choices=("mixed", "mileage"), default="mixed",
                    help="mixed: speeds 18-24 km/h (default); mileage: all at 20 km/h, as a mileage study's cases")
    ap.add_argument("--no-callgrind", action="store_true")
    ap.add_argument("--no-drives", action="store_true")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    from hpsim.units import parse_quantity
    from vehicle.numerics.lanes import default_isa, default_lanes

    isa = args.isa or default_isa()
    L = args.lanes or default_lanes(isa)
    model, solver, z0, U, P = block_inputs(L)
    res = {"lanes": L, "isa": isa, "per_step": per_step(model, solver, z0, U, P, L, isa, args.repeats)}
    ps = res["per_step"]
    with tempfile.TemporaryDirectory(prefix="hpsim-ens-bench-") as tmp:
        tmp = Path(tmp)
        if not args.no_callgrind:
            data = tmp / "block.npz"
            np.savez(data, z0=z0, U=U, Ul=np.ascontiguousarray(U.transpose(1, 0, 2)), P=P, K=ps["K"], M=ps["M"])
            n_steps = ps["K"] * ps["M"]
            ir_m = callgrind("scalar", ps["libm_library"], ps["libm_name"], data)
            # today's scalar engine: the one-lane library with batched calls (AVX2 under valgrind: 4 per call)
            from vehicle.numerics.lanes import LaneStepper

            one = LaneStepper(solver, model, 1, batched=True, isa="avx2" if isa == "avx512" else isa)
            data1 = tmp / "block1.npz"
            np.savez(data1, z0=z0[:, :1], U=U[:, :, :1], Ul=np.ascontiguousarray(U[:, :, :1].transpose(1, 0, 2)),
                     P=P[:, :1], K=ps["K"], M=ps["M"])
            ir_s = callgrind("lanes", str(one.library), one.name, data1)
            # valgrind cannot run AVX-512: the counts of the AVX2 library of 4 lanes then
            cg_lanes, lib, lname = L, ps["library"], ps["lanes_name"]
            if isa == "avx512":
                from vehicle.engines.ensemble import lane_stepper

                cg_lanes = 4
                st4 = lane_stepper(model, solver.dt, cg_lanes, "avx2")
                lib, lname = str(st4.library), st4.name
                np.savez(data, z0=z0[:, :4], U=U[:, :, :4], Ul=np.ascontiguousarray(U[:, :, :4].transpose(1, 0, 2)),
                         P=P[:, :4], K=ps["K"], M=ps["M"])
            ir_l = callgrind("lanes", lib, lname, data)
            res["instructions_per_lane_step"] = {"scalar": ir_s / n_steps if ir_s else None,
                                                 "libm": ir_m / n_steps if ir_m else None,
                                                 "lanes": ir_l / (n_steps * cg_lanes) if ir_l else None,
                                                 "lanes_isa": "avx2" if isa == "avx512" else isa, "lanes_n": cg_lanes}
        if not args.no_drives:
            km = parse_quantity(args.distance, "m", where="--distance") / 1e3
            (tmp / "short").mkdir()
            res["drives"] = drives(args.distance, L, isa, tmp, args.cases)
            res["drives_short"] = drives(f"{km / 4} km", L, isa, tmp / "short", args.cases)
    if "drives" in res:
        # per case: a fixed part (set-up, model, equilibria, files) and a part per km, from the two distances
        d, d4 = res["drives"], res["drives_short"]
        res["drives_per_hour"], res["per_case_106km_cpu_s"] = {}, {}
        for k in ("libm", "scalar", "ensemble"):
            per_km = (d[k]["cpu_s"] - d4[k]["cpu_s"]) / L / (0.75 * km)
            fixed = max(d[k]["cpu_s"] / L - per_km * km, 0.0)
            res["per_case_106km_cpu_s"][k] = {"fixed_s": fixed, "per_km_s": per_km,
                                              "total_s": fixed + per_km * MILEAGE_KM}
            res["drives_per_hour"][k] = args.workers * 3600.0 / (fixed + per_km * MILEAGE_KM)
    if args.json:
        print(json.dumps(res, indent=1, default=float))
        return
    print(f"ensemble of {L} lanes ({isa}, vector width {ps['vector_width']}) against the scalar engine, one run")
    print(f"  us per lane-step (CPU, min of {args.repeats}):  scalar with the C library's exp/log/pow/tanh "
          f"{ps['libm_us']:.2f}  scalar {ps['scalar_us']:.2f}  lanes {ps['lanes_us']:.2f}  ratios: lanes "
          f"{ps['scalar_us'] / ps['lanes_us']:.2f}x the scalar engine, {ps['libm_us'] / ps['lanes_us']:.2f}x the "
          f"C-library engine")
    ir = res.get("instructions_per_lane_step")
    if ir and ir["scalar"] and ir["lanes"]:
        libm = f"scalar with the C library {ir['libm']:.0f}  " if ir.get("libm") else ""
        print(f"  instructions per lane-step (callgrind, {ir['lanes_isa']}; lanes: {ir['lanes_n']}):  {libm}scalar "
              f"(batched calls) {ir['scalar']:.0f}  lanes {ir['lanes']:.0f}  ratio {ir['scalar'] / ir['lanes']:.2f}x")
    print(f"  one block, largest state difference lanes vs scalar: {ps['block_max_abs_difference']:.3g}")
    if "drives" in res:
        d = res["drives"]
        print(f"  {L} drives of {args.distance} ({args.cases} cases): scalar CPU {d['scalar']['cpu_s']:.1f} s (wall {d['scalar']['wall_s']:.1f})"
              f", ensemble CPU {d['ensemble']['cpu_s']:.1f} s (wall {d['ensemble']['wall_s']:.1f}, integration "
              f"{d['ensemble']['integration_s']:.1f}); ratio {d['scalar']['cpu_s'] / d['ensemble']['cpu_s']:.2f}x")
        dph, pc = res["drives_per_hour"], res["per_case_106km_cpu_s"]
        for k in ("libm", "scalar", "ensemble"):
            print(f"  {k}: per case {pc[k]['fixed_s']:.2f} s fixed + {pc[k]['per_km_s']:.3f} s per km (CPU; from "
                  f"{args.distance} and a quarter of it) -> {pc[k]['total_s']:.1f} s per 106 km drive")
        print(f"  106 km drives per hour on {args.workers} workers (CPU time, {args.workers} busy workers): C-library "
              f"engine (before issue 26's math) {dph['libm']:.0f}, scalar {dph['scalar']:.0f} "
              f"({dph['scalar'] / dph['libm']:.2f}x), ensemble {dph['ensemble']:.0f} "
              f"({dph['ensemble'] / dph['libm']:.2f}x the C-library engine, {dph['ensemble'] / dph['scalar']:.2f}x "
              f"the scalar)")
        print(f"  largest relative difference of the files (every series and statistics row): "
              f"{d['largest_relative_difference']:.3g}  status {d['scalar']['status']} {d['ensemble']['status']}")


if __name__ == "__main__":
    main()
