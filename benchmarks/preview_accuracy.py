"""How far a study's cost preview is from the time the study takes: every solver mode a study runs in, from an
empty compile cache and again with it warm.

    python benchmarks/preview_accuracy.py                    # every case, prints the table
    python benchmarks/preview_accuracy.py --cases uq,sweep   # some of them
    python benchmarks/preview_accuracy.py --output docs/preview_accuracy.md

Each case is an `hpsim` command in its own process, timed from outside (interpreter start and imports
included), in a temporary folder with copies of scenarios/ and examples/; its preview's "estimated ..." is read
from its stderr. "cold" runs with an empty compile cache of the case's own (it compiles what the study needs and
measures the drive rate on a probe drive), "warm" runs the same study again into another folder with that cache.
The ratio is the actual wall over the estimate (vehicle/studies/cost.py states the model; the aim is within a
factor 2 on an idle machine). The machine's load average is printed beside each row: on a shared machine the
drives after the preview run slower than the rate measured before them.

The cases, shortened as benchmarks/performance.py shortens them:
- uq: the README's per-axle study (multiscale), 15.9 km (three windows), 2 LHS samples + the nominal, 2 workers;
- sweep: the README tour's sweep (levelling off and on: two models), full mode, 2 km, 2 workers;
- ensemble: four speeds of the 2 km quick demo on 2 workers (ensemble lanes, as a study chooses them);
- time_parallel: two road seeds of the time-parallel 106 km scenario cut to 3 km, one worker;
- optimize: two trials of a one-case strut design on the 2 km quick demo, 2 workers.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "benchmarks"))
from performance import ESTIMATE, machine  # noqa: E402  (the same reading of the preview and of the machine)

QUICK_SWEEP = """base: scenarios/quick_demo.yaml
overrides: {distance: 2 km}
grid: {compensation.enabled: [false, true]}
"""
ENSEMBLE_SWEEP = """base: scenarios/quick_demo.yaml
overrides: {distance: 2 km}
grid: {speed: [16 km/h, 18 km/h, 20 km/h, 22 km/h]}
"""
TIME_PARALLEL_SWEEP = """base: scenarios/mileage_106km_time_parallel.yaml
overrides: {distance: 3 km}
grid: {road.seed: [0, 1]}
"""
OPTIMIZE_STUDY = """description: "preview benchmark: one ride case, one design parameter"
base: scenarios/quick_demo.yaml
cases:
  - {name: ride, distance: 2 km}
design:
  struts.all.overrides.valve.bleed_area: {range: [6e-6 m^2, 3e-5 m^2], log: true}
objectives:
  ride.seats.driver.weighted_rms_acceleration_m_s2: {case: ride, goal: min}
trials: 2
population: 2
seed: 0
"""
CASES = {
    "uq": ("per-axle UQ (multiscale), 15.9 km, 3 drives, 2 workers", {},
           "hpsim uq scenarios/mileage_106km_uq.yaml --method lhs --samples 2 --workers 2 --distance 15.9km --yes -o {out}"),
    "sweep": ("sweep, full mode, levelling off/on, 2 km, 2 workers", {"quick_sweep.yaml": QUICK_SWEEP},
              "hpsim sweep quick_sweep.yaml --workers 2 --yes -o {out}"),
    "ensemble": ("sweep on ensemble lanes, 4 speeds, 2 km, 2 workers", {"ensemble_sweep.yaml": ENSEMBLE_SWEEP},
                 "hpsim sweep ensemble_sweep.yaml --workers 2 --yes -o {out}"),
    "time_parallel": ("sweep of time-parallel drives (2 x 4 segments), 3 km, 1 worker",
                      {"tp_sweep.yaml": TIME_PARALLEL_SWEEP}, "hpsim sweep tp_sweep.yaml --workers 1 --yes -o {out}"),
    "optimize": ("optimize, 2 trials, 2 km, 2 workers", {"optimize_small.yaml": OPTIMIZE_STUDY},
                 "hpsim optimize optimize_small.yaml --workers 2 --yes -o {out}"),
}


@dataclass
class Row:
    case: str
    cache: str
    estimate_s: float
    actual_s: float
    load_before: float
    load_after: float
    compiles: str

    @property
    def ratio(self) -> float:
        return self.actual_s / self.estimate_s if self.estimate_s > 0 else float("nan")


def _seconds(value: str, unit: str) -> float:
    return float(value) * {"s": 1.0, "min": 60.0, "h": 3600.0}[unit]


def run_case(name: str, cache_state: str, work: Path, env: dict) -> Row:
    label, files, command = CASES[name]
    for file, text in files.items():
        (work / file).write_text(text)
    out = f"{name}_{cache_state}"
    load_before = os.getloadavg()[0]
    t0 = time.perf_counter()
    p = subprocess.run(["bash", "-c", command.format(out=out)], cwd=work, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:            # said in the table, and the other cases still run
        print(f"{name} ({cache_state}): exit {p.returncode}\n{p.stderr[-3000:]}", file=sys.stderr, flush=True)
        return Row(label, cache_state, float("nan"), wall, load_before, os.getloadavg()[0], f"FAILED (exit {p.returncode})")
    est = ESTIMATE.search(p.stderr)
    compiled = re.search(r"(\d+ librar(?:y|ies) of \d+ models?) compiled before the drives in ([0-9.]+ (?:s|min))",
                         p.stderr)
    compiles = (f"{compiled[1]}, {compiled[2]}" if compiled
                else "none" if "nothing compiled" in p.stderr else "not said")
    return Row(label, cache_state, _seconds(est["value"], est["unit"]) if est else float("nan"), wall, load_before,
               os.getloadavg()[0], compiles)


def table(rows: list[Row], info: dict) -> str:
    lines = ["# How far the study cost preview is from the study's time", "",
             "Generated by `python benchmarks/preview_accuracy.py` (do not edit by hand). The model the preview "
             "uses: vehicle/studies/cost.py.", "",
             "| study | compile cache | preview's estimate | actual wall | actual / estimate | compiled by the preview "
             "| load before, after |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r.case} | {r.cache} | {r.estimate_s:.0f} s | {r.actual_s:.0f} s | {r.ratio:.2f} | "
                     f"{r.compiles} | {r.load_before:.1f}, {r.load_after:.1f} |")
    lines += ["", f"Machine: {info['cpu']}, {info['cpus']} CPUs ({info['flags']}); {info['system']}, Python "
              f"{info['python']}; commit {info['commit']}, {info['date']}."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", default=",".join(CASES), help=f"comma-separated, of {', '.join(CASES)}")
    ap.add_argument("--output", type=Path, default=None, help="also write the table to this markdown file")
    args = ap.parse_args(argv)
    names = [c.strip() for c in args.cases.split(",") if c.strip()]
    unknown = [c for c in names if c not in CASES]
    if unknown or not names:
        ap.error(f"--cases: of {', '.join(CASES)}, got {args.cases!r}")
    work = Path(tempfile.mkdtemp(prefix="hpsim_preview_"))
    rows = []
    try:
        for folder in ("scenarios", "examples"):
            shutil.copytree(REPO / folder, work / folder)
        base = {**os.environ, "MPLBACKEND": "Agg",
                "PATH": str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")}
        for name in names:
            env = {**base, "HPSIM_CACHE": str(work / f"cache_{name}")}       # each case's own, empty at first
            for state in ("cold", "warm"):
                rows.append(run_case(name, state, work, env))
                r = rows[-1]
                print(f"{r.case} ({state}): estimate {r.estimate_s:.0f} s, actual {r.actual_s:.0f} s, "
                      f"ratio {r.ratio:.2f}, load {r.load_before:.1f} -> {r.load_after:.1f}", flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    text = table(rows, machine())
    print(text)
    if args.output is not None:
        args.output.write_text(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
