"""Drive sinks: where a drive's samples, statistics rows and checkpoints go.

    H5Sink       an HDF5 results file (netCDF4/CF layout, docs/hdf5.md), SWMR, double-buffered checkpoints
    MemorySink   everything in memory (blocks, rows, checkpoints, equilibria, summary)

Both take the drive's protocol (`samples(block)`, `stats(rows)`, `checkpoint(state)`, and the
runner's `start(info)` / `finish(info)`), and both are read through the same interface
(vehicle.results.reader.ResultsView: series, stats_series, equilibrium, ..., to_xarray), with the
same variable names, dimensions, coordinates and attributes (vehicle.physics.outputs, vehicle.results.variables).

The file's layout and its safe writing are vehicle.results.layout; its life cycle, vehicle.results.results_file.
"""
from __future__ import annotations

import time

import h5py
import numpy as np
from h5py import h5s

from vehicle.results.checkpoint import Checkpoint
from vehicle.results.layout import (CHECKPOINT, RECORD_DIM, SCENARIO, STATS, SUMMARY, TIMESERIES, equilibrium_group,
                                    labels_of)
from vehicle.results.reader import ResultsView, drive_key_for
from vehicle.results.variables import FileVariable, file_variables, group_dataset, require_xarray


# --- the sinks -------------------------------------------------------------------------------------
class H5Sink:
    """Writes into an open results file in SWMR mode: buffers samples and statistics rows and writes
    them a whole HDF5 chunk at a time (each compressed chunk written once: appending block by block
    would rewrite the last chunk every time, and SWMR mode does not reuse the freed space), then the
    checkpoint."""

    def __init__(self, f: h5py.File, n_samples: int = 0, n_stats: int = 0, wall_before_s: float = 0.0):
        self.f = f
        self.ts = f[TIMESERIES]
        self.st = f[STATS]
        self.ck = Checkpoint(f[CHECKPOINT])
        stations, axles, _ = labels_of(f)
        self.n_st, self.n_ax = len(stations), len(axles)
        self.chunk = int(self.ts[RECORD_DIM[TIMESERIES]].chunks[0])
        self.n_samples = n_samples          # rows written (and covered by the last checkpoint)
        self.n_stats = n_stats
        self.plan: dict[str, list[FileVariable]] = {}
        # open dataset handles by (group, name): h5py looks a name up in its group anew on every access, and a
        # flush appends to some 50 datasets
        self.datasets: dict[tuple[str, str], h5py.Dataset] = {}
        # the blocks as the drive handed them: laid out as stored once per flush (one concatenation per drive key,
        # not a reshaping of every variable of every block)
        self.blocks: list[dict] = []
        self.n_buffered = 0
        self.stats_buffer: list[dict] = []
        self.pending_state: dict | None = None
        self.wall_before_s = wall_before_s
        self.session_t0 = time.perf_counter()
        self.last_state: dict | None = None

    def _vars(self, group: str, key: str, value) -> list[FileVariable]:
        k = (group, key)
        if k not in self.plan:
            where = self._group(group)
            shape = np.asarray(value, float).shape[:-1]
            self.plan[k] = [v for v in file_variables(key, shape, RECORD_DIM[group], self.n_st, self.n_ax)
                            if v.name in where]
        return self.plan[k]

    # DriveSink protocol
    def start(self, info: dict) -> None:
        pass

    def finish(self, info: dict) -> None:
        pass

    def samples(self, block: dict) -> None:
        self.blocks.append(block)
        self.n_buffered += len(np.atleast_1d(block["t_s"]))

    def stats(self, rows: list[dict]) -> None:
        self.stats_buffer.extend(rows)

    def checkpoint(self, state: dict) -> None:
        """Called by the drive after a block: write when a chunk is full (`flush` writes the rest at the end)."""
        self.pending_state = state
        if (self.n_samples + self.n_buffered) // self.chunk > self.n_samples // self.chunk:
            self.flush()

    def _group(self, group: str) -> h5py.Group:
        return self.ts if group == TIMESERIES else self.st

    def _dataset(self, group: str, name: str) -> h5py.Dataset:
        ds = self.datasets.get((group, name))
        if ds is None:
            ds = self.datasets[group, name] = self._group(group)[name]
        return ds

    def _append(self, ds: h5py.Dataset, start: int, rows: np.ndarray) -> None:
        """rows after the first `start` of ds, through h5py's low-level dataset (a flush appends to some 50
        datasets: its high-level resize and slicing cost more than the writes)."""
        rows = np.ascontiguousarray(rows, dtype=np.float64)
        ds.id.set_extent((start + len(rows),) + ds.shape[1:])
        selected = ds.id.get_space()
        selected.select_hyperslab((start,) + (0,) * (rows.ndim - 1), rows.shape)
        ds.id.write(h5s.create_simple(rows.shape), selected, rows)

    def flush(self) -> None:
        """Append the buffered rows, then write the checkpoint that covers them (`Checkpoint.write`: the rows and its
        slot flushed before its pointer), or flush them."""
        if self.n_buffered:
            for key in self.blocks[0]:
                value = np.concatenate([b[key] for b in self.blocks], axis=-1)
                for v in self._vars(TIMESERIES, key, value):
                    self._append(self._dataset(TIMESERIES, v.name), self.n_samples, v.take(value, True))
            self.n_samples += self.n_buffered
            self.blocks, self.n_buffered = [], 0
        if self.stats_buffer:
            n = len(self.stats_buffer)
            for key in self.stats_buffer[0]:
                value = np.stack([np.asarray(r[key], float) for r in self.stats_buffer], axis=-1)
                for v in self._vars(STATS, key, value):
                    self._append(self._dataset(STATS, v.name), self.n_stats, v.take(value, True))
            self.n_stats += n
            self.stats_buffer = []
        if self.pending_state is None:
            self.f.flush()
            return
        # the checkpoint's first flush writes the rows with its (inactive) slot, its second the pointer to the slot:
        # the pointer is never on disk before what it covers
        self.ck.write(self.pending_state, {"n_samples": self.n_samples, "n_stats": self.n_stats,
                                           "wall_s": self.wall_s()})
        self.last_state = self.pending_state
        self.pending_state = None

    def release(self) -> None:
        """Drop every handle into the file (before the file is closed after a failure): nothing of it is left for
        the garbage collector to close later, when the HDF5 library may no longer hold the file."""
        self.datasets.clear()
        self.blocks, self.stats_buffer = [], []
        self.f = self.ts = self.st = self.ck = None

    def wall_s(self) -> float:
        return self.wall_before_s + (time.perf_counter() - self.session_t0)


class MemorySink(ResultsView):
    """Keeps every block, statistics row and checkpoint in memory, plus what the runner gives
    `start(info)` (scenario attributes, station and axle names, charged and before-drive equilibria)
    and `finish(info)` (after-drive equilibrium, summary). Read it like a results file
    (ResultsView): `series("wheel_load")`, `equilibrium("after")`, `to_xarray()`, ...; `drive_series(key)`
    gives a drive key's samples as the drive handed them ((width, n) or (n,))."""

    def __init__(self, name: str = "<memory>"):
        self.name = name
        self.blocks: list[dict] = []
        self.rows: list[dict] = []
        self.checkpoints: list[dict] = []
        self.info: dict = {"attrs": {}, "scenario": {}, "stations": [], "axles": [], "equilibrium": {},
                           "summary": {"status": "running", "complete": False}}
        self.final: dict = {}

    # DriveSink protocol
    def start(self, info: dict) -> None:
        self.info = {**self.info, **info}

    def samples(self, block: dict) -> None:
        self.blocks.append({k: np.array(v, float, copy=True) for k, v in block.items()})

    def stats(self, rows: list[dict]) -> None:
        self.rows.extend(rows)

    def checkpoint(self, state: dict) -> None:
        self.checkpoints.append(state)

    def finish(self, info: dict) -> None:
        self.final = info

    # the drive's own view
    def drive_series(self, key: str) -> np.ndarray:
        """A block key's samples concatenated as the drive hands them: (n,) or (width, n)."""
        return np.concatenate([b[key] for b in self.blocks], axis=-1)

    def _group_arrays(self, group: str) -> dict:
        if group == TIMESERIES:
            return {k: self.drive_series(k) for k in (self.blocks[0] if self.blocks else {})}
        if group == STATS:
            return {k: np.stack([np.asarray(r[k], float) for r in self.rows], axis=-1)
                    for k in (self.rows[0] if self.rows else {})}
        if group == SUMMARY:
            return dict(self.final.get("summary_values", {}))
        which = group.split("/", 1)[1]
        eq = {**self.info["equilibrium"], **self.final.get("equilibrium", {})}
        return eq.get(which)

    # ResultsView
    @property
    def stations(self):
        return list(self.info["stations"])

    @property
    def axles(self):
        return list(self.info["axles"])

    @property
    def root_attrs(self) -> dict:
        return dict(self.info["attrs"])

    @property
    def scenario_attrs(self) -> dict:
        return dict(self.info["scenario"])

    def summary_attrs(self) -> dict:
        return {**self.info["summary"], **self.final.get("summary", {})}

    def counts(self) -> tuple[int, int]:
        return sum(len(np.atleast_1d(b["t_s"])) for b in self.blocks), len(self.rows)

    def state(self) -> dict | None:
        return self.checkpoints[-1] if self.checkpoints else None

    def _record(self, group: str, name: str):
        arrays = self._group_arrays(group)
        key, v = drive_key_for(group, name, arrays)
        if key is None:
            return None
        return v.take(arrays[key], True)

    def series(self, name: str):
        return self._record(TIMESERIES, name) if self.blocks else None

    def stats_series(self, name: str):
        return self._record(STATS, name) if self.rows else None

    def _static(self, arrays: dict | None) -> dict | None:
        if arrays is None:
            return None
        out = {}
        for key, value in arrays.items():
            a = np.asarray(value, float)
            for v in file_variables(key, a.shape, None, len(self.stations), len(self.axles)):
                out[v.name] = v.take(a, False) if a.ndim else float(a)
        return out

    def equilibrium(self, which: str) -> dict | None:
        return self._static(self._group_arrays(equilibrium_group(which)))

    def summary_values(self) -> dict:
        return self._static(self._group_arrays(SUMMARY))

    def dataset(self, group: str):
        if group == SCENARIO:
            return require_xarray().Dataset(attrs=self.scenario_attrs)
        arrays = self._group_arrays(group) or {}
        attrs = self.summary_attrs() if group == SUMMARY else {}
        ds = group_dataset(RECORD_DIM.get(group), arrays, self.stations, self.axles, attrs, self.info.get("seats"))
        if group == STATS:        # attributes the file's stats variables get at creation (travel-bin edges)
            for name, extra in (self.info.get("stats_attrs") or {}).items():
                if name in ds:
                    ds[name].attrs.update(extra)
        return ds

    def groups(self) -> list[str]:
        out = [SCENARIO, TIMESERIES, STATS]
        eq = {**self.info["equilibrium"], **self.final.get("equilibrium", {})}
        out += [equilibrium_group(e) for e in ("charged", "before", "after") if e in eq]
        return out + [SUMMARY]

    def close(self) -> None:
        pass
