"""The baseline a careful engineer writes first: the same vehicle model under SUNDIALS CVODES (variable-order
BDF, Newton with the exact Jacobian by CasADi AD, right-hand side and Jacobian compiled to C by CasADi's
JIT), against the production engine (compiled fixed-step ROS2, 4 ms), both checked against a tight
reference (ROS2 at 1 ms), in one run.

    python benchmarks/cvodes_baseline.py [--distance 200m] [--rtol 3e-3] [--atol 3e-5] [--json]

Printed: each solver's integration time, their ratio and the errors against the reference; the JIT
compilation of the right-hand side and its Jacobian is timed apart (not in the ratio). The figures of the
default rtol 3e-3 and of 1e-2, between which equal accuracy lies, are in docs/validation.md.

The explicit-ODE form: the valve pressure drops are eliminated inside the right-hand side by the
struts' bracketed Newton solve from a cold start (`valve_pressure_drop`, --newton iterations), because
CVODES carries no memory between right-hand-side calls (the production engine warm-starts from the
previous step instead). The road, speed and ambient inputs are those of the drive (`Drive.inputs` at
every 4 ms step), interpolated linearly in time inside CVODES as vehicle.numerics.solvers.Idas does.
The drive: apc_8x8, ISO class D seed 0, 20 km/h, struts at 25 degC, 10 s of driving per CVODES call
with output every second. Compared: the final strut temperatures [K] the hull heave [mm] and the energy dissipated
per strut [%] at the end, and the integration wall time.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def make_drive(distance_m: float, dt_s: float):
    import yaml

    from vehicle.scenario.schema import prepare, read_scenario_text

    data = {"vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 0}, "speed": "20 km/h",
            "distance": f"{distance_m} m", "ambient_temperature": "25 degC", "solver": {"dt": f"{dt_s} s"},
            "output": {"interval": "1 s", "stats_interval": "1 km"}}
    return prepare(read_scenario_text(yaml.safe_dump(data), "baseline", "."))


def ros2(distance_m: float, dt_s: float):
    prep = make_drive(distance_m, dt_s)
    from vehicle.engines.build import build_engine

    model, drive = build_engine(prep)
    t0 = time.perf_counter()
    res = drive.run()
    return drive, res, time.perf_counter() - t0


def cvodes_integrator(model, drive, rtol, atol, newton: int, jit: bool):
    """CVODES over one block of K*M steps of drive.settings.dt_s, output at the M sample instants."""
    K, M, dt = drive.K, drive.M, drive.settings.dt_s
    n_in = K * M + 1
    grid = np.linspace(0.0, dt * K * M, n_in)
    x, _, _, p = model.symbols
    t = ca.SX.sym("t")
    data = ca.SX.sym("U", model.nu * n_in)
    u = ca.interpolant("U", "linear", [grid], model.nu)(t, data)
    X = {nm: x[k] for k, nm in enumerate(model.layout.names)}
    dps = []
    for i in range(model.n):
        strut = model.sym.struts[i]
        if strut.compressible:
            dps.append(None)
            continue
        _, vs = model.station_motion(X, i, model.sym)
        T_valve = X.get(f"T_oil[{i}]", X.get(f"T_strut[{i}]"))     # the oil temperature the valve sees (as the model)
        dps.append(strut.valve_pressure_drop(vs, T_valve, newton_iterations=newton))
    ode, _, _ = model.equations(x, None, u, p, dp_override=dps)
    dae = {"t": t, "x": x, "p": ca.vertcat(p, data), "ode": ca.vertcat(*ode)}
    opts = {"reltol": rtol, "abstol": atol, "max_num_steps": 10 ** 7, "max_step_size": 0.05}
    if jit:
        opts.update({"jit": True, "compiler": "shell", "jit_options": {"flags": ["-O2"], "verbose": False}})
    return ca.integrator("cvodes_baseline", "cvodes", dae, 0.0, grid[K::K], opts)


def cvodes(distance_m: float, rtol: float, atol: float, newton: int, jit: bool):
    prep = make_drive(distance_m, 0.004)
    from vehicle.engines.build import build_engine

    model, drive = build_engine(prep)
    t0 = time.perf_counter()
    F = cvodes_integrator(model, drive, rtol, atol, newton, jit)
    build = time.perf_counter() - t0
    st = drive.initial_state()
    x, t = st.x.copy(), 0.0
    dt, K, M = drive.settings.dt_s, drive.K, drive.M
    integ = 0.0
    n_samples = int(np.floor(drive.total_time_s / (dt * K) + 1e-9))    # as the drive: the last sample in the distance
    done = 0
    while done < n_samples:
        U = drive.inputs(t + dt * np.arange(K * M + 1))
        ti = time.perf_counter()
        sol = F(x0=x, p=np.concatenate([drive.p, U.ravel(order="F")]))
        integ += time.perf_counter() - ti
        X = np.asarray(sol["xf"])
        take = min(M, n_samples - done)
        x, t = X[:, take - 1].copy(), t + dt * K * take
        done += take
    return drive, x, t, integ, build, F.stats()


def compare(drive, x, ref_drive, x_ref) -> dict:
    m = drive.model
    T, T_ref = x[drive.T_index], x_ref[ref_drive.T_index]
    z, z_ref = x[m.idx("z")], x_ref[m.idx("z")]
    E = sum(x[m.energy_index[e]] for e in ("valve", "friction", "gas", "end_stop"))
    E_ref = sum(x_ref[m.energy_index[e]] for e in ("valve", "friction", "gas", "end_stop"))
    return {"max_temperature_error_K": float(np.max(np.abs(T - T_ref))),
            "heave_error_mm": float(abs(z - z_ref) * 1e3),
            "max_dissipated_energy_error_pct": float(np.max(np.abs(E - E_ref) / E_ref) * 100)}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", default="200m")
    ap.add_argument("--rtol", type=float, default=3e-3)
    ap.add_argument("--atol", type=float, default=3e-5)
    ap.add_argument("--newton", type=int, default=12, help="valve Newton iterations from a cold start")
    ap.add_argument("--no-jit", action="store_true", help="CasADi's virtual machine instead of compiled C")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from hpsim.units import parse_quantity

    distance = parse_quantity(args.distance, "m", where="--distance")
    ref_drive, ref, ref_wall = ros2(distance, 0.001)
    drive, res, _ = ros2(distance, 0.004)
    cv_drive, x_cv, t_cv, cv_integ, cv_build, stats = cvodes(distance, args.rtol, args.atol, args.newton,
                                                            not args.no_jit)
    assert abs(t_cv - ref.state.t_s) < 1e-6 and abs(res.state.t_s - ref.state.t_s) < 1e-6, (t_cv, ref.state.t_s)
    out = {"distance_m": distance, "simulated_s": ref.state.t_s,
           "reference": "ROS2 at 1 ms (same model)", "reference_integration_s": ref.integration_s,
           "ros2_4ms": {"integration_s": res.integration_s, **compare(drive, res.state.x, ref_drive, ref.state.x)},
           "cvodes": {"integration_s": cv_integ, "build_s": cv_build, "rtol": args.rtol, "atol": args.atol,
                      "newton_iterations": args.newton, "compiled": not args.no_jit,
                      "steps": int(stats.get("nsteps", -1)) if isinstance(stats, dict) else None,
                      **compare(cv_drive, x_cv, ref_drive, ref.state.x)}}
    out["speed_ratio_cvodes_over_ros2"] = cv_integ / max(res.integration_s, 1e-9)
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"{distance:g} m ({out['simulated_s']:.0f} s of driving), errors against {out['reference']}")
    for name in ("ros2_4ms", "cvodes"):
        r = out[name]
        print(f"  {name:9s} integration {r['integration_s']:8.2f} s  T {r['max_temperature_error_K']:.2e} K  "
              f"heave {r['heave_error_mm']:.3f} mm  dissipated energy {r['max_dissipated_energy_error_pct']:.3f} %")
    print(f"  CVODES (rtol {args.rtol:g}, atol {args.atol:g}, compiled {not args.no_jit}, build {cv_build:.1f} s) "
          f"takes {out['speed_ratio_cvodes_over_ros2']:.1f}x the ROS2 engine's integration time")


if __name__ == "__main__":
    main()
