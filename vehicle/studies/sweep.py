"""Sweeps: a base scenario run over a grid or list of overrides (`hpsim sweep`, docs/scenarios.md).

    base: mileage_106km.yaml            # scenario file, relative to the sweep file
    overrides: {distance: 10 km}        # applied to every case (optional)
    grid:                               # cartesian product of the lists (optional)
      compensation.enabled: [false, true]
      road.iso_class: [D, E]
    cases:                              # and/or explicit cases (optional), each a mapping of overrides
      - {name: hot_start, initial_temperatures: 45 degC}

Cases = cases (or one empty case) x grid. Every case is validated before any runs. Cases run in
parallel local processes (ProcessPoolExecutor) or on a Dask distributed cluster (--scheduler);
each writes <output_dir>/<case>.h5, a failed case is reported and the others go on, a case whose
file holds a complete summary is skipped on a re-run (an incomplete one is resumed). At the end:
<output_dir>/summary.csv (one row per case) and <output_dir>/compare.png.
"""
from __future__ import annotations

import contextlib
import csv
import itertools
import os
import re
import threading
import time
import traceback
from pathlib import Path
from typing import Any, Callable

import yaml

from hpsim.cancellation import CancelToken
from hpsim.config import Model, load_yaml, parse_yaml, validate
from hpsim.errors import SimulationError, Terminated, UserInputError
from hpsim.outputs import atomic_output
from hpsim.extras import install_hint

from vehicle.scenario.schema import ScenarioSource, apply_overrides, prepare, read_scenario
from vehicle.engines.pool import die_with_parent, stop_workers
from vehicle.results.run import RunInterrupted, run_scenario
from vehicle.results.validity import summary_cell
from vehicle.analysis.ride_metrics import axle_rows
from vehicle.analysis.summary import report
from vehicle.engines.ensemble import eligible, grouped_jobs
from vehicle.engines.shared_builds import process_builds
from vehicle.studies.study_folder import (StudyLock, case_state, check_case_count, check_study_kind, refuse_changed,
                                          safe_names)


class SweepSpec(Model):
    description: str = ""
    base: str
    overrides: dict[str, Any] = {}
    grid: dict[str, list] = {}
    cases: list[dict[str, Any]] = []


def _slug(value: Any) -> str:
    text = str(value).lower() if isinstance(value, bool) else str(value)
    return re.sub(r"[^A-Za-z0-9._+-]+", "", text.replace(" ", "")) or "x"


def _parts(overrides: dict) -> list[str]:
    return [f"{str(k).rsplit('.', 1)[-1]}-{_slug(v)}" for k, v in overrides.items() if not isinstance(v, (dict, list))]


def case_name(i: int, overrides: dict, given: str | None = None, grid: dict | None = None) -> str:
    """c00_enabled-false_iso_class-D, or the case's own name plus its grid values."""
    if given:
        return "_".join([_slug(given)] + _parts(grid or {}))
    parts = _parts(overrides)
    return f"c{i:02d}_" + ("_".join(parts) if parts else "base")


def load_sweep(path: str | Path) -> tuple[SweepSpec, ScenarioSource, list[dict]]:
    """Parse and validate the sweep and every case (nothing runs). Returns (spec, base, cases)."""
    path = Path(path)
    data = load_yaml(path)
    if not isinstance(data, dict):
        raise UserInputError(f"{path}: expected a mapping with base, grid and/or cases")
    spec = validate(SweepSpec, data, str(path))
    for k, v in spec.grid.items():
        if not v:
            raise UserInputError(f"{path}: grid.{k}: empty list (give at least one value)")
    base_path = Path(spec.base)
    if not base_path.is_absolute():
        base_path = path.resolve().parent / base_path
    if not base_path.exists():
        raise UserInputError(f"{path}: base: scenario file {spec.base!r} not found (looked at {base_path})")
    base = read_scenario(base_path)
    keys = list(spec.grid)
    explicit = spec.cases or [{}]
    n_grid = 1
    for k in keys:
        n_grid *= len(spec.grid[k])
    check_case_count(len(explicit) * n_grid, str(path))           # before the grid is expanded
    combos = list(itertools.product(*[spec.grid[k] for k in keys])) if keys else [()]
    planned = []
    for ci, case in enumerate(explicit):
        case = dict(case)
        given = case.pop("name", None)
        for combo in combos:
            ov = {**case, **dict(zip(keys, combo))}
            planned.append((ov, case_name(len(planned), ov, given, dict(zip(keys, combo)))))
    cases = []
    # file names: sanitised and collision-free (vehicle.studies.study_folder)
    for (ov, _), name in zip(planned, safe_names([n for _, n in planned])):
        label = f"{path} case {name}"
        try:
            merged = apply_overrides(base.data, {**spec.overrides, **ov})
        except UserInputError as exc:
            raise UserInputError(f"{label}: {exc}") from None
        text = f"# case {name} of sweep {path.name}: base {base.name} with {ov}\n" + \
            yaml.safe_dump(merged, sort_keys=False)
        src = ScenarioSource(text=text, name=label, base_dir=base.base_dir, data=merged)
        prepared = prepare(src)          # every case validated before anything runs
        cases.append({"name": name, "overrides": ov, "source": src, "prepared": prepared})
    return spec, base, cases


ORPHAN_CHECK_S = 0.5        # how often a running case looks whether its process lost its parent


@contextlib.contextmanager
def stop_when_orphaned(cancel: CancelToken):
    """Request `cancel` if this process's parent changes while the block runs: a worker whose study died stops its
    drive at the next checkpoint (its file stays resumable) where the kernel does not end it
    (vehicle.engines.pool.die_with_parent)."""
    parent = os.getppid()
    done = threading.Event()

    def watch():
        while not done.wait(ORPHAN_CHECK_S):
            if os.getppid() != parent:
                cancel.request()
                return

    watcher = threading.Thread(target=watch, name="hpsim-orphan-watch", daemon=True)
    watcher.start()
    try:
        yield cancel
    finally:
        done.set()
        watcher.join()


def run_case(text: str, name: str, base_dir: str, out: str, overwrite: bool = False,
             make_solver: Callable[[float], object] | None = None) -> dict:
    """One case in a worker process: never raises, returns status and message (overwrite: start it again;
    make_solver: the solver factory of an ensemble lane, `vehicle.engines.ensemble.run_lockstep`). The model, its
    vehicle check and the road are shared with the process's other cases (`vehicle.engines.shared_builds`)."""
    t0 = time.perf_counter()
    try:
        src = ScenarioSource(text=text, name=name, base_dir=Path(base_dir), data=parse_yaml(text, name))
        with stop_when_orphaned(CancelToken()) as cancel:
            summary = run_scenario(src, out, resume=not overwrite, overwrite=overwrite, progress=False, cancel=cancel,
                                   make_solver=make_solver, shared=process_builds())
        return {**summary, "status": "done", "error": "", "seconds": time.perf_counter() - t0}
    except (UserInputError, SimulationError) as exc:
        return {"status": "failed", "error": str(exc), "seconds": time.perf_counter() - t0}
    except (KeyboardInterrupt, RunInterrupted):
        # the case's file is closed and resumable: re-running the sweep continues it
        return {"status": "interrupted", "error": "interrupted", "seconds": time.perf_counter() - t0}
    except Exception as exc:  # a bug: report it with its traceback's last lines, keep the others going
        tb = traceback.format_exc().strip().splitlines()[-3:]
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc} ({' | '.join(tb)})",
                "seconds": time.perf_counter() - t0}


def dask_client(address: str):
    try:
        from distributed import Client
    except ImportError:
        raise UserInputError("--scheduler: Dask distributed is not installed; install the optional extra: "
                             f"{install_hint('dask')} (or run without --scheduler for local processes)") from None
    try:
        return Client(address, timeout="20s")
    except Exception as exc:
        raise UserInputError(f"--scheduler: cannot connect to the Dask scheduler at {address!r} ({exc})") from None


def execute(fn: Callable[..., dict], jobs: list[tuple[str, tuple]], *, workers: int | None = None, client=None,
            finished: Callable[[str, dict], None], key_prefix: str = "hpsim") -> None:
    """Run fn(*args) for every (tag, args) in `jobs`; call finished(tag, result) as each ends.

    In this process (workers == 1), in local processes (ProcessPoolExecutor, default: one per CPU)
    or on a Dask distributed `client`. `fn` must be picklable and return a dict without raising;
    an exception escaping a worker (e.g. a process killed by the OS) becomes a failed result.
    Used by `hpsim sweep` and `hpsim uq` (vehicle.studies.uq).
    """
    import os

    def failed(exc):
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}", "seconds": 0.0}

    if not jobs:
        return
    if client is not None:
        from distributed import as_completed as dask_completed

        futs = {client.submit(fn, *args, pure=False, key=f"{key_prefix}-{tag}"): tag for tag, args in jobs}
        for fut in dask_completed(futs):
            try:
                r = fut.result()
            except Exception as exc:
                r = failed(exc)
            finished(futs[fut], r)
        return
    workers = workers or min(len(jobs), os.cpu_count() or 1)
    if workers == 1:
        for tag, args in jobs:
            r = fn(*args)
            finished(tag, r)
            if r.get("status") == "interrupted":
                raise KeyboardInterrupt         # Ctrl-C stopped this case: the next ones do not start
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=min(workers, len(jobs)), initializer=worker_init,
                             initargs=(os.getpid(),)) as pool:
        futs = {pool.submit(fn, *args): tag for tag, args in jobs}
        try:
            for fut in as_completed(futs):
                try:
                    r = fut.result()
                except Exception as exc:   # e.g. a worker killed by the OS
                    r = failed(exc)
                finished(futs[fut], r)
        except (KeyboardInterrupt, Terminated):
            # Ctrl-C: cases not started are dropped; running ones stop at their next checkpoint (their
            # files stay resumable), also when only this process got the signal; a second Ctrl-C (or
            # SIGTERM, or no end within pool.STOP_GRACE_S) kills them: their files stay resumable too
            stop_workers(pool, futs)
            raise


def worker_init(parent_pid: int) -> None:
    """In each local worker process: die with the parent (vehicle.engines.pool.die_with_parent); where the kernel
    cannot do that, a running case stops at its next checkpoint (`stop_when_orphaned`)."""
    die_with_parent(parent_pid)


def run_sweep(path: str | Path, *, output_dir: str | Path | None = None, workers: int | None = None,
              scheduler: str | None = None, log: Callable[[str], None] | None = None,
              before_start: Callable[[list], None] | None = None, ensemble: int | None = None,
              overwrite: bool = False) -> dict:
    """before_start(the cases to run, prepared): called before any runs (the cost preview may stop it);
    overwrite: run again the cases made from another definition."""
    log = log or (lambda m: None)
    path = Path(path)
    spec, base, cases = load_sweep(path)
    out_dir = Path(output_dir) if output_dir else Path(path.stem)
    check_study_kind(out_dir, "sweep")
    out_dir.mkdir(parents=True, exist_ok=True)
    with StudyLock(out_dir):                 # one study writing into a folder at a time
        return _run_sweep(path, out_dir, cases, workers, scheduler, log, overwrite, before_start, ensemble)


def _run_sweep(path, out_dir, cases, workers, scheduler, log, overwrite, before_start, ensemble) -> dict:
    rows: dict[str, dict] = {}
    todo, changed = [], []
    for c in cases:
        f = out_dir / f"{c['name']}.h5"
        c["file"] = f
        state = case_state(f, c["source"])          # a case made from another definition is never reused
        c["overwrite"] = state.startswith("changed")
        if state == "complete":
            rows[c["name"]] = {"status": "skipped", "error": ""}
            log(f"{c['name']}: complete from an earlier run, skipped")
        else:
            todo.append(c)
            if c["overwrite"]:
                changed.append((c["name"], state))
    if not overwrite:
        refuse_changed(out_dir, changed)
    for name, why in changed:
        log(f"{name}: {why.removeprefix('changed: ')}: run again (--overwrite)")
    client = dask_client(scheduler) if scheduler else None
    n = len(todo)
    log(f"{path}: {len(cases)} cases, {n} to run, results in {out_dir}/")
    if before_start is not None:
        before_start([c["prepared"] for c in todo])
    t0 = time.perf_counter()
    done = 0

    def finished(c, r):
        nonlocal done
        done += 1
        rows[c["name"]] = r
        if r["status"] == "done":
            log(f"[{done}/{n}] {c['name']}: done in {r['seconds']:.1f} s")
        elif r["status"] == "interrupted":
            log(f"[{done}/{n}] {c['name']}: interrupted (resumable)")
        else:
            log(f"[{done}/{n}] {c['name']}: FAILED: {r['error']}")

    by_name = {c["name"]: c for c in todo}
    jobs = [(c["name"], (c["source"].text, c["source"].name, str(c["source"].base_dir), str(c["file"].resolve()),
                         c["overwrite"])) for c in todo]
    resume_cmd = f"hpsim sweep {path} -o {out_dir}"
    try:
        # --ensemble K: the full-fidelity cases K at a time in lockstep (vehicle.engines.ensemble)
        fn, jobs, unpack = grouped_jobs(run_case, jobs, ensemble, [eligible(c["source"].data) for c in todo],
                                        workers, durations=[c["prepared"].duration_s() for c in todo])
        execute(fn, jobs, workers=workers, client=client, key_prefix=f"hpsim-{path.stem}",
                finished=lambda tag, r: [finished(by_name[name], rr) for name, rr in unpack(tag, r)])
    except KeyboardInterrupt:
        interrupted = True
    else:
        interrupted = any(r.get("status") == "interrupted" for r in rows.values())
    finally:
        if client is not None:
            client.close()
    if interrupted:
        n_done = sum(r.get("status") in ("done", "skipped") for r in rows.values())
        log(f"{path}: interrupted, {n_done} of {len(cases)} cases complete in {out_dir}/ (an interrupted case "
            f"resumes, complete ones are skipped). Continue with: {resume_cmd}")
        raise KeyboardInterrupt
    result = summarise(path, out_dir, cases, rows)
    result["wall_s"] = time.perf_counter() - t0
    return result


# the ride and road-holding numbers of a case in the summary CSV: per seat, and per axle (worst of left and right)
SEAT_CSV_KEYS = ("weighted_rms_acceleration_m_s2", "vdv_m_s175", "absorbed_power_W")
AXLE_CSV_KEYS = ("dynamic_load_coefficient", "lift_off_share", "end_stop_time_s", "strut_travel_p99_m")


def ride_columns(ride: dict, n_axles: int) -> dict:
    """Flat CSV columns of a report's ride summary (vehicle.analysis.ride_metrics): `<key>_<seat>` per seat and
    `<key>_axle<k>` per axle; keys a run did not store are left out."""
    out = {}
    for seat in ride.get("seats", []):
        out.update({f"{k}_{seat['seat']}": seat[k] for k in SEAT_CSV_KEYS if seat.get(k) is not None})
    for row in axle_rows(ride, [None] * n_axles):
        out.update({f"{k}_axle{row['axle']}": row[k] for k in AXLE_CSV_KEYS if row.get(k) is not None})
    return out


def summarise(path: Path, out_dir: Path, cases: list[dict], rows: dict) -> dict:
    keys = []
    for c in cases:
        for k in c["overrides"]:
            if k not in keys:
                keys.append(k)
    table, ok_files, ok_labels = [], [], []
    for c in cases:
        r = rows.get(c["name"], {"status": "failed", "error": "not run"})
        row = {"case": c["name"], "status": r["status"], "error": r.get("error", ""), "file": str(c["file"])}
        for k in keys:
            v = c["overrides"].get(k, "")
            row[k] = v if isinstance(v, (str, int, float, bool)) else yaml.safe_dump(v, default_flow_style=True).strip()
        if r["status"] in ("done", "skipped"):
            try:
                # a case done now was written whole by its worker: the child-process read check is for other files
                rep = report(c["file"], check=r["status"] != "done")
            except UserInputError as exc:
                row["status"], row["error"] = "failed", str(exc)
            else:
                row.update({"distance_km": rep["distance_km"], "simulated_s": rep["simulated_s"], "wall_s": rep["wall_s"],
                            "load_shift_pct": rep["load_shift_pct"], "max_abs_dN_pct": rep["max_abs_dN_pct"],
                            "load_shift_vs_charged_pct": rep["load_shift_vs_charged_pct"],
                            "mean_temperature_rise_K": rep["mean_temperature_rise_K"],
                            "energy_dissipated_MJ": rep["energy_dissipated_MJ"]})
                if "solver_error_estimate" in rep:          # the step-doubling estimate and its advice
                    row.update({k: rep.get(k) for k in ("solver_error_estimate", "solver_tolerance", "solver_advice")})
                for a in rep["axles"]:
                    for q in ("dN_pct", "dN_charged_pct", "dh_mm", "T_end_C", "T_oil_end_C", "T_gas_end_C"):
                        if q in a:
                            row[f"{q}_axle{a['axle']}"] = a[q]
                    for q in ("dN_band_pct", "dh_band_mm"):     # the weighing bands: [low, high] -> two columns
                        if a.get(q) is not None:
                            row[f"{q}_low_axle{a['axle']}"], row[f"{q}_high_axle{a['axle']}"] = a[q]
                row.update(ride_columns(rep.get("ride") or {}, len(rep["axles"])))
                warnings = rep.get("warnings")          # the report's validity warnings (vehicle.results.validity)
                if warnings:
                    row["warnings"] = warnings if isinstance(warnings, str) else summary_cell(warnings)
                ok_files.append(c["file"])
                ok_labels.append(c["name"])
        table.append(row)
    columns = []
    for row in table:
        for k in row:
            if k not in columns:
                columns.append(k)
    csv_path = out_dir / "summary.csv"
    with atomic_output(csv_path) as tmp, open(tmp, "w", newline="") as fh:    # an old summary kept until complete
        w = csv.DictWriter(fh, fieldnames=columns)
        w.writeheader()
        for row in table:
            w.writerow({k: row.get(k, "") for k in columns})
    # the comparison figure is drawn by the presentation layer (vehicle.cli.drives) from these
    return {"sweep": str(path), "output_dir": str(out_dir), "summary_csv": str(csv_path), "plots": [],
            "finished_files": [str(f) for f in ok_files], "finished_labels": ok_labels,
            "cases": table, "failed": [r["case"] for r in table if r["status"] == "failed"]}
