"""`hpsim optimize` against brute force: a two-parameter, two-objective design of the quick demo (2 km).

    python benchmarks/optimize_grid.py [--out DIR] [--workers K] [--trials 12] [--sampler tpe] [--json]

A 7 x 7 grid (`hpsim sweep`) of the strut's bleed area (log-spaced) and the charge pressure offset, and a study of
a quarter of its evaluations (12 trials) over the same ranges; both objectives minimised: the driver's weighted RMS
acceleration (ride comfort) and the largest 99th percentile of the struts' travel (working space). (Comfort and
the wheels' dynamic load coefficient do not conflict over these ranges: the largest bleed area is best for both.) Prints the
hypervolume of each front (both objectives scaled by the worst value seen in either set; the reference point is
that corner) and the ratio study / grid. The drives of both are kept in DIR (default optimize_grid_bench/): a
re-run reuses them.
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
BLEED = "struts.all.overrides.valve.bleed_area"
FILL = "vehicle.overrides.charging.fill_pressure_offset"
BLEED_RANGE_M2 = (6e-6, 3e-5)
FILL_RANGE_MPA = (-0.5, 0.5)
POINTS = 7
COMFORT = "ride.seats.driver.weighted_rms_acceleration_m_s2"
WORKING_SPACE = "max(ride.stations.strut_travel_p99_m)"
CASE = {"name": "ride", "distance": "2 km"}


def grid_values() -> tuple[list[str], list[str]]:
    bleed = np.geomspace(*BLEED_RANGE_M2, POINTS)
    fill = np.linspace(*FILL_RANGE_MPA, POINTS)
    return [f"{float(b)!r} m^2" for b in bleed], [f"{float(f)!r} MPa" for f in fill]


def run_grid(out: Path, workers: int | None) -> np.ndarray:
    """The 49 drives through `hpsim sweep`'s machinery; (49 x 2) objective values."""
    from vehicle.studies.sweep import run_sweep

    bleed, fill = grid_values()
    sweep = {"base": str(REPO / "scenarios" / "quick_demo.yaml"), "overrides": {"distance": CASE["distance"]},
             "grid": {BLEED: bleed, FILL: fill}}
    out.mkdir(parents=True, exist_ok=True)
    path = out / "grid_sweep.yaml"
    path.write_text(yaml.safe_dump(sweep, sort_keys=False))
    res = run_sweep(path, output_dir=out / "grid", workers=workers, ensemble=1, log=lambda m: print(m, file=sys.stderr))
    with open(res["summary_csv"], newline="") as fh:
        rows = [r for r in csv.DictReader(fh) if r["status"] in ("done", "skipped")]
    comfort = [float(r["weighted_rms_acceleration_m_s2_driver"]) for r in rows]
    travel = [max(float(v) for k, v in r.items() if k.startswith("strut_travel_p99_m_axle") and v) for r in rows]
    return np.column_stack([comfort, travel])


def run_study(out: Path, workers: int | None, trials: int, sampler: str) -> np.ndarray:
    from vehicle.api import optimize

    study = {"base": str(REPO / "scenarios" / "quick_demo.yaml"), "cases": [CASE],
             "design": {BLEED: {"range": [f"{BLEED_RANGE_M2[0]} m^2", f"{BLEED_RANGE_M2[1]} m^2"], "log": True},
                        FILL: [f"{FILL_RANGE_MPA[0]} MPa", f"{FILL_RANGE_MPA[1]} MPa"]},
             "objectives": {COMFORT: {"goal": "min"}, WORKING_SPACE: {"goal": "min"}},
             "trials": trials, "population": 4, "sampler": sampler}
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"study_{sampler}.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    s = optimize(path, out / f"study_{sampler}", workers=workers, log=lambda m: print(m, file=sys.stderr))
    return np.array([[r["objectives"][COMFORT], r["objectives"][WORKING_SPACE]] for r in s["all_trials"]
                     if r["status"] == "done"])


def main(argv=None) -> int:
    from vehicle.studies.optimize_pareto import hypervolume_2d, non_dominated

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default="optimize_grid_bench")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--trials", type=int, default=POINTS * POINTS // 4)
    ap.add_argument("--sampler", default="tpe", choices=["tpe", "nsga2"])
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    out = Path(args.out)
    t0 = time.perf_counter()
    grid = run_grid(out, args.workers)
    t_grid = time.perf_counter() - t0
    study = run_study(out, args.workers, args.trials, args.sampler)
    t_study = time.perf_counter() - t0 - t_grid
    scale = np.max(np.vstack([grid, study]), axis=0)
    ref = (1.0, 1.0)
    hv_grid = hypervolume_2d(grid / scale, ref)
    hv_study = hypervolume_2d(study / scale, ref)
    result = {"grid_evaluations": len(grid), "study_evaluations": len(study), "sampler": args.sampler,
              "hypervolume_grid": hv_grid, "hypervolume_study": hv_study, "ratio": hv_study / hv_grid,
              "grid_front": grid[non_dominated(grid)].tolist(), "study_front": study[non_dominated(study)].tolist(),
              "objective_scale": scale.tolist(), "grid_wall_s": t_grid, "study_wall_s": t_study}
    if args.json:
        print(json.dumps(result, indent=1))
    else:
        print(f"grid {len(grid)} drives: hypervolume {hv_grid:.4f}; study ({args.sampler}) {len(study)} drives: "
              f"{hv_study:.4f}; ratio {hv_study / hv_grid:.3f} (objectives scaled by {scale.tolist()}, reference 1, 1)")
    (out / "result.json").write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
