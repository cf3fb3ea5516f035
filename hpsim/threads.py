"""Work beside the main thread: numpy's FFTs, random generators and most array loops, LAPACK's banded solves and
the compiled step (ctypes) leave Python's global lock, so two such pieces of work on threads use two cores.

    left, right = beside_map(envelope, (left_track, right_track))

Threads, not processes: the pieces share their inputs without copies and start in microseconds. The same operations
run either way, so the results are the same bits as one after the other.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from typing import Callable, Iterable, TypeVar

T = TypeVar("T")
R = TypeVar("R")

THREADS = 2        # the pieces at once: the work this is for comes in pairs (two tracks, two windows)
# the BLAS library's own threads: hpsim's parallel work is its pieces on threads (here) and its study workers in
# processes, each sized to the cores; a BLAS that starts threads of its own for the small matrices hpsim multiplies
# (8 x 8 to 40 x 40) oversubscribes the cores, and OpenBLAS's threads spin while they wait for the next product
# (docs/engines.md, "The whole command")
BLAS_THREAD_VARIABLES = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _pool() -> ThreadPoolExecutor:
    """One pool per process, made on first use and kept: no threads started and joined per call (a Ctrl-C then
    never lands in a pool's teardown)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=THREADS, thread_name_prefix="hpsim-beside")
        return _POOL


def _forget_pool() -> None:
    """In a forked child: the parent's threads are not there (a new pool on first use)."""
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


os.register_at_fork(after_in_child=_forget_pool)


def beside_map(fn: Callable[[T], R], items: Iterable[T]) -> list[R]:
    """[fn(item) for item in items], THREADS at a time on threads (one item: on this thread). Not nested: the items'
    work must not call beside_map itself (the pool's threads would wait for themselves)."""
    items = list(items)
    if len(items) < 2:
        return [fn(x) for x in items]
    return list(_pool().map(fn, items))


def beside(fn: Callable[[], R]) -> Future:
    """fn() started on a pool thread (`beside_map`'s); its Future. For work that waits (a child process, a file)
    while this thread goes on."""
    return _pool().submit(fn)


def one_blas_thread() -> None:
    """One thread for the BLAS library (BLAS_THREAD_VARIABLES), unless the environment already says how many: called
    before NumPy is imported (the libraries read the variables when they load); the study workers inherit it."""
    for name in BLAS_THREAD_VARIABLES:
        os.environ.setdefault(name, "1")


class InlineExecutor:
    """The `submit`/`shutdown` of a ThreadPoolExecutor, each job run at once on the calling thread: for a caller
    that hands work to an executor where a core would idle, when that work must stay on its thread (an ensemble
    lane's drive, vehicle.engines.ensemble). The job's exception is its Future's, as on a pool; a Ctrl-C is not
    held back."""

    def submit(self, fn: Callable[..., R], *args, **kwargs) -> Future:
        done: Future = Future()
        try:
            done.set_result(fn(*args, **kwargs))
        except Exception as exc:              # a Future carries it to whoever asks for the result
            done.set_exception(exc)
        return done

    def shutdown(self, wait: bool = True, cancel_futures: bool = False) -> None:
        """Nothing runs later: every job ran in `submit`."""
