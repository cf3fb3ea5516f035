"""hpsim's cache folder: ~/.cache/hpsim (or $HPSIM_CACHE), private to this user.

It holds the compiled model libraries (vehicle.numerics.codegen, whose module docstring gives the trust model),
this machine's compile and drive rates, the quantities already converted to SI (`hpsim.units`) and the random
roads already generated (`terrain.store`, in its `roads/` folder). The folder
is created with mode 0700; a folder owned by another user or writable by group/others is not trusted
(`trusted_cache_dir` says None, and nothing is read from it or written to it).
"""
from __future__ import annotations

import os
import shutil
import stat
import time
from pathlib import Path

from .errors import UserInputError

CACHE_ENV = "HPSIM_CACHE"
STALE_TEMPORARY_S = 3600.0      # a temporary folder older than this was left by a process killed while writing


def configured_cache_dir() -> Path:
    """The folder $HPSIM_CACHE names, else ~/.cache/hpsim (not checked)."""
    return Path(os.environ.get(CACHE_ENV) or Path.home() / ".cache" / "hpsim")


def untrusted(d: Path) -> str | None:
    """Why folder `d` may not hold what this process loads (None: it may)."""
    st = d.stat()
    if not stat.S_ISDIR(st.st_mode):
        return "not a folder"
    if hasattr(os, "geteuid") and st.st_uid != os.geteuid():
        return f"owned by another user (uid {st.st_uid})"
    if st.st_mode & (stat.S_IWGRP | stat.S_IWOTH):
        return f"writable by other users (mode {stat.S_IMODE(st.st_mode):o})"
    return None


def cache_problem() -> tuple[Path, str | None]:
    """(the configured cache folder, created 0700 when missing; why it cannot be trusted, or None)."""
    d = configured_cache_dir()
    try:
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
        return d, untrusted(d)
    except OSError as exc:
        return d, f"cannot be created ({exc.strerror})"


def trusted_cache_dir() -> Path | None:
    """The cache folder when it can be trusted, else None (quietly: the caller goes without the cache)."""
    d, problem = cache_problem()
    return d if problem is None else None


def size_limit_bytes(variable: str, default_mb: float, minimum_mb: float, what: str) -> float:
    """A size limit [bytes] from the environment variable `variable` in MB (default_mb when unset); UserInputError
    naming the variable, `what` it limits and the allowed range when it is not a number >= minimum_mb."""
    text = os.environ.get(variable)
    if not text:
        return default_mb * 1e6
    try:
        mb = float(text)
    except ValueError:
        mb = float("nan")
    if not mb >= minimum_mb:
        raise UserInputError(f"{variable}: expected {what} in MB (>= {minimum_mb:g}), got {text!r}")
    return mb * 1e6


def least_recently_used(entries: dict[str, tuple[float, int]], limit_bytes: float, keep: tuple[str, ...] = ()
                        ) -> list[str]:
    """The entries (name -> (last use [s since the epoch], size [bytes])) to remove, least recently used first, so
    that the others hold at most `limit_bytes`; those named in `keep` stay. The cache's one eviction policy (the
    compiled libraries, `vehicle.numerics.codegen.evict`; the roads, `terrain.store.prune`)."""
    total = sum(size for _, size in entries.values())
    removed = []
    for name in sorted(entries, key=lambda k: entries[k][0]):
        if total <= limit_bytes:
            break
        if name in keep:
            continue
        total -= entries[name][1]
        removed.append(name)
    return removed


def remove_stale_temporaries(folder: Path, pattern: str, older_than_s: float = STALE_TEMPORARY_S) -> None:
    """Remove the temporary folders `pattern` (a glob) in `folder` that are older than older_than_s."""
    now = time.time()
    for t in folder.glob(pattern):
        try:
            if now - t.stat().st_mtime > older_than_s:
                shutil.rmtree(t, ignore_errors=True)
        except OSError:
            pass
