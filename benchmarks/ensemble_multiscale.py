"""A generation of 106 km multiscale drives on ensemble lanes against the same drives one by one (issue 39 item 3),
in one run, through `hpsim sweep` as a user runs it.

    python benchmarks/ensemble_multiscale.py [--cases 40] [--workers 2] [--lanes 8] [--repeats 1]
                                             [--before DIR] [--json]

The drives: scenarios/mileage_106km_multiscale.yaml as shipped, one design per case, the way the trials of an
optimisation generation differ: a grid of charge pressure offsets (-0.4 to 0.4 MPa) and bleed areas (8e-6 to
2e-5 m^2), on one road. The ways, alternating --repeats times after one warm-up (compiles and road cached):

  scalar   `hpsim sweep --ensemble 1`: each drive on its own (the windows in pairs on two threads, as shipped);
  lanes    `hpsim sweep --ensemble K`: the drives K at a time as the lanes of one vector step
           (vehicle.engines.ensemble), each lane's windows one after the other;
  before   (with --before DIR, a checkout of an earlier commit) that code's `hpsim sweep`, which runs every
           multiscale drive on its own.

Printed for each: the median wall time and CPU time (the command and its worker processes), their ratios to
`scalar` (and to `before`), the load; then the accuracy of the lanes: for each case, the largest difference of
the per-axle end temperature and wheel-load change between the lane and the scalar drive, as a fraction of the
95 % error the lane's own results state (at most 1: within it). The machine is shared: ratios within one run.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

FILL_MPA = (-0.4, -0.3, -0.2, -0.1, 0.1, 0.2, 0.3, 0.4)
BLEED_M2 = ("8e-6", "1e-5", "1.2e-5", "1.6e-5", "2e-5")
RUN_CLI = "import sys; from vehicle.cli import entry; sys.argv = ['hpsim'] + sys.argv[1:]; sys.exit(entry())"


def sweep_file(folder: Path, cases: int) -> Path:
    designs = [(f, b) for b in BLEED_M2 for f in FILL_MPA][:cases]
    if len(designs) < cases:
        sys.exit(f"--cases: at most {len(FILL_MPA) * len(BLEED_M2)}")
    lines = [f"base: {REPO / 'scenarios' / 'mileage_106km_multiscale.yaml'}", "cases:"]
    for k, (f, b) in enumerate(designs):
        lines.append(f"  - {{name: d{k:02d}, vehicle.overrides.charging.fill_pressure_offset: {f} MPa, "
                     f"struts.all.overrides.valve.bleed_area: {b} m^2}}")
    path = folder / "generation.yaml"
    path.write_text("\n".join(lines) + "\n")
    return path


def timed_sweep(code: Path, path: Path, out: Path, workers: int, lanes: int) -> dict:
    """`hpsim sweep` of the code in `code` (a checkout): wall and CPU time of the command and its workers."""
    env = {**os.environ, "PYTHONPATH": str(code)}
    cmd = [sys.executable, "-c", RUN_CLI, "sweep", str(path), "-o", str(out), "--workers", str(workers),
           "--ensemble", str(lanes), "--yes", "-q"]
    before = os.times()
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, env=env, cwd=code, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = os.times()
    if proc.returncode != 0:
        sys.exit(f"sweep failed ({code}): {proc.stderr[-2000:]}")
    cpu = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    return {"wall_s": wall, "cpu_s": cpu}


def accuracy(scalar: Path, lanes: Path) -> list[dict]:
    """Per case: the largest |lane - scalar| per axle of T_end and dN, over the lane's stated 95 % error."""
    from vehicle.analysis.summary import report

    rows = []
    for f in sorted(scalar.glob("*.h5")):
        a, b = report(lanes / f.name), report(f)
        err = a["estimated_error"]
        rT = max(abs(x["T_end_C"] - y["T_end_C"]) / e for x, y, e in zip(a["axles"], b["axles"], err["T_end_K"]))
        rN = max(abs(x["dN_pct"] - y["dN_pct"]) / e for x, y, e in zip(a["axles"], b["axles"], err["dN_pct"]))
        rows.append({"case": f.stem, "T_over_stated": rT, "dN_over_stated": rN})
    return rows


def main(argv=None) -> int:
    from vehicle.numerics.lanes import default_lanes

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--lanes", type=int, default=default_lanes())
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--before", type=Path, help="a checkout of an earlier commit: its sweep, one drive at a time")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    ways = {"scalar": (REPO, 1), "lanes": (REPO, args.lanes)}
    if args.before:
        ways["before"] = (args.before.resolve(), 1)
    load_before = os.getloadavg()[0]
    runs: dict[str, list[dict]] = {w: [] for w in ways}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        warm = sweep_file(tmp, 2)
        for way, (code, lanes) in ways.items():           # compiles (the lane library included) and the road
            timed_sweep(code, warm, tmp / f"warm_{way}", args.workers, lanes)
        path = sweep_file(tmp, args.cases)
        names = list(ways)
        for r in range(args.repeats):
            for way in names if r % 2 == 0 else names[::-1]:
                code, lanes = ways[way]
                runs[way].append(timed_sweep(code, path, tmp / f"{way}{r}", args.workers, lanes))
        acc = accuracy(tmp / "scalar0", tmp / "lanes0")
    out = {"cases": args.cases, "workers": args.workers, "lanes": args.lanes, "repeats": args.repeats,
           "load_before": load_before, "load_after": os.getloadavg()[0], "cpu_count": os.cpu_count()}
    for way, rows in runs.items():
        out[way] = {"wall_s": statistics.median(x["wall_s"] for x in rows),
                    "cpu_s": statistics.median(x["cpu_s"] for x in rows)}
    for ref in ("scalar", "before"):
        if ref in out:
            out[f"lanes_over_{ref}"] = {k: out["lanes"][k] / out[ref][k] for k in ("wall_s", "cpu_s")}
    out["accuracy"] = acc
    out["worst_T_over_stated"] = max(r["T_over_stated"] for r in acc)
    out["worst_dN_over_stated"] = max(r["dN_over_stated"] for r in acc)
    if args.json:
        print(json.dumps(out, indent=2))
        return 0
    print(f"{args.cases} drives of 106 km (multiscale), {args.workers} workers, lanes {args.lanes}, medians of "
          f"{args.repeats}; load {load_before:.1f} before, {out['load_after']:.1f} after ({os.cpu_count()} CPUs)")
    for way in runs:
        w = out[way]
        print(f"{way:8s} wall {w['wall_s']:7.1f} s   CPU {w['cpu_s']:7.1f} s")
    for ref in ("scalar", "before"):
        if f"lanes_over_{ref}" in out:
            q = out[f"lanes_over_{ref}"]
            print(f"lanes / {ref}: wall {q['wall_s']:.2f}, CPU {q['cpu_s']:.2f}")
    print(f"lanes against scalar, largest difference over the stated error: temperature "
          f"{out['worst_T_over_stated']:.2f}, wheel-load change {out['worst_dN_over_stated']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
