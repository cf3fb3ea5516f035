"""The layout of a results file (docs/hdf5.md): the one place that names its groups, their record dimensions and
the datasets a reader requires. Then the writing side: creating every group and variable before the drive, the
static groups (equilibria, summary), the final write through a copy, the copy of what a checkpoint covers for a
resume, and the safe temporary paths all of these go through.

The reader (vehicle.results.reader) and the sinks (vehicle.results.sinks) find their groups by these names; the
content of the checkpoint group is vehicle.results.checkpoint's, of each variable vehicle.results.variables'.
"""
from __future__ import annotations

import contextlib
import errno
import os
import signal
import struct
import sys
import threading
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import h5py
import numpy as np

from hpsim.errors import UserInputError

from vehicle.results.checkpoint import Checkpoint
from vehicle.results.netcdf import attach, labels
from vehicle.results.variables import FileVariable, file_variables

LIBVER = ("v110", "v110")   # HDF5 1.10 file format: needed for SWMR, readable by HDF5 >= 1.10
STATS_CHUNK_ROWS = 64

# --- the groups ----------------------------------------------------------------------------------------
SCENARIO = "scenario"           # attributes only: the scenario's text, its resolved definition, the labels
TIMESERIES = "timeseries"       # one row per output sample
STATS = "stats"                 # one row per statistics interval
EQUILIBRIUM = "equilibrium"     # one group per standing equilibrium (EQUILIBRIA)
SUMMARY = "summary"             # the drive's end values and its status
CHECKPOINT = "checkpoint"       # the resume state (vehicle.results.checkpoint)
RECORD_DIM = {TIMESERIES: "time", STATS: "km"}
EQUILIBRIA = ("charged", "before", "after", "before_band", "after_band")
FINAL_EQUILIBRIA = ("after", "after_band")      # written by the final write only


def equilibrium_group(which: str) -> str:
    """The path of one equilibrium's group (`which` in EQUILIBRIA)."""
    return f"{EQUILIBRIUM}/{which}"


STATIC_GROUPS = tuple(equilibrium_group(e) for e in EQUILIBRIA) + (SUMMARY,)
DATA_GROUPS = (TIMESERIES, STATS) + STATIC_GROUPS
# what a reader requires: the scenario's attributes, groups, and the record coordinates by format version
SCENARIO_ATTRS = ("yaml", "resolved_json", "stations", "axles", "distance_m")
REQUIRED_GROUPS = (equilibrium_group("before"), TIMESERIES, STATS, CHECKPOINT)
RECORD_COORDINATES = {1: (f"{TIMESERIES}/t_s", f"{STATS}/distance_end_m"),
                      2: (f"{TIMESERIES}/{RECORD_DIM[TIMESERIES]}", f"{STATS}/{RECORD_DIM[STATS]}")}


def labels_of(f: h5py.File) -> tuple[list[str], list[str], list[str]]:
    """(stations, axles, seats) as the file's scenario group records them (seats empty when it has none)."""
    attrs = f[SCENARIO].attrs
    return ([str(s) for s in attrs["stations"]], [str(a) for a in attrs["axles"]],
            [str(s) for s in attrs.get("seats", [])])


@dataclass(frozen=True)
class NoRoom:
    """Why a write found no room (`reason`) and what the user can do about it (`remedy`)."""

    reason: str
    remedy: str


_NO_ROOM = ((errno.ENOSPC, "No space left on device", NoRoom("disk full (no space left on device)", "free some space")),
            (errno.EDQUOT, "Disk quota exceeded", NoRoom("disk quota exceeded", "free some space or raise the quota")),
            (errno.EFBIG, "File too large", NoRoom("file too large (over the file-size limit, ulimit -f)",
                                                   "raise the file-size limit (ulimit -f)")))


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def recorded_end(path: Path) -> int | None:
    """The end of the file its HDF5 superblock records (superblock versions 2 and 3, 8-byte addresses: what
    LIBVER writes), or None for another file. HDF5 records space as allocated before writing into it, so a write
    that found no room leaves a file shorter than this (HDF5 File Format Specification, section II.A)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(48)
    except OSError:
        return None
    if len(head) < 36 or head[:8] != HDF5_SIGNATURE or head[8] not in (2, 3) or head[9] != 8:
        return None
    base, _extension, end = struct.unpack_from("<QQQ", head, 12)
    return base + end


def _from_h5py_release(exc: BaseException | None, tb) -> bool:
    """Whether an error was raised by h5py letting go of an object (its traceback ends in h5py's own code)."""
    if not isinstance(exc, (RuntimeError, OSError)) or tb is None:
        return False
    while tb.tb_next is not None:
        tb = tb.tb_next
    return tb.tb_frame.f_code.co_filename.startswith("h5py/")


@contextlib.contextmanager
def h5py_releases_quietly():
    """Inside the block, h5py's objects that fail to release themselves (their file cannot be written: a full disk,
    the file-size limit) are let go without the tracebacks h5py prints for each (through sys.excepthook, then
    sys.unraisablehook: the interpreter's hooks for errors raised where no caller can catch them); anything else is
    reported as usual."""
    previous_unraisable, previous_except = sys.unraisablehook, sys.excepthook

    def unraisable(u):
        if not _from_h5py_release(u.exc_value, u.exc_traceback):
            previous_unraisable(u)

    def excepthook(kind, value, tb):
        if not _from_h5py_release(value, tb):
            previous_except(kind, value, tb)

    sys.unraisablehook, sys.excepthook = unraisable, excepthook
    try:
        yield
    finally:
        sys.unraisablehook, sys.excepthook = previous_unraisable, previous_except


def fault_point(point: str) -> None:
    """Test hook: HPSIM_FAULT=<point> kills the process there (tests/unit/results/test_results_robust.py)."""
    if os.environ.get("HPSIM_FAULT") == point:
        os.kill(os.getpid(), signal.SIGKILL)


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


def out_of_space(exc: BaseException) -> NoRoom | None:
    """Why a write failed for want of room (a full disk, a quota, the file-size limit), or None. h5py reports these
    as an OSError with the errno or as a RuntimeError/OSError naming it in its text."""
    code = getattr(exc, "errno", None)
    text = str(exc)
    for number, name, reason in _NO_ROOM:
        if code == number or name in text or f"errno = {number}" in text:
            return reason
    return None


def write_static_group(parent: h5py.Group, name: str, arrays: dict, stations, axles, attrs: dict | None = None,
                       seats=None):
    """An equilibrium or the summary: drive-keyed arrays ((width,) or scalars) as labelled variables."""
    if name in parent:
        del parent[name]
    g = parent.create_group(name)
    scales = labels(g, stations, axles)
    for key, value in arrays.items():
        a = np.asarray(value, float)
        for v in file_variables(key, a.shape, None, len(stations), len(axles)):
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
    plan = {key: file_variables(key, np.asarray(v, float).shape[:-1], RECORD_DIM[group], len(stations), len(axles))
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


# the empty record groups and checkpoint slots of recent files, by what lays them out (`_structure_key`): the cases
# of a study that share a vehicle structure share them (one file's bytes, copied), instead of creating some 50
# variables with their attributes and dimension scales for every case
_STRUCTURES: dict[bytes, bytes] = {}
_STRUCTURES_KEPT = 4
_STRUCTURES_LOCK = threading.Lock()          # the lanes of an ensemble create their files on threads


def _structure_key(info: dict, block: dict, row: dict, state: dict, stored: set[str], compression: int,
                   chunk_rows: int) -> bytes:
    """What the record groups and the checkpoint slots are made of: labels, variables and their widths, storage,
    the statistics variables' extra attributes (values included)."""
    def shapes(d: dict) -> list:
        return [(k, np.shape(v)) for k, v in d.items()]
    extra = [(name, sorted((k, np.asarray(v).dtype.str, np.asarray(v).tobytes()) for k, v in attrs.items()))
             for name, attrs in sorted((info.get("stats_attrs") or {}).items())]
    return repr((list(info["stations"]), list(info["axles"]), list(info.get("seats") or ()), int(compression),
                 int(chunk_rows), shapes({k: v for k, v in block.items() if k in stored}), shapes(row),
                 shapes(state), extra, LIBVER, STATS_CHUNK_ROWS)).encode()


def _create_structure(path: Path, info: dict, block: dict, row: dict, state: dict, stored: set[str],
                      compression: int, chunk_rows: int) -> None:
    """A new file at `path` holding every (empty) time-series and statistics variable and the checkpoint slots."""
    stations, axles, seats = info["stations"], info["axles"], info.get("seats")
    kw = {"compression": "gzip", "compression_opts": int(compression), "shuffle": True} if compression else {}
    kw["fletcher32"] = True        # a checksum per chunk: damaged data is reported, not read as numbers
    with create_h5(path) as f:
        _record_group(f, TIMESERIES, {k: v for k, v in block.items() if k in stored}, chunk_rows, kw,
                      stations, axles, seats)
        _record_group(f, STATS, {k: np.asarray(v, float)[..., None] for k, v in row.items()}, STATS_CHUNK_ROWS,
                      kw, stations, axles, seats, info.get("stats_attrs"))
        Checkpoint.create(f.create_group(CHECKPOINT), state)


def _write_new(path: Path, content: bytes) -> None:
    """`content` as a new file at a temporary path (created exclusively, as `create_h5`)."""
    remove_stale(path)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0), 0o644)
    with os.fdopen(fd, "wb") as fh:
        fh.write(content)


def create_file(path: Path, info: dict, block: dict, row: dict, state: dict, stored: set[str], compression: int,
                chunk_rows: int) -> None:
    """The whole file before the drive starts (SWMR mode cannot create objects): root and /scenario
    attributes, the charged and before-drive equilibria, /summary (status running), every (empty)
    time-series and statistics variable and the checkpoint slots (those as the last file of the same structure
    had them, `_STRUCTURES`)."""
    key = _structure_key(info, block, row, state, stored, compression, chunk_rows)
    with _STRUCTURES_LOCK:
        structure = _STRUCTURES.get(key)
    if structure is not None:
        _write_new(path, structure)
    else:
        _create_structure(path, info, block, row, state, stored, compression, chunk_rows)
        structure = path.read_bytes()
        with _STRUCTURES_LOCK:
            if len(_STRUCTURES) >= _STRUCTURES_KEPT:
                _STRUCTURES.pop(next(iter(_STRUCTURES)))
            _STRUCTURES[key] = structure
    stations, axles = info["stations"], info["axles"]
    with h5py.File(path, "r+", libver=LIBVER) as f:
        for k, v in info["attrs"].items():
            f.attrs[k] = v
        g = f.create_group(SCENARIO)
        for k, v in info["scenario"].items():
            g.attrs[k] = v
        e = f.create_group(EQUILIBRIUM)
        for name, arrays in info["equilibrium"].items():
            write_static_group(e, name, arrays, stations, axles)
        write_static_group(f, SUMMARY, {}, stations, axles, info["summary"])


def finish_file(path: Path, final: dict, then: Callable[[h5py.File], dict] | None = None) -> None:
    """The after-drive equilibrium and the summary, or a status: written into a copy that replaces the
    file only when complete, so a kill at any moment leaves the previous file (resumable) in place.
    The function then(f) gives more /summary attributes, read from the open copy as written. They go into the same
    copy: the validity warnings need no second copy of the file."""
    tmp = path.with_name(path.name + ".final")
    try:
        safe_copy(path, tmp)
        with h5py.File(tmp, "r+", libver=LIBVER) as f:
            stations, axles, seats = labels_of(f)
            for name, arrays in final.get("equilibrium", {}).items():
                write_static_group(f[EQUILIBRIUM], name, arrays, stations, axles)
            old = dict(f[SUMMARY].attrs) if SUMMARY in f else {}
            arrays = final.get("summary_values")
            if arrays is not None:
                write_static_group(f, SUMMARY, arrays, stations, axles, old, seats)
            for k, v in final.get("summary", {}).items():
                f[SUMMARY].attrs[k] = v
            for k, v in (then(f) if then is not None else {}).items():
                f[SUMMARY].attrs[k] = v
            fault_point("during_final_write")         # test hook: killed with the copy half written
            if "history" in final:
                f.attrs["history"] = str(f.attrs.get("history", "")) + "\n" + final["history"]
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        sync_replace(tmp, path)
    except BaseException:
        remove_stale(tmp)
        raise




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


def copy_covered(src: h5py.File, dst: h5py.File, n_samples: int, n_stats: int, history: str) -> None:
    """Copy into a fresh file what a checkpoint covers: every group the creation wrote (the equilibria before the
    drive, its weighing bands included), the record variables cut to `n_samples` and `n_stats` rows, and /summary
    reset to status running. UserInputError if a record variable holds fewer rows than the checkpoint."""
    for gname, n in ((TIMESERIES, n_samples), (STATS, n_stats)):
        for ds in src[gname].values():
            if ds.maxshape and ds.maxshape[0] is None and ds.shape[0] < n:
                raise UserInputError(f"{src.filename}: /{gname}/{ds.name.rsplit('/', 1)[-1]} has {ds.shape[0]} "
                                     f"rows, fewer than the checkpoint's {n}: the file is damaged, start again "
                                     "with --overwrite")
    for k, v in src.attrs.items():
        dst.attrs[k] = v
    dst.attrs["history"] = str(src.attrs.get("history", "")) + "\n" + history
    clone_group(src[SCENARIO], dst, SCENARIO)
    e = dst.create_group(EQUILIBRIUM)
    for name, group in src[EQUILIBRIUM].items():
        if name not in FINAL_EQUILIBRIA:
            clone_group(group, e, name)
    clone_group(src[TIMESERIES], dst, TIMESERIES, n_samples)
    clone_group(src[STATS], dst, STATS, n_stats)
    clone_group(src[CHECKPOINT], dst, CHECKPOINT)
    s = clone_group(src[SUMMARY], dst, SUMMARY, 0)
    for k in ("error", "stopped_at_km"):
        if k in s.attrs:
            del s.attrs[k]
    s.attrs["status"] = "running"
    s.attrs["complete"] = False


def valid_counts(f: h5py.File) -> tuple[int, int]:
    """(samples, statistics rows) covered by the last checkpoint: the rows to trust in a file
    whose writer may have been stopped between appending data and checkpointing."""
    ck = Checkpoint(f[CHECKPOINT]).read() if CHECKPOINT in f else None
    if ck is not None:
        return ck[1]["n_samples"], ck[1]["n_stats"]
    return 0, 0


def read_state(f: h5py.File) -> dict | None:
    """The last checkpointed DriveState dict (t_s, s_m, x, ...) or None."""
    ck = Checkpoint(f[CHECKPOINT]).read() if CHECKPOINT in f else None
    return None if ck is None else ck[0]
