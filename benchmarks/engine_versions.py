"""The full drive's cost in two versions of the code, interleaved: what a change of the engines' Python costs.

    python benchmarks/engine_versions.py BEFORE_TREE AFTER_TREE [--distance 3km] [--repeats 5]

Each repetition runs the same drive (apc_8x8, ISO D seed 0, 20 km/h, 4 ms, output 1 s) once in a process on
each tree (PYTHONPATH), alternating, with each tree's compile cache warm (HPSIM_CACHE_BEFORE / HPSIM_CACHE_AFTER,
default the current HPSIM_CACHE): Drive.run's wall time and its integration time (the solver's calls) per
simulated second. The ratios after / before of the medians are the result; single timings on a shared machine
are noise.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys

import numpy as np

PROBE = r"""
import json, sys, time
import yaml
from vehicle.engines.build import build_engine
from vehicle.scenario.schema import prepare, read_scenario_text
text = yaml.safe_dump({"description": "cost", "vehicle": {"name": "apc_8x8"}, "road": {"iso_class": "D", "seed": 0},
                       "speed": "20 km/h", "distance": sys.argv[1], "ambient_temperature": "25 degC",
                       "initial_temperatures": "25 degC", "solver": {"dt": "4 ms"},
                       "output": {"interval": "1 s", "stats_interval": "1 km"}})
model, drive = build_engine(prepare(read_scenario_text(text, "cost", ".")))
t0 = time.perf_counter()
res = drive.run()
wall = time.perf_counter() - t0
print(json.dumps({"wall_s": wall, "integration_s": res.integration_s, "simulated_s": res.state.t_s}))
"""


def run(tree: str, cache: str, distance: str) -> dict:
    env = {**os.environ, "PYTHONPATH": tree, "HPSIM_CACHE": cache}
    out = subprocess.run([sys.executable, "-c", PROBE, distance], env=env, capture_output=True, text=True, check=True)
    r = json.loads(out.stdout.strip().splitlines()[-1])
    return {"wall_us_per_step": r["wall_s"] / (r["simulated_s"] / 0.004) * 1e6,
            "integration_us_per_step": r["integration_s"] / (r["simulated_s"] / 0.004) * 1e6}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--distance", default="3km")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    caches = {"before": os.environ.get("HPSIM_CACHE_BEFORE", os.environ.get("HPSIM_CACHE", "")),
              "after": os.environ.get("HPSIM_CACHE_AFTER", os.environ.get("HPSIM_CACHE", ""))}
    trees = {"before": args.before, "after": args.after}
    for name in trees:                       # a first run each fills its cache: not counted
        run(trees[name], caches[name], "200m")
    got = {name: [] for name in trees}
    for _ in range(args.repeats):
        for name in trees:
            got[name].append(run(trees[name], caches[name], args.distance))
    med = {name: {k: float(np.median([r[k] for r in rows])) for k in rows[0]} for name, rows in got.items()}
    for k in med["before"]:
        print(f"{k:26s} before {med['before'][k]:7.2f}  after {med['after'][k]:7.2f}  "
              f"after/before {med['after'][k] / med['before'][k]:.3f}")


if __name__ == "__main__":
    main()
