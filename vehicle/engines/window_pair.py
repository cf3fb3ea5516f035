"""Two multiscale windows integrated at once (`solver.paired_windows`, vehicle.engines.multiscale): a window from
its true start and the next one from a predicted start, each on a thread with a solver of its own. How the pair's
second window is carried to its true start, and what it was measured to change: docs/engines.md, "Paired windows"."""
from __future__ import annotations

from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from hpsim.threads import InlineExecutor


class WindowPair:
    """Windows integrated on threads (`integrate`), two at once: slot 0 a window from its true start, slot 1 the
    next one from a predicted start (`paired_windows`), each on a solver of its own (the same compiled step; its
    integration leaves Python's lock). Where the drive's solver has no `refined_solver` (its
    `capabilities.step_doubling` False: vehicle.numerics.contract), or whose solver is bound to its thread (an ensemble
    lane: `thread_bound`), each runs at once on it (the numerics are the same either way: only the wall time
    differs)."""

    def __init__(self, drive):
        self.drive = drive               # a MultiscaleDrive: its `integrate`, solver, model and block shape
        self.pool = None
        self.solvers: list = []

    def submit(self, slot: int, x0: np.ndarray, t0: float, t_warm: float, t_end: float) -> Future:
        d = self.drive
        if self.pool is None:
            # the second window's solver: the same method at the same step (the solver contract's step_doubling
            # capability); a drive that keeps its work on its own thread (`beside` False: an ensemble lane)
            # integrates every window there, at once
            if d.beside and d.solver.capabilities.step_doubling:
                self.solvers = [d.solver, d.solver.refined_solver(1).bind(d.model, d.K, d.M)]
                self.pool = ThreadPoolExecutor(max_workers=2, thread_name_prefix="hpsim-window")
            else:
                self.solvers, self.pool = [d.solver, d.solver], InlineExecutor()
        return self.pool.submit(d.integrate, self.solvers[slot], x0, t0, t_end, t_warm)

    def close(self) -> None:
        if self.pool is not None:
            self.pool.shutdown(wait=True, cancel_futures=True)
