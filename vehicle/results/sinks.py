"""Drive sinks: where a drive's samples, statistics rows and checkpoints go.

    H5Sink       an HDF5 results file (netCDF4/CF layout, docs/hdf5.md), SWMR, double-buffered checkpoints
    MemorySink   everything in memory (blocks, rows, checkpoints, equilibria, summary)

Both take the drive's protocol (`samples(block)`, `stats(rows)`, `checkpoint(state)`, and the
runner's `start(info)` / `finish(info)`), and both are read through the same interface
(vehicle.results.reader.ResultsView: series, stats_series, equilibrium, ..., to_xarray), with the
same variable names, dimensions, coordinates and attributes (vehicle.physics.outputs, vehicle.results.variables).

This module also holds the low-level pieces of writing a results file safely: netCDF dimension
scales, never following a symbolic link at a temporary path, the copy-and-rename of the final
write, and recognising a full disk.
"""
from __future__ import annotations

import errno
import os
import time
from pathlib import Path

import h5py
import numpy as np

from hpsim.errors import UserInputError

from vehicle.results.checkpoint import Checkpoint
from vehicle.results.netcdf import attach, labels
from vehicle.results.reader import ResultsView, drive_key_for
from vehicle.results.variables import FileVariable, file_variables, group_dataset, require_xarray

LIBVER = ("v110", "v110")   # HDF5 1.10 file format: needed for SWMR, readable by HDF5 >= 1.10
STATS_CHUNK_ROWS = 64


# --- safe paths --------------------------------------------------------------------------------------
def remove_stale(path: Path) -> None:
    """Remove a leftover file or symbolic link at one of our temporary paths: the link itself, never its target."""
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass
    except IsADirectoryError:
        raise UserInputError(f"{path}: is a directory, in the way of a temporary file; remove it") from None


def create_h5(path: Path) -> h5py.File:
    """A new HDF5 file at a temporary path: whatever was there (a link included) is removed, and the file
    is created exclusively (O_EXCL does not follow a link planted in between)."""
    remove_stale(path)
    return h5py.File(path, "x", libver=LIBVER)


def safe_copy(src: Path, dst: Path) -> None:
    """Byte copy to a fresh file (exclusive create, no link followed), synced to disk."""
    remove_stale(dst)
    fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644)
    try:
        with open(src, "rb") as fin, os.fdopen(fd, "wb", closefd=False) as fout:
            while chunk := fin.read(1 << 20):
                fout.write(chunk)
            fout.flush()
            os.fsync(fd)
    finally:
        os.close(fd)


def sync_replace(tmp: Path, path: Path) -> None:
    """Rename over the result (atomic), then sync the folder so the rename survives a power cut."""
    os.replace(tmp, path)
    try:
        dfd = os.open(path.parent, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(dfd)
    except OSError:
        pass
    finally:
        os.close(dfd)


def is_disk_full(exc: BaseException) -> bool:
    """h5py reports a full disk as OSError errno 28 or as a RuntimeError/OSError naming errno 28."""
    if getattr(exc, "errno", None) in (errno.ENOSPC, errno.EDQUOT):
        return True
    text = str(exc)
    return "No space left on device" in text or "errno = 28" in text or "Disk quota exceeded" in text


def write_static_group(parent: h5py.Group, name: str, arrays: dict, stations, axles, attrs: dict | None = None,
                       seats=None):
    """An equilibrium or the summary: drive-keyed arrays ((width,) or scalars) as labelled variables."""
    if name in parent:
        del parent[name]
    g = parent.create_group(name)
    scales = labels(g, stations, axles)
    for key, value in arrays.items():
        a = np.asarray(value, float)
        for v in file_variables(key, a.shape, "static", len(stations), len(axles)):
            ds = g.create_dataset(v.name, data=v.take(a, False))
            attach(ds, v.dims, scales, seats)
            for k, val in v.attrs.items():
                ds.attrs[k] = val
    for k, v in (attrs or {}).items():
        g.attrs[k] = v
    return g


def _record_group(f: h5py.File, group: str, sample: dict, chunk: int, kw: dict, stations, axles, seats=None,
                  attrs: dict | None = None) -> dict[str, list[FileVariable]]:
    """/timeseries or /stats: every variable empty and resizable along the record dimension."""
    g = f.create_group(group)
    scales = labels(g, stations, axles)
    plan = {key: file_variables(key, np.asarray(v, float).shape[:-1], group, len(stations), len(axles))
            for key, v in sample.items()}
    ordered = sorted(((key, v) for key, vs in plan.items() for v in vs), key=lambda kv: kv[1].role != "record")
    coords = " ".join(v.name for _, v in ordered if v.role == "coord")
    for key, v in ordered:
        width = v.take(np.asarray(sample[key], float), True).shape[1:]
        ds = g.create_dataset(v.name, shape=(0,) + width, maxshape=(None,) + width, dtype="f8",
                              chunks=(chunk,) + width, **kw)
        for k, val in {**v.attrs, **(attrs or {}).get(v.name, {})}.items():
            ds.attrs[k] = val
        if v.role == "record":
            ds.make_scale(v.name)
            scales[v.name] = ds
        else:
            attach(ds, v.dims, scales, seats)
            if v.role == "data" and coords:
                ds.attrs["coordinates"] = coords
    return plan


def create_file(path: Path, info: dict, block: dict, row: dict, state: dict, stored: set[str], compression: int,
                chunk_rows: int) -> None:
    """The whole file before the drive starts (SWMR mode cannot create objects): root and /scenario
    attributes, the charged and before-drive equilibria, /summary (status running), every (empty)
    time-series and statistics variable and the checkpoint slots."""
    stations, axles, seats = info["stations"], info["axles"], info.get("seats")
    kw = {"compression": "gzip", "compression_opts": int(compression), "shuffle": True} if compression else {}
    kw["fletcher32"] = True        # a checksum per chunk: damaged data is reported, not read as numbers
    with create_h5(path) as f:
        for k, v in info["attrs"].items():
            f.attrs[k] = v
        g = f.create_group("scenario")
        for k, v in info["scenario"].items():
            g.attrs[k] = v
        e = f.create_group("equilibrium")
        for name, arrays in info["equilibrium"].items():
            write_static_group(e, name, arrays, stations, axles)
        _record_group(f, "timeseries", {k: v for k, v in block.items() if k in stored}, chunk_rows, kw,
                      stations, axles, seats)
        _record_group(f, "stats", {k: np.asarray(v, float)[..., None] for k, v in row.items()}, STATS_CHUNK_ROWS,
                      kw, stations, axles, seats, info.get("stats_attrs"))
        Checkpoint.create(f, state)
        write_static_group(f, "summary", {}, stations, axles, info["summary"])


def finish_file(path: Path, final: dict) -> None:
    """The after-drive equilibrium and the summary, or a status: written into a copy that replaces the
    file only when complete, so a kill at any moment leaves the previous file (resumable) in place."""
    tmp = path.with_name(path.name + ".final")
    try:
        safe_copy(path, tmp)
        with h5py.File(tmp, "r+", libver=LIBVER) as f:
            stations = [str(s) for s in f["scenario"].attrs["stations"]]
            axles = [str(a) for a in f["scenario"].attrs["axles"]]
            seats = [str(s) for s in f["scenario"].attrs.get("seats", [])]
            for name, arrays in final.get("equilibrium", {}).items():
                write_static_group(f["equilibrium"], name, arrays, stations, axles)
            old = dict(f["summary"].attrs) if "summary" in f else {}
            arrays = final.get("summary_values")
            if arrays is not None:
                write_static_group(f, "summary", arrays, stations, axles, old, seats)
            for k, v in final.get("summary", {}).items():
                f["summary"].attrs[k] = v
            if "history" in final:
                f.attrs["history"] = str(f.attrs.get("history", "")) + "\n" + final["history"]
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        sync_replace(tmp, path)
    except BaseException:
        remove_stale(tmp)
        raise


# --- the sinks -------------------------------------------------------------------------------------
_HOOKS: list = []


def add_checkpoint_hook(hook) -> None:
    """hook() -> bool is called by the sinks at every checkpoint; True stops the drive there as Ctrl-C
    does (the file stays resumable). Used by sweep workers to stop when their parent died."""
    _HOOKS.append(hook)


class H5Sink:
    """Writes into an open results file in SWMR mode: buffers samples and statistics rows and writes
    them a whole HDF5 chunk at a time (each compressed chunk written once: appending block by block
    would rewrite the last chunk every time, and SWMR mode does not reuse the freed space), then the
    checkpoint."""

    def __init__(self, f: h5py.File, n_samples: int = 0, n_stats: int = 0, wall_before_s: float = 0.0):
        self.f = f
        self.ts = f["timeseries"]
        self.st = f["stats"]
        self.ck = Checkpoint(f["checkpoint"])
        stations = [str(s) for s in f["scenario"].attrs["stations"]]
        axles = [str(a) for a in f["scenario"].attrs["axles"]]
        self.n_st, self.n_ax = len(stations), len(axles)
        self.chunk = int(self.ts["time"].chunks[0])
        self.n_samples = n_samples          # rows written (and covered by the last checkpoint)
        self.n_stats = n_stats
        self.plan: dict[str, list[FileVariable]] = {}
        # open dataset handles by (group, name): h5py looks a name up in its group anew on every access (0.2 ms
        # each; a flush appends to some 50 datasets)
        self.datasets: dict[tuple[str, str], h5py.Dataset] = {}
        self.buffer: dict[str, list] = {}
        self.n_buffered = 0
        self.stats_buffer: list[dict] = []
        self.pending_state: dict | None = None
        self.wall_before_s = wall_before_s
        self.session_t0 = time.perf_counter()
        self.last_state: dict | None = None
        self.stop_requested = False

    def _vars(self, group: str, key: str, value) -> list[FileVariable]:
        k = (group, key)
        if k not in self.plan:
            where = self._group(group)
            shape = np.asarray(value, float).shape[:-1]
            self.plan[k] = [v for v in file_variables(key, shape, group, self.n_st, self.n_ax) if v.name in where]
        return self.plan[k]

    # DriveSink protocol
    def start(self, info: dict) -> None:
        pass

    def finish(self, info: dict) -> None:
        pass

    def samples(self, block: dict) -> None:
        for key, value in block.items():
            for v in self._vars("timeseries", key, value):
                self.buffer.setdefault(v.name, []).append(v.take(value, True))
        self.n_buffered += len(np.atleast_1d(block["t_s"]))

    def stats(self, rows: list[dict]) -> None:
        self.stats_buffer.extend(rows)

    def checkpoint(self, state: dict) -> None:
        """Called by the drive after every block: write when a chunk is full (or on Ctrl-C)."""
        for hook in _HOOKS:
            if hook():
                self.stop_requested = True
        self.pending_state = state
        full = (self.n_samples + self.n_buffered) // self.chunk > self.n_samples // self.chunk
        if full or self.stop_requested:
            self.flush()
        if self.stop_requested:
            # Ctrl-C arrived during the last block: stop here, where the file is consistent
            raise KeyboardInterrupt

    def _group(self, group: str) -> h5py.Group:
        return self.ts if group == "timeseries" else self.st

    def _dataset(self, group: str, name: str) -> h5py.Dataset:
        ds = self.datasets.get((group, name))
        if ds is None:
            ds = self.datasets[group, name] = self._group(group)[name]
        return ds

    def _append(self, ds: h5py.Dataset, start: int, rows: np.ndarray) -> None:
        ds.resize(start + len(rows), axis=0)
        ds[start:] = rows

    def flush(self) -> None:
        """Append the buffered rows, flush, then write the checkpoint that covers them."""
        if self.n_buffered:
            for name, parts in self.buffer.items():
                self._append(self._dataset("timeseries", name), self.n_samples, np.concatenate(parts, axis=0))
            self.n_samples += self.n_buffered
            self.buffer, self.n_buffered = {}, 0
        if self.stats_buffer:
            n = len(self.stats_buffer)
            for key in self.stats_buffer[0]:
                value = np.stack([np.asarray(r[key], float) for r in self.stats_buffer], axis=-1)
                for v in self._vars("stats", key, value):
                    self._append(self._dataset("stats", v.name), self.n_stats, v.take(value, True))
            self.n_stats += n
            self.stats_buffer = []
        self.f.flush()
        if self.pending_state is not None:
            self.ck.write(self.pending_state, {"n_samples": self.n_samples, "n_stats": self.n_stats,
                                               "wall_s": self.wall_s()})
            self.last_state = self.pending_state
            self.pending_state = None

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
        self.stop_requested = False

    # DriveSink protocol
    def start(self, info: dict) -> None:
        self.info = {**self.info, **info}

    def samples(self, block: dict) -> None:
        self.blocks.append({k: np.array(v, float, copy=True) for k, v in block.items()})

    def stats(self, rows: list[dict]) -> None:
        self.rows.extend(rows)

    def checkpoint(self, state: dict) -> None:
        self.checkpoints.append(state)
        for hook in _HOOKS:
            if hook():
                self.stop_requested = True
        if self.stop_requested:
            raise KeyboardInterrupt

    def finish(self, info: dict) -> None:
        self.final = info

    # the drive's own view
    def drive_series(self, key: str) -> np.ndarray:
        """A block key's samples concatenated as the drive hands them: (n,) or (width, n)."""
        return np.concatenate([b[key] for b in self.blocks], axis=-1)

    def _group_arrays(self, group: str) -> dict:
        if group == "timeseries":
            return {k: self.drive_series(k) for k in (self.blocks[0] if self.blocks else {})}
        if group == "stats":
            return {k: np.stack([np.asarray(r[k], float) for r in self.rows], axis=-1)
                    for k in (self.rows[0] if self.rows else {})}
        if group == "summary":
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
        return self._record("timeseries", name) if self.blocks else None

    def stats_series(self, name: str):
        return self._record("stats", name) if self.rows else None

    def _static(self, arrays: dict | None) -> dict | None:
        if arrays is None:
            return None
        out = {}
        for key, value in arrays.items():
            a = np.asarray(value, float)
            for v in file_variables(key, a.shape, "static", len(self.stations), len(self.axles)):
                out[v.name] = v.take(a, False) if a.ndim else float(a)
        return out

    def equilibrium(self, which: str) -> dict | None:
        return self._static(self._group_arrays(f"equilibrium/{which}"))

    def summary_values(self) -> dict:
        return self._static(self._group_arrays("summary"))

    def dataset(self, group: str):
        if group == "scenario":
            return require_xarray().Dataset(attrs=self.scenario_attrs)
        arrays = self._group_arrays(group) or {}
        attrs = self.summary_attrs() if group == "summary" else {}
        ds = group_dataset(group, arrays, self.stations, self.axles, attrs, self.info.get("seats"))
        if group == "stats":        # attributes the file's stats variables get at creation (travel-bin edges)
            for name, extra in (self.info.get("stats_attrs") or {}).items():
                if name in ds:
                    ds[name].attrs.update(extra)
        return ds

    def groups(self) -> list[str]:
        out = ["scenario", "timeseries", "stats"]
        eq = {**self.info["equilibrium"], **self.final.get("equilibrium", {})}
        out += [f"equilibrium/{e}" for e in ("charged", "before", "after") if e in eq]
        return out + ["summary"]

    def close(self) -> None:
        pass



# --- a fresh copy of a file (resume) -------------------------------------------------------------------
_SCALE_ATTRS = ("CLASS", "NAME", "REFERENCE_LIST", "DIMENSION_LIST")


def clone_group(src: h5py.Group, dst_parent: h5py.Group, name: str, rows: int | None = None) -> h5py.Group:
    """Re-create a group in another file: datasets with the same storage (chunks, filters, resizable
    axis), values (resizable ones cut to `rows`), attributes and dimension scales. (h5py's copy
    cannot carry dimension scales across files: their object references would dangle.)"""
    g = dst_parent.create_group(name)
    for k, v in src.attrs.items():
        g.attrs[k] = v
    made: dict[str, h5py.Dataset] = {}
    for key, ds in src.items():
        if isinstance(ds, h5py.Group):
            clone_group(ds, g, key, rows)
            continue
        resizable = ds.maxshape and ds.maxshape[0] is None
        n = min(rows, ds.shape[0]) if resizable and rows is not None else (ds.shape[0] if ds.ndim else None)
        kw = {}
        if ds.chunks:
            kw = {"chunks": ds.chunks, "maxshape": ds.maxshape, "compression": ds.compression,
                  "compression_opts": ds.compression_opts, "shuffle": ds.shuffle, "fletcher32": ds.fletcher32}
        if ds.ndim == 0:
            new = g.create_dataset(key, data=ds[()], dtype=ds.dtype)
        else:
            new = g.create_dataset(key, shape=(n,) + ds.shape[1:], dtype=ds.dtype, **kw)
            if n:
                new[...] = ds[:n]
        for k, v in ds.attrs.items():
            if k not in _SCALE_ATTRS:
                new.attrs[k] = v
        if ds.attrs.get("CLASS") == b"DIMENSION_SCALE":
            new.make_scale(ds.attrs["NAME"].decode() if isinstance(ds.attrs["NAME"], bytes) else ds.attrs["NAME"])
        made[key] = new
    for key, ds in src.items():
        if isinstance(ds, h5py.Dataset) and ds.attrs.get("CLASS") != b"DIMENSION_SCALE" and "DIMENSION_LIST" in ds.attrs:
            for i in range(ds.ndim):
                for scale in ds.dims[i].values():
                    made[key].dims[i].attach_scale(made[scale.name.rsplit("/", 1)[-1]])
    return g
