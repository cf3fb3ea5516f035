"""What a run costs on this machine: writes docs/performance.md, the one source of the README's "What a run
costs" figures.

    python benchmarks/performance.py                       # the README's cases, as a user runs them
    python benchmarks/performance.py --distance 2km --samples 4 --no-suite   # a short configuration
    python benchmarks/performance.py --output /tmp/perf.md
    python benchmarks/performance.py --quote               # README's "What a run costs" from docs/performance.md

Each case is an `hpsim` command in its own process, timed from outside (interpreter start and imports
included), one after the other in a temporary folder:

- the main job with an empty compile cache, then again with the cache warm (the reference of the ratios);
- the multiscale and time-parallel modes of the same test, cache warm, with their error against the full
  run (the largest per-axle difference of the end surface temperature [K] and of the load change [pp]);
- the per-axle UQ study of the README (41 drives on 2 workers), its own preview's estimate beside it;
- the test suite (`python -m pytest -q -n 2`, the README's test command less the install).

It then writes the table's headline rows into README.md between its `performance` markers (`--quote`
does only that, from the docs/performance.md there is). The table states the machine, its CPU flags, its
load average before and after, the commit and the date. On a machine shared with other work the walls are
longer, the ratios of one run less so. --distance
shortens every 106 km scenario (the multiscale ones to at least three windows, the time-parallel one
to its segments' minimum) and says so in the table.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
OUTPUT = REPO / "docs" / "performance.md"
README = REPO / "README.md"
QUOTE_START, QUOTE_END = "<!-- performance:start -->", "<!-- performance:end -->"
MAIN = "scenarios/mileage_106km.yaml"
MULTISCALE = "scenarios/mileage_106km_multiscale.yaml"
TIME_PARALLEL = "scenarios/mileage_106km_time_parallel.yaml"
UQ = "scenarios/mileage_106km_uq.yaml"
MULTISCALE_SPACING_KM = 5.3          # the shipped multiscale scenarios' solver.spacing: three windows at least
# the time-parallel scenario's 2 x 4 segments need 60 s of driving each (vehicle.engines.time_parallel): 2.7 km
# at its 20 km/h
TIME_PARALLEL_MIN_KM = 3.0
FLAGS = ("avx", "avx2", "fma", "avx512f")
ESTIMATE = re.compile(r"estimated (?P<value>[0-9.]+) (?P<unit>s|min|h)\b")


@dataclass
class Case:
    name: str
    command: str
    wall_s: float = float("nan")
    note: str = ""
    summary: dict = field(default_factory=dict)


def _hpsim(args: str, cwd: Path, env: dict) -> tuple[float, str]:
    """Run `hpsim ARGS` (a shell command line) in cwd: (wall seconds, stderr). A failure stops the benchmark."""
    t0 = time.perf_counter()
    p = subprocess.run(["bash", "-c", args], cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        raise SystemExit(f"{args}: exit {p.returncode}\n{p.stderr[-3000:]}")
    return wall, p.stderr


def _summary(path: Path, cwd: Path, env: dict) -> dict:
    p = subprocess.run([sys.executable, "-m", "vehicle.cli", "report", str(path), "--json"], cwd=cwd, env=env,
                       capture_output=True, text=True, check=True)
    return json.loads(p.stdout)


def _errors(run: dict, reference: dict) -> str:
    """The largest per-axle difference against the full run: end surface temperature [K], load change [pp];
    none where the runs cover different distances (a shortened configuration)."""
    if abs(run["distance_km"] - reference["distance_km"]) > 1e-6:
        return (f"not compared: {run['distance_km']:g} km against the full run's {reference['distance_km']:g} km "
                "(shortened)")
    dT = max(abs(a["T_surface_end_C"] - b["T_surface_end_C"]) for a, b in zip(run["axles"], reference["axles"]))
    dN = max(abs(a["dN_pct"] - b["dN_pct"]) for a, b in zip(run["axles"], reference["axles"]))
    return f"{dT:.3f} K, {dN:.3f} pp"


def _seconds(match: re.Match) -> float:
    return float(match["value"]) * {"s": 1.0, "min": 60.0, "h": 3600.0}[match["unit"]]


def _shorten(work: Path, distance_km: float) -> None:
    """Cut the 106 km scenarios of the work folder to distance_km (the multiscale ones to three windows, the
    time-parallel one to its segments' minimum)."""
    shortest = {MULTISCALE: 3 * MULTISCALE_SPACING_KM, UQ: 3 * MULTISCALE_SPACING_KM, TIME_PARALLEL: TIME_PARALLEL_MIN_KM}
    for name in (MAIN, MULTISCALE, TIME_PARALLEL, UQ):
        path = work / name
        km = max(distance_km, shortest.get(name, 0.0))
        text, n = re.subn(r"(?m)^distance: .*$", f"distance: {km:g} km", path.read_text())
        if n != 1:
            raise SystemExit(f"{name}: no top-level distance to shorten")
        path.write_text(text)


def machine() -> dict:
    flags = set()
    model = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("flags"):
                flags = set(line.split(":", 1)[1].split())
            elif line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
    except OSError:
        pass
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=REPO, capture_output=True, text=True)
    dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=REPO, capture_output=True,
                           text=True).stdout.strip()
    return {"cpu": model, "cpus": os.cpu_count(), "flags": " ".join(f for f in FLAGS if f in flags) or "none of "
            + ", ".join(FLAGS), "python": platform.python_version(), "system": platform.platform(terse=True),
            "commit": (commit.stdout.strip() or "unknown") + (" (with uncommitted changes)" if dirty else ""),
            "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}


def measure(args) -> tuple[list[Case], dict]:
    work = Path(tempfile.mkdtemp(prefix="hpsim_perf_"))
    try:
        for folder in ("scenarios", "examples"):
            shutil.copytree(REPO / folder, work / folder)
        if args.distance_km:
            _shorten(work, args.distance_km)
        cache = work / "cache"
        env = {**os.environ, "HPSIM_CACHE": str(cache), "MPLBACKEND": "Agg",
               "PATH": str(Path(sys.executable).parent) + os.pathsep + os.environ.get("PATH", "")}
        load_before = os.getloadavg()[0]
        cases = []
        main = Case("main job, empty compile cache", f"hpsim run {MAIN} -o cold.h5")
        main.wall_s, _ = _hpsim(main.command, work, env)
        cases.append(main)
        warm = Case("main job, cache warm (reference)", f"hpsim run {MAIN} -o warm.h5")
        warm.wall_s, _ = _hpsim(warm.command, work, env)
        warm.summary = _summary(work / "warm.h5", work, env)
        cases.append(warm)
        for name, scenario, out in (("multiscale mode", MULTISCALE, "ms.h5"),
                                    ("time-parallel, 2 processes", TIME_PARALLEL, "tp.h5")):
            _hpsim(f"hpsim run {scenario} -o {out}.warmup.h5", work, env)       # its own libraries compiled
            case = Case(name + ", cache warm", f"hpsim run {scenario} -o {out}")
            case.wall_s, _ = _hpsim(case.command, work, env)
            errors = _errors(_summary(work / out, work, env), warm.summary)
            case.note = errors if errors.startswith("not compared") else "error against the full run: " + errors
            cases.append(case)
        uq = Case(f"a {args.samples + 1}-drive study, 2 workers",
                  f"hpsim uq {UQ} --method lhs --samples {args.samples} --workers 2 --yes -o uq_study")
        uq.wall_s, err = _hpsim(uq.command, work, env)
        est = ESTIMATE.search(err)
        uq.note = (f"its preview estimated {_seconds(est):.0f} s ({uq.wall_s / _seconds(est):.2f}x)" if est
                   else "no preview estimate printed")
        cases.append(uq)
        if args.suite:
            suite = Case("the test suite, 2 workers", "python -m pytest -q -n 2")
            t0 = time.perf_counter()
            p = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "2", "-p", "no:cacheprovider"],
                               cwd=REPO, env={**env, "HPSIM_CACHE": str(work / "suite_cache")},
                               capture_output=True, text=True)
            suite.wall_s = time.perf_counter() - t0
            suite.note = (p.stdout.strip().splitlines() or ["?"])[-1] + ("" if p.returncode == 0 else " (FAILED)")
            cases.append(suite)
        info = machine()
        info["load"] = f"{load_before:.1f} before, {os.getloadavg()[0]:.1f} after (1-minute load average)"
        return cases, info
    finally:
        shutil.rmtree(work, ignore_errors=True)


def table(cases: list[Case], info: dict, args) -> str:
    reference = next(c for c in cases if "reference" in c.name).wall_s
    scope = (f"the 106 km scenarios cut to {args.distance_km:g} km (multiscale: at least three windows, "
             f"time-parallel: at least {TIME_PARALLEL_MIN_KM:g} km), "
             f"{args.samples + 1} study drives" if args.distance_km else "the scenarios as shipped (106 km)")
    lines = ["# What a run costs", "",
             "Generated by `python benchmarks/performance.py` (do not edit by hand; the history is in CHANGELOG.md).",
             f"Scope: {scope}.", "",
             "| case | command | wall | ratio to the reference | error against the full run, notes |",
             "|---|---|---|---|---|"]
    for c in cases:
        lines.append(f"| {c.name} | `{c.command}` | {c.wall_s:.1f} s | {c.wall_s / reference:.2f} | {c.note} |")
    lines += ["", "| machine | |", "|---|---|"]
    lines += [f"| {k} | {v} |" for k, v in (("CPU", f"{info['cpu']}, {info['cpus']} CPUs"),
                                            ("CPU flags", info["flags"]), ("load", info["load"]),
                                            ("system", f"{info['system']}, Python {info['python']}"),
                                            ("commit", info["commit"]), ("date", info["date"]))]
    return "\n".join(lines) + "\n"


def quote(performance_md: str, readme: str) -> str:
    """README text with the block between its performance markers replaced by the generated table's rows
    (case, wall, ratio) and its scope and machine line."""
    rows = re.findall(r"(?m)^\| (?!case |---)([^|]+)\| `[^`]*` \| ([^|]+)\| ([^|]+)\|", performance_md)
    facts = dict(re.findall(r"(?m)^\| (CPU|load|commit|date) \| (.+) \|$", performance_md))
    scope = re.search(r"(?m)^Scope: (.+)$", performance_md)
    if not rows or QUOTE_START not in readme or QUOTE_END not in readme:
        raise SystemExit("nothing to quote: no table in the performance file or no markers in README.md")
    block = ["| run | wall | ratio to the warm main job |", "|---|---|---|"]
    block += [f"| {case.strip()} | {wall.strip()} | {ratio.strip()} |" for case, wall, ratio in rows]
    block += ["", f"Scope: {scope[1].rstrip('.') if scope else '?'}. Machine: {facts.get('CPU', '?')}, load "
              f"{facts.get('load', '?')}; commit {facts.get('commit', '?')}, {facts.get('date', '?')}."]
    head, rest = readme.split(QUOTE_START, 1)
    return head + QUOTE_START + "\n" + "\n".join(block) + "\n" + QUOTE_END + rest.split(QUOTE_END, 1)[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--distance", default=None, help="shorten the 106 km scenarios to this many km (e.g. 2km)")
    ap.add_argument("--samples", type=int, default=40, help="the study's LHS samples (default 40: 41 drives)")
    ap.add_argument("--no-suite", dest="suite", action="store_false", help="leave out the test suite")
    ap.add_argument("--output", type=Path, default=OUTPUT, help=f"default {OUTPUT.relative_to(REPO)}")
    ap.add_argument("--quote", action="store_true", help="only write README.md's rows from the existing table")
    args = ap.parse_args(argv)
    if args.quote:
        README.write_text(quote(args.output.read_text(), README.read_text()))
        return 0
    args.distance_km = None
    if args.distance is not None:
        m = re.fullmatch(r"\s*([0-9.]+)\s*km\s*", args.distance)
        if not m or float(m[1]) <= 0:
            ap.error(f"--distance: a positive distance in km (e.g. 2km), got {args.distance!r}")
        args.distance_km = float(m[1])
    if args.samples < 2:
        ap.error(f"--samples: at least 2 (a Latin hypercube of one draw has no spread), got {args.samples}")
    cases, info = measure(args)
    args.output.write_text(table(cases, info, args))
    print(args.output.read_text())
    if args.output == OUTPUT:
        README.write_text(quote(OUTPUT.read_text(), README.read_text()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
