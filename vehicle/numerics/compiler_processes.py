"""Compiler processes: a library built into the compile cache by a C compiler in a private build folder.

A `BuildJob` names what to build; `start_build` starts the compiler in its own session (a Ctrl-C at the terminal
reaches hpsim, which stops it, never the compiler alone), `finish_build` waits and moves the library and its record
into the cache by atomic renames. Every compiler this process starts is registered until it is reaped, so that
a command stopped while ensemble lanes compile leaves no compiler behind (`kill_running_compilers`, also at exit).
"""
from __future__ import annotations

import atexit
import contextlib
import errno
import hashlib
import json
import os
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from hpsim.cache import CACHE_ENV
from hpsim.errors import UserInputError

CACHE_MAX_ENV = "HPSIM_CACHE_MAX_MB"


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def library_record(path: Path) -> dict:
    """What a cache entry's record holds of its file (`_verified` compares it): its SHA-256, its size, when built."""
    return {"library_sha256": sha256_file(path), "library_bytes": path.stat().st_size,
            "built": time.strftime("%Y-%m-%dT%H:%M:%S")}


DISK_FULL = (errno.ENOSPC, errno.EDQUOT, errno.EFBIG)


def cache_full_error(d: Path, why: str) -> UserInputError:
    """The error of a cache folder that cannot take a library: names the folder and the ways out."""
    return UserInputError(f"compile cache {d}: {why}; free space there, or set {CACHE_ENV} to a folder on another "
                          f"disk (and {CACHE_MAX_ENV} to bound its size in MB)")


# compilers running in this process (started from any thread): killed with their process groups at exit, so that
# a command ended by SIGTERM while ensemble lanes compile leaves no compiler behind
RUNNING: set = set()
_RUNNING_LOCK = threading.Lock()


@atexit.register
def kill_running_compilers() -> None:
    """Kill every compiler this process started and is still waiting for, from any thread (their own sessions
    keep them from a terminal's signals): for a command or an ensemble stopped while its lanes' threads compile."""
    with _RUNNING_LOCK:
        running = list(RUNNING)
    for proc in running:
        _kill(proc)


@dataclass(frozen=True)
class BuildJob:
    """A library to compile into the cache: the compiler `cc` and its `flags`, the C `code` and its SHA-256, the cache
    `folder` and the library's `stem` there (stem.so, stem.json), and more entries of its record (a `Library`'s
    lookup key and signature)."""

    cc: str
    flags: Sequence[str]
    code: bytes
    code_sha: str
    folder: Path
    stem: str
    record: dict = field(default_factory=dict)


@dataclass(frozen=True)
class StartedBuild:
    """A compiler process working on `job` in its private build folder `build_dir`."""

    proc: subprocess.Popen
    job: BuildJob
    build_dir: Path


def start_build(job: BuildJob) -> StartedBuild:
    """Start compiling a job in a private build folder of its cache folder."""
    try:
        build = Path(tempfile.mkdtemp(prefix=f".build-{job.stem}-", dir=job.folder))
    except OSError as exc:
        if exc.errno in DISK_FULL:
            raise cache_full_error(job.folder, exc.strerror) from None
        raise
    try:
        src = build / f"{job.stem}.c"
        src.write_bytes(job.code)
        # the compiler runs in its own session: a Ctrl-C at the terminal reaches hpsim (which stops
        # it), never the compiler alone (a compiler killed under us used to fall back silently)
        proc = subprocess.Popen([job.cc, *job.flags, "-fPIC", "-shared", src.name, "-o", f"{job.stem}.so", "-lm"],
                                cwd=build, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        with _RUNNING_LOCK:
            RUNNING.add(proc)
    except BaseException as exc:
        shutil.rmtree(build, ignore_errors=True)
        if isinstance(exc, OSError) and exc.errno in DISK_FULL:
            raise cache_full_error(job.folder, exc.strerror) from None
        raise
    return StartedBuild(proc, job, build)


def finish_build(started: StartedBuild) -> str | None:
    """Wait for a started compiler and put its library and record into the cache (atomic renames); None when done,
    else the compiler's error. The build folder is removed whatever happens; an interrupt kills the compiler."""
    proc, job, build = started.proc, started.job, started.build_dir
    try:
        try:
            _, stderr = proc.communicate()
        except BaseException:
            _kill(proc)
            raise
        finally:
            with _RUNNING_LOCK:
                RUNNING.discard(proc)
        if proc.returncode == -signal.SIGINT:
            raise KeyboardInterrupt
        if proc.returncode != 0:
            full = next((os.strerror(e) for e in DISK_FULL if os.strerror(e) in stderr), None)
            if full is not None:        # the cache's disk (or the compiler's temporary folder) is full
                raise cache_full_error(job.folder, f"{full} ({stderr.strip().splitlines()[0][:160]})")
            return stderr.strip()[:300] or f"exit code {proc.returncode}"
        built = build / f"{job.stem}.so"
        meta = {"c_sha256": job.code_sha, **library_record(built), "compiler": job.cc, "flags": job.flags, **job.record}
        (build / f"{job.stem}.json").write_text(json.dumps(meta))
        # atomic renames, library first: a reader sees an old record with a new library at worst,
        # which fails verification and rebuilds
        os.replace(built, job.folder / f"{job.stem}.so")
        os.replace(build / f"{job.stem}.json", job.folder / f"{job.stem}.json")
        return None
    except OSError as exc:
        if exc.errno in DISK_FULL:
            raise cache_full_error(job.folder, exc.strerror) from None
        raise
    finally:
        shutil.rmtree(build, ignore_errors=True)


@contextlib.contextmanager
def _interrupts_held():
    """SIGINT held back while a compiler is started and recorded, so that a Ctrl-C cannot land between the two
    (a compiler nobody waits for, a build folder nobody removes); it is delivered right after."""
    if not hasattr(signal, "pthread_sigmask") or threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _abort(started: list[StartedBuild]) -> None:
    """Stop started compilers and remove their build folders (for any of them, finished or not)."""
    for build in started:
        _kill(build.proc)
        shutil.rmtree(build.build_dir, ignore_errors=True)


def _kill(proc) -> None:
    """Kill a compiler and what it started (cc1, as: its process group, the session it leads), and reap it."""
    with _RUNNING_LOCK:
        RUNNING.discard(proc)
    if proc.returncode is not None:     # reaped already: its process group id may be another's by now
        return
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        pass
    if proc.poll() is None:
        proc.kill()
    proc.wait()


def run_builds(jobs: list[BuildJob], width: int) -> list[str | None]:
    """Compile the jobs with at most `width` compilers at once; per job None when built, else the compiler's error. An interrupt or an error stops every
    compiler and keeps nothing of the unfinished ones."""
    errors, running = [], []                    # running: started, removed only once finished
    try:
        for job in jobs:
            if len(running) == width:
                errors.append(finish_build(running[0]))
                running.pop(0)
            with _interrupts_held():
                running.append(start_build(job))
        while running:
            errors.append(finish_build(running[0]))
            running.pop(0)
    except BaseException:
        _abort(running)
        raise
    return errors


def build_one(job: BuildJob) -> str | None:
    """Compile a job into folder/stem.so with its record folder/stem.json; None when done, else the compiler's
    error."""
    return run_builds([job], 1)[0]


