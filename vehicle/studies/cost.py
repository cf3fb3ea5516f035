"""What a study will cost, said before it starts: the number of drives and an estimated wall time.

The estimate comes from this machine's measured drive rate (vehicle.numerics.drive_rate: integration
steps per second of wall and the set-up time of a drive with the model cached, recorded by every
completed run in this solver mode). Where nothing is recorded yet, a short probe drive of the study's
own scenario (PROBE_DISTANCE_M, in memory) measures it first; its compile is the one the study would
need anyway.

    per drive  = build_s + (simulated time / dt) / steps_per_s
    wall       = drives x per drive / (workers x efficiency)

with the parallel efficiency of sweeps on 2 workers (PARALLEL_EFFICIENCY, from benchmarks/sweep_scaling.py);
one worker: 1. It leaves out the compile of a cold cache (announced when it
happens) and process start-up. A rate measured at another machine load than now (a shared machine) is
said beside the estimate, with the factor the CPU shares suggest.

At a terminal (stdin a tty) a study estimated above CONFIRM_ABOVE_S asks
before it starts; `--yes` skips the question, and a study started by a script never asks.
"""
from __future__ import annotations

import logging
import os
import sys
import time
from dataclasses import dataclass

from hpsim.errors import UserInputError

from vehicle.numerics import drive_rate
from vehicle.scenario.schema import ScenarioSource
from vehicle.results.run import run_in_memory

LOG = logging.getLogger("hpsim")
PROBE_DISTANCE_M = 200.0        # long enough for a few blocks of output, short enough to cost a few seconds
PARALLEL_EFFICIENCY = 0.65      # per worker on 2 workers: benchmarks/sweep_scaling.py on a 2-core machine
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


def _probe(prepared) -> dict:
    """Measure the rate on a short drive of this scenario (in memory; records it like any run)."""
    src = prepared.source
    short = ScenarioSource(text=src.text, name=f"{src.name} (cost probe)", base_dir=src.base_dir,
                           data={**src.data, "distance": min(PROBE_DISTANCE_M, float(prepared.scenario.distance))})
    LOG.info(f"measuring this machine's drive rate on {short.data['distance']:.0f} m of the scenario "
             "(no drive recorded yet in this solver mode)")
    t0 = time.perf_counter()
    S = run_in_memory(short).final["summary"]
    setup_s = time.perf_counter() - t0 - S["wall_s"]
    mode = drive_rate.mode_of(prepared.scenario)
    drive_rate.record(mode, prepared.scenario.solver.dt, S["simulated_s"], S["wall_s"], setup_s)
    rate = drive_rate.read(mode)
    if rate is None:              # a cache that cannot be written: the probe's own numbers
        rate = {"steps_per_s": S["simulated_s"] / prepared.scenario.solver.dt / S["wall_s"], "build_s": setup_s}
    return rate


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
    total, basis = 0.0, ""
    for p in prepared:
        if id(p) not in known:
            one = per_drive(p, probe=probe)
            if one is None:
                return None
            known[id(p)] = one
        total += known[id(p)][0]
        basis = basis or known[id(p)][1]
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
