"""Cancellation of a drive (hpsim.cancellation): a requested token stops an engine at its next checkpoint, it
returns normally with what it has, and a drive resumed from that checkpoint ends where an uninterrupted one does,
bit for bit (the checkpoint is the whole state of the drive)."""
from __future__ import annotations

import numpy as np

from hpsim.cancellation import CancelToken
from vehicle.results.sinks import MemorySink

from tests.helpers import make_drive


class _StopAtFirstCheckpoint(MemorySink):
    """A sink that asks the drive to stop when the first checkpoint reaches it (as a signal handler would)."""

    def __init__(self, token: CancelToken):
        super().__init__("stopping")
        self.token = token

    def checkpoint(self, state: dict) -> None:
        super().checkpoint(state)
        self.token.request()


def test_a_cancelled_drive_returns_at_its_checkpoint_and_resumes_to_the_same_end():
    d = make_drive(distance_m=300.0, samples_per_block=8)
    whole = MemorySink()
    full = d.run(whole, checkpoint_every_blocks=1)
    token = CancelToken()
    first = _StopAtFirstCheckpoint(token)
    stopped = d.run(first, checkpoint_every_blocks=1, cancel=token)
    assert token.requested
    assert len(first.checkpoints) == 1 and stopped.state.t_s == first.checkpoints[0]["t_s"]
    assert 0 < stopped.state.s_m < 0.5 * d.settings.distance_m
    rest = MemorySink()
    resumed = d.run(rest, state=stopped.state, checkpoint_every_blocks=1)
    np.testing.assert_array_equal(resumed.state.x, full.state.x)
    assert [r["distance_end_m"] for r in first.rows + rest.rows] == [r["distance_end_m"] for r in whole.rows]
