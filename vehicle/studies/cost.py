"""What a study will cost, said before it starts: the number of drives and an estimated wall time of the whole
command, from its start to its end.

    wall       = before + drives + finish
    before     = the command's start-up + the compiles its cases need + the rate probe (all measured: they are
                 done when the estimate is said)
    per drive  = set-up + (integrated simulated time / dt) / steps_per_s   (multiscale: its windows' time)
    drives     = the jobs on the workers: sum(jobs) / (workers x efficiency), at least the longest job;
                 a job is one drive, or a lockstep group of ensemble lanes (the lanes' set-ups one after the
                 other, then lanes x one drive's steps / LANE_GAIN)
    finish     = the tables and figures after the last drive (recorded per command, FINISH_DEFAULT_S before)

The rate is this machine's in the study's solver mode (vehicle.numerics.drive_rate: integration steps per second
of wall, and a drive's set-up with the model cached), recorded by every completed run. Before anything is driven
the libraries the cases need are built (`compile_ahead`: once, here, instead of in every worker at once): an
engine on a short stretch, and the lane library when the study runs ensemble lanes, once per model structure, step
and lanes (`library_key`: designs that differ in parameter values share them). The nominal case of a UQ study
usually has another model than its draws (a file's zero switches a mechanism off, hpsim.parameters), so a study
on an empty cache compiles two. Where no rate is recorded, a short probe drive of the study's own scenario then
measures it (`_probe`, in memory, its model compiled already). The estimate says how many libraries were compiled
and how long that took.

PARALLEL_EFFICIENCY is the sweeps' efficiency per worker on 2 workers of a 2-core machine; one worker: 1. A rate
measured at another machine load than now is said beside the estimate, with the factor the CPU shares suggest.
At a terminal a study whose remaining time is estimated above CONFIRM_ABOVE_S asks before it starts; `--yes`
skips the question, and a study started by a script never asks.
"""
from __future__ import annotations

import json
import logging
import math
import os
import sys
import time
from dataclasses import dataclass, field

from hpsim.errors import SimulationError, UserInputError

from vehicle.engines.build import engine_name
from vehicle.engines.ensemble import eligible, group_size
from vehicle.engines.multiscale import integrated_time_s
from vehicle.engines.time_parallel import MIN_SEGMENT_S
from vehicle.numerics import compile_time, drive_rate
from vehicle.scenario.schema import MULTISCALE_MIN_WINDOWS, MULTISCALE_RANGES_M, ScenarioSource, prepare
from vehicle.scenario.settings import resolve_segments, resolve_time_parallel_lanes
from vehicle.results.run import run_in_memory

LOG = logging.getLogger("hpsim")
PROBE_DISTANCE_M = 200.0        # long enough for a few blocks of output, short enough to cost a few seconds
#                                 (full and time-parallel modes; multiscale: `_probe_data`)
PARALLEL_EFFICIENCY = 0.65      # per worker on 2 workers of a 2-core machine (benchmarks/sweep_scaling.py)
SEGMENT_MARGIN = 1.25           # a time-parallel probe's segments: this much longer than the shortest allowed,
#                                 as a varying speed makes some shorter than the mean
CONFIRM_ABOVE_S = 300.0         # five minutes: longer than a user at a terminal waits without having been told
# a lane of a lockstep group costs a drive's steps divided by this: the CPU the lanes save (docs/engines.md,
# "Segments on the lane library"); a masked lane costs as much as a used one
LANE_GAIN = 2.3
# a multiscale drive's rate counts the work between its windows with their steps, and the lanes speed up only the
# windows' integration: the gain that, with a drive's recorded set-up, gives the CPU a generation of them saves on
# lanes (benchmarks/ensemble_multiscale.py, 40 designs of the 106 km drive: lanes / one by one 0.69 of the CPU with
# 0.7 s set-up and 2.4 s of windows recorded per drive: (0.7 + 2.4 / g) / 3.1 = 0.69)
MULTISCALE_LANE_GAIN = 1.67
# the tables and figures after a study's last drive, until this machine has recorded its own (FINISH_RECORD):
# assumed, the order of what benchmarks/preview_accuracy.py measures on an idle 2-core machine
FINISH_DEFAULT_S = {"hpsim uq": 6.0, "hpsim sweep": 3.0, "hpsim optimize": 3.0}
FINISH_KEY = "after the drives: "        # + the command, its entry in the drive-rate record


@dataclass(frozen=True)
class DriveCost:
    """One drive of a case, alone on a worker: its set-up (reading, checks, road, model, equilibria, file,
    summary) and its integration at the recorded rate [s]."""

    set_up_s: float
    steps_s: float
    lane_gain: float = LANE_GAIN      # how much less its steps cost on a lane

    @property
    def alone_s(self) -> float:
        return self.set_up_s + self.steps_s


@dataclass(frozen=True)
class Compiles:
    """What the command compiled before its drives (the preview's compiles and any before it, e.g. a check's short
    drive): libraries, the distinct models they belong to, their time [s] (the preview's: C generated, compiled,
    loaded; before it: the compiler's), and how many engines the preview built for them (one per `library_key`)."""

    libraries: int = 0
    models: int = 0
    seconds: float = 0.0
    looked: bool = True          # False: a listing, which compiles nothing and does not look
    engine_builds: int = 0       # engines the preview built to have their libraries in the cache (`compile_ahead`)

    def describe(self) -> str:
        if not self.looked:
            return "any compile the cache lacks not included"
        if self.libraries == 0:
            return "nothing compiled (the cache holds every model)"
        return (f"{self.libraries} librar{'ies' if self.libraries > 1 else 'y'} of {self.models} "
                f"model{'s' if self.models != 1 else ''} compiled before the drives in {format_duration(self.seconds)} "
                "(first run only)")


@dataclass
class Estimate:
    drives: int
    workers: int
    per_drive_s: float           # one drive of the scenario alone, set-up included
    wall_s: float                # the whole command: before + drives + finish
    basis: str                   # where the rate came from, for the message
    before_s: float = 0.0        # start-up, compiles and probe, done when the estimate is said
    drives_s: float = 0.0        # all the drives, on the workers
    finish_s: float = 0.0        # tables and figures after the last drive
    compiles: Compiles = field(default_factory=Compiles)
    lanes: int = 1               # ensemble lanes of a lockstep group (1: each drive alone)

    @property
    def remaining_s(self) -> float:
        """What is still to come when the estimate is said."""
        return self.drives_s + self.finish_s

    def line(self, what: str) -> str:
        lanes = f" in lockstep groups on {self.lanes} ensemble lanes" if self.lanes > 1 else ""
        return (f"{what}: {self.drives} drives on {self.workers} worker{'s' if self.workers > 1 else ''}{lanes}, "
                f"estimated {format_duration(self.wall_s)} wall ({format_duration(self.per_drive_s)} per drive, "
                f"{self.basis}; {format_duration(self.before_s)} before the drives: {self.compiles.describe()}; "
                f"the drives {format_duration(self.drives_s)}, then {format_duration(self.finish_s)} of tables and "
                "figures)")


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
    workers = resolve_segments(S.solver.time_parallel)
    if workers > 1:             # each time-parallel segment at least MIN_SEGMENT_S of driving, with a margin; the
        #                         study's lanes per process (its lane library), not fewer fitted to the short drive
        lanes = resolve_time_parallel_lanes(S.solver.time_parallel_lanes, workers, prepared.duration_s(), MIN_SEGMENT_S)
        mean_speed_m_s = float(S.distance) / prepared.duration_s()
        segments_m = SEGMENT_MARGIN * workers * lanes * MIN_SEGMENT_S * mean_speed_m_s
        data["distance"] = min(max(PROBE_DISTANCE_M, segments_m), float(S.distance))
        data["solver"] = {**(data.get("solver") or {}), "time_parallel_lanes": lanes}
        return data
    if drive_rate.mode_of(S) != "multiscale":
        data["distance"] = min(PROBE_DISTANCE_M, float(S.distance))
        return data
    stride_m = S.solver.window_m + S.solver.warm_up_m
    data["distance"] = min(MULTISCALE_MIN_WINDOWS * stride_m, float(S.distance))
    data["solver"] = {**(data.get("solver") or {}), "spacing": f"{max(stride_m, MULTISCALE_RANGES_M['spacing'][0])} m"}
    return data


def integrated_s(prepared) -> float:
    """The simulated time [s] a drive of the prepared scenario integrates: the whole drive in the full and
    time-parallel modes; in the multiscale mode its windows with their warm-ups (`integrated_time_s`)."""
    settings = prepared.settings()
    if drive_rate.mode_of(prepared.scenario) == "multiscale":
        return integrated_time_s(settings, prepared.scenario.solver.multiscale_settings())
    return settings.speed.statistics(float(prepared.scenario.distance))["duration_s"]


def rate_mode(prepared) -> str:
    """The drive-rate record's key of a prepared scenario (`drive_rate.mode_of`), "full" for a time-parallel one too
    short for two segments, which drives as a full drive (vehicle.engines.build.engine_name)."""
    return "full" if engine_name(prepared) == "full" else drive_rate.mode_of(prepared.scenario)


def _probe(prepared) -> dict:
    """Measure the rate on a short drive of this scenario (in memory) and record it for its solver mode; its model
    is compiled already (`compile_ahead`), so its set-up is a drive's with the cache warm. The rate counts the steps
    the probe integrates (`integrated_s`: a multiscale probe's windows)."""
    short = _probe_source(prepared)
    short_prepared = prepare(short)
    LOG.info(f"measuring this machine's drive rate on {float(short_prepared.scenario.distance):.0f} m of the scenario "
             "(no drive recorded yet in this solver mode)")
    t0 = time.perf_counter()
    compiled_before = compile_time.compiled_s
    S = run_in_memory(short).final["summary"]
    compile_s = compile_time.compiled_s - compiled_before
    setup_s = time.perf_counter() - t0 - S["wall_s"]
    integrated = integrated_s(short_prepared)
    mode, dt = rate_mode(prepared), prepared.scenario.solver.dt
    drive_rate.record(mode, dt, integrated, S["wall_s"], setup_s, compiled_s=compile_s, fresh=True)
    rate = drive_rate.read(mode)
    if rate is None:              # a cache that cannot be written: the probe's own numbers
        rate = {"steps_per_s": integrated / dt / S["wall_s"], "build_s": max(setup_s - compile_s, 0.0)}
    return rate


def _probe_source(prepared) -> ScenarioSource:
    return ScenarioSource(text=prepared.source.text, name=f"{prepared.source.name} (cost probe)",
                          base_dir=prepared.source.base_dir, data=_probe_data(prepared))


def library_key(prepared, lanes: int = 1) -> str:
    """What the libraries `compile_ahead` builds for a case are made from: vehicle.numerics.codegen keys each by the
    model's structure (`VehicleModel.structure`: not its parameter values), the step, the block shape and the lanes,
    which the probe scenario's solver and output settings and `lanes` determine. Cases with equal keys need the
    same libraries (a study's designs that differ in parameter values only)."""
    S, probe = prepared.scenario, _probe_data(prepared)
    settings = [probe.get("solver"), probe.get("output"), S.solver.model_dump(mode="json"),
                S.output.model_dump(mode="json"), int(lanes)]
    return prepared.model().structure + json.dumps(settings, sort_keys=True, default=str)


def compile_ahead(prepared, lanes: int = 1) -> int:
    """Build the engine of a short stretch of this scenario, and its lane library when the study runs `lanes` > 1
    ensemble lanes, so that the compiled model is in the cache before the study's workers start (each would
    compile a missing one at once); the number of libraries compiled."""
    from vehicle.engines.build import build_engine
    from vehicle.engines.ensemble import lane_stepper

    before = compile_time.compiled_libraries
    short = prepare(_probe_source(prepared))
    model, _ = build_engine(short)
    if lanes > 1:
        lane_stepper(model, float(short.scenario.solver.dt), lanes)
    return compile_time.compiled_libraries - before


def per_drive(prepared, *, probe: bool = True) -> tuple[DriveCost, str] | None:
    """(cost, basis) of one drive of the prepared scenario (vehicle.scenario.schema.Prepared) alone; None when no
    rate is recorded in its solver mode and probe is False."""
    mode = rate_mode(prepared)
    rate = drive_rate.read(mode)
    basis = f"{mode} mode"
    if rate is None:
        if not probe:
            return None
        rate = _probe(prepared)
        basis += ", rate measured now on a probe drive"
    steps = integrated_s(prepared) / prepared.scenario.solver.dt
    of_windows = " of its windows" if mode == "multiscale" else ""
    basis += (f": {steps:.3g} steps{of_windows} at {float(rate['steps_per_s']):.3g} steps/s measured on this machine "
              f"+ {float(rate['build_s']):.1f} s set-up and summary" + _load_note(rate))
    gain = MULTISCALE_LANE_GAIN if mode == "multiscale" else LANE_GAIN
    return DriveCost(float(rate["build_s"]), steps / float(rate["steps_per_s"]), gain), basis


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


def lane_count(lanes: int) -> int:
    """The lanes of the compiled lane library for a group of `lanes`: a power of two (vehicle.engines.ensemble)."""
    return 1 if lanes <= 1 else 1 << (int(lanes) - 1).bit_length()


def drives_wall(costs: list[DriveCost], workers: int, *, lanes: int = 1, group: int = 1,
                joins: list[bool] | None = None) -> float:
    """Wall time [s] of the drives `costs` on `workers` local processes. With lanes > 1 the drives that `joins`
    run in lockstep groups of `group` on a library of `lanes` lanes, the others alone (vehicle.engines.ensemble);
    a group's lanes set up one after the other and step together (each drive's lane_gain)."""
    joins = joins if joins is not None else [True] * len(costs)
    together = [c for c, ok in zip(costs, joins) if ok] if lanes > 1 else []
    jobs = [c.alone_s for c, ok in zip(costs, joins) if not (ok and lanes > 1)]
    for g in range(0, len(together), max(1, group)):
        chunk = together[g: g + max(1, group)]
        jobs.append(sum(c.set_up_s for c in chunk) + lanes * max(c.steps_s / c.lane_gain for c in chunk))
    if not jobs:
        return 0.0
    w = max(1, min(workers, len(jobs)))
    return max(sum(jobs) / (w * (PARALLEL_EFFICIENCY if w > 1 else 1.0)), max(jobs))


def finish_s(what: str) -> tuple[float, bool]:
    """(seconds of tables and figures after a study's last drive, recorded on this machine) for a command."""
    try:
        value = float(drive_rate.read_entry(FINISH_KEY + what))
        if math.isfinite(value) and value >= 0:
            return value, True
    except (ValueError, TypeError):
        pass
    return FINISH_DEFAULT_S.get(what, 3.0), False


def record_finish(what: str, seconds: float) -> None:
    """Keep how long a study's tables and figures took (best effort, beside the drive rates)."""
    if math.isfinite(seconds) and seconds >= 0:
        drive_rate.record_entry(FINISH_KEY + what, seconds)


def estimate(prepared: list, workers: int | None, *, probe: bool = True, cluster: bool = False,
             ensemble: int | None = 1, elapsed_s: float = 0.0, what: str = "hpsim uq") -> Estimate | None:
    """The cost of one drive of each prepared scenario (a study's cases) on `workers` local processes (None:
    one per CPU); None when there is nothing to run, or no rate is recorded and probe is False. probe: compile
    what the cases need and measure a missing rate now. cluster: the drives go to a Dask cluster of unknown
    size: the serial time, said so. ensemble: the study's --ensemble (None: chosen as the study chooses it).
    elapsed_s: the command's time before this call, counted in the estimate's wall."""
    if not prepared:
        return None
    t0 = time.perf_counter()
    n = len(prepared)
    joins = [eligible(p.source.data) for p in prepared]
    lanes, group = group_size(ensemble, sum(joins), 1 if cluster else workers)
    lanes = lane_count(lanes) if not cluster else 1
    known: dict[int, tuple[DriveCost, str]] = {}        # cases that share a scenario object are estimated once
    # what the command compiled before this call (e.g. a check's short drive), then what the preview compiles
    libraries, compile_wall, basis = compile_time.compiled_libraries, compile_time.compiled_s, ""
    models = int(libraries > 0)
    in_cache: set[str] = set()                          # `library_key`s whose engine was built here
    for p, joined in zip(prepared, joins):
        if id(p) in known:
            continue
        try:
            key = library_key(p, lanes if joined else 1) if probe else None
            if probe and key not in in_cache:            # its model (and lane library), if the cache lacks it
                c0 = time.perf_counter()
                built = compile_ahead(p, lanes if joined else 1)
                in_cache.add(key)
                libraries, models = libraries + built, models + (built > 0)
                compile_wall += time.perf_counter() - c0 if built else 0.0
            one = per_drive(p, probe=probe)
        except (UserInputError, SimulationError) as exc:   # the case fails when it runs, the others still run
            LOG.info(f"{what}: {p.source.name}: not in the estimate ({exc})")
            continue
        if one is None:
            return None
        known[id(p)] = one
        basis = basis or one[1]
    if not known:
        return None
    typical = next(iter(known.values()))[0]              # a case that cannot be built: costed as the first that can
    costs = [known[id(p)][0] if id(p) in known else typical for p in prepared]
    if cluster:
        basis += "; serial time on this machine: the cluster divides it by its workers"
    w = 1 if cluster else max(1, min(workers or os.cpu_count() or 1, n))
    drives = drives_wall(costs, w, lanes=lanes, group=group, joins=joins)
    if w > 1:
        basis += f", {PARALLEL_EFFICIENCY:g} parallel efficiency"
    finish, recorded = finish_s(what)
    basis += "" if recorded else ", the tables' and figures' time assumed (none recorded yet)"
    before = elapsed_s + time.perf_counter() - t0
    return Estimate(n, w, sum(c.alone_s for c in costs) / n, before + drives + finish, basis, before_s=before,
                    drives_s=drives, finish_s=finish, lanes=lanes,
                    compiles=Compiles(libraries, models, compile_wall, looked=probe, engine_builds=len(in_cache)))


def confirm(est: Estimate | None, what: str, yes: bool, *, stdin=None, stderr=None) -> None:
    """Say what the study costs (INFO); at a terminal, above CONFIRM_ABOVE_S and without --yes, ask first.
    A refusal (or no answer) is a UserInputError: nothing was started."""
    stdin = stdin or sys.stdin
    stderr = stderr or sys.stderr
    if est is None:
        return
    LOG.info(est.line(what))
    if yes or est.remaining_s <= CONFIRM_ABOVE_S or not _is_tty(stdin):
        return
    stderr.write(f"{what}: start {est.drives} drives, about {format_duration(est.remaining_s)}? [y/N] (--yes: do not ask) ")
    stderr.flush()
    answer = stdin.readline().strip().lower()
    if answer not in ("y", "yes"):
        raise UserInputError(f"not started ({est.drives} drives, estimated {format_duration(est.remaining_s)}); "
                             "give --yes to start without asking, or fewer samples / cases / a shorter --distance")


def _is_tty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False
