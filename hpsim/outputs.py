"""Output paths checked before any work starts, so that nothing computed is lost at the end.

`check_output_file` and `check_output_dir` raise `UserInputError` (one line, exit code 2) naming
the option and the path when the file or folder cannot be written: a directory where a file is
expected, a file where a folder is expected, a missing or read-only folder, a figure type the
plotting library does not know. Writability is tested by creating (and at once removing) a
uniquely named empty file in the folder: permission bits alone do not tell (root, read-only
mounts, /sys).
"""
from __future__ import annotations

import functools
import os
import tempfile
from pathlib import Path

from .errors import UserInputError


@functools.lru_cache(maxsize=1)
def figure_suffixes() -> tuple[str, ...]:
    """File types matplotlib can write (".png", ".pdf", ".svg", ...)."""
    from matplotlib.backend_bases import FigureCanvasBase

    return tuple(sorted(f".{ext}" for ext in FigureCanvasBase.get_supported_filetypes()))


def _nearest_existing(path: Path) -> Path:
    p = path
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def _probe_writable(folder: Path, where: str, path: Path) -> None:
    try:
        fd, probe = tempfile.mkstemp(prefix=".hpsim-write-test-", dir=folder)
    except OSError as exc:
        raise UserInputError(f"{where}: cannot write {path}: folder {folder} is not writable "
                             f"({exc.strerror or exc.__class__.__name__})") from None
    os.close(fd)
    os.unlink(probe)


def _check_folder(folder: Path, where: str, path: Path, make_parents: bool) -> None:
    existing = _nearest_existing(folder)
    if not existing.is_dir():
        raise UserInputError(f"{where}: cannot write {path}: {existing} is a file, not a folder")
    if existing != folder and not make_parents:
        raise UserInputError(f"{where}: cannot write {path}: folder {folder} does not exist")
    _probe_writable(existing, where, path)


def _not_empty(path, where: str) -> None:
    if not str(path).strip():
        raise UserInputError(f"{where}: empty path; give a file or folder name")


def check_output_file(path: str | Path, where: str, *, suffixes: tuple[str, ...] | None = None,
                      make_parents: bool = False) -> Path:
    """`path` can be written as a file (created or replaced). `suffixes`: allowed file types
    (an empty suffix is allowed too); `make_parents`: the command creates missing folders."""
    _not_empty(path, where)
    p = Path(path)
    if str(path).endswith(os.sep) or p.is_dir():
        raise UserInputError(f"{where}: {path} is a directory; give a file name"
                             + (f", e.g. {p / ('out' + suffixes[0])}" if suffixes else ""))
    if suffixes is not None and p.suffix and p.suffix.lower() not in suffixes:
        raise UserInputError(f"{where}: {path}: unknown file type {p.suffix!r}; allowed: {', '.join(suffixes)}")
    if p.exists() and not os.access(p, os.W_OK):
        raise UserInputError(f"{where}: {path} exists and is not writable")
    _check_folder(p.parent if str(p.parent) else Path("."), where, p, make_parents)
    return p


def check_figure_file(path: str | Path, where: str, *, make_parents: bool = False) -> Path:
    """A figure path: writable and of a file type matplotlib knows."""
    return check_output_file(path, where, suffixes=figure_suffixes(), make_parents=make_parents)


def check_output_dir(path: str | Path, where: str) -> Path:
    """`path` is (or can be created as) a writable folder."""
    _not_empty(path, where)
    p = Path(path)
    if p.exists() and not p.is_dir():
        raise UserInputError(f"{where}: {path} exists and is not a folder")
    if p.is_dir():
        _probe_writable(p, where, p)
    else:
        _check_folder(p, where, p, make_parents=True)
    return p
