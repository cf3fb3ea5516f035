"""Lanes across the struts of one drive (docs/engines.md): the split step against the whole step, side by side.

    python benchmarks/strut_lanes.py [--steps 20000] [--repeats 5] [--vehicle apc_8x8]

The engine's step is split around a strut kernel (`vehicle.numerics.split_step`, `vehicle.physics.strut_kernel`):
the scalar engine computes the kernel of a case's stations in one vector, the ensemble station after station over
its lanes of cases. `Ros2(strut_lanes=False)` builds the whole step as before (its exp/log/pow/tanh calls batched,
`lanes.emit_batched`). Printed, in one run:
  - SX operations per step (without reading inputs, writing outputs and loading constants): the whole step, the
    kernels x stations and the scalar rest (pieces A, B, C);
  - time per step of the scalar engine's block function (one lane, batched calls) and per lane-step of the
    ensemble's (`lanes.default_lanes()` lanes), whole against split: the minimum of --repeats interleaved runs of
    --steps steps of the mileage scenario's first seconds (ISO class D, 20 km/h);
  - one step from each of 200 states of the whole step's trajectory: the largest relative difference of the split
    step's result (rounding: the same equations grouped otherwise);
  - whether the ensemble's lanes give the scalar engine's bits (split).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from vehicle.numerics.lanes import LaneStepper, default_isa, default_lanes  # noqa: E402
from vehicle.numerics.solvers import Ros2                                    # noqa: E402

DT = 0.004


def drive_inputs(model, steps: int):
    """(z0, U (steps + 1, nu), p) of the mileage scenario's first steps (ISO class D, 20 km/h)."""
    from terrain import RoadSpec, build_road
    from vehicle.engines.full import Drive
    from vehicle.scenario.settings import DriveSettings
    from vehicle.scenario.speed import SpeedProfile

    length = 20 / 3.6 * DT * steps + 100.0
    road = build_road(RoadSpec(iso_class="D", length=length, seed=0))
    s = DriveSettings(distance_m=length - 50.0, speed=SpeedProfile.constant(20 / 3.6), error_check_every=0)
    drive = Drive(model, road, s, solver=Ros2(DT))
    st = drive.initial_state()
    U = np.asarray(drive.inputs(DT * np.arange(steps + 1)), float)
    U = U.T if U.shape[0] == model.nu else U
    return np.concatenate([st.x, drive.solver.memory]), np.ascontiguousarray(U), np.asarray(drive.p, float)


def arith(fn: ca.Function) -> int:
    """Operations of an SX function other than reading inputs, writing outputs and loading constants."""
    skip = {ca.OP_INPUT, ca.OP_OUTPUT, ca.OP_CONST}
    return sum(1 for k in range(fn.n_instructions()) if fn.instruction_id(k) not in skip)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=20000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--vehicle", default="apc_8x8")
    a = ap.parse_args()
    from vehicle.physics.model import VehicleModel
    from vehicle.physics.params import load_vehicle

    t0 = time.perf_counter()
    model = VehicleModel(load_vehicle(a.vehicle))
    split = Ros2(DT).split_step_functions(model)
    if split is None:
        sys.exit(f"{a.vehicle}: no strut kernel for all stations (the whole step runs)")
    whole, _ = Ros2(DT, strut_lanes=False).step_functions(model)
    n = model.n
    kern = [arith(k) for k in split.kernels]
    rest = [arith(f) for f in split.pieces]
    print(f"{a.vehicle}, {n} stations (kernel vectors of {split.padded}); lanes {default_isa()} x {default_lanes()}")
    print("SX operations per step (no inputs, outputs, constants):")
    print(f"  whole step                               {arith(whole):7d}")
    print(f"  strut kernels {n} x ({kern[0]} + {kern[1]})             {n * sum(kern):7d}")
    print(f"  rest: A {rest[0]} + B {rest[1]} + C {rest[2]}          {sum(rest):7d}   "
          f"(split total {n * sum(kern) + sum(rest)}: {(n * sum(kern) + sum(rest)) / arith(whole) - 1:+.0%})")

    z0, U, p = drive_inputs(model, a.steps)
    L = default_lanes()
    steppers = {(kind, lanes): LaneStepper(Ros2(DT, strut_lanes=kind == "split"), model, lanes, batched=lanes == 1)
                for lanes in (1, L) for kind in ("whole", "split")}
    best = {}
    K = 100
    M = a.steps // K
    for _ in range(a.repeats):
        for (kind, lanes), st in steppers.items():
            args = (np.repeat(z0[:, None], lanes, 1), np.ascontiguousarray(np.repeat(U[:K * M + 1, :, None], lanes, 2)),
                    np.repeat(p[:, None], lanes, 1))
            t = time.perf_counter()
            st.advance(*args, K, M)
            best[kind, lanes] = min(best.get((kind, lanes), np.inf), (time.perf_counter() - t) / (K * M * lanes))
    print(f"time per lane-step, us (minimum of {a.repeats} interleaved runs of {K * M} steps):")
    for lanes in (1, L):
        w, s = best["whole", lanes] * 1e6, best["split", lanes] * 1e6
        label = "scalar engine (1 lane, batched calls)" if lanes == 1 else f"ensemble ({lanes} lanes)"
        print(f"  {label:40s} whole {w:6.3f}  split {s:6.3f}   whole / split {w / s:.2f}x")

    # one step from each state of the whole step's trajectory: rounding
    one, ref = steppers["split", 1], steppers["whole", 1]
    Z = ref.advance(z0[:, None], np.ascontiguousarray(U[:201, :, None]), p[:, None], 1, 200)[:, :, 0]
    Z = np.vstack([z0, Z])
    pw_s, pw_w = one.parametric(p[:, None]), ref.parametric(p[:, None])
    scale = np.maximum(np.max(np.abs(Z), axis=0), 1e-300)
    worst = 0.0
    for k in range(200):
        x, y = (st.step(Z[k][:, None], U[k][:, None], U[k + 1][:, None], pw)[:, 0]
                for st, pw in ((one, pw_s), (ref, pw_w)))
        worst = max(worst, float(np.max(np.abs(x - y) / np.maximum(np.abs(y), 1e-6 * scale))))
    lanes_out = steppers["split", L].advance(np.repeat(z0[:, None], L, 1),
                                             np.ascontiguousarray(np.repeat(U[:1001, :, None], L, 2)),
                                             np.repeat(p[:, None], L, 1), 100, 10)
    single = one.advance(z0[:, None], np.ascontiguousarray(U[:1001, :, None]), p[:, None], 100, 10)[:, :, 0]
    equal = all(np.array_equal(lanes_out[:, :, lane], single) for lane in range(L))
    print(f"one step from 200 states, split against whole: largest relative difference {worst:.1e} (rounding)")
    print(f"ensemble lanes against the scalar engine, 1000 steps: {'bit for bit' if equal else 'DIFFERENT'}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
