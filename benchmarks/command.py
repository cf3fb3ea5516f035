"""The whole `hpsim run` command, full against multiscale, end to end ("the whole command, not only the
integration").

    python benchmarks/command.py [--repeat 3] [--json]
    python benchmarks/command.py --full scenarios/mileage_106km.yaml \
        --multiscale scenarios/mileage_106km_multiscale.yaml

Runs `hpsim -v run <scenario> -o <tmp>.h5 --overwrite --no-progress` for both scenarios as separate processes, one
after the other, --repeat times alternating (full, multiscale, full, ...), so that both see the same machine load;
first one warm-up run of each (the compile cache filled: the timings are those of a warm cache). Prints each
command's wall time (from outside the process: interpreter start and imports included) and the ratio full /
multiscale of the medians. It also prints the `-v` stage times of the median run of each (reading, scenario
checks, model, road, the cache lookup, the drive, the summary; "other" is the wall time outside the stages:
interpreter start, imports, the output file's set-up). Last comes each command's CPU time (user + system, of the
process and its children): on a shared machine the wall times are noisy (compare the ratio of one run), the CPU
times less so.

Python's bytecode cache: a user's Python writes each module's compiled bytecode (__pycache__) on the first import
and reads it afterwards. Where PYTHONDONTWRITEBYTECODE is set (this project's development machine sets it), every
command compiles hpsim's ~110 modules from their source again (~0.2 s in each command). The benchmark runs its
commands under the environment's setting and prints it; --bytecode-cache runs them with Python's default (the
warm-up run writes the cache beside the sources; __pycache__ is ignored by git).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STAGE = re.compile(r"^stage (?P<name>.+): (?P<s>[0-9.]+) s$")


def run_once(scenario: Path, out: Path, env: dict | None = None) -> dict:
    """One `hpsim -v run` (in the environment `env`, default this one's): its wall time and the stage times it
    logs."""
    cmd = [sys.executable, "-m", "vehicle.cli", "-v", "run", str(scenario), "-o", str(out), "--overwrite",
           "--no-progress"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO, env=env)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if res.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({res.returncode}):\n{res.stderr[-2000:]}")
    stages: dict[str, float] = {}
    for line in res.stderr.splitlines():
        m = STAGE.match(line.strip())
        if m:
            stages[m["name"]] = stages.get(m["name"], 0.0) + float(m["s"])
    return {"wall_s": wall, "cpu_s": cpu, "stages": stages}


def outside_stages(run: dict) -> float:
    """Wall time in no top-level stage (nested stages, "compile..." inside "build: drive" and "drive: ..." inside
    "drive", not counted twice)."""
    top = [k for k in run["stages"] if not k.startswith(("compile", "drive: "))]
    return run["wall_s"] - sum(run["stages"][k] for k in top)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", default=str(REPO / "scenarios" / "mileage_106km.yaml"))
    ap.add_argument("--multiscale", default=str(REPO / "scenarios" / "mileage_106km_multiscale.yaml"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--bytecode-cache", action="store_true",
                    help="run the commands with Python's bytecode cache (PYTHONDONTWRITEBYTECODE unset)")
    args = ap.parse_args(argv)
    scenarios = {"full": Path(args.full).resolve(), "multiscale": Path(args.multiscale).resolve()}
    runs: dict[str, list[dict]] = {k: [] for k in scenarios}
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"} if args.bytecode_cache else None
    bytecode = "written and read" if (env or os.environ).get("PYTHONDONTWRITEBYTECODE") is None else \
        "not written (PYTHONDONTWRITEBYTECODE is set: every command compiles hpsim's modules; --bytecode-cache)"
    with tempfile.TemporaryDirectory() as tmp:
        for name, scen in scenarios.items():           # warm-up: the compile cache (and bytecode cache) filled
            run_once(scen, Path(tmp) / f"{name}.h5", env)
        for _ in range(args.repeat):
            for name, scen in scenarios.items():
                runs[name].append(run_once(scen, Path(tmp) / f"{name}.h5", env))
    median = {}
    for name, rs in runs.items():
        walls = [r["wall_s"] for r in rs]
        mid = sorted(rs, key=lambda r: r["wall_s"])[len(rs) // 2]
        cpus = [r["cpu_s"] for r in rs]
        median[name] = {"wall_s": statistics.median(walls), "walls_s": walls, "cpu_s": statistics.median(cpus),
                        "cpus_s": cpus, "stages": mid["stages"], "other_s": outside_stages(mid)}
    ratio = median["full"]["wall_s"] / median["multiscale"]["wall_s"]
    ratios = [f["wall_s"] / m["wall_s"] for f, m in zip(runs["full"], runs["multiscale"])]
    cpu_ratio = median["full"]["cpu_s"] / median["multiscale"]["cpu_s"]
    if args.json:
        print(json.dumps({"runs": median, "ratio": ratio, "ratios": ratios, "cpu_ratio": cpu_ratio,
                          "cpus": os.cpu_count(), "bytecode": bytecode}, indent=1))
        return 0
    print(f"Python's bytecode cache: {bytecode}")
    for name, m in median.items():
        print(f"{name:10s} wall {m['wall_s']:6.2f} s (runs: {', '.join(f'{w:.2f}' for w in m['walls_s'])}), "
              f"CPU {m['cpu_s']:6.2f} s (runs: {', '.join(f'{c:.2f}' for c in m['cpus_s'])})")
    print(f"ratio full / multiscale: wall {ratio:.2f} (per pair: {', '.join(f'{r:.2f}' for r in ratios)}), "
          f"CPU {cpu_ratio:.2f}")
    names = list(dict.fromkeys(k for m in median.values() for k in m["stages"]))
    print(f"\n{'stage (median run)':52s} {'full':>8s} {'multiscale':>11s}")
    for k in names:
        print(f"{k:52s} {median['full']['stages'].get(k, 0.0):8.2f} {median['multiscale']['stages'].get(k, 0.0):11.2f}")
    print(f"{'other (start, imports, output file)':52s} {median['full']['other_s']:8.2f} "
          f"{median['multiscale']['other_s']:11.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
