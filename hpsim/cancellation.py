"""A cancellation token: the one way a long computation is asked to stop early.

The party that wants the stop (a signal handler, a study's scheduler, a test) calls `request()`; the
computation reads `requested` at its own safe points (after a block is written and checkpointed) and returns
normally with what it has. Nothing is raised from inside the computation, so every file it writes is closed
at a point where it is complete and resumable.

    token = CancelToken()
    signal.signal(signal.SIGINT, lambda *_: token.request())
    engine.run(..., cancel=token)
    if token.requested:
        ...  # the run stopped early; its file is resumable
"""
from __future__ import annotations

import threading


class CancelToken:
    """A flag set once by whoever wants a computation to stop, read by the computation at safe points."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def request(self) -> None:
        """Ask the computation to stop at its next safe point (idempotent, safe from a signal handler)."""
        self._event.set()

    @property
    def requested(self) -> bool:
        """True once `request()` was called."""
        return self._event.is_set()


NEVER = CancelToken()
"""A token nobody requests: the default for computations run without a way to stop them."""
