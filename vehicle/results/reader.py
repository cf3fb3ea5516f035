"""Reading results, for every reader (summary, report, plots, compare, resume): the file's groups by the names
of vehicle.results.layout (docs/hdf5.md).

    open_results(path)        a results file -> ResultsFile (checked first: a damaged file fails fast)
    ResultsView               the read interface shared by files and vehicle.results.sinks.MemorySink:
                              stations, axles, scenario_attrs, summary_attrs(), status(), counts(),
                              state(), series(name), stats_series(name), equilibrium(which),
                              summary_values(), dataset(group), to_xarray()

Names are the file's variable names (vehicle.physics.outputs): `series("strut_temperature")` is
(n, 8) time-major, `series("time")`, `stats_series("km")`, `equilibrium("after")["wheel_load"]`.

Files of format version 1 (hpsim before the netCDF/CF layout: drive keys as dataset names, no
dimension scales) are read through the same interface by mapping their names through the table.

A damaged file must not hang or crash the caller: before a file is opened in this process, a
child process reads all of it (every object, attribute and chunk, checksums verified) under a time
limit; whatever fails is reported as one line naming the file and the damaged object
(DamagedResults, a UserInputError: exit 2).
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import h5py
from h5py import h5d, h5ds, h5o, h5s
import numpy as np

from hpsim.errors import UserInputError

from vehicle.physics.outputs import VARIABLES, Split
from vehicle.results.checkpoint import Checkpoint
from vehicle.results.layout import (CHECKPOINT, DATA_GROUPS, RECORD_COORDINATES, RECORD_DIM, REQUIRED_GROUPS,
                                    SCENARIO, SCENARIO_ATTRS, STATS, SUMMARY, TIMESERIES, equilibrium_group)
from vehicle.results.variables import FileVariable, file_variables, group_dataset, require_xarray

FORMAT = "hpsim-drive"
FORMAT_VERSION = 2
READ_TIMEOUT_S = 60.0          # the check of a file (HPSIM_READ_TIMEOUT overrides)
NOT_A_VARIABLE = b"This is a netCDF dimension but not a netCDF variable."
_INTERNAL_ATTRS = {"CLASS", "NAME", "REFERENCE_LIST", "DIMENSION_LIST", "_Netcdf4Dimid", "_Netcdf4Coordinates",
                   "_NCProperties", "coordinates"}


class DamagedResults(UserInputError):
    """A results file that cannot be read (damaged, truncated, not HDF5, incomplete)."""


def drive_key_for(group: str, name: str, keys) -> tuple[str | None, FileVariable | None]:
    """Which drive key (among `keys`) holds the variable `name`, and how to take it from that key's array."""
    for key in keys:
        entry = VARIABLES.get(key)
        if entry is None:
            continue
        parts = entry.parts if isinstance(entry, Split) else (entry,)
        for j, p in enumerate(parts):
            if p.name == name:
                return key, FileVariable(p.name, key, (), p.attrs(), p.role,
                                         j if isinstance(entry, Split) else None, p.scale)
    return None, None


def open_read(path: str | Path) -> h5py.File:
    """Open a results file for reading, also one whose writer was killed (SWMR read). No checks."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if "already open for write" in str(exc):
            return h5py.File(path, "r", swmr=True)
        raise


class ResultsView:
    """The read interface of results, whatever holds them (a file, memory)."""

    name: str

    def status(self) -> str:
        return str(self.summary_attrs().get("status", "running"))

    def to_xarray(self, group: str | None = None):
        """All groups as one xarray.DataTree (nodes /timeseries, /stats, /equilibrium/charged|before|after,
        /summary, /scenario; root attributes on /), or one group as an xarray.Dataset. Needs xarray >= 2024.10
        (DataTree) and h5netcdf: pip install xarray h5netcdf."""
        if group is not None:
            return self.dataset(group)
        xr = require_xarray()
        if not hasattr(xr, "DataTree"):
            raise ImportError(f"to_xarray() needs xarray >= 2024.10 (DataTree), found {xr.__version__}: "
                              "pip install -U xarray h5netcdf (or use to_xarray(group=...))")
        nodes = {"/": xr.Dataset(attrs=self.root_attrs)}
        for g in self.groups():
            nodes["/" + g] = self.dataset(g)
        return xr.DataTree.from_dict(nodes)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


# --- the check in a child process (no hang, no crash in the caller) -----------------------------------
_CHECK = r"""
import os, re, sys, time
if os.environ.get("HPSIM_FAULT") == "read_hang":     # test hook: a file whose reading never ends
    time.sleep(3600)
import h5py, numpy as np
def short(exc):
    text = str(exc)
    m = re.search(r"truncated file: eof = (\d+).*stored_eof = (\d+)", text)
    if m:
        return f"truncated ({m.group(1)} of {m.group(2)} bytes)"
    if "file signature not found" in text:
        return "not an HDF5 file (no HDF5 signature)"
    inner = re.findall(r"\(([^()]*)\)", text)
    return (inner[-1] if inner else text).strip()[:160] or type(exc).__name__
def fail(where, exc):
    print(f"{where}: {short(exc)}" if where else short(exc))
    sys.exit(1)
def check(path):
    try:
        try:
            f = h5py.File(path, "r")
        except OSError as exc:
            if "already open for write" not in str(exc):
                raise
            f = h5py.File(path, "r", swmr=True)
    except Exception as exc:
        fail("", exc)
    try:
        for k in f.attrs:
            f.attrs[k]
    except Exception as exc:
        fail("/ attributes", exc)
    names = []
    try:
        f.visit(names.append)
    except Exception as exc:
        fail("structure", exc)
    for name in names:
        try:
            obj = f[name]
            for k in obj.attrs:
                obj.attrs[k]
            if isinstance(obj, h5py.Dataset):
                if obj.ndim == 0 or obj.shape[0] == 0:
                    obj[()]
                else:
                    step = max(1, (1 << 22) // max(1, obj.size // obj.shape[0]))
                    for i in range(0, obj.shape[0], step):
                        obj[i:i + step]
        except Exception as exc:
            fail("/" + name, exc)
    f.close()
for path in sys.argv[1:]:        # one line per file read whole, in order
    check(path)
    print("ok", flush=True)
"""


def check_file(path: str | Path, timeout_s: float | None = None) -> None:
    """Read the whole file in a child process under a time limit; DamagedResults if anything fails."""
    path = Path(path)
    timeout_s = _read_timeout_s(timeout_s)
    try:
        r = subprocess.run([sys.executable, "-c", _CHECK, str(path)], capture_output=True, text=True,
                           timeout=timeout_s, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        raise DamagedResults(f"{path}: reading it did not finish within {timeout_s:g} s (a damaged file can make the "
                             "HDF5 library loop); the file is damaged or on a stalled disk") from None
    if r.returncode != 0 or r.stdout.strip() != "ok":
        what = (r.stdout.strip().splitlines() or [""])[-1] or \
            (r.stderr.strip().splitlines() or ["the check crashed"])[-1][:160]
        raise DamagedResults(f"{path}: damaged results file: {what}")


def check_files(paths, timeout_s: float | None = None) -> None:
    """`check_file` of many files (a study's) in one child process: one interpreter started, not one per file;
    the caller then opens them with check=False. When that child fails or runs out of time, the files it did not
    find whole are checked one by one, so that the error names the damaged file as `check_file` does (a damaged
    file costs one time limit more). A missing file or folder is left to `open_results` to name."""
    paths = [Path(p) for p in paths if Path(p).is_file()]
    if len(paths) < 2:
        for p in paths:
            check_file(p, timeout_s)
        return
    try:
        r = subprocess.run([sys.executable, "-c", _CHECK, *map(str, paths)], capture_output=True, text=True,
                           timeout=_read_timeout_s(timeout_s), stdin=subprocess.DEVNULL)
        lines = r.stdout.splitlines()
        whole = next((k for k, line in enumerate(lines) if line.strip() != "ok"), len(lines))
    except subprocess.TimeoutExpired:
        whole = 0
    for p in paths[whole:]:
        check_file(p, timeout_s)


def _read_timeout_s(timeout_s: float | None) -> float:
    return float(os.environ.get("HPSIM_READ_TIMEOUT", READ_TIMEOUT_S)) if timeout_s is None else timeout_s


# --- reading a file ---------------------------------------------------------------------------------
def _h5_dims(ds: h5py.Dataset) -> tuple[str, ...]:
    if ds.attrs.get("CLASS") == b"DIMENSION_SCALE":
        return (ds.name.rsplit("/", 1)[-1],)
    dims = []
    for i in range(ds.ndim):
        d = ds.dims[i]
        dims.append(d[0].name.rsplit("/", 1)[-1] if len(d) else f"phony_dim_{i}")
    return tuple(dims)


def _attr_value(v):
    if isinstance(v, bytes):
        return v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.dtype.kind == "O":
        return np.array([x.decode() if isinstance(x, bytes) else x for x in v.tolist()], dtype=object)
    return v


def _copied(value):
    """value with its containers and arrays copied (scalars and strings shared)."""
    if isinstance(value, dict):
        return {k: _copied(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_copied(v) for v in value)
    return value.copy() if isinstance(value, np.ndarray) else value


class ResultsFile(ResultsView):
    """A results file (format 1 or 2) opened for reading. Use `open_results(path)`."""

    def __init__(self, path: str | Path, f: h5py.File):
        self.path = Path(path)
        self.name = str(path)
        self.f = f
        self.version = self._check_structure()
        self._read_once: dict = {}     # what a report reads many times: the checkpoint, the static groups

    # structure
    def _missing(self, what: str):
        raise DamagedResults(f"{self.path}: incomplete hpsim results file: {what} is missing (the file was cut short "
                             f"or edited); re-create it with: hpsim run SCENARIO -o {self.path} --overwrite")

    def _check_structure(self) -> int:
        f = self.f
        if f.attrs.get("format") != FORMAT:
            raise UserInputError(f"{self.path}: not an hpsim results file (written by `hpsim run`)")
        try:
            version = int(f.attrs.get("format_version", 1))
        except (TypeError, ValueError):
            self._missing("a valid root attribute format_version")
        if version > FORMAT_VERSION:
            raise UserInputError(f"{self.path}: written by a newer hpsim (results format {version}, this hpsim reads "
                                 f"up to {FORMAT_VERSION}); update hpsim to read it")
        sc = f.get(SCENARIO)
        if not isinstance(sc, h5py.Group):
            self._missing(f"/{SCENARIO}")
        for k in SCENARIO_ATTRS:
            if k not in sc.attrs:
                self._missing(f"/{SCENARIO} attribute {k!r}")
        try:
            json.loads(sc.attrs["resolved_json"])
        except (ValueError, TypeError):
            self._missing(f"a readable /{SCENARIO} attribute 'resolved_json'")
        n_st, n_ax = len(sc.attrs["stations"]), len(sc.attrs["axles"])
        if n_ax < 1 or n_st != 2 * n_ax:
            self._missing(f"a consistent list of stations and axles (got {n_st} stations, {n_ax} axles)")
        for g in REQUIRED_GROUPS:
            if not isinstance(f.get(g), h5py.Group):
                self._missing(f"/{g}")
        for item in RECORD_COORDINATES[2 if version >= 2 else 1]:
            if not isinstance(f.get(item), h5py.Dataset):
                self._missing(f"/{item}")
        if not Checkpoint.complete(f[CHECKPOINT]):
            self._missing(f"the checkpoint (/{CHECKPOINT} slots, pointer, fields)")
        return version

    @contextmanager
    def _reading(self, what: str):
        try:
            yield
        except (OSError, KeyError, ValueError, TypeError, IndexError, RuntimeError) as exc:
            if isinstance(exc, UserInputError):
                raise
            raise DamagedResults(f"{self.path}: damaged results file: {what}: {exc}") from None

    # ResultsView
    @property
    def stations(self):
        return [str(s) for s in self.f[SCENARIO].attrs["stations"]]

    @property
    def axles(self):
        return [str(a) for a in self.f[SCENARIO].attrs["axles"]]

    @property
    def root_attrs(self) -> dict:
        return {k: _attr_value(v) for k, v in self.f.attrs.items()}

    @property
    def scenario_attrs(self) -> dict:
        return self._once(f"/{SCENARIO} attributes",
                          lambda: {k: _attr_value(v) for k, v in self.f[SCENARIO].attrs.items()})

    def summary_attrs(self) -> dict:
        def read():
            g = self.f.get(SUMMARY)
            return {} if g is None else {k: _attr_value(v) for k, v in g.attrs.items()}
        return self._once(f"/{SUMMARY} attributes", read)

    def _once(self, key: str, read):
        """read() the first time `key` is asked for, the same value afterwards (the file is read, not written,
        through this object); a copy of its arrays each time, so that callers may change what they get."""
        if key not in self._read_once:
            self._read_once[key] = read()
        return _copied(self._read_once[key])

    def checkpoint(self) -> tuple[dict, dict] | None:
        """The last checkpoint: (DriveState dict, {n_samples, n_stats, wall_s}), or None before the first."""
        def read():
            with self._reading(f"/{CHECKPOINT}"):
                return Checkpoint(self.f[CHECKPOINT]).read()
        return self._once(f"/{CHECKPOINT}", read)

    def counts(self) -> tuple[int, int]:
        ck = self.checkpoint()
        return (ck[1]["n_samples"], ck[1]["n_stats"]) if ck is not None else (0, 0)

    def state(self) -> dict | None:
        ck = self.checkpoint()
        return None if ck is None else ck[0]

    def _record(self, group: str, name: str, n: int):
        g = self.f[group]
        with self._reading(f"/{group}/{name}"):
            if self.version >= 2:
                ds = g.get(name)
                return None if ds is None else np.asarray(ds[:min(n, ds.shape[0])], float)
            key, v = drive_key_for(group, name, list(g))
            if key is None:
                return None
            ds = g[key]
            a = np.asarray(ds[:min(n, ds.shape[0])], float)
            if v.row is not None:
                a = a[:, v.row]
            return a * v.scale if v.scale != 1.0 else a

    def series(self, name: str):
        return self._record(TIMESERIES, name, self.counts()[0])

    def stats_series(self, name: str):
        return self._record(STATS, name, self.counts()[1])

    def _v1_keys(self, g: h5py.Group) -> dict:
        """Format 1 equilibria and summary: Equilibrium fields as datasets and scalar attributes -> drive keys."""
        out = {k: g[k][()] for k in g if k in VARIABLES or k == "strut_temperature_end_K"}
        for k in ("heave_m", "pitch_rad", "roll_rad"):
            if k in g.attrs:
                out[k] = float(g.attrs[k])
        if "temperature_K" in g.attrs:                  # charged: one temperature for every strut
            out["temperatures_K"] = np.full(len(self.stations), float(g.attrs["temperature_K"]))
        if "strut_temperature_end_K" in out:
            out["strut_temperature_K"] = out.pop("strut_temperature_end_K")
        return out

    def _static_group(self, path: str) -> dict | None:
        return self._once(path, lambda: self._read_static_group(path))

    def _read_static_group(self, path: str) -> dict | None:
        g = self.f.get(path)
        if g is None:
            return None
        out = {}
        with self._reading(f"/{path}"):
            if self.version < 2:
                for key, value in self._v1_keys(g).items():
                    a = np.asarray(value, float)
                    for v in file_variables(key, a.shape, None, len(self.stations), len(self.axles)):
                        out[v.name] = v.take(a, False) if a.ndim else float(a)
                return out
            return _variables_of(g)

    def equilibrium(self, which: str) -> dict | None:
        return self._static_group(equilibrium_group(which))

    def summary_values(self) -> dict:
        return self._static_group(SUMMARY) or {}

    def groups(self) -> list[str]:
        return [SCENARIO] + [g for g in DATA_GROUPS if g in self.f]

    def dataset(self, group: str):
        xr = require_xarray()
        if group == SCENARIO:
            return xr.Dataset(attrs=self.scenario_attrs)
        if group not in self.f:
            raise UserInputError(f"{self.path}: no group /{group} (groups: {', '.join(self.groups())})")
        attrs = self.summary_attrs() if group == SUMMARY else {}
        with self._reading(f"/{group}"):
            if self.version < 2:
                return group_dataset(RECORD_DIM.get(group), self._v1_arrays(group), self.stations, self.axles, attrs)
            return self._nc_dataset(group)

    def _v1_arrays(self, group: str) -> dict:
        g = self.f[group]
        if group in RECORD_DIM:
            n = self.counts()[0 if group == TIMESERIES else 1]
            return {k: np.moveaxis(np.asarray(g[k][:min(n, g[k].shape[0])], float), 0, -1) for k in g}
        return self._v1_keys(g)

    def _nc_dataset(self, group: str):
        """A group as netCDF readers (xarray + h5netcdf) see it, the record dimension cut to the checkpoint."""
        xr = require_xarray()
        g = self.f[group]
        record = {TIMESERIES: (RECORD_DIM[TIMESERIES], self.counts()[0]),
                  STATS: (RECORD_DIM[STATS], self.counts()[1])}.get(group)
        coord_names = set()
        for ds in g.values():
            if isinstance(ds, h5py.Dataset) and "coordinates" in ds.attrs:
                coord_names |= set(_attr_value(ds.attrs["coordinates"]).split())
        coords, data_vars = {}, {}
        for name, ds in g.items():
            if not isinstance(ds, h5py.Dataset):
                continue
            is_scale = ds.attrs.get("CLASS") == b"DIMENSION_SCALE"
            if is_scale and bytes(ds.attrs.get("NAME", b"")).startswith(NOT_A_VARIABLE):
                continue
            dims = _h5_dims(ds)
            if ds.dtype.kind == "O" or h5py.check_string_dtype(ds.dtype) is not None:
                values = np.array(ds.asstr()[()])
            elif record is not None and dims and dims[0] == record[0]:
                values = ds[:min(record[1], ds.shape[0])]
            else:
                values = ds[()]
            attrs = {k: _attr_value(v) for k, v in ds.attrs.items() if k not in _INTERNAL_ATTRS}
            (coords if is_scale or name in coord_names else data_vars)[name] = (dims, values, attrs)
        attrs = {k: _attr_value(v) for k, v in g.attrs.items() if k not in _INTERNAL_ATTRS}
        return xr.Dataset(data_vars, coords=coords, attrs=attrs)

    def close(self) -> None:
        try:
            self.f.close()
        except Exception:
            pass


def _variables_of(g: h5py.Group) -> dict:
    """The datasets of a static group that are not dimension scales, as float arrays (scalars as float), in the
    group's order. Through h5py's low-level objects: a report and the validity checks read some 80 of them, and
    h5py's high-level Dataset and attribute objects cost about four times as much as the reads."""
    out = {}
    for name in g.id:
        obj = h5o.open(g.id, name)
        if not isinstance(obj, h5d.DatasetID) or h5ds.is_scale(obj):
            continue
        a = np.empty(obj.shape, float)
        if a.size:
            obj.read(h5s.ALL, h5s.ALL, a)         # HDF5 converts the stored type to float64
        out[name.decode()] = a if a.ndim else float(a)
    return out


def open_results(path: str | Path, check: bool = True) -> ResultsFile:
    """A results file for reading. check: first read all of it in a child process under a time limit
    (a damaged file fails fast, as DamagedResults, instead of hanging or crashing this process)."""
    path = Path(path)
    if not path.exists():
        raise UserInputError(f"{path}: file not found")
    if path.is_dir():
        raise UserInputError(f"{path}: is a directory, not a results file")
    if check:
        check_file(path)
    try:
        f = open_read(path)
    except OSError as exc:
        inner = re.findall(r"\(([^()]*)\)", str(exc))
        raise DamagedResults(f"{path}: cannot open as HDF5 ({inner[-1] if inner else exc})") from None
    try:
        return ResultsFile(path, f)
    except BaseException:
        f.close()
        raise
