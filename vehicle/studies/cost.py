"""What a study will cost, said before it starts: the number of drives and an estimated wall time.

The estimate comes from this machine's drive rate in the study's solver mode (vehicle.numerics.drive_rate:
integration steps per second of wall, and the set-up of a drive with the model cached), recorded by every
completed run. Where nothing is recorded yet, a short probe drive of the study's own scenario measures it
first (`_probe`, in memory). The probe runs in the study's mode, so it compiles the model the drives need;
a case whose model differs (a value drawn off a file's zero shapes the compiled model) is compiled before
the study too (`compile_ahead`), once, instead of in every worker at once. The estimate says how long
these compiles took.

    per drive  = build_s + (simulated time / dt) / steps_per_s
    wall       = drives x per drive / (workers x efficiency)

PARALLEL_EFFICIENCY is the sweeps' efficiency per worker on 2 workers of a 2-core machine; one worker: 1.
Process start-up is left out. A rate measured at another machine load than now is said beside the
estimate, with the factor the CPU shares suggest. At a terminal a study estimated above CONFIRM_ABOVE_S
asks before it starts; `--yes` skips the question, and a study started by a script never asks.
"""
from __future__ import annotations

import logging
import math
import os
import sys
import time
from dataclasses import dataclass

from hpsim.errors import UserInputError

from vehicle.engines.time_parallel import MIN_SEGMENT_S
from vehicle.numerics import compile_time, drive_rate
from vehicle.scenario.schema import MULTISCALE_MIN_WINDOWS, MULTISCALE_RANGES_M, ScenarioSource, prepare
from vehicle.scenario.settings import resolve_segments
from vehicle.results.run import run_in_memory

LOG = logging.getLogger("hpsim")
PROBE_DISTANCE_M = 200.0        # long enough for a few blocks of output, short enough to cost a few seconds
#                                 (full and time-parallel modes; multiscale: `_probe_data`)
PARALLEL_EFFICIENCY = 0.65      # per worker on 2 workers of a 2-core machine (benchmarks/sweep_scaling.py)
SEGMENT_MARGIN = 1.25           # a time-parallel probe's segments: this much longer than the shortest allowed,
#                                 as a varying speed makes some shorter than the mean
CONFIRM_ABOVE_S = 300.0         # five minutes: longer than a user at a terminal waits without having been told


@dataclass
class Estimate:
    drives: int
    workers: int
    per_drive_s: float           # one drive of the scenario, set-up included
    wall_s: float                # all of them, on the workers
    basis: str                   # where the rate came from, for the message

    def line(self, what: str) -> str:
        return (f"{what}: {self.drives} drives on {self.workers} worker{'s' if self.workers > 1 else ''}, "
                f"estimated {format_duration(self.wall_s)} wall ({format_duration(self.per_drive_s)} per drive, "
                f"{self.basis})")


def format_duration(seconds: float) -> str:
    """'42 s', '3.5 min', '1 h 10 min'."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 3600:
        return f"{seconds / 60:.1f} min"
    h, m = divmod(round(seconds / 60), 60)
    return f"{h} h {m} min"


def _probe_data(prepared) -> dict:
    """The scenario data of the probe drive: PROBE_DISTANCE_M of the scenario. A time-parallel scenario gets
    long enough segments; a multiscale one keeps its windows and warm-ups, back to back, MULTISCALE_MIN_WINDOWS
    of them (the fewest the mode accepts)."""
    S = prepared.scenario
    data = dict(prepared.source.data)
    segments = resolve_segments(S.solver.time_parallel)
    if segments > 1:            # each time-parallel segment at least MIN_SEGMENT_S of driving, with a margin
        mean_speed_m_s = float(S.distance) / prepared.duration_s()
        segments_m = SEGMENT_MARGIN * segments * MIN_SEGMENT_S * mean_speed_m_s
        data["distance"] = min(max(PROBE_DISTANCE_M, segments_m), float(S.distance))
        return data
    if drive_rate.mode_of(S) != "multiscale":
        data["distance"] = min(PROBE_DISTANCE_M, float(S.distance))
        return data
    stride_m = S.solver.window_m + S.solver.warm_up_m
    data["distance"] = min(MULTISCALE_MIN_WINDOWS * stride_m, float(S.distance))
    data["solver"] = {**(data.get("solver") or {}), "spacing": f"{max(stride_m, MULTISCALE_RANGES_M['spacing'][0])} m"}
    return data


def windowed_fraction(scenario) -> float:
    """The share of a drive's road the full model integrates: 1 in the full and time-parallel modes; in the
    multiscale mode its windows with their warm-ups, ceil(distance / spacing) of them, over the distance."""
    if drive_rate.mode_of(scenario) != "multiscale":
        return 1.0
    solver, distance = scenario.solver, float(scenario.distance)
    windows = math.ceil(distance / solver.spacing_m - 1e-9)
    return min(1.0, windows * (solver.window_m + solver.warm_up_m) / distance)


def _probe(prepared) -> dict:
    """Measure the rate on a short drive of this scenario (in memory) and record it for its solver mode.

    The probe compiles the model the study's drives need (it runs in the same mode). A multiscale rate (steps of the whole drive per second) is the probe's rate on its
    windows times the share of the real drive that is windowed (`windowed_fraction`)."""
    short = _probe_source(prepared)
    short_prepared = prepare(short)
    LOG.info(f"measuring this machine's drive rate on {float(short_prepared.scenario.distance):.0f} m of the scenario "
             "(no drive recorded yet in this solver mode)")
    t0 = time.perf_counter()
    compiled_before = compile_time.compiled_s
    S = run_in_memory(short).final["summary"]
    compile_s = compile_time.compiled_s - compiled_before
    setup_s = time.perf_counter() - t0 - S["wall_s"]
    scale = windowed_fraction(short_prepared.scenario) / windowed_fraction(prepared.scenario)
    mode, dt = drive_rate.mode_of(prepared.scenario), prepared.scenario.solver.dt
    drive_rate.record(mode, dt, S["simulated_s"] * scale, S["wall_s"], setup_s)
    rate = drive_rate.read(mode)
    if rate is None:              # a cache that cannot be written: the probe's own numbers
        rate = {"steps_per_s": S["simulated_s"] * scale / dt / S["wall_s"], "build_s": max(setup_s - compile_s, 0.0)}
    return {**rate, "probe_compile_s": compile_s}


def _probe_source(prepared) -> ScenarioSource:
    return ScenarioSource(text=prepared.source.text, name=f"{prepared.source.name} (cost probe)",
                          base_dir=prepared.source.base_dir, data=_probe_data(prepared))


def compile_ahead(prepared) -> float:
    """Build the engine of a short stretch of this scenario, so that its compiled model is in the cache before
    the study's workers start (each would compile a missing one at once); the compiler's seconds it took."""
    from vehicle.engines.build import build_engine

    before = compile_time.compiled_s
    build_engine(prepare(_probe_source(prepared)))
    return compile_time.compiled_s - before


def per_drive(prepared, *, probe: bool = True) -> tuple[float, str] | None:
    """(seconds, basis) of one drive of the prepared scenario (vehicle.scenario.schema.Prepared), set-up
    included; None when no rate is recorded in its solver mode and probe is False."""
    mode = drive_rate.mode_of(prepared.scenario)
    rate = drive_rate.read(mode)
    basis = f"{mode} mode"
    if rate is None:
        if not probe:
            return None
        rate = _probe(prepared)
        basis += ", rate measured now on a probe drive"
        if rate["probe_compile_s"] > 0:
            basis += f" (which compiled the model in {format_duration(rate['probe_compile_s'])})"
    simulated_s = prepared.settings().speed.statistics(float(prepared.scenario.distance))["duration_s"]
    steps = simulated_s / prepared.scenario.solver.dt
    basis += (f": {steps:.3g} steps at {float(rate['steps_per_s']):.3g} steps/s measured on this machine "
              f"+ {float(rate['build_s']):.1f} s set-up and summary" + _load_note(rate))
    return float(rate["build_s"]) + steps / float(rate["steps_per_s"]), basis


def _load_note(rate: dict) -> str:
    """A word when the machine is much busier (or idler) now than when the rate was measured."""
    then, now = rate.get("load"), drive_rate.load_average()
    cpus = os.cpu_count() or 1
    if then is None or now is None:
        return ""
    # the share of a CPU a process gets, roughly: 1 while the load is under the CPU count, cpus / load above
    share_then, share_now = min(1.0, cpus / max(then, 1e-9)), min(1.0, cpus / max(now, 1e-9))
    if not 0.67 < share_now / share_then < 1.5:
        return (f"; the machine's load is {now:.1f} on {cpus} CPUs now, {then:.1f} when the rate was measured: "
                f"expect about {share_then / share_now:.1f}x this")
    return ""


def estimate(prepared: list, workers: int | None, *, probe: bool = True, cluster: bool = False) -> Estimate | None:
    """The cost of one drive of each prepared scenario (a study's cases) on `workers` local processes (None:
    one per CPU); None when there is nothing to run, or no rate is recorded and probe is False. cluster: the
    drives go to a Dask cluster of unknown size: the serial time, said so."""
    if not prepared:
        return None
    known: dict[int, tuple[float, str]] = {}        # cases that share a scenario object are estimated once
    total, basis, compiled_s = 0.0, "", 0.0
    for p in prepared:
        if id(p) not in known:
            one = per_drive(p, probe=probe)
            if one is None:
                return None
            if known and probe:                       # another case's model: compiled now, if it is new
                compiled_s += compile_ahead(p)
            known[id(p)] = one
        total += known[id(p)][0]
        basis = basis or known[id(p)][1]
    if compiled_s > 0:
        basis += f"; the drawn cases' model compiled now in {format_duration(compiled_s)}"
    n = len(prepared)
    if cluster:
        workers = 1
        basis += "; serial time on this machine: the cluster divides it by its workers"
    w = max(1, min(workers or os.cpu_count() or 1, n))
    wall = total / (w * (PARALLEL_EFFICIENCY if w > 1 else 1.0))
    if w > 1:
        basis += f", {PARALLEL_EFFICIENCY:g} parallel efficiency"
    return Estimate(n, w, total / n, wall, basis)


def confirm(est: Estimate | None, what: str, yes: bool, *, stdin=None, stderr=None) -> None:
    """Say what the study costs (INFO); at a terminal, above CONFIRM_ABOVE_S and without --yes, ask first.
    A refusal (or no answer) is a UserInputError: nothing was started."""
    stdin = stdin or sys.stdin
    stderr = stderr or sys.stderr
    if est is None:
        return
    LOG.info(est.line(what))
    if yes or est.wall_s <= CONFIRM_ABOVE_S or not _is_tty(stdin):
        return
    stderr.write(f"{what}: start {est.drives} drives, about {format_duration(est.wall_s)}? [y/N] (--yes: do not ask) ")
    stderr.flush()
    answer = stdin.readline().strip().lower()
    if answer not in ("y", "yes"):
        raise UserInputError(f"not started ({est.drives} drives, estimated {format_duration(est.wall_s)}); "
                             "give --yes to start without asking, or fewer samples / cases / a shorter --distance")


def _is_tty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
