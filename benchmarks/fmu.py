"""The FMUs of `hpsim export fmu` (docs/fmu.md): their sizes, their speed against the same model in hpsim, and the
strut's heat output over a 10 min rig test.

    python benchmarks/fmu.py [--json] [--distance 1km] [--minutes 10]

- strut: the apc FMU (1 ms internal step) on the rig's 0.1 Hz / 50 mm sinusoid for --minutes, the body held at the
  rig temperature (heat.capacity 1e12 J/K through FMI), driven from Python through FMPy's FMU2Slave at a 10 ms
  communication step (deflection, rate and the rate's derivative set at every point), against `hpsim strut
  cycle` (struts.rig.cycle_test: IDAS, 400 samples per cycle) over the same cycles: the heat put out in the last
  cycle (valve + friction + gas + end stops) and the time per simulated second of each. The FMU is also timed in
  one fmi2DoStep of the whole span (the C alone, no Python per communication step).
- vehicle: the quick-demo vehicle FMU (4 ms) fed the drive's inputs at every 4 ms step (the importer's work in
  Python included) and in steps of 1 s with held inputs (the C alone), against the drive's integration time
  (vehicle.engines.full, the compiled ROS2 in blocks of 250 steps x 10 samples) over --distance.
Timings on a shared 2-core machine are noisy: compare the ratios of one run.
"""
from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from struts.params import load_strut  # noqa: E402
from struts.rig import cycle_test  # noqa: E402
from tests.integration.test_fmu import ISOTHERMAL, MEAN_M, T_RIG_K, Driven, drive_strut, last_cycle, run_drive  # noqa: E402
from vehicle.fmu.build import build_fmu  # noqa: E402
from vehicle.fmu.exports import strut_spec, vehicle_spec  # noqa: E402
from vehicle.scenario.schema import apply_overrides, prepare, read_scenario  # noqa: E402


def one_step_rate(path, span_s, start, inputs) -> float:
    """Simulated seconds per wall second of the FMU's C: the whole span in fmi2DoStep calls of 1 s."""
    d = Driven(path, start)
    d.set(inputs)
    d.fmu.exitInitializationMode()
    t0 = time.perf_counter()
    for k in range(int(span_s)):
        d.fmu.doStep(float(k), 1.0)
    wall = time.perf_counter() - t0
    d.close()
    return int(span_s) / wall


def strut(folder: Path, minutes: float) -> dict:
    path = folder / "apc.fmu"
    info = build_fmu(strut_spec("apc", motion_centre_m=MEAN_M, T_start_K=T_RIG_K), path)
    A, f, comm = 0.05, 0.1, 0.01
    cycles = int(round(minutes * 60 * f))
    spc = int(round(1 / f / comm))
    t0 = time.perf_counter()
    rig = cycle_test(load_strut("apc"), A, f, MEAN_M, cycles=cycles, T_K=T_RIG_K)
    rig_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    res = drive_strut(path, A, f, cycles, comm)
    fmu_s = time.perf_counter() - t0
    heat = sum(last_cycle(res[k], spc) for k in ("E_valve", "E_friction", "E_gas", "E_end_stop"))
    span = cycles / f
    c_rate = one_step_rate(path, span, {"motion_centre": MEAN_M, "T_start": T_RIG_K, **ISOTHERMAL},
                           {"deflection": MEAN_M, "deflection_rate": 0.0})
    return {"fmu_bytes": info["bytes"], "cycles": cycles, "span_s": span,
            "heat_last_cycle_J": {"rig": rig.heat_out_J, "fmu": heat, "rel_diff": heat / rig.heat_out_J - 1},
            "energy_last_cycle_J": {"rig": rig.energy_per_cycle_J, "fmu": last_cycle(res["E_work"], spc)},
            "wall_per_simulated_s": {"rig_idas": rig_s / span, "fmu_fmpy_10ms": fmu_s / span,
                                     "fmu_c_only": 1.0 / c_rate}}


def vehicle(folder: Path, distance: str) -> dict:
    src = read_scenario(Path(__file__).resolve().parents[1] / "scenarios" / "quick_demo.yaml")
    src.data = apply_overrides(src.data, {"distance": distance, "output.interval": "0.1 s",
                                          "solver.error_check_every": 0})
    prepared = prepare(src)
    path = folder / "vehicle.fmu"
    info = build_fmu(vehicle_spec(prepared), path)
    run = run_drive(prepared)
    span = float(run["t_s"][-1])
    from tests.integration.test_fmu import run_vehicle_fmu

    t0 = time.perf_counter()
    run_vehicle_fmu(path, run)
    fmu_s = time.perf_counter() - t0
    c_rate = one_step_rate(path, span, None, {})
    return {"fmu_bytes": info["bytes"], "span_s": span,
            "wall_per_simulated_s": {"drive_integration": run["integration_s"] / span,
                                     "fmu_fmpy_4ms_with_inputs": fmu_s / span, "fmu_c_only": 1.0 / c_rate}}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=10.0)
    ap.add_argument("--distance", default="1 km")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = {"strut": strut(Path(tmp), args.minutes), "vehicle": vehicle(Path(tmp), args.distance)}
    print(json.dumps(out, indent=1) if args.json else out)


if __name__ == "__main__":
    main()
