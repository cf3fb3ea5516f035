"""A results file being written: one object that creates it, appends a drive to it, checkpoints, finishes it,
records its status and truncates it to its last checkpoint for a resume.

    rf = DriveFile(out)
    rf.create(info, block, row, state, stored, compression, chunk_rows)   # every variable, before the drive
    sink = rf.open_sink(ResumePoint.start())                               # SWMR: the drive appends and checkpoints
    ...drive.run(sink, ...)...
    rf.close_sink()
    rf.finish(final)                                                       # /equilibrium/after, /summary

Every write that replaces the file goes through a temporary path beside it (`.partial`, `.resume`, `.final`) that is
renamed when complete, so a kill at any moment leaves the previous file. Errors are raised as they come (OSError,
RuntimeError); `vehicle.results.layout.out_of_space` tells the caller when they mean a full disk, a quota or the
file-size limit.
"""
from __future__ import annotations

import datetime as _dt
import gc
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import h5py

from vehicle.results.layout import (LIBVER, copy_covered, create_file, create_h5, finish_file, h5py_releases_quietly,
                                    recorded_end, remove_stale, sync_replace)
from vehicle.results.reader import open_read, open_results
from vehicle.results.sinks import H5Sink

LOCKED_RETRY_S = 10.0          # how long a run waits for a reader (hpsim report, a notebook) to let go of its file


@dataclass(frozen=True)
class ResumePoint:
    """Where a drive continues in its file: the last checkpoint's state (None: the start) and what it covers."""

    state: dict | None = None
    n_samples: int = 0
    n_stats: int = 0
    wall_s: float = 0.0

    @classmethod
    def start(cls) -> "ResumePoint":
        return cls()


@dataclass(frozen=True)
class StoredRun:
    """What a results file holds about its run: scenario and summary attributes, and where a resume continues."""

    scenario_attrs: dict
    summary_attrs: dict
    complete: bool
    resume_point: ResumePoint = field(default_factory=ResumePoint)


def _now() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def open_for_append(out: Path, wait_s: float = LOCKED_RETRY_S) -> h5py.File:
    """The results file opened for the drive to write into, without HDF5's file lock: a reader that opened the file
    (not SWMR) between its creation and this moment must not stop the run. A lock error (a file system that
    insists) is retried for up to wait_s."""
    t_end = time.monotonic() + wait_s
    while True:
        try:
            # the one writer is the output's lock file (vehicle.results.run.OutputLock); readers read in SWMR mode
            return h5py.File(out, "r+", libver=LIBVER, locking=False)
        except OSError as exc:
            if "unable to lock file" not in str(exc) or time.monotonic() > t_end:
                raise
            time.sleep(0.05)


class DriveFile:
    """The one owner of a results file's life cycle (layout: vehicle.results.layout, docs/hdf5.md)."""

    def __init__(self, path: str | Path):
        self.path = Path(path)
        self._f: h5py.File | None = None
        self.sink: H5Sink | None = None

    def _beside(self, suffix: str) -> Path:
        return self.path.with_name(self.path.name + suffix)

    # --- reading what is there --------------------------------------------------------------------------------
    def status(self) -> tuple[str, int]:
        """(status, format version) after checking all of the file; DamagedResults if it is damaged."""
        with open_results(self.path) as r:
            return r.status(), r.version

    def status_to_resume(self) -> tuple[str, int]:
        """`status` of a file to be resumed. A file whose writer found no room (a full disk, the file-size limit) can
        be shorter than the end its HDF5 superblock records. The bytes never written are restored as zeros (a hole)
        before the check, which verifies every chunk's checksum. If the check still fails, the file is cut back to
        its size and left as it was."""
        size = self.path.stat().st_size
        end = recorded_end(self.path)
        if end is None or end <= size:
            return self.status()
        os.truncate(self.path, end)
        try:
            return self.status()
        except BaseException:
            os.truncate(self.path, size)
            raise

    def stored_run(self) -> StoredRun:
        """The scenario and summary attributes and the last checkpoint (the file was checked by `status`)."""
        with open_results(self.path, check=False) as r:
            summary = {k: (v.item() if hasattr(v, "item") else v) for k, v in r.summary_attrs().items()}
            complete = r.status() == "complete"
            ck = None if complete else r.checkpoint()
            point = ResumePoint() if ck is None else ResumePoint(ck[0], ck[1]["n_samples"], ck[1]["n_stats"],
                                                                  ck[1]["wall_s"])
            return StoredRun(r.scenario_attrs, summary, complete, point)

    # --- writing -------------------------------------------------------------------------------------------------
    def create(self, info: dict, block: dict, row: dict, state: dict, stored: set[str], compression: int,
               chunk_rows: int) -> None:
        """The whole file before the drive (vehicle.results.layout.create_file), written beside it and renamed."""
        tmp = self._beside(".partial")
        try:
            with h5py_releases_quietly():
                create_file(tmp, info, block, row, state, stored, compression, chunk_rows)
            sync_replace(tmp, self.path)
        except BaseException:
            remove_stale(tmp)
            raise

    def truncate_for_resume(self, point: ResumePoint) -> None:
        """Replace the file by a fresh copy of what `point` covers (clears a killed writer's state); the file is
        unchanged if this fails (UserInputError if it holds fewer rows than its checkpoint)."""
        tmp = self._beside(".resume")
        try:
            with h5py_releases_quietly(), open_read(self.path) as src, create_h5(tmp) as dst:
                copy_covered(src, dst, point.n_samples, point.n_stats, f"{_now()}: resumed")
            sync_replace(tmp, self.path)
        except BaseException:
            remove_stale(tmp)
            raise

    def open_sink(self, point: ResumePoint) -> H5Sink:
        """Open the file in SWMR mode for a drive continuing from `point`: the sink it appends and checkpoints to."""
        self._f = open_for_append(self.path)
        try:
            self.sink = H5Sink(self._f, point.n_samples, point.n_stats, point.wall_s)
            self._f.swmr_mode = True
        except BaseException:
            self.abandon_sink()
            raise
        return self.sink

    def close_sink(self) -> None:
        """Write what the sink holds (its checkpoint last) and close the file; raises what the writes raise."""
        if self._f is None:
            return
        try:
            self.sink.flush()
            f, self._f = self._f, None
            f.close()
        except BaseException:
            self.abandon_sink()
            raise

    def abandon_sink(self) -> None:
        """Close the file without writing more (after a failure): what its last flush wrote stays. Every handle is
        dropped here, so that nothing is left for the garbage collector to close (and fail) later."""
        f, self._f = self._f, None
        sink, self.sink = self.sink, None
        with h5py_releases_quietly():
            if sink is not None:
                sink.release()
                del sink
            if f is not None:
                try:
                    f.close()
                except Exception:          # e.g. a full disk: the file keeps what its last flush wrote
                    pass
                del f
            gc.collect()

    def finish(self, final: dict, then: Callable[[h5py.File], dict] | None = None) -> None:
        """The after-drive equilibrium and the summary, written into a copy that replaces the file when complete;
        then(f): more /summary attributes read from that copy before it does (`layout.finish_file`)."""
        with h5py_releases_quietly():
            finish_file(self.path, final, then)

    def set_status(self, status: str, **attrs) -> None:
        """Record the run's status in /summary (after the drive's writer closed; through a copy, as `finish`)."""
        self.finish({"summary": {"status": status, "complete": status == "complete", **attrs}})
