"""The ensemble engine: many full-fidelity drives of one model structure stepping in lockstep.

K cases (different parameter values, roads, speeds, initial temperatures, distances) run as K ordinary
drives, each in its own thread with its own results file, checkpoints and resume (`vehicle.results.run`,
unchanged): only the integration is shared. Each drive's solver is a `LaneSolver`, one lane of a
`LockstepGroup`: its `advance` hands the block's start, inputs and parameters to the group and waits. When
every lane still running has handed in its block, one call of the compiled lane block function
(`vehicle.numerics.lanes.LaneStepper`, every operation on all K lanes in one vector instruction) integrates
them all, and each drive goes on with its own states (outputs, statistics, checks, sink) in Python.

- A lane whose drive ends (its distance reached), fails (non-finite or unphysical states: the drive's own
  checks raise, its file records the failure as for a single run) or is interrupted leaves the group; the
  others go on. Its slot in the vector is then filled with another lane's data and the result discarded
  (masked). A lane's NaN never reaches another lane: the lanes share no operation.
- A case whose model structure, step or block shape differs from the group's runs on the scalar engine
  (same thread, not in lockstep), as does each drive's step-doubling error probe.
- Only plain full-fidelity drives join (solver.mode full, no time-parallel segments): `eligible`.

`run_lockstep(fn, items, lanes)` runs fn(*args, make_solver=...) for each (tag, args) in one group (the per-case
function of `hpsim sweep` / `hpsim uq`, which passes the lane's solver factory down to `build_engine`);
`grouped_jobs` turns a study's job list into such groups.
"""
from __future__ import annotations

import signal
import threading
import time
import traceback
import warnings
from dataclasses import replace
from typing import Callable

import numpy as np

from hpsim.errors import UserInputError

from vehicle.numerics.compiler_processes import kill_running_compilers
from vehicle.numerics.contract import SolverCapabilities
from vehicle.numerics.lanes import ISAS, LaneStepper, default_lanes
from vehicle.scenario.settings import resolve_segments
from vehicle.engines.choice import engine_for
from vehicle.numerics.solvers import Ros2

LANE_ENGINES = ("full", "multiscale")      # the engines whose drives step with a lane's solver (`eligible`)
_STEPPERS: dict = {}         # compiled lane block functions of this process by (structure, dt, lanes, isa)
_STEPPERS_LOCK = threading.Lock()
# one lane at a time runs its Python and CasADi work (building models, equilibria, weighing bands, outputs): CasADi's
# symbolic operations release the GIL and are not thread-safe (two lanes building graphs at once crashed in
# casadi.jacobian). A lane gives the lock up only while it waits for the group's block call (`submit`).
LANE_LOCK = threading.Lock()


def lane_stepper(model, dt: float, lanes: int, isa: str | None = None) -> LaneStepper:
    """The compiled lane block function for this model structure (built once per process, cached on disk)."""
    lanes = 1 << max(0, int(lanes) - 1).bit_length()      # a vector holds a power of two: 3 cases -> 4 lanes
    key = (model.structure, float(dt), lanes, isa)
    with _STEPPERS_LOCK:
        if key not in _STEPPERS:
            _STEPPERS[key] = LaneStepper(Ros2(dt), model, lanes, isa=isa)
        return _STEPPERS[key]


class LockstepGroup:
    """`lanes` drives integrated together (see the module docstring). Slots 0..lanes-1; a slot is 'waiting to
    start' until its drive binds or its thread ends, then 'in' (it hands in every block) until it leaves."""

    def __init__(self, lanes: int, *, isa: str | None = None):
        self.lanes, self.isa = int(lanes), isa
        self.cond = threading.Condition()
        self.present = set(range(self.lanes))       # slots that will (or may still) hand in blocks
        self.pending: dict[int, tuple] = {}
        self.results: dict[int, np.ndarray] = {}
        self.key = None                              # (structure, dt, K, M) of the group's block function
        self.stepper = None
        self.generation = 0
        self.stop = False
        self.error: BaseException | None = None
        self.calls = 0
        self.lane_blocks = 0                         # blocks integrated for lanes in the group (not fillers)
        self.integration_s = 0.0

    # --- membership -----------------------------------------------------------------------------
    def join(self, slot: int, model, dt: float, K: int, M: int) -> bool:
        """A lane's drive binds: True when it steps in the group, False when it must run on its own (another
        structure or block shape than the group's; it then leaves)."""
        key = (model.structure, float(dt), int(K), int(M))
        with self.cond:
            if self.key is None:
                self.key = key
            same = key == self.key
        if not same:
            self.leave(slot)
            return False
        try:
            stepper = lane_stepper(model, dt, self.lanes, self.isa)      # compiled outside the group's lock
        except RuntimeError as exc:          # no compiler, or it failed: this lane runs on the scalar engine
            warnings.warn(f"ensemble: {exc}; the drive runs on the scalar engine")
            self.leave(slot)
            return False
        with self.cond:
            self.stepper = stepper
        return True

    def leave(self, slot: int) -> None:
        with self.cond:
            self.present.discard(slot)
            self.pending.pop(slot, None)
            self._run_if_ready()

    def request_stop(self) -> None:
        """Ctrl-C: every lane stops at its next block (its drive then records an interrupted, resumable file)."""
        with self.cond:
            self.stop = True
            self.cond.notify_all()

    # --- the lockstep call ----------------------------------------------------------------------------
    def submit(self, slot: int, z0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        """Hand in one block of lane `slot`; returns its states at the M samples (nz, M). The lane's LANE_LOCK is
        given up while it waits, so that the other lanes can reach the call."""
        LANE_LOCK.release()
        try:
            return self._submit(slot, z0, U, p)
        finally:
            LANE_LOCK.acquire()

    def _submit(self, slot: int, z0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        with self.cond:
            if self.stop:
                raise KeyboardInterrupt
            self.pending[slot] = (z0, U, p)
            gen = self.generation
            self._run_if_ready()
            self.cond.wait_for(lambda: self.generation != gen or self.stop or self.error is not None)
            if self.error is not None and slot not in self.results:
                raise RuntimeError(f"the ensemble's block function failed: {self.error}")
            if slot not in self.results:
                raise KeyboardInterrupt
            return self.results.pop(slot)

    def _run_if_ready(self) -> None:
        """(With the lock held.) Integrate when every present lane has handed in its block."""
        if not self.pending or set(self.pending) != self.present:
            return
        _, dt, K, M = self.key
        slots = sorted(self.pending)
        filler = self.pending[slots[0]]
        blocks = [self.pending.get(s, filler) for s in range(self.stepper.lanes)]   # absent lanes: masked copies
        try:
            t0 = time.perf_counter()
            Z = self.stepper.advance(np.stack([b[0] for b in blocks], 1), np.stack([b[1].T for b in blocks], 2),
                                     np.stack([b[2] for b in blocks], 1), K, M)
            self.integration_s += time.perf_counter() - t0
        except Exception as exc:          # a bug: every lane fails with it rather than waiting forever
            self.error = exc
        else:
            for s in slots:
                self.results[s] = Z[:, :, s].T.copy()
            self.calls += 1
            self.lane_blocks += len(slots)
        self.pending.clear()
        self.generation += 1
        self.cond.notify_all()


class LaneSolver(Ros2):
    """One drive's view of a `LockstepGroup`: the `Ros2` interface (bind, advance, memory), the block integrated
    with the other lanes. Refined solvers (the error probe) are the scalar `Ros2`."""

    def __init__(self, dt: float, group: LockstepGroup, slot: int):
        super().__init__(dt)
        self.group, self.slot = group, slot
        self.in_group = False

    @property
    def capabilities(self) -> SolverCapabilities:
        """Ros2's, and bound to its lane's thread: its block waits for the other lanes under LANE_LOCK."""
        return replace(super().capabilities, thread_bound=True)

    def block_graph(self, model, steps_per_sample, samples_per_call):
        return None                      # nothing for the scalar block compiler: the lanes' library serves

    def refined_solver(self, factor: int) -> Ros2:
        return Ros2(self.dt / factor)

    def bind(self, model, steps_per_sample: int, samples_per_call: int) -> "LaneSolver":
        t0 = time.perf_counter()
        self.in_group = self.group.join(self.slot, model, self.dt, steps_per_sample, samples_per_call)
        if not self.in_group:                # on its own: the scalar engine
            super().bind(model, steps_per_sample, samples_per_call)
            return self
        self.K, self.M = int(steps_per_sample), int(samples_per_call)
        self.nx, self.nmem = model.nx, model.n_memory
        self.memory = model.initial_memory()
        self.build_s = time.perf_counter() - t0
        return self

    def advance(self, x0: np.ndarray, U: np.ndarray, p: np.ndarray) -> np.ndarray:
        if not self.in_group:
            return super().advance(x0, U, p)
        Z = self.group.submit(self.slot, np.concatenate([x0, self.memory]), np.asarray(U, float),
                              np.asarray(p, float))
        self.memory_samples = Z[self.nx:]
        self.memory = Z[self.nx:, -1].copy()
        return Z[: self.nx]


def _lane(group: LockstepGroup, slot: int, fn: Callable[..., dict], args: tuple, out: dict, tag: str) -> None:
    LANE_LOCK.acquire()
    try:
        out[tag] = fn(*args, make_solver=lambda dt: LaneSolver(dt, group, slot))
    except KeyboardInterrupt:
        out[tag] = {"status": "interrupted", "error": "interrupted", "seconds": 0.0}
    except BaseException as exc:     # fn is meant not to raise; a bug fails this case only
        tb = traceback.format_exc().strip().splitlines()[-3:]
        out[tag] = {"status": "failed", "error": f"{type(exc).__name__}: {exc} ({' | '.join(tb)})", "seconds": 0.0}
    finally:
        group.leave(slot)
        LANE_LOCK.release()


def run_lockstep(fn: Callable[..., dict], items: list[tuple[str, tuple]], lanes: int | None = None,
                 isa: str | None = None) -> dict:
    """Run fn(*args, make_solver=...) for every (tag, args) of `items` (at most `lanes`), each in a thread whose
    drive is a lane of one `LockstepGroup`: make_solver(dt) is the lane's solver, which fn hands to the drives it
    builds (`build_engine(prepared, make_solver)`). Returns {"status": "done", "cases": {tag: fn's result},
    "lanes", "calls", "lane_blocks"}. A Ctrl-C (in the main thread) stops every lane at its next block (their
    files stay resumable)."""
    lanes = int(lanes or default_lanes(isa))
    if len(items) > lanes:
        raise ValueError(f"run_lockstep: {len(items)} cases for {lanes} lanes")
    group = LockstepGroup(lanes, isa=isa)
    for slot in range(len(items), lanes):
        group.present.discard(slot)
    out: dict = {}
    threads = [threading.Thread(target=_lane, args=(group, slot, fn, args, out, tag), daemon=True,
                                name=f"hpsim-lane-{slot}") for slot, (tag, args) in enumerate(items)]
    old = None
    if threading.current_thread() is threading.main_thread():
        old = signal.signal(signal.SIGINT, lambda *_: group.request_stop())
    try:
        for t in threads:
            t.start()
        for t in threads:
            while t.is_alive():
                t.join(0.2)
    except BaseException:
        # SIGTERM (or an error) in the main thread: a lane's thread may be waiting for a compiler, which runs in its
        # own session and would outlive this process; the lanes' threads are daemons and end with it
        kill_running_compilers()
        raise
    finally:
        if old is not None:
            signal.signal(signal.SIGINT, old)
    return {"status": "done", "cases": out, "lanes": lanes, "calls": group.calls, "lane_blocks": group.lane_blocks,
            "integration_s": group.integration_s, "seconds": 0.0}


def eligible(scenario_data: dict) -> bool:
    """A scenario mapping whose drive can be a lane: one the full or the multiscale engine runs (`choice.engine_for`:
    not in time-parallel segments, which make lanes of their own; solver.time_parallel "auto" counts one segment per
    CPU). A multiscale lane integrates its windows one after the other on the lane (no paired windows)."""
    solver = scenario_data.get("solver") or {}
    tp = solver.get("time_parallel")
    return engine_for(solver.get("mode"), resolve_segments(None if tp is False else tp)) in LANE_ENGINES


# The most lanes one lockstep group may have (`--ensemble K`): four vectors of the widest instruction set (AVX-512,
# 8 doubles). One vector's lanes step fastest per lane (docs/engines.md, "Vector lanes"; 8 lanes already gain little
# over 4), while the library's C, its compile time and memory grow with the lanes; beyond a few vectors a group only
# costs a longer compile and masks more lanes when its drives end apart.
MAX_LANES = 4 * max(width for _, width in ISAS.values())


def check_lanes(lanes: int | None, where: str = "--ensemble") -> None:
    """UserInputError unless `lanes` is None or an integer in [1, MAX_LANES]."""
    if lanes is not None and not 1 <= lanes <= MAX_LANES:
        raise UserInputError(f"{where}: must be in [1, {MAX_LANES}] lanes (1: off; {MAX_LANES} = four vectors of "
                             f"AVX-512, beyond which a group only compiles longer), got {lanes}")


def group_size(lanes: int | None, n_cases: int, workers: int | None) -> tuple[int, int]:
    """(lanes of the compiled library, cases per group) for `--ensemble` (None: chosen): given K, K and K.
    By default one vector's lanes when there are more cases than workers, the groups as full as the cases allow
    with every worker busy (a group of fewer cases than lanes leaves lanes masked: they cost as much as used
    ones), else 1 (each case on its own, the scalar engine). Lanes: one hardware vector (`default_lanes`: 8 with
    AVX-512, 4 with AVX2; benchmarks/ensemble.py)."""
    if lanes is not None:
        check_lanes(lanes)
        return int(lanes), int(lanes)
    import os

    n_lanes = default_lanes()
    w = max(1, workers or os.cpu_count() or 1)
    per_worker = -(-n_cases // w)
    if per_worker <= 1:
        return 1, 1
    return n_lanes, min(n_lanes, per_worker)


def grouped_jobs(fn: Callable[..., dict], jobs: list[tuple[str, tuple]], lanes: int | None, can_join: list[bool],
                 workers: int | None = None, durations: list[float] | None = None):
    """(function, jobs, unpack) for `vehicle.studies.sweep.execute`: the jobs that `can_join` in lockstep groups
    (`group_size`) run by `run_lockstep`, the others alone by `fn`; unpack(tag, result) -> [(case tag, result)].
    durations: each job's drive time [s]; given, the groups are formed in order of it (a lane whose drive ends
    first is masked, at the cost of a used lane, until the group's longest drive ends: cases of like duration
    share a group)."""
    lanes, size = group_size(lanes, sum(can_join), workers)
    if lanes <= 1:
        return fn, jobs, lambda tag, r: [(tag, r)]
    if durations is not None:
        order = sorted(range(len(jobs)), key=lambda k: durations[k])
        jobs, can_join = [jobs[k] for k in order], [can_join[k] for k in order]
    together = [j for j, ok in zip(jobs, can_join) if ok]
    alone = [j for j, ok in zip(jobs, can_join) if not ok]
    members: dict[str, list[str]] = {}
    out = []
    for g in range(0, len(together), size):
        chunk = together[g: g + size]
        tag = f"ensemble{g // size:03d}"
        members[tag] = [t for t, _ in chunk]
        out.append((tag, (fn, chunk, lanes)))
    out += [(tag, (fn, [(tag, args)], 1)) for tag, args in alone]

    def unpack(tag: str, r: dict) -> list[tuple[str, dict]]:
        cases = r.get("cases")
        if cases is None:            # the whole group failed (e.g. its worker was killed)
            return [(t, r) for t in members.get(tag, [tag])]
        return [(t, cases.get(t, {"status": "failed", "error": "not run", "seconds": 0.0}))
                for t in members.get(tag, [tag])]
    return _run_group, out, unpack


def _run_group(fn: Callable[..., dict], items: list[tuple[str, tuple]], lanes: int) -> dict:
    if lanes <= 1:
        tag, args = items[0]
        return {"status": "done", "cases": {tag: fn(*args)}, "seconds": 0.0}
    return run_lockstep(fn, items, lanes)
