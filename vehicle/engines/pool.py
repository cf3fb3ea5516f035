"""Worker processes for engines and studies: a pool whose workers die with their parent, ignore Ctrl-C
between tasks, and (forked) inherit one object from the parent instead of receiving it pickled.

A time-parallel drive forks its segment workers after building the model and the compiled solver: the
workers inherit that drive (`inherited()`), which costs nothing, where pickling it would rebuild and
recompile it in every worker. Only fork can do this; `fork_pool` refuses where fork does not exist.
"""
from __future__ import annotations

import ctypes
import multiprocessing as mp
import os
import signal
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager

from hpsim.errors import Terminated

_INHERITED = None                  # what the forked workers of the open pool inherit from the parent
STOP_GRACE_S = 30.0                # how long an interrupted study waits for its running cases to checkpoint


def die_with_parent(parent_pid: int) -> None:
    """In a worker: the kernel kills it when its parent dies (Linux prctl PR_SET_PDEATHSIG; a study killed with
    kill -9 leaves no workers running); Ctrl-C is ignored between tasks (a running task handles it itself)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            PR_SET_PDEATHSIG = 1
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent_pid:          # the parent died before prctl took effect
        os._exit(1)


def can_fork() -> bool:
    """Whether this process can fork workers that inherit its objects (not from a daemonic worker)."""
    return "fork" in mp.get_all_start_methods() and not mp.current_process().daemon


@contextmanager
def fork_pool(processes: int, inherit):
    """A process pool of forked workers that inherit `inherit` (`inherited()` in a worker) and die with this
    process. On any exception (Ctrl-C, a failed task) the workers are ended before it propagates."""
    global _INHERITED
    _INHERITED = inherit
    try:
        with ProcessPoolExecutor(max_workers=processes, mp_context=mp.get_context("fork"),
                                 initializer=die_with_parent, initargs=(os.getpid(),)) as pool:
            try:
                yield pool
            except BaseException:
                signal_workers(pool, signal.SIGTERM)
                raise
    finally:
        _INHERITED = None


def inherited():
    """In a forked worker of `fork_pool`: the object the parent handed down."""
    return _INHERITED


def worker_processes(pool: ProcessPoolExecutor) -> list:
    """The live worker processes of a pool (ProcessPoolExecutor keeps them in `_processes`, its one way to reach
    them; None once it is shut down)."""
    return list(pool._processes.values()) if pool._processes else []


def signal_workers(pool: ProcessPoolExecutor, signum: int) -> None:
    """Send a signal to every live worker process of a pool."""
    for proc in worker_processes(pool):
        try:
            os.kill(proc.pid, signum)
        except OSError:
            pass


def stop_workers(pool: ProcessPoolExecutor, futs) -> None:
    """Cancel what has not started, ask the workers to stop (SIGINT: at their next checkpoint), wait for them up to
    STOP_GRACE_S, then kill them; a second Ctrl-C (or SIGTERM) kills them at once. The pool is left shut down."""
    for fut in futs:
        fut.cancel()
    procs = worker_processes(pool)
    signal_workers(pool, signal.SIGINT)
    try:
        deadline = time.monotonic() + STOP_GRACE_S
        while any(p.is_alive() for p in procs) and time.monotonic() < deadline:
            time.sleep(0.05)
    except (KeyboardInterrupt, Terminated):
        pass
    finally:
        for proc in procs:
            if proc.is_alive():
                proc.kill()
        for proc in procs:
            proc.join(timeout=5.0)
        pool.shutdown(wait=False, cancel_futures=True)
