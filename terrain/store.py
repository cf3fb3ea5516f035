"""Generated roads kept on disk: a random road's tracks and what is derived from them (the tyre envelopes, the
spline's knot slopes), so that a second run on the same road reads them instead of computing them again.

A 106 km road on the 50 mm grid is 2.1 M points a track: generating it (noise and overlap-save FFTs), enveloping it
and solving its spline slopes take ~0.6 s of every run on it, a fifth of a multiscale run, and every case of a
sweep or UQ study on one road paid it again. From the store the arrays are memory-mapped (`numpy.load(...,
mmap_mode="r")`): opening them costs milliseconds, and a run that reads a few kilometres of the road (the multiscale
windows) reads only those pages.

Keys. An entry is found by the SHA-256 of what determines its numbers: for a generated road its `RoadSpec` (seed,
class, length, spacing, events, ...), for a derived array its parent's key and the operation with its parameters,
and for every entry the source of the `terrain` package and NumPy's version (its random generator and FFT). A
changed generator or NumPy is a new key; the arrays read equal the computed ones bit for bit (tests/unit/terrain/
test_road_store.py). Only random roads are stored: a CSV or OpenCRG road is read from its own file.

Where: `<cache folder>/roads/<key>/`, the cache folder of `hpsim.cache` (private to the user; an untrusted folder
is not used, and the road is computed as without a store). The files are data (`.npy`, no pickles), written to a
temporary folder and renamed into place, so parallel workers never read half an entry. Bounded: beyond
HPSIM_ROAD_CACHE_MAX_MB (default 1000 MB) the least recently used entries are removed after each write; 0 turns
the store off.
"""
from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import tempfile
import threading
import warnings
from importlib.util import find_spec
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from hpsim.cache import least_recently_used, remove_stale_temporaries, size_limit_bytes, trusted_cache_dir

ROAD_CACHE_MAX_ENV = "HPSIM_ROAD_CACHE_MAX_MB"
DEFAULT_ROAD_CACHE_MAX_MB = 1000.0
FOLDER = "roads"
# numpy.load parses an .npy header with ast.literal_eval, and CPython 3.11's AST constructor keeps its recursion
# depth per interpreter, not per thread (CPython gh-106905): two tracks read on two threads (`Road.prepare`) can
# fail with "SystemError: AST constructor recursion depth mismatch". Opening an entry is milliseconds; one at a time.
_OPEN_LOCK = threading.Lock()


def limit_bytes() -> float:
    """The store's size limit [bytes] from HPSIM_ROAD_CACHE_MAX_MB (0: no store)."""
    return size_limit_bytes(ROAD_CACHE_MAX_ENV, DEFAULT_ROAD_CACHE_MAX_MB, 0.0,
                            "the road store's size limit (0 turns it off)")


@functools.lru_cache(maxsize=1)
def generator_version() -> str:
    """SHA-256 of the `terrain` package's source (each file's name and bytes) and NumPy's version."""
    h = hashlib.sha256(f"numpy {np.__version__}\0".encode())
    for root in sorted(find_spec("terrain").submodule_search_locations):
        for path in sorted(Path(root).glob("*.py")):
            h.update(f"{path.name}\0".encode())
            h.update(path.read_bytes())
    return h.hexdigest()


def key_of(*parts) -> str:
    """The key of an entry determined by `parts` (JSON-serialisable: a spec, a parent key, an operation and its
    parameters) and the generator's version."""
    text = json.dumps(parts, sort_keys=True, separators=(",", ":"), default=float)
    return hashlib.sha256(f"{generator_version()}\0{text}".encode()).hexdigest()[:40]


def _folder() -> Path | None:
    if limit_bytes() <= 0:
        return None
    d = trusted_cache_dir()
    return None if d is None else d / FOLDER


def _read(entry: Path, names: Sequence[str]) -> tuple[np.ndarray, ...] | None:
    """The entry's arrays memory-mapped read-only, or None when it is missing or not whole."""
    try:
        with _OPEN_LOCK:
            arrays = tuple(np.load(entry / f"{n}.npy", mmap_mode="r", allow_pickle=False) for n in names)
        os.utime(entry)                                   # recently used (the bound removes the oldest first)
        return arrays
    except (OSError, ValueError):
        return None


def _write(folder: Path, entry: Path, names: Sequence[str], arrays: Sequence[np.ndarray]) -> None:
    """The arrays written to a temporary folder beside the entry, then renamed into place (another process that
    wrote the same entry first wins; this one's copy is dropped)."""
    tmp = None
    try:
        folder.mkdir(mode=0o700, parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{entry.name}.", dir=folder))
        for n, a in zip(names, arrays):
            np.save(tmp / f"{n}.npy", np.ascontiguousarray(a, dtype=float), allow_pickle=False)
        os.rename(tmp, entry)
    except OSError as exc:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
        if not entry.is_dir():              # not another process's copy in place first: the store cannot be written
            _unwritable(folder, exc.strerror or exc.__class__.__name__)


@functools.lru_cache(maxsize=None)
def _unwritable(folder: Path, why: str) -> None:
    """Warn once per folder and reason that the store cannot be written (a read-only or full cache): the runs go on,
    computing their roads each time."""
    warnings.warn(f"road store {folder}: cannot write ({why}); roads are computed again on every run "
                  f"({ROAD_CACHE_MAX_ENV}=0 turns the store off)", stacklevel=2)


def _size(entry: Path) -> int:
    try:
        return sum(p.stat().st_size for p in entry.iterdir())
    except OSError:
        return 0


def prune(folder: Path, limit: float) -> None:
    """Remove the least recently used entries until the store is within `limit` bytes."""
    try:
        entries = {e.name: (e.stat().st_mtime, _size(e)) for e in folder.iterdir()
                   if e.is_dir() and not e.name.startswith(".")}
    except OSError:
        return
    for name in least_recently_used(entries, limit):
        shutil.rmtree(folder / name, ignore_errors=True)


def stored_arrays(key: str | None, names: Sequence[str], compute: Callable[[], Sequence[np.ndarray]]
                  ) -> tuple[np.ndarray, ...]:
    """The arrays `names` of entry `key`, read from the store or computed by `compute()` and stored (key None, or
    no store: computed)."""
    folder = None if key is None else _folder()
    if folder is not None:
        found = _read(folder / key, names)
        if found is not None:
            return found
    arrays = tuple(compute())
    if folder is not None:
        _write(folder, folder / key, names, arrays)
        remove_stale_temporaries(folder, ".*")
        prune(folder, limit_bytes())
    return arrays
